"""Unwelded seams: coincident vertices on open borders, found and merged (and split again).

Real exports often duplicate vertices along UV seams, or leave a patch (a cheek, a whole triangle
soup) unwelded: two copies of one point, each on the open border of its own side. Fitting then
sees holes and separate pieces, and a deformation that uses the topology (normals, smoothing,
separate pieces riding the skin) moves the two copies apart, so the seam tears.

``find_weld`` groups vertices that lie within ``WELD_TOL_REL`` of the bounding-box diagonal of
each other **and are all on an open border** (a boundary edge). Coincident vertices inside a
surface are left alone on purpose: closed lips modelled as two sheets touch along a line of
interior vertices that must part when the mouth opens, and a separate piece resting on a surface
(an eyelash root on the lid) touches it with border vertices against interior ones.

``Weld`` holds the merged mesh (each group becomes its first vertex; faces that collapse are
dropped) and the maps both ways, so the user's vertex order and count come back in every output:
``weld.index[i]`` is the welded vertex of original vertex ``i``, ``weld.faces[j]`` the original
face of welded face ``j``.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from mimetic.mesh.geometry import connected_components as mesh_components
from mimetic.mesh.geometry import edges_with_counts, face_normals
from mimetic.mesh.model import Mesh

SEAM_AREA_SHARE = 0.01
"""A seam counts for ``seam_vertices`` when its welded piece holds at least this share of the area."""

WELD_TOL_REL = 1e-6
"""Vertices this close, as a fraction of the bounding-box diagonal, are coincident (0.3 µm on a head)."""


@dataclass(frozen=True, eq=False)
class Weld:
    """A mesh with its unwelded seams merged.

    Attributes
    ----------
    mesh : Mesh
        k vertices (the first of each coincident group, in the original order), faces through
        ``index`` without the ones that collapse, parts renumbered to the kept faces, colours and
        units as the original's.
    index : (n,) int64
        The welded vertex of each original vertex.
    first : (k,) int64
        The original vertex each welded vertex is (the lowest index of its group).
    faces : (f,) int64
        The original face of each welded face.
    n_original_faces : int
        The original mesh's face count m.
    """

    mesh: Mesh
    index: np.ndarray
    first: np.ndarray
    faces: np.ndarray
    n_original_faces: int

    @property
    def n_merged(self) -> int:
        """How many original vertices were merged into another one."""
        return len(self.index) - len(self.first)

    def groups(self) -> list[np.ndarray]:
        """The original vertices (sorted) of each group of two or more merged vertices."""
        order = np.argsort(self.index, kind="stable")
        starts = np.flatnonzero(np.diff(self.index[order], prepend=-1))
        return [g for g in np.split(order, starts[1:]) if len(g) > 1]

    def face_of(self, original_faces: np.ndarray) -> np.ndarray:
        """The welded face (k,) int64 of each original face index, -1 where the face collapsed."""
        lookup = np.full(self.n_original_faces, -1, dtype=np.int64)
        lookup[self.faces] = np.arange(len(self.faces))
        return lookup[np.asarray(original_faces, dtype=np.int64)]


def border_vertices(faces: np.ndarray, n: int) -> np.ndarray:
    """(n,) bool: the vertices on a boundary edge (an edge of exactly one face)."""
    edges, counts = edges_with_counts(faces)
    out = np.zeros(n, dtype=bool)
    out[edges[counts == 1].ravel()] = True
    return out


def coincident_groups(vertices: np.ndarray, candidates: np.ndarray, tol: float) -> np.ndarray:
    """Group labels (n,) int64: vertices among ``candidates`` (indices) within ``tol`` of each other,
    chained, share a label; every other vertex has a label of its own. Labels are the lowest
    original index of each group, so a vertex is its own label unless merged."""
    n = len(vertices)
    label = np.arange(n, dtype=np.int64)
    if len(candidates) < 2:
        return label
    # exactly coincident points first (a soup repeats each corner ~6 times; k copies of one point
    # would make k² pairs), then pairs of the distinct points within tol
    points, which = np.unique(vertices[candidates], axis=0, return_inverse=True)
    which = which.ravel()
    pairs = cKDTree(points).query_pairs(tol, output_type="ndarray")  # (p, 2) into points
    k = len(points)
    graph = sp.coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(k, k))
    _, component = connected_components(graph, directed=False)
    component = component[which]
    lowest = np.full(component.max() + 1, n, dtype=np.int64)
    np.minimum.at(lowest, component, candidates)
    label[candidates] = lowest[component]
    return label


def find_weld(mesh: Mesh, *, tol_rel: float = WELD_TOL_REL, min_share: float = SEAM_AREA_SHARE) -> Weld:
    """Merge the coincident border vertices of ``mesh`` (see the module docstring) where the piece
    they weld together holds at least ``min_share`` of the mesh's area: seams of the skin (a UV seam,
    a cut patch, a triangle soup), not small pieces touching at their borders (eyelash cards, a tear
    film against an occlusion shell), which stay separate pieces riding the skin.

    Parameters
    ----------
    mesh : Mesh
        Vertices (n, 3) with finite coordinates, faces (m, 3).
    tol_rel : float
        Coincidence tolerance as a fraction of the bounding-box diagonal.
    min_share : float
        Smallest share of the total area a welded piece must hold for its seams to be merged.

    Returns
    -------
    weld : Weld
        ``weld.n_merged == 0`` and ``weld.mesh`` equal to ``mesh`` when there is no seam.
    """
    v, f = mesh.vertices, mesh.faces
    n = len(v)
    with np.errstate(over="ignore", invalid="ignore"):
        diagonal = float(np.linalg.norm(np.ptp(v, axis=0))) if n else 0.0
    if not np.isfinite(diagonal):  # coordinates near the float64 limit: no tolerance makes sense
        diagonal = 0.0
    border = np.flatnonzero(border_vertices(f, n))
    label = coincident_groups(v, border, tol_rel * diagonal)
    if min_share > 0 and (label != np.arange(n)).any():
        _, piece = mesh_components(label[f], n)  # the pieces the merge would make
        face_piece = piece[label[f[:, 0]]]
        area = 0.5 * np.linalg.norm(face_normals(v, f, unit=False), axis=1)
        share = np.bincount(face_piece, weights=area, minlength=n) / max(area.sum(), 1e-300)
        _, before = mesh_components(f, n)  # the pieces as they are
        pieces_before = np.bincount(face_piece, weights=np.ones(len(f)), minlength=n)  # faces per piece
        loose = np.zeros(n)  # how many of a piece's faces were a piece of their own (a soup's)
        alone = np.bincount(before[f[:, 0]], minlength=n)[before[f[:, 0]]] == 1
        np.add.at(loose, face_piece, alone)
        small = (share < min_share) & (loose < pieces_before)  # small, and not a soup
        undo = small[piece[label]]
        label[undo] = np.flatnonzero(undo)  # left as they were
    first, index = np.unique(label, return_inverse=True)  # first: (k,) sorted lowest indices
    index = index.astype(np.int64)
    welded = index[f]  # (m, 3)
    keep = (welded[:, 0] != welded[:, 1]) & (welded[:, 1] != welded[:, 2]) & (welded[:, 0] != welded[:, 2])
    kept = np.flatnonzero(keep)
    if len(first) == n and len(kept) == len(f):
        return Weld(mesh, index, first, kept, len(f))
    renumber = np.full(len(f), -1, dtype=np.int64)
    renumber[kept] = np.arange(len(kept))
    parts = {}
    for name, ids in mesh.parts.items():
        new = renumber[ids]
        parts[name] = new[new >= 0]
    materials = {k: m for k, m in mesh.materials.items() if k in parts}
    merged = dataclasses.replace(
        mesh,
        vertices=v[first],
        faces=welded[kept],
        parts=parts,
        colors=None if mesh.colors is None else mesh.colors[first],
        materials=materials,
    )
    return Weld(merged, index, first.astype(np.int64), kept, len(f))


def seam_vertices(mesh: Mesh) -> np.ndarray:
    """The vertices (k,) sorted, on unwelded seams: border edges lying on another border edge of the
    same part (of the mesh, when it has no parts) with other vertices, where the welded piece holds
    at least ``SEAM_AREA_SHARE`` of the area. What a user would call unwelded: parts that meet along
    a border (a mouth cavity's rim on the lip) and small pieces touching (eyelash cards at their
    roots) are left out, though ``find_weld`` merges them too."""
    v, f = mesh.vertices, mesh.faces
    n = len(v)
    with np.errstate(over="ignore", invalid="ignore"):
        diagonal = float(np.linalg.norm(np.ptp(v, axis=0))) if n else 0.0
    if not np.isfinite(diagonal):  # coordinates near the float64 limit: no tolerance makes sense
        diagonal = 0.0
    border = border_vertices(f, n)
    label = coincident_groups(v, np.flatnonzero(border), WELD_TOL_REL * diagonal)
    if (label == np.arange(n)).all():
        return np.zeros(0, dtype=np.int64)
    face_part = np.zeros(len(f), dtype=np.int64)
    for k, ids in enumerate(mesh.parts.values()):
        face_part[ids] = k + 1
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])  # (3m, 2) half-edges
    part = np.tile(face_part, 3)
    lo, hi = edges.min(axis=1), edges.max(axis=1)
    _, inverse, count = np.unique(lo * n + hi, return_inverse=True, return_counts=True)
    open_edge = count[inverse] == 1
    edges, part = edges[open_edge], part[open_edge]
    welded = label[edges]
    lo, hi = welded.min(axis=1), welded.max(axis=1)
    _, inverse, count = np.unique((part * n + lo) * n + hi, return_inverse=True, return_counts=True)
    seam = count[inverse] > 1  # another open edge of the same part lies on it
    if not seam.any():
        return np.zeros(0, dtype=np.int64)
    # only seams of a sizeable surface: welded, does their piece hold SEAM_AREA_SHARE of the area?
    _, piece = mesh_components(label[f], n)
    area = 0.5 * np.linalg.norm(face_normals(v, f, unit=False), axis=1)
    share = np.bincount(piece[label[f[:, 0]]], weights=area, minlength=n) / max(area.sum(), 1e-300)
    seam &= share[piece[label[edges[:, 0]]]] >= SEAM_AREA_SHARE
    return np.unique(edges[seam])
