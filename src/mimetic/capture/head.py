"""Head motion: the skull's rigid motion in every frame, taken out of the captured points.

Per frame t, the motion ``S_t`` (rotation and translation, at the calibration's scale for a metric
capture; with a scale of its own for image points in pixels, which grow as the face nears the
camera) that maps the frame's points p_tj onto where the expression puts them in the rig's frame::

    minimise Σ_j w_tj ‖P_j (S_t(p_tj) − q_tj)‖²

* q_tj: the marker's neutral in the rig's frame plus the displacement the expression solve
  predicts there (none at first);
* P_j: the identity, but for a contour marker (``MarkerSet.sliding``) the projector that ignores
  its motion along the contour, which a tracker's silhouette point does not follow;
* w_tj: how far the marker can be trusted to be where the model says (``head_weights``).

Solved by the closed-form weighted similarity (Umeyama) with the projectors left out, then, when
some marker slides, Gauss-Newton steps on the six rigid parameters (seven with the scale) with
them. A marker farther than ``OUTLIER_FACTOR`` times the frame's median error (and
``OUTLIER_FLOOR_REL`` of the head) is left out and the frame refitted (a marker knocked loose, a
landmark jumping to the hairline).

The head's rotation relative to the neutral, ``R_0 R_tᵀ`` in the rig's frame, becomes the rig's
``head_yaw``/``head_pitch``/``head_roll`` channels (the skinning's ``R_y(yaw) R_x(pitch)
R_z(−roll)``); the jaw is not part of the skull, so its motion stays in the markers.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from mimetic.capture.trajectories import CaptureError
from mimetic.fit.similarity import Similarity

MODEL_ERROR = 0.5
"""κ in ``head_weights``: the rig's prediction of a marker the expression moves by m is taken to
be off by about κ·m. Chosen on the calibration heads of ``benchmarks/validate_capture.py`` (ICT's
neutral, identities 0 σ1 and 1 σ2; markers route): mean gap to the ceiling 4.4 points at κ 0.5,
4.6 at 1, 4.8 at 2 (τ 0.013); the check heads were not looked at."""
OUTLIER_FACTOR = 3.0
"""A marker farther than this times its frame's median error is left out of the frame's fit."""
OUTLIER_FLOOR_REL = 0.005
"""Errors below this fraction of the head's size are never outliers."""
OUTLIER_ROUNDS = 3
GAUSS_NEWTON_STEPS = 4
MIN_POINTS = 3
"""Markers a frame needs for its head fit."""


@dataclass(frozen=True, eq=False)
class HeadMotion:
    """Per-frame rigid motion of the head.

    Arrays are read-only.

    Attributes
    ----------
    rotation : (f, 3, 3) float64
        The head's rotation relative to the neutral frame, in the rig's frame.
    translation : (f, 3) float64
        How far the head joint moved from the neutral, in rig units.
    to_rig : (f, 4, 4) float64
        ``S_t``: frame t's capture coordinates to the rig's neutral frame (skull motion removed).
    residual : (f,) float64
        Weighted RMS error of the markers the fit kept, in rig units (nan for an unfitted frame).
    inliers : (f, m) bool
        The markers each frame's fit kept (those with weight, not rejected).
    fitted : (f,) bool
        False where fewer than ``MIN_POINTS`` markers were usable; those frames take the motion
        of the nearest fitted frame.
    """

    rotation: np.ndarray
    translation: np.ndarray
    to_rig: np.ndarray
    residual: np.ndarray
    inliers: np.ndarray
    fitted: np.ndarray

    def __post_init__(self) -> None:
        for name in ("rotation", "translation", "to_rig", "residual", "inliers", "fitted"):
            getattr(self, name).setflags(write=False)

    def angles(self) -> np.ndarray:
        """(f, 3) float64 ``head_yaw``, ``head_pitch``, ``head_roll`` in radians: R = R_y(yaw) R_x(pitch)
        R_z(−roll), as the rig's skinning composes them."""
        return rotation_angles(self.rotation)

    def stabilise(self, points: np.ndarray) -> np.ndarray:
        """``points`` (f, m, 3) in capture units mapped into the rig's neutral frame (rig units)."""
        S = self.to_rig
        return points @ S[:, :3, :3].transpose(0, 2, 1) + S[:, None, :3, 3]


def rotation_angles(R: np.ndarray) -> np.ndarray:
    """(f, 3) yaw, pitch, roll of rotations (f, 3, 3) = R_y(yaw) R_x(pitch) R_z(−roll)."""
    pitch = np.arcsin(np.clip(-R[:, 1, 2], -1.0, 1.0))
    yaw = np.arctan2(R[:, 0, 2], R[:, 2, 2])
    roll = -np.arctan2(R[:, 1, 0], R[:, 1, 1])
    return np.stack([yaw, pitch, roll], axis=1)


