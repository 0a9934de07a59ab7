"""The lids: where the upper lid meets the lower one, and the closing that brings it there.

Real lids close along a smooth line: the upper lid does most of the closing and comes down onto
the lower lid's margin, slightly below the eye's equator; the margins press together but never
pass through each other. A rig's lid bones turn each lid about the eye's centre. What makes them
close exactly is computed here, per rig, from the rig's own margins (a closing designed on the
reference head's ring topology and transferred to a scan lands short of, or past, the scan's
lids):

* **Rims** (``lid_rims``). In the eye frame (``eye_frame``: origin at the inner corner, ``u``
  toward the outer corner, ``w`` the gaze, ``v`` up), the rim of a lid is where its surface, seen
  along the gaze, ends or turns away: a vertex on a boundary edge (an eye hole), or shared by a
  face turned toward the viewer and one turned away (where the lid folds into an eye socket).
  Rim vertices of the eyelid regions on the skin (the largest piece of mesh the regions reach:
  lashes are separate pieces), in front of the eye's centre and between ``SPAN`` of the corner
  chord, are split into upper (``v > 0``) and lower by the corner chord, not by region (a transfer
  blurs the regions), and into two layers: the *visible* margins, and a conjunctiva skirt *tucked*
  inside the eyeball (nearer its centre than ``TUCKED_REL`` of its radius), as the generated
  heads have. The lower rim's highest vertex per column (columns as wide as the rim's edges run
  along ``u``) is the lower *margin*; the upper rim's lowest vertex per column the upper margin.
* **Contact** (``find_lid_contacts``, ``Rig.anatomy.lids``): per eye and layer, every upper rim
  vertex is a contact vertex and the lower margin, bridged over its dips and a corner's wall
  (``lower_line``), the line it meets. The engines keep each contact vertex on or above that line,
  in the eye frame at the vertex's own ``u`` (``mimetic.engines.chain.Chain``): the upper lid
  yields, the lower stays. The eye is the sclera's sphere (``mimetic.mesh.openings.eyeball``), on a
  rig without one the sphere through the eye part or the lid regions.
* **Closing weights** (``closing_weights``): the upper-lid bone weight of each column of the visible
  upper margin is the one whose skinning (as the engines skin, eyeball sculptor included, on the
  generic eyeball: the sculptor's push out of an eye's own cornea moves no margin in the eye's
  frame, ``mimetic.rig.anatomy.eyeball``) at the closing angle (the ``eyelid_upper`` channel's
  maximum) brings it onto that line; those weights are smoothed along the margin (a smoothing spline
  in ``u``, never below the columns' own weights), and every other upper-lid vertex keeps its share
  of its column's margin weight, but never more than brings the upper margin the front sees onto the
  lower margin the front sees. A partial closure (a wink) is then a smooth curve, and a skinned
  export without the contact closes too. Given the eyeball, the closed lid is then *looked at* from
  the front (``seen_eye``): where eyeball still shows down to the lower margin, the lid vertex on
  the edge of what shows (near the rim) joins the margin and the weights are solved again, keeping
  the pass whose widest open column shows least.
* **Pivot** (``closing_pivot``, used by the transfer): an opening taller than the closing angle can
  close turning about the eye's centre has its upper lid turn about a point set back behind it, so
  the margin travels farther and slides over the eyeball.

Lengths are in rig units; ``_rel`` values are fractions of the head height.

Over 600 lines because the rims, the contacts, the closing weights and the closing pivot all read
the same margins in the same eye frame; split, each module would find the rims again.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.interpolate import make_smoothing_spline
from scipy.sparse.csgraph import connected_components as graph_components

from mimetic.head.shape import smoothstep
from mimetic.mesh.geometry import connected_components, edges_unique
from mimetic.mesh.openings import (
    EYE_STEP_REL,
    SeenEye,
    eye_opening,
    eyeball,
    gaze_rim,
    margin_distance,
    margin_seeds,
    opening_sides,
    seen_eye,
    skin_faces,
)
from mimetic.rig.anatomy.eyeball import Eyeball

__all__ = [
    "LID_BRIDGE_REL",
    "LID_CLEARANCE_REL",
    "LID_COLUMN_REL",
    "LID_CONTACT_GAP_REL",
    "LID_THICKNESS_REL",
    "LidContact",
    "LidRims",
    "closing_pivot",
    "closing_weights",
    "eye_frame",
    "eye_sphere",
    "eyeball_sphere",
    "find_lid_contacts",
    "gaze_rim",
    "lid_rims",
    "lower_line",
]

LID_CLEARANCE_REL = 0.0002
"""Lids stay this far outside the eyeball, × the head height (0.005 cm on a 23 cm head)."""
LID_THICKNESS_REL = 0.01
"""The sculptor keeps each lid vertex at least as high over the eyeball as at rest, up to this × the
head height (2 mm): a closing lid keeps its thickness over the cornea."""
LID_CONTACT_GAP_REL = 0.001
"""Closed lids keep this far apart at the contact, × the head height (0.1 mm: they touch, and a margin
sampled more coarsely than the contact's still never shows them crossed)."""
TUCKED_REL = 0.9
"""Rim vertices nearer the eye's centre than this × its radius are a skirt tucked inside the eyeball."""
SPAN = (0.05, 0.95)
"""The part of the corner chord (fractions from the inner corner) whose rims are contacts."""
SEED_STEPS = 2.0
"""A rim vertex within this many steps of the eye's grid (``mimetic.mesh.openings.EYE_STEP_REL``) of
the opening's edge, seen from the front, is on the margin (``_seen_margins``). Not fitted: the grid's
own step, as ``mimetic.quality`` reads the margins; checked on the calibration heads of
``benchmarks/sweep_motion.py`` (ICT's neutral, identities s1-s2 σ 1, s2-s6 σ 2)."""
MIN_CHAIN = 0.25
"""A piece of rim is a margin when its envelope spans this much of the corner chord."""
OUTLIER_REL = 0.1
"""A margin point this far (× the lid width) beyond the line through its neighbours is not margin."""
MIN_MARGIN = 3
"""A layer whose lower margin has fewer columns than this has no contact."""
LID_BRIDGE_REL = 0.1
"""The upper lid bridges dips of the lower margin up to this × the eye's width along it (``lower_line``)."""
LID_COLUMN_REL = 2 * EYE_STEP_REL
"""... and rests on any chord of the lower margin this short (× the eye's width: two steps of the grid
the eye's opening is seen on, ``mimetic.mesh.openings``), dip or not: where the lower margin turns
steeply into a corner its rim runs down a wall of the canthus, and the lid closes over the corner
rather than into it (the margin read one vertex per grid column cuts that corner as well). Not
fitted: two grid steps, the widest chord between two columns' vertices; checked on the calibration
heads of ``benchmarks/sweep_motion.py`` (ICT's neutral, identities s1-s2 σ 1, s2-s6 σ 2)."""
SMOOTHING = 1e-5
"""Penalty of the smoothing spline of the closing weights along the margin (``u`` in lid widths)."""
BISECTIONS = 40
CLOSING_RESERVE = 0.85
"""The upper lid's pivot is set back behind the eye's centre (``closing_pivot``) until every column of
its margin closes within this share of the closing angle; the per-column weights do the rest. Not
fitted (room for the sculptor and the smoothing of the weights); checked on ICT identities s2-s6 σ2
and s101-s106 (``benchmarks/sweep_motion.py``)."""
SIGHT_SPAN = (0.1, 0.9)
"""The part of the corners' x range where the closed lid is checked by sight (``closing_weights``)."""
SIGHT_TOL_REL = 0.01
"""... on a grid this fine (× the corners' distance), and a column showing more eyeball than one step
of it (0.03 cm on ICT's eyes, a third of the sweep's 0.1 cm goal) is open."""
SIGHT_LOWER_REL = 0.05
"""... where what shows reaches down to within this × the corners' distance of the lower margin: an
eyeball seen through the middle of a closed lid (a cornea the lid's skin passes through, ICT
identity s145 σ 3) is not a lid edge left open, and dragging the skin above it down pinched the lid."""
SIGHT_REACH_REL = 0.15
"""... and only a vertex within this × the corners' distance of the upper rim along the skin (half the
lid band, ``LID_BAND_REL``) is taken for the lid's edge: farther up it is the lid's skin, seen over the
eyeball where the lid passes through a bulging cornea (s145 σ 3: vertices 0.15-0.31 up, whose pull
pinched the lid into a fold); the edges missed by the rim lie within 0.12 (s129 σ 2). Chosen on those
two heads of the sweep's check group (so they are no longer blind to it); the sweep's other heads
checked."""
SIGHT_PASSES = 3
"""At most this many times are the lid edges seen over the eyeball added to the margin."""
LID_BAND_REL = 0.3
"""The upper lid's skin follows its margin to this distance from it along the skin, × the eye's width
(the corners' distance; 0.9 cm on ICT's 3 cm eyes), fading from 1 at the margin (``lid_profile``).
Calibrated on ICT's neutral (its eyeBlink shapes' implied weights); checked on ICT identities
s101-s105 (``benchmarks/bench_weights.py``)."""


@dataclass(frozen=True, eq=False)
class LidContact:
    """Where one layer of one eye's upper lid meets its lower lid (see the module docstring).

    Attributes
    ----------
    side : "L" | "R"
    upper : (k,) int64
        The upper lid's rim vertices (the contact vertices), by increasing rest ``u``.
    lower : (j,) int64
        The lower margin (the lower rim's highest vertex per column), inner to outer corner.
    tucked : bool
        A conjunctiva skirt inside the eyeball (hidden) rather than the visible margins. Only the
        visible layer opens the upper lid's columns; a tucked contact only keeps its own vertices
        from crossing.
    """

    side: str
    upper: np.ndarray
    lower: np.ndarray
    tucked: bool = False

    def __post_init__(self) -> None:
        for name in ("upper", "lower"):
            array = np.array(getattr(self, name), dtype=np.int64, copy=True).reshape(-1)
            array.setflags(write=False)
            object.__setattr__(self, name, array)
        object.__setattr__(self, "tucked", bool(self.tucked))


@dataclass(frozen=True)
class LidRims:
    """The rims of one eye's lids at rest (``lid_rims``).

    Attributes
    ----------
    origin : (3,) float64
        The inner eye corner.
    axes : (3, 3) float64
        Rows ``u``, ``v``, ``w`` of the eye frame (``eye_frame``).
    width : float
        Distance between the corners.
    upper, lower : tuple of (k,) int64
        Per layer (visible, tucked): the upper rim vertices by increasing ``u``, and the lower margin
        (highest lower rim vertex per column) inner to outer.
    upper_margin : tuple of (k,) int64
        Per layer: the lowest upper rim vertex per column, inner to outer.
    upper_seen, lower_seen : (k,) int64, (j,) int64
        The visible rim vertices along the opening seen from the front (what a viewer takes for the
        margins; the lower by ``u``), whether or not the regions' rims are used instead (empty
        without).
    """

    origin: np.ndarray
    axes: np.ndarray
    width: float
    upper: tuple[np.ndarray, np.ndarray]
    lower: tuple[np.ndarray, np.ndarray]
    upper_margin: tuple[np.ndarray, np.ndarray]
    upper_seen: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    lower_seen: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))

    def uvw(self, points: np.ndarray) -> np.ndarray:
        """``points`` (k, 3) in the eye frame: (u, v, w), rig units."""
        return (points - self.origin) @ self.axes.T


