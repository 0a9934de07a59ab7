"""The openings of a head seen from the front: each eye between its lids, the mouth between its lips.

Found from the mesh's own geometry, so a rig can place its lids and lips on the head's real margins
whatever the landmarks or a fitted template say. The mesh is in a frame with +Y up and +Z forward
(the reference frame of a fit, or a rig's), and only its skin counts: the largest connected piece by
area (eyeballs, lashes, teeth and films are separate pieces, or are ignored with them).

* ``front_depth`` sees the skin along −Z on a regular grid: the depth (z) of the first hit per
  grid point (trimesh's ray-triangle test, on the grid points in each triangle's bounding box),
  NaN where the ray misses. ``seen_eye`` compares two such maps: where an eyeball shows in front
  of the skin (a lid that does not cover it).
* **Eyes** (``eye_opening``): a lid's margin is a silhouette seen from the front: past it the ray
  goes on into the eye socket or through a hole, so the depth jumps. The grid is split into pieces
  wherever neighbouring depths differ by more than ``JUMP_REL`` of the eye width; the skin around
  the eye is the piece holding most of the window's border, and the opening is the other grid
  points, the connected part of them covering the middle of the eye. Its top and bottom per column
  are the upper and lower margins.
* **Mouth** (``mouth_opening``): closed lips meet along a narrow valley of the depth, where the
  skin folds in between them. The seam is the cheapest path across the window (moving at most one
  row per column, within ``MOUTH_BAND_REL`` of the line between the corners) through a cost that
  is low in narrow valleys (the depth under the surface closed over it, a black top-hat: a broad
  slope such as the fold under a full lower lip is no valley) and along the skin's rim seen from
  the front; it ends at the commissures, where the valley under both lips falls below
  ``VALLEY_REL`` of the mouth width and no rim follows it (breaks shorter than ``VALLEY_GAP_REL``
  bridged), and never runs past the landmark corners. Where the lips are apart the seam runs
  through the gap (nothing behind it, or the mouth's cavity far behind: ``THROUGH_REL``), and the
  gap's top and bottom are the margins.

The constants below were chosen on ICT-FaceKit's neutral and identities s1-s2 at σ 1, s2-s6 at σ 2
and s4 at σ 3 (``benchmarks/sweep_motion.py``'s calibration heads); that benchmark reports them on
57 others. Both give up (``None``) rather than guess: a window without a clear opening or valley (eyes closed
by faces, as on a face mask; eyeballs fused into the skin; a mouth slit closed by faces is still
found, as a valley), or an opening far from where the corners said.

Over 600 lines because the eyes' and the mouth's openings, their margins and sides, and what is
seen of an eyeball all read the same depth maps seen from the front and the same skin graph.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import trimesh
from scipy import ndimage
from scipy.sparse.csgraph import connected_components as graph_components
from scipy.sparse.csgraph import dijkstra

from mimetic.mesh.geometry import (
    boundary_edges,
    closest_on_polyline,
    connected_components,
    edges_unique,
    face_normals,
    vertex_normals,
)
from mimetic.mesh.memo import per_arrays

__all__ = [
    "DepthMap",
    "Opening",
    "SeenEye",
    "eye_opening",
    "eyeball",
    "front_depth",
    "gaze_rim",
    "margin_distance",
    "margin_seeds",
    "mouth_opening",
    "opening_margins",
    "opening_sides",
    "seen_eye",
    "skin_faces",
    "without_pits",
]

EYE_SURFACE_SHARE = 0.9
"""A point of an eye part this far or farther from the eyeball's centre (× its radius) is on its
surface (``seen_eye``); ICT's caruncle pieces in the inner corners lie at 0.75."""
EYE_STEP_REL = 1 / 60
"""Grid spacing around an eye, × the eye width (0.5 mm on a 3 cm eye)."""
EYE_WINDOW_REL = (0.85, 0.6)
"""Half the window's width and height around an eye's corners, × the eye width."""
JUMP_REL = 0.06
"""Neighbouring depths further apart than this × the eye width are on two sides of a silhouette
(a slope of 3.6 over one grid step: 75° from the view)."""
MOUTH_STEP_REL = 1 / 100
"""Grid spacing around the mouth, × the mouth width (0.5 mm on a 5 cm mouth)."""
MOUTH_MARGIN_REL = (0.15, 0.3)
"""The mouth's window reaches this far beyond the corners, and above and below them, × its width."""
MOUTH_BAND_REL = 0.2
"""The lips' seam stays within this × the mouth width of the line through the corners."""
VALLEY_REL = 0.02
"""The seam is between the lips while the depth rises by this × the mouth width on both sides within
``VALLEY_REACH_REL``; past the commissures it does not."""
VALLEY_REACH_REL = 0.12
CORNER_SLACK_REL = 0.05
"""The seam ends at most this × the mouth width beyond either corner."""
VALLEY_GAP_REL = 0.15
"""Breaks in the valley up to this × the mouth width long are bridged."""
THROUGH_REL = 0.25
"""A seam point more than this × the mouth width behind the lips on both sides is seen through a gap
between them (into the mouth's cavity), not where they touch: touching lips left valleys up to 0.11
× the width deep on ICT's neutral (calibration) and s106 σ 3, s108 σ 2 (check heads), and a gap
showed the cavity 1.9-2.2 widths behind (ICT's middle, s106's corner)."""
RIM_GAIN = 0.05
"""A grid point next to the skin's rim counts as a valley this × the mouth width deep (the seam's
cost; a clear valley between parted lips is deeper)."""
MIN_SPAN_REL = 0.5
"""An opening spanning less than this × the corners' distance, or centred further than ``OFF_REL``
of it from their middle, is not the one the corners mean."""
OFF_REL = 0.35
SEED_TOLERANCE_REL = 0.03
"""A rim vertex within this × an opening's width of its edge, seen from the front, is on its margin
(two eye grid steps)."""
DEPTH_GATE_REL = 0.05
"""... unless it lies more than this × the opening's width behind the edge."""
EYEBALL_RADIUS_REL = (0.2, 0.9)
"""An eyeball's radius is between these × the eye's width (the corners' distance)."""
SPHERE_FIT = 0.1
HIDDEN_REL = 0.9


