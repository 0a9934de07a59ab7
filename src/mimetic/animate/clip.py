"""Keyframe clips: curves per channel, layers, B-spline displacement edits, JSON and CSV files.

A ``KeyframeClip`` is the editable form of an animation; ``KeyframeClip.sample(fps)`` bakes it
into the activation pivot (``mimetic.rig.activations.Clip``, (frames, c) float64). Times are in
seconds everywhere, so one clip samples at any frame rate (24, 30, 59.94 fps …).

Curves
------
A ``Curve`` is a tuple of ``Key`` sorted by time. A key's ``interpolation`` sets the segment that
*starts* at that key; before the first key and after the last the curve is constant:

- "step": hold the key's value until the next key;
- "linear": a straight line to the next key;
- "cubic": a Catmull–Rom cubic Hermite segment;
- "tcb": a Kochanek–Bartels (tension, continuity, bias) cubic Hermite segment.

Tangents belong to keys and are slopes in value per second. With ``s-`` and ``s+`` the chord
slopes of the intervals before and after key i (lengths ``h-`` and ``h+`` seconds) and
``w- = h- / (h- + h+)``, ``w+ = h+ / (h- + h+)``, key i leaves with ``m_out`` and arrives with
``m_in``::

    m_out = (1 - T) ((1 + C)(1 + B) w- s-  +  (1 - C)(1 - B) w+ s+)
    m_in  = (1 - T) ((1 - C)(1 + B) w- s-  +  (1 + C)(1 - B) w+ s+)

This is Kochanek & Bartels (1984) with their adjustment for unequal key spacing; for equal
spacing it is the textbook formula. T, C and B are used only by "tcb" keys; every other key has
T = C = B = 0, where both tangents reduce to the Catmull–Rom tangent
``(p[i+1] - p[i-1]) / (t[i+1] - t[i-1])``. So "tcb" with T = C = B = 0 *is* "cubic", a curve of
cubic keys is C1 in time at its interior keys even when keys are unevenly spaced, and it
reproduces a linear ramp exactly. At the first and last key the tangent is one-sided: the chord
slope of the single neighbouring interval, times ``1 - T`` (so a two-key cubic curve is a straight
line and tension 1 flattens the end). Continuity and bias have no effect on end keys.

Layers
------
A clip holds ``layers`` applied in order to every channel, starting from 0:

- "absolute": ``value = (1 - weight) * value + weight * curve(t)``;
- "additive": ``value = value + weight * curve(t)``.

A layer changes only the channels it has curves for. ``layers[0]`` is the *base* and is absolute;
``with_base`` swaps it (e.g. after the base is regenerated from speech or re-solved from capture)
and keeps every other layer.

Edits (seed-002 §4.1, motion displacement mapping)
--------------------------------------------------
``KeyframeClip.edit(channel, {time_s: value})`` makes the composed curve pass through new values
by adding a smooth displacement ``d(t)`` in an additive edit layer, so the detail of the curve
underneath survives and the edit survives a new base. ``d`` is a uniform cubic B-spline with knots
at integer multiples of ``knot_spacing_s`` (h). Its coefficients solve ``A c = delta`` (``delta`` the
discrepancy at each constraint) in the minimum-norm least-squares sense, over only the basis
functions that are non-zero at some constraint; all others are exactly 0. A constraint inside knot
interval ``[j h, (j + 1) h)`` therefore reaches exactly ``(j - 3) h … (j + 4) h`` (``(j - 3) h … (j + 3) h``
when it falls on a knot), and ``d`` is exactly 0 outside the union of those spans: the knot spacing
sets how far an edit reaches. The displacement is stored, not the constraints: after ``with_base``
the edit moves the new base by the same amount.

Files
-----
``save_clip``/``load_clip`` read and write JSON (``FORMAT``, ``VERSION``)::

    {"format": "mimetic-clip", "version": 1, "duration_s": 2.0, "channels": ["jaw_open"],
     "layers": [{"name": "base", "mode": "absolute", "weight": 1.0, "curves": {
         "jaw_open": {"keys": [[0.0, 0.0, "cubic", 0.0, 0.0, 0.0], [1.0, 0.3, "tcb", 0.5, 0.0, 0.0]]}}},
                {"name": "edit", "mode": "additive", "weight": 1.0, "curves": {
         "jaw_open": {"bspline": {"start_s": 0.25, "spacing_s": 0.25, "coefficients": [0.01, 0.02]}}}}]}

A key may also be written ``[t, v]`` (cubic) or ``[t, v, interpolation]``. ``save_csv``/``load_csv``
write and read sampled curves as ``time_s,channel,...`` rows. Every writer is atomic
(``mimetic.atomic.atomic_write``); every reader names the file, the line or the JSON path, and the
fix.
"""

from __future__ import annotations

import csv
import difflib
import io
import json
import logging
import math
import re
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path
from types import MappingProxyType
from typing import Any, Literal, get_args

import numpy as np

from mimetic.animate.expressions import Expression, ExpressionLibrary, compose_pose
from mimetic.atomic import atomic_write
from mimetic.errors import MimeticError, MimeticWarning
from mimetic.rig.activations import Clip, check_shape
from mimetic.rig.model import Channel, Rig

log = logging.getLogger(__name__)

Interpolation = Literal["step", "linear", "cubic", "tcb"]
LayerMode = Literal["absolute", "additive"]
INTERPOLATIONS: tuple[str, ...] = get_args(Interpolation)
LAYER_MODES: tuple[str, ...] = get_args(LayerMode)

FORMAT = "mimetic-clip"
VERSION = 1
DEFAULT_KNOT_SPACING_S = 0.25
"""Default edit reach: a constraint moves the curve at most 4 knots (1 s) either side."""

FIT_TOL = 1e-9
"""An edit whose constraints miss by more than this (relative to the largest change) warns."""

_STEP, _LINEAR = 0, 1
_CODES = {"step": _STEP, "linear": _LINEAR, "cubic": 2, "tcb": 3}
_TOP_KEYS = frozenset({"format", "version", "duration_s", "channels", "layers"})
_LAYER_KEYS = frozenset({"name", "mode", "weight", "curves"})
_BSPLINE_KEYS = frozenset({"start_s", "spacing_s", "coefficients"})


class ClipError(MimeticError, ValueError):
    """A malformed key, curve, layer, clip or clip file; the message names it and the fix."""


# --------------------------------------------------------------------------- small helpers


