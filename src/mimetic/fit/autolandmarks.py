"""Landmarks found automatically: render the mesh, run MediaPipe FaceMesh, lift the points onto it.

``auto_landmarks(mesh)`` renders the mesh (untextured is fine) from the front and at a few yaw
angles, runs MediaPipe FaceMesh on each render (``mimetic.fit.detect.detect_face``), casts a ray
through each 2D landmark onto the mesh, and votes across the views. The mesh may face any
axis-aligned direction with any axis-aligned up; the orientation is found by trying them. The
result is a ``mimetic.fit.landmarks.Landmarks``, as a landmark file gives.
``lift_mediapipe_points(mesh, indices)`` does the same for any FaceMesh indices and returns
bare surface points (e.g. all 468 for a capture marker layout).

This is the one module of ``fit`` that renders (``mimetic.render``, which sits below ``fit``);
mediapipe itself is imported only when ``auto_landmarks`` first runs (see ``mimetic.fit.detect``).

Over 600 lines because the views it renders, the detection in each and the lifting of 2D points
onto the surface are one chain with shared cameras.
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from mimetic.errors import LandmarkError, MeshError
from mimetic.fit.detect import N_LANDMARKS, detect_face
from mimetic.fit.landmarks import MIN_LANDMARKS, Landmarks
from mimetic.mesh.geometry import vertex_normals
from mimetic.mesh.model import Mesh
from mimetic.mesh.units import UNIT_SCALE, detect_units
from mimetic.render.appearance import Surface, surface
from mimetic.render.camera import Camera, frame_camera, project
from mimetic.render.raster import ALBEDO, DETECTION
from mimetic.render.renderer import Renderer, default_renderer

log = logging.getLogger(__name__)

__all__ = ["MEDIAPIPE_LANDMARKS", "SOURCE_AUTO", "auto_landmarks", "lift_mediapipe_points"]


def _pairs(**pairs: tuple[int, int]) -> dict[str, int]:
    """``name=(left, right)`` -> ``{"name_L": left, "name_R": right}``."""
    return {
        f"{name}_{side}": index for name, lr in pairs.items() for side, index in zip("LR", lr, strict=True)
    }


# Project landmark -> MediaPipe FaceMesh index (of 478, refine_landmarks=True): for each name, the
# mirror pair of indices whose lifted 3D points land nearest the head's own landmark, measured on
# 12 generated heads (9 parameter sets, with and without vertex colours) at yaws 0 and ±25°, and
# checked on ICT-FaceKit's iBUG-68 vertices. Left out as inaccurate (median error > 6.5 % or
# worst > 10 % of the inter-ocular distance): the jaw contour, gonion, tragion and zygion
# (silhouette points, 20-70 %), brow_mid (8-11 %), the nostrils (up to 18 % on ICT) and the
# inner-lip points off the midline (rays into the lip seam). The generated head's brow_outer and
# brow_outer_mid sit about 20 % of the IOD from ICT's iBUG brow points; 283/53 and 282/52 follow
# the reference head, which the fit needs.
MEDIAPIPE_LANDMARKS: dict[str, int] = {
    **_pairs(
        eye_outer_corner=(466, 246),
        eye_inner_corner=(362, 133),
        eye_upper_lid=(386, 159),
        eye_lower_lid=(374, 145),
        eye_upper_lid_inner=(385, 158),
        eye_upper_lid_outer=(387, 160),
        eye_lower_lid_inner=(380, 153),
        eye_lower_lid_outer=(390, 163),
        pupil=(473, 468),
        brow_inner=(336, 107),
        brow_inner_mid=(296, 66),
        brow_outer_mid=(282, 52),
        brow_outer=(283, 53),
        alar_base=(305, 75),
        alare=(294, 64),
        mouth_corner=(306, 76),
        upper_lip_peak=(267, 37),
        upper_lip_outer=(269, 39),
        lower_lip_mid=(315, 85),
        lower_lip_outer=(321, 91),
    ),
    "glabella": 9,
    "nasion": 8,
    "nose_bridge_upper": 6,
    "nose_bridge_lower": 195,
    "nose_tip": 4,
    "subnasale": 2,
    "upper_lip_top": 0,
    "upper_lip_inner": 13,
    "lower_lip_inner": 14,
    "lower_lip_bottom": 16,
    "menton": 152,
    "pogonion": 199,
}


CROWN_DEPTH_CM = 25.0  # frame the part of the mesh within this distance of the top of the head
FILL = 0.85  # fraction of the frame the framed box fills (as in tests/fit/test_detect.py)
SEARCH_SIZE = 192  # pixels; FaceDetection's short-range model looks at 128 x 128 anyway
GOOD_SCORE = 0.75  # an upright frontal face scoring this ends the orientation search early
MAX_ROLL_DEG = 30.0  # an upright face: eyes-to-mouth within this angle of the image's down
MIN_IOD_OVER_EYE_MOUTH = 0.8  # a frontal face: eyes apart at least this times eyes-to-mouth
MIN_SCORE = 0.5  # below this, a render has no face (detect_face's own gate)
MIN_FACING = 0.2  # |cos| between ray and surface normal below which a hit is grazing: dropped
FULL_FACING = 0.7  # |cos| from which a hit counts fully in the vote
INLIER_TOL_IOD = 0.10  # hits farther than this (fraction of the inter-ocular distance) are not averaged
TOL_2D_IOD = 0.08  # a candidate agrees with a view when it projects this close (fraction of 2D IOD)
SEEN_TOL_IOD = 0.03  # a candidate is visible in a view when the view's ray comes back this close
SOURCE_AUTO = "auto:mediapipe"
_OUTER_CANTHI = (263, 33)  # MediaPipe indices of the left and right outer eye corners
_MOUTH_CORNERS = (291, 61)


def _rotation(forward: np.ndarray, up: np.ndarray) -> np.ndarray:
    """The rotation (3, 3) taking ``forward`` to +Z and ``up`` to +Y (rows: right, up, forward)."""
    return np.stack([np.cross(up, forward), up, forward]).astype(np.float64)


def _orientation_stages() -> list[list[np.ndarray]]:
    """All 24 axis-aligned rotations (mesh frame → +Y up, +Z forward) in three stages.

    Stage 1 is our convention (the identity); stage 2 the usual exports (facing -Z, ±X with
    +Y up; Z-up files facing -Y or +Y); stage 3 the other 18.
    """
    x, y, z = np.eye(3)
    first = [_rotation(z, y)]
    common = [_rotation(-z, y), _rotation(x, y), _rotation(-x, y), _rotation(-y, z), _rotation(y, z)]
    rest = []
    for forward in (z, -z, x, -x, y, -y):
        for up in (y, -y, z, -z, x, -x):
            if abs(forward @ up) > 0.5:
                continue
            rotation = _rotation(forward, up)
            if not any(np.array_equal(rotation, r) for r in first + common):
                rest.append(rotation)
    return [first, common, rest]


def _crown_depth(mesh: Mesh) -> float:
    """CROWN_DEPTH_CM in the mesh's units (guessed from its size when unknown); inf when unknown."""
    units = mesh.units
    if units is None:
        try:
            units = detect_units(mesh.vertices)
        except MeshError:
            return math.inf
    return CROWN_DEPTH_CM * UNIT_SCALE["cm"] / UNIT_SCALE[units]