@dataclass(frozen=True)
class DepthMap:
    """The skin seen along −Z: ``z[i, j]`` is the depth of the first hit at (``x[j]``, ``y[i]``), NaN
    where the ray misses. ``x`` (nx,), ``y`` (ny,) increasing, mesh units."""

    x: np.ndarray
    y: np.ndarray
    z: np.ndarray


@dataclass(frozen=True)
class SeenEye:
    """Where an eyeball shows in front of the skin, seen along −Z (``seen_eye``): ``visible[i, j]`` at
    (``x[j]``, ``y[i]``), ``x`` (nx,) and ``y`` (ny,) increasing with spacing ``step``, mesh units."""

    x: np.ndarray
    y: np.ndarray
    visible: np.ndarray
    step: float

    @property
    def heights(self) -> np.ndarray:
        """(nx,) the height of eyeball seen in each column, mesh units."""
        return self.visible.sum(axis=0) * self.step

    @property
    def tops(self) -> np.ndarray:
        """(nx,) the highest point of eyeball seen in each column (NaN where none), mesh units."""
        top = np.where(self.visible, self.y[:, None], -np.inf).max(axis=0)
        return np.where(np.isfinite(top), top, np.nan)

    @property
    def bottoms(self) -> np.ndarray:
        """(nx,) the lowest point of eyeball seen in each column (NaN where none), mesh units."""
        bottom = np.where(self.visible, self.y[:, None], np.inf).min(axis=0)
        return np.where(np.isfinite(bottom), bottom, np.nan)


@dataclass(frozen=True)
class Opening:
    """An opening's margins, as polylines on the skin sampled at the same ``x`` (increasing).

    Attributes
    ----------
    upper, lower : (k, 3) float64
        Points of the upper and lower margin, mesh units; for closed lips both are the line where
        they meet. The first and last points are the corners' ends (the corners lie between
        ``upper[0]`` and ``lower[0]``, and between ``upper[-1]`` and ``lower[-1]``).
    """

    upper: np.ndarray
    lower: np.ndarray

    def __post_init__(self) -> None:
        for name in ("upper", "lower"):
            array = np.array(getattr(self, name), dtype=np.float64, copy=True).reshape(-1, 3)
            array.setflags(write=False)
            object.__setattr__(self, name, array)

    @property
    def corners(self) -> np.ndarray:
        """The two corners (2, 3), smaller x first."""
        return 0.5 * np.stack([self.upper[0] + self.lower[0], self.upper[-1] + self.lower[-1]])

    @property
    def width(self) -> float:
        return float(np.linalg.norm(self.corners[1] - self.corners[0]))

    def between_corners(self, points: np.ndarray, inset: float) -> np.ndarray:
        """(k,) bool: which ``points`` (k, 3) lie between the corners, ``inset`` × the width in from
        each, measured along the line through them."""
        a, b = self.corners
        along = (points - a) @ (b - a) / ((b - a) @ (b - a))
        return (along > inset) & (along < 1 - inset)


