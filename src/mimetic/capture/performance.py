"""Captured performance → the rig's channel activations (the paper's actuation estimation).

``solve_performance(rig, trajectories)`` runs the whole chain:

1. **Markers**: the captured points are matched by name to a ``MarkerSet`` on the rig (the
   layout is told from the names: ``ibug68_*``, ``mediapipe_*`` or the paper's).
2. **Calibration** (``capture.head``): the neutral pose (each marker's median over
   ``NEUTRAL_WINDOW_S`` around the neutral frame) is mapped onto the rig by a similarity.
3. **Temporal smoothing** (``smooth_markers``): each captured marker coordinate is smoothed as
   one banded problem over the whole clip, ``(W + λ D₂ᵀD₂) ŷ = W y`` (a Whittaker smoother: W the
   marker's per-frame weight, D₂ the second difference), with λ set so the response is one half
   at ``cutoff_hz``. Missing markers have weight 0, so gaps up to ``MAX_GAP_S`` are filled by
   the smoother; spikes are found by a robust reweighting (Cauchy weights on the smoothing
   residual, its scale from the residuals' median) and left out. For a linear basis D and
   inactive bounds this *is* the clip-wide solve with the marker motion's acceleration penalised
   — ‖(I⊗D)a − y‖² + λ‖(D₂⊗D)a‖² has normal equations ((I + λD₂ᵀD₂)⊗DᵀD) a = (I⊗Dᵀ) y, i.e. the
   per-frame solve of the smoothed markers — but it is separable per coordinate, so 10,000
   frames take a fraction of a second. (The head's rigid motion is smooth too, so smoothing before
   it is taken out changes little.)
   **Head motion**: each frame's markers that no channel moves give the skull's motion, which is
   removed and kept as the ``head_*`` channels; it is then refitted, alternating with step 4, to
   every trusted marker less the expression the solve predicts there.
4. **Solve** per frame (``capture.qp``), on the marker rows of the baked basis: ::

       minimise Σ_j w_tj ‖P_j (D_j a − y_tj)‖² + Σ_i λ_i a_i² + Σ_i σ_i a_i     lo ≤ a ≤ hi

   P_j drops a sliding marker's motion along its contour, λ_i = ``regularization`` · ‖D_i‖² (as
   in ``solve_activations``), σ_i = ``sparsity`` · ‖D_i‖² on channels bounded below by 0 (an L1
   term: a channel alone is soft-thresholded by ``sparsity`` activation units). With
   ``robust``, each alternation reweights every marker sample by a Cauchy function of its fit
   residual, with one scale for all markers, so a marker the model cannot explain (a mislabelled
   one) stops pulling the others.
5. Optionally (``refine``), Gauss-Newton steps against the full engine rather than its
   linearisation: the engine is posed at the solved activations and the solve repeated on
   targets corrected by the difference between the engine and the basis there.
"""

from __future__ import annotations

import logging
import os
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solveh_banded

from mimetic.capture.head import HeadMotion, calibrate, head_motion
from mimetic.capture.lift import lift_landmarks
from mimetic.capture.markers import MarkerSet, layout_for, marker_set
from mimetic.capture.qp import box_qp_frames
from mimetic.capture.solve import box_qp, channel_bounds
from mimetic.capture.trajectories import CaptureError, Trajectories
from mimetic.engines.basis import Basis
from mimetic.errors import MimeticWarning
from mimetic.fit.similarity import Similarity
from mimetic.rig.activations import Clip
from mimetic.rig.model import Rig

log = logging.getLogger(__name__)

Progress = Callable[[str, int, int], None]