def _camera(vertices: np.ndarray, rotation: np.ndarray, depth: float, yaw_deg: float) -> Camera:
    """A camera in the mesh frame framing the top ``depth`` (mesh units) of the head, re-oriented.

    ``vertices`` (n, 3) in the mesh frame; ``rotation`` (3, 3) takes it to +Y up, +Z forward, where
    ``frame_camera`` places the camera at ``yaw_deg``; the camera is then turned back by ``rotation.T``.
    """
    upright = vertices @ rotation.T  # (n, 3) in the +Y up, +Z forward frame
    top = upright[upright[:, 1] > upright[:, 1].max() - depth]
    c = frame_camera(top.min(axis=0), top.max(axis=0), yaw_deg=yaw_deg, fill=FILL)
    return Camera(rotation.T @ c.eye, rotation.T @ c.target, rotation.T @ c.up, c.fov_y_deg)


@dataclass(frozen=True, eq=False)
class _View:
    """One render with a face: camera, image size (w, h), FaceDetection score, FaceMesh pixels (478, 2)."""

    yaw_deg: float
    camera: Camera
    size: tuple[int, int]
    score: float
    pixels: np.ndarray


def _upright(landmarks: np.ndarray) -> bool:
    """Whether FaceMesh ``landmarks`` (478, 2) pixels show a face upright and seen from the front.

    Upright: the mouth is below the eyes, within ``MAX_ROLL_DEG`` of straight down the image.
    Frontal: the eyes are at least ``MIN_IOD_OVER_EYE_MOUTH`` times as far apart as the eyes are
    from the mouth (about 1.3 from the front, under 0.5 in profile), so a side view of the head,
    which FaceDetection may still score 0.85, does not pass for the front.
    """
    eyes = landmarks[list(_OUTER_CANTHI)]  # (2, 2)
    down = landmarks[list(_MOUTH_CORNERS)].mean(axis=0) - eyes.mean(axis=0)  # image y points down
    roll = math.degrees(math.atan2(-down[0], down[1]))
    iod = float(np.linalg.norm(eyes[0] - eyes[1]))
    return abs(roll) <= MAX_ROLL_DEG and iod >= MIN_IOD_OVER_EYE_MOUTH * float(np.linalg.norm(down))