@per_arrays(2)
def skin_faces(vertices: np.ndarray, faces: np.ndarray, *, labels: np.ndarray | None = None) -> np.ndarray:
    """The faces (f, 3) of the largest connected piece of the mesh by area: the skin. ``labels`` (n,):
    the pieces (``connected_components(faces, n)[1]``), when the caller has them. Read-only, and
    computed once per (``vertices``, ``faces``) of a ``Mesh`` (``mesh.memo``)."""
    if labels is None:
        _, labels = connected_components(faces, len(vertices))
    face_label = labels[faces[:, 0]]
    area = np.linalg.norm(face_normals(vertices, faces, unit=False), axis=1)
    return faces[face_label == np.argmax(np.bincount(face_label, weights=area))]


def gaze_rim(vertices: np.ndarray, faces: np.ndarray, gaze: np.ndarray) -> np.ndarray:
    """Vertices (n,) bool where the surface, seen along ``gaze`` (3,), ends or turns away: on a boundary
    edge, or shared by a face facing the viewer (n · gaze > 0) and one facing away. A lid margin is
    such a rim: the skin ends at an eye hole or folds back into the eye socket there. (Found once per
    mesh and gaze, ``mesh.memo``; a new array each call.)"""
    return _gaze_rim(vertices, faces, *(float(g) for g in np.asarray(gaze, dtype=np.float64).reshape(3)))


@per_arrays(2, copies=True)
def _gaze_rim(vertices: np.ndarray, faces: np.ndarray, *gaze: float) -> np.ndarray:
    n = len(vertices)
    normals = face_normals(vertices, faces, unit=False)
    facing = normals @ np.array(gaze)
    has_area = np.linalg.norm(normals, axis=1) > 0
    front = np.zeros(n, dtype=bool)
    back = np.zeros(n, dtype=bool)
    front[faces[has_area & (facing > 0)].ravel()] = True
    back[faces[has_area & (facing <= 0)].ravel()] = True
    rim = front & back
    rim[boundary_edges(faces).ravel()] = True
    return rim


