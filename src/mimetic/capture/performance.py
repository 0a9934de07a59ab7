"""Captured markers → the rig's channel activations and head motion (the paper's actuation estimation).

``solve_performance(rig, trajectories, basis=...)`` runs the whole chain:

1. **Markers**: the captured points are matched by name to a ``MarkerSet`` on the rig (the layout
   is told from the names: ``ibug68_*``, ``mediapipe_*`` or the paper's). The layout's contour
   points (the jaw line) slide only for a tracker's landmarks (``Trajectories.tracked``): a marker
   stuck on the skin is a point of the skin wherever it is.
2. **Smoothing** (``capture.smooth``): each marker coordinate is Whittaker-smoothed over the take
   (spikes found and left out, short gaps filled), which also measures the capture's noise σ.
3. **Calibration** (``capture.calibrate``): the neutral (each marker's median over
   ``NEUTRAL_WINDOW_S`` around the neutral frame) is mapped onto the rig by a similarity, and the
   layout's markers are moved to where this performer's are (unless the markers were placed on an
   earlier take).
4. **Head motion and expression**, alternating (``HEAD_ROUNDS`` at most):

   * the head: a rigid fit of each frame's markers to where the expression puts them
     (``capture.head``), each marker trusted as ``head_weights`` says: by the noise and by how far
     the expression moves it, so the markers the face barely moves carry the head; contour
     markers count only across their contour;
   * the expression: per frame, bounded least squares on the basis at the markers with a shape
     prior (``capture.expression``): ::

         minimise Σ_j w_tj ‖P_j (D_j a − y_tj)‖² + aᵀ Λ a + σᵀ a        lo ≤ a ≤ hi

5. **Outliers** (``robust``): a marker sample farther from the solved expression than the capture's
   noise allows by far (``GROSS_SIGMAS`` σ) and than ``GROSS_REL`` of the head (a mislabelled
   marker, a glitch the smoother kept) is left out and the frame solved again. What the rig cannot
   express is never judged an outlier: the threshold is the capture's noise and a gross error, not
   the model's typical residual.
6. Optionally (``refine``), Gauss-Newton steps against the full engine rather than its
   linearisation.
"""

from __future__ import annotations

import logging
import os
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from mimetic.capture.calibrate import Calibration, calibrate_performer
from mimetic.capture.camera import PinholeCamera
from mimetic.capture.expression import (
    marker_deltas,
    prepare_marker_solver,
    skin_gram,
    visible_channels,
)
from mimetic.capture.head import HeadMotion, head_motion, head_weights
from mimetic.capture.markers import MarkerSet, layout_for, marker_set
from mimetic.capture.smooth import CHI_MEDIAN, CUTOFF_HZ, smooth_points
from mimetic.capture.solve import channel_bounds
from mimetic.capture.trajectories import CaptureError, Trajectories
from mimetic.engines.basis import Basis
from mimetic.errors import MimeticWarning
from mimetic.rig.activations import Clip
from mimetic.rig.model import Rig

log = logging.getLogger(__name__)

Progress = Callable[[str, int, int], None]

