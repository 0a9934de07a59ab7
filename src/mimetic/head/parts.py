"""Separate parts of the reference head: eyeballs, teeth, tongue, mouth cavity and ears.

Each builder returns a closed (or, for the mouth cavity, rim-attached) ``Mesh`` in cm with
per-vertex colours. Vertex counts depend only on the resolution factor ``s``, never on the
head parameters, so generated heads keep exact correspondence.
"""

from __future__ import annotations

import numpy as np

from mimetic.mesh.model import Mesh

SCLERA = (0.93, 0.91, 0.87)
IRIS = (0.36, 0.22, 0.12)
PUPIL = (0.03, 0.03, 0.03)
TOOTH = (0.93, 0.91, 0.83)
TOOTH_GAP_SHADE = 0.45
"""Albedo of a tooth at the gaps between teeth, × ``TOOTH``: without it an arch read as one band."""
TOOTH_ROOT_SHADE = 0.7
"""Albedo at the root end of a tooth (toward the gum), × ``TOOTH``."""
TOOTH_COLUMNS = 3.5
"""A tooth's width in columns of the arch's mesh (48 columns at the default resolution)."""
TONGUE = (0.78, 0.38, 0.38)
MOUTH = (0.2, 0.05, 0.05)
"""The mouth cavity: dark red, so an open mouth reads as a hole, not as more lip."""
IRIS_ANGLE = 0.52  # angular radius of the iris on the eyeball, rad
CORNEA_BULGE = 0.05  # how far the cornea bulges out of the eyeball sphere, relative to its radius
PUPIL_ANGLE = 0.19


def _signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    tri = vertices[faces]
    return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)


def _grid_faces(rows: int, cols: int, closed_cols: bool = True) -> np.ndarray:
    """Triangles of a (rows, cols) vertex grid; columns wrap when ``closed_cols``."""
    r, c = np.meshgrid(np.arange(rows - 1), np.arange(cols if closed_cols else cols - 1), indexing="ij")
    a = r * cols + c
    b = r * cols + (c + 1) % cols
    d = (r + 1) * cols + c
    e = (r + 1) * cols + (c + 1) % cols
    return np.concatenate([np.stack([a, d, e], -1).reshape(-1, 3), np.stack([a, e, b], -1).reshape(-1, 3)])


def _cap(center: int, ring: np.ndarray, flip: bool) -> np.ndarray:
    tris = np.column_stack([np.full(len(ring), center), ring, np.roll(ring, -1)])
    return tris[:, ::-1] if flip else tris