HEAD_CHANNELS = ("head_yaw", "head_pitch", "head_roll")
GAZE_CHANNELS = ("gaze_yaw", "gaze_pitch", "gaze_convergence")
"""Left out unless named in ``active``: markers and face landmarks have no iris points, and the rig's
lids follow the gaze, so a lid marker would explain a blink as the eyes turning down."""
CUTOFF_HZ = 8.0
"""Default smoothing cutoff: facial motion (speech included) lives below ~8 Hz, tracker jitter above."""
MAX_GAP_S = 0.25
"""Gaps in a marker longer than this stay missing (the smoother's fill is not trusted)."""
CAUCHY_SCALE = 3.0
"""Robust weights 1 / (1 + (r / (CAUCHY_SCALE σ))²), σ from the residuals' median (``NORM_MEDIAN``)."""
NORM_MEDIAN = 1.5382
"""The median of |e| for e a 3-vector of unit normal noise (the χ distribution with 3 degrees of
freedom): σ per coordinate is the median residual distance over this."""
SIGMA_FLOOR_REL = 0.002
"""The robust scale σ is at least this fraction of the head (0.4 mm on a 22 cm head): clean data
has a median residual near 0, and a smooth motion's onset must not count as a spike."""
OUTLIER_SIGMAS = 6.0
"""Residuals beyond this many σ are reported as outliers and get weight 0."""
MODEL_OUTLIER_SIGMAS = 12.0
"""A marker sample this many σ from the solved model is dropped (looser than the smoother's spikes:
a model residual also holds what the rig cannot express)."""
ROBUST_ROUNDS = 3
HEAD_ROUNDS = 8
ROUNDS_TOLERANCE = 1e-3
"""The alternation stops once no activation moves by more than this between rounds (activation units
or radians: far below what a capture's noise allows)."""
NEUTRAL_WINDOW_S = 0.2
"""The neutral pose is each marker's median (smoothed, spikes left out) over this long a window
around the neutral frame."""
"""Alternations between the head's motion (refitted to every fixed marker, less the expression the
solve predicts there) and the expression (solved on the markers that head motion stabilises): the
stable markers alone are few and close together, so their pose is noisy."""
MIN_MOVE_REL = 1e-3
"""Channels moving the markers less than this fraction of the strongest channel are held at 0."""
MIN_SEEN_FRACTION = 0.5
"""Frames that see fewer than this fraction of the markers are flagged."""
MIN_CONFIDENCE = 0.5
"""Frames whose tracking confidence is below this are flagged (FaceDetection's own threshold)."""
STABLE_MOTION_REL = 0.005
"""A stable (head-motion) marker must move less than this fraction of the head's size under any
channel at its extreme; the layout's candidates that move more are not used for the head fit."""
MIN_STABLE_MARKERS = 4
FRAME_CHUNK = 2048
"""Frames whose normal matrices are built at once (bounds a (chunk, c, c) temporary)."""


@dataclass(frozen=True, eq=False)
class Performance:
    """A solved performance.

    Arrays are read-only.

    Attributes
    ----------
    clip : Clip
        Every rig channel at the capture's frame rate: the solved ones, ``head_*`` from the head
        motion, the rest 0.
    head : HeadMotion
    markers : MarkerSet
        The markers used (the captured points the rig has, in the capture's order).
    calibration : Similarity
        Capture → rig at the neutral frame.
    units : str or None
        The capture's length units (guessed from the calibration's scale when the file had none).
    marker_error : (f,) float64
        RMS distance between the fitted and the (stabilised, smoothed) markers a frame used, in
        rig units; nan for a frame that used none.
    used : (f, m) bool
        The markers each frame's solve used (seen or filled, not outliers).
    outliers : (f, m) bool
        Marker samples rejected as spikes or as unexplained by the model.
    flagged : (f,) bool
        Frames to distrust: little seen, no face, no head fit, or a head angle out of range.
    solved : tuple of str
        The channels solved for; the others are held at 0 (no marker sees them, or not ``active``).
    neutral_frame : int
    """

    clip: Clip
    head: HeadMotion
    markers: MarkerSet
    calibration: Similarity
    units: str | None
    marker_error: np.ndarray
    used: np.ndarray
    outliers: np.ndarray
    flagged: np.ndarray
    solved: tuple[str, ...]
    neutral_frame: int

    def __post_init__(self) -> None:
        for name in ("marker_error", "used", "outliers", "flagged"):
            getattr(self, name).setflags(write=False)

    def report(self, rig: Rig) -> dict[str, object]:
        """Plausibility numbers: marker fit (rig units and % of head size), flagged and outlier counts,
        head rotation range, and the most active channels."""
        error = self.marker_error[np.isfinite(self.marker_error)]
        values = self.clip.values
        peaks = {}  # each solved channel's signed value farthest from 0
        for j, name in enumerate(self.clip.channels):
            if name in self.solved:
                peaks[name] = float(values[np.argmax(np.abs(values[:, j])), j])
        top = sorted(peaks, key=lambda n: abs(peaks[n]), reverse=True)[:8]
        angles = self.head.angles()
        return {
            "frames": self.clip.n_frames,
            "fps": self.clip.fps,
            "markers": self.markers.n_markers,
            "layout": self.markers.layout,
            "units": self.units,
            "marker_rms_median": float(np.median(error)) if error.size else float("nan"),
            "marker_rms_median_rel": float(np.median(error) / rig.scale) if error.size else float("nan"),
            "marker_rms_max": float(error.max()) if error.size else float("nan"),
            "flagged_frames": int(self.flagged.sum()),
            "outlier_samples": int(self.outliers.sum()),
            "head_range_deg": [float(np.degrees(np.ptp(angles[:, k]))) for k in range(3)],
            "head_residual_median": float(np.nanmedian(self.head.residual)),
            "channels_solved": len(self.solved),
            "most_active": {n: round(peaks[n], 3) for n in top},
        }