@per_arrays(2)
def _face_boxes(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Each face's bounds in x and y, (f, 4): x min, x max, y min, y max (remembered per mesh)."""
    corners = vertices[faces]  # (f, 3, 3)
    x, y = corners[:, :, 0], corners[:, :, 1]
    return np.column_stack([x.min(axis=1), x.max(axis=1), y.min(axis=1), y.max(axis=1)])


@per_arrays(2)
def _face_centres(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Each face's centroid (f, 3) (remembered per mesh)."""
    return vertices[faces].mean(axis=1)


def front_depth(
    vertices: np.ndarray,
    faces: np.ndarray,
    low: np.ndarray,
    high: np.ndarray,
    step: float,
    *,
    keep: np.ndarray | None = None,
) -> DepthMap:
    """The depth of ``faces`` (only those of ``keep`` (f,) bool, when given) seen along −Z over the grid
    from ``low`` to ``high`` ((2,) x and y) with spacing ``step``, mesh units."""
    x = np.arange(low[0], high[0] + step / 2, step)
    y = np.arange(low[1], high[1] + step / 2, step)
    box = _face_boxes(vertices, faces)  # (f, 4)
    inside = (box[:, 1] >= low[0]) & (box[:, 0] <= high[0]) & (box[:, 3] >= low[1]) & (box[:, 2] <= high[1])
    if keep is not None:
        inside &= keep
    if not inside.any():
        return DepthMap(x, y, np.full((len(y), len(x)), np.nan))
    triangles = vertices[faces[inside]]  # (m, 3, 3)
    top = triangles[:, :, 2].max() + step  # the rays start above everything and go down
    # the grid points in each triangle's bounding box, widened by a millionth of a step (trimesh's
    # broad phase is the same test with an r-tree, and its hits lie within 1e-12 of a triangle's
    # barycentric range, so no hit is lost); then trimesh's narrow phase on them, compiled
    first = np.ceil((triangles[:, :, :2].min(axis=1) - [x[0], y[0]]) / step - 1e-6).astype(np.int64)  # (m, 2)
    last = np.floor((triangles[:, :, :2].max(axis=1) - [x[0], y[0]]) / step + 1e-6).astype(np.int64)
    first = np.maximum(first, 0)
    last = np.minimum(last, [len(x) - 1, len(y) - 1])
    from mimetic.mesh.kernels import first_hits  # numba loads on first use (~0.3 s), not on import

    z = first_hits(triangles, first, last, x, y, float(top), trimesh.tol.zero, trimesh.util.TOL_ZERO)
    return DepthMap(x, y, z)


def seen_eye(
    vertices: np.ndarray,
    eye: np.ndarray,
    skin: np.ndarray,
    corners: np.ndarray,
    span: tuple[float, float],
    step: float,
    sphere: tuple[np.ndarray, float] | None = None,
) -> SeenEye:
    """Where the eyeball's faces ``eye`` (e, 3) show in front of the ``skin`` faces (s, 3) (or with no
    skin in front) of ``vertices`` (n, 3), seen along −Z on a grid of spacing ``step`` over the part
    ``span`` (fractions) of the x range between the eye's ``corners`` (2, 3), as high and low as the
    corners are apart about their mean height. Lashes and films hide nothing unless passed as skin.
    With the eyeball's ``sphere`` (centre (3,), radius), only what is seen of its surface counts
    (``EYE_SURFACE_SHARE``): not a caruncle or tear film the eye part holds deep in the corner."""
    corners = np.asarray(corners, dtype=np.float64)
    x0, x1 = np.sort(corners[:, 0])
    width = float(np.linalg.norm(corners[1] - corners[0]))
    middle = corners[:, 1].mean()
    low = np.array([x0 + span[0] * (x1 - x0), middle - width])
    high = np.array([x0 + span[1] * (x1 - x0), middle + width])
    ball = front_depth(vertices, eye, low, high, step)
    cover = without_pits(front_depth(vertices, skin, low, high, step).z)
    visible = np.isfinite(ball.z) & ~(cover >= ball.z)  # NaN skin compares False: nothing hides it
    if sphere is not None:
        centre, radius = sphere
        hit = np.stack(np.broadcast_arrays(ball.x[None, :], ball.y[:, None], ball.z), axis=-1)
        visible &= np.linalg.norm(hit - centre, axis=-1) >= EYE_SURFACE_SHARE * radius
    return SeenEye(ball.x, ball.y, visible, step)


def without_pits(z: np.ndarray) -> np.ndarray:
    """The depth map ``z`` (ny, nx) (NaN: no hit) with its one-point pits filled: a ray along an edge
    two triangles share can miss both by a rounding (two of the 10,000 grid points over ICT's closed
    right eye showed the eyeball behind it), so a point deeper than all four of its neighbours takes
    the deepest of theirs (on the map's border, of those it has). A hole two points across keeps its
    depth."""
    deep = np.where(np.isnan(z), -np.inf, z)
    around = np.pad(deep, 1, constant_values=np.inf)
    neighbours = np.minimum.reduce([around[:-2, 1:-1], around[2:, 1:-1], around[1:-1, :-2], around[1:-1, 2:]])
    filled = np.maximum(deep, neighbours)
    return np.where(np.isinf(filled), np.nan, filled)


def _pieces(z: np.ndarray, jump: float) -> np.ndarray:
    """Labels (ny, nx) of the grid's pieces: 4-neighbours are joined where their depths differ by at
    most ``jump`` (two misses are joined; a miss and a hit are not)."""
    ids = np.arange(z.size).reshape(z.shape)
    deep = np.where(np.isnan(z), -np.inf, z)
    rows, cols = [], []
    for a, b in ((ids[:, :-1], ids[:, 1:]), (ids[:-1, :], ids[1:, :])):
        za, zb = deep.ravel()[a.ravel()], deep.ravel()[b.ravel()]
        with np.errstate(invalid="ignore"):
            near = (np.abs(za - zb) <= jump) | (np.isinf(za) & np.isinf(zb))
        rows.append(a.ravel()[near])
        cols.append(b.ravel()[near])
    r, c = np.concatenate(rows), np.concatenate(cols)
    graph = sp.coo_matrix((np.ones(len(r)), (r, c)), shape=(z.size, z.size))
    return graph_components(graph, directed=False)[1].reshape(z.shape)


def _margins(depth: DepthMap, mask: np.ndarray) -> Opening:
    """The top and bottom of ``mask`` (ny, nx) per column, on the skin just outside it."""
    step = float(depth.y[1] - depth.y[0])
    columns = np.flatnonzero(mask.any(axis=0))
    top = len(depth.y) - 1 - np.argmax(mask[::-1, columns], axis=0)  # highest row in the mask
    bottom = np.argmax(mask[:, columns], axis=0)
    above = np.minimum(top + 1, len(depth.y) - 1)
    below = np.maximum(bottom - 1, 0)
    x = depth.x[columns]
    upper = np.column_stack([x, depth.y[top] + step / 2, depth.z[above, columns]])
    lower = np.column_stack([x, depth.y[bottom] - step / 2, depth.z[below, columns]])
    return Opening(upper, lower)


def _plausible(opening: Opening, corners: np.ndarray) -> bool:
    """The opening spans the corners' distance roughly and is centred near them; its margins have a depth."""
    width = float(np.linalg.norm(corners[1] - corners[0]))
    if not (np.isfinite(opening.upper).all() and np.isfinite(opening.lower).all()):
        return False
    span = opening.upper[-1, 0] - opening.upper[0, 0]
    centre = 0.5 * (opening.upper[:, :2].mean(axis=0) + opening.lower[:, :2].mean(axis=0))
    return bool(
        span >= MIN_SPAN_REL * width and np.linalg.norm(centre - corners.mean(axis=0)[:2]) <= OFF_REL * width
    )


def eyeball(vertices: np.ndarray, faces: np.ndarray, corners: np.ndarray) -> tuple[np.ndarray, float] | None:
    """The sphere (centre (3,), radius) of one eye's eyeball: of the mesh's connected pieces other than
    the skin whose vertices lie on a sphere (RMS off it under ``SPHERE_FIT`` of its radius) of radius
    ``EYEBALL_RADIUS_REL`` × the corners' distance, centred between the ``corners`` (2, 3) seen from
    the front, the one with the largest area (the sclera, not a cornea or a tear film); None without."""
    corners = np.asarray(corners, dtype=np.float64)
    width = float(np.linalg.norm(corners[1] - corners[0]))
    middle = corners.mean(axis=0)
    low, high = EYEBALL_RADIUS_REL
    best, best_area = None, 0.0
    for area, mean, centre, radius, off in _spheres(vertices, faces):
        if area <= best_area or np.linalg.norm(mean[:2] - middle[:2]) > OFF_REL * width:
            continue
        if low * width < radius < high * width and off < SPHERE_FIT * radius:
            best, best_area = (centre, radius), area
    return best


@per_arrays(2)
def _spheres(
    vertices: np.ndarray, faces: np.ndarray
) -> tuple[tuple[float, np.ndarray, np.ndarray, float, float], ...]:
    """Per connected piece other than the largest (the skin) with at least 20 vertices, in piece order:
    its area, the mean (3,) of its vertices, their least-squares sphere's centre (3,) and radius, and
    the RMS of their distances off that sphere (remembered per mesh: ``eyeball`` asks once per eye)."""
    _, labels = connected_components(faces, len(vertices))
    face_label = labels[faces[:, 0]]
    area = np.bincount(face_label, weights=np.linalg.norm(face_normals(vertices, faces, unit=False), axis=1))
    order = np.argsort(face_label, kind="stable")
    bounds = np.searchsorted(face_label[order], np.arange(len(area) + 1))
    out = []
    for piece in np.flatnonzero(np.diff(bounds)):
        ids = np.unique(faces[order[bounds[piece] : bounds[piece + 1]]])
        if piece == area.argmax() or len(ids) < 20:
            continue
        points = vertices[ids]
        a = np.column_stack([2.0 * points, np.ones(len(points))])
        solution = np.linalg.lstsq(a, np.sum(points**2, axis=1), rcond=None)[0]
        centre = solution[:3]
        radius = float(np.sqrt(max(solution[3] + centre @ centre, 0.0)))
        off = float(np.sqrt(np.mean((np.linalg.norm(points - centre, axis=1) - radius) ** 2)))
        out.append((float(area[piece]), points.mean(axis=0), centre, radius, off))
    return tuple(out)


def eye_opening(
    vertices: np.ndarray,
    faces: np.ndarray,
    corners: np.ndarray,
    ball: tuple[np.ndarray, float] | None = None,
) -> Opening | None:
    """The opening between one eye's lids (see the module docstring).

    Parameters
    ----------
    vertices : (n, 3) float64
        +Y up, +Z forward.
    faces : (m, 3) int64
        The skin's faces (``skin_faces``): other pieces would hide the opening.
    corners : (2, 3) float64
        The eye's corners, roughly (landmarks): they set the window and which opening is meant.
    ball : (centre (3,), radius), optional
        The eyeball (``eyeball``): skin well inside it (nearer its centre than ``HIDDEN_REL`` of its
        radius: a conjunctiva tucked behind the lids) is hidden and left out.

    Returns
    -------
    Opening, or None when there is no opening near the corners.
    """
    corners = np.asarray(corners, dtype=np.float64)
    seen = None
    if ball is not None:
        seen = np.linalg.norm(_face_centres(vertices, faces) - ball[0], axis=1) >= HIDDEN_REL * ball[1]
    width = float(np.linalg.norm(corners[1] - corners[0]))
    middle = corners.mean(axis=0)
    half = np.array(EYE_WINDOW_REL) * width
    depth = front_depth(
        vertices, faces, middle[:2] - half, middle[:2] + half, EYE_STEP_REL * width, keep=seen
    )
    labels = _pieces(depth.z, JUMP_REL * width)
    border = np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])
    hole = labels != np.bincount(border).argmax()
    if not hole.any():
        return None
    ny, nx = hole.shape
    centre = np.zeros_like(hole)
    centre[ny // 2 - ny // 6 : ny // 2 + ny // 6 + 1, nx // 2 - nx // 4 : nx // 2 + nx // 4 + 1] = True
    pieces, _ = ndimage.label(hole)
    overlap = np.bincount(pieces[centre])
    overlap[0] = 0
    if overlap.max() == 0:
        return None
    mask = ndimage.binary_opening(ndimage.binary_fill_holes(pieces == overlap.argmax()), np.ones((3, 3)))
    pieces, count = ndimage.label(mask)
    if count == 0:
        return None
    mask = pieces == np.bincount(pieces.ravel())[1:].argmax() + 1
    if mask[0].any() or mask[-1].any():  # reaches the window's top or bottom: not an eye's opening
        return None
    opening = _margins(depth, mask)
    return opening if _plausible(opening, corners) else None


def _seam(cost: np.ndarray) -> np.ndarray:
    """Rows (nx,) of the cheapest path across ``cost`` (ny, nx) from its first column to its last,
    moving at most one row per column (dynamic programming)."""
    ny, nx = cost.shape
    total = cost[:, 0].copy()
    back = np.zeros((ny, nx), dtype=np.int64)
    rows = np.arange(ny)
    for column in range(1, nx):
        options = np.stack(
            [np.r_[np.inf, total[:-1]], total, np.r_[total[1:], np.inf]]
        )  # from row-1, row, row+1
        best = np.argmin(options, axis=0)
        back[:, column] = rows + best - 1
        total = options[best, rows] + cost[:, column]
    path = np.empty(nx, dtype=np.int64)
    path[-1] = int(np.argmin(total))
    for column in range(nx - 1, 0, -1):
        path[column - 1] = back[path[column], column]
    return path


def mouth_opening(vertices: np.ndarray, faces: np.ndarray, corners: np.ndarray) -> Opening | None:
    """Where the lips meet, or the gap between them (see the module docstring).

    Parameters
    ----------
    vertices : (n, 3) float64
        +Y up, +Z forward.
    faces : (m, 3) int64
        The skin's faces (``skin_faces``).
    corners : (2, 3) float64
        The mouth corners, roughly (landmarks).

    Returns
    -------
    Opening (``upper`` and ``lower`` the same line where the lips touch), or None without a
    valley between the corners.
    """
    corners = np.asarray(corners, dtype=np.float64)
    corners = corners[np.argsort(corners[:, 0])]
    width = float(np.linalg.norm(corners[1] - corners[0]))
    step = MOUTH_STEP_REL * width
    reach_x, reach_y = np.array(MOUTH_MARGIN_REL) * width
    middle_y = corners[:, 1].mean()
    low = np.array([corners[0, 0] - reach_x, middle_y - reach_y])
    high = np.array([corners[1, 0] + reach_x, middle_y + reach_y])
    depth = front_depth(vertices, faces, low, high, step)
    z = np.where(np.isnan(depth.z), -np.inf, depth.z)  # a miss is deepest: through the gap
    line = np.interp(depth.x, corners[:, 0], corners[:, 1])
    band = np.abs(depth.y[:, None] - line[None]) < MOUTH_BAND_REL * width
    finite = np.where(np.isinf(z), np.nanmin(depth.z) - width if np.isfinite(depth.z).any() else 0.0, z)
    reach = max(int(VALLEY_REACH_REL * width / step), 1)
    # how far each point lies below the surface closed over it up and down (a black top-hat): the
    # lips' seam is a narrow valley, a slope (the fold under a full lower lip) is none
    valley_depth = ndimage.grey_closing(finite, size=(2 * reach + 1, 1)) - finite
    # pressed lips leave almost no valley, but the skin still folds in between them: the seam
    # follows the skin's rim seen from the front (``gaze_rim``) where there is one
    rim = vertices[gaze_rim(vertices, faces, np.array([0.0, 0.0, 1.0]))]
    col = np.round((rim[:, 0] - depth.x[0]) / step).astype(np.int64)
    row = np.round((rim[:, 1] - depth.y[0]) / step).astype(np.int64)
    inside = (col >= 0) & (col < len(depth.x)) & (row >= 0) & (row < len(depth.y))
    folds = np.zeros(z.shape)
    folds[row[inside], col[inside]] = 1.0
    folds = ndimage.maximum_filter(folds, size=3)
    path = _seam(np.where(band, -(valley_depth / width + RIM_GAIN * folds), np.inf))
    columns = np.arange(len(depth.x))
    above = np.array([z[r : r + reach, c].max() for c, r in zip(columns, path, strict=True)])
    below = np.array([z[max(r - reach, 0) : r + 1, c].max() for c, r in zip(columns, path, strict=True)])
    floor = z[path, columns]
    with np.errstate(invalid="ignore"):  # a column with no skin (inf - inf) is no valley
        valley = (np.minimum(above, below) - floor > VALLEY_REL * width) | (folds[path, columns] > 0)
    gap = max(int(VALLEY_GAP_REL * width / step), 1)  # short breaks (lips pressed flat) are bridged
    valley = ndimage.binary_closing(valley, np.ones(gap)) | valley
    offset = np.abs(depth.x - corners[:, 0].mean())
    near = valley & (offset <= OFF_REL * width)
    if not near.any():
        return None
    start = int(np.argmin(np.where(near, offset, np.inf)))
    first, last = start, start
    while first > 0 and valley[first - 1]:
        first -= 1
    while last < len(columns) - 1 and valley[last + 1]:
        last += 1
    keep = columns[first : last + 1]
    # not past the corners the landmarks give: a crease running on from a commissure is no lip
    keep = keep[np.abs(depth.x[keep] - corners[:, 0].mean()) <= (0.5 + CORNER_SLACK_REL) * width]
    # through a gap the margins are its top and bottom; where the lips touch, the valley's floor. A
    # gap shows nothing (a mask's open mouth) or the mouth's cavity far behind the lips
    with np.errstate(invalid="ignore"):  # inf - inf where a column shows nothing at all
        through = np.isinf(floor) | (np.minimum(above, below) - floor > THROUGH_REL * width)
        gap = np.isinf(z) | (z < floor[None] + 0.5 * (np.minimum(above, below) - floor)[None])
    top, bottom = path.copy(), path.copy()
    for c in keep:
        while top[c] + 1 < len(depth.y) and gap[top[c] + 1, c] and through[c]:
            top[c] += 1
        while bottom[c] > 0 and gap[bottom[c] - 1, c] and through[c]:
            bottom[c] -= 1
    touching = ~through[keep]
    up_z = np.where(touching, floor[keep], depth.z[np.minimum(top[keep] + 1, len(depth.y) - 1), keep])
    low_z = np.where(touching, floor[keep], depth.z[np.maximum(bottom[keep] - 1, 0), keep])
    x = depth.x[keep]
    opening = Opening(
        np.column_stack([x, depth.y[top[keep]], up_z]), np.column_stack([x, depth.y[bottom[keep]], low_z])
    )
    return opening if _plausible(opening, corners) else None


def margin_distance(vertices: np.ndarray, faces: np.ndarray, seeds: np.ndarray, reach: float) -> np.ndarray:
    """Distance (n,) from the ``seeds`` (k,) int64 along the edges of ``faces`` (Dijkstra), inf beyond
    ``reach`` or where no path leads."""
    return _distance(_edge_graph(vertices, faces), seeds, reach)


@per_arrays(2)
def _edge_graph(vertices: np.ndarray, faces: np.ndarray) -> sp.csr_matrix:
    """The edges of ``faces`` as an (n, n) CSR graph weighted by their lengths (upper triangle);
    remembered for read-only arrays (never changed by its callers)."""
    edges = edges_unique(faces)
    length = np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1)
    return sp.coo_matrix((length, (edges[:, 0], edges[:, 1])), shape=(len(vertices),) * 2).tocsr()


