"""The per-frame expression solve on markers: bounded least squares on a baked basis with a shape prior.

For the k free channels, with D_j (3, k) marker j's displacement per unit of each channel (the
basis's deltas at the marker, ``marker_deltas``) and y_tj its stabilised displacement in frame t::

    minimise  Σ_j w_tj ‖P_j (D_j a − y_tj)‖²  +  aᵀ Λ a  +  σᵀ a        lo ≤ a ≤ hi

* P_j drops a sliding (contour) marker's motion along its contour; w_tj is 1 for a usable sample,
  0 for a missing or rejected one.
* Λ = λ · diag(‖P D_i‖²) + ν · (m / n) · D_sᵀ D_s: a small ridge (``regularization`` λ, relative
  to each channel's own effect, as in ``capture.solve``) and the **shape prior**: D_s (3n, k) is
  the channels' motion of all n skin vertices, so aᵀ D_sᵀ D_s a is how much the whole face moves.
  Among activations that explain the markers equally well it prefers the one that moves the face
  least: two channels that cancel each other at the markers but not between them (antagonists
  fighting over a lid, lip depressors against a pucker) move the face a lot for nothing, and are
  not chosen. ν weighs the face's mean squared motion as ν markers' worth; as the prior of a
  Gaussian model (each marker coordinate off by σ_e, each skin coordinate moving by about τ) it
  is ν = (σ_e / τ)²: ``solve`` takes it per call, so the caller can tie it to the noise.
* σ_i = ``sparsity`` · ‖D_i‖² on channels bounded below by 0 (an L1 term).

Each frame is a box-constrained quadratic programme (``capture.qp``) on the normal matrix
H_t = Σ_j w_tj (P_j D_j)ᵀ(P_j D_j) + Λ, shared by every frame whose markers are all usable.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg import cholesky
from scipy.optimize import lsq_linear

from mimetic.capture.markers import MarkerSet
from mimetic.capture.qp import box_qp_frames
from mimetic.capture.solve import box_qp, channel_bounds
from mimetic.engines.basis import Basis
from mimetic.errors import ActivationError
from mimetic.rig.model import Rig

GAZE_CHANNELS = ("gaze_yaw", "gaze_pitch", "gaze_convergence", "gaze_vertical_vergence")
"""Left out unless named in ``active``: markers and face landmarks have no iris points, and the rig's
lids follow the gaze, so a lid marker would explain a blink as the eyes turning down."""
NOSE_CHANNELS = (
    "depressor_septi",
    *(f"{name}_{side}" for name in ("dilator_naris", "nasalis_alar", "nasalis_transverse") for side in "LR"),
)
"""Also left out unless named in ``active``: the nose's small muscles move its tip and wings by about
2 mm, twice the markers' noise, at the few points a face layout puts there (5 of iBUG's 68, none on
the wing's side), so by default they would fit noise and what the levators do. On ICT's captured
shapes (none of which moves them) the markers route's face residual rose 0.4–0.6 points with them."""
MIN_MOVE_REL = 1e-3
"""Channels moving the markers less than this fraction of the strongest channel are held at 0."""
FRAME_CHUNK = 2048
"""Frames whose normal matrices are built at once (bounds a (chunk, k, k) temporary)."""


