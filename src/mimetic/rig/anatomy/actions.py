"""Tissue actions: the displacement fields of muscles that wires and vector muscles cannot make.

A wire or a Waters muscle moves skin near its insertion toward its origin. Much of what a face does
is tissue moving as a sheet or a mass instead (the automated-rigging thesis's §8, the survey's
muscle catalogue): the frontalis lifts the whole forehead, the corrugator and procerus gather the
brows, the orbital orbicularis oculi lifts the cheek toward the eye (AU6), a smile piles the malar
fat up, air pressure puffs the cheeks, the marginal orbicularis oris rolls the lips in and its
peripheral part pushes them out into a funnel, the lips slide sideways together, the nasalis draws
the side of the nose up, the levator of the nose wrinkles and lifts its side, and the tongue pokes
out, lifts its tip or draws back. The small muscles of the brow's head and of the nose's tip, wing
and side move fields sized by their feature instead of the head (``local``), and the skin around
each eye turns with its gaze (``gaze``); ``find_actions`` builds them all.

Each is an ``Action``: a displacement field over the rest surface, linear in its channels and added
before skinning (as the creases are), so it bakes exactly and follows the jaw it rides on. Two
kinds build them from the rig's own landmarks and normals, in fractions of the head height:

* ``Bump``: a smooth ellipsoidal bump ``w = (1 − r²)²`` placed from a landmark, reaching farther
  on one side than the other where the tissue does, moving its tissue by a vector slid onto the
  surface (a sheet sliding over the bone: the forehead, the brows; over the forehead it falls off
  in the face plane, so it follows the brow's skin as it curves back) or, for a mass (the lips, the
  cheek's fat, the side of the nose, the chin beside the lower lip), by the same vector everywhere
  and whole through its depth, plus a bulge along the normal (one normal for a whole mass); a
  slide moves the lips it reaches unslid, as a mass (``LIP_REGIONS``);
* ``Roll``: a lip turning about a horizontal line behind it (``θ x̂ × (p − pivot)``), weighted by a
  bump over the lip.

The constants (``BUMPS``, ``ROLLS``) were calibrated as mechanisms against captured expressions
(ICT-FaceKit's shapes: each mechanism's place, reach and amplitude, a dozen numbers, fitted with the
rest of the rig in place and applied to every head from its own landmarks), not as shapes. Reaches
run up to 0.3 of the head height (6.5 cm): a cheek raise or a brow lift moves the whole cheek or
forehead, and no muscle moves skin farther than 0.4 of it from its insertion.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass

import numpy as np

from mimetic.head.shape import smoothstep
from mimetic.rig.anatomy.creases import Crease
from mimetic.rig.anatomy.gaze import gaze_follow_actions
from mimetic.rig.anatomy.local import CHANNELS as LOCAL_CHANNELS
from mimetic.rig.anatomy.local import LOCAL_BUMPS, MIN_WEIGHT, local_actions, local_weights, mass_normals

Action = Crease
"""An action is stored as a crease is: channel gains, vertices and offsets at full activation."""

LIP_REGIONS = ("upper_lip", "lower_lip")
"""A slid bump moves these regions by its motion unslid, as a mass: slid onto each vertex's own
tangent plane, the cheek raise lifted the front of a mouth corner and not the lip's underside a
millimetre away (normals turned 90°), and the small triangles between turned over in joy, wink and
weeping: 91 lip triangles over the library on s115 σ 3, 8 after; s142 σ 3 16 → 2, s132 σ 2 12 → 0
(``benchmarks/sweep_motion.py``'s check heads; s115 was looked at to find it). ICT's fidelity as
before (wire 34.3 %, fem 34.7 %)."""


@dataclass(frozen=True)
class Bump:
    """A tissue mass or sheet moved as one by a muscle (one per side when ``sided``).

    Attributes
    ----------
    name : str
        Action name; ``_L``/``_R`` is appended for sided bumps.
    channel : str
        The channel driving it (side appended for sided bumps).
    anchor : str
        The landmark it is placed from (side appended for sided bumps).
    centre_rel : (3,) float
        Bump centre from the anchor, × head height; x points to the bump's own side (mirrored).
    radii_rel : (3,) float
        Semi-axes along x, y, z, × head height (toward the midline, below and behind the centre when
        ``radii_plus_rel`` is given).
    slide_rel : (3,) float
        Motion at the bump's centre at full activation, × head height, slid onto the surface (a
        ``mass`` moves by it unslid); x to the bump's own side.
    bulge_rel : float
        Motion along the outward normal at full activation, × head height: each vertex's own for a
        sheet, the weighted mean of the bump's normals for a ``mass`` (which moves as one: where the
        lips meet at the corners, vertices a tenth of a millimetre apart have normals up to 0.1 rad apart,
        and a bulge along each turned those slivers over in a pucker).
    sided : bool
        One bump per side (``_L``, ``_R``) or one on the midline.
    mass : bool
        The tissue moves as one mass (the lips, the cheek's fat): the motion is not slid onto the
        surface, and the bump falls off in the face plane, whole through its depth out to
        ``radii_rel[2]`` (``_bump_weights``), so the mass moves through its depth as one: where the
        lips fold into the mouth their inner faces move as their outer ones do instead of shearing
        past them or being overtaken from behind.
    plane : bool
        A sheet over a curved bone (the forehead): the bump falls off in the face plane and is whole
        through its depth as a mass's is, so it follows the forehead back as it curves up and away,
        but its motion is slid onto the surface.
    radii_plus_rel : (3,) float or None
        Semi-axes away from the midline, above and in front of the centre (× head height), for a bump
        that reaches farther on one side than the other; ``None``: ``radii_rel`` on both.
    """

    name: str
    channel: str
    anchor: str
    centre_rel: tuple[float, float, float]
    radii_rel: tuple[float, float, float]
    slide_rel: tuple[float, float, float]
    bulge_rel: float
    sided: bool = True
    mass: bool = False
    plane: bool = False
    radii_plus_rel: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class Roll:
    """A lip turned about a horizontal line (the marginal orbicularis oris rolls it in).

    The lip's vertices (``region``) move by ``angle_rad · x̂ × (p − pivot)`` (a turn about +x by the
    right-hand rule, linearised), weighted by a bump of ``radii_rel`` around the pivot; the pivot is
    ``pivot_rel`` (y, z; × head height) from the ``anchor`` landmark on the midline. Rolling in is a
    positive angle for the upper lip and a negative one for the lower.
    """

    name: str
    channel: str
    anchor: str
    region: str
    pivot_rel: tuple[float, float]
    radii_rel: tuple[float, float, float]
    angle_rad: float


@dataclass(frozen=True)
class Surface:
    """What the action builders read of a rig: rest vertices and normals, skin, landmarks, regions."""

    vertices: np.ndarray  # (n, 3) rig units
    normals: np.ndarray  # (n, 3) unit
    skin: np.ndarray  # (s,) int64, the vertices tissue actions may move
    landmark: Callable[[str], np.ndarray]  # name -> (3,) rest position
    landmarks: frozenset[str]
    regions: dict[str, np.ndarray]
    scale: float  # head height, rig units

    @property
    def lips(self) -> np.ndarray:
        """The vertices (k,) of the lips' regions (``LIP_REGIONS``)."""
        return np.concatenate([self.regions.get(r, np.zeros(0, np.int64)) for r in LIP_REGIONS])


