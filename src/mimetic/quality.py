"""Motion quality: numbers that say whether a rig moves like a face (issue 11).

Pure measurements over rest and posed vertex arrays, rigs and engines; nothing here changes how a
rig deforms. ``benchmarks/bench_quality.py`` prints them per head and engine; the tests in
``tests/test_quality.py`` check each on synthetic cases with known answers.

Definitions (lengths in rig units, ``Rig.units``; the issue's targets are in cm):

* **Edge stretch** (``edge_stretch``): for every unique edge of a face set, ``posed length / rest
  length``; its 99th percentile (numpy's linear interpolation) is the *stretch p99*. The *widest
  opening* is the largest ``posed length − rest length`` of one edge. Which faces count is the
  caller's choice (the benchmark uses ICT's "Face" part on ICT's topology, the front skin of a
  generated head, and the MediaPipe mask without the triangles that close its mouth slit and eyes).
* **Chin drop** (``chin_drop``): how far a chin point (a surface point; the rig's ``menton``
  landmark unless given) moves. The *ICT-matched jaw opening* (``matched_jaw_open``) is the
  ``jaw_open`` value, all other channels at their defaults, whose chin drop equals a target: ICT's
  own ``jawOpen`` shape moves ICT's menton vertex (iBUG point 8) 4.05 cm; on a head of ICT's
  topology the target is that shape's drop at that vertex on the same head, on any other head
  ``ICT_JAW_DROP_REL`` times the rig's head height (``Rig.scale``) at the rig's menton. Found by
  bracketed root finding (Brent's method, ``scipy.optimize.brentq``) on the engine itself.
* **Lip flips** (``triangle_flips`` over ``lip_faces``): triangles of the face set whose three
  vertices lie in the ``upper_lip`` and ``lower_lip`` regions and whose normal turns by more than
  90° from its rest direction (negative dot product). Triangles without area at rest never count.
* **Upper lip follows the jaw** (``upper_lip_follow``): under ``jaw_open`` alone, the mean
  displacement of the upper-lip vertices farther than a quarter of the mouth width from both
  mouth corners, divided by the same mean over the lower lip. 0: the upper lip stays; 1: it
  moves with the jaw. (ICT's own ``jawOpen`` scores 0.10: a real upper lip moves a little.)
* **Lid margins** (``find_lid_margins``): per eye, an eye frame from the rest mesh: origin at the
  inner eye corner, ``u`` along the chord to the outer corner (``width`` = its length), ``w`` the
  gaze (the eye bone's axis, made orthogonal to ``u``), ``v = w × u`` (up). The opening between the
  lids is found from the skin's own geometry near the corner landmarks (``mimetic.mesh.openings``:
  seen from the front, the lids' silhouettes bound it), not from the rig's regions or weights; the
  margins are the skin's rim vertices along its top and bottom edges (within two of its grid steps,
  ``MARGIN_TOLERANCE``), with ``u`` between 15 % and 85 % of the chord, ordered by ``u``. Without an
  opening (MediaPipe's mask, whose eyes are closed by faces) the mesh has no real lids (``bridged``)
  and gaps are not measured.
* **Lid gap** (``margin_gap``, ``lid_gap``): the posed margins projected on the eye frame's
  (u, v) plane, each sorted by ``u`` and interpolated linearly on 33 common ``u`` values over the
  range both cover; gap = ``v(upper) − v(lower)`` per column. Negative: the upper margin is below
  the lower one (the margins *cross*). The targets: with both upper lids at their maximum, the
  largest gap ≤ 0.1 cm and none negative.
* **Seen opening** (``seen_opening``, ``seen_eyeball``): the lids as a render shows them. Rays
  along −Z on a grid of 1 % of the corners' distance over the middle 70 % of their x range; a ray
  sees the eyeball (the rig's ``eye_<side>`` part, its surface: at least 0.9 of the eye bone's
  radius from its centre) where it hits it before the skin (the largest connected piece: lashes and
  see-through films do not hide it); per grid column the height seen.
  The margins above follow vertices: where the upper lid's rim is found over only part of the eye,
  or its rows fold past each other, the margins can meet while the eyeball shows (ICT identity s126
  σ 2's left eye: margins 0.08 cm apart, 0.79 cm of eyeball seen), and a lower margin found on a
  lid's inner roll can stay 0.1-0.27 cm below an upper lid that hides the eye (the generated heads).
  Target: at the lids' maximum, nothing over 0.1 cm seen in any column.
* **Margin roughness** (``margin_roughness``, ``lid_roughness``): the RMS distance of the upper
  margin's points (eye frame, without its first and last column, which can turn sharply into the
  corners) from least-squares polynomials of degree 4 in their rest ``u`` fitted to their ``v`` and
  ``w``, divided by the lid width. A smooth arc scores about 0; a sawtooth of amplitude ``a`` about
  ``a / width``. Measured on the upper margin of a wink and, as the baseline, at rest.
* **Implied weights** (``implied_weights``): how far each vertex of a captured shape follows a
  bone's motion: ``clip(d · r / |r|², 0, 1)`` for the captured offset ``d`` and the offset ``r`` the
  bone's rigid motion gives the vertex (``rigid_motion``: Kabsch on points that move rigidly, such as
  the lower teeth in a jaw opening). The weight an artist would paint there; compared with a rig's
  skin weights as the mean absolute difference over the vertices (the Maskle paper's metric).
* **Expression fidelity** (``expression_fidelity``): per target shape, bounded least squares of
  the channel activations on a baked basis (``mimetic.capture.prepare_solver``: the channel ranges
  as bounds, regularization 1e-3), then ``‖fit − target‖ / ‖target‖`` (Frobenius norms of the
  offsets from the neutral) over the chosen vertices; median and worst over the shapes.

Over 600 lines because each measure is short but they share their regions, openings and baked
basis; split, every module would rebuild them.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from mimetic.engines.basis import Basis
from mimetic.errors import MimeticWarning
from mimetic.mesh.geometry import edges_unique, face_normals
from mimetic.mesh.model import SurfacePoint
from mimetic.mesh.openings import EYE_STEP_REL, eye_opening, eyeball, margin_seeds, seen_eye, skin_faces
from mimetic.rig.anatomy.lids import eye_frame
from mimetic.rig.model import Channel, Rig

log = logging.getLogger(__name__)

__all__ = [
    "ICT_JAW_DROP_CM",
    "ICT_JAW_DROP_REL",
    "EdgeStretch",
    "Fidelity",
    "JawMatch",
    "LidGap",
    "LidMargins",
    "LipFollow",
    "chin_drop",
    "closed_lids_pose",
    "edge_stretch",
    "expression_fidelity",
    "find_lid_margins",
    "implied_weights",
    "lid_gap",
    "lid_roughness",
    "lip_faces",
    "margin_gap",
    "margin_roughness",
    "matched_jaw_open",
    "most_eyeball_seen",
    "rigid_motion",
    "seen_eyeball",
    "seen_opening",
    "triangle_flips",
    "upper_lip_follow",
]

ICT_JAW_DROP_CM = 4.047
"""How far ICT-FaceKit's ``jawOpen`` shape moves its menton (iBUG point 8, vertex 966), cm."""

