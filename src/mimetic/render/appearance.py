"""What each part of a mesh is, for drawing: eyeballs, lashes, teeth and see-through films.

A head from a file often carries parts that a plain shaded render gets wrong: transparent shells
over the eyes (an eye occlusion layer, a tear film) drawn as opaque caps, eyeballs without colours
drawn as blank skin-coloured balls, eyelash cards drawn as wide bands. ``surface`` decides, from the
mesh's colours, parts, materials and shape, which faces to draw and how to colour them; both
renderers draw exactly that ``Surface``, so they agree. The rules, in order:

1. Colours: ``mesh.colors`` when present; else ``albedo``, with each part's material colour
   (``Mesh.materials``) at its vertices. Colours from the file are never repainted, except the flat
   colour of an eyeball (rule 5).
2. Films: faces of a part whose material is transparent (opacity below 0.5) or whose name says it
   is a film over the eye (``FILM_WORDS``: occlusion, tear, lacrimal, cornea, ...) are not drawn.
3. Eyeballs: the pieces (connected components) of a part named as an eye (``EYE_WORDS``: eye,
   sclera, iris, pupil, but not a lid, brow or socket) or listed in ``eyes``; when no part is, the
   separate pieces that are balls of an eyeball's size (``EYEBALL_*``).
4. Separate pieces that no named part claims, near an eyeball: one lying on its surface is a film
   (not drawn); one growing out in front of it is a lash. Parts named as lashes are lashes too.
   Lashes are drawn dark (``LASH``, unless the file colours them) and only over the part of the
   card nearest the eyeball (``LASH_DRAWN_FRACTION``), as an alpha-textured card looks. Parts named
   as teeth are ``TOOTH``, and parts named as the mouth's cavity (``CAVITY_WORDS``) ``CAVITY``,
   where the file gives no colour.
5. An eyeball piece of one flat colour (no colour, or a light one from the file) gets a pupil, an
   iris with a darker rim, and a sclera (the file's light colour, else ``SCLERA``), around its gaze
   axis: world +Z (the face looks down +Z) through the centre of the sphere fitted to the piece,
   unless ``eyes`` gives the part's centre and axis (a rig's eye bones). The pattern is drawn per
   pixel from ``Surface.gaze_cos``, so the iris is round at any mesh resolution.

If all that would leave nothing to draw, every face is drawn. A part's name, for these rules, is
its part name and its material's name.
"""

from __future__ import annotations

import math
import re
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from mimetic.mesh.geometry import connected_components, face_normals, vertex_normals
from mimetic.mesh.model import Mesh

# The generated head's eyeball and tooth colours (``mimetic.head.parts``, which render cannot
# import: it sits below the head generator).
SCLERA = (0.93, 0.91, 0.87)
IRIS = (0.36, 0.22, 0.12)
LIMBUS_SHADE = 0.45
"""The limbal ring, the iris's outer rim, is the iris colour times this."""
PUPIL = (0.03, 0.03, 0.03)
TOOTH = (0.93, 0.91, 0.83)
CAVITY = (0.2, 0.05, 0.05)
"""The inside of the mouth: dark red, so an open mouth reads as a hole, not as skin."""
LASH = (0.08, 0.06, 0.05)
IRIS_ANGLE_RAD = 0.45
"""Angular radius of the iris seen from the eyeball's centre (a 5.2 mm iris radius on a 12 mm
eyeball; the outer 15 % of it is the darker limbal ring)."""
LIMBUS_ANGLE_RAD = 0.85 * IRIS_ANGLE_RAD
PUPIL_ANGLE_RAD = 0.16
NOT_EYE = -2.0
"""``Surface.gaze_cos`` of vertices that are not on a painted eyeball."""

FILM_WORDS = r"occlusion|lacrimal|tear|cornea|film|meniscus|wet|eye[\W_]*blend"
LASH_WORDS = r"lash"
IRIS_WORDS = r"iris|pupil"
TEETH_WORDS = r"teeth|tooth"
CAVITY_WORDS = r"mouth[\W_]*(socket|cavity|bag)|oral[\W_]*cavity"
EYE_WORDS = r"eye|sclera|iris|pupil"
NOT_EYE_WORDS = r"lid|brow|socket|bag|shadow|liner"
FLAT_COLOR_TOL = 0.02
"""Largest spread of a piece's colour channels that still counts as one flat colour."""
LIGHT_LUMINANCE = 0.5
"""A flat eyeball colour from the file at least this light is its sclera; a darker one is kept."""

