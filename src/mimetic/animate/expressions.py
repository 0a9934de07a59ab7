"""The expression library: named activation sets, blending and intensity.

An expression is a stored set of channel values (thesis §6.2, the Expressions tab): the channels
it names take those values, every other channel stays at its default (the rest pose). The
built-in library (``data/expressions.json``) holds the six universal expressions (joy, sadness,
anger, fear, surprise, disgust) and more, each built from the muscles of its FACS action units.

Blending rule (``blend``): with ``d`` the rig's default pose and ``e_i`` the pose of expression
i (its values over the defaults), the result is

    p = clip(d + intensity * sum_i w_i (e_i - d), channel minimum, channel maximum)

that is, a weighted sum of each expression's offsets from rest, scaled by ``intensity`` and only
then clipped into every channel's range. Before clipping it is linear in the weights; weights
and intensity are non-negative. Every default is 0 in the recipe's rigs, so ``p`` is simply the
clipped weighted sum of the expressions' values.

A library file is JSON::

    {"format": "mimetic-expressions", "version": 1,
     "expressions": {"smirk": {"description": "one-sided smile",
                               "values": {"zygomatic_major_L": 0.8, "risorius_L": 0.3}}}}

``facs`` (a string such as "AU6+12") is optional documentation. ``load_library`` checks every
name, number, channel and range and names the expression and channel of any problem.
"""

from __future__ import annotations

import difflib
import json
import math
import re
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from pathlib import Path
from types import MappingProxyType

import numpy as np

from mimetic.errors import ExpressionError
from mimetic.rig.activations import check_activations, pose
from mimetic.rig.model import Channel, Rig

FORMAT = "mimetic-expressions"
VERSION = 1
NAME_PATTERN = re.compile(r"^[A-Za-z][A-Za-z0-9_\-]*$")
ENTRY_KEYS = frozenset({"description", "facs", "values"})


@dataclass(frozen=True)
class Expression:
    """A named set of channel values; channels it does not name stay at their defaults.

    Attributes
    ----------
    name : str
        Letters, digits, ``_`` and ``-``, starting with a letter (e.g. "joyous_surprise").
    description : str
        What the face does.
    values : Mapping[str, float]
        Channel name → value in the channel's unit (muscles in [0, 1], jaw and eyelids in radians).
    facs : str
        The FACS action units it is built from, e.g. "AU6+12" (documentation only).
    """

    name: str
    description: str
    values: Mapping[str, float]
    facs: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(
            self, "values", MappingProxyType({str(k): float(v) for k, v in self.values.items()})
        )


@dataclass(frozen=True)
class ExpressionLibrary:
    """Expressions by name, in file order; ``library["joy"]``, ``library.names``, ``"joy" in library``."""

    expressions: Mapping[str, Expression]
    source: str = "the built-in library"
    _order: tuple[str, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "expressions", MappingProxyType(dict(self.expressions)))
        object.__setattr__(self, "_order", tuple(self.expressions))

    @property
    def names(self) -> tuple[str, ...]:
        return self._order

    def __getitem__(self, name: str) -> Expression:
        if name not in self.expressions:
            close = difflib.get_close_matches(name, self._order, n=3, cutoff=0.5)
            hint = f"did you mean {', '.join(close)}?" if close else f"known: {', '.join(self._order)}"
            raise ExpressionError(f"unknown expression {name!r} in {self.source}; {hint}")
        return self.expressions[name]

    def __contains__(self, name: object) -> bool:
        return name in self.expressions

    def __iter__(self) -> Iterator[str]:
        return iter(self._order)

    def __len__(self) -> int:
        return len(self._order)


# ---- loading and validation


@cache
def reference_channels() -> tuple[Channel, ...]:
    """The channels (names and ranges) of the recipe's rig, from a 1,500-vertex reference head.

    Built once per process (about 0.2 s; without the anatomy, which the channels do not need).
    """
    from mimetic.head.model import make_head
    from mimetic.rig.recipe import build_rig

    return build_rig(make_head(resolution=1_500), anatomy=False).channels