def _number(value: Any, where: str) -> float:
    """``value`` as a finite float; ``ClipError`` naming ``where`` otherwise (bools are refused)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ClipError(f"{where}={value!r} must be a number")
    number = float(value)
    if not math.isfinite(number):
        raise ClipError(f"{where}={number} must be finite")
    return number


def _positive(value: Any, where: str) -> float:
    number = _number(value, where)
    if number <= 0:
        raise ClipError(f"{where}={number:g} must be > 0")
    return number


def _times(times_s: Any) -> np.ndarray:
    """Query times as a float64 array of any shape; ``ClipError`` for non-finite or non-numeric times."""
    try:
        t = np.asarray(times_s, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ClipError(f"times_s cannot be read as float64 seconds: {error}") from None
    if not np.isfinite(t).all():
        raise ClipError(f"times_s must be finite; got {t[~np.isfinite(t)].ravel()[0]}")
    return t


def _unknown_channel(name: str, names: Sequence[str], owner: str) -> ClipError:
    close = difflib.get_close_matches(name, list(names), n=3)
    hint = f"did you mean {', '.join(close)}?" if close else f"{owner} has {', '.join(names[:6])}, …"
    return ClipError(f"unknown channel {name!r}; {hint}")


def _fmt(t: float) -> str:
    return f"{t:.6g}"


# --------------------------------------------------------------------------- keys and curves


@dataclass(frozen=True, slots=True)
class Key:
    """One key of a curve.

    Attributes
    ----------
    time_s : float
        When, in seconds (finite; may be negative or beyond the clip's duration).
    value : float
        The channel's value at ``time_s``, in the channel's unit.
    interpolation : "step" | "linear" | "cubic" | "tcb"
        How the segment that starts at this key reaches the next key.
    tension, continuity, bias : float
        Kochanek–Bartels parameters in [-1, 1], used only by "tcb" keys (0 for every other key).
        Tension 1 gives zero tangents; continuity ≠ 0 makes the incoming and outgoing tangents
        differ (a corner); bias > 0 tilts both tangents toward the incoming chord (overshoot),
        bias < 0 toward the outgoing one.
    """

    time_s: float
    value: float
    interpolation: Interpolation = "cubic"
    tension: float = 0.0
    continuity: float = 0.0
    bias: float = 0.0

    def __post_init__(self) -> None:
        time_s = _number(self.time_s, "key time_s")
        where = f"key at t={_fmt(time_s)} s"
        object.__setattr__(self, "time_s", time_s)
        object.__setattr__(self, "value", _number(self.value, f"{where}: value"))
        if self.interpolation not in INTERPOLATIONS:
            raise ClipError(
                f"{where}: unknown interpolation {self.interpolation!r}; "
                f"use one of {', '.join(INTERPOLATIONS)}"
            )
        for name in ("tension", "continuity", "bias"):
            number = _number(getattr(self, name), f"{where}: {name}")
            if not -1.0 <= number <= 1.0:
                raise ClipError(f"{where}: {name}={number:g} must be in [-1, 1]")
            if number != 0.0 and self.interpolation != "tcb":
                raise ClipError(
                    f"{where}: {name}={number:g} only applies to 'tcb' keys; "
                    f"set interpolation='tcb' or leave {name} at 0"
                )
            object.__setattr__(self, name, number + 0.0)  # -0.0 → 0.0


@dataclass(frozen=True)
class _Table:
    """A curve as arrays: key times/values (n,), interpolation codes (n,) and tangents (n,) in value/s."""

    times: np.ndarray
    values: np.ndarray
    codes: np.ndarray
    m_in: np.ndarray
    m_out: np.ndarray


def key_tangents(
    times_s: np.ndarray, values: np.ndarray, tcb: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Incoming and outgoing tangents (value per second) of keys, by the rule in the module docstring.

    Parameters
    ----------
    times_s : (n,) float64, strictly increasing
    values : (n,) float64
    tcb : (n, 3) float64 or None
        Tension, continuity, bias of each key; None (or zeros) gives Catmull–Rom tangents.

    Returns
    -------
    m_in, m_out : (n,) float64 each; zero for a single key.
    """
    n = len(times_s)
    tcb = np.zeros((n, 3)) if tcb is None else np.asarray(tcb, dtype=np.float64)
    T, C, B = tcb[:, 0], tcb[:, 1], tcb[:, 2]
    m_in = np.zeros(n)
    m_out = np.zeros(n)
    if n < 2:
        return m_in, m_out
    h = np.diff(times_s)  # (n-1,) interval lengths, s
    s = np.diff(values) / h  # (n-1,) chord slopes
    m_in[0] = m_out[0] = (1.0 - T[0]) * s[0]
    m_in[-1] = m_out[-1] = (1.0 - T[-1]) * s[-1]
    if n > 2:
        h_before, h_after = h[:-1], h[1:]
        w_before = h_before / (h_before + h_after)
        w_after = h_after / (h_before + h_after)
        before, after = w_before * s[:-1], w_after * s[1:]
        t, c, b = T[1:-1], C[1:-1], B[1:-1]
        m_out[1:-1] = (1.0 - t) * ((1.0 + c) * (1.0 + b) * before + (1.0 - c) * (1.0 - b) * after)
        m_in[1:-1] = (1.0 - t) * ((1.0 - c) * (1.0 + b) * before + (1.0 + c) * (1.0 - b) * after)
    return m_in, m_out


@dataclass(frozen=True)
class Curve:
    """One channel's keys, sorted by time with no two at the same time.

    ``evaluate(times_s)`` interpolates between keys (see the module docstring for the tangent rule)
    and holds the first/last key's value before/after them.
    """

    keys: tuple[Key, ...]

    def __post_init__(self) -> None:
        keys = tuple(self.keys)
        if not keys:
            raise ClipError("a curve needs at least one key")
        for i, key in enumerate(keys):
            if not isinstance(key, Key):
                raise TypeError(f"curve key {i} is a {type(key).__name__}; build it with Key(time_s, value)")
        for i in range(1, len(keys)):
            before, after = keys[i - 1].time_s, keys[i].time_s
            if after == before:
                raise ClipError(f"keys {i - 1} and {i} are both at t={_fmt(after)} s; keep one key per time")
            if after < before:
                raise ClipError(
                    f"key {i} at t={_fmt(after)} s comes before key {i - 1} at t={_fmt(before)} s; "
                    "sort keys by time (sorted(keys, key=lambda k: k.time_s))"
                )
        object.__setattr__(self, "keys", keys)

    @classmethod
    def from_arrays(cls, times_s: Any, values: Any, interpolation: Interpolation = "cubic") -> Curve:
        """A curve with one key per (time, value), all with ``interpolation``; times (n,) s, values (n,)."""
        t = np.asarray(times_s, dtype=np.float64).ravel()
        v = np.asarray(values, dtype=np.float64).ravel()
        if t.shape != v.shape:
            raise ClipError(f"times_s {t.shape} and values {v.shape} must have the same length")
        return cls(tuple(Key(ti, vi, interpolation) for ti, vi in zip(t.tolist(), v.tolist(), strict=True)))

    @cached_property
    def _table(self) -> _Table:
        times = np.array([k.time_s for k in self.keys])
        values = np.array([k.value for k in self.keys])
        codes = np.array([_CODES[k.interpolation] for k in self.keys], dtype=np.int64)
        tcb = np.array([(k.tension, k.continuity, k.bias) for k in self.keys]).reshape(-1, 3)
        m_in, m_out = key_tangents(times, values, tcb)
        for array in (times, values, codes, m_in, m_out):
            array.setflags(write=False)
        return _Table(times, values, codes, m_in, m_out)

    @property
    def times_s(self) -> np.ndarray:
        """Key times (n,) float64, seconds, read-only."""
        return self._table.times

    @property
    def values(self) -> np.ndarray:
        """Key values (n,) float64, read-only."""
        return self._table.values

    @property
    def tangents(self) -> tuple[np.ndarray, np.ndarray]:
        """``(m_in, m_out)``: each key's incoming and outgoing slope, (n,) float64 in value per second."""
        return self._table.m_in, self._table.m_out

    def evaluate(self, times_s: Any) -> np.ndarray:
        """The curve's values at ``times_s`` (any shape, seconds); float64 of the same shape."""
        t = _times(times_s)
        tab = self._table
        tk, p = tab.times, tab.values
        n = len(tk)
        if n == 1:
            return np.full(t.shape, p[0])
        i = np.clip(np.searchsorted(tk, t, side="right") - 1, 0, n - 2)  # segment index
        h = tk[i + 1] - tk[i]
        u = (t - tk[i]) / h  # in [0, 1) inside the keys
        p0, p1 = p[i], p[i + 1]
        u2 = u * u
        u3 = u2 * u
        hermite = (
            (2 * u3 - 3 * u2 + 1) * p0
            + (u3 - 2 * u2 + u) * h * tab.m_out[i]
            + (-2 * u3 + 3 * u2) * p1
            + (u3 - u2) * h * tab.m_in[i + 1]
        )
        code = tab.codes[i]
        out = np.where(code == _STEP, p0, np.where(code == _LINEAR, p0 + u * (p1 - p0), hermite))
        out = np.where(t < tk[0], p[0], out)
        return np.where(t >= tk[-1], p[-1], out)


# --------------------------------------------------------------------------- B-spline displacement


def _bspline_weights(f: np.ndarray) -> np.ndarray:
    """Uniform cubic B-spline weights (..., 4) of bases j-3 … j at fraction ``f`` in [0, 1) of interval j."""
    g = 1.0 - f
    f2 = f * f
    f3 = f2 * f
    return np.stack(
        [g * g * g / 6.0, (3 * f3 - 6 * f2 + 4) / 6.0, (-3 * f3 + 3 * f2 + 3 * f + 1) / 6.0, f3 / 6.0],
        axis=-1,
    )


@dataclass(frozen=True)
class BSplineEdit:
    """A displacement curve: a uniform cubic B-spline, used in additive edit layers.

    ``d(t) = sum_l coefficients[l] * N((t - start_s) / spacing_s - l)`` with ``N`` the cardinal
    cubic B-spline on [0, 4]. Basis l covers ``[start_s + l h, start_s + (l + 4) h]``, so ``d`` is
    exactly 0 outside ``support_s = (start_s, start_s + (len(coefficients) + 3) h)``.

    Attributes
    ----------
    start_s : float
        The first knot, seconds. ``fit_displacement`` puts knots at multiples of ``spacing_s``.
    spacing_s : float
        Knot spacing h > 0, seconds.
    coefficients : tuple of float
        One per basis function, in the channel's unit.
    """

    start_s: float
    spacing_s: float
    coefficients: tuple[float, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "start_s", _number(self.start_s, "bspline start_s"))
        object.__setattr__(self, "spacing_s", _positive(self.spacing_s, "bspline spacing_s"))
        raw = self.coefficients
        if isinstance(raw, np.ndarray):
            raw = raw.ravel().tolist()
        if isinstance(raw, (str, bytes)) or not isinstance(raw, Sequence):
            raise ClipError(f"bspline coefficients must be a list of numbers; got {raw!r}")
        coefficients = tuple(_number(c, f"bspline coefficient {i}") for i, c in enumerate(raw))
        if not coefficients:
            raise ClipError("a bspline edit needs at least one coefficient")
        object.__setattr__(self, "coefficients", coefficients)

    @property
    def support_s(self) -> tuple[float, float]:
        """(first, last) time in seconds; the displacement is exactly 0 at and outside them."""
        return self.start_s, self.start_s + (len(self.coefficients) + 3) * self.spacing_s

    def evaluate(self, times_s: Any) -> np.ndarray:
        """The displacement at ``times_s`` (any shape, seconds); float64 of the same shape."""
        t = _times(times_s)
        lo, hi = self.support_s
        n = len(self.coefficients)
        padded = np.concatenate([np.zeros(3), self.coefficients, np.zeros(3)])  # basis l → index l + 3
        u = (t - self.start_s) / self.spacing_s
        j = np.clip(np.floor(u), 0, n + 2).astype(np.int64)  # knot interval, basis j-3 … j active
        w = _bspline_weights(u - j)  # (..., 4)
        rows = j[..., None] + np.arange(4)  # padded index of bases j-3 … j
        d = np.sum(w * padded[rows], axis=-1)
        return np.where((t > lo) & (t < hi), d, 0.0)

    def __add__(self, other: BSplineEdit) -> BSplineEdit:
        """The sum of two displacements on the same knot grid (same spacing, knots aligned)."""
        if not isinstance(other, BSplineEdit):
            return NotImplemented
        h = self.spacing_s
        if not math.isclose(other.spacing_s, h, rel_tol=1e-12):
            raise ClipError(
                f"cannot merge B-spline edits with knot spacings {h:g} s and {other.spacing_s:g} s; "
                "edit with the same knot_spacing_s, or put the new edit in another layer (layer='edit2')"
            )
        offset = (other.start_s - self.start_s) / h
        if abs(offset - round(offset)) > 1e-6:
            raise ClipError(
                f"cannot merge B-spline edits whose knots are not aligned (starts {self.start_s:g} s and "
                f"{other.start_s:g} s, spacing {h:g} s); put the new edit in another layer"
            )
        first = min(0, round(offset))
        last = max(len(self.coefficients), round(offset) + len(other.coefficients))
        total = np.zeros(last - first)
        total[-first : -first + len(self.coefficients)] += self.coefficients
        start = round(offset) - first
        total[start : start + len(other.coefficients)] += other.coefficients
        return BSplineEdit(self.start_s + first * h, h, tuple(total.tolist()))


def fit_displacement(
    times_s: Any, deltas: Any, knot_spacing_s: float, *, regularization: float = 0.0
) -> BSplineEdit:
    """A cubic B-spline displacement ``d`` with ``d(times_s[k]) ≈ deltas[k]`` that vanishes away from them.

    Knots lie at integer multiples of ``h = knot_spacing_s``. Only basis functions that are non-zero
    at some constraint get a coefficient; they solve

        minimise ||A c - deltas||² + regularization ||c||²,   A[k, l] = N(times_s[k] / h - l)

    with the minimum-norm solution when several fit equally well (``numpy.linalg.lstsq``). With
    ``regularization`` = 0 the constraints are met to rounding whenever they can be (e.g. no more
    than four constraints within one knot interval); otherwise the least-squares fit is returned and
    a ``MimeticWarning`` names the largest miss. A positive ``regularization`` trades accuracy for
    smaller coefficients (useful when two constraints close in time ask for different values).

    Parameters
    ----------
    times_s : (k,) float64
        Distinct constraint times, seconds.
    deltas : (k,) float64
        Wanted displacement at each time, in the channel's unit.
    knot_spacing_s : float
        Knot spacing h > 0, seconds. A constraint reaches at most 4 h either side.
    regularization : float
        Ridge weight >= 0 on the coefficients.

    Returns
    -------
    BSplineEdit, exactly 0 outside the knot spans the constraints touch.
    """
    t = _times(times_s).ravel()
    d = np.asarray(deltas, dtype=np.float64).ravel()
    if t.shape != d.shape or t.size == 0:
        raise ClipError(
            f"need one delta per constraint time and at least one; got {t.size} times, {d.size} deltas"
        )
    if not np.isfinite(d).all():
        raise ClipError("constraint values must be finite")
    if len(np.unique(t)) != len(t):
        raise ClipError("constraint times must be distinct; give one value per time")
    h = _positive(knot_spacing_s, "knot_spacing_s")
    ridge = _number(regularization, "regularization")
    if ridge < 0:
        raise ClipError(f"regularization={ridge:g} must be >= 0")
    u = t / h
    on_knot = np.abs(u - np.round(u)) <= 1e-9
    u = np.where(on_knot, np.round(u), u)
    j = np.floor(u).astype(np.int64)
    w = _bspline_weights(u - j)  # (k, 4), bases j-3 … j; on a knot the last weight is exactly 0
    first = int((j - 3).min())
    A = np.zeros((len(t), int(j.max()) - first + 1))  # (k, L) basis values at the constraints
    for r in range(4):
        A[np.arange(len(t)), j - 3 + r - first] = w[:, r]
    active = np.flatnonzero(A.any(axis=0))
    A_active = A[:, active]
    if ridge > 0:
        A_active = np.vstack([A_active, math.sqrt(ridge) * np.eye(len(active))])
        rhs = np.concatenate([d, np.zeros(len(active))])
    else:
        rhs = d
    solution = np.linalg.lstsq(A_active, rhs, rcond=None)[0]
    coefficients = np.zeros(A.shape[1])
    coefficients[active] = solution
    lo, hi = active[0], active[-1] + 1  # trim inactive ends so the support is exactly the touched spans
    miss = np.abs(A @ coefficients - d)
    scale = max(1.0, float(np.abs(d).max()))
    if ridge == 0 and miss.max() > FIT_TOL * scale:
        k = int(np.argmax(miss))
        warnings.warn(
            f"the edit misses the constraint at t={_fmt(t[k])} s by {miss[k]:.3g}: too many constraints "
            f"within one knot interval of {h:g} s; use a smaller knot_spacing_s or fewer constraints",
            MimeticWarning,
            stacklevel=2,
        )
    log.debug(
        "fit_displacement: %d constraints, %d coefficients, max miss %.3g", len(t), len(active), miss.max()
    )
    return BSplineEdit((first + lo) * h, h, tuple(coefficients[lo:hi].tolist()))


# --------------------------------------------------------------------------- layers and clips


@dataclass(frozen=True)
class Layer:
    """A named set of curves applied on top of the layers before it (see the module docstring).

    Attributes
    ----------
    name : str
        Unique within a clip, e.g. "base", "edit".
    curves : Mapping[str, Curve | BSplineEdit]
        Channel name → curve (keyframes) or displacement (edit layers).
    mode : "absolute" | "additive"
        Absolute layers blend toward their curves by ``weight``; additive layers add
        ``weight * curve``.
    weight : float
        Finite; 1 applies the layer fully, 0 mutes it.
    """

    name: str
    curves: Mapping[str, Curve | BSplineEdit]
    mode: LayerMode = "absolute"
    weight: float = 1.0

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ClipError(f"layer name {self.name!r} must be a non-empty string")
        if self.mode not in LAYER_MODES:
            raise ClipError(f"layer {self.name!r}: unknown mode {self.mode!r}; use 'absolute' or 'additive'")
        object.__setattr__(self, "weight", _number(self.weight, f"layer {self.name!r}: weight"))
        if not isinstance(self.curves, Mapping):
            raise TypeError(f"layer {self.name!r}: curves must be a mapping channel → Curve")
        for channel, curve in self.curves.items():
            if not isinstance(channel, str) or not channel:
                raise ClipError(f"layer {self.name!r}: channel name {channel!r} must be a non-empty string")
            if not isinstance(curve, (Curve, BSplineEdit)):
                raise TypeError(
                    f"layer {self.name!r}: curve of {channel!r} is a {type(curve).__name__}; "
                    "use a Curve or a BSplineEdit"
                )
        object.__setattr__(self, "curves", MappingProxyType(dict(self.curves)))


@dataclass(frozen=True)
class KeyframeClip:
    """An editable animation: layers of per-channel curves over ``duration_s`` seconds.

    Attributes
    ----------
    channels : tuple of str
        The channels the clip animates, in output order. Every curve's channel is one of them; a
        channel with no curve stays 0.
    layers : tuple of Layer
        Applied in order; ``layers[0]`` is the base and must be absolute.
    duration_s : float or None
        Length in seconds (>= 0); None takes the time of the last key of any layer (at least 0).
    """

    channels: tuple[str, ...]
    layers: tuple[Layer, ...]
    duration_s: float | None = None

    def __post_init__(self) -> None:
        if isinstance(self.channels, str):
            raise TypeError("channels must be a sequence of names, not one string")
        channels = tuple(self.channels)
        seen: set[str] = set()
        for name in channels:
            if not isinstance(name, str) or not name:
                raise ClipError(f"channel name {name!r} must be a non-empty string")
            if name in seen:
                raise ClipError(f"channel {name!r} appears twice in the clip's channels; list it once")
            seen.add(name)
        layers = tuple(self.layers)
        if not layers:
            raise ClipError("a clip needs at least one layer (the base)")
        for layer in layers:
            if not isinstance(layer, Layer):
                raise TypeError(f"clip layers must be Layer objects; got {type(layer).__name__}")
        names = [layer.name for layer in layers]
        for layer in layers:
            if names.count(layer.name) > 1:
                raise ClipError(f"two layers are named {layer.name!r}; give each layer its own name")
            for channel in layer.curves:
                if channel not in seen:
                    error = _unknown_channel(channel, channels, "the clip")
                    raise ClipError(f"layer {layer.name!r}: {error} Add it to the clip's channels.")
        if layers[0].mode != "absolute":
            raise ClipError(
                f"layers[0] ({layers[0].name!r}) is the base and must be 'absolute'; "
                "put an absolute layer first"
            )
        if self.duration_s is None:
            ends = [
                c.keys[-1].time_s for layer in layers for c in layer.curves.values() if isinstance(c, Curve)
            ]
            duration = max([0.0, *ends])
        else:
            duration = _number(self.duration_s, "clip duration_s")
            if duration < 0:
                raise ClipError(f"clip duration_s={duration:g} must be >= 0")
        object.__setattr__(self, "channels", channels)
        object.__setattr__(self, "layers", layers)
        object.__setattr__(self, "duration_s", duration)

    @property
    def base(self) -> Layer:
        """The first layer, which ``with_base`` replaces."""
        return self.layers[0]

    def layer(self, name: str) -> Layer:
        """The layer called ``name``."""
        for layer in self.layers:
            if layer.name == name:
                return layer
        raise ClipError(f"no layer {name!r}; the clip has {', '.join(x.name for x in self.layers)}")

    def channel_values(self, channel: str, times_s: Any) -> np.ndarray:
        """Composed value of one channel at ``times_s`` (any shape, seconds), all layers, unclipped."""
        if channel not in self.channels:
            raise _unknown_channel(channel, self.channels, "the clip")
        t = _times(times_s)
        value = np.zeros(t.shape)
        for layer in self.layers:
            curve = layer.curves.get(channel)
            if curve is None:
                continue
            v = curve.evaluate(t)
            if layer.mode == "additive":
                value = value + layer.weight * v
            else:
                value = (1.0 - layer.weight) * value + layer.weight * v
        return value

    def evaluate(self, times_s: Any) -> np.ndarray:
        """Composed values (t, c) float64 at times (t,) seconds, columns in ``channels`` order, unclipped."""
        t = _times(times_s).ravel()
        out = np.zeros((len(t), len(self.channels)))
        for j, channel in enumerate(self.channels):
            out[:, j] = self.channel_values(channel, t)
        return out

    def frame_times(self, fps: float) -> np.ndarray:
        """Frame times (frames,) float64 in seconds: ``i / fps`` for ``0 <= i / fps <= duration_s``."""
        fps = _positive(fps, "fps")
        n = math.floor(self.duration_s * fps + 1e-9) + 1
        return np.arange(n) / fps

    def sample(
        self,
        fps: float,
        *,
        channels: Rig | Sequence[Channel] | Sequence[str] | None = None,
        defaults: Mapping[str, float] | None = None,
    ) -> Clip:
        """Bake the clip into the activation pivot at ``fps``.

        Frames are at ``i / fps`` for ``0 <= i / fps <= duration_s``: a 2 s clip at 24 fps has 49
        frames, the last at exactly 2 s. Times never accumulate, so any two frame rates agree at the
        times they share.

        Parameters
        ----------
        fps : float
            Frames per second, > 0 (e.g. 24, 30, 60000 / 1001).
        channels : Rig, sequence of Channel, sequence of str, or None
            None: the clip's channels, values as composed. Names: those columns in that order;
            names the clip lacks take ``defaults`` (or 0); clip channels not named are dropped.
            A rig or Channel objects: the rig's channel order; channels the clip lacks take their
            ``default``; every value is clipped into its channel's [minimum, maximum]; a clip
            channel the rig does not have raises ``ClipError``.
        defaults : Mapping[str, float] or None
            Values for requested names the clip lacks (names only; overrides ``Channel.default``).

        Returns
        -------
        Clip with values (frames, len(channels)) float64.
        """
        times = self.frame_times(fps)
        values = self.evaluate(times)  # (frames, c)
        if channels is None:
            return Clip(self.channels, values, float(fps))
        if isinstance(channels, Rig):
            channels = channels.channels
        if isinstance(channels, str):
            raise TypeError("channels must be a sequence of names or Channel objects, not one string")
        channels = tuple(channels)
        defaults = dict(defaults or {})
        index = {name: j for j, name in enumerate(self.channels)}
        if all(isinstance(c, Channel) for c in channels):
            names = tuple(c.name for c in channels)
            for name in self.channels:
                if name not in names:
                    close = difflib.get_close_matches(name, names, n=3)
                    hint = f" (did you mean {', '.join(close)}?)" if close else ""
                    raise ClipError(
                        f"clip channel {name!r} is not a channel of the rig{hint}; rename it or drop it "
                        "from the clip, or sample with channel names instead of the rig"
                    )
            lo = np.array([c.minimum for c in channels])
            hi = np.array([c.maximum for c in channels])
            fill = [defaults.get(c.name, c.default) for c in channels]
        elif all(isinstance(c, str) for c in channels):
            names, lo, hi = channels, None, None
            fill = [defaults.get(name, 0.0) for name in names]
        else:
            raise TypeError("channels must be all names or all Channel objects")
        out = np.empty((len(times), len(names)))
        for j, name in enumerate(names):
            out[:, j] = values[:, index[name]] if name in index else _number(fill[j], f"default of {name!r}")
        if lo is not None:
            clipped = np.clip(out, lo, hi)
            log.debug(
                "sample: clipped %d of %d values into channel ranges", int((clipped != out).sum()), out.size
            )
            out = clipped
        return Clip(names, out, float(fps))

    def edit(
        self,
        channel: str,
        constraints: Mapping[float, float] | Iterable[tuple[float, float]],
        *,
        knot_spacing_s: float = DEFAULT_KNOT_SPACING_S,
        layer: str = "edit",
        regularization: float = 0.0,
    ) -> KeyframeClip:
        """A new clip whose ``channel`` passes through ``constraints`` ({time_s: value}).

        The change is a B-spline displacement (``fit_displacement``) stored in the additive layer
        ``layer``: created at the end if missing, otherwise added to the displacement it already
        holds for ``channel`` (same ``knot_spacing_s`` required). Every other layer is unchanged.
        Each edit is fitted to the curve as it is now, earlier edits included; where the new edit
        reaches an earlier constraint it moves it, so repeat earlier constraints to keep them.

        Parameters
        ----------
        channel : str
            One of ``channels``.
        constraints : Mapping[float, float] or iterable of (time_s, value)
            Wanted values at distinct times, in the channel's unit.
        knot_spacing_s : float
            Knot spacing h > 0, seconds: each constraint changes the curve only within 3–4 h of it.
        layer : str
            Name of the edit layer (additive, with a weight that does not mute it).
        regularization : float
            See ``fit_displacement``.
        """
        if channel not in self.channels:
            raise _unknown_channel(channel, self.channels, "the clip")
        pairs = list(constraints.items() if isinstance(constraints, Mapping) else constraints)
        if not pairs:
            raise ClipError(f"edit of {channel!r} has no constraints; give {{time_s: value}}")
        times = np.array([_number(t, f"edit of {channel!r}: constraint time") for t, _ in pairs])
        wanted = np.array([_number(v, f"edit of {channel!r}: value at t={_fmt(t)} s") for t, v in pairs])
        position = next((i for i, x in enumerate(self.layers) if x.name == layer), None)
        if position is None:
            target = Layer(layer, {}, "additive", 1.0)
            layers = (*self.layers, target)
            position = len(layers) - 1
        else:
            target = self.layers[position]
            layers = self.layers
            if target.mode != "additive":
                raise ClipError(
                    f"layer {layer!r} is absolute; edits go in an additive layer, e.g. layer='edit'"
                )
        # the final value moves by gain * d: the edit layer's weight, times (1 - w) of later absolute layers
        gain = target.weight
        for later in layers[position + 1 :]:
            if later.mode == "absolute" and channel in later.curves:
                gain *= 1.0 - later.weight
        if gain == 0.0:
            raise ClipError(
                f"layer {layer!r} cannot change {channel!r}: its weight is 0 or a later absolute layer "
                "overrides it; edit in another layer or change the weights"
            )
        current = self.channel_values(channel, times)
        displacement = fit_displacement(
            times, (wanted - current) / gain, knot_spacing_s, regularization=regularization
        )
        existing = target.curves.get(channel)
        if isinstance(existing, Curve):
            raise ClipError(
                f"layer {layer!r} holds keyframes for {channel!r}; "
                "put the edit in another layer (e.g. layer='edit')"
            )
        if existing is not None:
            displacement = existing + displacement
        curves = {**target.curves, channel: displacement}
        new_layers = list(layers)
        new_layers[position] = replace(target, curves=curves)
        log.info("edited %r in layer %r with %d constraints", channel, layer, len(pairs))
        return replace(self, layers=tuple(new_layers))

    def with_base(self, base: Layer, *, duration_s: float | None = None) -> KeyframeClip:
        """This clip with ``base`` in place of ``layers[0]``; every other layer (the edits) is kept.

        Channels of ``base`` the clip lacks are appended to ``channels``. ``duration_s`` None keeps
        the current duration.
        """
        extra = tuple(c for c in base.curves if c not in self.channels)
        return KeyframeClip(
            (*self.channels, *extra),
            (base, *self.layers[1:]),
            self.duration_s if duration_s is None else duration_s,
        )

    def with_layer(self, layer: Layer) -> KeyframeClip:
        """This clip with ``layer`` replacing the layer of the same name, or appended if there is none."""
        layers = list(self.layers)
        names = [x.name for x in layers]
        if layer.name in names:
            layers[names.index(layer.name)] = layer
        else:
            layers.append(layer)
        return replace(self, layers=tuple(layers))


# --------------------------------------------------------------------------- building clips


def _channel_source(
    channels: Rig | Sequence[Channel] | Sequence[str],
) -> tuple[tuple[str, ...], np.ndarray]:
    """(names, defaults (c,)) from a rig, Channel objects or plain names (default 0)."""
    if isinstance(channels, Rig):
        channels = channels.channels
    if isinstance(channels, str):
        raise TypeError("channels must be a sequence of names or Channel objects, not one string")
    channels = tuple(channels)
    if all(isinstance(c, Channel) for c in channels):
        return tuple(c.name for c in channels), np.array([c.default for c in channels], dtype=np.float64)
    if all(isinstance(c, str) for c in channels):
        return channels, np.zeros(len(channels))
    raise TypeError("channels must be a Rig, or all names, or all Channel objects")


def from_poses(
    poses: Sequence[tuple[float, Any]],
    channels: Rig | Sequence[Channel] | Sequence[str],
    *,
    interpolation: Interpolation = "cubic",
    name: str = "base",
    duration_s: float | None = None,
) -> KeyframeClip:
    """A clip that passes through whole poses at given times: one key per pose in every channel.

    Parameters
    ----------
    poses : sequence of (time_s, pose)
        Strictly increasing times in seconds. A pose is a (c,) vector in ``channels`` order or a
        mapping {channel: value}; channels a mapping leaves out take their default (0 for names).
    channels : Rig, sequence of Channel, or sequence of str
        The clip's channels. Values are not range-checked here; ``sample(fps, channels=rig)``
        clips them (cubic interpolation may overshoot between poses).
    interpolation : "step" | "linear" | "cubic" | "tcb"
        Of every key.
    name : str
        Name of the single (base) layer.
    duration_s : float or None
        None: the last pose's time.

    Example: ``from_poses([(0, rest), (0.5, expression_pose(rig, "joy")), (1.0, rest)], rig)``.
    """
    names, defaults = _channel_source(channels)
    index = {n: j for j, n in enumerate(names)}
    times: list[float] = []
    rows: list[np.ndarray] = []
    for i, item in enumerate(poses):
        if not isinstance(item, (tuple, list)) or len(item) != 2:
            raise ClipError(f"pose {i} must be a (time_s, pose) pair; got {item!r}")
        time_s = _number(item[0], f"pose {i}: time_s")
        if times and time_s <= times[-1]:
            raise ClipError(
                f"pose {i} at t={_fmt(time_s)} s is not after pose {i - 1} at t={_fmt(times[-1])} s; "
                "give poses in increasing time order with no repeated times"
            )
        if isinstance(item[1], Mapping):
            row = defaults.copy()
            for channel, value in item[1].items():
                if channel not in index:
                    raise ClipError(f"pose {i}: {_unknown_channel(channel, names, 'the clip')}")
                row[index[channel]] = _number(value, f"pose {i}: {channel}")
        else:
            try:
                row = np.array(item[1], dtype=np.float64)
            except (TypeError, ValueError) as error:
                raise ClipError(f"pose {i} cannot be read as float64 numbers: {error}") from None
            if row.shape != (len(names),):
                raise ClipError(
                    f"pose {i} has shape {row.shape}; expected ({len(names)},) in the clip's channel order"
                )
            if not np.isfinite(row).all():
                bad = int(np.flatnonzero(~np.isfinite(row))[0])
                raise ClipError(f"pose {i}: channel {names[bad]!r} is not finite ({row[bad]})")
        times.append(time_s)
        rows.append(row)
    if not rows:
        raise ClipError("from_poses needs at least one (time_s, pose)")
    values = np.stack(rows)  # (poses, c)
    curves = {n: Curve.from_arrays(times, values[:, j], interpolation) for j, n in enumerate(names)}
    return KeyframeClip(names, (Layer(name, curves, "absolute"),), duration_s)


def from_expressions(
    rig: Rig,
    sequence: Sequence[tuple[float, str | Expression | Mapping[str, float] | None]],
    *,
    interpolation: Interpolation = "cubic",
    library: ExpressionLibrary | None = None,
) -> KeyframeClip:
    """A clip through named expressions, e.g. ``[(0, None), (0.5, "joy"), (1, "surprise"), (1.5, None)]``.

    Each entry is ``(time_s, expression)`` where expression is None or "rest" (the rig's defaults),
    an expression name or ``Expression`` (its pose at weight 1), or a mapping {name: weight} blended
    by ``compose_pose``. See ``from_poses`` for the rest.
    """
    poses = []
    for time_s, item in sequence:
        if item is None or (item == "rest" and (library is None or "rest" not in library)):
            weights: Any = ()
        elif isinstance(item, Mapping):
            weights = item
        else:
            weights = [(item, 1.0)]
        poses.append((time_s, compose_pose(rig, weights, library=library)))
    return from_poses(poses, rig, interpolation=interpolation)


def _simplify(times: np.ndarray, values: np.ndarray, tolerance: float | None) -> np.ndarray:
    """Indices of samples to keep so linear interpolation between them is within ``tolerance`` of all.

    Ramer–Douglas–Peucker with vertical error; None keeps every sample.
    """
    n = len(times)
    if tolerance is None or n <= 2:
        return np.arange(n)
    keep = np.zeros(n, dtype=bool)
    keep[0] = keep[-1] = True
    stack = [(0, n - 1)]
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        u = (times[a + 1 : b] - times[a]) / (times[b] - times[a])
        error = np.abs(values[a + 1 : b] - (values[a] + u * (values[b] - values[a])))
        k = int(np.argmax(error))
        if error[k] > tolerance:
            m = a + 1 + k
            keep[m] = True
            stack += [(a, m), (m, b)]
    return np.flatnonzero(keep)


def _from_samples(
    names: Sequence[str], times: np.ndarray, values: np.ndarray, tolerance: float | None, name: str
) -> KeyframeClip:
    if tolerance is not None:
        tolerance = _number(tolerance, "tolerance")
        if tolerance < 0:
            raise ClipError(f"tolerance={tolerance:g} must be >= 0 (or None to keep every sample)")
    curves = {}
    for j, channel in enumerate(names):
        keep = _simplify(times, values[:, j], tolerance)
        curves[channel] = Curve.from_arrays(times[keep], values[keep, j], "linear")
    return KeyframeClip(tuple(names), (Layer(name, curves, "absolute"),), max(0.0, float(times[-1])))


def from_clip(clip: Clip, *, tolerance: float | None = None, name: str = "base") -> KeyframeClip:
    """A keyframe clip from a baked one: a linear key at every frame ``i / clip.fps``.

    With ``tolerance`` (>= 0, the channel's unit) keys are dropped while linear interpolation of the
    rest stays within ``tolerance`` of every frame (Ramer–Douglas–Peucker). ``duration_s`` is the
    time of the last frame, ``(frames - 1) / fps``, so ``sample(clip.fps)`` gives back the same frames
    (``Clip.duration_s`` counts one frame more: ``frames / fps``).
    """
    values = check_shape(clip.channels, clip.values, ndim=2)  # names the frame of a NaN
    if len(values) == 0:
        raise ClipError("the clip has no frames")
    times = np.arange(len(values)) / clip.fps
    return _from_samples(clip.channels, times, values, tolerance, name)


# --------------------------------------------------------------------------- key specs (CLI)


_CHANNEL_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_.\-]*$")


