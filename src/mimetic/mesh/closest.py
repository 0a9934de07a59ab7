"""Closest points on a triangle mesh, vectorised: candidates from a k-d tree, exact per triangle.

``trimesh.proximity.closest_point`` is exact but loops in Python per query (about 0.6 ms each on
a 27k-triangle head, so 15 s for a 26k-vertex mesh). Here each query takes its ``k`` nearest
triangles by centroid from a ``cKDTree`` and the closest point on each is computed at once, as
``trimesh.triangles.closest_point`` computes it (a compiled loop with its arithmetic,
``mesh.kernels``); on meshes whose triangles are small next to the distances involved (heads) this
finds the exact closest triangle, and never returns a point off the mesh. An optional normal test
skips triangles facing away from the query's normal (the upper lip's underside does not take the
lower lip's vertices).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache
from types import ModuleType

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from mimetic.mesh.geometry import face_normals

CANDIDATES = 12


@cache
def _kernels() -> ModuleType:
    """``mimetic.mesh.kernels``, imported on first use (numba loads in ~0.3 s)."""
    from mimetic.mesh import kernels

    return kernels


@dataclass(frozen=True)
class ClosestPoints:
    """Closest points of queries on a mesh.

    Attributes
    ----------
    points : (q, 3) float64
        The closest points, in the mesh's units.
    faces : (q,) int64
        Their triangles (index into the mesh's faces); -1 where no triangle qualified.
    bary : (q, 3) float64
        Barycentric coordinates in ``faces`` (each row sums to 1).
    distance : (q,) float64
        Distance from each query (inf where ``faces`` is -1).
    """

    points: np.ndarray
    faces: np.ndarray
    bary: np.ndarray
    distance: np.ndarray


def closest_points(
    vertices: np.ndarray,
    faces: np.ndarray,
    queries: np.ndarray,
    *,
    query_normals: np.ndarray | None = None,
    min_cos: float = 0.0,
    candidates: int = CANDIDATES,
    among: np.ndarray | None = None,
    or_closest: bool = False,
) -> ClosestPoints:
    """The closest point on triangles ``faces`` (m, 3) of ``vertices`` (n, 3) to each query (q, 3).

    With ``query_normals`` (q, 3) (unit), triangles whose unit normal makes a cosine below
    ``min_cos`` with the query's normal are skipped; with ``or_closest`` a query none of whose
    candidates qualifies takes the closest of them anyway (a stray inner surface, the underside of
    a lip whose nearest triangles are the other lip's). ``among`` (q, k) int64, rows of ``faces``:
    each query's candidate triangles (repeats allowed), instead of its ``candidates`` nearest by
    centroid.
    """
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    q = np.asarray(queries, dtype=np.float64)
    tri = v[f]  # (m, 3, 3)
    if among is None:
        k = min(candidates, len(f))
        _, near = cKDTree(tri.mean(axis=1), balanced_tree=False).query(q, k=k)
        near = np.ascontiguousarray(near.reshape(len(q), k), dtype=np.int64)  # (q, k)
    else:
        near = np.ascontiguousarray(among, dtype=np.int64)
    # trimesh.triangles.closest_point on each (query, candidate) pair, compiled: (q, k, 3), (q, k)
    pts, dist = _kernels().closest_on_triangles(v, f, near, q, trimesh.tol.zero)
    dist = np.where(np.isfinite(dist), dist, np.inf)
    any_facing = dist
    if query_normals is not None:
        fn = face_normals(v, f)
        cos = np.einsum("qkd,qd->qk", fn[near], np.asarray(query_normals, dtype=np.float64))
        dist = np.where(cos >= min_cos, dist, np.inf)
    if or_closest:
        dist = np.where(np.isfinite(dist).any(axis=1, keepdims=True), dist, any_facing)
    best = np.argmin(dist, axis=1)
    rows = np.arange(len(q))
    face = near[rows, best]
    point = pts[rows, best]
    distance = dist[rows, best]
    found = np.isfinite(distance)
    bary = np.zeros((len(q), 3))
    if found.any():
        corners = tri[face[found]]  # (f, 3, 3)
        with np.errstate(invalid="ignore", divide="ignore"):
            b = np.clip(trimesh.triangles.points_to_barycentric(corners, point[found]), 0.0, None)
            b /= b.sum(axis=1, keepdims=True)
        # a degenerate triangle (no area: scans and decimations have them) has no barycentric
        # coordinates: its corner nearest the point stands for it
        flat = ~np.isfinite(b).all(axis=1)
        nearest = np.argmin(np.linalg.norm(corners[flat] - point[found][flat, None], axis=2), axis=1)
        b[flat] = np.eye(3)[nearest]
        bary[found] = b
    return ClosestPoints(point, np.where(found, face, -1), bary, distance)