def _find_orientation(
    mesh: Mesh, renderer: Renderer, depth: float, look: Surface
) -> tuple[np.ndarray, float, int]:
    """The candidate rotation whose front render (of what ``look`` says) shows the best upright frontal
    face.

    Candidates are ranked by (upright and frontal, FaceDetection score); the search stops after
    a stage of ``_orientation_stages`` once an upright frontal face scores ``GOOD_SCORE``.

    Returns
    -------
    (rotation (3, 3), its FaceDetection score, number of renders tried)
    """
    best, best_key, tried = np.eye(3), (False, -1.0), 0
    for stage in _orientation_stages():
        for rotation in stage:
            camera = _camera(mesh.vertices, rotation, depth, 0.0)
            detection = detect_face(
                renderer.render(mesh, camera, size=(SEARCH_SIZE, SEARCH_SIZE), lighting=DETECTION, look=look)
            )
            key = (detection.found and _upright(detection.landmarks), detection.score)
            tried += 1
            log.debug(
                "orientation forward=%s up=%s: score %.3f, upright %s", rotation[2], rotation[1], *key[::-1]
            )
            if key > best_key:
                best, best_key = rotation, key
        if best_key[0] and best_key[1] >= GOOD_SCORE:
            break
    return best, best_key[1], tried


def _views(
    mesh: Mesh, rotation: np.ndarray, depth: float, yaws_deg, size: int, renderer, look: Surface, progress
) -> list[_View]:
    """Render (what ``look`` says) at each yaw and run FaceMesh; only the renders with a face are kept."""
    views = []
    for k, yaw in enumerate(yaws_deg):
        camera = _camera(mesh.vertices, rotation, depth, float(yaw))
        detection = detect_face(
            renderer.render(mesh, camera, size=(size, size), lighting=DETECTION, look=look),
            min_score=MIN_SCORE,
        )
        log.debug("yaw %+.0f: score %.3f, found %s", yaw, detection.score, detection.found)
        if detection.found:
            views.append(_View(float(yaw), camera, (size, size), detection.score, detection.landmarks))
        if progress is not None:
            progress(k + 2, len(yaws_deg) + 2)
    return views


def _ray_directions(camera: Camera, pixels: np.ndarray, size: tuple[int, int]) -> np.ndarray:
    """Unit directions (k, 3) of the rays from ``camera.eye`` through ``pixels`` (k, 2) (x right, y down)."""
    w, h = size
    right, up, forward = camera.basis()
    tan = math.tan(math.radians(camera.fov_y_deg) / 2)
    ndc_x = 2.0 * pixels[:, 0] / w - 1.0  # inverse of mimetic.view.project
    ndc_y = 1.0 - 2.0 * pixels[:, 1] / h
    d = forward + (ndc_x * tan * w / h)[:, None] * right + (ndc_y * tan)[:, None] * up  # (k, 3)
    return d / np.linalg.norm(d, axis=1, keepdims=True)