def parse_key_spec(spec: str) -> tuple[str, float, float]:
    """``"jaw_open@1.25=0.3"`` → ``("jaw_open", 1.25, 0.3)``: channel, time in seconds, value.

    The time may end in "s" (``jaw_open@1.25s=0.3``); spaces around ``@`` and ``=`` are allowed.
    """
    usage = f"key {spec!r} must look like CHANNEL@TIME_S=VALUE, e.g. jaw_open@1.25=0.3"
    if (
        not isinstance(spec, str)
        or spec.count("@") != 1
        or spec.count("=") != 1
        or spec.index("@") > spec.index("=")
    ):
        raise ClipError(usage)
    channel, rest = spec.split("@")
    time_text, value_text = rest.split("=")
    channel, time_text, value_text = channel.strip(), time_text.strip(), value_text.strip()
    if not _CHANNEL_NAME.match(channel):
        raise ClipError(f"{usage}; {channel!r} is not a channel name")
    time_text = time_text.removesuffix("s").strip()
    numbers = []
    for text, what in ((time_text, "time"), (value_text, "value")):
        try:
            number = float(text)
        except ValueError:
            raise ClipError(f"{usage}; the {what} {text!r} is not a number") from None
        if not math.isfinite(number):
            raise ClipError(f"{usage}; the {what} {text!r} must be finite")
        numbers.append(number)
    return channel, numbers[0], numbers[1]