# Measured on ICT-FaceKit: its eyeballs fit spheres within 4.5 % rms, spread 0.29; its tear lines
# and occlusion shells lie within 5 % of the eyeball's radius of its surface (median), spread 0.77
# to 0.91; its lash strips come within 3 % of the radius of the eyeball and reach 0.7 radii off it.
EYEBALL_MIN_VERTICES = 30
EYEBALL_RADIUS_REL = (0.015, 0.1)
"""An eyeball's radius, as a fraction of the mesh's largest extent (about 0.05 on a head)."""
EYEBALL_RMS_REL = 0.08
"""Largest rms distance of an eyeball's vertices from its fitted sphere, × its radius."""
EYEBALL_SPREAD_MAX = 0.5
"""Largest norm of the mean direction of a ball's vertices from its centre (0 for a whole sphere,
about 0.5 for a hemisphere): a shell or cap over part of a sphere is not an eyeball."""
FILM_GAP_REL = 0.1
"""A piece whose vertices lie within this × the radius of an eyeball's surface (median) is a film."""
LASH_REACH_REL = 0.25
"""A lash comes within this × the eyeball radius of its surface, ..."""
LASH_EXTENT_REL = 3.0
"""... is at most this × the radius long, and lies in front of the eyeball's centre."""
WELD_MAX_ANGLE_RAD = math.radians(60)
"""Vertices of a part at one position are welded (``Surface.weld``) when their own normals are
within this angle: both sides of a UV seam are; the upper and lower lips, or lids, that touch at
rest are not (about 180° apart), and welding them streaked the lips."""
LASH_DRAWN_FRACTION = 0.4
"""The part of a lash card drawn: from its root to this fraction of its height off the eyeball."""


@dataclass(frozen=True, eq=False)
class Surface:
    """What to draw of a mesh, per vertex and face, so it stays valid when the mesh deforms.

    Attributes
    ----------
    faces : (k,) int64
        Indices of the faces to draw, sorted.
    colors : (n, 3) float64
        Albedo of every vertex, in [0, 1] (the sclera's on a painted eyeball).
    gaze_cos : (n,) float64
        On a painted eyeball, the cosine of the angle between the vertex and the gaze axis seen
        from the eyeball's centre; ``NOT_EYE`` elsewhere. A pixel whose interpolated value is at
        least cos ``PUPIL_ANGLE_RAD`` is ``PUPIL``, cos ``LIMBUS_ANGLE_RAD`` the iris colour, cos
        ``IRIS_ANGLE_RAD`` the iris colour times ``LIMBUS_SHADE`` (see ``eye_albedo``).
    cover : (n,) float64
        A pixel whose interpolated cover is below 0.5 is not drawn (the tips of lash cards); 1 on
        everything else.
    iris_colors : (n, 3) float64
        The iris colour of painted eyeballs (a flat iris part's colour from the file, else ``IRIS``).
    weld : (n,) int64
        For each vertex, the first vertex of its part at its rest position (itself, mostly):
        vertices of one part at one position share one normal (``shading_normals``), so a mesh
        split at its UV seams, as glTF files are, shades smoothly across them. Parts that meet,
        and surfaces that touch (``WELD_MAX_ANGLE_RAD``), keep their own normals.
    """

    faces: np.ndarray
    colors: np.ndarray
    gaze_cos: np.ndarray
    cover: np.ndarray
    iris_colors: np.ndarray
    weld: np.ndarray

    def check(self, mesh: Mesh) -> None:
        """Raise ``ValueError`` unless this surface was made for a mesh of ``mesh``'s shape."""
        n, m = mesh.n_vertices, mesh.n_faces
        shapes = (
            self.colors.shape,
            self.gaze_cos.shape,
            self.cover.shape,
            self.iris_colors.shape,
            self.weld.shape,
        )
        if shapes != ((n, 3), (n,), (n,), (n, 3), (n,)) or (len(self.faces) and (self.faces.max() >= m)):
            raise ValueError(
                f"this Surface was made for another mesh (colors {self.colors.shape}, faces up to "
                f"{int(self.faces.max()) if len(self.faces) else -1}); the mesh has {n} vertices and {m} "
                "faces. Make it with surface(mesh, albedo) for this mesh or its rest pose."
            )


def part_kind(name: str, material_name: str | None = None) -> str | None:
    """A part's kind from its name and its material's name: "film", "lash", "teeth", "cavity", "eye"
    or None."""
    text = f"{name} {material_name or ''}".lower()
    if re.search(FILM_WORDS, text):
        return "film"
    if re.search(LASH_WORDS, text):
        return "lash"
    if re.search(TEETH_WORDS, text):
        return "teeth"
    if re.search(CAVITY_WORDS, text):
        return "cavity"
    if re.search(EYE_WORDS, text) and not re.search(NOT_EYE_WORDS, text):
        return "eye"
    return None


