"""Calibration and head motion: captured points into the rig's frame, the skull's motion taken out.

1. **Calibration** (the paper's alignment, once): the similarity ``S_0`` (scale, rotation,
   translation; Umeyama) that maps the neutral frame's points onto the rig's virtual markers.
   It absorbs the capture's units and axes (millimetres, Z-up), and is checked: a mirror image
   (a left-handed export, swapped axes) or a scale that contradicts the stated units is an error.
2. **Head motion** (per frame): the similarity ``S_t`` that maps frame t's *stable* points
   (``MarkerSet.stable``) onto where the calibration put them in the neutral frame, refitted
   after dropping points farther than ``OUTLIER_FACTOR`` times the frame's median error (a
   marker knocked loose, a landmark jumping to the hairline). Metric captures keep the
   calibration's scale (a rigid fit); image landmarks ("px") get a scale per frame (the face
   comes nearer the camera). The head's rotation relative to the neutral, ``R_0 R_tᵀ`` in the
   rig's frame, becomes the rig's ``head_yaw``/``head_pitch``/``head_roll`` channels (the
   skinning's ``R_y(yaw) R_x(pitch) R_z(−roll)``); the jaw is not a stable point, so its motion
   stays in the markers and is solved as the ``jaw_*`` channels.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from mimetic.capture.trajectories import CaptureError
from mimetic.fit.similarity import Similarity, fit_similarity
from mimetic.mesh.units import UNIT_SCALE

OUTLIER_FACTOR = 3.0
"""A stable point farther than this times its frame's median error (and than ``OUTLIER_FLOOR_REL``)
is left out of the frame's head fit."""
OUTLIER_FLOOR_REL = 0.005
"""Errors below this fraction of the head's size are never outliers."""
OUTLIER_ROUNDS = 3
MIN_STABLE = 3
"""Stable points a frame needs for its head fit."""
MIRROR_RATIO = 0.5
"""A neutral frame that a mirror image fits with less than this fraction of the error of a proper
rotation is a left-handed (axis-swapped) capture."""
UNITS_TOLERANCE = 2.0
"""The calibration's scale may differ from the stated units' by this factor (people differ in size)."""


@dataclass(frozen=True, eq=False)
class HeadMotion:
    """Per-frame rigid motion of the head, from the stable points.

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
        RMS error of the stable points the fit kept, in rig units (nan for an unfitted frame).
    inliers : (f, k) bool
        The stable points each frame's fit kept.
    fitted : (f,) bool
        False where fewer than ``MIN_STABLE`` stable points were seen; those frames take the motion
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
        R = self.rotation
        pitch = np.arcsin(np.clip(-R[:, 1, 2], -1.0, 1.0))
        yaw = np.arctan2(R[:, 0, 2], R[:, 2, 2])
        roll = -np.arctan2(R[:, 1, 0], R[:, 1, 1])
        return np.stack([yaw, pitch, roll], axis=1)


def calibrate(
    reference: np.ndarray,
    neutral: np.ndarray,
    *,
    units: str | None,
    rig_units: str | None,
    source: str = "capture",
) -> tuple[Similarity, str | None]:
    """The similarity from the neutral frame's points to the rig's markers, checked.

    Parameters
    ----------
    reference : (k, 3) float64
        The rig's virtual markers at rest, rig units.
    neutral : (k, 3) float64
        The same markers in the capture's neutral frame (all finite), capture units.
    units, rig_units : str or None
        The capture's and the rig's length units ("px" for image landmarks).

    Returns
    -------
    similarity : Similarity
        Capture → rig.
    units : str or None
        The capture's units: as given, or guessed from the scale when not given (metric only).

    Raises
    ------
    CaptureError
        A mirror image fits far better (swapped axes), or the scale contradicts ``units``.
    """
    similarity = fit_similarity(neutral, reference)
    error = np.sqrt(np.mean(np.sum((similarity.apply(neutral) - reference) ** 2, axis=1)))
    mirrored = neutral * np.array([-1.0, 1.0, 1.0])
    mirror = fit_similarity(mirrored, reference)
    mirror_error = np.sqrt(np.mean(np.sum((mirror.apply(mirrored) - reference) ** 2, axis=1)))
    if mirror_error < MIRROR_RATIO * error:
        raise CaptureError(
            f"{source}: the neutral frame fits the rig as a mirror image ({mirror_error:.3g} against "
            f"{error:.3g} rig units when rotated): two of its axes are swapped or one is flipped "
            "(a left-handed export). Fix the export (right-handed, +Y up, +Z toward the camera) or "
            "negate one axis of the file"
        )
    if rig_units not in UNIT_SCALE or units == "px":
        return similarity, units
    if units is None:
        metres = similarity.scale * UNIT_SCALE[rig_units]  # metres per capture unit
        guess = min(("mm", "cm", "m"), key=lambda u: abs(np.log(UNIT_SCALE[u] / metres)))
        return similarity, guess
    expected = UNIT_SCALE[units] / UNIT_SCALE[rig_units]
    ratio = similarity.scale / expected
    if not 1 / UNITS_TOLERANCE <= ratio <= UNITS_TOLERANCE:
        metres = similarity.scale * UNIT_SCALE[rig_units]
        guess = min(("mm", "cm", "m"), key=lambda u: abs(np.log(UNIT_SCALE[u] / metres)))
        raise CaptureError(
            f"{source}: the file says its units are {units}, but the face it holds is {1 / ratio:.3g} "
            f"times the rig's size in those units; it looks like {guess}. Pass units={guess!r} "
            f"(CLI --units {guess}) or fix the file"
        )
    return similarity, units


def nearest_true(mask: np.ndarray) -> np.ndarray:
    """(f,) int64: for each frame, the nearest frame where ``mask`` (f,) bool is True (one must be)."""
    index = np.flatnonzero(mask)
    frames = np.arange(len(mask))
    after = np.clip(np.searchsorted(index, frames), 0, len(index) - 1)
    before = np.clip(after - 1, 0, len(index) - 1)
    closer = np.abs(index[before] - frames) < np.abs(index[after] - frames)
    return np.where(closer, index[before], index[after])


def _fit_frames(
    points: np.ndarray, target: np.ndarray, weights: np.ndarray, scale: float | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weighted similarity per frame (vectorised Umeyama): scale (f,), rotation (f, 3, 3) and
    translation (f, 3) minimising Σ_j w_tj |s R p_tj + t − q_tj|² (``target`` (k, 3) or (f, k, 3));
    ``scale`` fixes s."""
    w = weights / np.maximum(weights.sum(axis=1, keepdims=True), 1e-300)  # (f, k)
    p = np.nan_to_num(points)  # (f, k, 3); missing points have weight 0
    mu_p = (w[:, None] @ p)[:, 0]  # (f, 3)
    q = np.broadcast_to(target, p.shape)  # (f, k, 3)
    mu_q = (w[:, None] @ q)[:, 0]
    a = p - mu_p[:, None]
    b = q - mu_q[:, None]
    cov = (b * w[..., None]).transpose(0, 2, 1) @ a  # (f, 3, 3) Σ w b aᵀ
    u, d, vt = np.linalg.svd(cov)
    sign = np.sign(np.linalg.det(u @ vt))
    sign[sign == 0] = 1.0
    u[:, :, 2] *= sign[:, None]
    d[:, 2] *= sign
    rotation = u @ vt
    if scale is None:
        variance = np.einsum("fk,fkd,fkd->f", w, a, a)
        s = d.sum(axis=1) / np.maximum(variance, 1e-300)
    else:
        s = np.full(len(points), scale)
    translation = mu_q - s[:, None] * (rotation @ mu_p[..., None])[..., 0]
    return s, rotation, translation