# --------------------------------------------------------------------------- JSON files


def _curve_document(curve: Curve | BSplineEdit) -> dict[str, Any]:
    if isinstance(curve, BSplineEdit):
        return {
            "bspline": {
                "start_s": curve.start_s,
                "spacing_s": curve.spacing_s,
                "coefficients": list(curve.coefficients),
            }
        }
    return {
        "keys": [[k.time_s, k.value, k.interpolation, k.tension, k.continuity, k.bias] for k in curve.keys]
    }


def _document(clip: KeyframeClip) -> dict[str, Any]:
    """The JSON document of ``clip`` (plain dicts, lists, floats and strings)."""
    return {
        "format": FORMAT,
        "version": VERSION,
        "duration_s": clip.duration_s,
        "channels": list(clip.channels),
        "layers": [
            {
                "name": layer.name,
                "mode": layer.mode,
                "weight": layer.weight,
                "curves": {channel: _curve_document(curve) for channel, curve in layer.curves.items()},
            }
            for layer in clip.layers
        ],
    }


def _dumps(document: dict[str, Any]) -> str:
    """Indented JSON with every innermost list (a key, the coefficients, the channels) on one line."""
    text = json.dumps(document, indent=1, allow_nan=False, ensure_ascii=False)

    def one_line(match: re.Match[str]) -> str:
        # a raw newline never occurs inside a JSON string, so these only touch whitespace between tokens
        flat = re.sub(r",\n\s*", ", ", match.group(0))
        return re.sub(r"\n\s*", "", flat)

    return re.sub(r"\[[^\[\]{}]*\]", one_line, text) + "\n"