class _RayCaster:
    """Rays from one camera onto one mesh, for many queries (``prepare`` once, ``cast`` often).

    The triangles in front of the camera are binned once by their projected bounding boxes on a
    grid of ``GRID`` cells along the longer side; a ray is then tested (Möller–Trumbore) against
    the triangles of its own cell only.

    Parameters
    ----------
    vertices : (n, 3) float64; faces : (m, 3) int64
    normals : (n, 3) float64
        Unit vertex normals (``mimetic.mesh.geometry.vertex_normals``), interpolated at each hit.
    camera : Camera; size : (w, h) pixels
        The view the query pixels are in (as rendered and as ``mimetic.view.project`` maps).
    """

    GRID = 96

    def __init__(
        self,
        vertices: np.ndarray,
        faces: np.ndarray,
        normals: np.ndarray,
        camera: Camera,
        size: tuple[int, int],
    ) -> None:
        self.vertices, self.faces, self.normals, self.camera, self.size = (
            vertices,
            faces,
            normals,
            camera,
            size,
        )
        projection = project(vertices, camera, size)
        face_ids = np.flatnonzero((projection.depth[faces] > 0).all(axis=1))  # triangles in front
        corners = projection.pixels[faces[face_ids]]  # (m', 3, 2)
        lo, hi = corners.min(axis=1), corners.max(axis=1)  # (m', 2) bounding boxes
        self.origin = lo.min(axis=0) if len(face_ids) else np.zeros(2)
        extent = hi.max(axis=0) - self.origin if len(face_ids) else np.zeros(2)
        self.cell = max(float(extent.max()) / self.GRID, 1e-12)
        self.n_cells = np.floor(extent / self.cell).astype(np.int64) + 1  # (2,)
        c0 = np.minimum(np.floor((lo - self.origin) / self.cell).astype(np.int64), self.n_cells - 1)
        c1 = np.minimum(np.floor((hi - self.origin) / self.cell).astype(np.int64), self.n_cells - 1)
        span = c1 - c0 + 1  # (m', 2)
        count = span[:, 0] * span[:, 1]  # cells per triangle
        owner = np.repeat(np.arange(len(face_ids)), count)  # triangle of each (triangle, cell) pair
        local = np.arange(len(owner)) - np.repeat(np.cumsum(count) - count, count)
        cell_id = (
            (c0[owner, 1] + local // span[owner, 0]) * self.n_cells[0] + c0[owner, 0] + local % span[owner, 0]
        )
        order = np.argsort(cell_id, kind="stable")
        self.cell_sorted, self.face_sorted = cell_id[order], face_ids[owner[order]]

    def cast(self, pixels: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The first surface points hit by the rays from the camera through ``pixels`` (k, 2).

        Returns
        -------
        points : (k, 3) float64
            Exact points on the hit triangles (barycentric combinations of their corners); NaN
            where the ray misses or the pixel is NaN.
        facing : (k,) float64
            |cos| of the angle between the ray and the smooth surface normal at the hit; 0 on a miss.
        """
        k = len(pixels)
        points, facing = np.full((k, 3), np.nan), np.zeros(k)
        cells = np.floor((pixels - self.origin) / self.cell)  # (k, 2), NaN rows stay NaN
        inside = (
            np.isfinite(cells).all(axis=1) & (cells >= 0).all(axis=1) & (cells < self.n_cells).all(axis=1)
        )
        rows = np.flatnonzero(inside)
        qc = cells[rows].astype(np.int64)
        key = qc[:, 1] * self.n_cells[0] + qc[:, 0]
        start = np.searchsorted(self.cell_sorted, key, "left")
        n_pairs = np.searchsorted(self.cell_sorted, key, "right") - start
        ray = np.repeat(np.arange(len(rows)), n_pairs)  # (p,) ray of each (ray, triangle) pair
        tri_id = self.face_sorted[
            np.repeat(start - (np.cumsum(n_pairs) - n_pairs), n_pairs) + np.arange(len(ray))
        ]
        d = _ray_directions(self.camera, pixels[rows], self.size)[ray]  # (p, 3)
        tri = self.vertices[self.faces[tri_id]]  # (p, 3, 3)
        # Möller–Trumbore: eye + t d = (1 - u - v) A + u B + v C
        e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
        pvec = np.cross(d, e2)
        det = np.einsum("pi,pi->p", e1, pvec)
        usable = np.abs(det) > 1e-300
        inv = np.divide(1.0, det, out=np.zeros_like(det), where=usable)
        tvec = self.camera.eye - tri[:, 0]
        qvec = np.cross(tvec, e1)
        u = np.einsum("pi,pi->p", tvec, pvec) * inv
        v = np.einsum("pi,pi->p", d, qvec) * inv
        t = np.einsum("pi,pi->p", e2, qvec) * inv
        eps = 1e-9  # a ray through a shared edge hits at least one of its triangles
        hit = usable & (u >= -eps) & (v >= -eps) & (u + v <= 1 + eps) & (t > 0)
        t = np.where(hit, t, np.inf)
        nearest = np.full(len(rows), np.inf)
        np.minimum.at(nearest, ray, t)
        winners = np.flatnonzero(hit & (t == nearest[ray]))
        _, first = np.unique(ray[winners], return_index=True)  # one winner per ray
        winners = winners[first]
        uv = np.clip(np.column_stack([u[winners], v[winners]]), 0.0, 1.0)
        uv /= np.maximum(uv.sum(axis=1, keepdims=True), 1.0)
        bary = np.column_stack([1.0 - uv.sum(axis=1), uv])  # (w, 3)
        target = rows[ray[winners]]
        points[target] = np.einsum("wj,wjd->wd", bary, tri[winners])
        normal = np.einsum("wj,wjd->wd", bary, self.normals[self.faces[tri_id[winners]]])  # (w, 3) smooth
        flat = np.linalg.norm(normal, axis=1) < 1e-6  # opposite normals cancelled: use the triangle's
        normal[flat] = np.cross(e1[winners][flat], e2[winners][flat])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
        facing[target] = np.abs(np.einsum("wi,wi->w", normal, d[winners]))
        return points, facing


def _facing_weight(facing: np.ndarray) -> np.ndarray:
    """Vote weight of a hit: 0 when grazing (|cos| <= MIN_FACING), 1 from FULL_FACING, linear between."""
    return np.clip((facing - MIN_FACING) / (FULL_FACING - MIN_FACING), 0.0, 1.0)


def _vote(views: list[_View], casters: list[_RayCaster], indices: np.ndarray, iod: float):
    """Consensus positions of MediaPipe points ``indices`` (k,) over the views.

    Each view's ray through a landmark gives a candidate surface point. A candidate is supported
    by a view when it is visible there (the view's ray through its projection comes back to it)
    and projects within ``TOL_2D_IOD`` x that view's 2D inter-ocular distance of the view's own
    detection. The candidate with the most support (weighted by how squarely each view sees the
    surface) wins; this rejects rays that slid off a silhouette (the nose ridge in a turned
    view) onto the surface behind, which no other view confirms.

    Returns
    -------
    positions : (k, 3) float64
        Surface points: the mean of the supporting views' own hits within ``INLIER_TOL_IOD`` x
        ``iod`` of the winner, put back on the surface; NaN where no candidate was usable.
    confidence : (k,) float64 in [0, 1]
        Sum over supporting views of weight x exp(-(2D error / tolerance)^2), over the number
        of views; 0 where the position is NaN.
    backers : (k,) int64
        Views supporting the winner. A position needs two (one when there is a single view).
    """
    n_views, k = len(views), len(indices)
    pixels = np.stack([view.pixels[indices] for view in views])  # (v, k, 2)
    hits, facing = zip(*(caster.cast(pixels[v]) for v, caster in enumerate(casters)), strict=True)
    hits, facing = np.stack(hits), np.stack(facing)  # (v, k, 3), (v, k)
    usable = _facing_weight(facing) > 0  # (v, k): a hit on a surface seen squarely enough
    candidates = hits.reshape(-1, 3)  # (v * k, 3), candidate c = v * k + j
    support = np.zeros((n_views, n_views, k))  # [u, v, j]: view u's vote for view v's candidate j
    error = np.full((n_views, n_views, k), np.inf)  # 2D error in units of the tolerance
    for u, (view, caster) in enumerate(zip(views, casters, strict=True)):
        canthi = view.pixels[list(_OUTER_CANTHI)]
        tol_px = TOL_2D_IOD * float(np.linalg.norm(canthi[0] - canthi[1]))
        projected = project(np.nan_to_num(candidates), view.camera, view.size).pixels  # (v * k, 2)
        back, back_facing = caster.cast(projected)
        seen = np.linalg.norm(back - candidates, axis=1) <= SEEN_TOL_IOD * iod  # NaN compares False
        gap = np.linalg.norm(projected - np.tile(pixels[u], (n_views, 1)), axis=1) / tol_px
        agree = seen & (gap <= 1.0) & usable.reshape(-1)
        support[u] = np.where(agree, _facing_weight(back_facing), 0.0).reshape(n_views, k)
        error[u] = np.where(agree, gap, np.inf).reshape(n_views, k)
    votes = support * np.exp(-(error**2))  # (u, v, k): soft, so the tighter of two agreeing candidates wins
    # frontal views break ties: FaceMesh is most reliable on a face seen straight on
    frontal = np.array([math.cos(math.radians(view.yaw_deg)) for view in views])
    total = votes.sum(axis=0) + 1e-3 * frontal[:, None]  # (v, k)
    total[~usable] = -1.0
    winner = np.argmax(total, axis=0)  # (k,)
    columns = np.arange(k)
    centre = hits[winner, columns]  # (k, 3)
    backers = support[:, winner, columns] > 0  # (u, k)
    confidence = votes[:, winner, columns].sum(axis=0) / n_views
    near = np.linalg.norm(np.nan_to_num(hits) - centre, axis=2) <= INLIER_TOL_IOD * iod  # (v, k)
    mix = backers & usable & near
    mix[winner, columns] = usable[winner, columns]
    count = mix.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.einsum("vk,vkd->kd", mix, np.nan_to_num(hits)) / count[:, None]
    positions = centre.copy()
    for v, (view, caster) in enumerate(zip(views, casters, strict=True)):  # back onto the surface
        rows = np.flatnonzero((winner == v) & (count > 1))
        if len(rows):
            hit, _ = caster.cast(project(mean[rows], view.camera, view.size).pixels)
            good = np.linalg.norm(hit - mean[rows], axis=1) <= 0.5 * INLIER_TOL_IOD * iod
            positions[rows[good]] = hit[good]
    # one view alone is not evidence when others could have confirmed it (e.g. a pupil seen through
    # the socket of a mesh without eyeballs lands on the back of the head, somewhere else per view)
    found = usable[winner, columns] & (backers.sum(axis=0) >= min(2, n_views))
    positions[~found] = np.nan
    confidence[~found] = 0.0
    return positions, np.clip(confidence, 0.0, 1.0), backers.sum(axis=0)


@dataclass(frozen=True, eq=False)
class _Detected:
    """Everything ``_detect`` found, for ``auto_landmarks`` and for measuring index choices."""

    rotation: np.ndarray  # (3, 3) mesh frame -> +Y up, +Z forward
    score: float  # best FaceDetection score of the orientation search
    views: list[_View]
    iod: float  # inter-ocular distance (outer canthi), mesh units
    positions: np.ndarray  # (k, 3), NaN where no view agreed
    confidence: np.ndarray  # (k,)
    backers: np.ndarray  # (k,) int, views supporting each position


def _detect(
    mesh: Mesh,
    indices: np.ndarray,
    *,
    yaws_deg: Sequence[float],
    size: int,
    renderer: Renderer | None,
    progress: Callable[[int, int], None] | None,
) -> _Detected:
    """Orientation search, renders, FaceMesh, ray casting and vote for MediaPipe points ``indices`` (k,)."""
    if mesh.n_faces == 0:
        raise MeshError("cannot find landmarks on a mesh without faces")
    if not np.all(np.isfinite(mesh.vertices)):
        raise MeshError("cannot find landmarks: the mesh has NaN or infinite vertices; fix the mesh first")
    yaws = np.asarray(yaws_deg, dtype=np.float64).reshape(-1)
    if len(yaws) == 0 or not np.all(np.abs(yaws) < 90.0):
        raise ValueError(
            f"yaws_deg must list angles in (-90, 90) degrees, e.g. (0.0, -25.0, 25.0); got {yaws_deg!r}"
        )
    if int(size) != size or size < 64:
        raise ValueError(f"size must be an integer number of pixels >= 64, e.g. 512; got {size!r}")
    renderer = default_renderer() if renderer is None else renderer
    start = time.perf_counter()
    depth = _crown_depth(mesh)
    look = surface(mesh, ALBEDO)  # what every render draws, as ``render`` would find it each time
    rotation, score, tried = _find_orientation(mesh, renderer, depth, look)
    log.debug(
        "orientation search: %d renders, best score %.3f, %.2f s", tried, score, time.perf_counter() - start
    )
    if progress is not None:
        progress(1, len(yaws_deg) + 2)
    if score < MIN_SCORE:
        raise LandmarkError(
            f"no face found in renders of the mesh from {tried} directions (best FaceDetection score "
            f"{score:.2f} < {MIN_SCORE}). Check that the mesh is a head with a face (eyes, nose, mouth), "
            "or give the landmarks in a file (CLI: --landmarks lm.csv; API: read_landmarks)."
        )
    views = _views(mesh, rotation, depth, yaws_deg, size, renderer, look, progress)
    if not views:
        raise LandmarkError(
            f"FaceMesh found no face in the {len(yaws)} full-size renders (yaws {yaws.tolist()}) "
            f"although the orientation search scored {score:.2f}. Give the landmarks in a file instead "
            "(CLI: --landmarks lm.csv; API: read_landmarks), e.g. the 68 points dlib or face-alignment "
            "find on a render of the head."
        )
    normals = vertex_normals(mesh.vertices, mesh.faces)  # (n, 3)
    casters = [_RayCaster(mesh.vertices, mesh.faces, normals, view.camera, view.size) for view in views]
    iods = []
    for view, caster in zip(views, casters, strict=True):
        canthi, _ = caster.cast(view.pixels[list(_OUTER_CANTHI)])
        if np.isfinite(canthi).all():
            iods.append(float(np.linalg.norm(canthi[0] - canthi[1])))
    if not iods:
        raise LandmarkError(
            "the rays through the outer eye corners MediaPipe found miss the mesh in every view; "
            "give the landmarks in a file (CLI: --landmarks lm.csv; API: read_landmarks)."
        )
    iod = float(np.median(iods))
    positions, confidence, backers = _vote(views, casters, indices, iod)
    if progress is not None:
        progress(len(yaws_deg) + 2, len(yaws_deg) + 2)
    log.debug("auto landmarks: %d views, IOD %.3g, %.2f s", len(views), iod, time.perf_counter() - start)
    return _Detected(rotation, score, views, iod, positions, confidence, backers)


def lift_mediapipe_points(
    mesh: Mesh,
    indices: Sequence[int] | np.ndarray,
    *,
    yaws_deg: Sequence[float] = (0.0, -25.0, 25.0),
    size: int = 512,
    renderer: Renderer | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Any MediaPipe FaceMesh points on a head mesh's surface, found as ``auto_landmarks`` finds its own.

    The same orientation search, renders, ray casting and vote as ``auto_landmarks`` (see there),
    for the FaceMesh indices ``indices`` instead of ``MEDIAPIPE_LANDMARKS``.

    Parameters
    ----------
    mesh : Mesh
        Vertices (n, 3) in ``mesh.units``; colours are used when present, untextured is fine.
    indices : (k,) int
        FaceMesh landmark indices in 0..477 (468..477 are the iris points, which lie inside the
        eye and are rarely confirmed on a mesh).
    yaws_deg, size, renderer, progress
        As in ``auto_landmarks``.

    Returns
    -------
    positions : (k, 3) float64
        Exact surface points (on a triangle of ``mesh``) in the mesh's own frame and units; NaN
        where fewer than two views agree (one, when ``yaws_deg`` has a single angle).
    confidence : (k,) float64
        In [0, 1], the weighted share of views agreeing; 0 where ``positions`` is NaN.

    Raises
    ------
    LandmarkError, MissingExtraError, MeshError
        As in ``auto_landmarks``.
    ValueError
        An index outside 0..477, or bad ``yaws_deg`` or ``size``.
    """
    index = np.asarray(indices).reshape(-1)
    if index.dtype.kind not in "iu" or not np.all((index >= 0) & (index < N_LANDMARKS)):
        raise ValueError(
            f"indices must be FaceMesh landmark numbers in 0..{N_LANDMARKS - 1}; got {indices!r}"
        )
    found = _detect(
        mesh, index.astype(np.int64), yaws_deg=yaws_deg, size=size, renderer=renderer, progress=progress
    )
    return found.positions, found.confidence


def auto_landmarks(
    mesh: Mesh,
    *,
    yaws_deg: Sequence[float] = (0.0, -25.0, 25.0),
    size: int = 512,
    renderer: Renderer | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Landmarks:
    """Find the project's landmarks on a head mesh with MediaPipe FaceMesh.

    1. Orientation: the mesh may face any axis-aligned direction with any axis-aligned up.
       Small front renders (``SEARCH_SIZE``) of the candidates are ranked by (FaceMesh sees an
       upright frontal face, FaceDetection score): first ours (+Z forward, +Y up), then the usual
       exports (-Z or ±X forward; Z-up facing ∓Y), then the other 18, stopping after a stage
       once an upright face scores ``GOOD_SCORE``.
    2. Views: the top ``CROWN_DEPTH_CM`` of the mesh along the chosen up axis (so a neck or
       shoulders do not shrink the face) is framed and rendered at each yaw; FaceMesh runs on
       each render with a face.
    3. Lifting and vote: a ray through each 2D landmark gives one surface point per view. A
       point is kept when another view confirms it (it is visible there and projects within
       ``TOL_2D_IOD`` of that view's own detection); the confirmed hits are averaged and put
       back on the surface. Rays that graze the surface or slide off a silhouette are outvoted.

    Parameters
    ----------
    mesh : Mesh
        Vertices (n, 3) in ``mesh.units``; colours are used when present, untextured is fine.
    yaws_deg : sequence of float
        Yaw angles of the views in degrees (positive turns the face toward its left, +X).
    size : int
        Width and height of the renders in pixels.
    renderer : Renderer, optional
        Defaults to ``mimetic.view.default_renderer()``.
    progress : callable(done, total), optional
        Called after the orientation search, after each view, and at the end.

    Returns
    -------
    Landmarks
        The names of ``MEDIAPIPE_LANDMARKS`` confirmed by two views (by one when ``yaws_deg``
        has a single angle), in that table's order; positions (k, 3) float64, exact surface
        points in the mesh's own frame and ``mesh.units``; confidence (k,) in (0, 1], the
        weighted share of views agreeing; ``orientation`` the (3, 3) rotation taking the mesh
        frame to +Y up, +Z forward; ``source`` "auto:mediapipe".

    Raises
    ------
    LandmarkError
        No face in any orientation (e.g. a sphere or a cube), or too few landmarks on the surface.
    MissingExtraError
        mediapipe is not installed (``pip install 'mimetic[track]'``).
    MeshError
        The mesh has no faces, or NaN vertices.
    ValueError
        An empty or out-of-range ``yaws_deg``, or ``size`` below 64.
    """
    names = tuple(MEDIAPIPE_LANDMARKS)
    found = _detect(
        mesh,
        np.array([MEDIAPIPE_LANDMARKS[n] for n in names]),
        yaws_deg=yaws_deg,
        size=size,
        renderer=renderer,
        progress=progress,
    )
    keep = np.isfinite(found.positions).all(axis=1)
    if keep.sum() < MIN_LANDMARKS:
        raise LandmarkError(
            f"only {int(keep.sum())} landmarks could be put on the surface (need {MIN_LANDMARKS}); "
            "the mesh may have holes or be turned away. Give the landmarks in a file (CLI: --landmarks "
            "lm.csv; API: read_landmarks)."
        )
    return Landmarks(
        tuple(n for n, k in zip(names, keep, strict=True) if k),
        found.positions[keep],
        found.confidence[keep],
        mesh.units,
        SOURCE_AUTO,
        found.rotation,
    )