ICT_JAW_DROP_REL = 0.178
"""``ICT_JAW_DROP_CM`` over the head height (``Rig.scale``, 22.76 cm) of ICT's neutral rigged from its
file landmarks: the chin drop to match on heads of another topology, as a fraction of their head
height. The benchmark measures it afresh when the shared data is there."""

STRETCH_PERCENTILE = 99.0
CORNER_SHARE = 0.25
"""Lip vertices closer than this fraction of the mouth width to a mouth corner are not compared."""
MARGIN_SPAN = (0.15, 0.85)
"""The part of the eye-corner chord (fractions from the inner corner) where margins are compared."""
MARGIN_TOLERANCE = 2.0
"""A margin vertex lies within this many grid steps of the opening's edge (``mimetic.mesh.openings``)."""
GAP_SAMPLES = 33
SEEN_STEP_REL = 0.01
"""The grid step (× the eye corners' distance) at which ``seen_opening`` looks at an eye."""
ROUGHNESS_DEGREE = 4
MIN_ROUGHNESS_POINTS = 7


# --------------------------------------------------------------------------- edges and triangles


@dataclass(frozen=True)
class EdgeStretch:
    """How the edges of a face set change length from rest to a pose.

    Attributes
    ----------
    edges : (e, 2) int64
        Unique undirected edges (sorted pairs) with a rest length above zero.
    ratio : (e,) float64
        Posed length / rest length.
    opening : (e,) float64
        Posed length − rest length, rig units (negative: the edge got shorter).
    p99 : float
        The ``percentile``-th percentile of ``ratio`` (99 by default).
    widest : float
        ``opening.max()``, rig units: how far the most-opened edge opened.
    widest_edge : (2,) int64
        The vertex pair of that edge.
    """

    edges: np.ndarray
    ratio: np.ndarray
    opening: np.ndarray
    p99: float
    widest: float
    widest_edge: np.ndarray