@dataclass(frozen=True, eq=False)
class MarkerSolver:
    """The per-basis part of the marker solve (see the module docstring).

    Attributes
    ----------
    rows : (m, 3, k) float64
        P_j D_j for the k free channels: each marker's projected displacement per unit of each.
    blocks : (m, k, k) float64
        (P_j D_j)ᵀ (P_j D_j), the marker's share of the normal matrix.
    projectors : (m, 3, 3) float64
        P_j (identity for a fixed marker).
    ridge : (k, k) float64
        λ · diag(‖P D_i‖²), positive definite.
    shape : (k, k) float64
        (m / n) · D_sᵀ D_s, the shape prior per unit of ν (zeros without one).
    linear : (k,) float64
        The sparsity term σ.
    lower, upper : (k,) float64
    sliding : (m,) bool
        Markers whose projector is not the identity.
    """

    rows: np.ndarray
    blocks: np.ndarray
    projectors: np.ndarray
    ridge: np.ndarray
    shape: np.ndarray
    linear: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    sliding: np.ndarray

    def prior(self, nu: float = 0.0) -> np.ndarray:
        """Λ (k, k) with the shape prior at weight ν."""
        return self.ridge + nu * self.shape

    def normal(self, weights: np.ndarray, nu: float = 0.0) -> np.ndarray:
        """Normal matrices (f, k, k) for marker weights (f, m) and shape prior weight ν."""
        k = self.rows.shape[2]
        H = (weights @ self.blocks.reshape(len(self.blocks), k * k)).reshape(len(weights), k, k)
        return H + self.prior(nu)

    def solve(self, y: np.ndarray, weights: np.ndarray, nu: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Activations (f, k) for displacements ``y`` (f, m, 3) (finite where ``weights`` > 0),
        weights (f, m) ≥ 0 and the shape prior's weight ν; and the per-marker fit residuals (f, m)
        (projected, rig units)."""
        f, m, _ = y.shape
        y = np.where(weights[..., None] > 0, np.nan_to_num(y), 0.0)
        projected = y.copy()  # (f, m, 3): P_j y_tj (P_j is the identity but on sliding markers)
        sliding = self.sliding
        projected[:, sliding] = np.einsum("mij,fmj->fmi", self.projectors[sliding], y[:, sliding])
        flat_rows = self.rows.reshape(3 * m, -1)  # (3m, k)
        g = (weights[..., None] * projected).reshape(f, 3 * m) @ flat_rows - self.linear  # (f, k)
        x = np.empty_like(g)
        full = np.all(weights == 1.0, axis=1)
        shared = self.normal(np.ones((1, m)), nu)[0]
        if full.any():
            x[full], ok = box_qp_frames(shared, g[full], self.lower, self.upper)
            self._fallback(np.flatnonzero(full)[~ok], shared[None], g, x)
        partial = np.flatnonzero(~full)
        for lo in range(0, len(partial), FRAME_CHUNK):
            frames = partial[lo : lo + FRAME_CHUNK]
            H = self.normal(weights[frames], nu)
            x[frames], ok = box_qp_frames(H, g[frames], self.lower, self.upper)
            self._fallback(frames[~ok], H[~ok], g, x)
        fitted = (x @ flat_rows.T).reshape(f, m, 3)
        residual = np.linalg.norm(fitted - projected, axis=2)
        return x, residual

    def _fallback(self, frames: np.ndarray, H: np.ndarray, g: np.ndarray, x: np.ndarray) -> None:
        """Frames the compiled active set gave up on, by ``solve.box_qp`` (with a BVLS fallback)."""
        for i, t in enumerate(frames):
            Ht = H[0] if len(H) == 1 else H[i]
            x[t], done = box_qp(Ht, g[t], self.lower, self.upper, np.zeros(len(g[t])))
            if not done:
                L = cholesky(Ht)  # Ht = Lᵀ L: ‖L x − L⁻ᵀ g‖² = xᵀHx − 2gᵀx + const
                rhs = np.linalg.solve(L.T, g[t])
                x[t] = lsq_linear(L, rhs, bounds=(self.lower, self.upper), method="bvls", tol=1e-12).x


def marker_deltas(rig: Rig, basis: Basis, markers: MarkerSet) -> np.ndarray:
    """(c, m, 3) float64: each channel's displacement of each marker (barycentric on the basis's deltas)."""
    c, n, _ = basis.deltas.shape
    flat = markers.weights(rig) @ basis.deltas.transpose(1, 0, 2).reshape(n, 3 * c)  # (m, 3c)
    return flat.reshape(-1, c, 3).transpose(1, 0, 2)


def skin_gram(rig: Rig, basis: Basis, channels: np.ndarray) -> tuple[np.ndarray, int]:
    """D_sᵀ D_s (k, k) of the basis channels ``channels`` (k,) over the rig's skin vertices (all
    vertices without a "skin" part), and the vertex count n: how much the face moves."""
    mesh = rig.mesh
    vertices = mesh.part_vertices("skin") if "skin" in mesh.parts else np.arange(mesh.n_vertices)
    D = basis.deltas[channels][:, vertices].reshape(len(channels), -1)  # (k, 3n)
    return D @ D.T, len(vertices)


def visible_channels(basis: Basis, deltas: np.ndarray, active: Sequence[str] | None = None) -> np.ndarray:
    """(c,) bool: channels moving the markers (``deltas`` (c, m, 3)) by at least ``MIN_MOVE_REL`` of
    the strongest, among ``active`` (default: all but the gaze and the nose's small muscles,
    ``GAZE_CHANNELS`` and ``NOSE_CHANNELS``)."""
    effect = np.sqrt(np.einsum("cmd,cmd->c", deltas, deltas))
    chosen = (
        ~np.isin(basis.channels, GAZE_CHANNELS + NOSE_CHANNELS)
        if active is None
        else np.isin(basis.channels, list(active))
    )
    return (effect > MIN_MOVE_REL * effect.max()) & chosen


def prepare_marker_solver(
    deltas: np.ndarray,
    markers: MarkerSet,
    lower: np.ndarray,
    upper: np.ndarray,
    *,
    regularization: float = 1e-3,
    sparsity: float = 0.0,
    skin: tuple[np.ndarray, int] | None = None,
) -> MarkerSolver:
    """The solver for marker deltas (k, m, 3) of the free channels with bounds (k,); ``skin``,
    ``skin_gram`` of the same channels, gives the shape prior (none without it)."""
    m = markers.n_markers
    projectors = np.repeat(np.eye(3)[None], m, axis=0)
    t = markers.tangents[markers.sliding]
    projectors[markers.sliding] -= np.einsum("mi,mj->mij", t, t)
    rows = np.einsum("mij,kmj->mik", projectors, deltas)  # (m, 3, k)
    blocks = np.einsum("mik,mil->mkl", rows, rows)
    norms = np.einsum("mik,mik->k", rows, rows)  # ‖P D_i‖²
    ridge = np.diag(max(regularization, 1e-12) * np.maximum(norms, 1e-12 * norms.max()))
    shape = np.zeros_like(ridge) if skin is None else (m / skin[1]) * skin[0]
    linear = np.where(lower >= 0, sparsity * norms, 0.0)
    return MarkerSolver(rows, blocks, projectors, ridge, shape, linear, lower, upper, markers.sliding.copy())


def noise_gain(solver: MarkerSolver) -> np.ndarray:
    """(k,) float64: the standard deviation of each free channel's solved value per rig unit of
    independent noise on every marker coordinate (all markers seen, bounds inactive):
    ``sqrt(diag(H⁻¹ Hₙ H⁻¹))`` with H the normal matrix with its ridge and Hₙ without. A channel
    whose gain times the capture's noise is large compared with its range is not determined by the
    markers (two muscles that move them alike, a lid seen by no marker)."""
    undamped = solver.blocks.sum(axis=0)  # (k, k)
    inverse = np.linalg.inv(undamped + solver.ridge)
    return np.sqrt(np.maximum(np.diag(inverse @ undamped @ inverse), 0.0))


def determined_channels(
    rig: Rig, basis: Basis, markers: MarkerSet, *, noise: float, tolerance: float = 0.02
) -> tuple[str, ...]:
    """The channels a marker set determines: starting from every channel the markers see (but the
    gaze and the nose's small muscles), drop the one with the largest ``noise_gain`` · ``noise`` / range until
    each is within ``tolerance`` of its range (``noise``: per-coordinate marker noise in rig units,
    after smoothing)."""
    deltas = marker_deltas(rig, basis, markers)
    keep = list(np.flatnonzero(visible_channels(basis, deltas)))
    lower, upper = channel_bounds(basis, rig)
    span = upper - lower
    zeros = np.zeros(len(basis.channels))
    while keep:
        solver = prepare_marker_solver(deltas[keep], markers, zeros[keep], zeros[keep])
        error = noise_gain(solver) * noise / span[keep]
        worst = int(np.argmax(error))
        if error[worst] <= tolerance:
            break
        keep.pop(worst)
    return tuple(basis.channels[j] for j in keep)


DETERMINED_NOISE_M = 0.001
"""The marker noise ``resolve_channels`` asks ``determined_channels`` about: 1 mm (3D RMS) in metres."""


def resolve_channels(
    rig: Rig, basis: Basis, markers: MarkerSet, spec: str, *, fps: float, cutoff_hz: float | None
) -> tuple[str, ...] | None:
    """The channels a ``--channels`` option names: "all" (None: every channel the markers see but
    the gaze and the nose's small muscles), "determined" (``determined_channels`` at 1 mm of marker
    noise, after the smoother at ``cutoff_hz``), or comma-separated channel names.

    Raises
    ------
    ActivationError
        A name the rig has no channel for.
    """
    from mimetic.capture.smooth import smoothed_noise
    from mimetic.mesh.units import UNIT_SCALE

    if spec == "all":
        return None
    if spec == "determined":
        metre = UNIT_SCALE.get(rig.units or "")
        per_coordinate = DETERMINED_NOISE_M / metre / np.sqrt(3) if metre else 0.005 * rig.scale
        return determined_channels(rig, basis, markers, noise=smoothed_noise(per_coordinate, fps, cutoff_hz))
    names = tuple(n.strip() for n in spec.split(",") if n.strip())
    unknown = [n for n in names if n not in set(rig.channel_names)]
    if unknown:
        raise ActivationError(
            f"the rig has no channel(s) {', '.join(unknown[:5])}; `mimetic list channels RIG` lists them"
        )
    return names


def library_directions(basis: Basis, free: np.ndarray) -> np.ndarray:
    """(r, k) float64: the ARKit table's 52 shapes (``animate.arkit``; browInnerUp and cheekPuff as
    their ``_L``/``_R`` halves) as activations of the basis channels ``free`` (k,), the shapes that
    move none of them left out. The video solve's library prior keeps the face near the cone of
    their non-negative combinations: the table says which channels act together (a pucker's lips
    push forward as they narrow), which is what one camera cannot see."""
    from mimetic.animate.arkit import arkit_table, arkit_values

    rows = []
    for shape in arkit_table().values():
        names = [f"{shape.name}_{s}" for s in "LR"] if shape.halves else [shape.name]
        for name in names:
            values = arkit_values({name: 1.0})
            rows.append([values.get(basis.channels[j], 0.0) for j in free])
    directions = np.array(rows, dtype=np.float64).reshape(-1, len(free))
    return np.unique(directions[np.abs(directions).sum(axis=1) > 0], axis=0)


LIBRARY_RIDGE = 1e-6
"""Ridge on the library weights' block, relative to its diagonal (shapes alike on the skin)."""


