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

**A proxy for dense scans.** The volume's set-up grows with the skin (``MAX_NODES``), so on a skin
of more than ``PROXY_ABOVE`` vertices the tissue is laid under a decimated copy of it (``mesh.decimate``,
about ``PROXY_VERTICES`` vertices; ``proxy`` chooses another size or none). Each proxy node reads the
rig's per-vertex data (thickness, regions, muscle fields, skin weights) where it lies on the skin
(``sampling``: barycentric on the closest skin triangle facing its way), and every skin vertex follows
the proxy's motion by barycentric interpolation in its own proxy triangle (``to_vertices``): the
displacement is carried, so the rest skin keeps all its detail and comes back exactly at rest.

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
import scipy.sparse as sp
import trimesh
from scipy.spatial import cKDTree

from mimetic.errors import MimeticError
from mimetic.mesh.decimate import Embedding, decimate, embed
from mimetic.mesh.geometry import vertex_normals
from mimetic.mesh.weld import Weld, find_weld
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
with ``tissue`` beside it; a denser skin takes a proxy (``PROXY_ABOVE``)."""
PROXY_ABOVE = 30_000
"""A skin of more welded vertices than this gets a proxy by default (``proxy="auto"``): the default
head's (9,617) and ICT-FaceKit's (19,167) stay at full resolution, a phone or photogrammetry scan's
(0.5-5 M vertices) does not."""
PROXY_VERTICES = 20_000
"""Skin vertices of the automatic proxy: a volume of 60,000 nodes, a little more than ICT-FaceKit's
full skin, so the lips, lids and nasolabial folds keep several proxy triangles across them, at a fifth
of the largest volume ``MAX_NODES`` allows: ICT subdivided twice (300,177 skin vertices) poses in
1.8 GiB (fem) and 2.2 GiB (tissue), a quarter of the 8 GiB a 420k-vertex scan may take
(``benchmarks/bench_proxy.py``)."""
SLIVER_QUALITY = 1e-3
"""Proxy triangles of a quality (``4√3 area / Σ edge²``, 1 for an equilateral one) or an area (over
the median's) below this are left out: they hold no tissue, and their flat prisms have no stiffness
to invert. Quadric collapse on a flat patch (a subdivided scan: its midpoints lie exactly on the old
edges) leaves such slivers and specks (three vertices within 1e-7 cm): 958 of 39,720 triangles of
ICT-FaceKit subdivided twice, decimated to 20,000 vertices."""
MIN_PROXY = 500
EMBED_CHUNK = 200_000
"""Skin vertices tied to the proxy at a time: the closest-triangle search holds its candidates for a
chunk (about 1 KiB per vertex), so a 5 M-vertex scan does not hold them all at once."""
"""The smallest proxy asked for by size: fewer skin vertices leave no tissue across the lips."""
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
        The rig vertex (on the tissue) each follows.
    cavity_fall : (m,) float64
        How much of that vertex's motion each takes.
    proxy_nodes : Embedding or None
        With a proxy (module docstring): each skin node tied to the rig's skin triangles, where it
        reads the rig's per-vertex data (``sampling``); ``surface`` is then each node's nearest
        corner there, and ``index`` each rig vertex's nearest corner of its proxy triangle.
    proxy_skin : Embedding or None
        With a proxy: the rig vertices on the tissue (``index >= 0``, in order) tied to the proxy's
        triangles, by which they follow its motion (``to_vertices``).
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
    proxy_nodes: Embedding | None = None
    proxy_skin: Embedding | None = None

    def __post_init__(self) -> None:
        for name in self.__dataclass_fields__:
            if name.startswith("proxy_"):
                continue
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

    @property
    def is_proxy(self) -> bool:
        """True when the tissue lies under a decimated copy of the skin (module docstring)."""
        return self.proxy_skin is not None

    def sampling(self) -> sp.csr_matrix:
        """The (k, n) matrix that reads per-rig-vertex values at the skin nodes: ``sampling() @
        values``; at full resolution it picks each node's vertex (``surface``)."""
        if self.proxy_nodes is not None:
            return self.proxy_nodes.matrix()
        k, n = self.n_skin, len(self.index)
        return sp.csr_matrix((np.ones(k), (np.arange(k), self.surface)), shape=(k, n))

    def to_vertices(self, node_values: np.ndarray) -> np.ndarray:
        """Per-vertex values (n, ...) from skin-node values (k, ...): each skin vertex its node's (with
        a proxy: interpolated in its proxy triangle), the mouth's lining follows the skin
        (``cavity``), other vertices off the tissue (eyes, teeth, ears) get 0."""
        out = np.zeros((len(self.index), *node_values.shape[1:]))
        inside = self.index >= 0
        if self.proxy_skin is not None:
            flat = node_values.reshape(len(node_values), -1)
            out[inside] = (self.proxy_skin.matrix() @ flat).reshape(-1, *node_values.shape[1:])
        else:
            out[inside] = node_values[self.index[inside]]
        fall = self.cavity_fall.reshape((-1,) + (1,) * (node_values.ndim - 1))
        out[self.cavity] = out[self.cavity_source] * fall
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


def proxy_size(n_skin: int, proxy: int | str = "auto") -> int | None:
    """The proxy's skin vertex count for a skin of ``n_skin`` welded vertices, or None for the full
    skin: ``proxy`` "auto" (``PROXY_VERTICES`` above ``PROXY_ABOVE``), "off", or a count (at least
    ``MIN_PROXY``; a skin no larger keeps its full resolution).

    Raises ``MimeticError`` for any other value, and when the volume would be over ``MAX_NODES``.
    """
    if isinstance(proxy, str) and proxy.strip().lower() in ("auto", "off"):
        size = PROXY_VERTICES if proxy.strip().lower() == "auto" and n_skin > PROXY_ABOVE else None
    elif isinstance(proxy, (int, np.integer)) and not isinstance(proxy, bool) and proxy >= MIN_PROXY:
        size = int(proxy) if n_skin > proxy else None
    else:
        raise MimeticError(
            f"proxy={proxy!r}: say 'auto' (a proxy of {PROXY_VERTICES:,} skin vertices above "
            f"{PROXY_ABOVE:,}), 'off' (the full skin), or a skin vertex count of at least {MIN_PROXY:,}"
        )
    k = n_skin if size is None else size
    if 3 * k > MAX_NODES:
        what = f"the rig's skin has {n_skin:,} vertices" if size is None else f"a proxy of {size:,} vertices"
        raise MimeticError(
            f"{what}, a tissue volume of {3 * k:,} nodes; the physical engines (fem, tissue) take at "
            f"most {MAX_NODES:,} nodes ({MAX_NODES // 3:,} skin vertices), their memory and time grow "
            f"with it. Simulate through a smaller proxy (the engine option proxy='auto', or a count up "
            f"to {MAX_NODES // 3:,}; `--proxy auto` on the command line), or use the wire or vector engine"
        )
    return size


def solid_triangles(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Which triangles ``faces`` (q, 3) of ``vertices`` (p, 3) can hold tissue (q,) bool: not a flat
    sliver nor a speck (``SLIVER_QUALITY``)."""
    corners = vertices[faces]  # (q, 3, 3)
    area = 0.5 * np.linalg.norm(
        np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
    )
    squared = (np.diff(corners, axis=1, append=corners[:, :1]) ** 2).sum(axis=(1, 2))  # Σ edge²
    return (4 * np.sqrt(3) * area > SLIVER_QUALITY * squared) & (area > SLIVER_QUALITY * np.median(area))


def _proxy_surface(
    rig: Rig, weld: Weld, used: np.ndarray, faces: np.ndarray, size: int
) -> tuple[np.ndarray, np.ndarray, Embedding, Embedding]:
    """A decimated copy (about ``size`` vertices) of the welded skin ``faces`` (m, 3) over the welded
    vertices ``used`` (k,): its vertices (p, 3), triangles (q, 3), the ``Embedding`` of its vertices
    on the rig's skin triangles (where they read the rig's data) and that of the rig's vertices on
    the tissue, in order, in its triangles (how they follow it), both with the normal test
    (``mesh.decimate.embed``: a lip's vertex stays with its own lip)."""
    node_of = np.full(len(weld.mesh.vertices), -1, dtype=np.int64)
    node_of[used] = np.arange(len(used))
    dense, dense_faces = weld.mesh.vertices[used], node_of[faces]
    proxy_v, proxy_f = decimate(dense, dense_faces, size)
    proxy_f = proxy_f[solid_triangles(proxy_v, proxy_f)]
    kept, proxy_f = np.unique(proxy_f, return_inverse=True)  # drop any vertex left without a triangle
    proxy_v, proxy_f = proxy_v[kept], proxy_f.reshape(-1, 3)
    of_vertex = node_of[weld.index]  # (n,) each rig vertex's welded skin vertex, -1 off the tissue
    inside = np.flatnonzero(of_vertex >= 0)
    mesh_parts = [rig.mesh.parts[p] for p in SKIN_PARTS if p in rig.mesh.parts]
    rig_faces = rig.mesh.faces[np.concatenate(mesh_parts)] if mesh_parts else rig.mesh.faces
    rig_faces = rig_faces[(of_vertex[rig_faces] >= 0).all(axis=1)]  # the skin's own triangles
    nodes = embed(proxy_v, rig.mesh.vertices, rig_faces, normals=vertex_normals(proxy_v, proxy_f))
    normals = vertex_normals(dense, dense_faces)[of_vertex[inside]]
    parts = [
        embed(
            rig.mesh.vertices[inside[i : i + EMBED_CHUNK]],
            proxy_v,
            proxy_f,
            normals=normals[i : i + EMBED_CHUNK],
        )
        for i in range(0, len(inside), EMBED_CHUNK)
    ]
    skin = Embedding(
        *(np.concatenate([getattr(p, name) for p in parts]) for name in ("triangles", "bary", "offset")),
        len(proxy_v),
    )
    return proxy_v, proxy_f, nodes, skin


def build_volume(rig: Rig, *, proxy: int | str = "auto") -> TissueVolume:
    """The layered tissue volume (``TissueVolume``) under ``rig``'s skin (module docstring); under a
    decimated copy of it as ``proxy_size(skin vertices, proxy)`` says.

    Raises ``MimeticError`` when the rig has no skin triangles, or (``proxy_size``) for a volume over
    ``MAX_NODES`` nodes or a bad ``proxy``.
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
    size = proxy_size(len(used), proxy)
    node_of = np.full(len(welded.vertices), -1, dtype=np.int64)
    node_of[used] = np.arange(len(used))
    # 1. the skin surface the tissue lies under: the welded skin, or its proxy
    thickness_rel = np.zeros(len(welded.vertices))
    thickness_rel[weld.index] = rig.anatomy.thickness_rel
    free_rel = np.zeros(len(welded.vertices), dtype=bool)  # under the lips: no bone
    for name in FREE_REGIONS:
        free_rel[weld.index[rig.regions.get(name, np.zeros(0, np.int64))]] = True
    if size is None:
        proxy_nodes = proxy_skin = None
        skin, tri, surface = welded.vertices[used], node_of[faces], weld.first[used]
        thickness_rel, free_rel = thickness_rel[used], free_rel[used]
        index = node_of[weld.index]
    else:
        skin, tri, proxy_nodes, proxy_skin = _proxy_surface(rig, weld, used, faces, size)
        sampling = proxy_nodes.matrix()  # (p, n) rig vertices -> proxy nodes
        surface = proxy_nodes.triangles[np.arange(len(skin)), np.argmax(proxy_nodes.bary, axis=1)]
        thickness_rel = sampling @ thickness_rel[weld.index]
        free_rel = free_rel[weld.index[surface]]
        index = np.full(rig.n_vertices, -1, dtype=np.int64)
        index[node_of[weld.index] >= 0] = proxy_skin.triangles[
            np.arange(len(proxy_skin.triangles)), np.argmax(proxy_skin.bary, axis=1)
        ]
    k = len(skin)
    # 2. the depth under each skin node: its thickness, cut back clear of the other surfaces
    no_contact = np.zeros((0, 2), dtype=np.int64)  # each lip's tissue lies behind its own skin
    normals = tissue_normals(skin, tri, no_contact, rig.scale)
    thickness = np.maximum(thickness_rel, MIN_THICKNESS_REL) * rig.scale
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
    samples = np.flatnonzero(on_surface)
    lining = np.ones(len(welded.vertices), dtype=bool)
    lining[used] = False
    depth = _depths(
        skin,
        normals,
        thickness,
        rigid,
        welded.vertices[samples],
        vertex_normals(welded.vertices, faces)[samples],
        lining[samples],
    )
    # 3. the layers, their prisms' tetrahedra and the pinned skull nodes
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
    free = (depth < RIM_DEPTH * thickness) | free_rel  # a rim cut back by an opening, or the lips
    pinned = np.concatenate([np.zeros(2 * k, dtype=bool), ~free])
    # 4. the mouth's lining follows the skin it continues
    cavity = np.intersect1d(np.flatnonzero(index < 0), skin_vertices(rig.mesh))
    mesh_parts = [rig.mesh.parts[p] for p in SKIN_PARTS if p in rig.mesh.parts]
    unwelded = rig.mesh.faces[np.concatenate(mesh_parts)] if mesh_parts else rig.mesh.faces  # the rig's own
    follow, source, fall = cavity_links(rig.mesh.vertices, unwelded, cavity, LINING_REACH_REL * rig.scale)
    return TissueVolume(
        nodes,
        surface,
        index,
        tri,
        tets,
        layer,
        pinned,
        normals,
        depth,
        follow,
        source,
        fall,
        proxy_nodes,
        proxy_skin,
    )
