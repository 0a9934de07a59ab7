"""A coarse copy of a dense surface, and every dense point tied to it.

Dense scans (0.5-5 M vertices) are rigged and simulated on a decimated copy (a *proxy*) whose
answers are then carried to every vertex of the user's mesh. ``decimate`` makes the copy with
fast-simplification's quadric edge collapse (the backend of trimesh's
``simplify_quadric_decimation``); ``embed`` ties each dense point to its closest proxy triangle
(barycentric coordinates, plus its offset from the triangle in the triangle's own frame, so the
detail between proxy vertices is kept rather than flattened); ``Embedding.carry`` interpolates
per-vertex values (skin weights, displacements, memberships) from the proxy to the dense points.
"""

from __future__ import annotations

from dataclasses import dataclass

import fast_simplification
import numpy as np
from scipy import sparse

from mimetic.mesh.closest import CANDIDATES, closest_points


def decimate(vertices: np.ndarray, faces: np.ndarray, target: int) -> tuple[np.ndarray, np.ndarray]:
    """A copy of the surface ``faces`` (m, 3) of ``vertices`` (n, 3) with about ``target`` vertices.

    Quadric edge collapse: the copy keeps the surface's shape (and its units); vertices, faces and
    their order are new. A surface already at or under ``target`` vertices comes back as it is.
    Returns ``(vertices (k, 3) float64, faces (l, 3) int64)``.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    if target < 4:
        raise ValueError(f"a proxy needs at least 4 vertices, not {target}")
    used = np.unique(faces)
    if len(used) <= target:
        return vertices, faces
    # a closed surface has about twice as many triangles as vertices; an open one a little fewer
    reduction = 1.0 - target / len(used)
    # its binding takes only writeable C-ordered arrays (a Mesh's arrays are read-only)
    writeable = [np.require(a, requirements=["C", "W"]) for a in (vertices, faces)]
    out_v, out_f = fast_simplification.simplify(*writeable, target_reduction=reduction)
    return np.asarray(out_v, dtype=np.float64), np.asarray(out_f, dtype=np.int64)


@dataclass(frozen=True)
class Embedding:
    """Dense points tied to triangles of a proxy surface.

    Attributes
    ----------
    triangles : (n, 3) int64
        The proxy vertices of each point's triangle.
    bary : (n, 3) float64
        Barycentric coordinates in that triangle (each row sums to 1).
    offset : (n, 3) float64
        Each point's offset from its barycentric point, in its triangle's frame (first edge,
        in-plane perpendicular, unit normal: mostly the signed distance along the normal), in the
        surface's units.
    n_proxy : int
        The proxy's vertex count.
    """

    triangles: np.ndarray
    bary: np.ndarray
    offset: np.ndarray
    n_proxy: int

    def matrix(self) -> sparse.csr_matrix:
        """The (n, n_proxy) interpolation matrix: dense values = ``matrix() @ proxy values``."""
        n = len(self.triangles)
        rows = np.repeat(np.arange(n), 3)
        return sparse.csr_matrix((self.bary.ravel(), (rows, self.triangles.ravel())), shape=(n, self.n_proxy))

    def carry(self, values: np.ndarray) -> np.ndarray:
        """Per-proxy-vertex ``values`` (n_proxy, ...) interpolated at the dense points: (n, ...)."""
        values = np.asarray(values)
        picked = values[self.triangles]  # (n, 3, ...)
        weights = self.bary.reshape(self.bary.shape + (1,) * (values.ndim - 1))
        return (picked * weights).sum(axis=1)

    def place(self, proxy_vertices: np.ndarray) -> np.ndarray:
        """The dense points (n, 3) on the proxy posed at ``proxy_vertices`` (n_proxy, 3).

        Each point keeps its barycentric place and its offset in its triangle's posed frame, so at
        the proxy's rest pose the dense points come back exactly.
        """
        corners = np.asarray(proxy_vertices, dtype=np.float64)[self.triangles]  # (n, 3, 3)
        on = np.einsum("nk,nkd->nd", self.bary, corners)
        return on + np.einsum("nk,nkd->nd", self.offset, _frames(corners))


def embed(
    points: np.ndarray,
    vertices: np.ndarray,
    faces: np.ndarray,
    *,
    normals: np.ndarray | None = None,
    candidates: int = CANDIDATES,
) -> Embedding:
    """Tie each of ``points`` (n, 3) to its closest triangle of the proxy ``faces`` of ``vertices``.

    With ``normals`` (n, 3) (the points' unit normals) a point takes the closest triangle that faces
    its way (``closest_points``' normal test), so where two sheets of a surface nearly touch (the
    lips, a fold) a point is not tied to the other sheet; a point no such triangle faces takes the
    closest of all. ``candidates``: the triangles, nearest by centroid, each point looks among
    (``mesh.closest``; fewer is faster, and enough for points on the proxy's surface, as a dense
    mesh's own vertices are).
    """
    points = np.asarray(points, dtype=np.float64)
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    found = closest_points(vertices, faces, points, query_normals=normals, candidates=candidates)
    if normals is not None and np.any(found.faces < 0):  # facing no triangle: the closest of all
        lost = np.flatnonzero(found.faces < 0)
        anyway = closest_points(vertices, faces, points[lost], candidates=candidates)
        for name in ("points", "faces", "bary", "distance"):
            getattr(found, name)[lost] = getattr(anyway, name)
    if np.any(found.faces < 0):
        raise ValueError("some points found no proxy triangle")
    triangles = faces[found.faces]
    offset = np.einsum("nkd,nd->nk", _frames(vertices[triangles]), points - found.points)
    return Embedding(triangles, found.bary, offset, len(vertices))


def _frames(corners: np.ndarray) -> np.ndarray:
    """Orthonormal frames (n, 3 axes, 3) of triangles ``corners`` (n, 3, 3): first edge, in-plane
    perpendicular, unit normal."""
    edge = corners[:, 1] - corners[:, 0]
    normal = np.cross(edge, corners[:, 2] - corners[:, 0])
    edge /= np.maximum(np.linalg.norm(edge, axis=1, keepdims=True), 1e-300)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    return np.stack([edge, np.cross(normal, edge), normal], axis=1)