BUMPS: tuple[Bump, ...] = (
    # (name, channel, anchor, centre_rel, radii_rel, slide_rel, bulge_rel[, sided, mass, plane,
    # radii_plus_rel]), see ``Bump``
    # the upper face: the frontalis sheets, the brow depressors, the cheek raiser, the lids
    # browInnerUp: the inner forehead rises with the brow, a sheet over the frontal bone (reaching
    # less far down than fitted: farther, it moved the nose's side, and image-landmark solves took
    # some of the jaw's opening for it)
    Bump(
        "frontalis_sheet_inner",
        "frontalis_inner",
        "brow_inner_mid",
        (-0.0402, 0.0727, 0.0483),
        (0.1855, 0.2, 0.056),
        (0.0047, 0.0098, -0.0069),
        0.0069,
        plane=True,
        radii_plus_rel=(0.2183, 0.0888, 0.056),
    ),
    # browOuterUp: the outer brow and the forehead above and beside it rise
    Bump(
        "frontalis_sheet_outer",
        "frontalis_outer",
        "brow_outer_mid",
        (0.1876, 0.0952, 0.2516),
        (0.3, 0.3, 0.2516),
        (0.0276, 0.0468, -0.0119),
        0.0077,
        plane=True,
        radii_plus_rel=(0.3, 0.0996, 0.2516),
    ),
    # browDown: the brow and the forehead above it draw down, in and forward over the eye
    Bump(
        "corrugator_gather",
        "corrugator",
        "brow_inner_mid",
        (0.0997, 0.0106, 0.0),
        (0.3, 0.1514, 0.15),
        (-0.002, -0.0059, 0.0193),
        0.0026,
        plane=True,
        radii_plus_rel=(0.3, 0.3, 0.15),
    ),
    # cheekSquint (AU6): the cheek rises toward the eye
    Bump(
        "cheek_raise",
        "orbicularis_oculi_outer",
        "eye_outer_corner",
        (-0.0045, -0.1915, -0.1096),
        (0.1916, 0.28, 0.2732),
        (-0.007, 0.0348, 0.0195),
        0.0084,
    ),
    # eyeSquint: the lower lid and the skin under it bunch up and in
    Bump(
        "lower_lid_squint",
        "orbicularis_oculi",
        "eye_lower_lid",
        (-0.0342, -0.0561, -0.0234),
        (0.1047, 0.1791, 0.3),
        (-0.0445, 0.0138, -0.008),
        -0.0153,
        radii_plus_rel=(0.2088, 0.093, 0.0944),
    ),
    # eyeWide: the skin between the lid's margin and its fold drawn up with the lid (the levator)
    Bump(
        "lid_fold_lift",
        "levator_palpebrae",
        "eye_upper_lid",
        (-0.0031, 0.0039, -0.0417),
        (0.1295, 0.0621, 0.0384),
        (0.001, 0.0103, 0.0033),
        -0.0047,
        plane=True,
        radii_plus_rel=(0.1142, 0.0563, 0.0384),
    ),
    # the mid face: the nose's side, the malar fat in a smile, the dimple, the corner drawn down and
    # out, the lower lip pressed, the cheek under pressure
    # noseSneer: the side of the nose and the cheek beside it rise
    Bump(
        "nose_side_lift",
        "levator_labii_nasal",
        "alar_base",
        (0.1171, -0.0341, -0.0647),
        (0.2391, 0.295, 0.1),
        (-0.0024, 0.0316, 0.0102),
        -0.0007,
        mass=True,
    ),
    # mouthSmile: the malar fat piles up over the zygomatic major
    Bump(
        "malar_bulk",
        "zygomatic_major",
        "mouth_corner",
        (0.0602, 0.0417, -0.0954),
        (0.1923, 0.265, 0.1),
        (0.0225, 0.0253, -0.0219),
        0.0015,
        mass=True,
    ),
    # mouthDimple: the cheek beside the corner is drawn back and in
    Bump(
        "dimple",
        "buccinator",
        "mouth_corner",
        (0.0155, -0.0385, -0.0266),
        (0.0876, 0.17, 0.0786),
        (-0.0102, 0.032, -0.0268),
        0.0069,
        mass=True,
        radii_plus_rel=(0.1126, 0.1209, 0.0786),
    ),
    # mouthFrown: the corner and a band of the cheek beside it drawn down (the triangularis); no bulge
    Bump(
        "corner_down",
        "triangularis",
        "mouth_corner",
        (0.0509, -0.0059, -0.0219),
        (0.1078, 0.3, 0.0731),
        (0.0041, -0.0112, 0.0034),
        0.0,
        mass=True,
        radii_plus_rel=(0.1822, 0.3, 0.0731),
    ),
    # mouthStretch: the corner drawn out, down and back (the risorius); no bulge along the normal,
    # which pushed the two faces of the commissure's fold apart and turned them over (fear, weeping)
    Bump(
        "corner_stretch",
        "risorius",
        "mouth_corner",
        (0.0142, 0.0083, -0.0166),
        (0.1, 0.1, 0.1),
        (0.0121, -0.0174, -0.009),
        0.0,
        mass=True,
    ),
    # mouthPress: the lower lip and the chin beside it pressed up and forward (0.6 of the fitted motion:
    # the pucker's incisivis at 1 turned a sliver at the commissure over with all of it)
    Bump(
        "lip_press",
        "orbicularis_oris_incisivis",
        "mouth_corner",
        (-0.031, -0.1386, 0.0194),
        (0.1453, 0.3, 0.11),
        (-0.0023, 0.0118, 0.005),
        0.0,
        mass=True,
        radii_plus_rel=(0.3, 0.1778, 0.11),
    ),
    # cheekPuff: air pushes the cheek and the lips out
    Bump(
        "cheek_puff",
        "cheek_puff",
        "mouth_corner",
        (0.0303, 0.009, -0.0793),
        (0.2506, 0.2134, 0.1),
        (-0.0056, 0.0098, 0.0588),
        0.0045,
        mass=True,
    ),
    # no captured shape: the side of the nose above the wing drawn up and in (the sneer's nasal part)
    Bump("nasalis", "nasalis", "alare", (-0.02, 0.04, 0.0), (0.035, 0.04, 0.04), (-0.006, 0.008, 0.0), 0.0),
    # the lips: sideways together, pushed out into a funnel, protruded in a pucker
    # mouthLeft / mouthRight: the lips and corners slide sideways together
    Bump(
        "mouth_slide",
        "mouth_slide",
        "mouth_corner",
        (-0.1868, -0.0011, -0.0344),
        (0.3, 0.2526, 0.1),
        (0.0657, 0.006, 0.0068),
        0.0027,
        mass=True,
    ),
    # mouthFunnel: both lips pushed forward and out
    Bump(
        "lip_funnel",
        "orbicularis_oris_peripheralis",
        "upper_lip_inner",
        (0.0, -0.0118, -0.0809),
        (0.3, 0.1357, 0.1),
        (0.0, 0.0076, 0.0414),
        0.0024,
        sided=False,
        mass=True,
    ),
    # mouthPucker: the closed lips pushed forward
    Bump(
        "lip_protrusion",
        "orbicularis_oris",
        "upper_lip_inner",
        (0.0, -0.0004, -0.1139),
        (0.3, 0.1309, 0.1),
        (0.0, 0.0073, 0.0396),
        0.0042,
        sided=False,
        mass=True,
    ),
)
"""Every bump, calibrated (with the driving channel at 1, or 0.3 for the orbicularis oculi as ARKit's
eyeSquint drives it, 0.6 for the incisivis as its mouthPress does) against the ICT-FaceKit shape named
in its comment, with the rest of the rig in place. The brows', the lids', the dimple's, the corners'
and the lower lip's bumps (place, one-sided reaches, motion) were fitted on ICT's neutral and its
identity s1 σ1 (reaches then held to 0.3) and checked on identities s101 σ1, s102 σ2 and s105 σ2
(``docs/benchmarks.md``)."""

