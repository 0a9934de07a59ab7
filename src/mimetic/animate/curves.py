"""Keyframe curves and B-spline displacement edits: the maths under ``mimetic.animate.keyframes``.

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
"""

from __future__ import annotations

import difflib
import logging
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Any, Literal, get_args

import numpy as np

from mimetic.errors import MimeticError, MimeticWarning

log = logging.getLogger(__name__)

Interpolation = Literal["step", "linear", "cubic", "tcb"]
INTERPOLATIONS: tuple[str, ...] = get_args(Interpolation)

DEFAULT_KNOT_SPACING_S = 0.25
"""Default edit reach: a constraint moves the curve at most 4 knots (1 s) either side."""

FIT_TOL = 1e-9
"""An edit whose constraints miss by more than this (relative to the largest change) warns."""

_STEP, _LINEAR = 0, 1
_CODES = {"step": _STEP, "linear": _LINEAR, "cubic": 2, "tcb": 3}


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
