"""Channel activations that make a baked basis reproduce captured vertex positions.

For each frame, with the basis restricted to the fitted vertices S (s of them) — deltas D (3s, c),
corrective deltas C (3s, k) — and the target offsets y = (target − neutral) on S, flattened::

    minimise   ‖D a + C p(a) − y‖² + Σ_j λ_j a_j²     subject to   lo ≤ a ≤ hi
    p_k(a) = a_i(k) a_j(k)                            (the corrective products)
    λ_j = regularization · ‖D_j‖²                     (per channel, so unit-free)

Scaling the penalty by each channel's own norm makes it independent of the channel's unit (a jaw
in radians moves centimetres per unit, a muscle millimetres): alone, a channel is shrunk by the
factor 1 / (1 + regularization).

Without correctives the problem is a convex bounded linear least-squares problem and one solve is
exact. With correctives it is solved by bounded Gauss-Newton: linearise p at the current
activations (starting at 0, where the first step is the linear solve with the correctives
ignored), solve the bounded linear problem, and backtrack along the step until the true objective
decreases; stop when it decreases by less than ``tolerance`` (relative) or after ``iterations``
steps.

Every product over the vertices is taken once: the Gram matrix G = Bᵀ B of B = [D C]
(3s, c + k), per solver, and the projections Bᵀ y, per frame. A Gauss-Newton step then costs
O((c + k)²) plus a bounded quadratic programme on c unknowns (``box_qp``, an active-set method on
the normal matrix; scipy's ``lsq_linear`` BVLS on the same problem took 7 ms a step on the ICT rig,
``box_qp`` 1.5 ms), independent of the vertex count. The final residual is evaluated on the
vertices, not from G, so it is exact.

Channels that move nothing on S (head rotation, which a basis cannot represent, or eyelids when
the eyes are left out) and channels left out of ``active`` are held at 0, the basis's rest.

Over 600 lines because the solver's prepared factorisations belong with the maths they implement.
"""

from __future__ import annotations

import difflib
import logging
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg import cho_factor, cho_solve, solve_triangular
from scipy.optimize import lsq_linear

from mimetic.engines.basis import Basis
from mimetic.errors import ActivationError, MimeticWarning
from mimetic.rig.model import Channel, Rig

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None]

FRAME_CHUNK = 256
"""Frames whose residual is evaluated together (bounds the (frames, 3s) temporary)."""

BACKTRACK_STEPS = 8
"""Halvings of a Gauss-Newton step tried before a frame is declared converged."""

OBJECTIVE_PRECISION = 1e-13
"""Objective changes below this fraction of ‖y‖² are rounding (zᵀGz − 2zᵀh + yᵀy cancels)."""

STEP_PRECISION = 1e-12
"""A step moving no activation by more than this ends the Gauss-Newton loop."""


@dataclass(frozen=True)
class SolveResult:
    """Activations fitted to target frames, and how well they reproduce them.

    Arrays are read-only.

    Attributes
    ----------
    channels : tuple of str, (c,)
        The basis's channels, in the order of ``activations``.
    activations : (f, c) float64
        Per frame; within the channel ranges given to the solver. A single (n, 3) target gives f = 1.
    relative_residual : (f,) float64
        ‖fit − target‖ / ‖target − neutral‖ over the fitted vertices (Frobenius norms); nan for a
        frame whose target equals the neutral there (its absolute errors still say how well it fits).
    rms_error : (f,) float64
        Root mean square over the fitted vertices of the distance |fit − target|, in basis units.
    max_error : (f,) float64
        Largest such distance, in basis units.
    iterations : (f,) int64
        Gauss-Newton steps taken per frame (1 when the basis has no correctives in play).
    vertices : (s,) int64
        The fitted vertices.
    held : tuple of str
        Channels held at 0: not in ``active``, or moving none of the fitted vertices.
    success : bool
        False when some frame was still improving after ``iterations`` steps.
    message : str
    """

    channels: tuple[str, ...]
    activations: np.ndarray
    relative_residual: np.ndarray
    rms_error: np.ndarray
    max_error: np.ndarray
    iterations: np.ndarray
    vertices: np.ndarray
    held: tuple[str, ...]
    success: bool
    message: str