def with_library(
    H: np.ndarray,
    g: np.ndarray,
    lower: np.ndarray,
    upper: np.ndarray,
    shape: np.ndarray,
    library: np.ndarray,
    mu: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A box QP (``capture.qp``: H (b, k, k), g (f, k), bounds (k,)) with the library prior added at
    weights μ (b,): the face's motion off the cone of the ``library``'s directions (r, k), min over
    w ≥ 0 of μ ‖S^½ (a − Mᵀ w)‖² (S = ``shape`` (k, k), the skin's motion gram), solved with the shape
    weights w as r more variables. Returns H (b, k + r, k + r), g (f, k + r) and the bounds (k + r,);
    the QP unchanged without directions or weight."""
    r, k = library.shape
    if r == 0 or not np.any(mu > 0):
        return H, g, lower, upper
    SM = shape @ library.T
    MSM = library @ SM
    MSM[np.diag_indices(r)] += LIBRARY_RIDGE * np.maximum(np.diag(MSM), 1e-12 * np.diag(MSM).max())
    mu = np.asarray(mu, dtype=np.float64)[:, None, None]
    full = np.empty((len(H), k + r, k + r))
    full[:, :k, :k] = H + mu * shape
    full[:, :k, k:] = -mu * SM
    full[:, k:, :k] = -mu * SM.T
    full[:, k:, k:] = mu * MSM
    padded = np.concatenate([g, np.zeros((len(g), r))], axis=1)
    return full, padded, np.concatenate([lower, np.zeros(r)]), np.concatenate([upper, np.full(r, np.inf)])