def head_motion(
    stable: np.ndarray,
    target: np.ndarray,
    calibration: Similarity,
    *,
    pivot: np.ndarray,
    size: float,
    fixed_scale: bool,
) -> HeadMotion:
    """The head's motion from its stable points.

    Parameters
    ----------
    stable : (f, k, 3) float64
        The stable points per frame, capture units, NaN where missing.
    target : (k, 3) or (f, k, 3) float64
        Where they should land in the rig's frame: the calibrated neutral, or per frame the
        neutral plus the expression's predicted displacement (rig units).
    calibration : Similarity
        Capture → rig at the neutral frame.
    pivot : (3,) float64
        The rig's head joint (rig units).
    size : float
        The rig's head size (``Rig.scale``), for the outlier floor.
    fixed_scale : bool
        Keep the calibration's scale (metric captures) instead of fitting one per frame.
    """
    f, k, _ = stable.shape
    seen = np.isfinite(stable).all(axis=2) & np.isfinite(target).all(axis=-1)  # (f, k)
    keep = seen.copy()
    fixed = calibration.scale if fixed_scale else None
    for _ in range(OUTLIER_ROUNDS):
        usable = keep.sum(axis=1) >= MIN_STABLE
        weights = np.where(usable[:, None], keep, seen).astype(np.float64)
        s, R, t = _fit_frames(stable, target, weights, fixed)
        moved = s[:, None, None] * (np.nan_to_num(stable) @ R.transpose(0, 2, 1)) + t[:, None]
        error = np.linalg.norm(moved - target, axis=2)  # (f, k)
        error[~seen] = np.inf
        with warnings.catch_warnings():  # a frame with no point kept has no median: it gets inf below
            warnings.simplefilter("ignore", RuntimeWarning)
            median = np.nanmedian(np.where(keep, error, np.nan), axis=1)  # (f,)
        limit = np.maximum(OUTLIER_FACTOR * np.nan_to_num(median, nan=np.inf), OUTLIER_FLOOR_REL * size)
        new = seen & (error <= limit[:, None])
        if np.array_equal(new, keep):
            break
        keep = new
    fitted = keep.sum(axis=1) >= MIN_STABLE
    if not fitted.any():
        raise CaptureError(
            f"no frame shows {MIN_STABLE} of the {k} stable (head) markers, so the head's motion cannot be "
            "removed; check the marker names match the layout"
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
    kept = np.where(keep, error, 0.0)
    with np.errstate(invalid="ignore", divide="ignore"):
        residual = np.sqrt((kept**2).sum(axis=1) / keep.sum(axis=1))
    residual[~fitted] = np.nan
    return HeadMotion(rotation, moved_pivot - pivot, to_rig, residual, keep, fitted)
