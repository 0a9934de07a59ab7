"""Apple ARKit's 52 blend shapes as a control layer: the table, the names, and weights → activations.

The table (``data/arkit.json``) gives each of the 52 ``ARFaceAnchor.BlendShapeLocation`` names
the channel values that realise its meaning at weight 1, in the order of Apple's documentation
(``ARKIT_NAMES``).

**Sides.** "Left" and "Right" are the subject's own sides: ``eyeBlinkLeft`` closes the eye on
the subject's left, +X in mimetic. Apple's face mesh, MediaPipe's blend shapes and ICT-FaceKit
agree (ICT's ``eyeBlink_L`` moves vertices at x ≈ +3.3 cm, its ``mouthSmile_L`` the corner at
x = +2.5 cm). ICT-style names are accepted as aliases: ``eyeBlink_L`` for ``eyeBlinkLeft`` and
so on (but ``jawLeft``, ``mouthLeft`` and their Right twins are directions, the same in both);
ICT splits two symmetric shapes into halves, ``browInnerUp_L/_R`` and ``cheekPuff_L/_R``, which
are accepted too (a half drives that side's channels and half of each midline channel).

**Pose** (``arkit_pose``): ``p = clip(d + sum_k w_k v_k)``, linear in the weights before the
clip, like the expression blend.

The bake (the 52 shapes as vertex deltas of a rigged head) and the reverse map (activations →
ARKit weights) work on geometry, so they live in ``mimetic.export.arkit``.
"""

from __future__ import annotations

import difflib
import json
import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from importlib import resources
from types import MappingProxyType

import numpy as np

from mimetic.errors import MimeticError
from mimetic.rig.activations import check_activations
from mimetic.rig.model import Rig

log = logging.getLogger(__name__)

FORMAT = "mimetic-arkit"
VERSION = 1
STATUSES = ("exact", "split", "approximate", "unsupported")
_ENTRY_KEYS = frozenset({"description", "values", "status", "pair", "note", "halves"})


class ArkitError(MimeticError, ValueError):
    """An unknown ARKit name, a weight outside [0, 1], or shapes of the wrong size."""


@dataclass(frozen=True)
class ArkitShape:
    """One ARKit blend shape and how the rig realises it.

    Attributes
    ----------
    name : str
        Apple's name, e.g. "eyeBlinkLeft".
    description : str
        What the shape does (after Apple's documentation).
    values : Mapping[str, float]
        Channel values at weight 1.
    status : "exact" | "split" | "approximate" | "unsupported"
    side : "L" | "R" | ""
        The subject's side the shape belongs to ("" for symmetric and directional shapes).
    pair : str
        For a split shape, the shape it is baked together with ("" otherwise).
    halves : bool
        A symmetric shape that ICT splits into ``_L``/``_R`` halves (browInnerUp, cheekPuff).
    note : str
        Why a shape is split, approximate or unsupported.
    """

    name: str
    description: str
    values: Mapping[str, float]
    status: str
    side: str = ""
    pair: str = ""
    halves: bool = False
    note: str = ""


# ---- the table