# --------------------------------------------------------------------------- smoothing


def smoothing_weight(fps: float, cutoff_hz: float) -> float:
    """λ of the Whittaker smoother whose response 1 / (1 + λ (2 − 2 cos ω)²) is ½ at ``cutoff_hz``."""
    omega = 2 * np.pi * min(cutoff_hz / fps, 0.5)
    return 1.0 / (2.0 - 2.0 * np.cos(omega)) ** 2


def smoothed_noise(noise: float, fps: float, cutoff_hz: float | None) -> float:
    """The standard deviation white ``noise`` keeps through the smoother: ``noise`` times the RMS of
    its response 1 / (1 + λ (2 − 2 cos ω)²) over the band (about 0.5 for 8 Hz at 60 fps)."""
    if cutoff_hz is None:
        return noise
    omega = np.linspace(0.0, np.pi, 2049)
    response = 1.0 / (1.0 + smoothing_weight(fps, cutoff_hz) * (2.0 - 2.0 * np.cos(omega)) ** 2)
    return float(noise * np.sqrt(np.mean(response**2)))


def _second_difference_banded(f: int, lam: float, weights: np.ndarray) -> np.ndarray:
    """Upper banded form (3, f) of diag(weights) + λ D₂ᵀ D₂ (D₂ the (f − 2, f) second difference)."""
    diagonal = np.full(f, 6.0)
    off1 = np.full(f - 1, -4.0)
    if f >= 2:
        diagonal[[0, -1]] = 1.0
        off1[[0, -1]] = -2.0
    if f >= 3:
        diagonal[[1, -2]] = 5.0
    if f == 3:
        diagonal[1] = 4.0
    ab = np.zeros((3, f))
    ab[2] = lam * diagonal + weights
    ab[1, 1:] = lam * off1
    ab[0, 2:] = lam
    return ab