def _closed_grid(front: np.ndarray, rings: np.ndarray, back: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A closed sphere-like surface: a front pole (3,), rings (k, cols, 3) and a back pole (3,).

    The rings run from the front pole to the back pole; each ring is counter-clockwise seen
    from the front pole's side, so the faces point outward.
    """
    k, cols = rings.shape[:2]
    verts = np.concatenate([front[None], rings.reshape(-1, 3), back[None]])
    body = 1 + _grid_faces(k, cols)
    first = _cap(0, 1 + np.arange(cols), flip=False)
    last = _cap(1 + k * cols, 1 + (k - 1) * cols + np.arange(cols), flip=True)
    return verts, np.concatenate([first, body, last])


def _lathe(profile_angles: np.ndarray, radius_of, cols: int) -> tuple[np.ndarray, np.ndarray]:
    """A closed surface of revolution about +Z with ``radius_of(θ)`` at polar angle θ.

    ``profile_angles`` (k,) are the polar angles of the rings in (0, π).
    """
    phi = 2 * np.pi * np.arange(cols) / cols
    th = profile_angles[:, None]
    r = radius_of(th)
    rings = np.stack(
        [r * np.sin(th) * np.cos(phi), r * np.sin(th) * np.sin(phi), r * np.cos(th) + 0 * phi], -1
    )
    front = np.array([0.0, 0.0, float(radius_of(np.array(0.0)))])
    back = np.array([0.0, 0.0, -float(radius_of(np.array(np.pi)))])
    return _closed_grid(front, rings, back)


def eyeball_profile(theta: np.ndarray) -> np.ndarray:
    """The eyeball's radius relative to its sphere at angle ``theta`` (rad) from the gaze axis.

    1 everywhere except over the iris, where the cornea bulges by up to 5 %.
    """
    theta = np.abs(np.asarray(theta, dtype=np.float64))
    bulge = CORNEA_BULGE * np.clip(np.cos(np.minimum(theta, np.pi) / IRIS_ANGLE * np.pi / 2), 0, None) ** 2
    return 1.0 + bulge * (theta < IRIS_ANGLE)


def eyeball(centre: np.ndarray, radius: float, s: float) -> Mesh:
    """An eyeball looking down +Z with sclera, iris and pupil colours and a slight cornea bulge."""
    cols = max(16, 4 * round(8 * s))
    front = np.concatenate(
        [
            np.linspace(0, PUPIL_ANGLE, max(2, round(2 * s)) + 1)[1:],
            np.linspace(PUPIL_ANGLE, IRIS_ANGLE, max(3, round(4 * s)) + 1)[1:],
        ]
    )
    back = np.linspace(IRIS_ANGLE, np.pi, max(8, round(12 * s)) + 1)[1:-1]
    angles = np.concatenate([front, back])

    v, f = _lathe(angles, lambda th: radius * eyeball_profile(th), cols)
    polar = np.arccos(np.clip(v[:, 2] / np.linalg.norm(v, axis=1), -1, 1))
    colors = np.where(
        (polar <= PUPIL_ANGLE + 1e-9)[:, None],
        PUPIL,
        np.where((polar <= IRIS_ANGLE + 1e-9)[:, None], IRIS, SCLERA),
    )
    ring = np.abs(polar - 0.75 * IRIS_ANGLE) < 0.5 * (IRIS_ANGLE - PUPIL_ANGLE)
    colors = np.where(ring[:, None], np.array(IRIS) * 1.25, colors)
    return Mesh(v + centre, f, colors=colors.astype(np.float32))


def _arch(width: float, depth: float, s: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Points (n, 2) in x-z of a dental arch from the left end to the right end, and unit normals."""
    a = np.linspace(-1, 1, n)
    x = width * np.sin(a * 1.25) / np.sin(1.25)
    z = -depth * (1 - np.cos(a * 1.35)) / (1 - np.cos(1.35))
    pts = np.column_stack([x, z])
    tangent = np.gradient(pts, axis=0)
    normal = np.column_stack([tangent[:, 1], -tangent[:, 0]])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    normal *= np.sign(normal[n // 2, 1])  # point forward (+z) at the front
    return pts, normal


def teeth(front: np.ndarray, upper: bool, s: float) -> Mesh:
    """A dental arch whose front incisal edge is at ``front`` (3,); a closed swept box."""
    n = max(24, 2 * round(24 * s))
    pts, nrm = _arch(2.15 if upper else 1.95, 2.8, s, n)
    thick, height = 0.65, 0.95
    a = np.linspace(-1, 1, n)
    tooth = 0.04 * np.abs(np.sin(a * np.pi * 8)) ** 0.3  # separations between teeth
    sign = 1.0 if upper else -1.0
    # cross-section: labial-top, labial-edge, lingual-edge, lingual-top (a closed loop of 4)
    section = [(0.0, sign * height), (0.0, 0.0), (-thick, 0.0), (-thick, sign * height)]
    rows = []
    for off, dy in section:
        xz = pts + nrm * (off + tooth)[:, None]
        rows.append(np.column_stack([xz[:, 0], np.full(n, dy), xz[:, 1]]))
    grid = np.stack(rows, axis=1).reshape(-1, 3)  # (n*4, 3): arch position major
    faces = _grid_faces(n, 4)
    cap = np.array([[0, 1, 2], [0, 2, 3]])
    faces = np.concatenate([faces, cap, (n - 1) * 4 + cap[:, ::-1]])
    if _signed_volume(grid, faces) < 0:
        faces = faces[:, ::-1]
    verts = grid + front
    # teeth TOOTH_COLUMNS columns wide with dark gaps, one gap on the midline: shaded by column, as
    # the notches above fall between columns at this resolution, too fine to shade the teeth apart
    d = np.abs(np.arange(n) - (n - 1) / 2)  # columns from the midline (0.5, 1.5, ...)
    crown = np.abs(np.sin(np.pi * d / TOOTH_COLUMNS))  # (n,) 0 at a gap, 1 mid-tooth
    section_shade = np.array([TOOTH_ROOT_SHADE, 1.0, 1.0, TOOTH_ROOT_SHADE])  # root, edge, edge, root
    shade = TOOTH_GAP_SHADE + (1 - TOOTH_GAP_SHADE) * crown[:, None] * section_shade  # (n, 4)
    colors = (shade.reshape(-1, 1) * np.array(TOOTH)).astype(np.float32)  # (n*4, 3), as ``grid``
    return Mesh(verts, faces, colors=colors)


def tongue(centre: np.ndarray, s: float) -> Mesh:
    """A flattened ellipsoid tongue centred at ``centre`` (3,), tip toward +Z."""
    cols = max(16, 4 * round(6 * s))
    angles = np.linspace(0, np.pi, max(10, round(12 * s)) + 1)[1:-1]
    v, f = _lathe(angles, lambda th: np.ones_like(th), cols)
    v = v * np.array([1.75, 0.6, 2.6])
    v[:, 1] += 0.2 * (1 - (v[:, 0] / 1.75) ** 2) * (v[:, 1] > 1e-9)
    return Mesh(v + centre, f, colors=np.tile(np.float32(TONGUE), (len(v), 1)))


def mouth_cavity(rim: np.ndarray, s: float) -> Mesh:
    """The mouth bag: a closed pocket whose first loop is ``rim`` (k, 3), the inner lip.

    The rim runs counter-clockwise seen from the front (as the skin's inner-lip ring); the
    bag's normals face away from the cavity, continuing the skin's outward orientation.
    """
    k = len(rim)
    loops = max(5, round(7 * s))
    centre = rim.mean(axis=0)
    t = np.arctan2(rim[:, 1] - centre[1], rim[:, 0] - centre[0])
    width = np.abs(rim[:, 0]).max()
    rows = [rim]
    for i in range(1, loops + 1):
        f = i / loops
        depth = 6.0 * f**0.9
        wx = width * (1.0 + 0.15 * np.sin(np.pi * min(f * 1.6, 1.0))) * (1 - 0.55 * f**2)
        hy = 0.4 + 1.9 * np.sin(np.pi * min(f * 1.3, 1.0) / 2) * (1 - 0.5 * f**2)
        rows.append(
            np.column_stack(
                [wx * np.cos(t), centre[1] - 0.4 * f + hy * np.sin(t), np.full(k, centre[2] - depth)]
            )
        )
    grid = np.concatenate(rows)
    body = _grid_faces(loops + 1, k)[:, ::-1]  # rim traversed opposite to the skin's
    back_centre = np.array([[0.0, centre[1] - 0.5, centre[2] - 6.3]])
    verts = np.concatenate([grid, back_centre])
    cap = _cap(len(verts) - 1, loops * k + np.arange(k), flip=False)
    faces = np.concatenate([body, cap])
    return Mesh(verts, faces, colors=np.tile(np.float32(MOUTH), (len(verts), 1)))


def ear(tragus: np.ndarray, side: float, s: float) -> Mesh:
    """An ear attached behind ``tragus`` (3,): helix rim, antihelix, concha, lobe; closed.

    ``side`` is +1 for the left ear (+X) and -1 for the right ear.
    """
    cols = max(24, 4 * round(10 * s))
    rows = max(8, round(10 * s))
    phi = 2 * np.pi * np.arange(cols) / cols  # 0 = front, π/2 = top
    rho = np.linspace(0, 1, rows + 1)[1:]
    P, R = np.meshgrid(phi, rho)
    sx = np.cos(P) * (1.55 - 0.2 * np.sin(P)) * np.where(np.sin(P) < 0, 1 + 0.35 * np.sin(P), 1.0)
    sy = np.sin(P) * np.where(np.sin(P) > 0, 3.1, 2.9)
    ex, ey = R * sx, R * sy
    helix = (
        0.42 * np.exp(-(((R - 0.9) / 0.1) ** 2)) * (1 - 0.6 * np.clip(np.cos(P), 0, 1) * (np.sin(P) < 0.3))
    )
    scapha = -0.18 * np.exp(-(((R - 0.72) / 0.08) ** 2)) * (np.sin(P) > -0.2)
    antihelix = 0.22 * np.exp(-(((R - 0.55) / 0.1) ** 2)) * (np.sin(P) > -0.5)
    concha = -0.65 * np.exp(-(((ex - 0.15) / 0.75) ** 2) - ((ey + 0.35) / 1.0) ** 2)
    lobe = 0.2 * np.exp(-(((ey + 2.2) / 0.6) ** 2))
    front_h = 0.35 + helix + scapha + antihelix + concha + lobe
    back_h = -0.35 * (1 - R**2) - 0.1
    front = np.stack([ex, ey, front_h], -1)  # (rows, cols, 3), inward to rim
    back = np.stack([ex, ey, back_h], -1)[:-1][::-1]  # from the rim back inward
    pole_f = np.array([0.0, 0.0, float(front_h[0].mean())])
    local, faces = _closed_grid(pole_f, np.concatenate([front, back]), np.array([0.0, 0.0, -0.45]))
    # local frame: x = forward along the head, y = up, h = outward; tilt the ear back 15°,
    # flare it 25° away from the head; its front edge sits at the tragus
    tilt, flare = np.radians(15), np.radians(22)
    fwd = np.array([0.0, 0.0, 1.0])
    up = np.array([0.0, 1.0, 0.0])
    out = np.array([side, 0.0, 0.0])
    up_t = np.cos(tilt) * up + np.sin(tilt) * (-fwd)
    fwd_t = np.cos(tilt) * fwd + np.sin(tilt) * up
    out_f = np.cos(flare) * out + np.sin(flare) * (-fwd_t)
    fwd_f = np.cross(up_t, out_f) * side
    world = (
        tragus + (local[:, 0:1] - 1.45) * fwd_f + (local[:, 1:2] - 0.2) * up_t + (local[:, 2:3] - 0.2) * out_f
    )
    if _signed_volume(world, faces) < 0:
        faces = faces[:, ::-1]
    return Mesh(world, faces)
