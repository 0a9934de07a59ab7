"""Image landmarks → head pose and activations through a perspective camera (video capture).

A video's landmarks say where the face's points land in the picture, nothing about their depth.
They are solved on their reprojection error, with the rig's own depth::

    minimise Σ_j c_tj ‖Q_tj (π(R_t (N_j + D_j a) + t_t) − u_tj)‖² + s_t² aᵀ Λ a
             + μ s_t² min_{w ≥ 0} ‖S^½ (a − Mᵀ w)‖²                                     lo ≤ a ≤ hi

* π: a pinhole camera (``capture.camera``); R_t, t_t the head's pose in the camera in frame t. The
  face is taken to be the rig's size: one picture cannot tell a larger face from a nearer one, so
  the scale is fixed once and the depth follows.
* N_j the marker's reference (on its landmark's ray at the neutral, at the rig's depth there), D_j
  its displacement per unit of each channel; u_tj the landmark; Q_tj the identity, or for a
  tracker's contour point (the face's oval) the projector across the contour as the image shows it.
* c_tj the landmark's confidence: how squarely the skin under it faces the camera (a point on the
  far cheek of a turned head, seen edge-on, counts for little; one turned away, nothing).
* Λ the expression solve's prior (``capture.expression``: ridge and shape prior ν S, S the skin's
  motion per unit of ν), in pixels by the face's scale s_t (pixels per rig unit at its depth).
* The **library prior**: M the ARKit table's shapes as activations (``expression.library_directions``),
  so the face is drawn toward non-negative combinations of them, weighed by how far its skin would
  move off them. One camera sees a pucker narrow the lips, not push them forward; the table says the
  two go together. With a perfect tracker (the true image points) it takes ICT's captured take from
  58.6 to 55.5 % face residual, on MediaPipe's video from 78.0 to 74.8 %. Its weight μ is
  ``LIBRARY_GAIN`` ν.

The chain (``solve_image``):

1. **Smoothing** (``capture.smooth``) in pixels: spikes, short gaps, the tracker's noise.
2. **Camera**: the focal length given (``focal`` in pixels or ``fov_deg``), else estimated from the
   take (``camera.estimate_focal``: the field of view under which the points no channel moves stay
   most rigid).
3. **Calibration** at the neutral (``calibrate_image``): the pose of the layout's markers, then each
   marker moved to where its landmark's ray meets the rig's skin (the performer's own points), pose
   and placement in turn; each marker's reference on its landmark's ray.
4. **Pose and expression** per frame, alternately (``ImageModel``): the pose by Gauss-Newton, each
   landmark trusted by the noise, by how far the expression moves it and by how far it strays from
   the solved face over the take (a tracker's point on featureless skin drifts as the head turns);
   the expression with the projection linearised at that pose, a box-constrained quadratic
   programme per frame (``capture.qp``).
5. **Outliers**: a landmark farther from the solved face than ``GROSS_SIGMAS`` times the tracker's
   noise and ``GROSS_REL`` of the head (a landmark that jumped) is left out and its frame solved again.

MediaPipe's depth (z) is not used: against the true depth of a captured performance it correlates
at 0.3 on the lips (and negatively in a pucker), so it would only add its own face model's guess.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mimetic.capture.calibrate import Calibration
from mimetic.capture.camera import (
    PinholeCamera,
    contour_projectors,
    estimate_focal,
    initial_pose,
    refine_pose,
)
from mimetic.capture.expression import (
    library_directions,
    marker_deltas,
    skin_gram,
    visible_channels,
    with_library,
)
from mimetic.capture.head import MODEL_ERROR, HeadMotion, nearest_true
from mimetic.capture.markers import MarkerSet, marker_normals, snap_to_skin, with_tangents
from mimetic.capture.qp import box_qp_frames
from mimetic.capture.smooth import CHI_MEDIAN, smooth_points
from mimetic.capture.solve import channel_bounds
from mimetic.capture.trajectories import CaptureError, Trajectories
from mimetic.engines.basis import Basis
from mimetic.errors import MimeticWarning
from mimetic.fit.similarity import Similarity
from mimetic.mesh.geometry import vertex_normals
from mimetic.rig.model import Rig

ROUNDS = 4
"""Alternations of pose and expression."""
VISIBLE_COS = 0.3
"""A landmark whose skin faces the camera at a cosine of this or more counts fully; less, in
proportion; turned away, not at all."""
PLACE_ROUNDS = 2
RAY_REACH_REL = 0.08
"""A landmark's ray is searched for skin within this fraction of the head of where the layout put
its marker; a marker whose ray passes farther than ``OFF_SKIN_REL`` from any is left where it was."""
OFF_SKIN_REL = 0.01
FOCAL_FRAMES = 40
"""Frames (spread over the take) the focal length is estimated on."""
GROSS_SIGMAS = 8.0
GROSS_REL = 0.03
"""A landmark is an outlier when farther from the solved face than both this many times the
tracker's noise and this fraction of the head (in pixels at the face's depth)."""
GROSS_MOST = 0.2
"""A frame with more than this fraction of its landmarks beyond the gross limit failed as a whole; its
landmarks are kept (and the frame flagged by its residual)."""
PIXEL_FLOOR = 0.1
"""No tracker places a landmark better than this (pixels, per coordinate): the noise the solve
assumes is at least this, so exact synthetic landmarks still get a prior."""
MIN_LANDMARKS = 6
"""Landmarks a frame needs for its pose."""
CHUNK = 64
"""Frames whose (m, 2, k) linearised rows are built at once."""
LIBRARY_GAIN = 30.0
"""μ / ν, the library prior's weight over the shape prior's. Both follow the misfit σ_e: ν = (σ_e / τ)²
and μ = (σ_e / τ_E)², so a skin coordinate is taken to stray from the library's combinations by
τ_E = τ / √30, about a fifth of how far it moves. Chosen on the calibration heads' video (face
residual −3.1 points against no library prior at 30, −2.1 at 10, −3.0 at 100; docs/capture.md)."""


@dataclass(frozen=True, eq=False)
class ImageModel:
    """The prepared image solve of one rig, camera and marker set (the module docstring's terms).

    Attributes
    ----------
    camera : PinholeCamera
    markers : MarkerSet
        As placed on the performer; ``sliding`` and ``tangents`` give the contour landmarks.
    reference : (m, 3) float64
        N, rig units.
    flat : (m, 3, k) float64
        D, each marker's displacement per unit of the k free channels.
    normals : (m, 3) float64
        The skin's unit normal at each marker, at rest.
    lower, upper : (k,) float64
    shape : (k, k) float64
        The shape prior per unit of ν (``capture.expression``), in rig units.
    regularization : float
        The ridge λ, relative to each channel's own effect in the frame.
    library : (r, k) float64
        The library prior's directions (``expression.library_directions``; (0, k) for none).
    """

    camera: PinholeCamera
    markers: MarkerSet
    reference: np.ndarray
    flat: np.ndarray
    normals: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    shape: np.ndarray
    regularization: float
    library: np.ndarray

    def model(self, x: np.ndarray) -> np.ndarray:
        """The markers (f, m, 3) in the rig's frame at activations ``x`` (f, k)."""
        return self.reference + np.einsum("fk,mdk->fmd", x, self.flat)

    def visibility(self, R: np.ndarray, P: np.ndarray) -> np.ndarray:
        """(f, m) each landmark's confidence from the angle between its turned rest normal and the view
        ray to its camera point P (f, m, 3)."""
        n = np.einsum("fij,mj->fmi", R, self.normals)
        cos = -np.einsum("fmi,fmi->fm", n, P) / np.maximum(np.linalg.norm(P, axis=-1), 1e-300)
        return np.clip(cos / VISIBLE_COS, 0.0, 1.0)

    def pose(
        self, X: np.ndarray, u: np.ndarray, weights: np.ndarray, R: np.ndarray, t: np.ndarray, steps: int = 6
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``camera.refine_pose`` of the model points X (f, m, 3) to the landmarks u (f, m, 2)."""
        markers = self.markers
        return refine_pose(
            self.camera, X, u, weights, R, t, tangents=markers.tangents, sliding=markers.sliding, steps=steps
        )

    def expression(
        self, R: np.ndarray, t: np.ndarray, x: np.ndarray, u: np.ndarray, confidence: np.ndarray, nu: float
    ) -> np.ndarray:
        """Activations (f, k) from the projection linearised at the pose (R, t) and activations ``x``:
        a box-constrained quadratic programme per frame (``capture.qp``)."""
        camera, markers = self.camera, self.markers
        X = self.model(x)
        P = np.einsum("fij,fmj->fmi", R, X) + t[:, None]
        scale = camera.focal / np.median(P[..., 2], axis=1)  # (f,) pixels per rig unit
        k = self.flat.shape[2]
        out = np.empty_like(x)
        for lo in range(0, len(x), CHUNK):
            c = slice(lo, lo + CHUNK)
            Q = contour_projectors(camera, P[c], markers.tangents, R[c], markers.sliding)  # (b, m, 2, 2)
            QJR = Q @ camera.jacobian(P[c]) @ R[c][:, None]  # (b, m, 2, 3)
            A = QJR @ self.flat  # (b, m, 2, k): ∂(Q π)/∂a
            e = (Q @ (np.nan_to_num(u[c]) - camera.project(P[c]))[..., None])[..., 0]  # (b, m, 2)
            target = e + (A @ x[c][:, None, :, None])[..., 0]
            root = np.sqrt(confidence[c])[..., None, None]  # (b, m, 1, 1)
            rows = (root * A).reshape(len(A), -1, k)  # (b, 2m, k): the weighted rows
            H = rows.transpose(0, 2, 1) @ rows
            ridge = np.maximum(np.einsum("bii->bi", H), 1e-12)
            H[:, np.arange(k), np.arange(k)] += max(self.regularization, 1e-12) * ridge
            H += nu * (scale[c] ** 2)[:, None, None] * self.shape
            g = (rows.transpose(0, 2, 1) @ (root[..., 0] * target).reshape(len(A), -1, 1))[..., 0]
            mu = LIBRARY_GAIN * nu * scale[c] ** 2
            H, g, lower, upper = with_library(H, g, self.lower, self.upper, self.shape, self.library, mu)
            start = np.zeros_like(g)
            start[:, :k] = np.clip(x[c], self.lower, self.upper)
            solved, ok = box_qp_frames(H, g, lower, upper, start)
            solved = solved[:, :k]
            if not ok.all():
                warnings.warn(
                    f"{(~ok).sum()} frames' expression solve did not converge; their activations are kept",
                    MimeticWarning,
                    stacklevel=3,
                )
                solved[~ok] = x[c][~ok]
            out[c] = solved
        return out

    def scale(self, R: np.ndarray, t: np.ndarray) -> np.ndarray:
        """(f,) pixels per rig unit at the face's depth."""
        depth = np.median(np.einsum("fij,mj->fmi", R, self.reference)[..., 2] + t[:, None, 2], axis=1)
        return self.camera.focal / depth

    def trust(
        self, x: np.ndarray, R: np.ndarray, t: np.ndarray, sigma: float, stray: np.ndarray
    ) -> np.ndarray:
        """(f, m) each landmark's weight in the pose: 1 / (σ² + (κ · motion · s)² + stray²), by the noise σ
        (pixels), how far the expression ``x`` moves its marker (κ ``head.MODEL_ERROR``, s the scale)
        and how far it strays from the solved face over the take (``_stray``, pixels)."""
        motion = np.linalg.norm(np.einsum("fk,mdk->fmd", x, self.flat), axis=-1)
        return 1.0 / (sigma**2 + (MODEL_ERROR * motion * self.scale(R, t)[:, None]) ** 2 + stray**2 + 1e-300)


def prepare_image_model(
    rig: Rig,
    basis: Basis,
    markers: MarkerSet,
    camera: PinholeCamera,
    reference: np.ndarray,
    free: np.ndarray,
    *,
    regularization: float,
    shape_prior: bool,
) -> ImageModel:
    """The ``ImageModel`` of the basis channels ``free`` (k,) at ``markers``, their ``reference`` (m, 3);
    without ``shape_prior`` neither the shape prior nor the library prior."""
    D = marker_deltas(rig, basis, markers)[free]  # (k, m, 3)
    lower, upper = (b[free] for b in channel_bounds(basis, rig))
    k, m = len(free), markers.n_markers
    gram, n_skin = skin_gram(rig, basis, free) if shape_prior else (np.zeros((k, k)), 1)
    return ImageModel(
        camera,
        markers,
        reference,
        D.transpose(1, 2, 0),
        marker_normals(markers, rig),
        lower,
        upper,
        (m / n_skin) * gram,
        regularization,
        library_directions(basis, free) if shape_prior else np.zeros((0, k)),
    )


# --------------------------------------------------------------------------- calibration


def _place(
    rig: Rig, markers: MarkerSet, camera: PinholeCamera, pixels: np.ndarray, R: np.ndarray, t: np.ndarray
) -> tuple[MarkerSet, np.ndarray, np.ndarray]:
    """Each marker moved to where its landmark's ray (``pixels`` (m, 2), NaN unseen) through the
    camera at pose (R, t) meets the rig's skin: the front-facing skin vertex nearest the ray among
    those within ``RAY_REACH_REL`` of the marker, its point on the ray snapped to the skin (on skin
    facing as the marker's did). Returns the markers, how far each moved and each ray's miss
    distance (rig units; nan unseen)."""
    mesh = rig.mesh
    skin = mesh.part_vertices("skin") if "skin" in mesh.parts else np.arange(mesh.n_vertices)
    vertices = mesh.vertices[skin]
    normals = vertex_normals(mesh.vertices, mesh.faces)[skin]
    origin = -R.T @ t  # the camera in the rig's frame
    facing = np.einsum("vd,vd->v", normals, origin - vertices) > 0
    layout = markers.positions(rig)
    layout_normals = marker_normals(markers, rig)
    seen = np.isfinite(pixels).all(axis=1)
    rays = camera.rays(np.nan_to_num(pixels)) @ R  # (m, 3) in the rig's frame (Rᵀ d)
    reach = RAY_REACH_REL * rig.scale
    points, miss = list(markers.points), np.full(len(layout), np.nan)
    hits = np.full((len(layout), 3), np.nan)  # each ray's point at the skin vertex nearest it
    for j in np.flatnonzero(seen):
        near = facing & (np.linalg.norm(vertices - layout[j], axis=1) < reach)
        if not near.any():
            continue
        rel = vertices[near] - origin
        along = rel @ rays[j]
        off = np.linalg.norm(rel - along[:, None] * rays[j], axis=1)
        best = int(np.argmin(off))
        miss[j] = off[best]
        hits[j] = origin + along[best] * rays[j]
    onto = np.flatnonzero(miss <= OFF_SKIN_REL * rig.scale)  # nan compares False
    for j, point in zip(onto, snap_to_skin(rig, hits[onto], layout_normals[onto]).points, strict=True):
        points[j] = point
    placed = with_tangents(markers.replace(points=tuple(points), placed=True), rig)
    return placed, np.linalg.norm(placed.positions(rig) - layout, axis=1), miss


def calibrate_image(
    rig: Rig, markers: MarkerSet, camera: PinholeCamera, neutral: np.ndarray, *, place: bool, source: str
) -> tuple[Calibration, np.ndarray, np.ndarray]:
    """The neutral's pose and, with ``place``, the performer's markers, from the neutral landmarks
    ``neutral`` (m, 2) (NaN unseen); each marker's reference on its landmark's ray at the rig's depth.

    Returns
    -------
    calibration : Calibration
        ``similarity`` the camera → rig at the neutral, ``reference`` the references (m, 3),
        ``off_skin`` each ray's miss distance (rig units), ``usable`` the markers placed on skin.
    R0, t0 : (3, 3), (3,) the neutral's pose (rig → camera).
    """
    at_neutral = np.isfinite(neutral).all(axis=1)
    fixed = (at_neutral & ~markers.sliding).astype(np.float64)
    if fixed.sum() < MIN_LANDMARKS:
        raise CaptureError(
            f"{source}: the neutral frame shows {int(fixed.sum())} landmarks; pick a frame where the face is "
            "seen from the front (CLI --neutral-frame)"
        )
    layout = markers
    N = markers.positions(rig)
    R0, t0 = initial_pose(camera, N, neutral[None], fixed[None])
    R0, t0 = R0[0], t0[0]
    moved, miss = np.zeros(len(N)), np.full(len(N), np.nan)
    for _ in range(PLACE_ROUNDS if place else 0):
        markers, moved, miss = _place(rig, layout, camera, neutral, R0, t0)
        N = markers.positions(rig)
        R0, t0, _ = refine_pose(camera, N, neutral[None], fixed[None], R0[None], t0[None])
        R0, t0 = R0[0], t0[0]
    # each marker's reference on its landmark's ray, at its depth (as the 3D route's calibrated neutral):
    # the pixels between a tracker's point and its skin point would otherwise read as expression
    P0 = N @ R0.T + t0
    rays = camera.rays(np.where(at_neutral[:, None], neutral, camera.project(P0)))
    reference = (rays / rays[:, 2:] * P0[:, 2:] - t0) @ R0  # Rᵀ (P − t), as rows
    usable = ~(np.isfinite(miss) & (miss > OFF_SKIN_REL * rig.scale) & markers.placed)
    calibration = Calibration(
        Similarity(1.0, R0.T, -R0.T @ t0), "px", markers, reference, moved, miss, usable
    )
    return calibration, R0, t0


# --------------------------------------------------------------------------- the take


def _stray(residual: np.ndarray, usable: np.ndarray) -> np.ndarray:
    """(m,) each landmark's typical distance (pixels) from where the solved face puts it: its median
    residual over the frames. A tracker's landmark on featureless skin (the forehead, the jaw's
    outline) is placed by the tracker's own face model and drifts over the skin as the head turns
    (11 px on a 1280 × 720 video of a face 60 cm away, where the eye corners stay within 2 px), so it
    should not carry the head."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nan_to_num(np.nanmedian(np.where(usable, residual, np.nan), axis=0))


def _mean_pose(
    R: np.ndarray, t: np.ndarray, fitted: np.ndarray, neutral_frame: int, fps: float
) -> tuple[np.ndarray, np.ndarray]:
    """The pose (R (3, 3), t (3,)) at the neutral: the mean over the fitted frames of
    ``NEUTRAL_WINDOW_S`` around it, the rotations' mean made a rotation (SVD)."""
    from mimetic.capture.performance import NEUTRAL_WINDOW_S

    half = max(1, round(NEUTRAL_WINDOW_S * fps / 2))
    window = np.arange(max(0, neutral_frame - half), min(len(R), neutral_frame + half + 1))
    window = window[fitted[window]] if fitted[window].any() else np.flatnonzero(fitted)[:1]
    u, _, vt = np.linalg.svd(R[window].mean(axis=0))
    return u @ np.diag([1.0, 1.0, np.linalg.det(u @ vt)]) @ vt, t[window].mean(axis=0)


def image_pixels(trajectories: Trajectories) -> np.ndarray:
    """(f, m, 2) the points in image pixels, x right and y down: as given for 2D points, (x, −y) of
    3D points in pixels (``track_video``'s, +Y up)."""
    positions = trajectories.positions
    return positions if trajectories.dims == 2 else positions[..., :2] * np.array([1.0, -1.0])


def image_size(trajectories: Trajectories, pixels: np.ndarray) -> tuple[int, int]:
    """The images' width and height: as the trajectories say, else twice the landmarks' median
    position (the camera usually is on the face)."""
    if trajectories.image_size is not None:
        return trajectories.image_size
    middle = np.nanmedian(pixels.reshape(-1, 2), axis=0)
    return round(2 * middle[0]), round(2 * middle[1])


def solve_image(
    rig: Rig,
    trajectories: Trajectories,
    markers: MarkerSet,
    *,
    basis: Basis,
    neutral_frame: int,
    active,
    cutoff_hz: float | None,
    regularization: float,
    shape_prior: float | None,
    shape_motion: float,
    robust: bool,
    place: bool,
    focal: float | None,
    fov_deg: float | None,
    step: Callable[[str, int, int], None],
):
    """The image-landmark route of ``performance.solve_performance`` (see the module docstring);
    ``markers`` matched to ``trajectories``' points, in their order. Returns a ``Performance``."""
    from mimetic.capture.performance import Performance, marker_reach, neutral_points

    # 1. pixels (x right, y down), smoothing, the channels
    pixels = image_pixels(trajectories)
    f, m, _ = pixels.shape
    if not trajectories.tracked:
        markers = markers.replace(sliding=np.zeros(m, bool), tangents=np.zeros((m, 3)))
    layout = markers.positions(rig)
    with warnings.catch_warnings():  # frames without a face are NaN throughout
        warnings.simplefilter("ignore", RuntimeWarning)
        middle = np.nanmean(pixels, axis=1, keepdims=True)
        spread = np.nanmedian(np.nanmean(np.linalg.norm(pixels - middle, axis=-1), axis=1))
    per_unit = spread / np.linalg.norm(layout - layout.mean(axis=0), axis=1).mean()  # pixels per rig unit
    step("smooth", 0, 1)
    smoothed = smooth_points(pixels, trajectories.fps, cutoff_hz, robust=robust, size=rig.scale * per_unit)
    u, outliers = smoothed.points, smoothed.outliers
    step("smooth", 1, 1)
    seen = np.isfinite(u).all(axis=-1) & ~outliers
    deltas = marker_deltas(rig, basis, markers)
    free = np.flatnonzero(visible_channels(basis, deltas, active))

    # 2. the camera
    size = image_size(trajectories, pixels)
    if focal is not None:
        camera = PinholeCamera(float(focal), (size[0] / 2, size[1] / 2), size)
    elif fov_deg is not None:
        camera = PinholeCamera.from_fov(fov_deg, size)
    else:
        step("camera", 0, 1)
        frames = np.flatnonzero(seen.sum(axis=1) >= max(MIN_LANDMARKS, m // 2))
        sample = frames[np.linspace(0, len(frames) - 1, min(FOCAL_FRAMES, len(frames))).astype(int)]
        lower, upper = (b[free] for b in channel_bounds(basis, rig))
        reach = marker_reach(deltas[free], lower, upper)  # what no channel moves is rigid, as the rig knows
        trust = (seen[sample] & ~markers.sliding) / ((MODEL_ERROR * reach) ** 2 + (1e-3 * rig.scale) ** 2)
        camera, _ = estimate_focal(layout, u[sample], trust, size)
        step("camera", 1, 1)

    # 3. calibration at the neutral
    step("calibrate", 0, 1)
    neutral = neutral_points(u, outliers, neutral_frame, trajectories.fps)  # (m, 2)
    calibration, _, _ = calibrate_image(
        rig, markers, camera, neutral, place=place, source=trajectories.source
    )
    model = prepare_image_model(
        rig,
        basis,
        calibration.markers,
        camera,
        calibration.reference,
        free,
        regularization=regularization,
        shape_prior=shape_prior != 0,
    )
    step("calibrate", 1, 1)

    # 4. pose and expression in turn; the first poses from the face at rest, every landmark alike
    usable = seen & calibration.usable
    fixed = usable & ~model.markers.sliding
    sigma = max(smoothed.noise * smoothed.kept, PIXEL_FLOOR)  # pixels per coordinate, after smoothing
    N = model.reference
    R, t = initial_pose(camera, N, u, fixed.astype(float))
    _, _, residual = model.pose(N, u, usable.astype(float), R, t, steps=0)
    stray = _stray(residual, usable)
    R, t, _ = model.pose(N, u, fixed / (sigma**2 + stray**2), R, t)
    x = np.zeros((f, len(free)))
    nu = 0.0 if shape_prior is None else shape_prior
    tau = shape_motion * rig.scale
    for round_ in range(ROUNDS):
        step("solve", round_, ROUNDS)
        P = np.einsum("fij,fmj->fmi", R, model.model(x)) + t[:, None]
        confidence = model.visibility(R, P) * usable
        x = model.expression(R, t, x, u, confidence, nu)
        weights = confidence * model.trust(x, R, t, sigma, stray)
        R, t, residual = model.pose(model.model(x), u, weights, R, t)
        stray = _stray(residual, usable)
        if shape_prior is None:  # ν = (σ_e / τ)², σ_e the misfit per coordinate in rig units
            misfit = residual[usable & np.isfinite(residual)]
            sigma_e = max(float(np.median(misfit)) / CHI_MEDIAN[2] if misfit.size else 0.0, sigma)
            nu = (sigma_e / float(np.median(model.scale(R, t))) / tau) ** 2

    # 5. gross errors: far beyond the noise and a gross fraction of the head; not a whole frame
    scale = model.scale(R, t)
    limit = np.maximum(GROSS_SIGMAS * np.sqrt(2) * sigma, GROSS_REL * rig.scale * scale)[:, None]
    gross = usable & (np.nan_to_num(residual) > limit) if robust else np.zeros((f, m), bool)
    gross[gross.sum(axis=1) > GROSS_MOST * usable.sum(axis=1)] = False
    if gross.any():
        outliers |= gross
        usable &= ~gross
        P = np.einsum("fij,fmj->fmi", R, model.model(x)) + t[:, None]
        confidence = model.visibility(R, P) * usable
        x = model.expression(R, t, x, u, confidence, nu)
        weights = confidence * model.trust(x, R, t, sigma, stray)
        R, t, residual = model.pose(model.model(x), u, weights, R, t)
    step("solve", ROUNDS, ROUNDS)

    # 6. the head's motion relative to the neutral, the clip and the report
    fitted = usable.sum(axis=1) >= MIN_LANDMARKS
    if not fitted.any():
        raise CaptureError(f"{trajectories.source}: no frame shows enough landmarks to place the head")
    nearest = nearest_true(fitted)  # a frame without a face holds the nearest fitted frame's pose
    R, t, x = R[nearest], t[nearest], x[nearest]
    head = image_head(rig, R, t, fitted, neutral_frame, trajectories.fps)
    kept = np.where(usable, residual, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt((kept**2).sum(axis=1) / usable.sum(axis=1)) / model.scale(R, t)  # rig units
    rms[~fitted] = np.nan
    head = HeadMotion(head.rotation, head.translation, head.to_rig, rms, usable.copy(), fitted)
    return Performance.assemble(
        rig,
        trajectories,
        basis=basis,
        free=free,
        x=x,
        head=head,
        calibration=calibration,
        marker_error=rms,
        noise=smoothed.noise / float(np.median(scale)),
        used=usable,
        outliers=outliers,
        neutral_frame=neutral_frame,
        camera=camera,
    )


def image_head(
    rig: Rig, R: np.ndarray, t: np.ndarray, fitted: np.ndarray, neutral_frame: int, fps: float
) -> HeadMotion:
    """The head's motion from its poses (R (f, 3, 3), t (f, 3), rig → camera), relative to the pose at
    the neutral (``_mean_pose``): rotation R0ᵀ R_t in the rig's frame, the head joint's translation,
    and ``to_rig`` the camera → rig map per frame (residual and inliers left empty)."""
    f = len(R)
    R0, t0 = _mean_pose(R, t, fitted, neutral_frame, fps)
    rotation = np.einsum("ji,fjk->fik", R0, R)  # R0ᵀ R_t: the head's turn in the rig's frame
    pivot = rig.bone("head").head
    translation = np.einsum("ji,fj->fi", R0, t - t0) + np.einsum("fij,j->fi", rotation, pivot) - pivot
    to_rig = np.zeros((f, 4, 4))
    to_rig[:, :3, :3] = R.transpose(0, 2, 1)
    to_rig[:, :3, 3] = -np.einsum("fji,fj->fi", R, t)
    to_rig[:, 3, 3] = 1.0
    return HeadMotion(rotation, translation, to_rig, np.full(f, np.nan), np.zeros((f, 0), bool), fitted)