def edge_stretch(
    rest: np.ndarray, posed: np.ndarray, faces: np.ndarray, *, percentile: float = STRETCH_PERCENTILE
) -> EdgeStretch:
    """Edge stretch ratios and openings of ``faces`` between two poses.

    Parameters
    ----------
    rest, posed : (n, 3) float64
        Vertex positions, rig units, the same vertex order.
    faces : (m, 3) int
        The face set whose edges count (each unique edge once).
    percentile : float
        Which percentile of the ratios is reported as ``p99``.

    Returns
    -------
    EdgeStretch
    """
    edges = edges_unique(np.asarray(faces, dtype=np.int64))  # (e, 2)
    before = np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)  # (e,)
    keep = before > 0
    edges, before = edges[keep], before[keep]
    after = np.linalg.norm(posed[edges[:, 0]] - posed[edges[:, 1]], axis=1)
    ratio, opening = after / before, after - before
    widest = int(np.argmax(opening))
    return EdgeStretch(
        edges,
        ratio,
        opening,
        float(np.percentile(ratio, percentile)),
        float(opening[widest]),
        edges[widest].copy(),
    )


def triangle_flips(rest: np.ndarray, posed: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Which triangles turned their normal by more than 90° from rest.

    Parameters
    ----------
    rest, posed : (n, 3) float64
    faces : (m, 3) int

    Returns
    -------
    flipped : (m,) bool
        ``n_rest · n_posed < 0``; a triangle without area at rest is never flipped.
    """
    faces = np.asarray(faces, dtype=np.int64)
    before = face_normals(rest, faces, unit=False)  # (m, 3), length = 2 area
    after = face_normals(posed, faces, unit=False)
    has_area = np.linalg.norm(before, axis=1) > 0
    return has_area & (np.einsum("md,md->m", before, after) < 0)


def lip_faces(rig: Rig, faces: np.ndarray) -> np.ndarray:
    """The rows (k, 3) of ``faces`` (m, 3) whose three vertices lie in ``upper_lip`` ∪ ``lower_lip``."""
    lips = np.zeros(rig.n_vertices, dtype=bool)
    for name in ("upper_lip", "lower_lip"):
        lips[rig.regions[name]] = True
    faces = np.asarray(faces, dtype=np.int64)
    return faces[lips[faces].all(axis=1)]


def lip_gap(rig: Rig, posed: np.ndarray) -> float:
    """The distance between the inner lips' midpoints (the landmarks ``upper_lip_inner`` and
    ``lower_lip_inner`` on the posed vertices (n, 3)), rig units: about 0.4 % of the head height
    when the lips are pressed shut."""
    points = [rig.landmarks[n] for n in ("upper_lip_inner", "lower_lip_inner")]
    upper, lower = (p.position(posed, rig.mesh.faces) for p in points)
    return float(np.linalg.norm(upper - lower))


# --------------------------------------------------------------------------- the jaw


def chin_drop(rig: Rig, rest: np.ndarray, posed: np.ndarray, *, chin: SurfacePoint | None = None) -> float:
    """Distance (rig units) the chin point moves from ``rest`` (n, 3) to ``posed`` (n, 3).

    ``chin`` is a surface point of ``rig.mesh``; the rig's ``menton`` landmark by default (on ICT's
    topology the benchmark passes ICT's own menton vertex, iBUG point 8).
    """
    point = rig.landmarks["menton"] if chin is None else chin
    faces = rig.mesh.faces
    return float(np.linalg.norm(point.position(posed, faces) - point.position(rest, faces)))


@dataclass(frozen=True)
class JawMatch:
    """The ``jaw_open`` value whose chin drop matches a target.

    Attributes
    ----------
    value : float
        ``jaw_open`` in radians; the channel's maximum when the target is out of reach.
    drop, target : float
        The chin drop reached and the one asked for, rig units.
    reached : bool
        False when even the channel's maximum drops the chin less than ``target``.
    vertices : (n, 3) float64
        The engine's vertices at ``value`` (all other channels at their defaults).
    evaluations : int
        Engine evaluations spent.
    """

    value: float
    drop: float
    target: float
    reached: bool
    vertices: np.ndarray
    evaluations: int


def matched_jaw_open(
    engine, target: float, *, chin: SurfacePoint | None = None, xtol_rad: float = 1e-4
) -> JawMatch:
    """Find the ``jaw_open`` value whose chin drop (``chin_drop``) equals ``target`` on ``engine``.

    Parameters
    ----------
    engine : mimetic.engines.Engine
        Any engine; only ``jaw_open`` moves, every other channel stays at its default.
    target : float
        Chin drop to match, rig units (e.g. ``ICT_JAW_DROP_REL * rig.scale``).
    chin : SurfacePoint, optional
        Where the drop is measured (``chin_drop``); the rig's ``menton`` landmark by default.
    xtol_rad : float
        Tolerance on the angle (Brent's bracketed method between 0 and the channel's maximum,
        ``scipy.optimize.brentq``; the drop grows with the angle).

    Returns
    -------
    JawMatch
    """
    from scipy.optimize import brentq

    rig = engine.rig
    base = np.array([c.default for c in rig.channels], dtype=np.float64)
    j = rig.channel_index("jaw_open")
    rest = engine.deform(base)
    count = [1]

    def drop_at(angle: float) -> tuple[float, np.ndarray]:
        values = base.copy()
        values[j] = angle
        vertices = engine.deform(values)
        count[0] += 1
        return chin_drop(rig, rest, vertices, chin=chin), vertices

    top = rig.channels[j].maximum
    reach, vertices = drop_at(top)
    if reach < target:
        return JawMatch(top, reach, float(target), False, vertices, count[0])
    angle = brentq(lambda a: drop_at(a)[0] - target, 0.0, top, xtol=xtol_rad)
    drop, vertices = drop_at(angle)
    return JawMatch(float(angle), drop, float(target), True, vertices, count[0])


@dataclass(frozen=True)
class LipFollow:
    """How much the upper lip moves with the jaw, against the lower lip.

    Attributes
    ----------
    ratio : float
        ``upper_mean / lower_mean``: 0 when the upper lip stays, 1 when it moves as the lower lip.
    upper_mean, lower_mean : float
        Mean displacement (rig units) of the compared upper- and lower-lip vertices.
    upper_max, upper_p99 : float
        Largest and 99th-percentile displacement of the compared upper-lip vertices, rig units.
    upper, lower : (k,) int64
        The compared vertices: the lip regions' vertices (within ``vertices`` when given) farther
        than ``corner_share`` of the mouth width from both mouth corners.
    """

    ratio: float
    upper_mean: float
    lower_mean: float
    upper_max: float
    upper_p99: float
    upper: np.ndarray
    lower: np.ndarray


def upper_lip_follow(
    rig: Rig,
    rest: np.ndarray,
    posed: np.ndarray,
    *,
    vertices: np.ndarray | None = None,
    corner_share: float = CORNER_SHARE,
) -> LipFollow:
    """Upper-lip displacement relative to the lower lip's between ``rest`` and ``posed`` (n, 3).

    Meant for ``jaw_open`` alone (``matched_jaw_open``) or a jaw-opening shape such as ICT's
    ``jawOpen`` (``posed = rest + delta``). ``vertices`` (k,) restricts the compared vertices (e.g.
    to the visible face, leaving out a mouth socket the regions reach into).
    """
    corners = rig.landmark_positions(["mouth_corner_L", "mouth_corner_R"])  # (2, 3)
    width = float(np.linalg.norm(corners[0] - corners[1]))
    allowed = np.ones(rig.n_vertices, dtype=bool)
    if vertices is not None:
        allowed[:] = False
        allowed[np.asarray(vertices, dtype=np.int64)] = True

    def chosen(region: str) -> np.ndarray:
        ids = rig.regions[region]
        ids = ids[allowed[ids]]
        distance = np.linalg.norm(rest[ids, None] - corners[None], axis=2).min(axis=1)  # (k,)
        return ids[distance > corner_share * width]

    upper, lower = chosen("upper_lip"), chosen("lower_lip")
    move_upper = np.linalg.norm(posed[upper] - rest[upper], axis=1)
    move_lower = np.linalg.norm(posed[lower] - rest[lower], axis=1)
    lower_mean = float(move_lower.mean())
    upper_mean = float(move_upper.mean())
    ratio = upper_mean / lower_mean if lower_mean > 0 else float("nan")
    return LipFollow(
        ratio,
        upper_mean,
        lower_mean,
        float(move_upper.max()),
        float(np.percentile(move_upper, 99)),
        upper,
        lower,
    )


# --------------------------------------------------------------------------- the lids


@dataclass(frozen=True)
class LidMargins:
    """The upper and lower lid margins of one eye, found on the rest mesh (see the module docstring).

    Attributes
    ----------
    side : "L" | "R"
    upper, lower : (k,) int64, (j,) int64
        Margin vertices, one per column, ordered from the inner to the outer corner.
    origin : (3,) float64
        The inner eye corner, rig units.
    axes : (3, 3) float64
        Rows ``u`` (inner → outer corner), ``v`` (up), ``w`` (gaze), orthonormal.
    width : float
        Distance between the eye corners, rig units.
    bridged : bool
        The upper and lower margins share a triangle: the opening is closed by faces, the mesh
        has no real lids (gap and roughness are then not measured).
    reason : str
        Why the margins are not usable ("" when they are).
    upper_u : (k,) float64
        The rest ``u`` of each upper margin vertex (the column parameter of ``lid_roughness``).
    """

    side: str
    upper: np.ndarray
    lower: np.ndarray
    origin: np.ndarray
    axes: np.ndarray
    width: float
    bridged: bool
    reason: str = ""
    upper_u: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @property
    def usable(self) -> bool:
        return not self.reason

    def project(self, vertices: np.ndarray, ids: np.ndarray) -> np.ndarray:
        """Positions (k, 3) of ``vertices[ids]`` in the eye frame: (u, v, w), rig units."""
        return (vertices[ids] - self.origin) @ self.axes.T


def _eye_frame(rig: Rig, side: str) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Origin (inner corner), axes (3, 3) rows u, v, w, corner distance and the eyeball centre: the
    frame the rig's lid contact uses (``mimetic.rig.anatomy.lids.eye_frame``)."""
    inner, outer = rig.landmark_positions([f"eye_inner_corner_{side}", f"eye_outer_corner_{side}"])
    eye = rig.bone(f"eye_{side}")
    origin, axes, width = eye_frame(inner, outer, eye.tail - eye.head)
    return origin, axes, width, np.asarray(eye.head, dtype=np.float64)


