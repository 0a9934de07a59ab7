"""Rigging a dense scan at a working resolution: a decimated copy is rigged, every vertex carried.

Above ``WORKING_THRESHOLD`` vertices ``rig_head`` does not fit and transfer on the user's own
vertices (the transfer's closest points, smoothing solves and lid searches grow faster than the
vertex count: 620 s and 7.4 GiB at 1.68M vertices). It rigs a *working copy* instead:

1. ``working_copy``: each connected piece of the welded mesh (skin, each eyeball, each tooth …)
   is decimated on its own (``mesh.decimate``) to its share of ``WORKING_VERTICES``; a piece under
   ``KEEP_WHOLE`` vertices is kept as it is. Every one of the user's vertices is then tied to the
   closest triangle of *its own piece's* copy facing its way (``mesh.decimate.embed``), so an
   eyelid never takes the eyeball's data however close they lie, and of its own sheet (within
   ``mesh.decimate.SHEET_RINGS`` copy edges of the vertex it was collapsed into), so the
   upper lip never takes the lower's where they touch and their copies cross.
2. The existing pipeline rigs the copy (landmarks from its renders, fit, transfer).
3. ``carry_rig``: the rig on the user's vertices, order, units and faces: skin weights are
   interpolated through each vertex's embedding (then the 4 largest kept and renormalised) and
   diffused over the user's own surface by about one edge of the copy, so they bend smoothly
   rather than at the copy's edges (where a skinned dense surface would show facets); region
   and wire-set memberships are interpolated indicators kept from 0.5 (the transfer's own rule),
   each lip vertex in one lip only; per-vertex anatomy (crease and tissue-action offsets, the tissue
   thickness) is interpolated the same way; what refers to vertex indices is found again on the
   dense vertices: surface points (landmarks, muscle ends, wire control points) at the closest point
   of the dense skin; the forehead's skull, lip contact pairs, lid margins and the accessories'
   rivets by the anatomy's own rules (``rig.anatomy``) on the dense mesh. Bones, channels
   and muscle parameters are the copy's.

A whole connected piece lands on one piece of the copy, so a rigid part (an eyeball, a tooth) takes
exactly its bone's weight at every vertex.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components as graph_components
from scipy.spatial import cKDTree

from mimetic.errors import MeshError
from mimetic.fit.transfer import MAX_INFLUENCES, MEMBERSHIP, close_lids, top_influences
from mimetic.mesh.closest import closest_points
from mimetic.mesh.decimate import Embedding, decimate_mapped, embed
from mimetic.mesh.geometry import connected_components, vertex_normals
from mimetic.mesh.model import Mesh, SurfacePoint, surface_positions
from mimetic.rig.anatomy import (
    Accessories,
    Anatomy,
    find_accessories,
    find_lid_contacts,
    forehead_skull,
    lip_contact,
)
from mimetic.rig.anatomy.derive import skin_vertices
from mimetic.rig.model import Rig

WORKING_THRESHOLD = 200_000
"""``rig_head`` rigs a working copy of a mesh with more vertices than this (see docs/rigging.md)."""
WORKING_VERTICES = 50_000
"""The working copy's vertex count (about: each piece is decimated to its share)."""
MIN_WORKING_VERTICES = 5_000
"""The smallest working copy accepted: below it the reference's mouth and lids have too few vertices."""
KEEP_WHOLE = 300
"""A connected piece with fewer vertices than this is kept as it is in the working copy."""
CHUNK = 200_000
"""Dense points embedded at a time (the closest-point search holds ~1 kB per point)."""
EMBED_CANDIDATES = 6
"""Copy triangles (nearest by centroid) among which each dense vertex finds its closest: the dense
vertices lie on the copy's surface, where 6 find the same triangle as 12 at half the time."""
NEEDLE_REL = 1e-6
"""Corners of a decimated piece closer than this × its median edge are merged (``_decimated``)."""
SLIVER_REL = 1e-6
"""Copy triangles with less area than this × the piece's median are not embedded in (quadric
decimation leaves a few needles whose barycentric coordinates are not defined)."""
LID_BOX_REL = (1.3, 1.1)
"""Half the width and height of the box around an eye's corners its lid contacts are found in, ×
the eye width (``mesh.openings`` looks over 0.85 and 0.6)."""
LID_DEPTH_REL = 3.0
"""... and how far behind the eyeball's centre the box reaches, × the eyeball's radius."""
MAX_DIFFUSION_STEPS = 64
"""The most neighbour-averaging steps the carried skin weights take (``_diffused``)."""


