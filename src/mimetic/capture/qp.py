"""Bounded quadratic programmes on the normal equations, one per frame, compiled (numba, in parallel).

Each frame t solves ::

    minimise ½ xᵀ H_t x − g_tᵀ x     subject to   lower ≤ x ≤ upper

with H_t symmetric positive definite (c, c) — the Gram matrix of a basis on the markers seen in the
frame, plus damping — by the primal active-set method of ``solve.box_qp`` (the box form of Lawson
and Hanson's NNLS). It is exact: once the active set is right, the free variables solve their
normal equations, so the answer matches ``scipy.optimize.lsq_linear`` to rounding.

Frames are split into ``CHUNK``-frame runs solved in parallel; within a run each frame starts from
the previous frame's answer, whose active set is usually right already (captured motion is
smooth), so most frames cost one Cholesky factorisation of their free block.
"""

from __future__ import annotations

import numba
import numpy as np

CHUNK = 64
"""Consecutive frames per parallel task (each warm-starts from its predecessor)."""

BULK_EXCHANGES = 6
"""Exchanges, at the start of a frame, that move every variable that wants to move at once (primal-dual
active set, fast but not monotone); then one at a time, stepping to the first bound (monotone, so it
finishes). Either way a frame ends only where the KKT conditions hold."""

KKT_TOLERANCE = 1e-12
"""A bound variable is freed when its gradient exceeds this fraction of the problem's scale."""


@numba.njit(cache=True, error_model="numpy")
def _free_solve(H, g, x, free, count, A, b):
    """Solve H_FF z = g_F − H_FB x_B for the ``count`` free variables (indices ``free[:count]``) into
    ``b[:count]``, factoring H_FF in ``A`` (scratch, (c, c)) by Cholesky; False if it is not positive
    definite."""
    c = len(g)
    for p in range(count):
        i = free[p]
        total = g[i]
        for j in range(c):
            total -= H[i, j] * x[j]
        for q in range(count):
            A[p, q] = H[i, free[q]]
            total += H[i, free[q]] * x[free[q]]
        b[p] = total
    for p in range(count):  # A = L Lᵀ, L in the lower triangle
        for q in range(p + 1):
            total = A[p, q]
            for k in range(q):
                total -= A[p, k] * A[q, k]
            if p == q:
                if total <= 0.0:
                    return False
                A[p, p] = np.sqrt(total)
            else:
                A[p, q] = total / A[q, q]
    for p in range(count):  # forward: L y = b
        total = b[p]
        for q in range(p):
            total -= A[p, q] * b[q]
        b[p] = total / A[p, p]
    for p in range(count - 1, -1, -1):  # backward: Lᵀ z = y
        total = b[p]
        for q in range(p + 1, count):
            total -= A[q, p] * b[q]
        b[p] = total / A[p, p]
    return True


@numba.njit(cache=True, error_model="numpy")
def _box_qp(H, g, lower, upper, x):
    """Solve one frame in place, starting from ``x`` (clipped into the box); True when it finished."""
    c = len(g)
    is_free = np.empty(c, np.bool_)
    scale = 0.0
    for i in range(c):
        x[i] = min(max(x[i], lower[i]), upper[i])
        is_free[i] = lower[i] < x[i] < upper[i]
        scale = max(scale, abs(g[i]))
    biggest_h, biggest_x = 0.0, 0.0
    for i in range(c):
        biggest_x = max(biggest_x, abs(x[i]))
        for j in range(c):
            biggest_h = max(biggest_h, abs(H[i, j]))
    tolerance = KKT_TOLERANCE * max(scale + biggest_h * biggest_x, 1e-300)
    free = np.empty(c, np.int64)
    A = np.empty((c, c))
    z = np.empty(c)
    just_freed = -1
    for iteration in range(BULK_EXCHANGES + 3 * c + 10):
        bulk = iteration < BULK_EXCHANGES
        count = 0
        for i in range(c):
            if is_free[i]:
                free[count] = i
                count += 1
        if count:
            if not _free_solve(H, g, x, free, count, A, z):
                return False
            if bulk:
                outside = False
                for p in range(count):
                    i = free[p]
                    if z[p] <= lower[i] or z[p] >= upper[i]:
                        x[i] = lower[i] if z[p] <= lower[i] else upper[i]
                        is_free[i] = False
                        outside = True
                    else:
                        x[i] = z[p]
                if outside:
                    continue
            first, alpha = -1, np.inf
            for p in range(count):
                i = free[p]
                if z[p] < lower[i] or z[p] > upper[i]:
                    d = z[p] - x[i]
                    room = (lower[i] - x[i]) / d if d < 0 else (upper[i] - x[i]) / d
                    if room < alpha:
                        first, alpha = p, room
            if first >= 0:
                alpha = min(max(alpha, 0.0), 1.0)
                if free[first] == just_freed and alpha == 0.0:
                    return False  # the freed variable cannot move: degenerate
                for p in range(count):
                    i = free[p]
                    d = z[p] - x[i]
                    x[i] += alpha * d
                    if p == first:  # the bound it stepped to
                        x[i] = lower[i] if d < 0 else upper[i]
                        is_free[i] = False
                    elif x[i] <= lower[i] or x[i] >= upper[i]:  # the bound it reached (d may be 0)
                        x[i] = lower[i] if x[i] <= lower[i] else upper[i]
                        is_free[i] = False
                just_freed = -1
                continue
            for p in range(count):
                x[free[p]] = z[p]
        best, best_score = -1, 0.0
        for i in range(c):
            if is_free[i]:
                continue
            gradient = -g[i]
            for j in range(c):
                gradient += H[i, j] * x[j]
            score = 0.0
            if x[i] <= lower[i] and gradient < -tolerance:
                score = -gradient
            elif x[i] >= upper[i] and gradient > tolerance:
                score = gradient
            if score > best_score:
                best, best_score = i, score
            if bulk and score > 0.0:
                is_free[i] = True
        if best < 0:
            return True
        just_freed = -1 if bulk else best
        is_free[best] = True
    return False