def _channels(source: Rig | Sequence[Channel] | None) -> tuple[Channel, ...]:
    if source is None:
        return reference_channels()
    return tuple(source.channels) if isinstance(source, Rig) else tuple(source)


def _parse(data: object, source: str) -> dict[str, Expression]:
    if not isinstance(data, dict):
        raise ExpressionError(f"{source}: the top level must be a JSON object with an 'expressions' object")
    if data.get("format", FORMAT) != FORMAT:
        raise ExpressionError(f"{source}: 'format' is {data['format']!r}; expected {FORMAT!r}")
    version = data.get("version", VERSION)
    if not isinstance(version, int) or version > VERSION:
        raise ExpressionError(
            f"{source}: format version {version!r} is newer than this mimetic reads ({VERSION}); "
            "upgrade mimetic"
        )
    entries = data.get("expressions")
    if not isinstance(entries, dict) or not entries:
        raise ExpressionError(f"{source}: 'expressions' must be a non-empty object of name → expression")
    out = {}
    for name, entry in entries.items():
        where = f"{source}: expression {name!r}"
        if not NAME_PATTERN.match(name):
            raise ExpressionError(
                f"{where}: names use letters, digits, '_' and '-' and start with a letter (e.g. 'big_smile')"
            )
        if not isinstance(entry, dict):
            raise ExpressionError(f"{where}: expected an object with 'values' (and 'description')")
        extra = sorted(set(entry) - ENTRY_KEYS)
        if extra:
            raise ExpressionError(
                f"{where}: unknown key(s) {', '.join(map(repr, extra))}; use {sorted(ENTRY_KEYS)}"
            )
        values = entry.get("values")
        if not isinstance(values, dict):
            raise ExpressionError(f"{where}: 'values' must be an object of channel → number")
        for key in ("description", "facs"):
            if not isinstance(entry.get(key, ""), str):
                raise ExpressionError(f"{where}: {key!r} must be a string")
        for channel, value in values.items():
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ExpressionError(f"{where}: channel {channel!r} = {value!r} is not a finite number")
        out[name] = Expression(name, entry.get("description", ""), values, entry.get("facs", ""))
    return out


def check_library(library: ExpressionLibrary, channels: Rig | Sequence[Channel] | None = None) -> None:
    """Raise ExpressionError unless every expression names known channels with values in range.

    ``channels`` defaults to the recipe's channels (``reference_channels``).
    """
    known = {c.name: c for c in _channels(channels)}
    for expression in library.expressions.values():
        where = f"{library.source}: expression {expression.name!r}"
        for name, value in expression.values.items():
            if name not in known:
                close = difflib.get_close_matches(name, list(known), n=3)
                hint = (
                    f"did you mean {', '.join(close)}?"
                    if close
                    else "see `mimetic info RIG.mrig` for channels"
                )
                raise ExpressionError(f"{where}: unknown channel {name!r}; {hint}")
            c = known[name]
            if not c.minimum - 1e-9 <= value <= c.maximum + 1e-9:
                raise ExpressionError(
                    f"{where}: channel {name!r} = {value:g} is outside its range "
                    f"[{c.minimum:g}, {c.maximum:g}] {c.unit}"
                )


@cache
def _builtin() -> ExpressionLibrary:
    text = resources.files("mimetic.animate").joinpath("data/expressions.json").read_text("utf-8")
    return ExpressionLibrary(_parse(json.loads(text), "the built-in library"))