ROLLS: tuple[Roll, ...] = (
    # mouthRollUpper: the lip rolls in over the teeth
    Roll(
        "lip_roll_upper",
        "orbicularis_oris_marginalis_upper",
        "upper_lip_top",
        "upper_lip",
        (0.042, -0.0384),
        (0.1877, 0.2148, 0.3),
        0.8622,
    ),
    # mouthRollLower: the lip rolls in over the teeth
    Roll(
        "lip_roll_lower",
        "orbicularis_oris_marginalis_lower",
        "lower_lip_bottom",
        "lower_lip",
        (-0.0227, -0.0452),
        (0.1378, 0.1614, 0.1121),
        -1.5185,
    ),
)
"""The lip rolls; see ``Roll``."""


def _bump_weights(
    surface: Surface,
    centre: np.ndarray,
    radii_rel,
    ids: np.ndarray,
    *,
    mass: bool = False,
    radii_plus_rel=None,
    sx: float = 1.0,
) -> tuple:
    """Vertices (k,) among ``ids`` and weights (k,) in (0, 1] of the bump ``(1 − r²)²`` around ``centre``
    (``r`` over the semi-axes ``radii_rel``; over ``radii_plus_rel`` away from the midline, above and
    in front when given, ``sx`` +1 on the subject's left and −1 on the right). A ``mass`` bump
    measures ``r`` in the face plane (x, y) and is whole through its depth out to its depth
    semi-axis, fading to 0 at twice that (a smoothstep in ``|z − centre_z|``)."""
    points = surface.vertices[ids]
    minus = np.asarray(radii_rel, dtype=np.float64) * surface.scale
    plus = minus if radii_plus_rel is None else np.asarray(radii_plus_rel, dtype=np.float64) * surface.scale
    depth = 1.0
    if mass:
        dz = points[:, 2] - centre[2]
        depth = 1.0 - smoothstep(1.0, 2.0, np.abs(dz) / np.where(dz < 0.0, minus[2], plus[2]))
        minus, plus = minus * [1.0, 1.0, np.inf], plus * [1.0, 1.0, np.inf]  # r in the face plane
    w = local_weights(points, centre, minus, plus, sx) * depth
    keep = w > MIN_WEIGHT
    return ids[keep], w[keep]