def save_clip(clip: KeyframeClip, path: str | Path) -> Path:
    """Write ``clip`` as a JSON clip file (``FORMAT`` version ``VERSION``), atomically; returns the path.

    Floats are written with full precision, so ``load_clip`` gives back an equal clip.
    """
    if not isinstance(clip, KeyframeClip):
        raise TypeError(
            f"save_clip writes a KeyframeClip; got {type(clip).__name__} (use save_csv for a Clip)"
        )
    path = Path(path)
    with atomic_write(path, "w") as handle:
        handle.write(_dumps(_document(clip)))
    log.info("wrote clip %s (%d layers, %d channels)", path, len(clip.layers), len(clip.channels))
    return path


def _check_keys(data: Mapping[str, Any], allowed: frozenset[str], where: str) -> None:
    extra = sorted(set(data) - allowed)
    if extra:
        raise ClipError(
            f"{where}: unknown field {extra[0]!r}; allowed fields are {', '.join(sorted(allowed))}"
        )


def _parse_curve(data: Any, where: str) -> Curve | BSplineEdit:
    if not isinstance(data, dict) or len(data) != 1 or next(iter(data)) not in ("keys", "bspline"):
        raise ClipError(f'{where}: a curve must be {{"keys": [[t, v, ...], ...]}} or {{"bspline": {{...}}}}')
    if "bspline" in data:
        spline = data["bspline"]
        if not isinstance(spline, dict):
            raise ClipError(f"{where}.bspline must be an object with start_s, spacing_s, coefficients")
        _check_keys(spline, _BSPLINE_KEYS, f"{where}.bspline")
        missing = sorted(_BSPLINE_KEYS - set(spline))
        if missing:
            raise ClipError(f"{where}.bspline: missing field {missing[0]!r}")
        if not isinstance(spline["coefficients"], list):
            raise ClipError(f"{where}.bspline.coefficients must be a list of numbers")
        try:
            return BSplineEdit(spline["start_s"], spline["spacing_s"], tuple(spline["coefficients"]))
        except ClipError as error:
            raise ClipError(f"{where}.bspline: {error}") from None
    rows = data["keys"]
    if not isinstance(rows, list) or not rows:
        raise ClipError(f"{where}.keys must be a non-empty list of [time_s, value, interpolation, T, C, B]")
    keys = []
    for i, row in enumerate(rows):
        if not isinstance(row, list) or len(row) not in (2, 3, 6):
            raise ClipError(
                f"{where}.keys[{i}] = {row!r}: a key is [time_s, value], [time_s, value, interpolation] or "
                "[time_s, value, interpolation, tension, continuity, bias]"
            )
        try:
            keys.append(Key(*row))
        except ClipError as error:
            raise ClipError(f"{where}.keys[{i}]: {error}") from None
    try:
        return Curve(tuple(keys))
    except ClipError as error:
        raise ClipError(f"{where}.keys: {error}") from None


