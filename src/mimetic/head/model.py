"""``make_head``: the parametric reference head with its parts, landmarks and regions."""

from __future__ import annotations

import itertools
from collections.abc import Mapping
from dataclasses import dataclass, replace
from types import MappingProxyType

import numpy as np

from mimetic.head import parts
from mimetic.head.params import HeadParams
from mimetic.head.shape import default_skin_geometry, skin_geometry
from mimetic.head.topology import HeadTopology, build_topology
from mimetic.mesh.model import Mesh

SKIN = np.float32((0.87, 0.68, 0.58))
LIP = np.float32((0.74, 0.42, 0.40))
INNER_LIP = np.float32((0.70, 0.36, 0.36))
CARUNCLE = np.float32((0.85, 0.55, 0.52))
BROW = np.float32((0.33, 0.23, 0.17))
BROW_HALF_WIDTH = (0.42, 0.22)
"""Half the brow's height at its inner and outer end, cm: the hair is drawn along the brow line
(``brow_inner`` … ``brow_outer``), tapering outward, so a render shows brows a face tracker can follow
(MediaPipe places its brow points on the hair's edge; on a bare head it guesses them)."""
BROW_LINE = ("brow_inner", "brow_inner_mid", "brow_mid", "brow_outer_mid", "brow_outer")
DEFAULT_RESOLUTION = 10_000


@dataclass(frozen=True, eq=False)
class Head:
    """A generated head: one mesh with named parts, plus what is known by construction.

    Attributes
    ----------
    mesh : Mesh
        All parts in one vertex array, skin first (vertices ``0 .. n_skin-1``), units "cm".
        Parts: skin, eye_L, eye_R, teeth_upper, teeth_lower, tongue, mouth, ear_L, ear_R.
    params : HeadParams
    resolution : int
        The requested skin vertex count; the actual count is ``n_skin``.
    n_skin : int
    mirror : (n,) int64
        Vertex index of each vertex's mirror image under x -> -x (exact).
    landmarks : Mapping[str, int]
        Landmark name -> vertex index (see ``landmarks.py``).
    regions : Mapping[str, (k,) int64]
        Region name -> sorted vertex indices (see ``regions.py``); the lips also hold the first
        two loops of the mouth cavity, whose rim continues the inner lip.
    eye_centres : (2, 3) float64
        Eyeball centres, left (+X) then right, cm.
    eye_radius : float
    """

    mesh: Mesh
    params: HeadParams
    resolution: int
    n_skin: int
    mirror: np.ndarray
    landmarks: Mapping[str, int]
    regions: Mapping[str, np.ndarray]
    eye_centres: np.ndarray
    eye_radius: float

    @property
    def vertices(self) -> np.ndarray:
        return self.mesh.vertices

    def landmark_positions(self, names: list[str] | None = None) -> np.ndarray:
        """Positions (k, 3) of the named landmarks (all, in ``landmarks`` order, by default)."""
        names = list(self.landmarks) if names is None else names
        return self.mesh.vertices[[self.landmarks[n] for n in names]]


def _skin_colors(topo: HeadTopology) -> np.ndarray:
    colors = np.tile(SKIN, (topo.n_vertices, 1))
    m = topo.mouth
    for k, u in enumerate(m.u):
        if u <= 1.0:
            colors[m.index[k]] = INNER_LIP if u < 0 else LIP
    for rings in (topo.eye_L, topo.eye_R):
        medial = np.cos(topo.ring_uv[rings.index[0], 1]) < -0.6
        colors[rings.index[0][medial]] = CARUNCLE
    return colors


def make_head(params: HeadParams | None = None, resolution: int = DEFAULT_RESOLUTION) -> Head:
    """Generate the reference head for ``params`` with about ``resolution`` skin vertices.

    Vertex count and order depend on ``resolution`` only, so two heads made at the same
    resolution correspond vertex by vertex. The result is exactly mirror-symmetric.
    """
    from mimetic.head.landmarks import skin_landmarks

    params = params or HeadParams()
    topo = build_topology(resolution)
    geo = skin_geometry(topo, params)
    s = np.sqrt(resolution / DEFAULT_RESOLUTION)
    skin = Mesh(geo.vertices, topo.faces, colors=_skin_colors(topo))

    eye_l = geo.eye_centre_L
    eye_r = eye_l * np.array([-1.0, 1.0, 1.0])
    mouth_rim = geo.vertices[topo.mouth.index[0]]
    stomion = geo.mouth_anchor
    incisal = np.array([0.0, stomion[1] - 0.05, stomion[2] - 1.45])
    lower_incisal = incisal + np.array([0.0, 0.0, -0.15])
    tragus_l = _tragus(geo.vertices[: topo.n_vertices], params)
    pieces = {
        "skin": skin,
        "eye_L": parts.eyeball(eye_l, geo.eye_radius, s),
        "eye_R": parts.eyeball(eye_r, geo.eye_radius, s),
        "teeth_upper": parts.teeth(incisal, upper=True, s=s),
        "teeth_lower": parts.teeth(lower_incisal, upper=False, s=s),
        "tongue": parts.tongue(incisal + np.array([0.0, -0.7, -2.9]), s),
        "mouth": parts.mouth_cavity(mouth_rim, s),
        "ear_L": parts.ear(tragus_l, 1.0, s),
        "ear_R": parts.ear(tragus_l * np.array([-1.0, 1.0, 1.0]), -1.0, s),
    }
    for name in ("ear_L", "ear_R"):
        pieces[name] = Mesh(
            pieces[name].vertices, pieces[name].faces, colors=np.tile(SKIN, (pieces[name].n_vertices, 1))
        )
    mesh = Mesh.concatenate(pieces, units="cm")
    mirror = _mirror_map(mesh, topo, pieces)
    rest = mesh.vertices
    rest = 0.5 * (rest + rest[mirror] * np.array([-1.0, 1.0, 1.0]))  # exact symmetry
    scale = np.array([params.head_width, params.head_height, params.head_depth])
    v = rest * scale
    # eyeballs stay spheres: scaled about their centres by the smallest factor, which keeps the
    # (anisotropically scaled) lids outside them
    centres = np.stack([eye_l, eye_r])
    for centre, part in zip(centres, ("eye_L", "eye_R"), strict=True):
        ids = mesh.part_vertices(part)
        v[ids] = centre * scale + (rest[ids] - centre) * scale.min()
    mesh = mesh.with_vertices(v)
    mirror.setflags(write=False)
    eye_centres = centres * scale
    eye_centres.setflags(write=False)
    landmarks = skin_landmarks(topo, mesh, pieces)
    brows = _with_brows(mesh.colors, default_skin_geometry(topo).vertices, landmarks)  # as every head's
    mesh = replace(mesh, colors=brows)
    return Head(
        mesh=mesh,
        params=params,
        resolution=resolution,
        n_skin=topo.n_vertices,
        mirror=mirror,
        landmarks=MappingProxyType(landmarks),
        regions=MappingProxyType(_regions(topo, mesh)),
        eye_centres=eye_centres,
        eye_radius=geo.eye_radius * float(scale.min()),
    )