def shading_normals(vertices: np.ndarray, faces: np.ndarray, weld: np.ndarray) -> np.ndarray:
    """Area-weighted unit normals (n, 3) float64 of ``vertices`` (n, 3) over the drawn ``faces``
    (k, 3), summed over each group of vertices that ``weld`` (n,) (``Surface.weld``) joins; (0, 0, 0)
    where no drawn face touches the group."""
    fn = face_normals(vertices, faces, unit=False)  # (k, 3), |fn| = 2 area
    corner = weld[faces].ravel()  # (3k,) the group of each corner
    out = np.stack([np.bincount(corner, np.repeat(fn[:, d], 3), len(vertices)) for d in range(3)], axis=1)
    out = out[weld]  # (n, 3) each vertex takes its group's sum
    length = np.linalg.norm(out, axis=1, keepdims=True)
    return out / np.where(length > 0, length, 1.0)


def eye_albedo(gaze_cos: np.ndarray, sclera: np.ndarray, iris: np.ndarray) -> np.ndarray:
    """Albedo (k, 3) float64 of eyeball samples from their ``gaze_cos`` (k,) (see ``Surface``),
    sclera and iris colours (k, 3): pupil, iris, limbal ring, then sclera, by angle from the gaze
    axis. The GL fragment shader does the same."""
    out = np.array(sclera, dtype=np.float64, copy=True)
    ring = gaze_cos >= math.cos(IRIS_ANGLE_RAD)
    out[ring] = LIMBUS_SHADE * iris[ring]
    inner = gaze_cos >= math.cos(LIMBUS_ANGLE_RAD)
    out[inner] = iris[inner]
    out[gaze_cos >= math.cos(PUPIL_ANGLE_RAD)] = PUPIL
    return out


def sphere_centre(points: np.ndarray) -> np.ndarray:
    """Centre (3,) of the sphere best fitting ``points`` (k, 3) (algebraic least squares), or the
    centre of their bounding box when they are not round (residual over 20 % of the radius)."""
    p = np.asarray(points, dtype=np.float64)
    box_centre = (p.min(axis=0) + p.max(axis=0)) / 2
    if len(p) < 4:
        return box_centre
    shift = p - box_centre  # better conditioned
    a = np.column_stack([2 * shift, np.ones(len(p))])  # |x|^2 = 2 c.x + (r^2 - |c|^2)
    solution, *_ = np.linalg.lstsq(a, np.einsum("kd,kd->k", shift, shift), rcond=None)
    c = solution[:3]
    r2 = solution[3] + c @ c
    if not (np.isfinite(r2) and r2 > 0):
        return box_centre
    r = np.sqrt(r2)
    residual = np.sqrt(np.mean((np.linalg.norm(shift - c, axis=1) - r) ** 2))
    return c + box_centre if residual <= 0.2 * r else box_centre


def _luminance(rgb: np.ndarray) -> float:
    return float(np.dot(rgb, (0.2126, 0.7152, 0.0722)))


@dataclass(frozen=True, eq=False)
class _Ball:
    """An eyeball piece: its vertices (k,) int64, centre (3,), outer radius, unit gaze axis (3,), and
    whether its part is named as an iris (or pupil)."""

    vertices: np.ndarray
    centre: np.ndarray
    radius: float
    axis: np.ndarray
    iris: bool = False

    @staticmethod
    def of(vertices: np.ndarray, points: np.ndarray, centre, axis, iris: bool = False) -> _Ball:
        centre = sphere_centre(points) if centre is None else np.asarray(centre, dtype=np.float64)
        radius = float(np.percentile(np.linalg.norm(points - centre, axis=1), 95))
        axis = np.asarray(axis, dtype=np.float64)
        return _Ball(vertices, centre, max(radius, 1e-300), axis / np.linalg.norm(axis), iris)

    def height(self, points: np.ndarray) -> np.ndarray:
        """Distance (k,) of ``points`` (k, 3) off this ball's surface, × its radius."""
        return np.linalg.norm(points - self.centre, axis=1) / self.radius - 1.0


def _is_eyeball(points: np.ndarray, extent: float) -> bool:
    """Whether a separate piece's points (k, 3) form a ball of an eyeball's size (see ``EYEBALL_*``)."""
    if len(points) < EYEBALL_MIN_VERTICES:
        return False
    rel = points - sphere_centre(points)
    d = np.linalg.norm(rel, axis=1)
    r = float(d.mean())
    if not (EYEBALL_RADIUS_REL[0] * extent <= r <= EYEBALL_RADIUS_REL[1] * extent):
        return False
    rms = float(np.sqrt(np.mean((d - r) ** 2)))
    spread = float(np.linalg.norm((rel / np.maximum(d, 1e-300)[:, None]).mean(axis=0)))
    return rms <= EYEBALL_RMS_REL * r and spread <= EYEBALL_SPREAD_MAX