def find_lid_margins(rig: Rig, side: str) -> LidMargins:
    """The lid margins of eye ``side`` ("L" or "R") on ``rig``'s rest mesh (see the module docstring).

    Returns
    -------
    LidMargins
        ``reason`` says why the margins are not usable: no opening between the lids (``bridged``: a
        face mask whose eyes are closed by faces), or too few margin vertices.
    """
    if side not in ("L", "R"):
        raise ValueError(f"side must be 'L' or 'R'; got {side!r}")
    V = rig.mesh.vertices
    origin, axes, width, _ = _eye_frame(rig, side)
    empty = np.zeros(0, dtype=np.int64)
    skin = skin_faces(V, rig.mesh.faces)
    corners = rig.landmark_positions([f"eye_inner_corner_{side}", f"eye_outer_corner_{side}"])
    opening = eye_opening(V, skin, corners, eyeball(V, rig.mesh.faces, corners))
    if opening is None:
        reason = "no real lids: no opening between the lids seen from the front"
        return LidMargins(side, empty, empty, origin, axes, width, True, reason)
    tolerance = MARGIN_TOLERANCE * EYE_STEP_REL * width
    lo, hi = MARGIN_SPAN[0] * width, MARGIN_SPAN[1] * width
    margins = []
    for ids, pick in zip(margin_seeds(V, skin, opening, tolerance), (np.argmin, np.argmax), strict=True):
        u = (V[ids] - origin) @ axes[0]
        v = (V[ids] - origin) @ axes[1]
        ids, u, v = ids[(u > lo) & (u < hi)], u[(u > lo) & (u < hi)], v[(u > lo) & (u < hi)]
        # one vertex per column a grid step wide: the one nearest the opening
        column = np.floor(u / (EYE_STEP_REL * width)).astype(np.int64)
        chosen = [ids[column == k][pick(v[column == k])] for k in np.unique(column)]
        chosen = np.asarray(chosen, dtype=np.int64)
        margins.append(chosen[np.argsort((V[chosen] - origin) @ axes[0])])
    upper, lower = margins
    if min(len(upper), len(lower)) < 3:
        return LidMargins(side, upper, lower, origin, axes, width, False, "fewer than 3 margin vertices")
    return LidMargins(side, upper, lower, origin, axes, width, False, "", (V[upper] - origin) @ axes[0])