def _parse(data: object, source: str) -> tuple[dict[str, ArkitShape], dict[str, tuple[str, str]]]:
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise ArkitError(f"{source}: not a {FORMAT!r} file")
    if not isinstance(data.get("version"), int) or data["version"] > VERSION:
        raise ArkitError(f"{source}: format version {data.get('version')!r} is newer than {VERSION}")
    entries = data.get("shapes")
    if not isinstance(entries, dict) or len(entries) != 52:
        raise ArkitError(f"{source}: 'shapes' must hold the 52 ARKit shapes")
    directional = set(data.get("directional", ()))
    shapes: dict[str, ArkitShape] = {}
    for name, entry in entries.items():
        where = f"{source}: {name!r}"
        if not isinstance(entry, dict) or not isinstance(entry.get("values"), dict):
            raise ArkitError(f"{where}: expected an object with 'values'")
        extra = sorted(set(entry) - _ENTRY_KEYS)
        if extra:
            raise ArkitError(f"{where}: unknown key(s) {', '.join(map(repr, extra))}")
        values = {}
        for channel, value in entry["values"].items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ArkitError(f"{where}: channel {channel!r} = {value!r} is not a finite number")
            values[channel] = float(value)
        status = entry.get("status", "exact")
        if status not in STATUSES:
            raise ArkitError(f"{where}: status {status!r} is not one of {STATUSES}")
        side = ""
        if name not in directional:
            side = "L" if name.endswith("Left") else "R" if name.endswith("Right") else ""
        pair = entry.get("pair", "")
        if (status == "split") != bool(pair) or (pair and not side):
            raise ArkitError(f"{where}: a split shape is one-sided and names its 'pair' (and only it does)")
        if status != "exact" and not entry.get("note"):
            raise ArkitError(f"{where}: a {status} shape needs a 'note' saying why")
        shapes[name] = ArkitShape(
            name,
            str(entry.get("description", "")),
            MappingProxyType(values),
            status,
            side,
            pair,
            bool(entry.get("halves", False)),
            str(entry.get("note", "")),
        )
    for shape in shapes.values():
        if shape.pair and shape.pair not in shapes:
            raise ArkitError(f"{source}: {shape.name!r} pairs with unknown shape {shape.pair!r}")
    aliases: dict[str, tuple[str, str]] = {name: (name, "") for name in shapes}
    for shape in shapes.values():
        if shape.side:
            base = shape.name[: -len("Left" if shape.side == "L" else "Right")]
            aliases[f"{base}_{shape.side}"] = (shape.name, "")  # ICT: eyeBlink_L
        if shape.halves:
            for s in ("L", "R"):
                aliases[f"{shape.name}_{s}"] = (shape.name, s)  # ICT: browInnerUp_L
    return shapes, aliases


@cache
def _table() -> tuple[Mapping[str, ArkitShape], Mapping[str, tuple[str, str]]]:
    text = resources.files("mimetic.animate").joinpath("data/arkit.json").read_text("utf-8")
    shapes, aliases = _parse(json.loads(text), "arkit.json")
    return MappingProxyType(shapes), MappingProxyType(aliases)


def arkit_table() -> Mapping[str, ArkitShape]:
    """The 52 shapes by Apple name, in Apple's documentation order (read once)."""
    return _table()[0]


ARKIT_NAMES: tuple[str, ...] = tuple(arkit_table())
"""The 52 Apple names in the order of Apple's documentation (left eye, right eye, mouth and jaw,
brows, cheeks and nose, tongue); the order of ``arkit_weights``'s output."""
STATUS: Mapping[str, str] = MappingProxyType({s.name: s.status for s in arkit_table().values()})
SPLIT: Mapping[str, str] = MappingProxyType(
    {s.name: s.note for s in arkit_table().values() if s.status == "split"}
)
APPROXIMATE: Mapping[str, str] = MappingProxyType(
    {s.name: s.note for s in arkit_table().values() if s.status == "approximate"}
)
UNSUPPORTED: Mapping[str, str] = MappingProxyType(
    {s.name: s.note for s in arkit_table().values() if s.status == "unsupported"}
)


def resolve_name(name: str) -> tuple[str, str]:
    """(Apple name, half) of an ARKit or ICT name: "eyeBlink_L" → ("eyeBlinkLeft", ""),
    "browInnerUp_L" → ("browInnerUp", "L"). Case is ignored when there is no exact match."""
    aliases = _table()[1]
    if name in aliases:
        return aliases[name]
    folded = {a.casefold(): a for a in aliases}
    if isinstance(name, str) and name.casefold() in folded:
        return aliases[folded[name.casefold()]]
    close = difflib.get_close_matches(str(name), list(aliases), n=3, cutoff=0.6)
    hint = f"did you mean {', '.join(close)}?" if close else "see mimetic.animate.arkit.ARKIT_NAMES"
    raise ArkitError(f"unknown ARKit blend shape {name!r}; {hint}")


