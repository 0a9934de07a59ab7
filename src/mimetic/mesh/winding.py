"""Faces that wind against their neighbours: a patch turned inside out, found and turned back.

Two triangles sharing an edge are consistently wound when they run along it in opposite
directions. A patch of reversed faces (a bad boolean, a mirrored piece pasted back) breaks that
along its border: its normals point into the head, so it renders dark in every pose and confuses
anything that uses normals. ``winding_flips`` finds the fewest faces to turn so that each connected
piece is consistent: a spanning tree over the faces (through edges shared by exactly two faces)
carries the parity "same direction" from face to face; in each piece the side holding the smaller
area is the one to turn. Turning a whole piece inside out (a mirrored export) is a different
problem: the fit decides that from the landmarks (``fit.reference``).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order, connected_components

from mimetic.mesh.geometry import face_normals


def winding_flips(vertices: np.ndarray, faces: np.ndarray, *, min_share: float = 0.0) -> np.ndarray:
    """Which faces to turn (reverse their corner order) so every connected piece winds consistently.

    Parameters
    ----------
    vertices : (n, 3) float64
    faces : (m, 3) int64
    min_share : float
        Leave pieces holding less than this share of the total area alone (thin films and cards
        touching at their borders, as an eye's tear line and occlusion shell, may face either way).

    Returns
    -------
    flip : (m,) bool
        True for the faces of the smaller-area side of each piece's inconsistency; all False when
        every piece is consistent. Edges shared by more than two faces are not followed.
    """
    m = len(faces)
    if m == 0:
        return np.zeros(0, dtype=bool)
    a = faces.ravel()
    b = np.roll(faces, -1, axis=1).ravel()
    face = np.repeat(np.arange(m), 3)
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    forward = a < b  # the direction the face runs along its edge (lo, hi)
    order = np.lexsort((hi, lo))
    lo, hi, face, forward = lo[order], hi[order], face[order], forward[order]
    key = np.flatnonzero((lo[1:] != lo[:-1]) | (hi[1:] != hi[:-1]))
    starts = np.concatenate([[0], key + 1])
    counts = np.diff(np.concatenate([starts, [len(lo)]]))
    pair = starts[counts == 2]  # edges of exactly two faces: half-edges pair, pair + 1
    f0, f1 = face[pair], face[pair + 1]
    same = forward[pair] == forward[pair + 1]  # both run the same way: one of them is reversed
    parity = np.zeros(m, dtype=bool)
    if not same.any():
        return parity
    # the face graph, weight 1 for a consistent edge and 2 for a reversed one, plus a hub (node m)
    # joined to one face of each piece, so one breadth-first search spans every piece
    n_pieces, piece = connected_components(sp.coo_matrix((np.ones(len(pair)), (f0, f1)), shape=(m, m)))
    roots = np.unique(piece, return_index=True)[1]
    rows = np.concatenate([f0, roots])
    cols = np.concatenate([f1, np.full(len(roots), m)])
    weight = np.concatenate([1.0 + same, np.ones(len(roots))])
    graph = sp.coo_matrix((weight, (rows, cols)), shape=(m + 1, m + 1)).tocsr()
    graph = (graph + graph.T).tocsr()
    _, parent = breadth_first_order(graph, m, directed=False, return_predecessors=True)
    parent = parent[:m].copy()
    parent[roots] = roots  # the pieces' roots end the paths
    step = np.asarray(graph[np.arange(m), parent]).ravel() == 2.0  # reversed relative to the parent
    # pointer jumping: the parity of each face relative to its piece's root, in log(depth) passes
    ptr = parent
    while np.any(ptr != ptr[ptr]):
        step = step ^ step[ptr]
        ptr = ptr[ptr]
    parity = step
    area = 0.5 * np.linalg.norm(face_normals(vertices, faces, unit=False), axis=1)
    odd = np.bincount(piece, weights=area * parity, minlength=n_pieces)
    total = np.bincount(piece, weights=area, minlength=n_pieces)
    parity ^= (odd > 0.5 * total)[piece]  # turn the smaller side
    return parity & (total >= min_share * total.sum())[piece]