def _distance(graph: sp.csr_matrix, seeds: np.ndarray, reach: float) -> np.ndarray:
    """``margin_distance`` over a graph from ``_edge_graph``."""
    if not len(seeds):
        return np.full(graph.shape[0], np.inf)
    return dijkstra(graph, directed=False, indices=seeds, limit=reach, min_only=True)


def opening_sides(
    vertices: np.ndarray, faces: np.ndarray, upper: np.ndarray, lower: np.ndarray, reach: float
) -> np.ndarray:
    """Which side of an opening each vertex is on: the side of the margin nearest to it along the
    mesh's edges (a geodesic Voronoi split of the lips, or of the lids).

    The upper lip's inner surface, and the mouth cavity behind it, are nearer the upper margin than
    the lower along the surface even where the lips overlap and a plane through the opening would
    cut them; the corners, where the margins meet, split halfway.

    Parameters
    ----------
    vertices : (n, 3) float64
    faces : (m, 3) int64
    upper, lower : (a,), (b,) int64
        The margins' vertices (seeds); a vertex in both counts for neither.
    reach : float
        Vertices farther than this from both margins along the edges are on neither side (0).

    Returns
    -------
    (n,) int8: +1 upper, −1 lower, 0 neither.
    """
    upper, lower = np.setdiff1d(upper, lower), np.setdiff1d(lower, upper)
    side = np.zeros(len(vertices), dtype=np.int8)
    if not len(upper) or not len(lower):
        return side
    graph = _edge_graph(vertices, faces)  # once for both margins
    to_upper = _distance(graph, upper, reach)
    to_lower = _distance(graph, lower, reach)
    side[to_upper < to_lower] = 1
    side[to_lower < to_upper] = -1
    return side