@dataclass(frozen=True, eq=False)
class ActivationSolver:
    """The per-basis part of ``solve_activations`` (``prepare_solver``), reusable for many clips.

    Attributes
    ----------
    basis : Basis
    vertices : (s,) int64
        Fitted vertices.
    free : (m,) int64
        Indices of the channels solved for; the others are held at 0.
    lower, upper : (m,) float64
        Their bounds (±inf when unbounded).
    pairs : (k, 2) int64
        The correctives in play, as positions in ``free``.
    terms : (m + k, 3s) float64
        Bᵀ on the fitted vertices: the free channels' deltas, then the correctives', as rows.
    gram : (m + k, m + k) float64
        Bᵀ B.
    damping : (m,) float64
        λ_j in squared basis units per unit of channel j (``regularization`` · ‖D_j‖²).
    iterations : int
    tolerance : float
    """

    basis: Basis
    vertices: np.ndarray
    free: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    pairs: np.ndarray
    terms: np.ndarray
    gram: np.ndarray
    damping: np.ndarray
    iterations: int
    tolerance: float

    @property
    def held(self) -> tuple[str, ...]:
        free = set(self.free.tolist())
        return tuple(name for j, name in enumerate(self.basis.channels) if j not in free)

    def solve(self, targets: np.ndarray, *, progress: Progress | None = None) -> SolveResult:
        """Fit every frame of ``targets`` ((n, 3) or (f, n, 3) float64, the basis's vertex order and
        units); see ``solve_activations``."""
        basis = self.basis
        frames = _check_targets(basis, targets, self.vertices)  # (f, s, 3)
        f, s = frames.shape[:2]
        y = (frames - basis.neutral[self.vertices]).reshape(f, 3 * s)  # (f, 3s) target offsets
        projections = y @ self.terms.T  # (f, m + k): Bᵀ y per frame
        squared = np.einsum("fi,fi->f", y, y)  # (f,) ‖y‖²
        x = np.zeros((f, len(self.free)))  # (f, m)
        steps = np.zeros(f, np.int64)
        unconverged = 0
        for t in range(f):
            x[t], steps[t], converged = self._frame(projections[t], squared[t])
            unconverged += not converged
            if progress is not None:
                progress(t + 1, f)
        activations = np.zeros((f, basis.n_channels))
        activations[:, self.free] = x
        relative, rms, worst = self._residuals(x, y)
        if unconverged:
            success = False
            message = (
                f"{unconverged} of {f} frames still improved after {self.iterations} Gauss-Newton steps; "
                "raise iterations= (their activations are the last iterate)"
            )
            warnings.warn(message, MimeticWarning, stacklevel=3)
        else:
            success = True
            message = f"converged: {f} frames, at most {int(steps.max(initial=0))} Gauss-Newton steps"
        log.debug("solve_activations: %s", message)
        for array in (activations, relative, rms, worst, steps):
            array.setflags(write=False)
        return SolveResult(
            channels=basis.channels,
            activations=activations,
            relative_residual=relative,
            rms_error=rms,
            max_error=worst,
            iterations=steps,
            vertices=self.vertices,
            held=self.held,
            success=success,
            message=message,
        )

    # ------------------------------------------------------------------ kernels

    def _objective(self, x: np.ndarray, h: np.ndarray, yy: float) -> float:
        """‖D x + C p(x) − y‖² + Σ λ_j x_j² from the Gram matrix: zᵀ G z − 2 zᵀ h + yᵀy + …, z = [x; p(x)]."""
        z = np.concatenate([x, x[self.pairs[:, 0]] * x[self.pairs[:, 1]]])  # (m + k,)
        return float(z @ self.gram @ z - 2.0 * z @ h + yy + self.damping @ (x * x))

    def _step(self, x0: np.ndarray, h: np.ndarray) -> np.ndarray:
        """The bounded minimiser of the objective with p linearised at ``x0`` (m,).

        p(x) ≈ p(x0) + M (x − x0), M = ∂p/∂x (k, m), so the model is J x + C q with J = D + C M and
        q = p(x0) − M x0 = −p(x0). Normal equations: H = Jᵀ J + diag(λ), g = Jᵀ (y − C q).
        """
        m, k = len(self.free), len(self.pairs)
        G = self.gram
        Gdd, Gdc, Gcc = G[:m, :m], G[:m, m:], G[m:, m:]  # (m, m), (m, k), (k, k)
        hd, hc = h[:m], h[m:]
        H = Gdd + np.diag(self.damping)
        g = hd.copy()
        if k:
            i, j = self.pairs[:, 0], self.pairs[:, 1]
            M = np.zeros((k, m))
            np.add.at(M, (np.arange(k), i), x0[j])  # ∂(x_i x_j)/∂x_i = x_j
            np.add.at(M, (np.arange(k), j), x0[i])
            q = -x0[i] * x0[j]  # (k,)
            GdcM = Gdc @ M  # (m, m)
            H += GdcM + GdcM.T + M.T @ Gcc @ M
            g += -Gdc @ q + M.T @ (hc - Gcc @ q)
        x, solved = box_qp(H, g, self.lower, self.upper, x0)
        if solved:
            return x
        log.debug("box_qp did not finish in %d exchanges; falling back to scipy's BVLS", 3 * m + 10)
        L = np.tril(cho_factor(H, lower=True, check_finite=False)[0])  # H = L Lᵀ
        b = solve_triangular(L, g, lower=True, check_finite=False)  # ‖Lᵀ x − b‖² = xᵀHx − 2gᵀx + const
        return lsq_linear(L.T, b, bounds=(self.lower, self.upper), method="bvls", tol=1e-12).x

    def _frame(self, h: np.ndarray, yy: float) -> tuple[np.ndarray, int, bool]:
        """Activations (m,) of one frame from its projections ``h`` (m + k,) and ``yy`` = ‖y‖²;
        the Gauss-Newton steps taken, and whether it converged."""
        m = len(self.free)
        x = self._step(np.zeros(m), h)
        if not len(self.pairs):
            return x, 1, True
        value = self._objective(x, h, yy)
        for step in range(2, self.iterations + 1):
            proposal = self._step(x, h)
            t = 1.0
            for _ in range(BACKTRACK_STEPS):
                trial = x + t * (proposal - x)  # stays in the box: it is convex
                new = self._objective(trial, h, yy)
                if new <= value:
                    break
                t *= 0.5
            else:
                return x, step, True  # no descent along the step: numerically stationary
            change, moved = value - new, np.abs(trial - x).max()
            x, value = trial, new
            # the objective is evaluated from the Gram matrix, to about OBJECTIVE_PRECISION · ‖y‖²
            if change <= self.tolerance * value + OBJECTIVE_PRECISION * yy or moved <= STEP_PRECISION:
                return x, step, True
        return x, self.iterations, False

    def _residuals(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Relative, RMS and max residual per frame, evaluated on the vertices (not from the Gram)."""
        f = len(y)
        s = len(self.vertices)
        relative, rms, worst = np.empty(f), np.empty(f), np.empty(f)
        for lo in range(0, f, FRAME_CHUNK):
            hi = min(f, lo + FRAME_CHUNK)
            xc = x[lo:hi]  # (b, m)
            z = np.concatenate([xc, xc[:, self.pairs[:, 0]] * xc[:, self.pairs[:, 1]]], axis=1)
            r = (z @ self.terms - y[lo:hi]).reshape(hi - lo, s, 3)  # (b, s, 3) fit − target
            distance = np.linalg.norm(r, axis=2)  # (b, s)
            norm_r = np.sqrt(np.einsum("bs,bs->b", distance, distance))
            norm_y = np.linalg.norm(y[lo:hi], axis=1)
            with np.errstate(divide="ignore", invalid="ignore"):
                relative[lo:hi] = np.where(norm_y > 0, norm_r / norm_y, np.nan)
            rms[lo:hi] = norm_r / np.sqrt(s)
            worst[lo:hi] = distance.max(axis=1)
        return relative, rms, worst


# --------------------------------------------------------------------------- the bounded solve


def box_qp(
    H: np.ndarray, g: np.ndarray, lower: np.ndarray, upper: np.ndarray, start: np.ndarray
) -> tuple[np.ndarray, bool]:
    """Minimise ½ xᵀ H x − gᵀ x subject to lower ≤ x ≤ upper, by a primal active-set method.

    The box form of Lawson and Hanson's NNLS (as BVLS, Stark and Parker 1995), on the normal
    matrix instead of the least-squares matrix: solve on the free variables with the others at
    their bounds; if that leaves the box, step to the first bound and fix the variable there; once
    the free solve is inside, free the bound variable whose gradient most wants it inside, until
    none does (the KKT conditions).

    Parameters
    ----------
    H : (m, m) float64
        Symmetric positive definite.
    g : (m,) float64
    lower, upper : (m,) float64
        lower < upper; ±inf for no bound.
    start : (m,) float64
        A warm start (clipped into the box); variables on a bound start fixed there.

    Returns
    -------
    x : (m,) float64
    solved : bool
        False when the exchanges did not finish within 3 m + 10 (degenerate cycling); the caller
        should then use a robust solver.
    """
    m = len(g)
    x = np.clip(start, lower, upper)
    free = (x > lower) & (x < upper)
    scale = np.abs(g).max(initial=0.0) + np.abs(H).max(initial=0.0) * np.abs(x).max(initial=0.0)
    kkt_tol = 1e-12 * max(scale, np.finfo(float).tiny)
    just_freed = -1
    for _ in range(3 * m + 10):
        F = np.flatnonzero(free)
        if len(F):
            fixed = ~free
            rhs = g[F] - H[np.ix_(F, fixed)] @ x[fixed]
            z = cho_solve(cho_factor(H[np.ix_(F, F)], check_finite=False), rhs, check_finite=False)
            lo, hi = lower[F], upper[F]
            outside = (z < lo) | (z > hi)
            if outside.any():
                d = z - x[F]
                with np.errstate(divide="ignore", invalid="ignore"):
                    room = np.where(d < 0, (lo - x[F]) / d, np.where(d > 0, (hi - x[F]) / d, np.inf))
                room[~outside & (room > 1)] = np.inf
                first = int(np.argmin(room))
                alpha = float(np.clip(room[first], 0.0, 1.0))
                if F[first] == just_freed and alpha == 0.0:
                    return x, False  # the freed variable cannot move: degenerate, let BVLS decide
                x[F] += alpha * d
                hit = (x[F] <= lo) | (x[F] >= hi)
                hit[first] = True
                x[F[hit]] = np.where(d[hit] < 0, lo[hit], hi[hit])
                free[F[hit]] = False
                just_freed = -1
                continue
            x[F] = z
        gradient = H @ x - g  # (m,): the objective's gradient
        wants_up = ~free & (x <= lower) & (gradient < -kkt_tol)
        wants_down = ~free & (x >= upper) & (gradient > kkt_tol)
        score = np.where(wants_up, -gradient, np.where(wants_down, gradient, 0.0))
        if not score.any():
            return x, True
        just_freed = int(np.argmax(score))
        free[just_freed] = True
    return x, False


# --------------------------------------------------------------------------- checks


def _check_vertices(basis: Basis, vertices: object) -> np.ndarray:
    """The fitted vertices as sorted unique (s,) int64 indices, from None, a bool mask or indices."""
    n = basis.n_vertices
    if vertices is None:
        return np.arange(n, dtype=np.int64)
    if isinstance(vertices, slice):
        return np.arange(n, dtype=np.int64)[vertices]
    array = np.asarray(vertices)
    if array.dtype == bool:
        if array.shape != (n,):
            raise ActivationError(
                f"a vertex mask must have shape ({n},) like basis.neutral; got {array.shape}"
            )
        index = np.flatnonzero(array)
    else:
        if array.ndim != 1 or (array.size and not np.issubdtype(array.dtype, np.integer)):
            raise ActivationError(
                f"vertices must be a (s,) array of vertex indices or a ({n},) bool mask; "
                f"got shape {array.shape}, dtype {array.dtype}"
            )
        index = array.astype(np.int64)
        if index.size and (index.min() < 0 or index.max() >= n):
            bad = index[(index < 0) | (index >= n)][0]
            raise ActivationError(
                f"vertex index {bad} is out of range: the basis has {n} vertices (0..{n - 1})"
            )
        if len(np.unique(index)) != len(index):
            raise ActivationError("vertices has repeated indices; pass each vertex once (np.unique)")
    if index.size == 0:
        raise ActivationError("vertices selects no vertex; pass at least one to fit")
    return np.sort(index)


def _check_targets(basis: Basis, targets: object, vertices: np.ndarray) -> np.ndarray:
    """Targets on the fitted vertices as (f, s, 3) float64; ``ActivationError`` names what is wrong."""
    n = basis.n_vertices
    try:
        array = np.asarray(targets, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ActivationError(f"targets cannot be read as float64 numbers: {error}") from None
    if array.ndim == 2:
        array = array[None]
    if array.ndim != 3 or array.shape[1:] != (n, 3):
        raise ActivationError(
            f"targets must have shape ({n}, 3) or (frames, {n}, 3), the basis's vertices in its order; "
            f"got {np.shape(targets)}"
        )
    if len(array) == 0:
        raise ActivationError(f"targets has no frames; got shape {array.shape}")
    frames = array[:, vertices]  # (f, s, 3), a copy
    bad = ~np.isfinite(frames)
    if bad.any():
        t, v, _ = np.argwhere(bad)[0]
        count = int(bad.any(axis=2).sum())
        raise ActivationError(
            f"targets have {count} non-finite vertex position(s) among the fitted vertices, the first at "
            f"frame {t}, vertex {vertices[v]} ({frames[t, v].tolist()}); fill them, drop the frame, or "
            "leave those vertices out with vertices="
        )
    return frames


def channel_bounds(basis: Basis, channels: Rig | Sequence[Channel] | None) -> tuple[np.ndarray, np.ndarray]:
    """Lower and upper bounds (c,) for the basis's channels, from channel definitions matched by name."""
    c = basis.n_channels
    if channels is None:
        return np.full(c, -np.inf), np.full(c, np.inf)
    definitions = channels.channels if isinstance(channels, Rig) else tuple(channels)
    by_name = {}
    for ch in definitions:
        if not isinstance(ch, Channel):
            raise TypeError(f"channels must be a Rig or Channel objects; got {type(ch).__name__}")
        by_name[ch.name] = ch
    missing = [name for name in basis.channels if name not in by_name]
    if missing:
        raise ActivationError(
            f"no range for basis channel(s) {', '.join(missing[:5])}: channels= must define every channel "
            "of the basis (pass the rig the basis was baked from, or channels=None for no bounds)"
        )
    lower = np.array([by_name[name].minimum for name in basis.channels])
    upper = np.array([by_name[name].maximum for name in basis.channels])
    return lower, upper


def _active(basis: Basis, active: Sequence[str] | None) -> np.ndarray:
    """(c,) bool: the channels named in ``active`` (all when None)."""
    if active is None:
        return np.ones(basis.n_channels, dtype=bool)
    if isinstance(active, str):
        active = (active,)
    index = {name: j for j, name in enumerate(basis.channels)}
    mask = np.zeros(basis.n_channels, dtype=bool)
    for name in active:
        if name not in index:
            close = difflib.get_close_matches(name, basis.channels, n=3)
            hint = (
                f"did you mean {', '.join(close)}?"
                if close
                else f"channels are {', '.join(basis.channels[:6])}, …"
            )
            raise ActivationError(f"active names unknown channel {name!r}; {hint}")
        mask[index[name]] = True
    return mask


# --------------------------------------------------------------------------- public API


def prepare_solver(
    basis: Basis,
    *,
    vertices: np.ndarray | slice | None = None,
    channels: Rig | Sequence[Channel] | None = None,
    active: Sequence[str] | None = None,
    regularization: float = 1e-3,
    iterations: int = 30,
    tolerance: float = 1e-9,
) -> ActivationSolver:
    """The per-basis precomputation of ``solve_activations`` (its arguments), for reuse over many clips."""
    if not isinstance(basis, Basis):
        raise TypeError(f"basis must be a mimetic.engines.basis.Basis; got {type(basis).__name__}")
    if not (np.isfinite(regularization) and regularization >= 0):
        raise ActivationError(f"regularization must be a finite number ≥ 0; got {regularization}")
    if int(iterations) < 1:
        raise ActivationError(f"iterations must be ≥ 1; got {iterations}")
    if not (np.isfinite(tolerance) and tolerance >= 0):
        raise ActivationError(f"tolerance must be a finite number ≥ 0; got {tolerance}")
    index = _check_vertices(basis, vertices)  # (s,)
    lower, upper = channel_bounds(basis, channels)
    if np.any(lower > 0) or np.any(upper < 0):
        j = int(np.flatnonzero((lower > 0) | (upper < 0))[0])
        raise ActivationError(
            f"channel {basis.channels[j]!r} has range [{lower[j]}, {upper[j]}], which leaves out 0, the "
            "basis's rest; the solver needs every range to hold 0"
        )
    if np.any(lower >= upper):
        j = int(np.flatnonzero(lower >= upper)[0])
        raise ActivationError(f"channel {basis.channels[j]!r} has an empty range [{lower[j]}, {upper[j]}]")
    s, c = len(index), basis.n_channels
    deltas = basis.deltas[:, index].reshape(c, 3 * s)  # (c, 3s)
    moves = np.abs(deltas).max(axis=1) > 0  # (c,)
    pairs_all = basis.corrective_pairs  # (K, 2)
    corrective = basis.corrective_deltas[:, index].reshape(len(pairs_all), 3 * s)  # (K, 3s)
    corrective_moves = np.abs(corrective).max(axis=1) > 0 if len(pairs_all) else np.zeros(0, bool)
    for (i, j), on in zip(pairs_all, corrective_moves, strict=True):
        if on:
            moves[i] = moves[j] = True
    free_mask = moves & _active(basis, active)
    free = np.flatnonzero(free_mask)  # (m,)
    if len(free) == 0:
        raise ActivationError(
            "no channel left to solve: the active channels move none of the fitted vertices "
            "(check vertices= and active=)"
        )
    position = np.full(c, -1)
    position[free] = np.arange(len(free))
    keep = corrective_moves & free_mask[pairs_all[:, 0]] & free_mask[pairs_all[:, 1]]  # (K,) bool
    pairs = position[pairs_all[keep]].reshape(-1, 2).astype(np.int64)  # (k, 2) positions in free
    terms = np.concatenate([deltas[free], corrective[keep]]) if len(pairs) else deltas[free].copy()
    gram = terms @ terms.T  # (m + k, m + k)
    m = len(free)
    norms = np.diag(gram)[:m]  # ‖D_j‖² per free channel; a held channel moves nothing, but a free one
    norms = np.maximum(norms, 1e-12 * norms.max())  # may move only through its correctives
    damping = max(regularization, 1e-12) * norms  # (m,); the jitter keeps H factorable at 0
    for array in (index, free, pairs, terms, gram, damping):
        array.setflags(write=False)
    bounds = [np.ascontiguousarray(b[free]) for b in (lower, upper)]
    for array in bounds:
        array.setflags(write=False)
    log.debug("prepare_solver: %d vertices, %d of %d channels free, %d correctives", s, m, c, len(pairs))
    return ActivationSolver(
        basis,
        index,
        free,
        bounds[0],
        bounds[1],
        pairs,
        terms,
        gram,
        damping,
        int(iterations),
        float(tolerance),
    )


def solve_activations(
    basis: Basis,
    targets: np.ndarray,
    *,
    vertices: np.ndarray | slice | None = None,
    channels: Rig | Sequence[Channel] | None = None,
    active: Sequence[str] | None = None,
    regularization: float = 1e-3,
    iterations: int = 30,
    tolerance: float = 1e-9,
    progress: Progress | None = None,
) -> SolveResult:
    """Per-frame bounded least-squares activations that make ``basis`` reproduce ``targets``.

    Minimises ‖D a + C p(a) − y‖² + Σ_j λ_j a_j² per frame within the channel ranges (see the module
    docstring for the equation and the Gauss-Newton treatment of the correctives).

    Parameters
    ----------
    basis : Basis
        ``neutral`` (n, 3), ``deltas`` (c, n, 3), ``correctives`` (each a_i a_j delta), rig units.
    targets : (n, 3) or (f, n, 3) float64
        Vertex positions to reproduce, in the basis's vertex order and units (the same frame:
        remove any head motion first). Only the fitted ``vertices`` must be finite.
    vertices : (s,) int64 indices, (n,) bool mask or slice, optional
        The vertices the fit looks at (e.g. ``slice(0, 9409)``, ICT's face); all by default.
    channels : Rig or sequence of Channel, optional
        Channel definitions whose ``minimum``/``maximum`` bound the solve, matched to
        ``basis.channels`` by name (a ``Basis`` does not keep the ranges: pass the rig it was baked
        from). None solves without bounds, so only the regularization keeps values finite.
    active : sequence of str, optional
        The channels to solve for; the others are held at 0. All by default.
    regularization : float
        Tikhonov weight relative to each channel's own effect: λ_j = regularization · ‖D_j‖² on the
        fitted vertices, pulling activations toward 0; a channel alone is shrunk by 1 / (1 +
        regularization). 0 gives an unregularized fit (a 1e-12 jitter is still added so the normal
        matrix can be factored).
    iterations : int
        Most Gauss-Newton steps per frame (used only when correctives are in play).
    tolerance : float
        A frame stops when a step lowers the objective by less than this fraction of it.
    progress : callable(done, total), optional
        Called after each frame.

    Returns
    -------
    result : SolveResult
        ``activations`` (f, c) float64 and per-frame ``relative_residual``, ``rms_error`` and
        ``max_error`` (basis units) on the fitted vertices. A frame that did not converge is reported
        with ``success=False`` and a ``MimeticWarning``, not raised.

    Raises
    ------
    ActivationError
        Targets of the wrong shape or non-finite on the fitted vertices; bad ``vertices``,
        ``active`` or ``channels``; a range that leaves out 0.
    """
    solver = prepare_solver(
        basis,
        vertices=vertices,
        channels=channels,
        active=active,
        regularization=regularization,
        iterations=iterations,
        tolerance=tolerance,
    )
    return solver.solve(targets, progress=progress)
