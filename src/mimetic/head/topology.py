"""Chart-space topology of the reference head's skin, built once per resolution.

The skin is a closed surface minus three holes (two eyes, the mouth), triangulated over the
unit sphere of directions from the head centre:

* explicit quad rings (split into triangles) around each eye (skirt, lid margin, lid, socket)
  and the mouth (inner lip, contact line, vermilion, skin), giving radial edge loops;
* everywhere else, a spherical Delaunay triangulation of Fibonacci points, made denser over
  the face and nose by smooth radial warps of the sphere, stitched to the outermost rings.

Only the x >= 0 half is triangulated; the x < 0 half is its mirror image, so the mesh is
exactly symmetric with a known mirror vertex map. The topology depends on the resolution
only: every parameter set moves the same vertices (see ``shape.py``).

Chart coordinates (X, Y) are a gnomonic projection of directions at distance ``CHART_D``
(X = D dx/dz, Y = D dy/dz), roughly centimetres on the face.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy.spatial import ConvexHull

from mimetic.head.params import HeadParamError

CHART_D = 10.0  # gnomonic chart distance, cm
EYE_CENTRE = np.array([3.5, 0.0])  # left eye (+X, the subject's left) in the canonical chart
EYE_OUTER = (2.75, 2.25)  # semi-axes of the outermost eye ring
MOUTH_CENTRE = np.array([0.0, -7.0])
MOUTH_OUTER = (4.4, 2.35, 3.15)  # semi-axes: half-width, up, down


@dataclass(frozen=True, eq=False)
class RingSet:
    """Concentric rings around one feature: ``index[k, j]`` is the vertex of ring k at angle j."""

    index: np.ndarray  # (rings, per_ring) int64
    u: np.ndarray  # (rings,) float64, ring parameter (0 = lid margin / lip contact, 1 = outermost)


@dataclass(frozen=True, eq=False)
class HeadTopology:
    """Skin connectivity and canonical chart data for one resolution.

    Attributes
    ----------
    directions : (n, 3) float64
        Canonical unit direction of each skin vertex from the head centre.
    faces : (m, 3) int64
        Counter-clockwise triangles (seen from outside).
    eye_L, eye_R, mouth : RingSet
        The explicit rings; ``eye_R`` is the mirror image of ``eye_L`` vertex by vertex.
    ring_uv : (n, 2) float64
        For ring vertices, (ring parameter u, angle t in radians); NaN for fill vertices.
    mirror : (n,) int64
        Index of each vertex's mirror image under x -> -x.
    """

    directions: np.ndarray
    faces: np.ndarray
    eye_L: RingSet
    eye_R: RingSet
    mouth: RingSet
    ring_uv: np.ndarray
    mirror: np.ndarray

    @property
    def n_vertices(self) -> int:
        return len(self.directions)


def chart_to_direction(chart: np.ndarray) -> np.ndarray:
    """Unit directions (k, 3) of gnomonic chart points (k, 2)."""
    d = np.column_stack([chart[:, 0], chart[:, 1], np.full(len(chart), CHART_D)])
    return d / np.linalg.norm(d, axis=1, keepdims=True)


def direction_to_chart(directions: np.ndarray) -> np.ndarray:
    """Gnomonic chart points (k, 2) of directions (k, 3); meaningful where d_z > 0."""
    z = np.maximum(directions[:, 2], 1e-6)
    return CHART_D * directions[:, :2] / z[:, None]


def eye_ring_params(resolution: int) -> tuple[int, np.ndarray]:
    """(vertices per ring, ring parameters u) for the eye rings at a resolution."""
    s = np.sqrt(resolution / 10_000)
    per_ring = max(16, 4 * round(11 * s))
    outer = max(5, round(7 * s**0.6))
    u = np.concatenate([[-0.12], np.linspace(0.0, 1.0, outer + 1) ** 1.3])
    return per_ring, u


def mouth_ring_params(resolution: int) -> tuple[int, np.ndarray]:
    """(vertices per ring, ring parameters u) for the mouth rings at a resolution.

    u = -1 is the inner lip (the hole's edge), 0 the contact line, (0, 1] the vermilion
    (``u <= 1``) and then the skin up to the outermost ring at u = 2.
    """
    s = np.sqrt(resolution / 10_000)
    per_ring = max(24, 4 * round(16 * s))
    vermilion = max(2, round(3 * s**0.6))
    skin = max(3, round(6 * s**0.6))
    u = np.concatenate(
        [
            [-1.0, 0.0],
            np.linspace(0.0, 1.0, vermilion + 1)[1:],
            1.0 + np.linspace(0.0, 1.0, skin + 1)[1:] ** 1.15,
        ]
    )
    return per_ring, u


def _ellipse(t: np.ndarray, a: float, b_up: float, b_down: float) -> np.ndarray:
    b = np.where(np.sin(t) >= 0, b_up, b_down)
    return np.column_stack([a * np.cos(t), b * np.sin(t)])


def _warp_towards(p: np.ndarray, centre: np.ndarray, g) -> np.ndarray:
    """Move unit vectors p (k, 3) radially about unit ``centre`` so their angle θ becomes g(θ)."""
    cos = np.clip(p @ centre, -1.0, 1.0)
    theta = np.arccos(cos)
    perp = p - cos[:, None] * centre
    norm = np.linalg.norm(perp, axis=1, keepdims=True)
    perp = np.where(norm > 1e-12, perp / np.where(norm > 0, norm, 1), 0.0)
    new = g(theta)
    return np.cos(new)[:, None] * centre + np.sin(new)[:, None] * perp


def _density_warp(p: np.ndarray) -> np.ndarray:
    """Concentrate points over the face (x2 linear density) and the nose (a further x1.8)."""
    face = np.array([0.0, -0.05, 1.0])
    face /= np.linalg.norm(face)
    p = _warp_towards(p, face, lambda th: th - 0.5 * np.sin(th) * (1 + np.cos(th)) / 2)
    nose = chart_to_direction(np.array([[0.0, -3.2]]))[0]
    return _warp_towards(p, nose, lambda th: th * (1 - 0.45 * np.exp(-((th / 0.2) ** 2))))


def _fibonacci(n: int) -> np.ndarray:
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    phi = np.pi * (1 + 5**0.5) * i
    r = np.sqrt(1 - z * z)
    return np.column_stack([r * np.cos(phi), z, r * np.sin(phi)])  # pole along ±y


def _ring_quads(index: np.ndarray, flip: bool, swap: np.ndarray | None = None) -> np.ndarray:
    """Triangles joining ring k to ring k+1; counter-clockwise seen from outside.

    ``swap`` (per_ring,) bool chooses the other diagonal for the quads starting at those angles,
    so that a ring crossing the mirror plane splits its quads symmetrically.
    """
    k = index[:-1]
    k1 = index[1:]
    j1 = np.roll(index, -1, axis=1)[:-1]
    jk1 = np.roll(index, -1, axis=1)[1:]
    swap = np.zeros(index.shape[1], bool) if swap is None else swap
    a = np.where(swap[None, :, None], np.stack([k, k1, j1], -1), np.stack([k, k1, jk1], -1)).reshape(-1, 3)
    b = np.where(swap[None, :, None], np.stack([k1, jk1, j1], -1), np.stack([k, jk1, j1], -1)).reshape(-1, 3)
    tris = np.concatenate([a, b])
    return tris[:, ::-1] if flip else tris


@lru_cache(maxsize=8)
def build_topology(resolution: int = 10_000) -> HeadTopology:
    """The skin topology for about ``resolution`` skin vertices (1,500 to 250,000)."""
    if not 1_500 <= resolution <= 250_000:
        raise HeadParamError(f"resolution={resolution} is outside the supported 1,500..250,000 skin vertices")
    s = np.sqrt(resolution / 10_000)
    m_eye, u_eye = eye_ring_params(resolution)
    m_mouth, u_mouth = mouth_ring_params(resolution)

    # --- canonical ring chart positions (shape.py moves them per parameter set) -------------
    t_eye = 2 * np.pi * np.arange(m_eye) / m_eye
    eye_outer = EYE_CENTRE + _ellipse(t_eye, EYE_OUTER[0], EYE_OUTER[1], EYE_OUTER[1])
    t_mouth = 2 * np.pi * np.arange(m_mouth) / m_mouth
    mouth_outer = MOUTH_CENTRE + _ellipse(t_mouth, *MOUTH_OUTER)
    mouth_outer[np.isclose(mouth_outer[:, 0], 0, atol=1e-9), 0] = 0.0

    # --- fill points on the x >= 0 half sphere ------------------------------------------------
    n_fib = round(9_000 * s**2)
    spacing = np.sqrt(4 * np.pi / n_fib)
    pts = _fibonacci(n_fib)
    pts = pts[pts[:, 0] > 0.5 * spacing]
    n_meridian = 2 * int(np.ceil(np.pi / spacing))
    angles = np.arange(n_meridian) * (2 * np.pi / n_meridian)
    meridian = np.column_stack([np.zeros_like(angles), np.cos(angles), np.sin(angles)])
    pts = _density_warp(pts)
    meridian = _density_warp(meridian)
    meridian[:, 0] = 0.0
    meridian /= np.linalg.norm(meridian, axis=1, keepdims=True)

    def outside_features(p: np.ndarray, margin: float) -> np.ndarray:
        chart = direction_to_chart(p)
        front = p[:, 2] > 0.3
        e = (chart - EYE_CENTRE) / np.array(EYE_OUTER)
        m = chart - MOUTH_CENTRE
        mb = np.where(m[:, 1] >= 0, MOUTH_OUTER[1], MOUTH_OUTER[2])
        rho_eye = np.hypot(e[:, 0], e[:, 1])
        rho_mouth = np.hypot(m[:, 0] / MOUTH_OUTER[0], m[:, 1] / mb)
        return ~front | ((rho_eye > 1 + margin) & (rho_mouth > 1 + margin))

    margin = 0.09 / s  # keep fill points clear of the outer rings (elliptical radius > 1 + margin)
    pts = pts[outside_features(pts, margin)]
    meridian = meridian[outside_features(meridian, margin)]

    # --- vertex numbering ------------------------------------------------------------------------
    # mouth rings, left-eye rings, right-eye rings, meridian fill, x > 0 fill, x < 0 fill
    n_mouth = len(u_mouth) * m_mouth
    n_eye = len(u_eye) * m_eye
    mouth_index = np.arange(n_mouth).reshape(len(u_mouth), m_mouth)
    eye_l_index = n_mouth + np.arange(n_eye).reshape(len(u_eye), m_eye)
    eye_r_index = n_mouth + n_eye + np.arange(n_eye).reshape(len(u_eye), m_eye)
    base_fill = n_mouth + 2 * n_eye
    n_mer, n_half = len(meridian), len(pts)
    mer_index = base_fill + np.arange(n_mer)
    pos_index = base_fill + n_mer + np.arange(n_half)
    neg_index = base_fill + n_mer + n_half + np.arange(n_half)
    n = base_fill + n_mer + 2 * n_half

    # --- triangulate the x >= 0 half: hull of directions, then drop hole and cut facets --------
    mouth_half_j = np.nonzero(mouth_outer[:, 0] >= 0)[0]
    half_dirs = np.concatenate(
        [meridian, pts, chart_to_direction(eye_outer), chart_to_direction(mouth_outer[mouth_half_j])]
    )
    half_ids = np.concatenate([mer_index, pos_index, eye_l_index[-1], mouth_index[-1][mouth_half_j]])
    hull = ConvexHull(half_dirs)
    simp = hull.simplices
    on_cut = np.abs(half_dirs[:, 0]) < 1e-12
    in_eye = np.zeros(len(half_dirs), bool)
    in_eye[n_mer + n_half : n_mer + n_half + m_eye] = True
    in_mouth = np.zeros(len(half_dirs), bool)
    in_mouth[n_mer + n_half + m_eye :] = True
    drop = on_cut[simp].all(1) | in_eye[simp].all(1) | in_mouth[simp].all(1)
    simp = simp[~drop]
    normal = np.cross(
        half_dirs[simp[:, 1]] - half_dirs[simp[:, 0]], half_dirs[simp[:, 2]] - half_dirs[simp[:, 0]]
    )
    flip = np.einsum("ij,ij->i", normal, half_dirs[simp].sum(1)) < 0
    simp[flip] = simp[flip][:, ::-1]
    half_faces = half_ids[simp]

    # --- mirror map ---------------------------------------------------------------------------------
    mirror = np.arange(n)
    mirror[eye_l_index.ravel()] = eye_r_index.ravel()
    mirror[eye_r_index.ravel()] = eye_l_index.ravel()
    mirror[pos_index] = neg_index
    mirror[neg_index] = pos_index
    j = np.arange(m_mouth)
    mirror_j = (m_mouth // 2 - j) % m_mouth
    mirror[mouth_index] = mouth_index[:, mirror_j]

    mirrored_faces = mirror[half_faces][:, ::-1]
    fill_faces = np.concatenate([half_faces, mirrored_faces])
    ring_faces = np.concatenate(
        [
            _ring_quads(mouth_index, flip=False, swap=(j >= m_mouth // 4) & (j < 3 * m_mouth // 4)),
            _ring_quads(eye_l_index, flip=False),
            _ring_quads(eye_r_index, flip=True),
        ]
    )
    faces = np.concatenate([ring_faces, fill_faces]).astype(np.int64)

    # --- canonical directions (ring shapes are placed later; here the outer rings and fill) -------
    directions = np.zeros((n, 3))
    directions[mer_index] = meridian
    directions[pos_index] = pts
    directions[neg_index] = pts * np.array([-1.0, 1.0, 1.0])
    ring_uv = np.full((n, 2), np.nan)
    ring_uv[mouth_index] = np.stack(np.broadcast_arrays(u_mouth[:, None], t_mouth[None, :]), -1)
    ring_uv[eye_l_index] = np.stack(np.broadcast_arrays(u_eye[:, None], t_eye[None, :]), -1)
    ring_uv[eye_r_index] = ring_uv[eye_l_index]
    # placeholder directions for ring vertices: their outer ring (exact ones come from shape.py)
    directions[mouth_index] = chart_to_direction(mouth_outer)[None]
    directions[eye_l_index] = chart_to_direction(eye_outer)[None]
    directions[eye_r_index] = directions[eye_l_index] * np.array([-1.0, 1.0, 1.0])

    for a in (directions, faces, ring_uv, mirror, mouth_index, eye_l_index, eye_r_index):
        a.setflags(write=False)
    return HeadTopology(
        directions=directions,
        faces=faces,
        eye_L=RingSet(eye_l_index, u_eye),
        eye_R=RingSet(eye_r_index, u_eye),
        mouth=RingSet(mouth_index, u_mouth),
        ring_uv=ring_uv,
        mirror=mirror,
    )