def _line_distance(points: np.ndarray, line: np.ndarray) -> np.ndarray:
    """Distance (k,) of ``points`` (k, 3) from a margin ``line`` (p, 3) seen from the front (in x and
    y), inf for points more than ``DEPTH_GATE_REL`` of the line's length behind it (a rim deeper in
    the socket or the mouth, seen through the opening)."""
    flat = np.column_stack([points[:, :2], np.zeros(len(points))])
    seg, t, dist = closest_on_polyline(flat, np.column_stack([line[:, :2], np.zeros(len(line))]))
    depth = line[seg, 2] + t * (line[np.minimum(seg + 1, len(line) - 1), 2] - line[seg, 2])
    span = float(np.linalg.norm(line[-1, :2] - line[0, :2]))
    return np.where(points[:, 2] >= depth - DEPTH_GATE_REL * span, dist, np.inf)


def margin_seeds(
    vertices: np.ndarray, faces: np.ndarray, opening: Opening, tolerance: float
) -> tuple[np.ndarray, np.ndarray]:
    """The vertices (a,), (b,) int64 of the upper and lower margin of ``opening``: the skin's rim
    vertices (``gaze_rim``; ``faces`` are the skin's) within ``tolerance`` of a margin line seen
    from the front and not far behind it (``_line_distance``), on the nearer line's margin. Where
    the lips touch both lines are the one they meet along; there the normals tell the lips apart:
    upper where the skin's normal points down (the upper lip's underside), lower where it points up."""
    rim = np.flatnonzero(gaze_rim(vertices, faces, np.array([0.0, 0.0, 1.0])))
    if len(opening.upper) < 2 or not len(rim):
        return rim[:0], rim[:0]
    to_upper = _line_distance(vertices[rim], opening.upper)
    to_lower = _line_distance(vertices[rim], opening.lower)
    near = np.minimum(to_upper, to_lower) <= tolerance
    down = vertex_normals(vertices, faces)[rim, 1] < 0
    with np.errstate(invalid="ignore"):  # both inf: behind both lines, not near either
        tied = np.abs(to_upper - to_lower) <= tolerance / 2
    upper = np.where(tied, down, to_upper < to_lower)
    return rim[near & upper], rim[near & ~upper]


def opening_margins(
    vertices: np.ndarray, faces: np.ndarray, openings: Mapping[str, Opening]
) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per opening, its upper and lower margin vertices (a,), (b,) int64 on the mesh's skin
    (``margin_seeds`` within ``SEED_TOLERANCE_REL`` of the opening's width)."""
    skin = skin_faces(vertices, faces)
    return {
        name: margin_seeds(vertices, skin, opening, SEED_TOLERANCE_REL * opening.width)
        for name, opening in openings.items()
    }
