"""Apple ARKit's 52 blend shapes on the muscle rig: weights → activations, the ARKit-52 bake, and back.

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

**Bake** (``arkit_shapes``): the 52 shapes as vertex deltas of *any* rigged head, each the
engine's deformation under the activation set that realises it, minus the rest pose. Four
kinds (``STATUS``):

* exact: ``deform(v_k) - rest``;
* split (``SPLIT``): the rig drives both sides with one channel (one gaze pitch for both eyes,
  the midline procerus and mentalis), so the pose of such a shape alone moves both sides by
  half. The bake keeps this side's half of the symmetric pair's motion,
  ``s_L(x) * (deform(v_k + v_pair) - rest)``, with ``s_L`` a smooth step across the midline
  (``s_L + s_R = 1``). So the baked pair adds up to the symmetric motion and each half is
  one-sided, as artists split symmetric shapes. ``eyeLookOutLeft`` pairs with
  ``eyeLookInRight`` (the eyes cannot diverge, but both can look left);
* approximate (``APPROXIMATE``): the nearest motion the rig has (the lips cannot roll or flare);
* unsupported (``UNSUPPORTED``): ``tongueOut`` (no tongue channel) and ``cheekPuff`` (no
  inflation) get a stand-in posture so that all 52 targets exist.

**Reverse map** (``arkit_weights``): the ARKit weights ``w`` in [0, 1] that best reproduce a
pose's displacement ``d`` with the baked shapes ``S``, on the vertices that at least one shape
moves (the face, lids, eyeballs and the lower teeth; the rest of the head carries no ARKit
information)::

    min_w  |S w - d|^2 + sum_k RIDGE_REL |S_k|^2 w_k^2    subject to 0 <= w <= 1

The small ridge only breaks ties: ``jawLeft`` and ``jawRight`` move along one line in opposite
directions (as do eyeLookIn/Out, Up/Down of one eye), so without it the pair (0.6, 0) and
(1, 0.4) would fit equally; with it the sparser answer wins. Unsupported shapes are not fitted
(their weights are 0): their stand-ins are made of other shapes' muscles. The whole-head
rotation channels are set to 0 first, as ARKit reports head pose separately.
"""

from __future__ import annotations

import difflib
import json
import logging
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from importlib import resources
from types import MappingProxyType

import numpy as np
import scipy.linalg
from scipy.optimize import lsq_linear

from mimetic.engines import Engine, make_engine
from mimetic.engines.bake import RIGID
from mimetic.engines.basis import Basis, evaluate_basis
from mimetic.errors import MimeticError
from mimetic.rig.activations import check_activations, check_shape
from mimetic.rig.model import Rig

log = logging.getLogger(__name__)

FORMAT = "mimetic-arkit"
VERSION = 1
STATUSES = ("exact", "split", "approximate", "unsupported")
SPLIT_BLEND_REL = 0.02
"""Half-width of the midline blend of split shapes, as a fraction of the mesh's width (x extent)."""
RIDGE_REL = 1e-8
"""Tie-breaking ridge of the reverse map, relative to each shape's squared norm."""
MOVING_REL = 1e-6
"""A vertex belongs to the fit region when some shape moves it by more than this fraction of the
largest shape displacement."""
CHUNK_FRAMES = 128
"""Frames whose displacements ``arkit_weights`` holds at once (bounds its memory on long clips)."""
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


def shape_values(name: str) -> dict[str, float]:
    """Channel values of one shape (or ICT half) at weight 1."""
    apple, half = resolve_name(name)
    values = arkit_table()[apple].values
    return _half(values, half) if half else dict(values)


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


# ---- the bake


def side_weights(vertices: np.ndarray, side: str) -> np.ndarray:
    """Share (n,) of each vertex in one side's half of a split shape; ``side_weights(v, "L") +
    side_weights(v, "R") == 1``. A smooth step across the midline (the middle of the x extent)
    over ``2 * SPLIT_BLEND_REL`` of the width."""
    x = np.asarray(vertices, dtype=np.float64)[:, 0]
    lo, hi = float(x.min()), float(x.max())
    half = max(SPLIT_BLEND_REL * (hi - lo), 1e-12)
    t = np.clip((x - 0.5 * (lo + hi) + half) / (2 * half), 0.0, 1.0)
    left = t * t * (3 - 2 * t)
    return left if side == "L" else 1.0 - left


def _pose_vector(channels: Sequence[str], values: Mapping[str, float], base: np.ndarray) -> np.ndarray:
    index = {name: j for j, name in enumerate(channels)}
    out = base.copy()
    for channel, value in values.items():
        if channel not in index:
            raise ArkitError(f"the ARKit table drives channel {channel!r}, which this rig does not have")
        out[index[channel]] += value
    return out