HEAD_CHANNELS = ("head_yaw", "head_pitch", "head_roll")
SHAPE_MOTION_REL = 0.008
"""τ of the shape prior (``capture.expression``), as a fraction of the head's size: how far a skin
coordinate typically moves in an expression. The prior's weight is ν = (σ_e / τ)², σ_e what the
solve cannot fit per marker coordinate: the capture's noise, and how far the rig is from the
performer's face. Chosen on the calibration heads of ``benchmarks/validate_capture.py`` (markers
route, κ 0.5): gap to the ceiling 11.1 points at τ 0.004, 6.1 at 0.006, 4.5 at 0.008, 4.4 at
0.013, 5.1 without the prior; moving frames worse than rest 0.1 %, 0.2 %, 0.5 %, 1.0 %, 1.2 %."""
SPARSITY = 0.005
"""Weight of the markers' L1 term (``capture.expression``: σ_i = ``SPARSITY`` · ‖D_i‖² on each
one-sided channel, so a channel that moves the markers little is not kept on for a few tenths of a
millimetre it explains): with the shape prior alone, 49 channels from 68 markers keep lip
depressors and a lid raiser on in acts that do not use them. Chosen on the calibration heads of
``benchmarks/validate_capture.py`` (markers route; gap to the ceiling, mean of the three): 5.0
points without it, 4.6 at 0.005, 4.7 at 0.01, 5.4 at 0.03 (ICT's neutral alone: 8.2 at 0.1, 19.5
at 0.3). Checked on the check heads: 5.6 → 5.1 (3.6 → 3.2, 6.4 → 6.1, 6.9 → 6.1). Image landmarks
do without it (their solve has the library prior)."""
HEAD_ROUNDS = 8
ROUNDS_TOLERANCE = 1e-3
"""The alternation stops once no activation moves by more than this between rounds (activation units
or radians: far below what a capture's noise allows)."""
NEUTRAL_WINDOW_S = 0.2
"""The neutral pose is each marker's median (smoothed, spikes left out) over this long a window
around the neutral frame."""
GROSS_SIGMAS = 8.0
GROSS_REL = 0.03
"""A marker sample is an outlier when it is farther from the solved expression than both
``GROSS_SIGMAS`` times the capture's noise (3D) and this fraction of the head (6.5 mm on a 22 cm
head)."""
MIN_SEEN_FRACTION = 0.5
"""Frames that see fewer than this fraction of the markers are flagged."""
MIN_CONFIDENCE = 0.5
"""Frames whose tracking confidence is below this are flagged (FaceDetection's own threshold)."""


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
    calibration : Calibration
        The neutral mapped onto the rig, and the markers placed on this performer
        (``calibration.markers``: save them with ``save_marker_set`` for the performer's next take).
    marker_error : (f,) float64
        RMS distance between the fitted and the (stabilised, smoothed) markers a frame used, in
        rig units; nan for a frame that used none.
    noise : float
        The capture's noise per coordinate, measured by the smoother, in rig units.
    used : (f, m) bool
        The markers each frame's solve used (seen or filled, not outliers).
    outliers : (f, m) bool
        Marker samples rejected as spikes or gross errors.
    flagged : (f,) bool
        Frames to distrust: little seen, no face, no head fit, or a head angle out of range.
    solved : tuple of str
        The channels solved for; the others are held at 0 (no marker sees them, or not ``active``).
    neutral_frame : int
    camera : PinholeCamera or None
        For image landmarks, the camera they were solved through (its focal length given or
        estimated).
    """

    clip: Clip
    head: HeadMotion
    calibration: Calibration
    marker_error: np.ndarray
    noise: float
    used: np.ndarray
    outliers: np.ndarray
    flagged: np.ndarray
    solved: tuple[str, ...]
    neutral_frame: int
    camera: PinholeCamera | None = None

    def __post_init__(self) -> None:
        for name in ("marker_error", "used", "outliers", "flagged"):
            getattr(self, name).setflags(write=False)

    @classmethod
    def assemble(
        cls,
        rig: Rig,
        trajectories: Trajectories,
        *,
        basis: Basis,
        free: np.ndarray,
        x: np.ndarray,
        head: HeadMotion,
        calibration: Calibration,
        marker_error: np.ndarray,
        noise: float,
        used: np.ndarray,
        outliers: np.ndarray,
        neutral_frame: int,
        camera: PinholeCamera | None = None,
    ) -> Performance:
        """The performance of the solved activations ``x`` (f, k) of the basis channels ``free`` (k,)
        and the head's motion: every rig channel in a clip (the head's angles clipped to their
        ranges), the frames to distrust flagged (and a warning saying how many)."""
        f, m = used.shape
        values = np.zeros((f, len(rig.channels)))
        for i, j in enumerate(free):
            values[:, rig.channel_index(basis.channels[j])] = x[:, i]
        angles = head.angles()
        flagged = (
            ~head.fitted
            | (used.sum(axis=1) < MIN_SEEN_FRACTION * m)
            | (trajectories.confidence < MIN_CONFIDENCE)
        )
        for k, name in enumerate(HEAD_CHANNELS):
            if name in rig.channel_names:
                ch = rig.channel(name)
                flagged |= (angles[:, k] < ch.minimum) | (angles[:, k] > ch.maximum)
                values[:, rig.channel_index(name)] = np.clip(angles[:, k], ch.minimum, ch.maximum)
        if flagged.any():
            first = np.flatnonzero(flagged)[:5].tolist()
            warnings.warn(
                f"{trajectories.source}: {flagged.sum()} of {f} frames are flagged (few markers seen, no "
                f"face, no head fit or a head angle out of range), the first {first}; the report lists them",
                MimeticWarning,
                stacklevel=4,
            )
        return cls(
            clip=Clip(rig.channel_names, values, trajectories.fps),
            head=head,
            calibration=calibration,
            marker_error=marker_error,
            noise=noise,
            used=used,
            outliers=outliers,
            flagged=flagged,
            solved=tuple(basis.channels[j] for j in free),
            neutral_frame=neutral_frame,
            camera=camera,
        )

    @property
    def markers(self) -> MarkerSet:
        """The markers used, as placed on this performer (the captured points the rig has, in the
        capture's order)."""
        return self.calibration.markers

    @property
    def units(self) -> str | None:
        """The capture's length units (guessed from the calibration's scale when the file had none)."""
        return self.calibration.units

    def report(self, rig: Rig) -> dict[str, object]:
        """Plausibility numbers: marker fit (rig units and % of head size), noise, flagged and outlier
        counts, head rotation range, how far calibration moved the markers, the most active channels."""
        error = self.marker_error[np.isfinite(self.marker_error)]
        values = self.clip.values
        peaks = {}  # each solved channel's signed value farthest from 0
        for j, name in enumerate(self.clip.channels):
            if name in self.solved:
                peaks[name] = float(values[np.argmax(np.abs(values[:, j])), j])
        top = sorted(peaks, key=lambda n: abs(peaks[n]), reverse=True)[:8]
        angles = self.head.angles()
        moved = self.calibration.moved
        return {
            "frames": self.clip.n_frames,
            "fps": self.clip.fps,
            "markers": self.markers.n_markers,
            "layout": self.markers.layout,
            "units": self.units,
            "noise": self.noise,
            "markers_moved_median": float(np.median(moved)),
            "markers_moved_max": float(moved.max(initial=0.0)),
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


def _marker_set(rig: Rig, trajectories: Trajectories, markers: MarkerSet | str | None) -> MarkerSet:
    if markers is None:
        markers = layout_for(trajectories.names)
    if not isinstance(markers, MarkerSet):
        markers = marker_set(rig, markers)
    common = [n for n in trajectories.names if n in set(markers.names)]
    if len(common) < 4:
        raise CaptureError(
            f"{trajectories.source}: only {len(common)} of its {trajectories.n_points} points are markers of "
            f"the {markers.layout!r} layout ({', '.join(markers.names[:4])}, …); name the points as the "
            "layout does or give a marker file"
        )
    return markers.select(common)


def neutral_points(points: np.ndarray, outliers: np.ndarray, neutral_frame: int, fps: float) -> np.ndarray:
    """(m, 3): each marker's median over ``NEUTRAL_WINDOW_S`` around the neutral frame, spikes left out
    (NaN for a marker not seen there). A single frame would carry its noise, or a spike the smoother's
    ends let through, into every frame's displacement."""
    half = max(1, round(NEUTRAL_WINDOW_S * fps / 2))
    window = slice(max(0, neutral_frame - half), neutral_frame + half + 1)
    sample = np.where(outliers[window][..., None], np.nan, points[window])
    with warnings.catch_warnings():  # a marker unseen in the whole window: NaN, handled by the caller
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nanmedian(sample, axis=0)


def _size_ratio(neutral: np.ndarray, markers: MarkerSet, rig: Rig) -> float:
    """Capture units per rig unit, roughly: the spread of the neutral's seen markers (m, 3) over the
    spread of the same markers on the rig."""
    seen = np.isfinite(neutral).all(axis=1)
    capture, layout = neutral[seen], markers.positions(rig)[seen]
    spread = np.linalg.norm(capture - capture.mean(axis=0), axis=1).mean()
    return float(spread / np.linalg.norm(layout - layout.mean(axis=0), axis=1).mean())


def marker_reach(deltas: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    """(m,) how far the channels can move each marker, rig units: the root sum of squares over the
    channels (``deltas`` (k, m, 3)) of their motion at their extremes."""
    extent = np.maximum(np.abs(lower), np.abs(upper))  # (k,)
    return np.sqrt(np.einsum("kmd,k->m", deltas**2, extent**2))


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
    shape_prior: float | None = None,
    sparsity: float = SPARSITY,
    robust: bool = True,
    place: bool | None = None,
    focal: float | None = None,
    fov_deg: float | None = None,
    refine: int = 0,
    engine=None,
    progress: Progress | None = None,
) -> Performance:
    """Channel activations and head motion of ``rig`` that reproduce a captured performance.

    Parameters
    ----------
    rig : Rig
    trajectories : Trajectories
        Markers or landmarks in 3D; image landmarks (d = 2, or pixels from ``track_video``) are
        solved through a perspective camera (``capture.reprojection``).
    basis : Basis
        The rig baked with the engine to solve against (``bake(make_engine(rig, name)).basis``).
    markers : MarkerSet, layout name or JSON file, optional
        Told from the point names by default.
    neutral_frame : int
        A frame with a neutral expression (the paper's first frame), for the calibration.
    active : sequence of str, optional
        Channels to solve for (default: every channel the markers see but the gaze and the nose's
        small muscles, ``expression.NOSE_CHANNELS``).
    cutoff_hz : float or None
        Temporal smoothing cutoff (``capture.smooth``); None solves each frame on its own.
    regularization, sparsity : float
        The ridge λ and the L1 weight of the markers' expression solve (``capture.expression``;
        ``SPARSITY`` by default; image landmarks do without it).
    shape_prior : float or None
        The shape prior's weight ν; None ties it to the misfit, ν = (σ_e / τ)² (``SHAPE_MOTION_REL``),
        remeasured after every solve; 0 solves without it. Image landmarks add the library prior at
        ``reprojection.LIBRARY_GAIN`` times ν (none with 0).
    robust : bool
        Reject spikes and gross errors.
    place : bool or None
        Move the markers to the performer's at the neutral (``capture.calibrate``). None: unless the
        markers were placed on an earlier take (``MarkerSet.placed``).
    focal, fov_deg : float, optional
        Image landmarks only: the camera's focal length in pixels, or its vertical field of view in
        degrees; estimated from the take when neither is given (``camera.estimate_focal``).
    refine : int
        Gauss-Newton steps against ``engine`` (an ``Engine`` of ``rig``) after the linear solve
        (3D markers only).
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
    unknown = [n for n in active or () if n not in basis.channels]
    if unknown:
        raise CaptureError(f"active names unknown channel(s) {', '.join(unknown[:5])}")
    # 1. markers; contour markers slide only when the points are a tracker's outline
    markers = _marker_set(rig, trajectories, markers)
    trajectories = trajectories.select(markers.names)
    f = trajectories.n_frames
    if not 0 <= neutral_frame < f:
        raise CaptureError(f"neutral_frame {neutral_frame} is outside the capture's {f} frames")
    place = not markers.placed if place is None else place
    if trajectories.dims == 2 or trajectories.units == "px":
        from mimetic.capture.reprojection import solve_image

        return solve_image(
            rig,
            trajectories,
            markers,
            basis=basis,
            neutral_frame=neutral_frame,
            active=active,
            cutoff_hz=cutoff_hz,
            regularization=regularization,
            shape_prior=shape_prior,
            shape_motion=SHAPE_MOTION_REL,
            robust=robust,
            place=place,
            focal=focal,
            fov_deg=fov_deg,
            step=step,
        )
    if not trajectories.tracked:
        markers = markers.replace(
            sliding=np.zeros(markers.n_markers, bool), tangents=np.zeros((markers.n_markers, 3))
        )
    points = trajectories.positions  # (f, m, 3) capture units
    m = points.shape[1]
    seen = np.isfinite(points).all(axis=2)
    never = [markers.names[j] for j in np.flatnonzero(~seen.any(axis=0))]
    if never:
        warnings.warn(
            f"{trajectories.source}: marker(s) {', '.join(never[:5])} never appear; solving without them",
            MimeticWarning,
            stacklevel=2,
        )
    rough = neutral_points(points, np.zeros((f, m), bool), neutral_frame, trajectories.fps)
    if np.isfinite(rough).all(axis=1).sum() < max(4, m // 2):
        raise CaptureError(
            f"{trajectories.source}: the neutral frame {neutral_frame} shows "
            f"{np.isfinite(rough).all(axis=1).sum()} of {m} markers; pick a frame with a neutral face "
            "and most markers seen (CLI --neutral-frame)"
        )
    deltas_layout = marker_deltas(rig, basis, markers)
    free_index = np.flatnonzero(visible_channels(basis, deltas_layout, active))
    counts = seen.sum(axis=1)
    typical = int(np.median(counts[counts > 0])) if counts.any() else 0  # empty frames are flagged later
    constraints = 3 * typical - int((markers.sliding & seen.any(axis=0)).sum())
    if constraints < len(free_index):
        raise CaptureError(
            f"{trajectories.source}: {typical} markers per frame ({constraints} coordinates) cannot "
            f"determine {len(free_index)} channels; solve fewer channels (CLI --channels) or capture "
            "more markers"
        )

    # 2. smoothing: spikes, gaps, the capture's noise (capture units)
    step("smooth", 0, 1)
    ratio = _size_ratio(rough, markers, rig)  # capture units per rig unit, roughly
    smoothed = smooth_points(points, trajectories.fps, cutoff_hz, robust=robust, size=rig.scale * ratio)
    points, outliers = smoothed.points, smoothed.outliers
    step("smooth", 1, 1)

    # 3. calibration and the performer's markers
    step("calibrate", 0, 1)
    neutral = neutral_points(points, outliers, neutral_frame, trajectories.fps)
    window = max(1, round(NEUTRAL_WINDOW_S * trajectories.fps))
    calibration = calibrate_performer(
        rig,
        markers,
        neutral,
        units=trajectories.units,
        place=place,
        noise=smoothed.noise * smoothed.kept / ratio / np.sqrt(window),
        source=trajectories.source,
    )
    markers, reference = calibration.markers, calibration.reference
    noise = smoothed.noise * calibration.similarity.scale  # rig units, per coordinate, raw
    sigma = noise * smoothed.kept  # after smoothing
    step("calibrate", 1, 1)

    # 4. the expression solver at the placed markers, then head and expression in turn
    deltas = marker_deltas(rig, basis, markers)[free_index]  # (k, m, 3)
    lower, upper = (bound[free_index] for bound in channel_bounds(basis, rig))
    solver = prepare_marker_solver(
        deltas,
        markers,
        lower,
        upper,
        regularization=regularization,
        sparsity=sparsity,
        skin=skin_gram(rig, basis, free_index) if shape_prior != 0 else None,
    )
    usable = np.isfinite(points).all(axis=2) & ~outliers & calibration.usable
    trust = usable.astype(np.float64)
    flat_deltas = deltas.reshape(len(free_index), 3 * m)
    tau = SHAPE_MOTION_REL * rig.scale
    fixed_scale = calibration.units != "px"

    def shape_weight(residual: np.ndarray | None) -> float:
        """ν: fixed, or (σ_e / τ)² with σ_e the solve's misfit per coordinate (``residual`` (f, m)),
        at least the noise."""
        if shape_prior is not None:
            return shape_prior
        misfit = np.zeros(0) if residual is None else residual[usable]
        return (max(float(np.median(misfit)) / CHI_MEDIAN[3] if misfit.size else 0.0, sigma) / tau) ** 2

    def realign(motion: np.ndarray, model: np.ndarray) -> HeadMotion:
        """The head fitted to the markers, each trusted by how far the expression moves it
        (``motion`` (f, m) or (m,), rig units), landing where ``model`` (f, m, 3) puts them."""
        return head_motion(
            points,
            reference + model,
            head_weights(usable, motion, sigma),
            calibration.similarity,
            projectors=solver.projectors,
            pivot=rig.bone("head").head,
            size=rig.scale,
            fixed_scale=fixed_scale,
        )

    head = realign(marker_reach(deltas, lower, upper), np.zeros((f, m, 3)))
    x = np.zeros((f, len(free_index)))
    nu = shape_weight(None)
    for round_ in range(HEAD_ROUNDS):
        step("solve", round_, HEAD_ROUNDS)
        previous = x
        x, residual = solver.solve(head.stabilise(points) - reference, trust, nu)
        nu = shape_weight(residual)
        model = (x @ flat_deltas).reshape(f, m, 3)
        head = realign(np.linalg.norm(model, axis=2), model)
        if np.abs(x - previous).max(initial=0.0) < ROUNDS_TOLERANCE:
            break
    x, residual = solver.solve(head.stabilise(points) - reference, trust, nu)

    # 5. gross errors: far beyond the noise and beyond a gross fraction of the head
    if robust:
        gross = usable & (residual > max(GROSS_SIGMAS * np.sqrt(3) * sigma, GROSS_REL * rig.scale))
        if gross.any():
            outliers |= gross
            usable &= ~gross
            trust = usable.astype(np.float64)
            x, residual = solver.solve(head.stabilise(points) - reference, trust, nu)

    # 6. Gauss-Newton against the engine: its markers, not the basis's, at x
    solved = tuple(basis.channels[j] for j in free_index)
    W = markers.weights(rig)
    for k in range(refine):
        step("refine", k, refine)
        model = _engine_markers(engine, rig, solved, W, W @ basis.neutral, x)
        head = realign(np.linalg.norm(model, axis=2), model)
        linear = (x @ flat_deltas).reshape(f, m, 3)
        x, residual = solver.solve(head.stabilise(points) - reference - (model - linear), trust, nu)
    step("solve", HEAD_ROUNDS, HEAD_ROUNDS)

    # 7. the clip, flags and the report
    with np.errstate(invalid="ignore", divide="ignore"):
        error = np.sqrt((np.where(usable, residual, 0.0) ** 2).sum(axis=1) / usable.sum(axis=1))
    log.debug(
        "solve_performance: %d frames, %d markers, %d channels, noise %.3g", f, m, len(free_index), noise
    )
    return Performance.assemble(
        rig,
        trajectories,
        basis=basis,
        free=free_index,
        x=x,
        head=head,
        calibration=calibration,
        marker_error=error,
        noise=noise,
        used=usable,
        outliers=outliers,
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
