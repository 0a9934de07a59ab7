"""Perspective cameras, named views and the projection shared by both renderers.

Conventions: world axes are right-handed, +Y up, +Z forward (the face looks down +Z). View
space is OpenGL's: the camera looks down -Z with +Y up. Pixel coordinates have x to the right
and y down, with the centre of pixel ``(i, j)`` at ``(i + 0.5, j + 0.5)``; they are the
coordinates in which ``render`` draws, so ``project`` tells where a 3D point lands in an image.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from types import MappingProxyType
from typing import NamedTuple

import numpy as np

#: Named views: yaw in degrees. Positive yaw turns the face toward the subject's left (+X),
#: which is the image right, so "profile" shows the nose pointing right.
VIEWS = MappingProxyType({"front": 0.0, "three_quarter": 35.0, "profile": 90.0})


def _vec3(value, name: str) -> np.ndarray:
    array = np.array(value, dtype=np.float64).reshape(-1)
    if array.shape != (3,) or not np.all(np.isfinite(array)):
        raise ValueError(f"camera {name} must be 3 finite numbers; got {value!r}")
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class Camera:
    """A pinhole camera at ``eye`` looking at ``target``.

    Attributes
    ----------
    eye, target : (3,) float64
        Camera position and the point it looks at, in mesh units.
    up : (3,) float64
        Approximate up direction; it is made orthogonal to the viewing direction.
    fov_y_deg : float
        Vertical field of view in degrees.
    """

    eye: np.ndarray
    target: np.ndarray
    up: np.ndarray = (0.0, 1.0, 0.0)  # type: ignore[assignment]
    fov_y_deg: float = 28.0

    def __post_init__(self) -> None:
        for name in ("eye", "target", "up"):
            object.__setattr__(self, name, _vec3(getattr(self, name), name))
        if not 0.0 < self.fov_y_deg < 180.0:
            raise ValueError(f"fov_y_deg={self.fov_y_deg} must be in (0, 180)")
        forward = self.target - self.eye
        if np.linalg.norm(forward) == 0.0:
            raise ValueError(f"camera eye and target are the same point {self.eye.tolist()}")
        side = np.cross(forward, self.up)
        if np.linalg.norm(side) <= 1e-12 * np.linalg.norm(forward) * np.linalg.norm(self.up):
            raise ValueError(f"camera up {self.up.tolist()} is parallel to the viewing direction")

    def basis(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Unit ``(right, up, forward)`` (3,) vectors in world space; ``forward`` points at the target."""
        forward = self.target - self.eye
        forward = forward / np.linalg.norm(forward)
        right = np.cross(forward, self.up)
        right /= np.linalg.norm(right)
        return right, np.cross(right, forward), forward

    def view_matrix(self) -> np.ndarray:
        """World → view transform (4, 4) float64 (OpenGL ``lookAt``: the camera looks down -Z)."""
        right, up, forward = self.basis()
        rotation = np.stack([right, up, -forward])  # (3, 3), rows = view axes
        view = np.eye(4)
        view[:3, :3] = rotation
        view[:3, 3] = -rotation @ self.eye
        return view

    def projection_matrix(self, aspect: float, near: float, far: float) -> np.ndarray:
        """View → clip transform (4, 4) float64 (OpenGL ``gluPerspective``); ``aspect`` is width / height."""
        if not (aspect > 0 and 0 < near < far):
            raise ValueError(f"need aspect > 0 and 0 < near < far; got {aspect=}, {near=}, {far=}")
        f = 1.0 / math.tan(math.radians(self.fov_y_deg) / 2)
        return np.array(
            [
                [f / aspect, 0.0, 0.0, 0.0],
                [0.0, f, 0.0, 0.0],
                [0.0, 0.0, (far + near) / (near - far), 2 * far * near / (near - far)],
                [0.0, 0.0, -1.0, 0.0],
            ]
        )