def _with_brows(colors: np.ndarray, skin: np.ndarray, landmarks: Mapping[str, int]) -> np.ndarray:
    """``colors`` (n, 3) with eyebrows painted on the skin, whose vertices come first: each skin vertex
    within ``BROW_HALF_WIDTH`` of a side's brow line (the ``BROW_LINE`` landmarks) is ``BROW``: one
    flat colour, as the lips are (the web viewer draws the skin's few flat colours as pieces; the
    renderers' colour interpolation softens the edge). ``skin`` (s, 3) cm: the default head's skin, on
    which the landmarks are defined, so every head of one resolution has the same colours."""
    out = colors.copy()
    t = np.linspace(0.0, 1.0, 24)[:, None]
    for side in "LR":
        line = skin[[landmarks[f"{name}_{side}"] for name in BROW_LINE]]
        dense = np.concatenate([a + t * (b - a) for a, b in itertools.pairwise(line)])
        along = np.linspace(0.0, 1.0, len(dense))
        reach = np.linalg.norm(line - line.mean(axis=0), axis=1).max() + BROW_HALF_WIDTH[0]
        near = np.flatnonzero(np.linalg.norm(skin - line.mean(axis=0), axis=1) < reach)
        gap = np.linalg.norm(skin[near, None] - dense[None], axis=2)  # (k, d)
        closest = gap.argmin(axis=1)
        half = BROW_HALF_WIDTH[0] + (BROW_HALF_WIDTH[1] - BROW_HALF_WIDTH[0]) * along[closest]
        out[near[gap[np.arange(len(near)), closest] < half]] = BROW
    return out


def _regions(topo: HeadTopology, mesh: Mesh) -> dict[str, np.ndarray]:
    """The skin regions, with the first two loops of the mouth cavity added to the lips.

    The cavity's rim coincides with the inner lip, so whatever moves a lip moves its rim too.
    """
    from mimetic.head.regions import skin_regions

    regions = skin_regions(topo)
    per_ring = topo.mouth.index.shape[1]
    bag = mesh.part_vertices("mouth")[: 2 * per_ring].reshape(2, per_ring)  # rim loop, next loop
    t = topo.ring_uv[topo.mouth.index[0], 1]
    for name, half in (("upper_lip", np.sin(t) > 1e-9), ("lower_lip", np.sin(t) < -1e-9)):
        ids = np.union1d(regions[name], bag[:, half].ravel())
        ids.setflags(write=False)
        regions[name] = ids
    return regions


def _tragus(skin: np.ndarray, params: HeadParams) -> np.ndarray:
    """The left tragus: the skin point at the side of the head at the ear's height."""
    side = skin[(np.abs(skin[:, 1] + 1.6) < 0.6) & (np.abs(skin[:, 2] + 0.3) < 1.2)]
    x = side[:, 0].max()
    return np.array([x - 0.15, -1.6, -0.3])


def _mirror_map(mesh: Mesh, topo: HeadTopology, pieces: Mapping[str, Mesh]) -> np.ndarray:
    """Mirror vertex map: the skin's by construction, the parts' by matching mirrored points."""
    from scipy.spatial import cKDTree

    mirror = np.arange(mesh.n_vertices)
    mirror[: topo.n_vertices] = topo.mirror
    offsets = {}
    start = 0
    for name, piece in pieces.items():
        offsets[name] = (start, start + piece.n_vertices)
        start += piece.n_vertices
    pairs = [
        ("eye_L", "eye_R"),
        ("ear_L", "ear_R"),
        ("teeth_upper",) * 2,
        ("teeth_lower",) * 2,
        ("tongue",) * 2,
        ("mouth",) * 2,
    ]
    for a, b in pairs:
        a0, a1 = offsets[a]
        b0, b1 = offsets[b]
        tree = cKDTree(mesh.vertices[b0:b1])
        dist, idx = tree.query(mesh.vertices[a0:a1] * np.array([-1.0, 1.0, 1.0]))
        assert dist.max() < 1e-6, f"part {a} is not the mirror image of {b} ({dist.max():.2g} cm)"
        mirror[a0:a1] = b0 + idx
        mirror[b0:b1][idx] = np.arange(a0, a1)
    return mirror
