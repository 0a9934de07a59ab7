"""Image landmarks → head pose and activations through a perspective camera (video capture).

A video's landmarks say where the face's points land in the picture, nothing about their depth.
They are solved on their reprojection error, with the rig's own depth::

    minimise Σ_j c_tj ‖Q_tj (π(R_t (N_j + D_j a) + t_t) − u_tj)‖² + s_t² aᵀ Λ a      lo ≤ a ≤ hi

* π: a pinhole camera (``capture.camera``); R_t, t_t the head's pose in the camera in frame t. The
  face is taken to be the rig's size: one picture cannot tell a larger face from a nearer one, so
  the scale is fixed once and the depth follows.
* N_j the marker on the rig at rest, D_j its displacement per unit of each channel; u_tj the
  landmark; Q_tj the identity, or for a tracker's contour point (the face's oval) the projector
  across the contour as the image shows it.
* c_tj the landmark's confidence: how squarely the skin under it faces the camera (a point on the
  far cheek of a turned head, seen edge-on, counts for little; one turned away, nothing).
* Λ the expression solve's prior (``capture.expression``: ridge and shape prior), in pixels by
  the face's scale s_t (pixels per rig unit at its depth).

The chain:

1. **Smoothing** (``capture.smooth``) in pixels: spikes, short gaps, the tracker's noise.
2. **Camera**: the focal length given (``focal`` in pixels or ``fov_deg``), else estimated from the
   take (``camera.estimate_focal``: the field of view under which the face's stiff points move
   most rigidly).
3. **Calibration** at the neutral: the pose of the layout's markers (``camera.initial_pose``), then
   each marker moved to where its landmark's ray meets the rig's skin (the performer's own points),
   pose and placement in turn.
4. **Pose and expression** per frame, alternately: the pose by Gauss-Newton with each marker
   trusted as ``head.head_weights`` says (by the noise and how far the expression moves it); the
   expression with the projection linearised at that pose, a box-constrained quadratic programme
   per frame (``capture.qp``).
5. **Outliers**: a landmark farther from the solved face than ``GROSS_SIGMAS`` times the tracker's
   noise and ``GROSS_REL`` of the head (a landmark that jumped) is left out and its frame solved again.

MediaPipe's depth (z) is not used: it is a guess of the tracker's own face model.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

import numpy as np

from mimetic.capture.calibrate import Calibration
from mimetic.capture.camera import PinholeCamera, estimate_focal, initial_pose, refine_pose
from mimetic.capture.expression import marker_deltas, skin_gram, visible_channels
from mimetic.capture.head import MODEL_ERROR, HeadMotion, nearest_true
from mimetic.capture.markers import MarkerSet, with_tangents
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


def _visibility(normals: np.ndarray, R: np.ndarray, P: np.ndarray) -> np.ndarray:
    """(f, m) confidence of each landmark from the angle between its turned rest normal (m, 3) and
    the view ray to its camera point P (f, m, 3)."""
    n = np.einsum("fij,mj->fmi", R, normals)
    cos = -np.einsum("fmi,fmi->fm", n, P) / np.maximum(np.linalg.norm(P, axis=-1), 1e-300)
    return np.clip(cos / VISIBLE_COS, 0.0, 1.0)


def _place(
    rig: Rig, markers: MarkerSet, camera: PinholeCamera, pixels: np.ndarray, R: np.ndarray, t: np.ndarray
) -> tuple[MarkerSet, np.ndarray, np.ndarray]:
    """Each marker moved to where its landmark's ray (``pixels`` (m, 2), NaN unseen) through the
    camera at pose (R, t) meets the rig's skin: the front-facing skin vertex nearest the ray among
    those within ``RAY_REACH_REL`` of the marker, its point on the ray snapped to the skin. Returns
    the markers, how far each moved and each ray's miss distance (rig units; nan unseen)."""
    from mimetic.capture.markers import marker_normals, snap_to_skin

    mesh = rig.mesh
    skin = mesh.part_vertices("skin") if "skin" in mesh.parts else np.arange(mesh.n_vertices)
    vertices = mesh.vertices[skin]
    normals = vertex_normals(mesh.vertices, mesh.faces)[skin]
    origin = -R.T @ t  # the camera in the rig's frame
    facing = np.einsum("vd,vd->v", normals, origin - vertices) > 0
    layout = markers.positions(rig)
    seen = np.isfinite(pixels).all(axis=1)
    rays = camera.rays(np.nan_to_num(pixels)) @ R  # (m, 3) in the rig's frame (Rᵀ d)
    reach = RAY_REACH_REL * rig.scale
    points, miss = list(markers.points), np.full(len(layout), np.nan)
    layout_normals = marker_normals(markers, rig)
    for j in np.flatnonzero(seen):
        near = facing & (np.linalg.norm(vertices - layout[j], axis=1) < reach)
        if not near.any():
            continue
        rel = vertices[near] - origin
        along = rel @ rays[j]
        off = np.linalg.norm(rel - along[:, None] * rays[j], axis=1)
        best = int(np.argmin(off))
        snapped = snap_to_skin(rig, (origin + along[best] * rays[j])[None], layout_normals[j : j + 1])
        miss[j] = off[best]
        if off[best] <= OFF_SKIN_REL * rig.scale:
            points[j] = snapped.points[0]
    placed = with_tangents(markers.replace(points=tuple(points), placed=True), rig)
    return placed, np.linalg.norm(placed.positions(rig) - layout, axis=1), miss


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

    # 1. pixels (x right, y down) and smoothing
    positions = trajectories.positions
    pixels = positions if trajectories.dims == 2 else positions[..., :2] * np.array([1.0, -1.0])
    f, m, _ = pixels.shape
    if not trajectories.tracked:
        markers = markers.replace(sliding=np.zeros(m, bool), tangents=np.zeros((m, 3)))
    layout = markers.positions(rig)
    with warnings.catch_warnings():  # frames without a face are NaN throughout
        warnings.simplefilter("ignore", RuntimeWarning)
        spread = np.nanmedian(
            np.nanmean(np.linalg.norm(pixels - np.nanmean(pixels, axis=1, keepdims=True), axis=-1), axis=1)
        )
    per_unit = spread / np.linalg.norm(layout - layout.mean(axis=0), axis=1).mean()  # pixels per rig unit
    step("smooth", 0, 1)
    smoothed = smooth_points(pixels, trajectories.fps, cutoff_hz, robust=robust, size=rig.scale * per_unit)
    u, outliers = smoothed.points, smoothed.outliers
    step("smooth", 1, 1)
    seen = np.isfinite(u).all(axis=-1) & ~outliers

    # 2. the camera
    if trajectories.image_size is not None:
        size = trajectories.image_size
    else:  # centred on the landmarks: the camera usually is on the face
        middle = np.nanmedian(pixels.reshape(-1, 2), axis=0)
        size = (round(2 * middle[0]), round(2 * middle[1]))
    N = markers.positions(rig)  # (m, 3) rig units
    deltas = marker_deltas(rig, basis, markers)
    free = np.flatnonzero(visible_channels(basis, deltas, active))
    D = deltas[free]  # (k, m, 3)
    lower, upper = (b[free] for b in channel_bounds(basis, rig))
    if focal is not None:
        camera = PinholeCamera(float(focal), (size[0] / 2, size[1] / 2), size)
    elif fov_deg is not None:
        camera = PinholeCamera.from_fov(fov_deg, size)
    else:
        step("camera", 0, 1)
        usable_frames = np.flatnonzero(seen.sum(axis=1) >= max(6, m // 2))
        sample = usable_frames[
            np.linspace(0, len(usable_frames) - 1, min(FOCAL_FRAMES, len(usable_frames))).astype(int)
        ]
        reach = marker_reach(
            D, lower, upper
        )  # the points no channel moves are rigid, as far as the rig knows
        trust = (seen[sample] & ~markers.sliding) / ((MODEL_ERROR * reach) ** 2 + (1e-3 * rig.scale) ** 2)
        camera, _ = estimate_focal(N, u[sample], trust, size)
        step("camera", 1, 1)

    # 3. calibration at the neutral: pose, then the performer's markers
    step("calibrate", 0, 1)
    neutral = neutral_points(u, outliers, neutral_frame, trajectories.fps)  # (m, 2)
    at_neutral = np.isfinite(neutral).all(axis=1)
    fixed = at_neutral & ~markers.sliding
    if fixed.sum() < 6:
        raise CaptureError(
            f"{trajectories.source}: the neutral frame {neutral_frame} shows {fixed.sum()} landmarks; pick a "
            "frame where the face is seen from the front (CLI --neutral-frame)"
        )
    layout_markers, moved = markers, np.zeros(m)
    miss = np.full(m, np.nan)
    R0, t0 = initial_pose(camera, N, neutral[None], fixed[None].astype(float))
    R0, t0 = R0[0], t0[0]
    for _ in range(PLACE_ROUNDS if place else 0):
        markers, moved, miss = _place(rig, layout_markers, camera, neutral, R0, t0)
        N = markers.positions(rig)
        R0, t0, _ = refine_pose(camera, N, neutral[None], fixed[None].astype(float), R0[None], t0[None])
        R0, t0 = R0[0], t0[0]
    if place:
        deltas = marker_deltas(rig, basis, markers)
        D = deltas[free]
        # each marker's reference: on its landmark's ray at the neutral, at its depth (the 3D route's
    # calibrated neutral): the few pixels between a tracker's point and any skin point would
    # otherwise be read as expression in every frame
    P0 = N @ R0.T + t0
    rays = camera.rays(np.where(at_neutral[:, None], neutral, camera.project(P0)))
    N = (rays / rays[:, 2:] * P0[:, 2:] - t0) @ R0  # Rᵀ (P − t), as rows
    usable_marker = ~(np.isfinite(miss) & (miss > OFF_SKIN_REL * rig.scale) & markers.placed)
    calibration = Calibration(
        Similarity(1.0, R0.T, -R0.T @ t0), "px", markers, N.copy(), moved, miss, usable_marker
    )
    step("calibrate", 1, 1)

    # 4. pose and expression in turn
    k = len(free)
    normals = vertex_normals(rig.mesh.vertices, rig.mesh.faces)
    marker_normals = markers.weights(rig) @ normals
    marker_normals /= np.maximum(np.linalg.norm(marker_normals, axis=1, keepdims=True), 1e-300)
    usable = seen & usable_marker
    sigma = max(smoothed.noise * smoothed.kept, PIXEL_FLOOR)  # pixels, per coordinate, after smoothing
    # the first poses from the face at rest, every landmark alike; then each trusted as it keeps to it
    R, t = initial_pose(camera, N, u, (usable & ~markers.sliding).astype(float))
    _, _, residual = refine_pose(camera, N, u, usable.astype(float), R, t, steps=0)
    stray = _stray(residual, usable)
    R, t, _ = refine_pose(camera, N, u, usable * ~markers.sliding / (sigma**2 + stray**2), R, t)
    x = np.zeros((f, k))
    flat = D.transpose(1, 2, 0)  # (m, 3, k)
    gram, n_skin = skin_gram(rig, basis, free) if shape_prior != 0 else (np.zeros((k, k)), 1)
    shape = (m / n_skin) * gram
    tau = shape_motion * rig.scale
    nu = 0.0 if shape_prior is None else shape_prior
    for round_ in range(ROUNDS):
        step("solve", round_, ROUNDS)
        X = N + np.einsum("fk,mdk->fmd", x, flat)  # (f, m, 3)
        P = np.einsum("fij,fmj->fmi", R, X) + t[:, None]
        depth = np.nanmedian(P[..., 2], axis=1)
        scale = camera.focal / depth  # (f,) pixels per rig unit
        confidence = _visibility(marker_normals, R, P) * usable
        # expression: the projection linearised at the pose
        x = _expression(camera, R, P, X, u, confidence, flat, x, markers, scale, lower, upper,
                        regularization, shape, nu)  # fmt: skip
        X = N + np.einsum("fk,mdk->fmd", x, flat)
        # pose: every marker, trusted by how far the expression moves it and how far it strays
        model_motion = np.linalg.norm(X - N, axis=-1)
        w = confidence / (sigma**2 + (MODEL_ERROR * model_motion * scale[:, None]) ** 2 + stray**2 + 1e-300)
        R, t, residual = refine_pose(
            camera, X, u, w, R, t, tangents=markers.tangents, sliding=markers.sliding
        )
        stray = _stray(residual, usable)
        if shape_prior is None:  # ν = (σ_e / τ)², σ_e the misfit per coordinate in rig units
            misfit = residual[usable & np.isfinite(residual)]
            sigma_e = max(float(np.median(misfit)) / CHI_MEDIAN[2] if misfit.size else 0.0, sigma)
            nu = (sigma_e / float(np.median(scale)) / tau) ** 2
    # 5. gross errors
    limit = np.maximum(GROSS_SIGMAS * np.sqrt(2) * sigma, GROSS_REL * rig.scale * scale)[:, None]
    gross = usable & (np.nan_to_num(residual) > limit) if robust else np.zeros((f, m), bool)
    gross[gross.sum(axis=1) > GROSS_MOST * usable.sum(axis=1)] = (
        False  # a frame that failed, not its landmarks
    )
    if gross.any():
        outliers |= gross
        usable &= ~gross
        P = np.einsum("fij,fmj->fmi", R, X) + t[:, None]
        confidence = _visibility(marker_normals, R, P) * usable
        x = _expression(camera, R, P, X, u, confidence, flat, x, markers, scale, lower, upper,
                        regularization, shape, nu)  # fmt: skip
        X = N + np.einsum("fk,mdk->fmd", x, flat)
        R, t, residual = refine_pose(
            camera, X, u, w * usable, R, t, tangents=markers.tangents, sliding=markers.sliding
        )
    step("solve", ROUNDS, ROUNDS)

    # 6. the head's motion relative to the neutral, the clip and the report
    fitted = usable.sum(axis=1) >= MIN_LANDMARKS
    if not fitted.any():
        raise CaptureError(f"{trajectories.source}: no frame shows enough landmarks to place the head")
    nearest = nearest_true(fitted)  # a frame without a face holds the nearest fitted frame's pose
    R, t, x = R[nearest], t[nearest], x[nearest]
    R0, t0 = _mean_pose(R, t, fitted, neutral_frame, trajectories.fps)  # the solved neutral
    rotation = np.einsum("ji,fjk->fik", R0, R)  # R0ᵀ R_t: the head's turn in the rig's frame
    pivot = rig.bone("head").head
    translation = np.einsum("ji,fj->fi", R0, t - t0) + np.einsum("fij,j->fi", rotation, pivot) - pivot
    to_rig = np.zeros((f, 4, 4))
    to_rig[:, :3, :3] = R.transpose(0, 2, 1)
    to_rig[:, :3, 3] = -np.einsum("fji,fj->fi", R, t)
    to_rig[:, 3, 3] = 1.0
    kept = np.where(usable, residual, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        rms = np.sqrt((kept**2).sum(axis=1) / usable.sum(axis=1)) / scale  # rig units
    rms[~fitted] = np.nan
    head = HeadMotion(rotation, translation, to_rig, rms, usable.copy(), fitted)
    performance = Performance.assemble(
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
    return performance


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


def _stray(residual: np.ndarray, usable: np.ndarray) -> np.ndarray:
    """(m,) each landmark's typical distance (pixels) from where the solved face puts it: its median
    residual over the frames. A tracker's landmark on featureless skin (the forehead, the jaw's
    outline) is placed by the tracker's own face model and drifts over the skin as the head turns
    (11 px on a 1280 × 720 video of a face 60 cm away, where the eye corners stay within 2 px), so it
    should not carry the head."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return np.nan_to_num(np.nanmedian(np.where(usable, residual, np.nan), axis=0))


def _expression(
    camera, R, P, X, u, confidence, flat, x, markers, scale, lower, upper, regularization, shape, nu
):
    """Activations (f, k) from the projection linearised at the camera points P (f, m, 3) of the model X
    (f, m, 3) with activations ``x`` (f, k); a box QP per frame."""
    from mimetic.capture.camera import contour_projectors

    f = len(P)
    k = flat.shape[2]
    out = np.empty_like(x)
    for lo in range(0, f, CHUNK):
        c = slice(lo, lo + CHUNK)
        Q = contour_projectors(camera, P[c], markers.tangents, R[c], markers.sliding)  # (b, m, 2, 2)
        J = Q @ camera.jacobian(P[c])  # (b, m, 2, 3)
        A = np.einsum("bmij,bjl,mlk->bmik", J, R[c], flat)  # (b, m, 2, k): ∂(Q π)/∂a
        e = np.einsum("bmij,bmj->bmi", Q, np.nan_to_num(u[c]) - camera.project(P[c]))
        target = e + np.einsum("bmik,bk->bmi", A, x[c])  # (b, m, 2)
        w = confidence[c]
        H = np.einsum("bm,bmdi,bmdj->bij", w, A, A)
        ridge = np.maximum(np.einsum("bii->bi", H), 1e-12)
        H[:, np.arange(k), np.arange(k)] += max(regularization, 1e-12) * ridge
        H += nu * (scale[c] ** 2)[:, None, None] * shape
        g = np.einsum("bm,bmdi,bmd->bi", w, A, target)
        solved, ok = box_qp_frames(H, g, lower, upper, np.clip(x[c], lower, upper))
        if not ok.all():
            warnings.warn(
                f"{(~ok).sum()} frames' expression solve did not converge; their activations are kept",
                MimeticWarning,
                stacklevel=3,
            )
            solved[~ok] = x[c][~ok]
        out[c] = solved
    return out
