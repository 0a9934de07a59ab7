"""Geometry helpers over ``(vertices, faces)`` arrays."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from scipy import sparse
from scipy.sparse import csgraph
from scipy.sparse.linalg import splu

from mimetic.mesh.memo import per_arrays


@per_arrays(2, copies=True)
def face_normals(vertices: np.ndarray, faces: np.ndarray, *, unit: bool = True) -> np.ndarray:
    """Normals (m, 3) float64 of triangles ``faces`` (m, 3) over ``vertices`` (n, 3).

    With ``unit=False`` each normal's length is twice the triangle's area. Computed once per
    (``vertices``, ``faces``) of a ``Mesh`` (``mesh.memo``), a new array each call.
    """
    tri = vertices[faces]  # (m, 3, 3)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])  # (m, 3)
    if unit:
        length = np.linalg.norm(n, axis=1, keepdims=True)
        n = n / np.where(length > 0, length, 1.0)
    return n


@per_arrays(2, copies=True)
def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals (n, 3) float64; unused vertices get (0, 0, 0). Computed once
    per (``vertices``, ``faces``) of a ``Mesh`` (``mesh.memo``), a new array each call."""
    fn = face_normals(vertices, faces, unit=False)  # (m, 3), |fn| = 2 area
    corner = faces.ravel()  # (3m,)
    out = np.stack([np.bincount(corner, np.repeat(fn[:, d], 3), len(vertices)) for d in range(3)], axis=1)
    length = np.linalg.norm(out, axis=1, keepdims=True)
    return out / np.where(length > 0, length, 1.0)


def vertex_areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Each vertex's share (n,) float64 of the surface ``faces`` (m, 3) over ``vertices`` (n, 3): a
    third of the area of every triangle it is a corner of (squared units; 0 for unused vertices).

    Weighting a per-vertex value by these shares averages it over the surface, exactly for values
    linear over each triangle (``np.average(y, weights=vertex_areas(v, f))`` is the surface's area
    centroid height), so the average does not depend on how densely or evenly the surface is
    sampled, as a plain mean over the vertices does.
    """
    area = 0.5 * np.linalg.norm(face_normals(vertices, faces, unit=False), axis=1)  # (m,)
    return np.bincount(faces.ravel(), np.repeat(area / 3.0, 3), len(vertices))


# --- topology -----------------------------------------------------------------------------------
# These take ``faces`` (m, 3) int64 only, so they serve the loader, the validator, the head
# generator and the fitting code alike. Edges are undirected and stored as sorted pairs (i < j).
# An "edge" whose two ends are the same vertex (from a degenerate face such as (4, 4, 7)) is
# not an edge: every function here leaves it out. The edges, the boundary and the pieces of a
# ``Mesh``'s faces (read-only arrays) are computed once per faces array (``mesh.memo``) and handed
# out read-only.


class BoundaryPaths(NamedTuple):
    """Boundary edges (edges used by exactly one face) split into paths.

    loops : list of (k,) int64
        Closed loops, each listed once without repeating its first vertex, oriented like the
        faces' own edges (for counter-clockwise faces the surface lies to the left when walking
        along a loop seen from outside), starting at the loop's smallest vertex index.
    chains : list of (k,) int64
        Open chains: runs of boundary edges that do not close, which happens only around
        non-manifold edges (e.g. three faces on one edge). Empty for a manifold mesh.
    """

    loops: list[np.ndarray]
    chains: list[np.ndarray]


def _as_faces(faces: np.ndarray) -> np.ndarray:
    faces = np.asarray(faces)
    if faces.size == 0:
        return np.zeros((0, 3), np.int64)
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise ValueError(f"faces must have shape (m, 3); got {faces.shape}")
    if not np.issubdtype(faces.dtype, np.integer):
        raise TypeError(f"faces must be integer vertex indices; got dtype {faces.dtype}")
    return faces.astype(np.int64, copy=False)


def _unique_counts(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Sorted unique values of 1-D ``keys`` and their counts, by sorting.

    numpy 2.4's ``np.unique(x)`` (no return_* flags) takes a hash-table path that is 10-30x
    slower than sorting for large int64 keys spread over a wide range, such as packed edges.
    """
    s = np.sort(keys)
    if len(s) == 0:
        return s, np.zeros(0, np.int64)
    start = np.flatnonzero(np.r_[True, s[1:] != s[:-1]])
    return s[start], np.diff(np.r_[start, len(s)]).astype(np.int64)