def slide_onto(direction: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """``direction`` (3,) projected onto the tangent planes of ``normals`` (k, 3): (k, 3)."""
    d = np.asarray(direction, dtype=np.float64)
    return d[None, :] - (normals @ d)[:, None] * normals


def _sides(sided: bool) -> tuple[tuple[str, float], ...]:
    return (("_L", 1.0), ("_R", -1.0)) if sided else (("", 1.0),)


def bump_actions(surface: Surface, bump: Bump, channels: Iterable[str]) -> list[Action]:
    """The actions (one per side, or one) of ``bump`` on ``surface``, for the channels the rig has."""
    channels, out = set(channels), []
    for suffix, sx in _sides(bump.sided):
        channel, anchor = bump.channel + suffix, bump.anchor + suffix
        if channel not in channels or anchor not in surface.landmarks:
            continue
        mirror = np.array([sx, 1.0, 1.0])
        centre = surface.landmark(anchor) + np.asarray(bump.centre_rel) * mirror * surface.scale
        ids, w = _bump_weights(
            surface,
            centre,
            bump.radii_rel,
            surface.skin,
            mass=bump.mass or bump.plane,
            radii_plus_rel=bump.radii_plus_rel,
            sx=sx,
        )
        normals = surface.normals[ids]
        motion = np.asarray(bump.slide_rel) * mirror
        if bump.mass:  # one mass, one bulge
            normals = mass_normals(w, normals)
        slide = np.broadcast_to(motion, normals.shape) if bump.mass else slide_onto(motion, normals)
        if not bump.mass:  # the lips move as a mass: unslid (``LIP_REGIONS``)
            slide = np.where(np.isin(ids, surface.lips)[:, None], motion, slide)
        field = slide + bump.bulge_rel * normals
        out.append(Action(bump.name + suffix, {channel: 1.0}, ids, w[:, None] * field))
    return out


def roll_actions(surface: Surface, roll: Roll, channels: Iterable[str]) -> list[Action]:
    """The action of ``roll`` on ``surface`` (none if the rig lacks its channel, anchor or region)."""
    if roll.channel not in set(channels) or roll.anchor not in surface.landmarks:
        return []
    lip = surface.regions.get(roll.region)
    if lip is None or len(lip) == 0:
        return []
    pivot = surface.landmark(roll.anchor) + np.array([0.0, *roll.pivot_rel]) * surface.scale
    ids, w = _bump_weights(surface, pivot, roll.radii_rel, np.intersect1d(lip, surface.skin))
    arm = surface.vertices[ids] - pivot
    turn = roll.angle_rad * np.cross([1.0, 0.0, 0.0], arm) / surface.scale  # × head height
    return [Action(roll.name, {roll.channel: 1.0}, ids, w[:, None] * turn)]


# --- the tongue: out, tip up, back (what lip sync needs for th, l, t/d and k/g) --------------------
TONGUE_OUT_REL = 0.13
"""How far the tip moves forward at full ``tongue_out``, × head height (past the lips when the jaw
is open); the root stays, so the tongue stretches along its length."""
TONGUE_OUT_DROP_REL = 0.015
"""How far the protruded tip drops onto the lower lip, × head height."""
TONGUE_NARROW = 0.3
"""Share by which the protruded tip narrows (a stretched tongue gets thinner)."""
TONGUE_TIP_UP_RAD = 1.0
"""How far the front half turns up at full ``tongue_tip_up`` (toward the alveolar ridge), radians."""
TONGUE_BACK_REL = 0.025
"""How far the whole tongue draws back at full ``tongue_back``, × head height; its back rises by as
much (it bunches toward the soft palate, as for k and g)."""


def tongue_actions(surface: Surface, tongue: np.ndarray, channels: Iterable[str]) -> list[Action]:
    """``tongue_out``, ``tongue_tip_up`` and ``tongue_back`` on the ``tongue`` vertices (k,).

    Positions along the tongue run from its root (0, the back, smallest z) to its tip (1)."""
    channels = set(channels)
    tongue = np.asarray(tongue, dtype=np.int64)
    if len(tongue) < 4:
        return []
    v = surface.vertices[tongue]
    back, tip = float(v[:, 2].min()), float(v[:, 2].max())
    t = (v[:, 2] - back) / max(tip - back, 1e-12)  # (k,) root 0 … tip 1
    mid_x = float(np.median(v[:, 0]))
    out = []
    if "tongue_out" in channels:
        reach = t**2
        offsets = np.zeros_like(v)
        offsets[:, 2] = TONGUE_OUT_REL * reach
        offsets[:, 1] = -TONGUE_OUT_DROP_REL * reach
        offsets[:, 0] = -TONGUE_NARROW * reach * (v[:, 0] - mid_x) / surface.scale
        out.append(Action("tongue_out", {"tongue_out": 1.0}, tongue, offsets))
    if "tongue_tip_up" in channels:
        hinge = np.array([0.0, float(np.median(v[:, 1])), back + 0.5 * (tip - back)])
        share = np.clip((t - 0.5) / 0.5, 0.0, 1.0) ** 2
        arm = v - hinge
        turn = np.cross([-1.0, 0.0, 0.0], arm) * TONGUE_TIP_UP_RAD  # tip forward of the hinge goes up
        out.append(
            Action("tongue_tip_up", {"tongue_tip_up": 1.0}, tongue, share[:, None] * turn / surface.scale)
        )
    if "tongue_back" in channels:
        offsets = np.zeros_like(v)
        offsets[:, 2] = -TONGUE_BACK_REL
        offsets[:, 1] = TONGUE_BACK_REL * (1.0 - t)
        out.append(Action("tongue_back", {"tongue_back": 1.0}, tongue, offsets))
    return out


CHANNELS: dict[str, tuple[str, str]] = {
    **{
        f"{name}_{side}": (group, doc)
        for side in "LR"
        for name, group, doc in (
            ("cheek_puff", "cheeks", "air pressure puffs the cheek out against the relaxed buccinator"),
            ("mouth_slide", "mouth", "the lips and modiolus slide together toward this side"),
            ("nasalis", "nose", "the nasalis draws the side of the nose above the wing up and in (a sneer)"),
            ("dilator_naris", "nose", "the dilator naris flares the whole nostril wing outward (AU38)"),
        )
    },
    "orbicularis_oris_marginalis_upper": ("mouth", "the marginal orbicularis oris rolls the upper lip in"),
    "orbicularis_oris_marginalis_lower": ("mouth", "the marginal orbicularis oris rolls the lower lip in"),
    "orbicularis_oris_peripheralis": (
        "mouth",
        "the peripheral orbicularis oris pushes the lips out into a funnel",
    ),
    "tongue_out": ("tongue", "the genioglossus pushes the tongue out between the teeth"),
    "tongue_tip_up": ("tongue", "the superior longitudinal muscle lifts the tip toward the alveolar ridge"),
    "tongue_back": ("tongue", "the styloglossus draws the tongue back and up toward the soft palate"),
    **LOCAL_CHANNELS,
}
"""The channels only tissue actions drive: name -> (group, what it does). All run 0..1."""


def find_actions(
    vertices: np.ndarray,
    normals: np.ndarray,
    skin: np.ndarray,
    tongue: np.ndarray,
    landmark: Callable[[str], np.ndarray],
    landmark_names: Iterable[str],
    regions: dict[str, np.ndarray],
    channel_names: Iterable[str],
    scale: float,
) -> tuple[Action, ...]:
    """Every tissue action of a rig: ``BUMPS``, ``ROLLS``, the feature-local ``local.LOCAL_BUMPS``, the
    tongue's and the gaze's (``gaze.gaze_follow_actions``), for the channels it has.

    ``vertices``/``normals`` (n, 3) are the rest mesh (rig units); ``skin`` (s,) the vertices the
    face's tissue actions may move, ``tongue`` (t,) the tongue's (may be empty); ``scale`` the head
    height. Rigs without a channel, landmark or region an action needs simply lack that action.
    """
    channels = set(channel_names)
    surface = Surface(
        np.asarray(vertices, dtype=np.float64),
        np.asarray(normals, dtype=np.float64),
        np.asarray(skin, dtype=np.int64),
        landmark,
        frozenset(landmark_names),
        {k: np.asarray(v, dtype=np.int64) for k, v in regions.items()},
        float(scale),
    )
    out: list[Action] = []
    for bump in BUMPS:
        out += bump_actions(surface, bump, channels)
    for roll in ROLLS:
        out += roll_actions(surface, roll, channels)
    for local in LOCAL_BUMPS:
        out += local_actions(surface, local, channels)
    out += tongue_actions(surface, tongue, channels)
    out += gaze_follow_actions(surface, channels)
    return tuple(a for a in out if len(a.vertices))
