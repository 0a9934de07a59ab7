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

from mimetic.mesh.closest import CANDIDATES, ClosestPoints, closest_points
from mimetic.mesh.geometry import vertex_adjacency

SHEET_RINGS = 2
"""How many edges of the proxy a point's triangle may lie from the vertex its own sheet collapsed into
(``embed``'s ``around``)."""
SHEET_SLACK_REL = 0.5
"""... and how much further (× the proxy's median edge) its own sheet's closest triangle may lie
than the closest of all, for the point to take it (``embed``)."""


def decimate(vertices: np.ndarray, faces: np.ndarray, target: int) -> tuple[np.ndarray, np.ndarray]:
    """A copy of the surface ``faces`` (m, 3) of ``vertices`` (n, 3) with about ``target`` vertices.

    Quadric edge collapse: the copy keeps the surface's shape (and its units); vertices, faces and
    their order are new. A surface already at or under ``target`` vertices comes back as it is.
    Returns ``(vertices (k, 3) float64, faces (l, 3) int64)``.
    """
    vertices, faces, _, reduction = _prepared(vertices, faces, target)
    if reduction is None:
        return vertices, faces
    out_v, out_f = fast_simplification.simplify(vertices, faces, target_reduction=reduction)
    return np.asarray(out_v, dtype=np.float64), np.asarray(out_f, dtype=np.int64)