def _bake(
    channels: Sequence[str],
    base: np.ndarray,
    deform: Callable[[np.ndarray], np.ndarray],
    rest: np.ndarray,
) -> dict[str, np.ndarray]:
    """The 52 Apple-named deltas (n, 3) from a deform function over pose vectors (c,)."""
    table = arkit_table()
    out: dict[str, np.ndarray] = {}
    sides = {s: side_weights(rest, s)[:, None] for s in ("L", "R")}
    for name, shape in table.items():
        values = dict(shape.values)
        if shape.status == "split":
            for channel, value in table[shape.pair].values.items():
                values[channel] = values.get(channel, 0.0) + value
        delta = deform(_pose_vector(channels, values, base)) - rest
        if shape.status == "split":
            delta *= sides[shape.side]
        out[name] = delta
    return out


def _source(
    source: Rig | Engine | Basis, engine: str
) -> tuple[Sequence[str], np.ndarray, Callable, np.ndarray]:
    """(channels, base pose, deform(pose) -> (n, 3), rest (n, 3)) of a rig, engine or basis."""
    if isinstance(source, Basis):
        base = np.zeros(source.n_channels)
        return source.channels, base, lambda a: evaluate_basis(source, a), source.neutral
    if isinstance(source, Rig):
        source = make_engine(source, engine)
    rig = source.rig
    base = np.array([c.default for c in rig.channels], dtype=np.float64)

    def deform(a: np.ndarray) -> np.ndarray:
        return source.deform(check_activations(rig, a, clip=True))

    return rig.channel_names, base, deform, deform(base)


def arkit_shapes(
    source: Rig | Engine | Basis, *, engine: str = "wire", naming: str = "apple"
) -> dict[str, np.ndarray]:
    """The ARKit-52 bake: each shape's vertex deltas from the muscle rig.

    Parameters
    ----------
    source : Rig, Engine or Basis
        A rig (an engine named ``engine`` is made for it), a prepared engine, or a baked basis
        (shapes evaluated linearly, with its correctives).
    naming : "apple" | "ict"
        Apple's 52 names, or ICT-FaceKit's (``eyeBlink_L``, ``browInnerUp_L``/``_R`` halves,
        ``cheekPuff_L``/``_R`` halves: 54 entries with ``tongueOut``).

    Returns
    -------
    shapes : dict[str, (n, 3) float64]
        Deltas from the rest pose in rig units, in ``ARKIT_NAMES`` order (each C-contiguous).
        Every shape exists; see ``STATUS`` for how faithful each is.
    """
    if naming not in ("apple", "ict"):
        raise ArkitError(f"naming {naming!r} must be 'apple' or 'ict'")
    channels, base, deform, rest = _source(source, engine)
    shapes = _bake(channels, base, deform, rest)
    if naming == "apple":
        return shapes
    out = {}
    for name, delta in shapes.items():
        if arkit_table()[name].halves:
            for s in ("L", "R"):
                out[f"{name}_{s}"] = delta * side_weights(rest, s)[:, None]
        else:
            out[ict_name(name)] = delta
    return out


# ---- the reverse map


@dataclass(frozen=True, eq=False)
class ArkitFit:
    """A prepared reverse map: ARKit weights from vertex displacements (see the module docstring).

    Attributes
    ----------
    fitted : tuple of str
        The Apple names solved for, in ``ARKIT_NAMES`` order; the others read 0.
    vertices : (k,) int64
        The vertices the fit compares (those some fitted shape moves).
    projection : (m, 3k) float64
        ``S^T`` restricted to ``vertices``: shape k's deltas, flattened.
    factor : (m, m) float64
        Lower Cholesky factor L of ``S^T S + ridge``.
    n_vertices : int
        The vertex count of the shapes (and of the displacements ``solve`` takes).
    """

    fitted: tuple[str, ...]
    vertices: np.ndarray
    projection: np.ndarray
    factor: np.ndarray
    n_vertices: int

    def solve(self, displacements: np.ndarray) -> np.ndarray:
        """Weights (52,) or (f, 52) in [0, 1], ARKIT_NAMES order, for displacements (n, 3) or (f, n, 3)."""
        d = np.asarray(displacements, dtype=np.float64)
        if d.ndim not in (2, 3) or d.shape[-2:] != (self.n_vertices, 3):
            raise ArkitError(
                f"displacements must have shape ({self.n_vertices}, 3) or (frames, {self.n_vertices}, 3); "
                f"got {d.shape}"
            )
        frames = d.reshape(-1, self.n_vertices, 3)[:, self.vertices].reshape(len(d) if d.ndim == 3 else 1, -1)
        b = frames @ self.projection.T  # (f, m): S^T d
        rhs = scipy.linalg.solve_triangular(self.factor, b.T, lower=True).T  # (f, m): L^-1 S^T d
        upper = self.factor.T
        index = [ARKIT_NAMES.index(n) for n in self.fitted]
        out = np.zeros((len(frames), len(ARKIT_NAMES)))
        for f, r in enumerate(rhs):
            out[f, index] = np.clip(lsq_linear(upper, r, bounds=(0.0, 1.0), method="bvls").x, 0.0, 1.0)
        return out[0] if d.ndim == 2 else out