def margin_gap(
    upper: np.ndarray, lower: np.ndarray, *, samples: int = GAP_SAMPLES
) -> tuple[np.ndarray, np.ndarray]:
    """Vertical gap between two margin polylines, column by column.

    Parameters
    ----------
    upper, lower : (k, 2+) and (j, 2+) float64
        Points whose first two coordinates are (u, v) in one frame (v up); any order.
    samples : int
        Number of common ``u`` values, evenly spaced over the range both polylines cover.

    Returns
    -------
    u : (samples,) float64
    gap : (samples,) float64
        ``v_upper(u) − v_lower(u)``, each polyline sorted by ``u`` and interpolated linearly; negative
        where the upper polyline lies below the lower one. Empty when the ``u`` ranges do not overlap.
    """
    upper, lower = np.asarray(upper, dtype=np.float64), np.asarray(lower, dtype=np.float64)
    a, b = upper[np.argsort(upper[:, 0])], lower[np.argsort(lower[:, 0])]
    start, stop = max(a[0, 0], b[0, 0]), min(a[-1, 0], b[-1, 0])
    if stop < start:
        return np.zeros(0), np.zeros(0)
    u = np.linspace(start, stop, samples)
    return u, np.interp(u, a[:, 0], a[:, 1]) - np.interp(u, b[:, 0], b[:, 1])