@dataclass(frozen=True)
class WorkingCopy:
    """A decimated copy of a dense mesh and the dense mesh's vertices tied to it.

    Attributes
    ----------
    mesh : Mesh
        The copy: (k, 3) vertices in the dense mesh's frame and units, no parts; vertex colours
        taken from the nearest dense vertex when the dense mesh has them.
    embedding : Embedding
        Each dense vertex (n of them, the user's order) on a triangle of its own piece's copy.
    """

    mesh: Mesh
    embedding: Embedding


def working_copy(mesh: Mesh, welded: Mesh, index: np.ndarray, target: int) -> WorkingCopy:
    """A copy of ``welded`` (the user's ``mesh`` with its seams merged; ``index`` (n,) maps each user
    vertex to its welded vertex) with about ``target`` vertices, and ``mesh``'s vertices tied to it.

    A connected piece of ``welded`` under ``KEEP_WHOLE`` vertices is kept whole; the others are each
    decimated in proportion to their size, to what is left of ``target``; each user vertex is then
    embedded in its own piece's copy.
    """
    n_pieces, label = connected_components(welded.faces, welded.n_vertices)
    sizes = np.bincount(label, minlength=n_pieces)
    whole = sizes < KEEP_WHOLE
    # the pieces kept whole count toward the target; the others share what is left
    share = max(target - sizes[whole].sum(), KEEP_WHOLE) / max(sizes[~whole].sum(), 1)
    face_piece = label[welded.faces[:, 0]]
    order = np.argsort(face_piece, kind="stable")
    bounds = np.searchsorted(face_piece[order], np.arange(n_pieces + 1))
    user_piece = label[index]  # (n,)
    user_order = np.argsort(user_piece, kind="stable")
    user_bounds = np.searchsorted(user_piece[user_order], np.arange(n_pieces + 1))
    vertices, faces = [], []
    triangles = np.zeros((mesh.n_vertices, 3), dtype=np.int64)
    bary = np.zeros((mesh.n_vertices, 3))
    offset = np.zeros((mesh.n_vertices, 3))
    start = 0
    loose = []  # user vertices of pieces without faces: tied to the whole copy afterwards
    for piece in range(n_pieces):
        users = user_order[user_bounds[piece] : user_bounds[piece + 1]]
        piece_faces = welded.faces[order[bounds[piece] : bounds[piece + 1]]]
        if not len(piece_faces):
            loose.append(users)
            continue
        used, local = np.unique(piece_faces, return_inverse=True)
        v, f = welded.vertices[used], local.reshape(-1, 3)
        # the user's vertices' own normals (k, 3), from the piece's welded surface
        normals = vertex_normals(v, f)[np.searchsorted(used, index[users])]
        source = np.arange(len(used))  # each welded vertex's copy vertex, on its own sheet
        if len(used) >= KEEP_WHOLE:
            v, f, source = _decimated(v, f, max(KEEP_WHOLE, round(len(used) * share)))
        around = source[np.searchsorted(used, index[users])]  # (k,)
        tie = f[_areas(v, f) > SLIVER_REL * np.median(_areas(v, f))]  # slivers have no barycentrics
        for rows in np.array_split(np.arange(len(users)), max(1, -(-len(users) // CHUNK))):
            chunk = users[rows]
            tied = embed(
                mesh.vertices[chunk],
                v,
                tie,
                candidates=EMBED_CANDIDATES,
                normals=normals[rows],
                around=around[rows],
            )
            triangles[chunk], bary[chunk], offset[chunk] = tied.triangles + start, tied.bary, tied.offset
        vertices.append(v)
        faces.append(f + start)
        start += len(v)
    copy_v, copy_f = np.concatenate(vertices), np.concatenate(faces)
    if loose:
        users = np.concatenate(loose)
        tied = embed(mesh.vertices[users], copy_v, copy_f)
        triangles[users], bary[users], offset[users] = tied.triangles, tied.bary, tied.offset
    colors = None
    if mesh.colors is not None:
        _, nearest = cKDTree(mesh.vertices).query(copy_v)
        colors = mesh.colors[nearest]
    copy = Mesh(copy_v, copy_f, colors=colors, units=mesh.units)
    return WorkingCopy(copy, Embedding(triangles, bary, offset, len(copy_v)))


def _decimated(
    vertices: np.ndarray, faces: np.ndarray, target: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``decimate_mapped``, then its needles collapsed: quadric collapses over flat patches (a
    subdivided mesh's) leave about 1 % of triangles with two corners a thousand-billionth of an edge
    apart, which have no normal and upset the fit and the lids. Corners closer than ``NEEDLE_REL`` ×
    the median edge are merged, the faces left without area dropped, unused vertices removed.
    Returns the copy's vertices (k, 3), faces (l, 3) and each input vertex's copy vertex (n,)
    (-1: none)."""
    v, f, source = decimate_mapped(vertices, faces, target)
    lowest = np.arange(len(v))
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    length = np.linalg.norm(v[edges[:, 0]] - v[edges[:, 1]], axis=1)
    short = edges[length <= NEEDLE_REL * np.median(length)]
    if len(short):
        graph = sp.coo_matrix((np.ones(len(short)), (short[:, 0], short[:, 1])), shape=(len(v), len(v)))
        _, label = graph_components(graph, directed=False)
        first = np.full(label.max() + 1, len(v))
        np.minimum.at(first, label, np.arange(len(v)))
        lowest = first[label]
        f = lowest[f]
    f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 0] != f[:, 2])]
    _, first = np.unique(np.sort(f, axis=1), axis=0, return_index=True)  # a collapse can leave twins
    f = f[np.sort(first)]
    used, local = np.unique(f, return_inverse=True)
    renumber = np.full(len(v) + 1, -1, dtype=np.int64)  # the last entry: no copy vertex
    renumber[used] = np.arange(len(used))
    source = renumber[np.where(source >= 0, lowest[source], len(v))]
    return np.ascontiguousarray(v[used]), local.reshape(-1, 3).astype(np.int64), source


def _areas(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Twice the area (m,) of each triangle."""
    tri = vertices[faces]
    return np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)


def working_vertices_for(n_vertices: int, working_vertices: int | str | None) -> int | None:
    """The working copy's vertex count for a mesh of ``n_vertices``, or None to rig it directly.

    ``working_vertices``: None (automatic: ``WORKING_VERTICES`` above ``WORKING_THRESHOLD``
    vertices, else direct), ``"full"`` (always direct) or a count ≥ ``MIN_WORKING_VERTICES`` (a
    count at or over the mesh's own is direct too).
    """
    if working_vertices is None:
        return WORKING_VERTICES if n_vertices > WORKING_THRESHOLD else None
    if working_vertices == "full":
        return None
    if isinstance(working_vertices, bool) or not isinstance(working_vertices, (int, np.integer)):
        raise MeshError(
            f"working resolution {working_vertices!r} is neither a vertex count nor 'full'; "
            f"give a count ≥ {MIN_WORKING_VERTICES:,} (e.g. 100000) or 'full'"
        )
    if working_vertices < MIN_WORKING_VERTICES:
        raise MeshError(
            f"working resolution {working_vertices:,} vertices is too coarse for the reference's lids and "
            f"lips; give at least {MIN_WORKING_VERTICES:,}, or 'full' to rig every vertex directly"
        )
    return None if working_vertices >= n_vertices else int(working_vertices)


def carry_rig(proxy: Rig, copy: WorkingCopy, mesh: Mesh, metadata: dict | None = None) -> Rig:
    """The rig of the working copy (``proxy``, on ``copy.mesh``'s vertices) on ``mesh``: the user's
    vertices (n, 3) in the rig's frame and units, their faces as the rig has them (turned where the
    fit turned them).

    See the module docstring for what is carried and how.
    """
    tie = copy.embedding
    pick = tie.matrix()  # (n, k)
    n = mesh.n_vertices
    # 1. skin weights: interpolated, the 4 largest kept and renormalised
    weights = (pick @ proxy.skin_weights).toarray()
    weights = top_influences(weights, MAX_INFLUENCES)
    # interpolated over the copy's triangles the weights bend at the copy's edges, which a skinned
    # dense surface shows as facets (a jaw opening crumpled the cheeks at 420k): diffused over the
    # user's own surface by about one copy edge they bend smoothly (each rigid piece stays one-hot)
    steps = _diffusion_steps(copy, mesh)
    weights = top_influences(_diffused(weights, mesh.faces, steps), MAX_INFLUENCES)

    # 2. parts: a whole piece lands on one piece of the copy; a face takes its first vertex's
    nearest = tie.triangles[np.arange(n), np.argmax(tie.bary, axis=1)]  # (n,) copy vertex
    copy_part = np.zeros(proxy.n_vertices, dtype=np.int64)
    names = list(proxy.mesh.parts)
    for i, name in enumerate(names):
        copy_part[proxy.mesh.faces[proxy.mesh.parts[name]].ravel()] = i
    face_part = copy_part[nearest[mesh.faces[:, 0]]]
    parts = {name: np.flatnonzero(face_part == i) for i, name in enumerate(names)}
    rigid = np.zeros(n, dtype=bool)
    for name in names:
        if name != "skin":
            rigid[np.unique(mesh.faces[parts[name]])] = True
    dense = dataclasses.replace(mesh, parts=parts, materials={})

    # 3. vertex sets: interpolated indicators kept from MEMBERSHIP
    def indicator(ids: np.ndarray) -> np.ndarray:
        values = np.zeros(proxy.n_vertices)
        values[ids] = 1.0
        return pick @ values

    def members(ids: np.ndarray) -> np.ndarray:
        return np.flatnonzero((indicator(ids) >= MEMBERSHIP) & ~rigid)

    regions = {name: members(ids) for name, ids in proxy.regions.items()}
    if "upper_lip" in regions and "lower_lip" in regions:
        both = np.intersect1d(regions["upper_lip"], regions["lower_lip"])
        if len(both):
            upper = indicator(proxy.regions["upper_lip"])[both] >= indicator(proxy.regions["lower_lip"])[both]
            regions["lower_lip"] = np.setdiff1d(regions["lower_lip"], both[upper])
            regions["upper_lip"] = np.setdiff1d(regions["upper_lip"], both[~upper])

    # 4. surface points: the closest point of the dense skin
    skin_faces = parts["skin"] if "skin" in parts else np.arange(mesh.n_faces)
    points = [
        *proxy.landmarks.values(),
        *(p for m in proxy.muscles for p in (m.origin, m.insertion)),
        *(p for w in proxy.wires for p in w.points),
    ]
    moved = iter(_on_skin(surface_positions(points, proxy.mesh.vertices, proxy.mesh.faces), mesh, skin_faces))
    landmarks = {name: next(moved) for name in proxy.landmarks}
    muscles = tuple(dataclasses.replace(m, origin=next(moved), insertion=next(moved)) for m in proxy.muscles)
    wires = tuple(
        dataclasses.replace(w, points=tuple(next(moved) for _ in w.points), vertices=members(w.vertices))
        for w in proxy.wires
    )
    weights, bones = _closed_lids(proxy, dense, weights, regions, landmarks)
    # accessories take the weights at their rivets, as the transfer gives them (a lash swings with its lid)
    riding = find_accessories(dense, proxy.scale, sp.csr_matrix(weights))
    weights[riding.vertices] = top_influences(riding.weights, MAX_INFLUENCES)
    skin_weights = sp.csr_matrix(weights)
    anatomy = _carried_anatomy(proxy, pick, dense, landmarks, regions, skin_weights, riding)
    return Rig(
        mesh=dense,
        units=proxy.units,
        scale=proxy.scale,
        landmarks=landmarks,
        regions=regions,
        muscles=muscles,
        wires=wires,
        bones=bones,
        skin_weights=skin_weights,
        channels=proxy.channels,
        metadata={**proxy.metadata, **(metadata or {})},
        anatomy=anatomy,
    )


def _median_edge(vertices: np.ndarray, faces: np.ndarray, sample: int = 100_000) -> float:
    """The median length of the first edge of (up to ``sample`` evenly spread) ``faces``."""
    picked = faces[:: max(1, len(faces) // sample)]
    return float(np.median(np.linalg.norm(vertices[picked[:, 1]] - vertices[picked[:, 0]], axis=1)))


def _diffusion_steps(copy: WorkingCopy, mesh: Mesh) -> int:
    """Averaging steps over ``mesh``'s edges that spread a value about one edge of the copy: k steps
    of neighbour averaging spread it about ``edge × sqrt(k / 2)``, so ``k = (copy edge / edge)² / 2``,
    at most ``MAX_DIFFUSION_STEPS``."""
    ratio = _median_edge(copy.mesh.vertices, copy.mesh.faces) / max(
        _median_edge(mesh.vertices, mesh.faces), 1e-300
    )
    return int(min(MAX_DIFFUSION_STEPS, np.ceil(0.5 * ratio**2)))


def _diffused(values: np.ndarray, faces: np.ndarray, steps: int) -> np.ndarray:
    """``values`` (n, c) after ``steps`` rounds of each vertex taking the mean of itself and its
    neighbours along ``faces`` (m, 3); rows that sum to 1 still do."""
    if steps <= 0:
        return values
    n = len(values)
    rows = np.concatenate([faces[:, 0], faces[:, 1], faces[:, 2], faces[:, 1], faces[:, 2], faces[:, 0]])
    cols = np.concatenate([faces[:, 1], faces[:, 2], faces[:, 0], faces[:, 0], faces[:, 1], faces[:, 2]])
    adjacency = sp.csr_matrix((np.ones(len(rows), np.float32), (rows, cols)), shape=(n, n))
    adjacency.data[:] = 1.0  # an edge shared by two faces counts once
    adjacency = adjacency + sp.identity(n, dtype=np.float32, format="csr")
    average = sp.diags(1.0 / np.asarray(adjacency.sum(axis=1)).ravel()) @ adjacency  # rows sum to 1
    out = values
    for _ in range(steps):
        out = average @ out
    return np.asarray(out)


def _on_skin(points: np.ndarray, mesh: Mesh, skin_faces: np.ndarray) -> list[SurfacePoint]:
    """The closest point (as a ``SurfacePoint`` of ``mesh``) on the faces ``skin_faces`` to each of
    ``points`` (q, 3), searched among the faces around the nearest skin vertices."""
    skin = np.unique(mesh.faces[skin_faces])
    _, near = cKDTree(mesh.vertices[skin]).query(points, k=min(16, len(skin)))
    around = np.zeros(mesh.n_vertices, dtype=bool)
    around[skin[np.ravel(near)]] = True
    candidates = skin_faces[around[mesh.faces[skin_faces]].any(axis=1)]
    found = closest_points(mesh.vertices, mesh.faces[candidates], points)
    return [
        SurfacePoint(int(candidates[f]), tuple(b.tolist()))
        for f, b in zip(found.faces, found.bary, strict=True)
    ]


def _carried_field(pick: sp.csr_matrix, ids: np.ndarray, values: np.ndarray, keep: np.ndarray):
    """A field ``values`` (k, d) on the copy's vertices ``ids`` interpolated at the dense vertices:
    (dense ids (m,), values (m, d)), for the dense vertices whose triangle touches ``ids`` and that
    ``keep`` (n,) bool allows."""
    full = np.zeros((pick.shape[1], values.shape[1]))
    full[ids] = values
    touched = np.zeros(pick.shape[1])
    touched[ids] = 1.0
    out = np.flatnonzero(((pick @ touched) > 0) & keep)
    return out, pick[out] @ full


def _carried_anatomy(
    proxy: Rig,
    pick: sp.csr_matrix,
    mesh: Mesh,
    landmarks: dict[str, SurfacePoint],
    regions: dict[str, np.ndarray],
    skin_weights: sp.csr_matrix,
    accessories: Accessories,
) -> Anatomy:
    """The anatomy of the dense rig: per-vertex fields interpolated from ``proxy.anatomy``, the ones
    that pair vertices found again on ``mesh`` (lip contacts, lid margins, accessory rivets)."""
    body = proxy.anatomy
    n = mesh.n_vertices
    deformable = np.zeros(n, dtype=bool)
    deformable[skin_vertices(mesh)] = True

    def carried(fields):
        out = []
        for field in fields:
            ids, offsets = _carried_field(pick, field.vertices, field.offsets_rel, deformable)
            out.append(dataclasses.replace(field, vertices=ids, offsets_rel=offsets))
        return tuple(out)

    thickness = pick @ body.thickness_rel
    corners = {
        side: np.stack([
            landmarks[f"eye_inner_corner_{side}"].position(mesh.vertices, mesh.faces),
            landmarks[f"eye_outer_corner_{side}"].position(mesh.vertices, mesh.faces),
        ])
        for side in ("L", "R")
        if f"eye_inner_corner_{side}" in landmarks and f"eye_outer_corner_{side}" in landmarks
    }  # fmt: skip
    return Anatomy(
        creases=carried(body.creases),
        skull=forehead_skull(mesh.vertices, regions, proxy.scale),
        lip_contact=lip_contact(mesh.vertices, regions, proxy.scale),
        accessories=accessories,
        thickness_rel=thickness,
        lids=_lid_contacts(proxy, mesh, regions, corners) if body.lids else (),
        actions=carried(body.actions),
    )


def _eye_faces(proxy: Rig, mesh: Mesh, side: str, corners: np.ndarray) -> np.ndarray:
    """The faces (f,) of ``mesh`` around eye ``side`` (``corners`` (2, 3)) where its lids are searched:
    those with a corner in a box over ``LID_BOX_REL`` × the eye width around the corners (seen from
    the front: the window where ``mesh.openings`` looks for the opening between the lids lies
    inside), reaching ``LID_DEPTH_REL`` × the eyeball's radius behind its centre."""
    eye = proxy.bone(f"eye_{side}")
    width = float(np.linalg.norm(corners[1] - corners[0]))
    middle = corners.mean(axis=0)
    v = mesh.vertices
    near = (np.abs(v[:, 0] - middle[0]) <= LID_BOX_REL[0] * width) & (
        np.abs(v[:, 1] - middle[1]) <= LID_BOX_REL[1] * width
    )
    near &= v[:, 2] >= eye.head[2] - LID_DEPTH_REL * eye.length
    return np.flatnonzero(near[mesh.faces].any(axis=1))


@dataclass(frozen=True)
class _Crop:
    """The faces of a mesh around its eyes as a mesh of their own: ``mesh`` (its vertices are
    ``kept`` (k,) of the whole mesh's, in order), ``face`` (m,) each whole-mesh face's index in it
    (-1: cropped away) and ``vertex`` (n,) each whole-mesh vertex's (-1: cropped away)."""

    mesh: Mesh
    kept: np.ndarray
    face: np.ndarray
    vertex: np.ndarray

    def regions(self, regions: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """Vertex sets of the whole mesh as sets (sorted) of the crop's vertices."""
        out = {}
        for name, ids in regions.items():
            local = self.vertex[ids]
            out[name] = local[local >= 0]
        return out


def _cropped(mesh: Mesh, crop: np.ndarray) -> _Crop:
    """``mesh``'s faces ``crop`` (f,) and the vertices they use, as a ``_Crop``."""
    face = np.full(mesh.n_faces, -1, dtype=np.int64)
    face[crop] = np.arange(len(crop))
    kept, local = np.unique(mesh.faces[crop], return_inverse=True)
    vertex = np.full(mesh.n_vertices, -1, dtype=np.int64)
    vertex[kept] = np.arange(len(kept))
    parts = {name: face[ids][face[ids] >= 0] for name, ids in mesh.parts.items()}
    small = Mesh(mesh.vertices[kept], local.reshape(-1, 3), parts=parts, units=mesh.units)
    return _Crop(small, kept, face, vertex)


def _lid_contacts(
    proxy: Rig, mesh: Mesh, regions: dict[str, np.ndarray], corners: dict[str, np.ndarray]
) -> tuple:
    """``find_lid_contacts`` on ``mesh``, each eye searched on the faces around it only
    (``_eye_faces``): the same contacts as on the whole mesh (the searches are local), in a second
    instead of a minute at 1.7M vertices."""
    out = []
    for side, pair in corners.items():
        if f"eye_{side}" not in proxy.bone_names:
            continue
        crop = _cropped(mesh, _eye_faces(proxy, mesh, side, pair))
        small = crop.mesh
        for contact in find_lid_contacts(
            small.vertices, small.faces, small.parts, crop.regions(regions), {side: pair}
        ):
            out.append(
                dataclasses.replace(contact, upper=crop.kept[contact.upper], lower=crop.kept[contact.lower])
            )
    return tuple(sorted(out, key=lambda c: c.side))  # left eye first, each eye's layers in order


def _closed_lids(
    proxy: Rig,
    mesh: Mesh,
    weights: np.ndarray,
    regions: dict[str, np.ndarray],
    landmarks: dict[str, SurfacePoint],
) -> tuple[np.ndarray, tuple]:
    """``weights`` (n, b) whose upper lids close onto ``mesh``'s own lower lids, and the bones with
    the lids' pivots where they can (``fit.transfer``'s closing, on the faces around the eyes): the
    copy's closing, interpolated, lands between the dense margin's vertices."""
    sides = [
        s for s in ("L", "R") if f"eye_inner_corner_{s}" in landmarks and f"eye_outer_corner_{s}" in landmarks
    ]
    if not sides or not all(f"eye_{s}" in proxy.bone_names for s in sides):
        return weights, proxy.bones
    corners = {
        s: np.stack(
            [landmarks[f"eye_{c}_corner_{s}"].position(mesh.vertices, mesh.faces) for c in ("inner", "outer")]
        )
        for s in sides
    }
    crop = _cropped(mesh, np.unique(np.concatenate([_eye_faces(proxy, mesh, s, corners[s]) for s in sides])))
    local = {
        name: SurfacePoint(int(crop.face[landmarks[name].face]), landmarks[name].bary)
        for s in sides
        for name in (f"eye_inner_corner_{s}", f"eye_outer_corner_{s}")
        if crop.face[landmarks[name].face] >= 0
    }
    near, bones = close_lids(
        proxy, crop.mesh, weights[crop.kept], crop.regions(regions), list(proxy.bones), local, proxy.scale
    )
    out = weights.copy()
    out[crop.kept] = near
    return out, tuple(bones)