@numba.njit(cache=True, error_model="numpy", parallel=True)
def _box_qp_frames(H, g, lower, upper, start, out, solved):
    """Every frame of g (f, c); H is (1, c, c) shared or (f, c, c) per frame; chunks in parallel."""
    f = g.shape[0]
    shared = H.shape[0] == 1
    for chunk in numba.prange((f + CHUNK - 1) // CHUNK):
        lo = chunk * CHUNK
        hi = min(f, lo + CHUNK)
        x = start[lo].copy()
        for t in range(lo, hi):
            if t > lo and not np.isfinite(x).all():
                x[:] = start[t]
            ok = _box_qp(H[0] if shared else H[t], g[t], lower, upper, x)
            solved[t] = ok
            if ok:
                out[t] = x
            else:
                out[t] = start[t]
                x[:] = start[t]


def box_qp_frames(
    H: np.ndarray, g: np.ndarray, lower: np.ndarray, upper: np.ndarray, start: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Solve min ½ xᵀ H_t x − g_tᵀ x, lower ≤ x ≤ upper, for every frame.

    Parameters
    ----------
    H : (c, c) or (f, c, c) float64
        Symmetric positive definite; shared by all frames or one per frame.
    g : (f, c) float64
    lower, upper : (c,) float64
        Bounds (±inf allowed), lower < upper.
    start : (f, c) float64, optional
        Where each run of frames starts (the first frame of each ``CHUNK``); the unconstrained
        solution clipped into the box by default (0 for a frame after one the kernel gave up on).

    Returns
    -------
    x : (f, c) float64
    solved : (f,) bool
        False for a frame whose exchanges cycled (degenerate); its ``x`` is its start, and the
        caller should solve it with a robust method (``solve.box_qp``'s BVLS fallback).
    """
    g = np.ascontiguousarray(g, dtype=np.float64)
    H = np.ascontiguousarray(H, dtype=np.float64)
    H3 = H[None] if H.ndim == 2 else H
    if start is None:  # the kernel reads it at each run's first frame (and after a frame it gave up on)
        first = np.arange(0, len(g), CHUNK)
        start = np.zeros_like(g)
        if H.ndim == 2:
            start[first] = np.linalg.solve(H, g[first].T).T
        else:
            start[first] = np.linalg.solve(H[first], g[first][..., None])[..., 0]
    start = np.clip(np.ascontiguousarray(start, dtype=np.float64), lower, upper)
    out = np.empty_like(g)
    solved = np.empty(len(g), np.bool_)
    lower = np.ascontiguousarray(lower, dtype=np.float64)
    upper = np.ascontiguousarray(upper, dtype=np.float64)
    if len(g) == 1:  # one frame (a live stream's): no parallel launch
        x = start[0].copy()
        solved[0] = _box_qp(H3[0], g[0], lower, upper, x)
        out[0] = x if solved[0] else start[0]
    else:
        _box_qp_frames(H3, g, lower, upper, start, out, solved)
    return out, solved