@dataclass(frozen=True)
class LidGap:
    """The gap between one eye's posed lid margins (``margin_gap`` in the eye frame), rig units.

    ``smallest``/``largest``: the extreme column gaps; ``crossing``: some column's gap is below
    ``-tolerance`` (the upper margin under the lower one); ``gaps`` (s,) per column.
    """

    side: str
    smallest: float
    largest: float
    crossing: bool
    gaps: np.ndarray


def lid_gap(margins: LidMargins, posed: np.ndarray, *, tolerance: float = 0.0) -> LidGap:
    """Column gaps of ``margins`` (found at rest) at the posed vertices ``posed`` (n, 3)."""
    if not margins.usable:
        raise ValueError(f"eye {margins.side}: lid margins are not usable ({margins.reason})")
    _, gaps = margin_gap(margins.project(posed, margins.upper), margins.project(posed, margins.lower))
    return LidGap(margins.side, float(gaps.min()), float(gaps.max()), bool(gaps.min() < -tolerance), gaps)


def margin_roughness(
    t: np.ndarray, points: np.ndarray, width: float, *, degree: int = ROUGHNESS_DEGREE
) -> float:
    """How jagged a margin is: RMS distance of ``points`` from a smooth curve, over ``width``.

    Parameters
    ----------
    t : (k,) float64
        The parameter each point belongs to (the margin's rest ``u``), distinct values.
    points : (k, d) float64
        The margin's posed coordinates that should vary smoothly with ``t`` (the eye frame's v and
        w), rig units.
    width : float
        The length the result is relative to (the lid width), rig units.
    degree : int
        Degree of the least-squares polynomial in ``t`` fitted to each coordinate.

    Returns
    -------
    roughness : float
        ``sqrt(mean_k |points_k − fit(t_k)|²) / width``: about 0 for a smooth arc, ``a / width`` for
        a sawtooth of amplitude ``a``; nan with fewer than ``MIN_ROUGHNESS_POINTS`` points.
    """
    t = np.asarray(t, dtype=np.float64)
    points = np.asarray(points, dtype=np.float64).reshape(len(t), -1)
    if len(t) < MIN_ROUGHNESS_POINTS:
        return float("nan")
    residual = np.empty_like(points)
    for d in range(points.shape[1]):
        fit = np.polynomial.Polynomial.fit(t, points[:, d], degree)
        residual[:, d] = points[:, d] - fit(t)
    return float(np.sqrt(np.mean(np.sum(residual**2, axis=1))) / width)