def decimate_mapped(
    vertices: np.ndarray, faces: np.ndarray, target: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``decimate``, and where each vertex went: ``(vertices (k, 3), faces (l, 3), source (n,) int64)``,
    ``source[i]`` the copy vertex vertex ``i`` was collapsed into (-1 for vertices no face uses).

    Collapses run along edges, so ``source`` follows the surface: a vertex of one lip lands on that
    lip's copy even where the two lips touch and their copies cross.
    """
    vertices, faces, used, reduction = _prepared(vertices, faces, target)
    source = np.full(len(vertices), -1, dtype=np.int64)
    if reduction is None:
        source[used] = used
        return vertices, faces, source
    out_v, out_f, collapses = fast_simplification.simplify(
        vertices, faces, target_reduction=reduction, return_collapses=True
    )
    # collapses[j] = (kept, gone): each vertex goes where its chain of collapses ends; the copy's
    # vertices are the ends that faces still use, in their input order (as the library's
    # replay_simplification finds them, without its copies of the whole mesh: 0.5 GiB at 1.68M)
    parent = np.arange(len(vertices))
    parent[collapses[:, 1]] = collapses[:, 0]
    while not np.array_equal(end := parent[parent], parent):
        parent = end
    left = parent[faces]  # (m, 3)
    left = left[(left[:, 0] != left[:, 1]) & (left[:, 1] != left[:, 2]) & (left[:, 0] != left[:, 2])]
    kept = np.zeros(len(vertices), dtype=bool)
    kept[left.ravel()] = True
    assert kept.sum() == len(out_v), "the collapses do not give the decimation's vertices"
    rank = np.cumsum(kept) - 1
    source[used] = np.where(kept[parent[used]], rank[parent[used]], -1)
    return np.asarray(out_v, dtype=np.float64), np.asarray(out_f, dtype=np.int64), source


def _prepared(
    vertices: np.ndarray, faces: np.ndarray, target: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, float | None]:
    """The arrays as ``fast_simplification`` takes them (writeable, C-ordered: a Mesh's are
    read-only), the vertices the faces use, and the reduction that leaves about ``target`` of them
    (None: there are no more than that)."""
    if target < 4:
        raise ValueError(f"a proxy needs at least 4 vertices, not {target}")
    vertices = np.require(np.asarray(vertices, dtype=np.float64), requirements=["C", "W"])
    faces = np.require(np.asarray(faces, dtype=np.int64), requirements=["C", "W"])
    used = np.unique(faces)
    # a closed surface has about twice as many triangles as vertices; an open one a little fewer
    return vertices, faces, used, None if len(used) <= target else 1.0 - target / len(used)


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
    around: np.ndarray | None = None,
) -> Embedding:
    """Tie each of ``points`` (n, 3) to its closest triangle of the proxy ``faces`` of ``vertices``.

    With ``normals`` (n, 3) (the points' unit normals) a point takes the closest triangle that faces
    its way (``closest_points``' normal test), so where two sheets of a surface nearly touch (the
    lips, a fold) a point is not tied to the other sheet; a point no such triangle faces takes the
    closest of all. ``candidates``: the triangles, nearest by centroid, each point looks among
    (``mesh.closest``; fewer is faster, and enough for points on the proxy's surface, as a dense
    mesh's own vertices are).

    ``around`` (n,) int64: a proxy vertex on each point's own sheet (``decimate_mapped``'s
    ``source``; -1: none). Where the proxy's two sheets cross (the decimated lips of a 1.68M head
    overlap where the lips touch, both facing forward at their front) the closest triangle facing a
    point's way can still be the other sheet's. A point whose triangle has no corner within
    ``SHEET_RINGS`` edges of its ``around`` vertex, or that no nearby triangle faces, takes the
    closest triangle with a corner there instead (facing its way where one does), when that lies
    less than ``SHEET_SLACK_REL`` × the proxy's median edge further away (a collapse can carry a
    vertex's mapping a few edges off: then the first answer stays).
    """
    points = np.asarray(points, dtype=np.float64)
    vertices = np.asarray(vertices, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    found = closest_points(vertices, faces, points, query_normals=normals, candidates=candidates)
    if around is not None:
        _keep_to_sheet(found, vertices, faces, points, normals, np.asarray(around, dtype=np.int64))
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


def _keep_to_sheet(
    found: ClosestPoints,
    vertices: np.ndarray,
    faces: np.ndarray,
    points: np.ndarray,
    normals: np.ndarray | None,
    around: np.ndarray,
) -> None:
    """``found`` (changed in place) with each point's triangle within ``SHEET_RINGS`` edges of its
    ``around`` vertex (see ``embed``): the points whose triangle is not are searched again among
    the triangles with a corner there."""
    n = len(vertices)
    step = (vertex_adjacency(faces, n) + sparse.identity(n)).tocsr().astype(bool)  # closed one-rings
    reach = step
    for _ in range(SHEET_RINGS - 1):
        reach = (reach @ step).astype(bool)  # (n, n): within SHEET_RINGS edges
    has = np.flatnonzero((around >= 0) & (found.faces >= 0))
    corners = faces[found.faces[has]]  # (h, 3)
    near = np.zeros(len(has), dtype=bool)
    for j in range(3 if len(has) else 0):  # (scipy's pair indexing takes no empty arrays)
        near |= np.asarray(reach[around[has], corners[:, j]]).ravel().astype(bool)
    # and those no candidate faces (the underside of a lip, whose nearest triangles by centroid are
    # the other lip's): the closest of all would be the other sheet's
    redo = np.union1d(has[~near], np.flatnonzero((around >= 0) & (found.faces < 0)))
    if not len(redo):
        return
    incidence = sparse.csr_matrix(
        (np.ones(faces.size), (faces.ravel(), np.repeat(np.arange(len(faces)), 3))), shape=(n, len(faces))
    )
    options = (reach[around[redo]] @ incidence).tocsr()  # (r, m): triangles with a corner in reach
    width = np.diff(options.indptr)
    # each row's triangles, padded with its last (repeats are harmless)
    among = options.indices[
        options.indptr[:-1, None] + np.minimum(np.arange(width.max()), width[:, None] - 1)
    ]
    again = closest_points(
        vertices,
        faces,
        points[redo],
        query_normals=None if normals is None else normals[redo],
        among=among,
        or_closest=True,
    )
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])  # each side of each face
    edge = np.median(np.linalg.norm(vertices[edges[:, 0]] - vertices[edges[:, 1]], axis=1))
    take = again.distance <= found.distance[redo] + SHEET_SLACK_REL * edge
    for name in ("points", "faces", "bary", "distance"):
        getattr(found, name)[redo[take]] = getattr(again, name)[take]


def _frames(corners: np.ndarray) -> np.ndarray:
    """Orthonormal frames (n, 3 axes, 3) of triangles ``corners`` (n, 3, 3): first edge, in-plane
    perpendicular, unit normal."""
    edge = corners[:, 1] - corners[:, 0]
    normal = np.cross(edge, corners[:, 2] - corners[:, 0])
    edge /= np.maximum(np.linalg.norm(edge, axis=1, keepdims=True), 1e-300)
    normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-300)
    return np.stack([edge, np.cross(normal, edge), normal], axis=1)