def _gaps(seen: np.ndarray, longest: int) -> np.ndarray:
    """(f,) bool: frames inside runs of ``~seen`` longer than ``longest`` frames (or at either end)."""
    edges = np.diff(np.concatenate([[0], (~seen).astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)  # runs [start, end)
    out = np.zeros(len(seen), bool)
    for start, end in zip(starts, ends, strict=True):
        if end - start > longest or start == 0 or end == len(seen):
            out[start:end] = True
    return out


def smooth_markers(
    y: np.ndarray, fps: float, cutoff_hz: float, *, robust: bool = True, size: float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """Whittaker-smooth marker trajectories, filling short gaps and rejecting spikes.

    Parameters
    ----------
    y : (f, m, 3) float64
        Stabilised marker displacements, NaN where missing.
    fps, cutoff_hz : float
        Frame rate and the frequency where the response is ½.
    robust : bool
        Reweight by the smoothing residual and drop spikes beyond ``OUTLIER_SIGMAS``.
    size : float
        The head's size in the markers' units, for the floor of the robust scale
        (``SIGMA_FLOOR_REL`` of it).

    Returns
    -------
    smoothed : (f, m, 3) float64
        NaN in gaps longer than ``MAX_GAP_S`` and for markers never seen.
    outliers : (f, m) bool
    """
    f, m, _ = y.shape
    seen = np.isfinite(y).all(axis=2)
    smoothed = np.full_like(y, np.nan)
    outliers = np.zeros((f, m), bool)
    if f < 3:
        return np.where(seen[..., None], y, np.nan), outliers
    lam = smoothing_weight(fps, cutoff_hz)
    longest = max(1, round(MAX_GAP_S * fps))
    filled = np.nan_to_num(y)
    for j in range(m):
        if seen[:, j].sum() < 3:  # too few samples to smooth: kept as captured
            smoothed[:, j] = np.where(seen[:, j, None], y[:, j], np.nan)
            continue
        weights = seen[:, j].astype(np.float64)
        for _ in range(ROBUST_ROUNDS if robust else 1):
            fit = solveh_banded(_second_difference_banded(f, lam, weights), weights[:, None] * filled[:, j])
            if not robust:
                break
            residual = np.linalg.norm(filled[:, j] - fit, axis=1)
            sigma = max(np.median(residual[seen[:, j]]) / NORM_MEDIAN, SIGMA_FLOOR_REL * size)
            spike = seen[:, j] & (residual > OUTLIER_SIGMAS * sigma)
            new = np.where(seen[:, j] & ~spike, 1.0 / (1.0 + (residual / (CAUCHY_SCALE * sigma)) ** 2), 0.0)
            if np.array_equal(spike, outliers[:, j]) and np.allclose(new, weights, atol=1e-3):
                break
            outliers[:, j] = spike
            weights = new
        smoothed[:, j] = fit
        smoothed[_gaps(seen[:, j] & ~outliers[:, j], longest), j] = np.nan
    return smoothed, outliers


# --------------------------------------------------------------------------- the per-frame solve


@dataclass(frozen=True, eq=False)
class MarkerSolver:
    """The per-basis part of the marker solve (see the module docstring, step 4).

    Attributes
    ----------
    rows : (m, 3, k) float64
        P_j D_j for the k free channels: each marker's projected displacement per unit of each.
    blocks : (m, k, k) float64
        (P_j D_j)ᵀ (P_j D_j), the marker's share of the normal matrix.
    projectors : (m, 3, 3) float64
        P_j (identity for a fixed marker).
    damping : (k,) float64
    linear : (k,) float64
        The sparsity term σ.
    lower, upper : (k,) float64
    sliding : (m,) bool
        Markers whose projector is not the identity.
    """

    rows: np.ndarray
    blocks: np.ndarray
    projectors: np.ndarray
    damping: np.ndarray
    linear: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    sliding: np.ndarray

    def normal(self, weights: np.ndarray) -> np.ndarray:
        """Normal matrices (f, k, k) for marker weights (f, m)."""
        k = self.rows.shape[2]
        H = (weights @ self.blocks.reshape(len(self.blocks), k * k)).reshape(len(weights), k, k)
        H[:, np.arange(k), np.arange(k)] += self.damping
        return H

    def solve(self, y: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Activations (f, k) for displacements ``y`` (f, m, 3) (finite where ``weights`` > 0) and
        weights (f, m) ≥ 0; and the per-marker fit residuals (f, m) (projected, rig units)."""
        f, m, _ = y.shape
        y = np.where(weights[..., None] > 0, np.nan_to_num(y), 0.0)
        projected = y.copy()  # (f, m, 3): P_j y_tj (P_j is the identity but on sliding markers)
        sliding = self.sliding
        projected[:, sliding] = np.einsum("mij,fmj->fmi", self.projectors[sliding], y[:, sliding])
        flat_rows = self.rows.reshape(3 * m, -1)  # (3m, k)
        g = (weights[..., None] * projected).reshape(f, 3 * m) @ flat_rows - self.linear  # (f, k)
        x = np.empty_like(g)
        full = np.all(weights == 1.0, axis=1)
        shared = self.normal(np.ones((1, m)))[0]
        if full.any():
            x[full], ok = box_qp_frames(shared, g[full], self.lower, self.upper)
            self._fallback(np.flatnonzero(full)[~ok], shared[None], g, x)
        partial = np.flatnonzero(~full)
        for lo in range(0, len(partial), FRAME_CHUNK):
            frames = partial[lo : lo + FRAME_CHUNK]
            H = self.normal(weights[frames])
            x[frames], ok = box_qp_frames(H, g[frames], self.lower, self.upper)
            self._fallback(frames[~ok], H[~ok], g, x)
        fitted = (x @ flat_rows.T).reshape(f, m, 3)
        residual = np.linalg.norm(fitted - projected, axis=2)
        return x, residual

    def _fallback(self, frames: np.ndarray, H: np.ndarray, g: np.ndarray, x: np.ndarray) -> None:
        """Frames the compiled active set gave up on, by ``solve.box_qp`` (with its BVLS fallback)."""
        for i, t in enumerate(frames):
            Ht = H[0] if len(H) == 1 else H[i]
            x[t], done = box_qp(Ht, g[t], self.lower, self.upper, np.zeros(len(g[t])))
            if not done:
                from scipy.linalg import cholesky
                from scipy.optimize import lsq_linear

                L = cholesky(Ht)  # Ht = Lᵀ L: ‖L x − L⁻ᵀ g‖² = xᵀHx − 2gᵀx + const
                rhs = np.linalg.solve(L.T, g[t])
                x[t] = lsq_linear(L, rhs, bounds=(self.lower, self.upper), method="bvls", tol=1e-12).x


def noise_gain(solver: MarkerSolver) -> np.ndarray:
    """(k,) float64: the standard deviation of each free channel's solved value per rig unit of
    independent noise on every marker coordinate (all markers seen, bounds inactive):
    ``sqrt(diag(H⁻¹ Hₙ H⁻¹))`` with H the damped normal matrix and Hₙ its undamped part. A channel
    whose gain times the capture's noise is large compared with its range is not determined by the
    markers (two muscles that move them alike, a lid seen by no marker)."""
    undamped = solver.blocks.sum(axis=0)  # (k, k)
    inverse = np.linalg.inv(undamped + np.diag(solver.damping))
    return np.sqrt(np.maximum(np.diag(inverse @ undamped @ inverse), 0.0))


def marker_deltas(rig: Rig, basis: Basis, markers: MarkerSet) -> np.ndarray:
    """(c, m, 3) float64: each channel's displacement of each marker (barycentric on the basis's deltas)."""
    c, n, _ = basis.deltas.shape
    flat = markers.weights(rig) @ basis.deltas.transpose(1, 0, 2).reshape(n, 3 * c)  # (m, 3c)
    return flat.reshape(-1, c, 3).transpose(1, 0, 2)


def _visible_channels(basis: Basis, deltas: np.ndarray, active: Sequence[str] | None = None) -> np.ndarray:
    """(c,) bool: channels moving the markers (``deltas`` (c, m, 3)) by at least ``MIN_MOVE_REL`` of
    the strongest, among ``active`` (default: all but the gaze, ``GAZE_CHANNELS``)."""
    effect = np.sqrt(np.einsum("cmd,cmd->c", deltas, deltas))
    chosen = (
        ~np.isin(basis.channels, GAZE_CHANNELS) if active is None else np.isin(basis.channels, list(active))
    )
    return (effect > MIN_MOVE_REL * effect.max()) & chosen


def determined_channels(
    rig: Rig, basis: Basis, markers: MarkerSet, *, noise: float, tolerance: float = 0.02
) -> tuple[str, ...]:
    """The channels a marker set determines: starting from every channel the markers see (but the
    gaze, ``GAZE_CHANNELS``), drop the
    one with the largest ``noise_gain`` · ``noise`` / range until each is within ``tolerance`` of
    its range (``noise``: per-coordinate marker noise in rig units, after smoothing)."""
    deltas = marker_deltas(rig, basis, markers)
    keep = list(np.flatnonzero(_visible_channels(basis, deltas)))
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


def prepare_marker_solver(
    deltas: np.ndarray,
    markers: MarkerSet,
    lower: np.ndarray,
    upper: np.ndarray,
    *,
    regularization: float = 1e-3,
    sparsity: float = 0.0,
) -> MarkerSolver:
    """The solver for marker deltas (k, m, 3) of the free channels with bounds (k,)."""
    projectors = np.repeat(np.eye(3)[None], markers.n_markers, axis=0)
    t = markers.tangents[markers.sliding]
    projectors[markers.sliding] -= np.einsum("mi,mj->mij", t, t)
    rows = np.einsum("mij,kmj->mik", projectors, deltas)  # (m, 3, k)
    blocks = np.einsum("mik,mil->mkl", rows, rows)
    norms = np.einsum("mik,mik->k", rows, rows)  # ‖P D_i‖²
    damping = max(regularization, 1e-12) * np.maximum(norms, 1e-12 * norms.max())
    linear = np.where(lower >= 0, sparsity * norms, 0.0)
    return MarkerSolver(rows, blocks, projectors, damping, linear, lower, upper, markers.sliding.copy())


# --------------------------------------------------------------------------- the whole chain


def _marker_set(rig: Rig, trajectories: Trajectories, markers: MarkerSet | str | None) -> MarkerSet:
    if markers is None:
        markers = layout_for(trajectories.names)
    if not isinstance(markers, MarkerSet):
        markers = marker_set(rig, markers)
    common = [n for n in trajectories.names if n in set(markers.names)]
    if len(common) < 4:
        raise CaptureError(
            f"{trajectories.source}: only {len(common)} of its {trajectories.n_points} points are markers of "
            f"the {markers.layout!r} layout ({', '.join(markers.names[:4])}, …); "
            "name the points as the layout "
            "does or pass a marker file"
        )
    return markers.select(common)


def stable_markers(rig: Rig, basis: Basis, deltas: np.ndarray, markers: MarkerSet) -> np.ndarray:
    """(m,) bool: the markers to fit the head's motion to: those no channel moves by more than
    ``STABLE_MOTION_REL`` of the head (at the channel's extreme); if fewer than
    ``MIN_STABLE_MARKERS``, the layout's stable markers; else the least-moving ones."""
    lower, upper = channel_bounds(basis, rig)
    extent = np.maximum(np.abs(lower), np.abs(upper))
    motion = (np.linalg.norm(deltas, axis=2) * extent[:, None]).max(axis=0)  # (m,) rig units
    still = motion <= STABLE_MOTION_REL * rig.scale
    for candidates in (still, markers.stable):
        if candidates.sum() >= MIN_STABLE_MARKERS:
            return candidates
    return motion <= np.sort(motion)[min(len(motion), 2 * MIN_STABLE_MARKERS) - 1]


def _neutral_points(points: np.ndarray, outliers: np.ndarray, neutral_frame: int, fps: float) -> np.ndarray:
    """(m, 3): each marker's median over ``NEUTRAL_WINDOW_S`` around the neutral frame, spikes left out
    (NaN for a marker not seen there). A single frame would carry its noise, or a spike the smoother's
    ends let through, into every frame's displacement."""
    half = max(1, round(NEUTRAL_WINDOW_S * fps / 2))
    window = slice(max(0, neutral_frame - half), neutral_frame + half + 1)
    sample = np.where(outliers[window][..., None], np.nan, points[window])
    with warnings.catch_warnings():  # a marker unseen in the whole window: NaN, handled by the caller
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmedian(sample, axis=0)


def _neutral_reference(neutral: np.ndarray, rig_points: np.ndarray, calibration: Similarity) -> np.ndarray:
    """The markers' neutral positions in the rig's frame: the calibrated ``neutral`` (m, 3) where seen,
    else the rig's virtual marker."""
    seen = np.isfinite(neutral).all(axis=1)
    reference = rig_points.copy()
    reference[seen] = calibration.apply(neutral[seen])
    return reference


def _robust_weights(residual: np.ndarray, usable: np.ndarray, floor: float) -> np.ndarray:
    """Cauchy weights (f, m) of the model residuals with one scale for all markers (a marker that is
    wrong in every frame must not set its own scale), 0 beyond ``MODEL_OUTLIER_SIGMAS``."""
    sigma = max(float(np.median(residual[usable])) / NORM_MEDIAN, floor) if usable.any() else floor
    keep = usable & (residual <= MODEL_OUTLIER_SIGMAS * sigma)
    return np.where(keep, 1.0 / (1.0 + (residual / (CAUCHY_SCALE * sigma)) ** 2), 0.0)


def solve_performance(
    rig: Rig,
    trajectories: Trajectories,
    *,
    basis: Basis,
    markers: MarkerSet | str | os.PathLike[str] | None = None,
    neutral_frame: int = 0,
    active: Sequence[str] | None = None,
    cutoff_hz: float | None = CUTOFF_HZ,
    regularization: float = 1e-3,
    sparsity: float = 0.0,
    robust: bool = True,
    refine: int = 0,
    engine=None,
    progress: Progress | None = None,
) -> Performance:
    """Channel activations and head motion of ``rig`` that reproduce a captured performance.

    Parameters
    ----------
    rig : Rig
    trajectories : Trajectories
        Markers or landmarks; image landmarks (d = 2) are lifted with the rig's depth
        (``capture.lift.lift_landmarks``).
    basis : Basis
        The rig baked with the engine to solve against (``bake(make_engine(rig, name)).basis``).
    markers : MarkerSet, layout name or JSON file, optional
        Told from the point names by default.
    neutral_frame : int
        A frame with a neutral expression (the paper's first frame), for the calibration.
    active : sequence of str, optional
        Channels to solve for (default: every channel the markers see but the gaze).
    cutoff_hz : float or None
        Temporal smoothing cutoff (``smooth_markers``); None solves each frame on its own.
    regularization, sparsity : float
        See the module docstring (step 4).
    robust : bool
        Reject spikes and reweight markers the model cannot explain.
    refine : int
        Gauss-Newton steps against ``engine`` (an ``Engine`` of ``rig``) after the linear solve.
    progress : callable(stage, done, total), optional

    Raises
    ------
    CaptureError
        Unknown layout, too few markers for the channels, no usable neutral frame, a mirror-image
        or wrongly scaled capture, no frame with a head fit.
    """
    step = progress or (lambda stage, done, total: None)
    if refine and engine is None:
        raise CaptureError("refine= needs engine= (the Engine the basis was baked from)")
    markers = _marker_set(rig, trajectories, markers)
    trajectories = trajectories.select(markers.names)
    if trajectories.dims == 2:
        trajectories = lift_landmarks(trajectories, markers.positions(rig))
    points = trajectories.positions  # (f, m, 3) capture units
    f, m, _ = points.shape
    if not 0 <= neutral_frame < f:
        raise CaptureError(f"neutral_frame {neutral_frame} is outside the capture's {f} frames")
    seen = np.isfinite(points).all(axis=2)
    never = [markers.names[j] for j in np.flatnonzero(~seen.any(axis=0))]
    if never:
        warnings.warn(
            f"{trajectories.source}: marker(s) {', '.join(never[:5])} never appear; solving without them",
            MimeticWarning,
            stacklevel=2,
        )
    rig_points = markers.positions(rig)
    neutral = _neutral_points(points, np.zeros((f, m), bool), neutral_frame, trajectories.fps)
    at_neutral = np.isfinite(neutral).all(axis=1)
    if at_neutral.sum() < max(4, m // 2):
        raise CaptureError(
            f"{trajectories.source}: the neutral frame {neutral_frame} shows {at_neutral.sum()} of {m} "
            "markers; "
            "pick a frame with a neutral face and most markers seen (neutral_frame=, CLI --neutral-frame)"
        )
    step("calibrate", 0, 1)
    calibration, units = calibrate(
        rig_points[at_neutral],
        neutral[at_neutral],
        units=trajectories.units,
        rig_units=rig.units,
        source=trajectories.source,
    )
    step("calibrate", 1, 1)
    outliers = np.zeros((f, m), bool)
    if cutoff_hz is not None:
        step("smooth", 0, 1)
        size = rig.scale / calibration.scale  # the head's size in capture units
        points, outliers = smooth_markers(points, trajectories.fps, cutoff_hz, robust=robust, size=size)
        step("smooth", 1, 1)
    reference = _neutral_reference(
        _neutral_points(points, outliers, neutral_frame, trajectories.fps), rig_points, calibration
    )
    deltas = marker_deltas(rig, basis, markers)  # (c, m, 3)
    # the channels the markers see, and whether the markers can tell them apart
    unknown = [n for n in active or () if n not in basis.channels]
    if unknown:
        raise CaptureError(f"active names unknown channel(s) {', '.join(unknown[:5])}")
    free_index = np.flatnonzero(_visible_channels(basis, deltas, active))
    counts = seen.sum(axis=1)
    typical = int(np.median(counts[counts > 0])) if counts.any() else 0  # empty frames are flagged later
    constraints = 3 * typical - int((markers.sliding & seen.any(axis=0)).sum())
    if constraints < len(free_index):
        raise CaptureError(
            f"{trajectories.source}: {typical} markers per frame ({constraints} coordinates) cannot "
            f"determine {len(free_index)} channels; pass fewer channels (active=, CLI --channels) or "
            "capture more markers"
        )
    stable = stable_markers(rig, basis, deltas, markers)
    head = head_motion(
        points[:, stable],
        reference[stable],
        calibration,
        pivot=rig.bone("head").head,
        size=rig.scale,
        fixed_scale=units != "px",
    )
    # stabilised displacements in the rig's frame
    S = head.to_rig
    moved = points @ S[:, :3, :3].transpose(0, 2, 1) + S[:, None, :3, 3]
    y = moved - reference[None]  # (f, m, 3), NaN where missing
    usable = np.isfinite(y).all(axis=2) & ~outliers
    lower, upper = (bound[free_index] for bound in channel_bounds(basis, rig))
    solver = prepare_marker_solver(
        deltas[free_index], markers, lower, upper, regularization=regularization, sparsity=sparsity
    )
    weights = usable.astype(np.float64)
    x, residual = solver.solve(y, weights)
    # the head again, from every fixed marker, with the expression predicted by the solve taken out;
    # robust weights from the solve's residuals
    flat_deltas = deltas[free_index].reshape(len(free_index), 3 * m)
    floor = SIGMA_FLOOR_REL * rig.scale

    def realign(model: np.ndarray) -> tuple[HeadMotion, np.ndarray]:
        """The head fitted to the trusted fixed markers less the ``model`` (f, m, 3) expression; the
        stabilised displacements y."""
        fixed = (weights > 0.5) & (~markers.sliding | stable)  # the first fit's markers, and any fixed one
        motion = head_motion(
            np.where(fixed[..., None], points, np.nan),
            reference + model,
            calibration,
            pivot=rig.bone("head").head,
            size=rig.scale,
            fixed_scale=units != "px",
        )
        S = motion.to_rig
        return motion, points @ S[:, :3, :3].transpose(0, 2, 1) + S[:, None, :3, 3] - reference[None]

    for round_ in range(HEAD_ROUNDS):
        step("solve", round_, HEAD_ROUNDS)
        if robust:
            weights = _robust_weights(residual, usable, floor)
        head, y = realign((x @ flat_deltas).reshape(f, m, 3))
        previous = x
        x, residual = solver.solve(y, weights)
        if np.abs(x - previous).max(initial=0.0) < ROUNDS_TOLERANCE:
            break
    outliers |= usable & (weights == 0)
    usable &= weights > 0
    solved = tuple(basis.channels[j] for j in free_index)
    W = markers.weights(rig)
    for k in range(refine):  # Gauss-Newton against the engine: its markers, not the basis's, at x
        step("refine", k, refine)
        model = _engine_markers(engine, rig, solved, W, W @ basis.neutral, x)
        head, y = realign(model)
        x, residual = solver.solve(y - (model - (x @ flat_deltas).reshape(f, m, 3)), weights)
    step("solve", HEAD_ROUNDS, HEAD_ROUNDS)
    values = np.zeros((f, len(rig.channels)))
    for i, j in enumerate(free_index):
        values[:, rig.channel_index(basis.channels[j])] = x[:, i]
    angles = head.angles()
    flagged = (
        ~head.fitted
        | (usable.sum(axis=1) < MIN_SEEN_FRACTION * m)
        | (trajectories.confidence < MIN_CONFIDENCE)
    )
    for k, name in enumerate(HEAD_CHANNELS):
        if name in rig.channel_names:
            ch = rig.channel(name)
            flagged |= (angles[:, k] < ch.minimum) | (angles[:, k] > ch.maximum)
            values[:, rig.channel_index(name)] = np.clip(angles[:, k], ch.minimum, ch.maximum)
    with np.errstate(invalid="ignore", divide="ignore"):
        error = np.sqrt((np.where(usable, residual, 0.0) ** 2).sum(axis=1) / usable.sum(axis=1))
    if flagged.any():
        first = np.flatnonzero(flagged)[:5].tolist()
        warnings.warn(
            f"{trajectories.source}: {flagged.sum()} of {f} frames are flagged (few markers seen, no face, "
            "no "
            f"head fit or a head angle out of range), first {first}; see Performance.flagged",
            MimeticWarning,
            stacklevel=2,
        )
    log.debug("solve_performance: %d frames, %d markers, %d channels", f, m, len(solved))
    return Performance(
        clip=Clip(rig.channel_names, values, trajectories.fps),
        head=head,
        markers=markers,
        calibration=calibration,
        units=units,
        marker_error=error,
        used=usable,
        outliers=outliers,
        flagged=flagged,
        solved=solved,
        neutral_frame=neutral_frame,
    )


def _engine_markers(
    engine, rig: Rig, channels: Sequence[str], W, neutral: np.ndarray, x: np.ndarray
) -> np.ndarray:
    """Marker displacements (f, m, 3) of the full engine posed at activations ``x`` (f, k) of
    ``channels``, from the markers' rest ``neutral`` (m, 3); ``W`` the markers' (m, n) weights."""
    pose = np.zeros(len(rig.channels))
    index = [rig.channel_index(name) for name in channels]
    out = np.empty((len(x), *neutral.shape))
    for t in range(len(x)):
        pose[index] = x[t]
        out[t] = W @ engine.deform(pose) - neutral
    return out