def lid_roughness(margins: LidMargins, posed: np.ndarray) -> float:
    """``margin_roughness`` of the upper margin of ``margins`` at ``posed`` (n, 3): its eye-frame v and w
    against its rest u, over the lid width, without its first and last column (where a margin can turn
    sharply into the corner)."""
    if not margins.usable:
        raise ValueError(f"eye {margins.side}: lid margins are not usable ({margins.reason})")
    inner = slice(1, -1)  # the first and last columns turn into the corners
    points = margins.project(posed, margins.upper[inner])  # (k, 3) u, v, w
    return margin_roughness(margins.upper_u[inner], points[:, 1:], margins.width)


def seen_opening(
    posed: np.ndarray,
    eye: np.ndarray,
    skin: np.ndarray,
    corners: np.ndarray,
    *,
    sphere: tuple[np.ndarray, float] | None = None,
    span: tuple[float, float] = MARGIN_SPAN,
    step_rel: float = SEEN_STEP_REL,
) -> np.ndarray:
    """How much of an eyeball a viewer in front sees, column by column: the lids' opening as a render
    shows it, whatever the margins' vertices do.

    Parameters
    ----------
    posed : (n, 3) float64
        Vertex positions, +Z toward the viewer, rig units.
    eye, skin : (e, 3), (s, 3) int64
        The eyeball's faces and the faces that can hide it (the skin; lashes and see-through films
        are not counted).
    corners : (2, 3) float64
        The eye's corners (any order).
    sphere : ((3,) float64, float), optional
        The eyeball's centre and radius: only its surface counts (``openings.EYE_SURFACE_SHARE``),
        not pieces the eye part holds deep inside the corners (a caruncle).
    span : (float, float)
        The part of the corners' x range looked at (``MARGIN_SPAN``: the corners themselves, where
        the lids meet at rest, are left out).
    step_rel : float
        Grid step × the corners' distance.

    Returns
    -------
    heights : (k,) float64
        The height of the eyeball seen (in front of the skin, or with no skin in front) in each
        column, a grid step wide, rig units; 0 where the lids cover it.
    """
    corners = np.asarray(corners, dtype=np.float64)
    step = step_rel * float(np.linalg.norm(corners[1] - corners[0]))
    return seen_eye(posed, eye, skin, corners, span, step, sphere).heights


def seen_eyeball(rig: Rig, posed: np.ndarray, side: str) -> np.ndarray | None:
    """``seen_opening`` of eye ``side`` of ``rig`` at ``posed`` (n, 3), a pose with the head and the eyes
    at rest (the eyeball's sphere is the eye bone's at rest): (k,) heights, rig units, or None when
    the rig has no eyeball for that eye (a face mask)."""
    part = f"eye_{side}"
    if part not in rig.mesh.parts or not len(rig.mesh.parts[part]):
        return None
    faces = rig.mesh.faces
    corners = rig.landmark_positions([f"eye_inner_corner_{side}", f"eye_outer_corner_{side}"])
    skin = skin_faces(rig.mesh.vertices, faces)
    bone = rig.bone(part)
    sphere = (bone.head, float(np.linalg.norm(bone.tail - bone.head)))
    return seen_opening(posed, faces[rig.mesh.parts[part]], skin, corners, sphere=sphere)


def most_eyeball_seen(rig: Rig, posed: np.ndarray) -> float | None:
    """The most eyeball ``seen_eyeball`` shows in any column of either eye at ``posed`` (n, 3), rig
    units, or None when the rig lacks an eyeball."""
    heights = [seen_eyeball(rig, posed, side) for side in ("L", "R")]
    if not all(h is not None and len(h) for h in heights):
        return None
    return max(float(h.max()) for h in heights)