def ict_name(name: str) -> str:
    """ICT-FaceKit's name of an Apple shape: "eyeBlinkLeft" → "eyeBlink_L" (others unchanged)."""
    shape = arkit_table()[resolve_name(name)[0]]
    if not shape.side:
        return shape.name
    return shape.name[: -len("Left" if shape.side == "L" else "Right")] + f"_{shape.side}"


def _half(values: Mapping[str, float], side: str) -> dict[str, float]:
    """One side's share of a symmetric set: that side's channels, half of each midline channel."""
    other = "R" if side == "L" else "L"
    out = {}
    for channel, value in values.items():
        if channel.endswith(f"_{side}"):
            out[channel] = value
        elif not channel.endswith(f"_{other}"):
            out[channel] = 0.5 * value
    return out


# ---- weights → activations


def _weights(weights: Mapping[str, float] | np.ndarray) -> dict[tuple[str, str], float]:
    if not isinstance(weights, Mapping):
        array = np.asarray(weights, dtype=np.float64)
        if array.shape != (len(ARKIT_NAMES),):
            raise ArkitError(
                f"ARKit weights as an array must have shape ({len(ARKIT_NAMES)},) in ARKIT_NAMES order; "
                f"got {array.shape}"
            )
        weights = dict(zip(ARKIT_NAMES, array.tolist(), strict=True))
    out: dict[tuple[str, str], float] = {}
    given: dict[tuple[str, str], str] = {}
    for name, weight in weights.items():
        if name == "_neutral":  # MediaPipe's extra score
            continue
        key = resolve_name(name)
        if key in given:
            raise ArkitError(f"ARKit shape {name!r} is given twice (also as {given[key]!r})")
        given[key] = name
        if isinstance(weight, bool) or not isinstance(weight, (int, float, np.integer, np.floating)):
            raise ArkitError(f"ARKit weight of {name!r} must be a number in [0, 1]; got {weight!r}")
        w = float(weight)
        if not (math.isfinite(w) and -1e-9 <= w <= 1.0 + 1e-9):
            raise ArkitError(f"ARKit weight of {name!r} is {w:g}; ARKit weights lie in [0, 1]")
        out[key] = min(max(w, 0.0), 1.0)
    return out


def arkit_values(weights: Mapping[str, float] | np.ndarray) -> dict[str, float]:
    """Summed channel values (unclipped) ``sum_k w_k v_k`` of ARKit weights."""
    table = arkit_table()
    total: dict[str, float] = {}
    for (apple, half), w in _weights(weights).items():
        values = table[apple].values
        for channel, value in (_half(values, half) if half else values).items():
            total[channel] = total.get(channel, 0.0) + w * value
    return total


def arkit_pose(rig: Rig, weights: Mapping[str, float] | np.ndarray) -> np.ndarray:
    """A pose (c,) float64 from ARKit weights: ``clip(d + sum_k w_k v_k)``.

    Parameters
    ----------
    rig : Rig
        Gives the channel order, defaults and ranges.
    weights : Mapping[str, float] or (52,) float64
        Apple or ICT names → weight in [0, 1] (MediaPipe's "_neutral" is ignored), or an array in
        ``ARKIT_NAMES`` order.

    Returns
    -------
    pose : (c,) float64 in the rig's channel order, each channel clipped into its range.
    """
    index = {name: j for j, name in enumerate(rig.channel_names)}
    out = np.array([c.default for c in rig.channels], dtype=np.float64)
    for channel, value in arkit_values(weights).items():
        if channel not in index:
            raise ArkitError(f"the ARKit table drives channel {channel!r}, which this rig does not have")
        out[index[channel]] += value
    return check_activations(rig, out, clip=True)