def _contains(haystack: np.ndarray, needles: np.ndarray) -> np.ndarray:
    """Boolean mask (k,): which of 1-D ``needles`` occur in 1-D ``haystack`` (fast ``np.isin``)."""
    s = np.sort(haystack)
    i = np.minimum(np.searchsorted(s, needles), max(len(s) - 1, 0))
    return s[i] == needles if len(s) else np.zeros(len(needles), dtype=bool)


def _half_edges(faces: np.ndarray) -> np.ndarray:
    """Directed edges (3m, 2) of ``faces`` in face order: (a, b), (b, c), (c, a) for each face."""
    return faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)


@per_arrays(1)
def edges_with_counts(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Unique undirected edges of ``faces`` and how many faces use each.

    Parameters
    ----------
    faces : (m, 3) int
        Triangles as vertex indices.

    Returns
    -------
    edges : (e, 2) int64
        Sorted pairs ``i < j``, in lexicographic order.
    counts : (e,) int64
        Number of faces using each edge: 1 on a boundary, 2 inside a manifold surface, 3 or
        more on a non-manifold edge. A face that repeats an edge counts twice.
    """
    faces = _as_faces(faces)
    a, b = faces.ravel(), faces[:, [1, 2, 0]].ravel()  # (3m,) each: edge a -> b
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    keep = lo != hi
    if not keep.any():
        return np.zeros((0, 2), np.int64), np.zeros(0, np.int64)
    n = int(hi.max()) + 1
    keys, counts = _unique_counts((lo * n + hi)[keep])  # key = i * n + j
    return np.column_stack(np.divmod(keys, n)), counts


def edges_unique(faces: np.ndarray) -> np.ndarray:
    """Unique undirected edges (e, 2) int64 of ``faces`` (m, 3): sorted pairs ``i < j``, sorted rows."""
    return edges_with_counts(faces)[0]


def vertex_adjacency(faces: np.ndarray, n: int) -> sparse.csr_matrix:
    """Vertex adjacency matrix of the edges of ``faces`` (m, 3) over ``n`` vertices.

    Returns
    -------
    adjacency : (n, n) scipy.sparse.csr_matrix of float64
        Symmetric; entry (i, j) is 1.0 when an edge joins i and j; the diagonal is empty.
        Row i's column indices are vertex i's neighbours; ``adjacency.sum(axis=1)`` is the degree.
    """
    edges = _check_n(edges_unique(faces), n)
    rows = np.concatenate([edges[:, 0], edges[:, 1]])
    cols = np.concatenate([edges[:, 1], edges[:, 0]])
    return sparse.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))


def smooth_field(
    values: np.ndarray,
    vertices: np.ndarray,
    faces: np.ndarray,
    length: float,
    *,
    free: np.ndarray | None = None,
) -> np.ndarray:
    """``values`` diffused over the surface by about ``length``: the package's one smoothing operator.

    Solves the screened Poisson equation ``(I + length² L) x = values`` on the free vertices, with
    ``L`` the graph Laplacian whose edge weights ``4 / (degree · |edge|²)`` approximate −∇² on any
    mesh, so ``length`` is a distance in mesh units, whatever the resolution: a step in ``values``
    becomes a ramp a few ``length`` wide, a field smoother than ``length`` is left nearly as it was.
    Vertices that are not free keep their values and act as boundary conditions; vertices of no
    face of ``faces`` are never changed.

    Parameters
    ----------
    values : (n,) or (n, k) float64
    vertices : (n, 3) float64
    faces : (m, 3) int64
        The surface to smooth along (e.g. only the skin's faces).
    length : float
        Diffusion length, mesh units (0 returns ``values``).
    free : (n,) bool, optional
        The vertices to change (default: every vertex of ``faces``).

    Returns
    -------
    (n,) or (n, k) float64, a new array.
    """
    values = np.asarray(values, dtype=np.float64)
    out = values.copy()
    n = len(vertices)
    edges = _check_n(edges_unique(faces), n)
    if length <= 0 or len(edges) == 0:
        return out
    used = np.zeros(n, dtype=bool)
    used[edges.ravel()] = True
    free = used if free is None else (np.asarray(free, dtype=bool) & used)
    ids = np.flatnonzero(free)
    if len(ids) == 0:
        return out
    edge_sq = np.sum((vertices[edges[:, 0]] - vertices[edges[:, 1]]) ** 2, axis=1)
    inverse_sq = 1.0 / np.maximum(edge_sq, 1e-300)
    rows = np.concatenate([edges[:, 0], edges[:, 1]])
    cols = np.concatenate([edges[:, 1], edges[:, 0]])
    weight = sparse.csr_matrix((np.tile(inverse_sq, 2), (rows, cols)), shape=(n, n))  # symmetric
    # row i of the system, divided by its scale 4 length² / degree_i, is symmetric: a Cholesky-like
    # factorisation (symmetric ordering, diagonal pivots) solves it in two thirds of a general LU's time
    scale = 4.0 * length**2 / np.maximum(np.diff(weight.indptr), 1)
    system = sparse.diags(1.0 / scale + np.asarray(weight.sum(axis=1)).ravel()) - weight
    fixed = np.flatnonzero(~free)
    rhs = values[ids] / (scale[ids] if values.ndim == 1 else scale[ids, None])
    if len(fixed):
        rhs = rhs + weight[ids][:, fixed] @ values[fixed]
    factor = splu(
        system[ids][:, ids].tocsc(),
        permc_spec="MMD_AT_PLUS_A",
        diag_pivot_thresh=0.0,
        options={"SymmetricMode": True},
    )
    out[ids] = factor.solve(rhs)
    return out


@per_arrays(1)
def connected_components(faces: np.ndarray, n: int) -> tuple[int, np.ndarray]:
    """Connected components of ``n`` vertices joined by the edges of ``faces`` (m, 3).

    Faces that share at least one vertex are in the same component.

    Returns
    -------
    count : int
        Number of components, counting each vertex used by no face as its own component.
    labels : (n,) int64
        Component index of each vertex, in ``range(count)``.
    """
    return _edge_components(_check_n(edges_unique(faces), n), n)


def _check_n(edges: np.ndarray, n: int) -> np.ndarray:
    if len(edges) and int(edges.max()) >= n:
        raise ValueError(f"faces refer to vertex {int(edges.max())} but n={n}")
    return edges


def _edge_components(edges: np.ndarray, n: int) -> tuple[int, np.ndarray]:
    """Connected components of ``n`` vertices joined by undirected ``edges`` (e, 2)."""
    graph = sparse.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    count, labels = csgraph.connected_components(graph, directed=False)
    return int(count), labels.astype(np.int64)


def boundary_paths(faces: np.ndarray) -> BoundaryPaths:
    """Boundary edges of ``faces`` (m, 3) as ordered closed loops and open chains.

    A vertex where two loops touch (a "pinch") is split so that each loop is a simple cycle.
    Runs in O(m log m) plus a Python loop over the boundary edges.
    """
    faces = _as_faces(faces)
    be = boundary_edges(faces)  # (b, 2), oriented as their faces walk them
    if len(be) == 0:
        return BoundaryPaths([], [])
    # Walk undirected edges (sorted pairs) so that a flipped face cannot break a loop;
    # ``forward`` remembers which way each edge's face runs, to orient the result.
    forward = be[:, 0] < be[:, 1]  # (b,)
    loops, chains = _walk(np.sort(be, axis=1), forward)
    return BoundaryPaths(
        [_orient(path, agree, closed=True) for path, agree in loops],
        [_orient(path, agree, closed=False) for path, agree in chains],
    )


@per_arrays(1)
def boundary_edges(faces: np.ndarray) -> np.ndarray:
    """Edges (b, 2) int64 used by exactly one face of ``faces`` (m, 3), as that face walks them.

    Rows are in the order of :func:`edges_unique` (by sorted vertex pair); each row is (from, to)
    in its face's winding, so for outward counter-clockwise faces the surface lies to the left.
    """
    faces = _as_faces(faces)
    edges, counts = edges_with_counts(faces)
    be = edges[counts == 1]  # (b, 2), i < j
    if len(be) == 0:
        return be
    n = int(faces.max()) + 1
    half = _half_edges(faces)  # (3m, 2), face winding
    forward = _contains(half[:, 0] * n + half[:, 1], be[:, 0] * n + be[:, 1])  # (b,) face runs i -> j
    return np.where(forward[:, None], be, be[:, ::-1])


def boundary_counts(faces: np.ndarray) -> tuple[int, int]:
    """Numbers of closed boundary loops and open boundary chains of ``faces`` (m, 3).

    Equal to ``len(p.loops), len(p.chains)`` for ``p = boundary_paths(faces)``, but vectorised:
    only boundary components with a vertex of degree other than 2 (pinches, non-manifold edges)
    are walked in Python. Use this for counting on large, possibly unwelded meshes.
    """
    edges, counts = edges_with_counts(faces)
    return _boundary_counts(edges[counts == 1])


def _boundary_counts(be: np.ndarray) -> tuple[int, int]:
    """(loops, chains) formed by undirected boundary edges ``be`` (b, 2); see :func:`boundary_counts`."""
    if len(be) == 0:
        return 0, 0
    verts, local = np.unique(be, return_inverse=True)  # relabel 0..k-1: cost scales with b, not n
    local = local.reshape(-1, 2)
    k = len(verts)
    degree = np.bincount(local.ravel(), minlength=k)  # (k,)
    _, labels = _edge_components(local, k)
    odd_shape = np.zeros(labels.max() + 1, dtype=bool)  # components that are not one simple cycle
    odd_shape[labels[degree != 2]] = True
    n_simple = int((~odd_shape).sum())
    if not odd_shape.any():
        return n_simple, 0
    rest = be[odd_shape[labels[local[:, 0]]]]
    loops, chains = _walk(rest, np.ones(len(rest), dtype=bool))
    return n_simple + len(loops), len(chains)


def _walk(be: np.ndarray, forward: np.ndarray) -> tuple[list, list]:
    """Split undirected edges ``be`` (b, 2) into simple cycles and open chains.

    Returns ``(loops, chains)``, each a list of ``(vertices, agree)`` where ``agree[k]`` says
    whether the k-th step runs the same way as ``forward`` says its edge's face does.
    """
    b = len(be)
    ends = np.concatenate([be[:, 0], be[:, 1]])  # (2b,)
    order = np.argsort(ends, kind="stable")
    incident = np.concatenate([np.arange(b), np.arange(b)])[order].tolist()
    verts, first = np.unique(ends[order], return_index=True)
    degree = np.diff(np.append(first, 2 * b))
    ptr = dict(zip(verts.tolist(), first.tolist(), strict=True))
    stop = dict(zip(verts.tolist(), (first + degree).tolist(), strict=True))
    a_end, b_end, fwd = be[:, 0].tolist(), be[:, 1].tolist(), forward.tolist()
    used = bytearray(b)

    def next_edge(v: int) -> int:
        p = ptr[v]
        while p < stop[v] and used[incident[p]]:
            p += 1
        ptr[v] = p
        return incident[p] if p < stop[v] else -1

    loops: list = []
    chains: list = []
    # Chains can only start at odd-degree vertices; starting there first leaves only cycles.
    starts = verts[degree % 2 == 1].tolist() + verts.tolist()
    for s in starts:
        while next_edge(s) != -1:
            path, agree, pos, v = [s], [], {s: 0}, s
            while (e := next_edge(v)) != -1:
                used[e] = 1
                w = b_end[e] if a_end[e] == v else a_end[e]
                agree.append(fwd[e] == (a_end[e] == v))
                if w in pos:  # closed a simple cycle
                    i = pos[w]
                    loops.append((path[i:], agree[i:]))
                    for x in path[i + 1 :]:
                        del pos[x]
                    del path[i + 1 :], agree[i:]
                else:
                    pos[w] = len(path)
                    path.append(w)
                v = w
            if len(path) > 1:
                chains.append((path, agree))
    return loops, chains


def _orient(path: list[int], agree: list[bool], *, closed: bool) -> np.ndarray:
    """``path`` as int64, reversed if most of its edges run against the faces' orientation."""
    out = np.asarray(path, dtype=np.int64)
    if 2 * sum(agree) < len(agree):
        out = out[::-1]
    if closed:
        out = np.roll(out, -int(np.argmin(out)))
    return np.ascontiguousarray(out)


def boundary_loops(faces: np.ndarray) -> list[np.ndarray]:
    """Closed boundary loops of ``faces`` (m, 3): a list of (k,) int64 ordered vertex indices.

    Each loop is listed once (its first vertex is not repeated), oriented like the faces' edges,
    starting at its smallest vertex index; loops are in order of discovery (by smallest vertex).
    A closed surface has none; an open neck gives one; each eye socket hole one more. Open chains
    around non-manifold edges are left out; see :func:`boundary_paths`.
    """
    return boundary_paths(faces).loops


def closest_on_polyline(
    points: np.ndarray, polyline: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Closest points of ``points`` (m, 3) on ``polyline`` (k, 3), k >= 2.

    Returns the segment index (m,) int, the parameter t (m,) in [0, 1] along that segment and
    the distance (m,) float64; the first such segment on a tie.
    """
    from mimetic.mesh.kernels import closest_on_segments  # numba loads on first use, not on import

    if len(polyline) < 2:
        raise ValueError(f"a polyline needs at least 2 points; got {len(polyline)}")
    points = np.ascontiguousarray(points, dtype=np.float64)
    return closest_on_segments(points, np.ascontiguousarray(polyline, dtype=np.float64))