def load_library(
    path: str | Path | None = None, *, channels: Rig | Sequence[Channel] | None = None
) -> ExpressionLibrary:
    """The built-in expression library (``path`` None) or one read from a JSON file.

    A file is checked fully: its structure, every name and number, and every channel against
    ``channels`` (a rig or its channels; default the recipe's channels) and its range. Problems
    raise ``ExpressionError`` naming the file, expression and channel.
    """
    if path is None:
        library = _builtin()
        if channels is not None:
            check_library(library, channels)
        return library
    path = Path(path)
    try:
        text = path.read_text("utf-8")
    except FileNotFoundError:
        raise ExpressionError(f"expression library {str(path)!r} does not exist") from None
    except (OSError, UnicodeDecodeError) as error:
        raise ExpressionError(f"cannot read expression library {str(path)!r}: {error}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise ExpressionError(f"{path.name}: not valid JSON ({error})") from None
    library = ExpressionLibrary(_parse(data, path.name), path.name)
    check_library(library, channels)
    return library


# ---- posing


def _resolve(item: str | Expression, library: ExpressionLibrary | None) -> Expression:
    if isinstance(item, Expression):
        return item
    return (library if library is not None else load_library())[item]


def blend(
    rig: Rig,
    weights: Sequence[tuple[str | Expression, float]] | Mapping[str, float],
    *,
    intensity: float = 1.0,
    library: ExpressionLibrary | None = None,
) -> np.ndarray:
    """A pose (c,) float64 blending expressions: ``clip(d + intensity * sum_i w_i (e_i - d))``.

    Parameters
    ----------
    rig : Rig
        Gives the channel order, defaults ``d`` and ranges.
    weights : sequence of (name or Expression, weight), or Mapping name → weight
        E.g. ``[("joy", 0.7), ("surprise", 0.5)]``; weights are finite and >= 0. A name may repeat.
    intensity : float
        >= 0, scales the whole blend (1 = as stored).
    library : ExpressionLibrary, optional
        Where names are looked up (default: the built-in library).

    Returns
    -------
    pose : (c,) float64, each channel clipped into [minimum, maximum].
    """
    if not (math.isfinite(intensity) and intensity >= 0):
        raise ExpressionError(f"intensity {intensity!r} must be a finite number >= 0")
    items = list(weights.items()) if isinstance(weights, Mapping) else list(weights)
    index = {name: j for j, name in enumerate(rig.channel_names)}
    default = np.array([c.default for c in rig.channels], dtype=np.float64)
    offset = np.zeros_like(default)
    for item, weight in items:
        expression = _resolve(item, library)
        weight = float(weight)
        if not (math.isfinite(weight) and weight >= 0):
            raise ExpressionError(
                f"expression {expression.name!r}: weight {weight!r} must be a finite number >= 0"
            )
        for name, value in expression.values.items():
            if name not in index:
                close = difflib.get_close_matches(name, list(index), n=3)
                hint = f"; did you mean {', '.join(close)}?" if close else ""
                raise ExpressionError(
                    f"expression {expression.name!r} sets channel {name!r}, "
                    f"which this rig does not have{hint}"
                )
            j = index[name]
            offset[j] += weight * (value - default[j])
    return check_activations(rig, default + intensity * offset, clip=True)


def expression_pose(
    rig: Rig, expression: str | Expression, weight: float = 1.0, *, library: ExpressionLibrary | None = None
) -> np.ndarray:
    """The pose (c,) of one expression at ``weight`` (``blend(rig, [(expression, weight)])``)."""
    return blend(rig, [(expression, weight)], library=library)


def compose_pose(
    rig: Rig,
    expressions: Sequence[tuple[str | Expression, float]] | Mapping[str, float] = (),
    values: Mapping[str, float] | None = None,
    *,
    intensity: float = 1.0,
    library: ExpressionLibrary | None = None,
) -> np.ndarray:
    """A pose (c,) float64: a blend of ``expressions`` (see ``blend``), then channel ``values`` set exactly.

    ``values`` override the blend channel by channel; unlike the blend they are not clipped, so
    an unknown channel or a value outside its range raises ``ActivationError``.
    """
    out = blend(rig, expressions, intensity=intensity, library=library)
    if values:
        exact = pose(rig, values)  # validates names and ranges
        for name in values:
            j = rig.channel_index(name)
            out[j] = exact[j]
    return out