def frame_camera(
    bbox_min: np.ndarray,
    bbox_max: np.ndarray,
    *,
    yaw_deg: float = 0.0,
    pitch_deg: float = 0.0,
    fill: float = 0.8,
    fov_y_deg: float = 28.0,
    aspect: float = 1.0,
) -> Camera:
    """A camera looking at the centre of a box from the +Z side, turned by yaw and pitch.

    The face is seen as if turned by ``yaw_deg`` toward the subject's left (+X, the image right)
    and tilted by ``pitch_deg`` chin-up (the camera moves below). The distance is the smallest at
    which all 8 box corners project inside the central ``fill`` fraction of the frame, for an
    image of the given ``aspect`` (width / height); the box touches that margin on at least one side.

    Parameters
    ----------
    bbox_min, bbox_max : (3,) float
        Opposite corners of the box, e.g. ``vertices.min(0)`` and ``vertices.max(0)``.

    Returns
    -------
    Camera with ``up`` the tilted +Y.
    """
    lo, hi = _vec3(bbox_min, "bbox_min"), _vec3(bbox_max, "bbox_max")
    if np.any(hi < lo):
        raise ValueError(f"bbox_max {hi.tolist()} is below bbox_min {lo.tolist()} on some axis")
    if not fill > 0:
        raise ValueError(f"fill={fill} must be positive")
    diagonal = float(np.linalg.norm(hi - lo))
    if diagonal == 0.0:
        raise ValueError(f"the box is a single point {lo.tolist()}; nothing to frame")
    # Turning the face by (yaw, pitch) is the camera orbiting by (-yaw, -pitch): the eye direction
    # is R_y(-yaw) (0, -sin pitch, cos pitch), and up is R_y(-yaw) (0, cos pitch, sin pitch).
    sy, cy = math.sin(math.radians(yaw_deg)), math.cos(math.radians(yaw_deg))
    sp, cp = math.sin(math.radians(pitch_deg)), math.cos(math.radians(pitch_deg))
    toward_eye = np.array([-sy * cp, -sp, cy * cp])
    up = np.array([-sy * sp, cp, cy * sp])
    right = np.cross(-toward_eye, up)
    center = (lo + hi) / 2
    signs = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    corners = signs * (hi - lo) / 2  # (8, 3) relative to centre
    x, y, z = corners @ right, corners @ up, corners @ toward_eye  # (8,) each, z toward the eye
    tan_y = fill * math.tan(math.radians(fov_y_deg) / 2)
    tan_x = tan_y * aspect
    # A corner fits when |x| <= tan_x (d - z) and |y| <= tan_y (d - z), d = eye-to-centre distance.
    distance = float(np.max(z + np.maximum(np.abs(x) / tan_x, np.abs(y) / tan_y)))
    distance = max(distance, float(z.max()) + 0.01 * diagonal)
    return Camera(center + distance * toward_eye, center, up, fov_y_deg)


class Projection(NamedTuple):
    """Where points land in an image: ``pixels`` (k, 2) float64 (x right, y down, NaN behind the
    camera) and ``depth`` (k,) float64, the distance in front of the camera along its axis."""

    pixels: np.ndarray
    depth: np.ndarray


def _size(size: int | tuple[int, int]) -> tuple[int, int]:
    w, h = (size, size) if np.isscalar(size) else size  # type: ignore[misc]
    if int(w) != w or int(h) != h or w < 1 or h < 1:
        raise ValueError(f"image size must be a positive int or (width, height); got {size!r}")
    return int(w), int(h)


def project(points: np.ndarray, camera: Camera, size: int | tuple[int, int]) -> Projection:
    """Pixel coordinates of 3D points in an image rendered with ``camera`` at ``size``.

    Parameters
    ----------
    points : (k, 3) or (3,) float
        World positions.
    size : int or (width, height)

    Returns
    -------
    Projection(pixels (k, 2) float64, depth (k,) float64). The centre of pixel ``(i, j)`` is at
    ``(i + 0.5, j + 0.5)``; points at depth <= 0 (behind the camera) get NaN pixels.
    """
    w, h = _size(size)
    p = np.asarray(points, dtype=np.float64)
    single = p.ndim == 1
    p = np.atleast_2d(p)
    if p.shape[1] != 3:
        raise ValueError(f"points must have shape (k, 3); got {np.shape(points)}")
    right, up, forward = camera.basis()
    rel = p - camera.eye  # (k, 3)
    depth = rel @ forward  # (k,)
    f = 1.0 / math.tan(math.radians(camera.fov_y_deg) / 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        ndc_x = (f * h / w) * (rel @ right) / depth
        ndc_y = f * (rel @ up) / depth
    pixels = np.stack([(ndc_x + 1) * (w / 2), (1 - ndc_y) * (h / 2)], axis=1)
    pixels[depth <= 0] = np.nan
    if single:
        return Projection(pixels[0], depth[0])
    return Projection(pixels, depth)


def clip_planes(camera: Camera, vertices: np.ndarray) -> tuple[float, float]:
    """Near and far distances (both > 0) that enclose ``vertices`` (n, 3) in front of ``camera``.

    Both renderers use these, so they clip and order depths the same way.
    """
    _, _, forward = camera.basis()
    if len(vertices) == 0:
        return 0.01, 1.0
    depth = (np.asarray(vertices, dtype=np.float64) - camera.eye) @ forward  # (n,)
    far = float(depth.max())
    if far <= 0:  # everything is behind the camera: any valid planes draw nothing
        return 0.01, 1.0
    far *= 1.05
    near = max(0.5 * float(depth.min()), 1e-4 * far)
    return near, far