def _nearest_ball(points: np.ndarray, balls: list[_Ball]) -> tuple[_Ball, np.ndarray]:
    """The ball whose surface ``points`` (k, 3) come closest to, and their heights (k,) off it."""
    heights = [ball.height(points) for ball in balls]
    k = int(np.argmin([h.min() for h in heights]))
    return balls[k], heights[k]


def _piece_kind(points: np.ndarray, balls: list[_Ball]) -> str | None:
    """The kind of a separate piece (points (k, 3)) near the eyeballs: "film", "lash" or None."""
    low, high = points.min(axis=0), points.max(axis=0)
    centre, half = (low + high) / 2, float(np.linalg.norm(high - low)) / 2
    reach = 1.0 + max(FILM_GAP_REL, LASH_REACH_REL)
    balls = [b for b in balls if np.linalg.norm(centre - b.centre) - half <= reach * b.radius]
    if not balls:
        return None  # no vertex comes near an eyeball
    if min(float(np.median(np.abs(ball.height(points)))) for ball in balls) <= FILM_GAP_REL:
        return "film"
    ball, height = _nearest_ball(points, balls)
    ahead = float(((points - ball.centre) @ ball.axis).mean()) > 0
    if (
        height.min() <= LASH_REACH_REL
        and ahead
        and np.ptp(points, axis=0).max() <= LASH_EXTENT_REL * ball.radius
    ):
        return "lash"
    return None


def _groups(label: np.ndarray, ids: np.ndarray) -> list[np.ndarray]:
    """``ids`` (k,) split by their ``label`` (k,), in label order."""
    order = np.argsort(label, kind="stable")
    cuts = np.flatnonzero(np.diff(label[order])) + 1
    return np.split(ids[order], cuts) if len(ids) else []


