"""A pinhole camera for video capture: projection, the head's pose in the camera, the focal length.

Camera axes are a computer-vision camera's: x right, y down, z forward (into the picture), in the
rig's units; pixel coordinates have x right and y down. A point P in the camera projects to

    π(P) = f (P_x / P_z, P_y / P_z) + c

with f the focal length in pixels and c the principal point (the image's centre). The head's pose
maps the rig's frame into the camera's, P = R X + t; a face seen from the front has R = ``FRONT``
(the rig's +X, +Y, +Z are the camera's x, −y, −z).

* ``initial_pose``: the pose of a rigid point set from its landmarks, by a scaled orthographic
  (affine) fit made orthonormal, refined by ``refine_pose``.
* ``refine_pose``: Gauss-Newton on rotation and translation, many frames at once, each landmark
  weighted and, for a contour landmark, only its motion across the contour counted.
* ``estimate_focal``: the focal length under which the face's stiff points move most rigidly.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

FRONT = np.diag([1.0, -1.0, -1.0])
"""The rotation of a face seen from the front: rig (+Y up, +Z toward the viewer) → camera (y down,
z forward)."""
POSE_STEPS = 6
FOV_RANGE_DEG = (15.0, 100.0)
"""The vertical fields of view ``estimate_focal`` searches (a long lens to a wide phone camera)."""
DEFAULT_FOV_DEG = 50.0
"""The vertical field of view assumed when the take cannot tell (a webcam or phone at arm's length)."""
FOCAL_CONTRAST = 0.02
"""``estimate_focal`` keeps its answer only when the rigid fit's error at the ends of the search is at
least this much (relative) above its best; else the take does not tell (no head turn), and the default
field of view is used."""


@dataclass(frozen=True)
class PinholeCamera:
    """A camera with square pixels and no distortion.

    Attributes
    ----------
    focal : float
        Focal length in pixels.
    centre : (2,) float64
        Principal point in pixels (x right, y down).
    size : (2,) int
        Image width and height in pixels.
    """

    focal: float
    centre: tuple[float, float]
    size: tuple[int, int]

    @staticmethod
    def from_fov(fov_y_deg: float, size: tuple[int, int]) -> PinholeCamera:
        """The camera with a vertical field of view of ``fov_y_deg`` for images of ``size`` (w, h)."""
        w, h = size
        focal = 0.5 * h / math.tan(math.radians(fov_y_deg) / 2)
        return PinholeCamera(focal, (w / 2, h / 2), (int(w), int(h)))

    @property
    def fov_y_deg(self) -> float:
        return math.degrees(2 * math.atan(0.5 * self.size[1] / self.focal))

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixels (..., 2) of camera points (..., 3)."""
        z = points[..., 2:3]
        return self.focal * points[..., :2] / z + np.asarray(self.centre)

    def jacobian(self, points: np.ndarray) -> np.ndarray:
        """∂π/∂P (..., 2, 3) at camera points (..., 3)."""
        x, y, z = points[..., 0], points[..., 1], points[..., 2]
        J = np.zeros((*points.shape[:-1], 2, 3))
        J[..., 0, 0] = J[..., 1, 1] = self.focal / z
        J[..., 0, 2] = -self.focal * x / z**2
        J[..., 1, 2] = -self.focal * y / z**2
        return J

    def rays(self, pixels: np.ndarray) -> np.ndarray:
        """Unit directions (..., 3) in the camera through ``pixels`` (..., 2)."""
        xy = (pixels - np.asarray(self.centre)) / self.focal
        d = np.concatenate([xy, np.ones((*xy.shape[:-1], 1))], axis=-1)
        return d / np.linalg.norm(d, axis=-1, keepdims=True)


def skew(v: np.ndarray) -> np.ndarray:
    """[v]× (..., 3, 3) of vectors (..., 3)."""
    out = np.zeros((*v.shape, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def rodrigues(omega: np.ndarray) -> np.ndarray:
    """Rotations (..., 3, 3) exp([ω]×) of rotation vectors (..., 3)."""
    angle = np.linalg.norm(omega, axis=-1)
    K = skew(omega / np.maximum(angle, 1e-300)[..., None])
    sin, cos = np.sin(angle)[..., None, None], np.cos(angle)[..., None, None]
    return np.eye(3) + sin * K + (1.0 - cos) * (K @ K)


def contour_projectors(
    camera: PinholeCamera, P: np.ndarray, tangents: np.ndarray, R: np.ndarray, sliding: np.ndarray
) -> np.ndarray:
    """Image-plane projectors (f, m, 2, 2): the identity, but for a sliding landmark the projector across
    its contour (the rig's contour tangents (m, 3), turned by R (f, 3, 3) and projected at the camera
    points P (f, m, 3))."""
    Q = np.broadcast_to(np.eye(2), (*P.shape[:2], 2, 2)).copy()
    if sliding.any():
        J = camera.jacobian(P[:, sliding])  # (f, s, 2, 3)
        t2 = np.einsum("fsij,fjk,sk->fsi", J, R, tangents[sliding])
        t2 /= np.maximum(np.linalg.norm(t2, axis=-1, keepdims=True), 1e-300)
        Q[:, sliding] -= np.einsum("fsi,fsj->fsij", t2, t2)
    return Q


def refine_pose(
    camera: PinholeCamera,
    model: np.ndarray,
    pixels: np.ndarray,
    weights: np.ndarray,
    R: np.ndarray,
    t: np.ndarray,
    *,
    tangents: np.ndarray | None = None,
    sliding: np.ndarray | None = None,
    steps: int = POSE_STEPS,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Gauss-Newton on the pose of each frame: minimise Σ_j w_tj ‖Q_tj (π(R_t X_tj + t_t) − u_tj)‖².

    Parameters
    ----------
    model : (m, 3) or (f, m, 3) float64
        The points X in the rig's frame (the markers, with the expression when known), rig units.
    pixels : (f, m, 2) float64
        The landmarks u, NaN where missing (their weight must be 0).
    weights : (f, m) float64
    R, t : (f, 3, 3), (f, 3) float64
        The starting pose, rig → camera.
    tangents, sliding : (m, 3) float64, (m,) bool, optional
        Contour landmarks and the rig's contour directions at them (``contour_projectors``).

    Returns
    -------
    R, t : the refined pose; residual (f, m) float64, ‖Q (π(P) − u)‖ in pixels (nan where missing).
    """
    X = np.broadcast_to(model, (*pixels.shape[:2], 3))
    u = np.nan_to_num(pixels)
    w = np.where(np.isfinite(pixels).all(axis=-1), weights, 0.0)
    for _ in range(steps):
        RX = np.einsum("fij,fmj->fmi", R, X)
        P = RX + t[:, None]
        Q = np.broadcast_to(np.eye(2), (*P.shape[:2], 2, 2))
        if sliding is not None:
            Q = contour_projectors(camera, P, tangents, R, sliding)
        e = np.einsum("fmij,fmj->fmi", Q, camera.project(P) - u)
        dP = np.concatenate([-skew(RX), np.broadcast_to(np.eye(3), (*RX.shape[:2], 3, 3))], axis=-1)
        J = Q @ camera.jacobian(P) @ dP  # (f, m, 2, 6): ∂e/∂(ω, δt)
        A = np.einsum("fm,fmdi,fmdj->fij", w, J, J) + 1e-9 * np.eye(6)
        b = -np.einsum("fm,fmdi,fmd->fi", w, J, e)
        step = np.linalg.solve(A, b[..., None])[..., 0]
        R = rodrigues(step[:, :3]) @ R
        t = t + step[:, 3:]
    P = np.einsum("fij,fmj->fmi", R, X) + t[:, None]
    Q = np.broadcast_to(np.eye(2), (*P.shape[:2], 2, 2))
    if sliding is not None:
        Q = contour_projectors(camera, P, tangents, R, sliding)
    residual = np.linalg.norm(np.einsum("fmij,fmj->fmi", Q, camera.project(P) - pixels), axis=-1)
    return R, t, residual


def initial_pose(
    camera: PinholeCamera, model: np.ndarray, pixels: np.ndarray, weights: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """A first pose (R (f, 3, 3), t (f, 3)) of the rigid points ``model`` (m, 3) from ``pixels`` (f, m, 2)
    (NaN where missing) with ``weights`` (f, m): per frame, the affine camera fitted by weighted least
    squares, its 2 × 3 part made the nearest scaled pair of orthonormal rows (the rotation; the scale
    gives the depth f / s), then ``refine_pose``."""
    f, m, _ = pixels.shape
    seen = np.isfinite(pixels).all(axis=-1) & (weights > 0)
    R = np.repeat(FRONT[None], f, axis=0)
    t = np.zeros((f, 3))
    X = np.concatenate([model, np.ones((m, 1))], axis=1)  # (m, 4)
    centre = np.asarray(camera.centre)
    for k in range(f):
        use = seen[k]
        if use.sum() < 4:
            t[k] = [0.0, 0.0, 1.0]
            continue
        sw = np.sqrt(weights[k, use])[:, None]
        affine, *_ = np.linalg.lstsq(sw * X[use], sw * (pixels[k, use] - centre), rcond=None)  # (4, 2)
        u, sigma, vt = np.linalg.svd(affine[:3].T, full_matrices=False)  # (2, 3) = u diag(σ) vt
        rows = u @ vt
        third = np.cross(rows[0], rows[1])
        R[k] = np.stack([rows[0], rows[1], third])
        depth = camera.focal / sigma.mean()
        mean = (weights[k, use] @ model[use]) / weights[k, use].sum()
        image = (weights[k, use] @ pixels[k, use]) / weights[k, use].sum()
        t[k] = np.append((image - centre) * depth / camera.focal, depth) - R[k] @ mean
    R, t, _ = refine_pose(camera, model, pixels, weights * seen, R, t)
    return R, t


def estimate_focal(
    model: np.ndarray, pixels: np.ndarray, weights: np.ndarray, size: tuple[int, int]
) -> tuple[PinholeCamera, bool]:
    """The camera under which the rigid points ``model`` (m, 3) fit the frames' ``pixels`` (f, m, 2)
    (weights (f, m): trust the stiff points) best: a golden-section search over the vertical field of
    view in ``FOV_RANGE_DEG``, each candidate scored by the weighted RMS reprojection error of
    ``initial_pose``. Perspective shows only when the head turns; when the error barely changes
    across the range (``FOCAL_CONTRAST``), the default field of view is returned with ``False``."""

    def error(fov: float) -> float:
        camera = PinholeCamera.from_fov(fov, size)
        R, t = initial_pose(camera, model, pixels, weights)
        _, _, residual = refine_pose(camera, model, pixels, weights, R, t, steps=2)
        w = np.where(np.isfinite(residual), weights, 0.0)
        return float(np.sqrt((w * np.nan_to_num(residual) ** 2).sum() / max(w.sum(), 1e-300)))

    lo, hi = (math.log(math.tan(math.radians(a) / 2)) for a in FOV_RANGE_DEG)  # search in log tan(fov/2)

    def fov_of(x: float) -> float:
        return math.degrees(2 * math.atan(math.exp(x)))

    golden = (math.sqrt(5) - 1) / 2
    a, b = lo, hi
    c, d = b - golden * (b - a), a + golden * (b - a)
    fc, fd = error(fov_of(c)), error(fov_of(d))
    for _ in range(12):
        if fc < fd:
            b, d, fd = d, c, fc
            c = b - golden * (b - a)
            fc = error(fov_of(c))
        else:
            a, c, fc = c, d, fd
            d = a + golden * (b - a)
            fd = error(fov_of(d))
    best = (a + b) / 2
    best_error = error(fov_of(best))
    ends = min(error(fov_of(lo)), error(fov_of(hi)))
    if ends < (1.0 + FOCAL_CONTRAST) * best_error:
        return PinholeCamera.from_fov(DEFAULT_FOV_DEG, size), False
    return PinholeCamera.from_fov(fov_of(best), size), True