def head_weights(usable: np.ndarray, motion: np.ndarray, noise: float) -> np.ndarray:
    """Per-marker trust in the head fit, (f, m) or (m,): ``usable / (σ² + (κ m)²)``.

    ``motion`` (same shape) is how far the expression moves each marker (rig units): the solve's
    prediction, or before a solve the marker's reach under the rig's channels; ``noise`` σ is the
    capture's noise in rig units, per coordinate. A marker the expression barely moves (the nose
    bridge, the eye corners) then carries the head; the lips, which move much and which the rig
    predicts least well, barely count. κ is ``MODEL_ERROR``.
    """
    return usable / (noise**2 + (MODEL_ERROR * motion) ** 2 + 1e-300)


def nearest_true(mask: np.ndarray) -> np.ndarray:
    """(f,) int64: for each frame, the nearest frame where ``mask`` (f,) bool is True (one must be)."""
    index = np.flatnonzero(mask)
    frames = np.arange(len(mask))
    after = np.clip(np.searchsorted(index, frames), 0, len(index) - 1)
    before = np.clip(after - 1, 0, len(index) - 1)
    closer = np.abs(index[before] - frames) < np.abs(index[after] - frames)
    return np.where(closer, index[before], index[after])


def _umeyama(
    points: np.ndarray, target: np.ndarray, weights: np.ndarray, scale: float | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weighted similarity per frame (vectorised Umeyama): scale (f,), rotation (f, 3, 3) and
    translation (f, 3) minimising Σ_j w_tj |s R p_tj + t − q_tj|² (``target`` (m, 3) or (f, m, 3));
    ``scale`` fixes s."""
    w = weights / np.maximum(weights.sum(axis=1, keepdims=True), 1e-300)  # (f, m)
    p = np.nan_to_num(points)  # (f, m, 3); missing points have weight 0
    q = np.nan_to_num(np.broadcast_to(target, p.shape))
    mu_p = np.einsum("fm,fmd->fd", w, p)
    mu_q = np.einsum("fm,fmd->fd", w, q)
    a = p - mu_p[:, None]
    b = q - mu_q[:, None]
    cov = np.einsum("fm,fmi,fmj->fij", w, b, a)  # (f, 3, 3) Σ w b aᵀ
    u, d, vt = np.linalg.svd(cov)
    sign = np.sign(np.linalg.det(u @ vt))
    sign[sign == 0] = 1.0
    u[:, :, 2] *= sign[:, None]
    d[:, 2] *= sign
    rotation = u @ vt
    if scale is None:
        variance = np.einsum("fm,fmd,fmd->f", w, a, a)
        s = d.sum(axis=1) / np.maximum(variance, 1e-300)
    else:
        s = np.full(len(points), scale)
    translation = mu_q - s[:, None] * np.einsum("fij,fj->fi", rotation, mu_p)
    return s, rotation, translation


def _skew(v: np.ndarray) -> np.ndarray:
    """[v]× (..., 3, 3) of vectors v (..., 3)."""
    out = np.zeros((*v.shape, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def _rodrigues(omega: np.ndarray) -> np.ndarray:
    """Rotations (f, 3, 3) exp([ω]×) of rotation vectors (f, 3)."""
    angle = np.linalg.norm(omega, axis=1)
    axis = omega / np.maximum(angle, 1e-300)[:, None]
    K = _skew(axis)
    sin, cos = np.sin(angle)[:, None, None], np.cos(angle)[:, None, None]
    return np.eye(3) + sin * K + (1.0 - cos) * (K @ K)


def _gauss_newton(
    points: np.ndarray,
    target: np.ndarray,
    weights: np.ndarray,
    projectors: np.ndarray,
    s: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    free_scale: bool,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``GAUSS_NEWTON_STEPS`` steps of min Σ w ‖P (s R p + t − q)‖² from (s, R, t); R ← exp([ω]×) R,
    t ← t + v, s ← s e^ρ."""
    p = np.nan_to_num(points)
    q = np.nan_to_num(np.broadcast_to(target, p.shape))
    W = weights[..., None, None] * projectors[None]  # (f, m, 3, 3)
    k = 7 if free_scale else 6
    for _ in range(GAUSS_NEWTON_STEPS):
        X = s[:, None, None] * np.einsum("fij,fmj->fmi", R, p)  # (f, m, 3)
        e = X + t[:, None] - q
        J = np.zeros((*X.shape, k))  # (f, m, 3, k): ∂e/∂(ω, v[, ρ])
        J[..., :3] = -_skew(X)
        J[..., 3:6] = np.eye(3)
        if free_scale:
            J[..., 6] = X
        WJ = W @ J  # (f, m, 3, k)
        A = np.einsum("fmdi,fmdj->fij", J, WJ) + 1e-12 * np.eye(k)
        b = -np.einsum("fmdi,fmd->fi", WJ, e)
        step = np.linalg.solve(A, b[..., None])[..., 0]  # (f, k)
        R = _rodrigues(step[:, :3]) @ R
        t = t + step[:, 3:6]
        if free_scale:
            s = s * np.exp(step[:, 6])
    return s, R, t


def head_motion(
    points: np.ndarray,
    target: np.ndarray,
    weights: np.ndarray,
    calibration: Similarity,
    *,
    projectors: np.ndarray | None = None,
    pivot: np.ndarray,
    size: float,
    fixed_scale: bool,
) -> HeadMotion:
    """The head's motion from the captured markers (see the module docstring).

    Parameters
    ----------
    points : (f, m, 3) float64
        The markers per frame, capture units, NaN where missing.
    target : (m, 3) or (f, m, 3) float64
        Where they should land in the rig's frame: the calibrated neutral, or per frame the
        neutral plus the expression's predicted displacement (rig units).
    weights : (f, m) or (m,) float64
        Each marker's trust (``head_weights``); 0 leaves a marker out.
    calibration : Similarity
        Capture → rig at the neutral frame.
    projectors : (m, 3, 3) float64, optional
        P_j (identity for a fixed marker); all identities by default.
    pivot : (3,) float64
        The rig's head joint (rig units).
    size : float
        The rig's head size (``Rig.scale``), for the outlier floor.
    fixed_scale : bool
        Keep the calibration's scale (metric captures) instead of fitting one per frame.

    Raises
    ------
    CaptureError
        No frame has ``MIN_POINTS`` usable markers.
    """
    f, m, _ = points.shape
    seen = np.isfinite(points).all(axis=2) & np.isfinite(target).all(axis=-1)
    weights = np.broadcast_to(weights, (f, m)) * seen
    projectors = np.broadcast_to(np.eye(3), (m, 3, 3)) if projectors is None else projectors
    keep = weights > 0
    fixed = calibration.scale if fixed_scale else None
    contour = not np.allclose(projectors, np.eye(3))
    for _ in range(OUTLIER_ROUNDS):
        w = np.where(keep, weights, 0.0)
        usable = keep.sum(axis=1) >= MIN_POINTS
        w[~usable] = np.where(seen[~usable], 1.0, 0.0)  # too few trusted: any seen marker, flagged below
        s, R, t = _umeyama(points, target, w, fixed)
        if contour:  # Umeyama is exact without projectors
            s, R, t = _gauss_newton(points, target, w, projectors, s, R, t, not fixed_scale)
        moved = s[:, None, None] * np.einsum("fij,fmj->fmi", R, np.nan_to_num(points)) + t[:, None]
        error = np.linalg.norm(np.einsum("mij,fmj->fmi", projectors, moved - target), axis=2)  # (f, m)
        error[~seen] = np.inf
        with warnings.catch_warnings():  # a frame with no marker kept has no median: it gets inf below
            warnings.simplefilter("ignore", RuntimeWarning)
            median = np.nanmedian(np.where(keep, error, np.nan), axis=1)  # (f,)
        limit = np.maximum(OUTLIER_FACTOR * np.nan_to_num(median, nan=np.inf), OUTLIER_FLOOR_REL * size)
        new = (weights > 0) & (error <= limit[:, None])
        if np.array_equal(new, keep):
            break
        keep = new
    fitted = keep.sum(axis=1) >= MIN_POINTS
    if not fitted.any():
        raise CaptureError(
            f"no frame shows {MIN_POINTS} usable markers of the {m} that carry the head, so the head's "
            "motion cannot be removed; check that the marker names match the layout"
        )
    nearest = nearest_true(fitted)
    s, R, t = s[nearest], R[nearest], t[nearest]
    to_rig = np.zeros((f, 4, 4))
    to_rig[:, :3, :3] = s[:, None, None] * R
    to_rig[:, :3, 3] = t
    to_rig[:, 3, 3] = 1.0
    R0 = calibration.rotation
    rotation = R0 @ R.transpose(0, 2, 1)  # (f, 3, 3): the head's rotation in the rig's frame
    # the head in frame t, in the rig's frame: M_t = S_0 ∘ S_t⁻¹, x ↦ s0/s_t R0 R_tᵀ (x − t_t) + t0
    ratio = calibration.scale / s
    moved_pivot = (
        ratio[:, None] * np.einsum("fij,fj->fi", rotation, pivot[None] - t) + calibration.translation
    )
    kept = np.where(keep, weights, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        residual = np.sqrt((kept * np.where(keep, error, 0.0) ** 2).sum(axis=1) / kept.sum(axis=1))
    residual[~fitted] = np.nan
    return HeadMotion(rotation, moved_pivot - pivot, to_rig, residual, keep, fitted)