def surface(
    mesh: Mesh,
    albedo: tuple[float, float, float] | np.ndarray,
    *,
    eyes: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None,
) -> Surface:
    """What to draw of ``mesh`` and in which colours (see the module docstring).

    Parameters
    ----------
    mesh : Mesh
    albedo : (3,) float in [0, 1]
        The colour of vertices the mesh does not colour (skin).
    eyes : part name → (centre (3,), gaze axis (3,)), optional
        Eyeball parts with a known centre and gaze (a rig's eye bones); these parts are eyes
        whatever their names.

    Returns
    -------
    Surface, valid for ``mesh`` and any deformation of it that keeps its faces (the eyeballs'
    pattern and the lashes' cover ride on their vertices).
    """
    n, m = mesh.n_vertices, mesh.n_faces
    v, f = mesh.vertices, mesh.faces
    albedo = np.asarray(albedo, dtype=np.float64).reshape(3)
    eyes = dict(eyes or {})
    kinds = {}
    for name in mesh.parts:
        material = mesh.materials.get(name)
        kinds[name] = "eye" if name in eyes else part_kind(name, material.name if material else None)

    # 1. colours, and which of them the file gave
    if mesh.colors is not None:
        colors = mesh.colors.astype(np.float64)
        given = np.ones(n, dtype=bool)
    else:
        colors = np.tile(albedo, (n, 1))
        total, count = np.zeros((n, 3)), np.zeros(n)
        for name, material in mesh.materials.items():
            if material.color is not None and not material.transparent:
                corners = f[mesh.parts[name]].ravel()
                np.add.at(total, corners, material.color)
                np.add.at(count, corners, 1.0)
        given = count > 0
        colors[given] = total[given] / count[given, None]
    gaze_cos = np.full(n, NOT_EYE)
    cover = np.ones(n)
    part_of = np.full(n, -1.0)  # (n,) a part holding the vertex (the last listed), -1 for none
    for k, ids in enumerate(mesh.parts.values()):
        part_of[f[ids].ravel()] = k
    key = np.column_stack([v, part_of])  # a part's seam is welded; two parts that meet are not
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    weld = first[inverse.reshape(-1)].astype(np.int64)  # (n,) the part's first vertex at each position
    own = vertex_normals(v, f)  # (n, 3) each vertex's normal before welding
    apart = np.einsum("nd,nd->n", own, own[weld]) < math.cos(WELD_MAX_ANGLE_RAD)  # lips that touch
    weld[apart] = np.flatnonzero(apart)
    if m == 0:
        return Surface(np.zeros(0, np.int64), colors, gaze_cos, cover, np.tile(IRIS, (n, 1)), weld)

    # 2. films named or transparent are not drawn
    drawn = np.ones(m, dtype=bool)
    named = np.zeros(m, dtype=bool)  # faces of a part whose name or material says what it is
    for name, ids in mesh.parts.items():
        material = mesh.materials.get(name)
        named[ids] |= kinds[name] is not None or material is not None
        if kinds[name] == "film" or (material is not None and material.transparent):
            drawn[ids] = False

    # 3. the eyeballs: named parts, else separate balls of an eyeball's size
    _, label = connected_components(f, n)
    balls: list[_Ball] = []
    for name, ids in mesh.parts.items():
        if kinds[name] == "eye":
            used = np.unique(f[ids[drawn[ids]]])
            centre, axis = eyes.get(name, (None, (0.0, 0.0, 1.0)))
            material = mesh.materials.get(name)
            iris = bool(re.search(IRIS_WORDS, f"{name} {material.name if material else ''}".lower()))
            balls += [_Ball.of(piece, v[piece], centre, axis, iris) for piece in _groups(label[used], used)]
    face_label = label[f[:, 0]]
    sizes = np.bincount(face_label)
    claimed = np.bincount(face_label[named], minlength=len(sizes))  # named faces per component
    separate = (sizes > 0) & (claimed == 0)
    separate[np.argmax(sizes)] = False
    pieces = [p for p in _groups(face_label, np.arange(m)) if separate[face_label[p[0]]]]  # face ids
    if not balls:
        extent = float(np.ptp(v, axis=0).max())
        for faces in list(pieces):
            used = np.unique(f[faces])
            if _is_eyeball(v[used], extent):
                balls.append(_Ball.of(used, v[used], None, (0.0, 0.0, 1.0)))
                pieces = [p for p in pieces if p is not faces]

    # 4. unnamed pieces on an eyeball are films, pieces growing out in front of it lashes
    lash_faces = [ids for name, ids in mesh.parts.items() if kinds[name] == "lash"]
    if balls:
        for faces in pieces:
            kind = _piece_kind(v[np.unique(f[faces])], balls)
            if kind == "film":
                drawn[faces] = False
            elif kind == "lash":
                lash_faces.append(faces)
    lash = np.zeros(n, dtype=bool)
    for faces in lash_faces:
        used = np.unique(f[faces[drawn[faces]]])
        lash[used] = True
        for piece in _groups(label[used], used) if balls else []:
            _, height = _nearest_ball(v[piece], balls)
            span = max(float(np.ptp(height)), 1e-12)
            cover[piece] = np.clip(1.0 - (height - height.min()) / (2 * LASH_DRAWN_FRACTION * span), 0.0, 1.0)
    colors[lash & ~given] = LASH
    for name, ids in mesh.parts.items():
        if kinds[name] in ("teeth", "cavity"):
            used = np.unique(f[ids])
            colors[used[~given[used]]] = TOOTH if kinds[name] == "teeth" else CAVITY

    # 5. eyeballs of one flat colour get a pupil, an iris and a sclera; a flat iris part from the
    # file (named so, or dark) keeps its colour and lends it to the iris painted on its eyeball
    iris_colors = np.tile(np.asarray(IRIS, dtype=np.float64), (n, 1))
    paint, lenders = [], []
    for ball in balls:
        flat = colors[ball.vertices]
        if np.ptp(flat, axis=0).max() > FLAT_COLOR_TOL:
            continue  # the file painted this eyeball
        color = flat.mean(axis=0)
        if given[ball.vertices].all() and (ball.iris or _luminance(color) < LIGHT_LUMINANCE):
            lenders.append((ball, color))
        else:
            paint.append((ball, color if given[ball.vertices].all() else np.asarray(SCLERA)))
    for ball, sclera in paint:
        near = [
            c for lender, c in lenders if np.linalg.norm(lender.centre - ball.centre) <= 0.3 * ball.radius
        ]
        colors[ball.vertices] = sclera
        iris_colors[ball.vertices] = near[0] if near else IRIS
        rel = v[ball.vertices] - ball.centre
        gaze_cos[ball.vertices] = (rel @ ball.axis) / np.maximum(np.linalg.norm(rel, axis=1), 1e-300)

    if not drawn.any():
        drawn[:] = True  # nothing but films: draw them rather than nothing
    return Surface(np.flatnonzero(drawn), colors, gaze_cos, cover, iris_colors, weld)