def closed_lids_pose(rig: Rig) -> np.ndarray:
    """The pose (c,) with both upper lids at their channel maximum, every other channel at its default."""
    values = np.array([c.default for c in rig.channels], dtype=np.float64)
    for side in ("L", "R"):
        j = rig.channel_index(f"eyelid_upper_{side}")
        values[j] = rig.channels[j].maximum
    return values


# --------------------------------------------------------------------------- weights


def rigid_motion(rest: np.ndarray, moved: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rotation (3, 3) and translation (3,) taking points ``rest`` (k, 3) closest to ``moved``
    (k, 3) in least squares (Kabsch): ``moved ≈ rest @ R.T + t``."""
    a, b = rest.mean(axis=0), moved.mean(axis=0)
    u, _, vt = np.linalg.svd((rest - a).T @ (moved - b))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rotation = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return rotation, b - rotation @ a


def implied_weights(offsets: np.ndarray, motion: np.ndarray) -> np.ndarray:
    """How far each vertex follows a bone (n,) in [0, 1]: its captured ``offsets`` (n, 3) projected on
    the bone's full ``motion`` of that vertex (n, 3), ``clip(d · r / |r|², 0, 1)``."""
    size2 = np.einsum("nd,nd->n", motion, motion)
    return np.clip(np.einsum("nd,nd->n", offsets, motion) / np.maximum(size2, 1e-24), 0.0, 1.0)


# --------------------------------------------------------------------------- fidelity


@dataclass(frozen=True)
class Fidelity:
    """How well a baked rig reproduces target shapes.

    Attributes
    ----------
    names : tuple of str, (k,)
    residual : (k,) float64
        ``‖fit − target‖ / ‖target‖`` over the fitted vertices (offsets from the neutral).
    activations : (k, c) float64
        The fitted channel values.
    median, worst : float
        Over ``residual``.
    worst_name : str
    success : bool
        The solve converged on every shape (``SolveResult.success``).
    """

    names: tuple[str, ...]
    residual: np.ndarray
    activations: np.ndarray
    median: float
    worst: float
    worst_name: str
    success: bool = True


def expression_fidelity(
    basis: Basis,
    deltas: np.ndarray,
    *,
    names: Sequence[str],
    channels: Rig | Sequence[Channel],
    vertices: np.ndarray | slice | None = None,
    iterations: int = 30,
) -> Fidelity:
    """Fit each target shape with bounded least squares on ``basis`` and report the residuals.

    Parameters
    ----------
    basis : Basis
        ``bake(engine).basis``: neutral (n, 3), deltas (c, n, 3), correctives; rig units.
    deltas : (k, n, 3) float64
        Target shapes as offsets from ``basis.neutral`` (e.g. ICT's expression deltas), rig units.
    names : sequence of str, (k,)
    channels : Rig or sequence of Channel
        Channel ranges bounding the fit (the rig the basis was baked from).
    vertices : (s,) int, (n,) bool or slice, optional
        Where the fit and the residual look (ICT's face: ``slice(0, 9409)``); all by default.
    iterations : int
        Gauss-Newton steps per shape when the basis has correctives.

    Returns
    -------
    Fidelity
        ``residual`` = ``SolveResult.relative_residual`` of ``mimetic.capture.solve_activations``.
    """
    from mimetic.capture.solve import prepare_solver

    deltas = np.asarray(deltas, dtype=np.float64)
    if deltas.ndim != 3 or len(deltas) != len(names):
        raise ValueError(f"deltas must be (k, n, 3) with k = len(names) = {len(names)}; got {deltas.shape}")
    solver = prepare_solver(basis, vertices=vertices, channels=channels, iterations=iterations)
    with warnings.catch_warnings():  # a shape still improving is reported in ``success``
        warnings.simplefilter("ignore", MimeticWarning)
        solved = solver.solve(basis.neutral + deltas)
    residual = np.asarray(solved.relative_residual, dtype=np.float64)
    worst = int(np.nanargmax(residual))
    log.debug("expression_fidelity: %d shapes, median %.3f", len(names), float(np.nanmedian(residual)))
    return Fidelity(
        tuple(names),
        residual,
        np.asarray(solved.activations),
        float(np.nanmedian(residual)),
        float(residual[worst]),
        names[worst],
        bool(solved.success),
    )