def prepare_arkit_fit(
    shapes: Mapping[str, np.ndarray],
    *,
    vertices: np.ndarray | None = None,
    exclude: Sequence[str] = tuple(UNSUPPORTED),
) -> ArkitFit:
    """Prepare the reverse map for baked shapes (``arkit_shapes``'s output, Apple names).

    ``vertices`` (default: every vertex some fitted shape moves) restricts the comparison;
    ``exclude`` names shapes not to fit (default: the unsupported stand-ins).
    """
    missing = [n for n in ARKIT_NAMES if n not in shapes]
    if missing:
        raise ArkitError(f"the shapes lack {', '.join(missing[:4])}{', …' if len(missing) > 4 else ''}")
    fitted = [n for n in ARKIT_NAMES if n not in set(exclude)]
    try:
        stack = np.array([np.asarray(shapes[n], dtype=np.float64) for n in fitted])  # (m, n, 3)
    except ValueError:
        raise ArkitError("the shapes must all have the same shape (n, 3)") from None
    if stack.ndim != 3 or stack.shape[2] != 3:
        raise ArkitError(f"each shape must have shape (n, 3); got {stack.shape[1:]}")
    n = stack.shape[1]
    motion = np.linalg.norm(stack, axis=2)  # (m, n)
    if vertices is None:
        largest = motion.max(axis=0)
        vertices = np.nonzero(largest > MOVING_REL * max(float(largest.max()), 1e-300))[0]
    vertices = np.asarray(vertices, dtype=np.int64)
    moves = motion[:, vertices].max(axis=1) > 0  # a shape that moves nothing here cannot be fitted
    fitted = [name for name, m in zip(fitted, moves, strict=True) if m]
    projection = stack[moves][:, vertices].reshape(len(fitted), -1)  # (m, 3k)
    gram = projection @ projection.T
    gram[np.diag_indices_from(gram)] *= 1.0 + RIDGE_REL
    factor = np.linalg.cholesky(gram)
    log.debug("ARKit fit: %d shapes on %d of %d vertices", len(fitted), len(vertices), n)
    return ArkitFit(tuple(fitted), vertices, projection, factor, n)


def arkit_weights(
    source: Basis | Engine | Rig,
    activations: np.ndarray,
    *,
    shapes: Mapping[str, np.ndarray] | None = None,
    engine: str = "wire",
) -> np.ndarray:
    """ARKit weights (52,) or (f, 52) that best reproduce poses (bounded least squares).

    Parameters
    ----------
    source : Basis, Engine or Rig
        Turns activations into displacements: a basis (fast, for clips), an engine or a rig (an
        engine named ``engine`` is made).
    activations : (c,) or (f, c) float64
        Poses in the source's channel order; the head rotation channels are ignored.
    shapes : Mapping[str, (n, 3)], optional
        The ARKit shapes to fit with (default: ``arkit_shapes(source)``, so the shapes and the
        displacements come from the same model).

    Returns
    -------
    weights : (52,) or (f, 52) float64 in [0, 1], ``ARKIT_NAMES`` order; unsupported shapes read 0.
    """
    channels, base, deform, rest = _source(source, engine)
    a = check_shape(channels, activations)
    poses = np.atleast_2d(a).copy()
    rigid = [j for j, name in enumerate(channels) if name in RIGID]
    poses[:, rigid] = base[rigid]
    if shapes is None:
        shapes = _bake(channels, base, deform, rest)
    fit = prepare_arkit_fit(shapes)
    out = np.zeros((len(poses), len(ARKIT_NAMES)))
    for start in range(0, len(poses), CHUNK_FRAMES):
        chunk = poses[start : start + CHUNK_FRAMES]
        if isinstance(source, Basis):
            displacement = evaluate_basis(source, chunk) - rest  # (f, n, 3)
        else:
            displacement = np.array([deform(p) - rest for p in chunk])
        out[start : start + len(chunk)] = fit.solve(displacement)
    return out[0] if a.ndim == 1 else out
