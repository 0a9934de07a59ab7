"""The tissue volume under a rig's skin, for the physically based engines (``tissue``, ``fem``).

As in Lee, Terzopoulos and Waters (1995) the skin is the top of a layered volume: each skin vertex
has a node on the skin, one on the fascia and one on the skull, offset inward along the rig's tissue
normals (``rig.anatomy.tissue_normals``: smoothed, with the lips closed) by ``FASCIA_DEPTH`` and 1
times its soft-tissue thickness (``rig.anatomy.thickness_rel``: thin on the lids and over the nose,
thick on the cheeks). Each skin triangle gives two triangular prisms, the dermal-fatty layer (skin
to fascia) and the muscle layer (fascia to skull), each split into three tetrahedra by a rule that
makes neighbouring prisms share their quad diagonals (from the top of a quad's lower-numbered vertex
to the bottom of the other), so the tetrahedra form a conforming mesh.

The tissue lies under the ``skin`` part (every deformable face on a mesh without parts); the mouth's
lining has no tissue of its own and follows the lips and cheeks it continues (``cavity``). The
volume is built with unwelded seams merged (``mesh.weld``), so both copies of a seam vertex are one
node and move together.

Robust at openings and on scans: the depth under a vertex is cut back (``DEPTH_STEPS``) until its
skull node is clear of the mesh's other surfaces: the eyes and teeth (never inside them), and skin
facing back at the vertex (the back of a thin lip, the far side of a fold in a scan). So no
tetrahedron reaches through a lip or into an eye, and a scan with holes only has thinner tissue at
their rims.

Choices the paper leaves open: the skull nodes are fixed to the bone (``pinned``) except under the
lips (``FREE_REGIONS``) and at the rims where the depth was cut back to less than ``RIM_DEPTH`` of the
thickness (the mouth's corners, the lids' edges): no bone lies behind those, and pinning them made
the mouth's corners stiff knots. The jaw and the lids are bones applied after the tissue (the
engines' shared chain), so the physics runs in the rest frame of the head.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from itertools import permutations

import numpy as np
import trimesh
from scipy.spatial import cKDTree

from mimetic.errors import MimeticError
from mimetic.mesh.geometry import vertex_normals
from mimetic.mesh.weld import find_weld
from mimetic.rig.anatomy.derive import SKIN_PARTS, cavity_links, skin_vertices, tissue_normals
from mimetic.rig.model import Rig

FASCIA_DEPTH = 0.4
"""The fascia lies at this fraction of the tissue thickness under the skin."""
DEPTH_STEPS = (1.0, 0.75, 0.55, 0.4, 0.3, 0.2, 0.12)
"""Fractions of the thickness tried in turn until the skull node is clear of other surfaces."""
CLEARANCE = 0.85
"""A skull node is clear when no other surface is nearer to it than this × its depth."""
LINING_REACH_REL = 0.1
"""The mouth's lining follows the lips and cheeks it continues this far into the mouth, × the head
height (2.2 cm: the default head's lining is 1.3 to 6 cm deep)."""
RIM_DEPTH = 0.5
"""Where the depth had to be cut back below this × the thickness (the rims of the mouth and the
eyes, a thin lip) the skull node is not on bone: it hangs (``pinned`` is False)."""
FACING = 0.3
"""Skin counts as another surface where its normal and the point's have a dot product below −this."""
MAX_NODES = 300_000
"""Most nodes of a volume (three per skin vertex). Setup grows with them: 258,834 nodes (a generated
head of 95,000 skin vertices) took 59 s and 4.4 GiB for ``fem``, then 67 s and a peak of 10.2 GiB
with ``tissue`` beside it; a bigger scan is decimated first."""
NEIGHBOURS = 12
"""Nearest mesh vertices checked around a skull node (``_depths``)."""
MIN_THICKNESS_REL = 0.008
"""Tissue under skin the anatomy gives no thickness (a mesh without regions) is at least this × the
head height deep."""
FREE_REGIONS = ("upper_lip", "lower_lip")
"""Regions whose skull nodes are not fixed: no bone lies behind the lips."""


def _splits() -> tuple[np.ndarray, np.ndarray]:
    """The distinct tetrahedra (12, 4) of a prism's six three-tetrahedron splits (local nodes: top 0-2,
    bottom 3-5, node ``i + 3`` under node ``i``) and how many of the six splits hold each (12,)."""
    tets = [
        tuple(sorted(tet))
        for a, b, c in permutations(range(3))
        for tet in ((a, b, c, c + 3), (a, b, b + 3, c + 3), (a, a + 3, b + 3, c + 3))
    ]
    distinct, counts = np.unique(np.array(tets), axis=0, return_counts=True)
    return distinct, counts


SPLITS, SPLIT_COUNTS = _splits()


@dataclass(frozen=True, eq=False)
class TissueVolume:
    """Layered tetrahedral tissue under a rig's deformable skin.

    Nodes are layer-major: skin nodes ``0 .. k-1``, fascia ``k .. 2k-1``, skull ``2k .. 3k-1``;
    node ``i`` of each layer lies under skin node ``i``.

    Attributes
    ----------
    nodes : (3k, 3) float64
        Rest positions, rig units.
    surface : (k,) int64
        The rig vertex of each skin node (the first copy of a welded seam vertex).
    index : (n,) int64
        The skin node of each rig vertex, -1 for vertices outside the tissue (eyes, teeth, ears).
    triangles : (m, 3) int64
        The skin triangles (skin nodes); each is the top of one prism per layer.
    tets : (t, 4) int64
        Node indices of each tetrahedron, positively oriented: three per prism, the dermal-fatty
        layer's ``3m`` first.
    tet_layer : (t,) int64
        0 for the dermal-fatty layer (skin to fascia), 1 for the muscle layer (fascia to skull).
    pinned : (3k,) bool
        Nodes fixed to the bone.
    normals : (k, 3) float64
        The outward unit normals the layers were offset along.
    depth : (k,) float64
        Distance from each skin node to its skull node, rig units.
    cavity : (m,) int64
        Rig vertices of the mouth's lining that follow the tissue (``cavity_links``): the lining has
        no tissue of its own (its triangles need not be mirror-symmetric where the head is).
    cavity_source : (m,) int64
        The skin node each follows.
    cavity_fall : (m,) float64
        How much of that node's motion each takes.
    """

    nodes: np.ndarray
    surface: np.ndarray
    index: np.ndarray
    triangles: np.ndarray
    tets: np.ndarray
    tet_layer: np.ndarray
    pinned: np.ndarray
    normals: np.ndarray
    depth: np.ndarray
    cavity: np.ndarray
    cavity_source: np.ndarray
    cavity_fall: np.ndarray

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            array = np.array(getattr(self, name), copy=True)
            array.setflags(write=False)
            object.__setattr__(self, name, array)

    @property
    def n_skin(self) -> int:
        return len(self.surface)

    @property
    def n_nodes(self) -> int:
        return len(self.nodes)

    @cached_property
    def rest_volumes(self) -> np.ndarray:
        """Volume (t,) of each tetrahedron at rest, rig units cubed (all positive)."""
        return tet_volumes(self.nodes, self.tets)

    @cached_property
    def prisms(self) -> np.ndarray:
        """The prisms (2m, 6) as nodes: the top triangle then the nodes under it; the dermal-fatty
        layer's m first."""
        k, tri = self.n_skin, self.triangles
        return np.concatenate([np.hstack([tri, tri + k]), np.hstack([tri + k, tri + 2 * k])])

    @cached_property
    def nodal_volumes(self) -> np.ndarray:
        """The tissue volume (N,) each node stands for: a sixth of each prism it is a corner of (a
        prism's volume is the mean over its six splits into tetrahedra, so it does not depend on how
        the vertices are numbered), rig units cubed."""
        prisms = self.prisms
        volumes = sum(
            count / 6.0 * np.abs(tet_volumes(self.nodes, prisms[:, tet]))
            for tet, count in zip(SPLITS, SPLIT_COUNTS, strict=True)
        )
        return np.bincount(prisms.ravel(), np.repeat(volumes / 6.0, 6), self.n_nodes)

    def to_vertices(self, node_values: np.ndarray) -> np.ndarray:
        """Per-vertex values (n, ...) from skin-node values (k, ...): the mouth's lining follows the
        skin (``cavity``), other vertices off the tissue (eyes, teeth, ears) get 0."""
        out = np.zeros((len(self.index), *node_values.shape[1:]))
        inside = self.index >= 0
        out[inside] = node_values[self.index[inside]]
        fall = self.cavity_fall.reshape((-1,) + (1,) * (node_values.ndim - 1))
        out[self.cavity] = node_values[self.cavity_source] * fall
        return out


def triple_products(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """``a · (b × c)`` (k,) for rows of ``a``, ``b``, ``c`` (k, 3) (component-wise: ``np.cross`` copies
    strided rows and is several times slower)."""
    a0, a1, a2 = a[:, 0], a[:, 1], a[:, 2]
    b0, b1, b2 = b[:, 0], b[:, 1], b[:, 2]
    c0, c1, c2 = c[:, 0], c[:, 1], c[:, 2]
    return a0 * (b1 * c2 - b2 * c1) + a1 * (b2 * c0 - b0 * c2) + a2 * (b0 * c1 - b1 * c0)


def tet_volumes(nodes: np.ndarray, tets: np.ndarray) -> np.ndarray:
    """Signed volumes (t,) of tetrahedra ``tets`` (t, 4) over ``nodes`` (N, 3)."""
    origin = nodes[tets[:, 0]]
    return (
        triple_products(nodes[tets[:, 1]] - origin, nodes[tets[:, 2]] - origin, nodes[tets[:, 3]] - origin)
        / 6.0
    )


def prism_tets(top: np.ndarray, bottom: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Three tetrahedra (3m, 4) per prism between triangles ``faces`` (m, 3) of surface vertices
    whose nodes are ``top[v]`` and ``bottom[v]``; conforming across shared edges (module docstring).
    """
    f = np.sort(faces, axis=1)  # by vertex number: the diagonal rule depends only on the edge
    a, b, c = f[:, 0], f[:, 1], f[:, 2]
    return np.concatenate(
        [
            np.column_stack([top[a], top[b], top[c], bottom[c]]),
            np.column_stack([top[a], top[b], bottom[b], bottom[c]]),
            np.column_stack([top[a], bottom[a], bottom[b], bottom[c]]),
        ]
    )


def _depths(
    points: np.ndarray,
    normals: np.ndarray,
    thickness: np.ndarray,
    rigid: trimesh.Trimesh | None,
    samples: np.ndarray,
    sample_normals: np.ndarray,
    lining: np.ndarray,
) -> np.ndarray:
    """Depth (k,) under each skin point (k, 3) with outward ``normals`` (k, 3): the largest
    ``DEPTH_STEPS`` fraction of ``thickness`` (k,) whose inward node is clear of the mesh's other
    surfaces: never inside the ``rigid`` parts (eyes, teeth) nor nearer to them than ``CLEARANCE`` ×
    the depth (measured to their triangles); and no vertex of the deformable surface (``samples``
    (s, 3), of its ``NEIGHBOURS`` nearest) that near where it is the mouth's ``lining`` (s,) bool (the
    back of the lips and cheeks) or skin facing back at the point (its normal in ``sample_normals``
    against the point's: the other side of a fold). Skin that does not face back (the lips' faces
    across the mouth's slit, the skin beside the point) does not limit it. Nothing here depends on
    how the lining or the rigid parts are triangulated, so a mirror-symmetric head gets a
    mirror-symmetric volume.
    """
    tree = cKDTree(samples)
    depth = thickness * DEPTH_STEPS[-1]
    chosen = np.zeros(len(points), dtype=bool)
    near = min(NEIGHBOURS, len(samples))
    if rigid is not None:
        edge = float(rigid.edges_unique_length.max())
        rigid_tree = cKDTree(rigid.vertices)
        rigid_normals = rigid.vertex_normals
    for step in DEPTH_STEPS:
        d = thickness * step
        inner = points - d[:, None] * normals
        dist, idx = tree.query(inner, k=near)
        dist, idx = dist.reshape(len(points), -1), idx.reshape(len(points), -1)
        facing = np.einsum("kji,ki->kj", sample_normals[idx], normals) < -FACING
        clear = ~((lining[idx] | facing) & (dist < CLEARANCE * d[:, None])).any(axis=1)
        if rigid is not None:  # the nearest rigid vertex settles most points; the rest, its triangles
            gap, at = rigid_tree.query(inner)
            behind = np.einsum("ki,ki->k", inner - rigid.vertices[at], rigid_normals[at]) < 0
            sure = (gap - edge >= CLEARANCE * d) & ~behind  # far outside
            sure |= gap < CLEARANCE * d  # too near, or inside near the surface
            sure |= behind & (gap > edge)  # deep inside
            clear &= ~(gap < CLEARANCE * d) & ~(behind & (gap > edge))
            test = ~chosen & clear & ~sure
            if test.any():
                closest, exact, face = trimesh.proximity.closest_point(rigid, inner[test])
                outside = np.einsum("ki,ki->k", inner[test] - closest, rigid.face_normals[face]) >= 0
                clear[test] = outside & (exact >= CLEARANCE * d[test])
        ok = ~chosen & clear
        depth[ok] = d[ok]
        chosen |= ok
    return depth


def build_volume(rig: Rig) -> TissueVolume:
    """The layered tissue volume (``TissueVolume``) under ``rig``'s skin (module docstring).

    Raises ``MimeticError`` when the rig has no skin triangles or more than ``MAX_NODES // 3`` skin
    vertices.
    """
    weld = find_weld(rig.mesh)
    welded = weld.mesh
    parts = welded.parts
    if "skin" in parts:
        faces = welded.faces[parts["skin"]]
    elif any(p in parts for p in SKIN_PARTS):
        faces = welded.faces[np.concatenate([parts[p] for p in SKIN_PARTS if p in parts])]
    else:
        faces = welded.faces
    if not len(faces):
        raise MimeticError("the rig has no skin triangles to lay tissue under; rebuild it with `mimetic rig`")
    used = np.unique(faces)
    k = len(used)
    if 3 * k > MAX_NODES:
        raise MimeticError(
            f"the rig's skin has {k:,} vertices, a tissue volume of {3 * k:,} nodes; the physical engines "
            f"(fem, tissue) take at most {MAX_NODES:,} nodes ({MAX_NODES // 3:,} skin vertices), their "
            "memory and time grow with it. Decimate the mesh before `mimetic rig` (trimesh's "
            "simplify_quadric_decimation, Blender's Decimate modifier), or use the wire or vector engine"
        )
    node_of = np.full(len(welded.vertices), -1, dtype=np.int64)
    node_of[used] = np.arange(k)
    tri = node_of[faces]  # (m, 3) skin-node triangles
    no_contact = np.zeros((0, 2), dtype=np.int64)  # each lip's tissue lies behind its own skin
    normals = tissue_normals(welded.vertices, faces, no_contact, rig.scale)[used]
    skin = welded.vertices[used]
    thickness_rel = np.zeros(len(welded.vertices))
    thickness_rel[weld.index] = rig.anatomy.thickness_rel
    thickness = np.maximum(thickness_rel[used], MIN_THICKNESS_REL) * rig.scale
    deformable = (
        welded.faces[np.concatenate([parts[p] for p in SKIN_PARTS if p in parts])] if parts else faces
    )
    on_surface = np.zeros(len(welded.vertices), dtype=bool)
    on_surface[deformable.ravel()] = True
    rigid_faces = welded.faces[~on_surface[welded.faces].any(axis=1)]  # eyes, teeth, tongue, ears
    rigid = None
    if len(rigid_faces):
        kept, compact = np.unique(rigid_faces, return_inverse=True)
        rigid = trimesh.Trimesh(welded.vertices[kept], compact.reshape(-1, 3), process=False)
    surface = np.flatnonzero(on_surface)
    lining = np.ones(len(welded.vertices), dtype=bool)
    lining[used] = False
    depth = _depths(
        skin,
        normals,
        thickness,
        rigid,
        welded.vertices[surface],
        vertex_normals(welded.vertices, faces)[surface],
        lining[surface],
    )
    fascia = skin - (FASCIA_DEPTH * depth)[:, None] * normals
    skull = skin - depth[:, None] * normals
    ids = np.arange(k)
    tets = np.concatenate([prism_tets(ids, ids + k, tri), prism_tets(ids + k, ids + 2 * k, tri)])
    layer = np.repeat([0, 1], 3 * len(tri))
    nodes = np.concatenate([skin, fascia, skull])
    if not np.all(np.isfinite(nodes)):
        raise MimeticError("the tissue volume has non-finite nodes; check the rig's mesh for NaN vertices")
    negative = tet_volumes(nodes, tets) < 0
    tets[negative] = tets[negative][:, [0, 2, 1, 3]]
    free = depth < RIM_DEPTH * thickness  # a rim: cut back by an opening, no bone behind it
    for name in FREE_REGIONS:
        ids_in = node_of[np.unique(weld.index[rig.regions.get(name, np.zeros(0, np.int64))])]
        free[ids_in[ids_in >= 0]] = True
    pinned = np.concatenate([np.zeros(2 * k, dtype=bool), ~free])
    index = node_of[weld.index]
    cavity = np.intersect1d(np.flatnonzero(index < 0), skin_vertices(rig.mesh))  # the mouth's lining
    mesh_parts = [rig.mesh.parts[p] for p in SKIN_PARTS if p in rig.mesh.parts]
    unwelded = rig.mesh.faces[np.concatenate(mesh_parts)] if mesh_parts else rig.mesh.faces  # the rig's own
    follow, source, fall = cavity_links(rig.mesh.vertices, unwelded, cavity, LINING_REACH_REL * rig.scale)
    return TissueVolume(
        nodes, weld.first[used], index, tri, tets, layer, pinned, normals, depth, follow, index[source], fall
    )