def eye_frame(inner: np.ndarray, outer: np.ndarray, gaze: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The eye frame: origin (3,) at the inner corner, axes (3, 3) with rows ``u`` (inner → outer
    corner), ``v`` (up) and ``w`` (the gaze made orthogonal to ``u``; +Z when the gaze lies along
    ``u``), and the corner distance. ``mimetic.quality`` measures lid gaps in the same frame."""
    inner, outer = np.asarray(inner, dtype=np.float64), np.asarray(outer, dtype=np.float64)
    width = float(np.linalg.norm(outer - inner))
    u = (outer - inner) / width
    gaze = np.asarray(gaze, dtype=np.float64)
    if np.linalg.norm(gaze - gaze.dot(u) * u) < 1e-9 * max(width, 1e-300):
        gaze = np.array([0.0, 0.0, 1.0])
    w = gaze - gaze.dot(u) * u
    w /= np.linalg.norm(w)
    v = np.cross(w, u)
    if v[1] < 0:
        v = -v
    return inner, np.stack([u, v, w]), width


def eye_sphere(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares sphere through ``points`` (k, 3): centre (3,) and radius."""
    a = np.column_stack([2.0 * points, np.ones(len(points))])
    b = np.sum(points**2, axis=1)
    x = np.linalg.lstsq(a, b, rcond=None)[0]
    return x[:3], float(np.sqrt(max(x[3] + x[:3] @ x[:3], 0.0)))


def _inner_edges(edges: np.ndarray, ids: np.ndarray, n: int) -> np.ndarray:
    """The ``edges`` (e, 2) both of whose ends are among ``ids`` (of ``n`` vertices)."""
    among = np.zeros(n, dtype=bool)
    among[ids] = True
    return edges[among[edges].all(axis=1)]


def _envelope(ids: np.ndarray, edges: np.ndarray, uvw: np.ndarray, *, lowest: bool) -> np.ndarray:
    """The vertices of ``ids`` on the lower (``lowest``) or upper envelope, seen along the gaze, of the
    polylines their mesh edges draw in the eye's (u, v) plane, ordered by ``u``.

    A vertex is dropped when an edge between two of ``ids`` passes under it (over it for the upper
    envelope) at its ``u``: a lid crease folds above the margin, and the margin's own edges pass
    under it; a second row of the margin lies above the first.
    """
    sign = 1.0 if lowest else -1.0
    inner = _inner_edges(edges, ids, len(uvw))
    u, v = uvw[:, 0], sign * uvw[:, 1]
    a, b = inner[:, 0], inner[:, 1]
    lo, hi = np.minimum(u[a], u[b]), np.maximum(u[a], u[b])
    tol = 1e-9 * max(float(np.ptp(u[ids])) if len(ids) else 1.0, 1e-300)
    between = (u[ids, None] > lo[None] + tol) & (u[ids, None] < hi[None] - tol)  # (k, e)
    t = (u[ids, None] - u[a][None]) / np.where(hi - lo > 0, u[b] - u[a], 1.0)[None]
    below = (1 - t) * v[a][None] + t * v[b][None] < v[ids, None] - tol
    keep = ids[~(between & below).any(axis=1)]
    return keep[np.argsort(uvw[keep, 0], kind="stable")]


def _chain(
    envelope: np.ndarray, ids: np.ndarray, edges: np.ndarray, uvw: np.ndarray, width: float
) -> np.ndarray:
    """The ``envelope`` vertices on pieces of the rim ``ids`` (joined by mesh edges) whose envelope
    spans at least ``MIN_CHAIN`` of the lid ``width`` along ``u``: the margin runs from corner to
    corner, a fold beside a corner does not."""
    if len(envelope) == 0:
        return envelope
    inner = _inner_edges(edges, ids, len(uvw))
    index = np.full(int(max(ids.max(), inner.max(initial=0))) + 1, -1)
    index[ids] = np.arange(len(ids))
    graph = sp.coo_matrix(
        (np.ones(len(inner)), (index[inner[:, 0]], index[inner[:, 1]])), shape=(len(ids),) * 2
    )
    _, label = graph_components(graph, directed=False)
    piece = label[index[envelope]]
    u = uvw[envelope, 0]
    keep = np.zeros(len(envelope), dtype=bool)
    for p in np.unique(piece):
        mine = piece == p
        if np.ptp(u[mine]) >= MIN_CHAIN * width:
            keep |= mine
    return envelope[keep]


def _smooth_run(margin: np.ndarray, uvw: np.ndarray, width: float, *, lowest: bool) -> np.ndarray:
    """``margin`` (by ``u``) without the points farther from the opening than the line through their
    neighbours (the ends: through the next two) by ``OUTLIER_REL`` of the lid ``width`` or more: a
    fold beyond a corner that joins the margin's piece of rim."""
    sign = 1.0 if lowest else -1.0  # away from the opening is up for the upper lid
    while len(margin) > 3:
        u, v = uvw[margin, 0], sign * uvw[margin, 1]
        a = np.concatenate([[1], np.arange(len(u) - 2), [len(u) - 3]])
        b = np.concatenate([[2], np.arange(2, len(u)), [len(u) - 2]])
        span = u[b] - u[a]
        t = (u - u[a]) / np.where(np.abs(span) > 0, span, 1.0)
        excess = v - ((1 - t) * v[a] + t * v[b])
        worst = int(np.argmax(excess))
        if excess[worst] <= OUTLIER_REL * width:
            break
        margin = np.delete(margin, worst)
    return margin


def _overlap(margin: np.ndarray, other: np.ndarray, uvw: np.ndarray) -> np.ndarray:
    """``margin`` (by ``u``) within the ``u`` range of ``other``, and its nearest vertex beyond either end."""
    if len(margin) == 0 or len(other) == 0:
        return margin[:0]
    u = uvw[margin, 0]
    first = max(int(np.searchsorted(u, uvw[other, 0].min(), side="right")) - 1, 0)
    last = int(np.searchsorted(u, uvw[other, 0].max(), side="left")) + 1
    return margin[first:last]


def _seen_margins(
    vertices: np.ndarray,
    faces: np.ndarray,
    corners: np.ndarray,
    centre: np.ndarray,
    radius: float,
) -> tuple[np.ndarray, np.ndarray] | None:
    """The rim vertices along the upper and lower edges of the eye's opening seen from the front
    (``mimetic.mesh.openings``: the lids' silhouettes, whatever the regions say), or None when no
    opening is found (eyes closed by faces).

    A rim vertex is on the opening's edge within ``SEED_STEPS`` steps of the grid the opening was
    seen on (``EYE_STEP_REL`` × the corners' distance), as ``mimetic.quality`` reads the margins:
    the opening's own width is narrower (it stops short of the canthus), and a tolerance taken from
    it left the innermost margin vertices out of the contact, free to pass the lower lid."""
    skin = skin_faces(vertices, faces)
    opening = eye_opening(vertices, skin, corners, (centre, radius))
    if opening is None:
        return None
    width = float(np.linalg.norm(corners[1] - corners[0]))
    return margin_seeds(vertices, skin, opening, SEED_STEPS * EYE_STEP_REL * width)


def lid_rims(
    vertices: np.ndarray,
    faces: np.ndarray,
    regions: Mapping[str, np.ndarray],
    side: str,
    *,
    corners: np.ndarray,
    centre: np.ndarray,
    radius: float,
    gaze: np.ndarray,
    sclera: tuple[np.ndarray, float] | None = None,
    carried: bool = False,
) -> LidRims | None:
    """The rims of eye ``side``'s lids on a rest mesh (see the module docstring).

    Parameters
    ----------
    vertices : (n, 3) float64
    faces : (m, 3) int64
    regions : Mapping[str, (k,) int64]
        ``eyelid_upper_<side>`` and ``eyelid_lower_<side>``.
    side : "L" | "R"
    corners : (2, 3) float64
        The inner and outer eye corners.
    centre, radius : (3,) float64, float
        The eyeball's centre and radius.
    gaze : (3,) float64
        The eye's gaze direction.
    sclera : ((3,) float64, float), optional
        The sclera's sphere (``eyeball_sphere``) when ``centre`` and ``radius`` are another's (an eye
        bone's, through the whole eye part): a rim vertex is tucked only inside both. The whole
        part's sphere (ICT's cornea and films with the sclera) is larger and lies farther back, and
        where an identity's lid sinks toward its eyeball it took margin vertices that show in front
        of the sclera for a skirt (ICT identity s129 σ2's right upper lid stayed 0.7 cm open).
    carried : bool
        The lid regions were carried from the reference onto this mesh (a guess, not its own): the
        opening is seen with the sclera's sphere, and its silhouette is the visible margin wherever
        it runs, skin inside the eyeballs' spheres included, whenever it spans half the regions'
        rims. On ICT's σ 2-3 identity heads a lid sinks into its eyeball's spheres and the regions'
        rim runs a row or more above the opening (s115 σ3's right upper lid stopped 0.47 cm short of
        the lower one; 0.18 now); on the reference the regions are the head's own, and the opening's
        rim there is the tucked skirt's edge.

    Returns
    -------
    LidRims, or None when a lid region is missing or has no rim.
    """
    names = (f"eyelid_upper_{side}", f"eyelid_lower_{side}")
    if any(len(regions.get(name, ())) == 0 for name in names):
        return None
    origin, axes, width = eye_frame(corners[0], corners[1], gaze)
    _, labels = connected_components(faces, len(vertices))
    lids = np.unique(np.concatenate([np.asarray(regions[name], dtype=np.int64) for name in names]))
    sizes = np.bincount(labels)
    reached = np.unique(labels[lids])
    lids = lids[labels[lids] == reached[np.argmax(sizes[reached])]]
    uvw = (vertices - origin) @ axes.T
    in_front = (vertices[lids] - centre) @ axes[2] > 0
    lo, hi = SPAN[0] * width, SPAN[1] * width
    inside = (uvw[lids, 0] > lo) & (uvw[lids, 0] < hi)
    lids = lids[in_front & inside]
    is_tucked = np.zeros(len(vertices), dtype=bool)
    balls = [(centre, radius)] if sclera is None else [(centre, radius), sclera]
    is_tucked[lids] = np.all(
        [np.linalg.norm(vertices[lids] - c, axis=1) < TUCKED_REL * r for c, r in balls], axis=0
    )
    # the rims: where the lid ends or turns away along the gaze, or (visible layer) meets the skirt
    edges = edges_unique(faces)
    next_to_tucked = np.zeros(len(vertices), dtype=bool)
    mixed = is_tucked[edges[:, 0]] != is_tucked[edges[:, 1]]
    next_to_tucked[edges[mixed].ravel()] = True
    rim = gaze_rim(vertices, faces, axes[2])
    seen = _seen_margins(
        vertices, faces, corners, *(sclera if carried and sclera is not None else (centre, radius))
    )
    upper, lower, margin = [], [], []
    upper_seen = lower_seen = np.zeros(0, dtype=np.int64)
    for tucked in (False, True):
        layer = lids[is_tucked[lids] == tucked]
        ids = layer[rim[layer] | (next_to_tucked[layer] & (not tucked))]
        up, low = ids[uvw[ids, 1] > 0], ids[uvw[ids, 1] <= 0]
        top = _chain(_envelope(up, edges, uvw, lowest=True), up, edges, uvw, width)
        bottom = _chain(_envelope(low, edges, uvw, lowest=False), low, edges, uvw, width)
        if not tucked and seen is not None:  # the head's own opening, not the regions' guess
            on_span = [(uvw[m, 0] > lo) & (uvw[m, 0] < hi) & (carried | ~is_tucked[m]) for m in seen]
            up_seen, low_seen = (m[keep] for m, keep in zip(seen, on_span, strict=True))
            top_seen = _envelope(up_seen, edges, uvw, lowest=True)
            bottom_seen = _envelope(low_seen, edges, uvw, lowest=False)
            upper_seen, lower_seen = up_seen, _smooth_run(bottom_seen, uvw, width, lowest=False)
            # unless the opening's rim is sparser than the regions' (a coarse mesh: a few vertices
            # across the eye, where the regions' rim is the margin); carried regions are compared by
            # the span of the eye they cover (their rim runs wherever the guess put it)
            if carried:
                taken = all(
                    len(a) >= MIN_MARGIN and np.ptp(uvw[a, 0]) >= 0.5 * (np.ptp(uvw[b, 0]) if len(b) else 0.0)
                    for a, b in ((top_seen, top), (bottom_seen, bottom))
                )
            else:
                taken = len(top_seen) >= len(top) / 2 and len(bottom_seen) >= len(bottom) / 2
            if taken:
                up, low, top, bottom = up_seen, low_seen, top_seen, bottom_seen
        upper.append(up[np.argsort(uvw[up, 0], kind="stable")])
        top, bottom = _smooth_run(top, uvw, width, lowest=True), _smooth_run(bottom, uvw, width, lowest=False)
        margin.append(_overlap(top, bottom, uvw))
        lower.append(bottom)
    return LidRims(origin, axes, width, tuple(upper), tuple(lower), tuple(margin), upper_seen, lower_seen)


def eyeball_sphere(
    vertices: np.ndarray,
    faces: np.ndarray,
    parts: Mapping[str, np.ndarray],
    regions,
    side: str,
    corners: np.ndarray,
) -> tuple[np.ndarray, float] | None:
    """The eyeball's sphere: the sclera's (``mimetic.mesh.openings.eyeball``: the largest spherical
    piece between the ``corners`` (2, 3)), else through the ``eye_<side>`` part's vertices, else
    through the lids'. A sphere through the whole part (ICT's: cornea, iris and films with the
    sclera) is larger and lies farther back, and put margins that show in front of the eyeball
    inside it, as if tucked."""
    ball = eyeball(vertices, faces, corners)
    if ball is not None:
        return ball
    part = parts.get(f"eye_{side}")
    if part is not None and len(part):
        ids = np.unique(faces[part])
    else:
        ids = np.unique(
            np.concatenate(
                [regions.get(f"eyelid_{lid}_{side}", np.zeros(0, np.int64)) for lid in ("upper", "lower")]
            )
        )
    if len(ids) < 10:
        return None
    centre, radius = eye_sphere(vertices[ids])
    return (centre, radius) if np.all(np.isfinite(centre)) and radius > 0 else None


def find_lid_contacts(
    vertices: np.ndarray,
    faces: np.ndarray,
    parts: Mapping[str, np.ndarray],
    regions: Mapping[str, np.ndarray],
    corners: Mapping[str, np.ndarray],
) -> tuple[LidContact, ...]:
    """Where each eye's upper lid meets its lower lid, per layer (see the module docstring).

    Parameters
    ----------
    vertices : (n, 3) float64
        The rest mesh, rig units (+Y up, +Z forward: the gaze is +Z).
    faces : (m, 3) int64
    parts : Mapping[str, (f,) int64]
        The mesh's parts (face indices); ``eye_L`` / ``eye_R`` give the eyeballs.
    regions : Mapping[str, (k,) int64]
        ``eyelid_upper_L`` … ``eyelid_lower_R``.
    corners : Mapping[str, (2, 3) float64]
        Per side ("L", "R"), the inner and outer eye corners; a side without corners has no contact.

    Returns
    -------
    tuple of LidContact, left eye first, visible layer before tucked; empty for a mesh without lids.
    """
    out = []
    for side in ("L", "R"):
        if side not in corners:
            continue
        eye = eyeball_sphere(
            vertices, faces, parts, regions, side, np.asarray(corners[side], dtype=np.float64)
        )
        if eye is None:
            continue
        rims = lid_rims(
            vertices,
            faces,
            regions,
            side,
            corners=np.asarray(corners[side], dtype=np.float64),
            centre=eye[0],
            radius=eye[1],
            gaze=np.array([0.0, 0.0, 1.0]),
        )
        if rims is None:
            continue
        for layer, tucked in ((0, False), (1, True)):
            if len(rims.upper[layer]) and len(rims.lower[layer]) >= MIN_MARGIN:
                out.append(LidContact(side, rims.upper[layer], rims.lower[layer], tucked))
    return tuple(out)


def lower_line(points: np.ndarray, span: float, column: float) -> tuple[np.ndarray, np.ndarray]:
    """(u, v), each (j,), of the line the upper lid closes onto: the lower margin (j, 3 in the eye
    frame) sorted by u, each point raised to the highest chord between two margin points around it
    at most ``column`` apart, or at most ``span`` apart where it lies no higher than both (a dip),
    and each end raised to the highest point within ``column`` of it.

    The upper lid's margin is stiff (the tarsal plate): it does not sink into the lower one's dips,
    but follows its rise into a corner (bridged, it would stand off it by the rise); a canthus' wall
    (rim vertices stacked at one u) holds the lid's corner at its top, not beside its foot. The
    closing weights aim at this line and the engines' contact stops the lid on it
    (``mimetic.engines.chain``, compiled per frame).
    """
    order = np.argsort(points[:, 0], kind="stable")
    u, v = points[order, 0], points[order, 1]
    if len(u) < 3:
        return u, v
    k = np.arange(len(u))
    between = (k[:, None, None] < k[None, None, :]) & (k[None, None, :] < k[None, :, None])  # (a, b, i)
    width = u[None, :] - u[:, None]  # (a, b)
    slope = (v[None, :] - v[:, None]) / np.maximum(width, 1e-300)
    chord = v[:, None, None] + (u[None, None, :] - u[:, None, None]) * slope[:, :, None]
    dip = (v[None, None, :] <= v[:, None, None]) & (v[None, None, :] <= v[None, :, None])
    usable = between & ((width <= column)[:, :, None] | ((width <= span)[:, :, None] & dip))
    line = np.maximum(v, np.where(usable, chord, -np.inf).max(axis=(0, 1)))
    line[0] = max(line[0], v[: np.searchsorted(u, u[0] + column, side="right")].max())
    line[-1] = max(line[-1], v[np.searchsorted(u, u[-1] - column, side="left") :].max())
    return u, line


def closing_pivot(rims: LidRims, vertices: np.ndarray, centre: np.ndarray, closed_rad: float) -> np.ndarray:
    """The upper lid's pivot (3,): the eye's ``centre``, or set back behind it along the gaze until the
    tallest column of the visible margin (``rims``, at rest ``vertices``) closes within
    ``CLOSING_RESERVE`` × ``closed_rad``.

    A lid turns about the eye's centre; an opening taller than that angle can close (a wide-open or
    large eye: 1.5 cm between the margins on ICT identities at σ 2, where 0.75 rad closes 1 cm) would
    leave its upper lid short of the lower one however its weights were set. Turning about a point
    behind the centre, the margin travels farther for the same angle, and the sculptor keeps it on
    the eyeball as it slides down (as a real lid slides over the globe). Heads whose lids close
    within the angle keep the centre.
    """
    upper, lower = rims.upper_margin[0], rims.lower[0]
    if len(upper) < MIN_MARGIN or len(lower) < MIN_MARGIN:
        return np.asarray(centre, dtype=np.float64)
    top, bottom = rims.uvw(vertices[upper]), rims.uvw(vertices[lower])
    order = np.argsort(bottom[:, 0])
    v_low = np.interp(top[:, 0], bottom[order, 0], bottom[order, 1])
    w_low = np.interp(top[:, 0], bottom[order, 0], bottom[order, 2])
    c = rims.uvw(np.asarray(centre, dtype=np.float64)[None])[0]

    def tallest(back: float) -> float:
        """The largest angle (rad) between a column's upper and lower margin, seen from ``back``
        behind the centre."""
        w0 = c[2] - back
        angle = np.arctan2(top[:, 1] - c[1], top[:, 2] - w0) - np.arctan2(v_low - c[1], w_low - w0)
        return float(angle.max())

    limit = CLOSING_RESERVE * closed_rad
    if tallest(0.0) <= limit:
        return np.asarray(centre, dtype=np.float64)
    lo, hi = 0.0, rims.width
    while tallest(hi) > limit and hi < 16 * rims.width:
        hi *= 2
    for _ in range(BISECTIONS):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if tallest(mid) > limit else (lo, mid)
    return np.asarray(centre, dtype=np.float64) - hi * rims.axes[2]


def _rotation_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def closing_weights(
    vertices: np.ndarray,
    faces: np.ndarray,
    weights: np.ndarray,
    regions: Mapping[str, np.ndarray],
    side: str,
    *,
    lid: int,
    head: int,
    pivot: np.ndarray,
    corners: np.ndarray,
    centre: np.ndarray,
    radius: float,
    gaze: np.ndarray,
    closed_rad: float,
    clearance: float,
    thickness: float,
    rims: LidRims | None = None,
    eyeball_faces: np.ndarray | None = None,
) -> np.ndarray:
    """Skin weights whose upper-lid column closes eye ``side`` onto its lower margin at ``closed_rad``.

    Parameters
    ----------
    vertices : (n, 3) float64
        The rest mesh, rig units.
    faces : (m, 3) int64
    weights : (n, b) float64
        The rig's skin weights (rows sum to 1); not changed.
    regions : Mapping[str, (k,) int64]
        ``eyelid_upper_<side>`` and ``eyelid_lower_<side>``.
    side : "L" | "R"
    lid, head : int
        Columns of the upper-lid bone and of the head bone (which takes what the lid gives back).
    pivot : (3,) float64
        The upper-lid bone's head: it turns about +X through it.
    corners : (2, 3) float64
        The inner and outer eye corners.
    centre, radius, gaze : (3,) float64, float, (3,) float64
        The eyeball (the eye bone's head, length and direction).
    closed_rad : float
        The upper-lid rotation that closes the eye (the ``eyelid_upper`` channel's maximum).
    clearance, thickness : float
        The sculptor's clearance outside the eyeball and the most of its rest height over the eyeball
        it keeps for each lid vertex, rig units (``LID_CLEARANCE_REL``, ``LID_THICKNESS_REL``).
    rims : LidRims, optional
        ``lid_rims`` of this eye with these arguments, when the caller has them already.
    eyeball_faces : (e, 3) int64, optional
        The eyeball's faces. Given, the closed lid is looked at from the front: where the eyeball
        still shows (``SIGHT_TOL_REL``), the upper lid's vertex on the edge of what shows joins the
        margin and the weights are solved again (``SIGHT_PASSES``). The rim misses a lid's edge
        where it rolls back without a silhouette (over a cornea bulging level with it: ICT identity
        s129 σ 2's left eye had no upper margin over its middle fifth, and that stretch stopped 0.45
        cm short).

    Returns
    -------
    (n, b) float64, a new array: the upper-lid column rescaled per column of the lid (the head
    column takes the difference); ``weights`` unchanged when the lids have no visible rim.
    """
    out = np.array(weights, dtype=np.float64, copy=True)
    gaze = np.asarray(gaze, dtype=np.float64) / np.linalg.norm(gaze)
    if rims is None:
        rims = lid_rims(
            vertices, faces, regions, side, corners=corners, centre=centre, radius=radius, gaze=gaze
        )
    if rims is None or len(rims.upper_margin[0]) < MIN_MARGIN or len(rims.lower[0]) < MIN_MARGIN:
        return out
    margin, lower = rims.upper_margin[0], rims.lower[0]
    # the generic eyeball: the engines push a lid forward out of the eye's own surface, which moves
    # no margin in the eye's frame (``mimetic.rig.anatomy.eyeball``); solved against the eye's own,
    # the passes by sight below chose other edges (ICT identity s144 σ 2: 0.09 → 0.12 cm seen)
    eye = Eyeball.of(centre, gaze, radius)

    def line(ids: np.ndarray) -> np.ndarray:
        """The line (j, 2) (u, v) the contact stops the lid on over the lower margin ``ids``: aiming
        below it (into a corner's wall) the contact opens the column again, and its neighbours too."""
        return np.column_stack(
            lower_line(rims.uvw(vertices[ids]), LID_BRIDGE_REL * rims.width, LID_COLUMN_REL * rims.width)
        )

    low = line(lower)
    # the lower margin itself, its dips not bridged: no vertex found by sight closes past it
    column = LID_COLUMN_REL * rims.width
    floor = np.column_stack(lower_line(rims.uvw(vertices[lower]), column, column))
    turn = _rotation_x(closed_rad)

    def skinned(ids: np.ndarray, w: np.ndarray) -> np.ndarray:
        """Where the vertices ``ids`` (k,) go at the closing angle with lid weights ``w`` (k,), skinned
        as the engines skin (sculptor included, on the generic eyeball), (k, 3)."""
        p = vertices[ids]
        swing = (p - pivot) @ turn.T + pivot - p  # (k, 3) where a full weight takes each
        # the sculptor keeps a lid vertex clear of the eyeball at rest at its rest height, up to thickness
        return eye.sculpt(p + w[:, None] * swing, eye.rest_clearance(p, clearance, thickness))

    def landing(ids: np.ndarray, low: np.ndarray) -> np.ndarray:
        """The lid weight (k,) that brings each vertex of ``ids`` onto the line ``low`` (j, 2) (u, v)
        at the closing angle, or its whole budget."""
        lo, hi = np.zeros(len(ids)), out[ids, lid] + out[ids, head]
        for _ in range(BISECTIONS):  # the lid comes down as its weight grows
            mid = 0.5 * (lo + hi)
            uvw = rims.uvw(skinned(ids, mid))
            above = uvw[:, 1] > np.interp(uvw[:, 0], low[:, 0], low[:, 1])
            lo, hi = np.where(above, mid, lo), np.where(above, hi, mid)
        return 0.5 * (lo + hi)

    skin = skin_faces(vertices, faces)

    def solve(margin: np.ndarray, *, capped: bool = False) -> np.ndarray:
        """The weights (n, b) that close the lid with ``margin`` (k,) as its edge; ``capped``: no
        vertex in front of the eye's centre closes past the lower margin (``floor``: the edges found
        by sight need more than the rim's columns beside them, which the spline shares out)."""
        out = np.array(weights, dtype=np.float64, copy=True)
        edge = np.union1d(rims.upper[0], margin)
        share = lid_profile(vertices, skin, edge, lower, LID_BAND_REL * rims.width)
        ids = np.flatnonzero((share > 0) | (out[:, lid] > 0))
        p = vertices[margin]  # (k, 3)
        needed = landing(margin, low)  # (k,)
        # the lid moves as its edge does: each vertex on the upper lid's side of the opening takes its
        # column's closing weight times its share of the margin's motion, which falls with its distance
        # from the margin along the skin (``lid_profile``: the skin of the lid, and the lid's inner
        # surface behind its edge, but not the brow nor the socket behind the eyeball)
        u = rims.uvw(p)[:, 0] / rims.width
        closing = _smooth(u, needed)
        at = rims.uvw(vertices[ids])[:, 0] / rims.width
        # past the ends: the end's. Never below the margin's own weights (linear between its columns):
        # the spline rounds off the steep rise of the weights into the inner corner, which left the lid
        # short of the lower one there; a column that would close too far the contact stops
        order = np.argsort(u, kind="stable")
        t = np.clip(at, u.min(), u.max())
        want = np.clip(np.maximum(closing(t), np.interp(t, u[order], needed[order])), 0.0, None)
        total = out[ids, lid] + out[ids, head]  # a vertex the head bone does not weight only gives
        new = np.minimum(share[ids] * want, total)
        # what the front sees of the upper margin never closes past what it sees of the lower (on a slit
        # of an eye the regions' rims are the margins, and a canthus's rim deep behind them needs more)
        seen = np.flatnonzero(np.isin(ids, rims.upper_seen))
        if len(seen) and len(rims.lower_seen) >= MIN_MARGIN:
            new[seen] = np.minimum(new[seen], landing(ids[seen], line(rims.lower_seen)))
        if capped:
            front = np.flatnonzero((vertices[ids] - centre) @ gaze > 0)
            new[front] = np.minimum(new[front], landing(ids[front], floor))
            # a contact vertex past the line the contact holds it on opens its whole column again
            contact = np.flatnonzero(np.isin(ids, rims.upper[0]))
            new[contact] = np.minimum(new[contact], landing(ids[contact], low))
        given = out[ids, lid] - new
        out[ids, lid], out[ids, head] = new, total - new
        # where the head bone did not weight a vertex its other bones share what the lid gives, so no
        # vertex gains an influence
        others = out[ids].copy()
        others[:, [lid, head]] = 0.0
        room = others.sum(axis=1)
        spread = (weights[ids, head] == 0) & (room > 0) & (given > 0)
        rows = ids[spread]
        out[rows, head] = 0.0
        out[rows] += others[spread] * (given[spread] / room[spread])[:, None]
        return out

    out = solve(margin)
    if eyeball_faces is None or not len(eyeball_faces):
        return out
    eyeball_faces = np.asarray(eyeball_faces, dtype=np.int64)
    near_rim = np.isfinite(margin_distance(vertices, skin, rims.upper[0], SIGHT_REACH_REL * rims.width))
    best, best_open = out, np.inf
    for _ in range(SIGHT_PASSES + 1):
        closed = vertices.copy()
        ids = np.flatnonzero(out[:, lid] > 0)
        closed[ids] = skinned(ids, out[ids, lid])
        seen = seen_eye(
            closed, eyeball_faces, skin, corners, SIGHT_SPAN, SIGHT_TOL_REL * rims.width, (centre, radius)
        )
        shown = float(seen.heights.max(initial=0.0))
        if shown >= best_open:  # a pass that shows more is not kept, and the next would not help
            break
        best, best_open = out, shown
        edge = np.setdiff1d(_seen_edge(seen, closed, ids, centre, gaze, rims.width, lower, near_rim), margin)
        if not len(edge):
            break
        margin = np.concatenate([margin, edge])
        out = solve(margin, capped=True)
    return best


def _seen_edge(
    seen: SeenEye,
    closed: np.ndarray,
    ids: np.ndarray,
    centre: np.ndarray,
    gaze: np.ndarray,
    width: float,
    lower: np.ndarray,
    near_rim: np.ndarray,
) -> np.ndarray:
    """The upper lid's edge over the eyeball still ``seen`` from the front at ``closed`` (n, 3): in
    each column showing more than ``SIGHT_TOL_REL`` × ``width`` of it, down to the lower margin
    ``lower`` (j,) (``SIGHT_LOWER_REL``), the lowest vertex of ``ids`` in front of the eye's ``centre``
    (along ``gaze``) and ``near_rim`` (n,) bool above the highest point seen, within two of the eye
    grid's steps of the column. Sorted, unique (k,) int64."""
    heights, tops = seen.heights, seen.tops
    order = np.argsort(closed[lower, 0])
    floor = np.interp(seen.x, closed[lower[order], 0], closed[lower[order], 1])  # the lower margin's height
    open_ = (heights > SIGHT_TOL_REL * width) & (seen.bottoms <= floor + SIGHT_LOWER_REL * width)
    p = closed[ids]
    ids = ids[((p - centre) @ gaze > 0) & near_rim[ids]]
    p = closed[ids]
    reach = 2 * EYE_STEP_REL * width
    edge = []
    for j in np.flatnonzero(open_):
        near = np.flatnonzero((np.abs(p[:, 0] - seen.x[j]) <= reach) & (p[:, 1] >= tops[j]))
        if len(near):
            edge.append(ids[near[np.argmin(p[near, 1])]])
    return np.unique(np.asarray(edge, dtype=np.int64))


def lid_profile(
    vertices: np.ndarray, faces: np.ndarray, upper: np.ndarray, lower: np.ndarray, band: float
) -> np.ndarray:
    """The share (n,) of the upper lid margin's motion each vertex takes: 1 on the margin ``upper``,
    falling smoothly to 0 at ``band`` from it along the skin ``faces`` (a smoothstep), and 0 off the
    upper lid's side of the opening (nearer the lower margin ``lower``: ``opening_sides``).

    ICT's captured blinks move the skin this way: the implied lid weight is about 1 at the margin,
    0.5 at 0.12 eye widths from it and under 0.1 beyond 0.3 (``LID_BAND_REL``).
    """
    distance = margin_distance(vertices, faces, upper, band)
    share = np.where(np.isfinite(distance), 1.0 - smoothstep(0.0, band, np.minimum(distance, band)), 0.0)
    share[opening_sides(vertices, faces, upper, lower, band) != 1] = 0.0
    return share


def _smooth(u: np.ndarray, values: np.ndarray):
    """A smoothing spline (callable) of ``values`` (k,) over distinct increasing-ish ``u`` (k,)."""
    order = np.argsort(u, kind="stable")
    x, y = u[order], values[order]
    keep = np.concatenate([[True], np.diff(x) > 1e-9])
    x, y = x[keep], y[keep]
    if len(x) < 5:
        return lambda t: np.interp(t, x, y)
    return make_smoothing_spline(x, y, lam=SMOOTHING)