def _parse_clip(data: Any, source: str) -> KeyframeClip:
    if not isinstance(data, dict):
        raise ClipError(f"{source}: a clip file holds a JSON object; got {type(data).__name__}")
    if data.get("format") != FORMAT:
        raise ClipError(f"{source}: not a mimetic clip (format={data.get('format')!r}; expected {FORMAT!r})")
    version = data.get("version")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise ClipError(f"{source}: version={version!r} must be a positive integer")
    if version > VERSION:
        raise ClipError(
            f"{source}: written by a newer mimetic (clip version {version}; this one reads up to {VERSION}). "
            "Upgrade mimetic."
        )
    _check_keys(data, _TOP_KEYS, source)
    layers_data = data.get("layers")
    if not isinstance(layers_data, list) or not layers_data:
        raise ClipError(f"{source}: 'layers' must be a non-empty list of layers")
    layers = []
    order: list[str] = []
    for i, item in enumerate(layers_data):
        where = f"{source}: layers[{i}]"
        if not isinstance(item, dict):
            raise ClipError(f"{where} must be an object with name, mode, weight, curves")
        _check_keys(item, _LAYER_KEYS, where)
        curves_data = item.get("curves", {})
        if not isinstance(curves_data, dict):
            raise ClipError(f"{where}.curves must be an object channel → curve")
        curves = {}
        for channel, curve in curves_data.items():
            curves[channel] = _parse_curve(curve, f"{where}.curves[{channel!r}]")
            if channel not in order:
                order.append(channel)
        try:
            layers.append(
                Layer(item.get("name"), curves, item.get("mode", "absolute"), item.get("weight", 1.0))
            )
        except ClipError as error:
            raise ClipError(f"{where}: {error}") from None
    channels = data.get("channels", order)
    if not isinstance(channels, list):
        raise ClipError(f"{source}: 'channels' must be a list of channel names")
    try:
        return KeyframeClip(tuple(channels), tuple(layers), data.get("duration_s"))
    except ClipError as error:
        raise ClipError(f"{source}: {error}") from None


def _read_text(path: Path) -> str:
    try:
        return path.read_text(encoding="utf-8-sig")
    except FileNotFoundError:
        raise ClipError(f"{path}: no such file") from None
    except IsADirectoryError:
        raise ClipError(f"{path} is a folder; give a clip file") from None
    except UnicodeDecodeError as error:
        raise ClipError(f"{path.name}: not UTF-8 text (byte {error.start}); is this a clip file?") from None


def load_clip(path: str | Path) -> KeyframeClip:
    """Read a JSON clip file written by ``save_clip`` (or by hand; see the module docstring).

    Raises ``ClipError`` naming the file and the line (syntax) or JSON path (content) of a problem:
    invalid JSON, NaN/Infinity, unsorted or repeated key times, unknown interpolation, unknown
    fields, or a newer format version.
    """
    path = Path(path)
    text = _read_text(path)

    def reject_constant(name: str) -> float:
        at = re.search(rf"(?<![\w\"]){re.escape(name)}(?![\w\"])", text)
        line = text.count("\n", 0, at.start()) + 1 if at else "?"
        raise ClipError(f"{path.name} line {line}: {name} is not allowed; every number must be finite")

    try:
        data = json.loads(text, parse_constant=reject_constant)
    except json.JSONDecodeError as error:
        raise ClipError(
            f"{path.name} line {error.lineno} column {error.colno}: not valid JSON ({error.msg})"
        ) from None
    return _parse_clip(data, path.name)


# --------------------------------------------------------------------------- CSV files


def save_csv(
    clip: KeyframeClip | Clip,
    path: str | Path,
    *,
    fps: float | None = None,
    digits: int | None = None,
) -> Path:
    """Write sampled curves as CSV, atomically: a ``time_s,<channel>,...`` header, one row per frame.

    Parameters
    ----------
    clip : KeyframeClip or Clip
        A keyframe clip is sampled at ``fps`` (required); a baked ``Clip`` is written at its own fps.
    path : path-like
    fps : float or None
        Frame rate for a keyframe clip; frame times are ``i / fps`` seconds.
    digits : int or None
        Significant digits of the values (1–17); None writes each value exactly (shortest repr).
        Times are always written exactly.
    """
    if isinstance(clip, KeyframeClip):
        if fps is None:
            raise ClipError("save_csv needs fps= to sample a keyframe clip, e.g. fps=30")
        sampled = clip.sample(fps)
    elif isinstance(clip, Clip):
        if fps is not None and fps != clip.fps:
            raise ClipError(f"the clip is already sampled at {clip.fps:g} fps; leave fps out or resample it")
        sampled = clip
    else:
        raise TypeError(f"save_csv writes a KeyframeClip or Clip; got {type(clip).__name__}")
    if digits is not None and (
        isinstance(digits, bool) or not isinstance(digits, int) or not 1 <= digits <= 17
    ):
        raise ClipError(f"digits={digits!r} must be an integer in 1…17, or None for exact values")
    values = check_shape(sampled.channels, sampled.values, ndim=2)  # names frame and channel of a NaN
    times = (np.arange(len(values)) / sampled.fps).tolist()

    def text(value: float) -> str:
        return repr(value) if digits is None else f"{value:.{digits}g}"

    path = Path(path)
    with atomic_write(path, "w") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(["time_s", *sampled.channels])
        for time_s, row in zip(times, values.tolist(), strict=True):
            writer.writerow([repr(time_s), *(text(v) for v in row)])
    log.info("wrote %s (%d frames at %g fps)", path, len(values), sampled.fps)
    return path


def load_csv(path: str | Path, *, tolerance: float | None = None, name: str = "base") -> KeyframeClip:
    """Read sampled curves (``time_s,<channel>,...``) as a clip of linear keys, one per row.

    Rows may be at any times (any fps, even uneven), strictly increasing. ``tolerance`` drops keys
    as in ``from_clip``. ``duration_s`` is the last row's time. Raises ``ClipError`` naming the file,
    line and column of a bad header, a short row, a non-number, NaN, or a time out of order.
    """
    path = Path(path)
    reader = csv.reader(io.StringIO(_read_text(path)))
    header: list[str] | None = None
    times: list[float] = []
    rows: list[list[float]] = []
    for fields in reader:
        line = reader.line_num
        if not any(f.strip() for f in fields):
            continue
        if header is None:
            header = [f.strip() for f in fields]
            if header[0] != "time_s":
                raise ClipError(
                    f"{path.name} line {line}: the first column must be 'time_s'; got {header[0]!r}. "
                    "The header is time_s,<channel>,<channel>,…"
                )
            if len(header) < 2 or not all(header[1:]):
                raise ClipError(
                    f"{path.name} line {line}: the header needs at least one non-empty channel name"
                )
            repeated = [c for c in header[1:] if header[1:].count(c) > 1]
            if repeated:
                raise ClipError(
                    f"{path.name} line {line}: channel {repeated[0]!r} appears twice in the header"
                )
            continue
        if len(fields) != len(header):
            raise ClipError(
                f"{path.name} line {line}: expected {len(header)} values ({', '.join(header[:3])}, …); "
                f"got {len(fields)}"
            )
        numbers = []
        for column, field in zip(header, fields, strict=True):
            try:
                number = float(field)
            except ValueError:
                raise ClipError(
                    f"{path.name} line {line}, column {column!r}: {field!r} is not a number"
                ) from None
            if not math.isfinite(number):
                raise ClipError(f"{path.name} line {line}, column {column!r}: {field.strip()} must be finite")
            numbers.append(number)
        if times and numbers[0] <= times[-1]:
            raise ClipError(
                f"{path.name} line {line}: time_s {numbers[0]:g} is not after the previous row's "
                f"{times[-1]:g}; rows must be in increasing time with no repeats"
            )
        times.append(numbers[0])
        rows.append(numbers[1:])
    if header is None:
        raise ClipError(f"{path.name}: empty file; expected a time_s,<channel>,… header and rows")
    if not rows:
        raise ClipError(f"{path.name}: no rows after the header")
    return _from_samples(header[1:], np.array(times), np.array(rows), tolerance, name)


__all__ = [
    "DEFAULT_KNOT_SPACING_S",
    "FORMAT",
    "INTERPOLATIONS",
    "LAYER_MODES",
    "VERSION",
    "BSplineEdit",
    "ClipError",
    "Curve",
    "Interpolation",
    "Key",
    "KeyframeClip",
    "Layer",
    "LayerMode",
    "fit_displacement",
    "from_clip",
    "from_expressions",
    "from_poses",
    "key_tangents",
    "load_clip",
    "load_csv",
    "parse_key_spec",
    "save_clip",
    "save_csv",
]
