"""Feature-local tissue actions: small muscles whose reach is the feature they move, not the head.

The brow's head, the nose's tip, wing and side are moved by muscles a few millimetres to a
centimetre long (the depressor supercilii, the depressor septi nasi, the two parts of the nasalis).
A field sized by the head height (``actions.Bump``) either misses such a feature on a small nose or
drags the cheek and the lid with it on a large one. Each ``LocalBump`` is therefore placed and
sized by the feature it moves, measured on each head from its own landmarks (``feature_widths``):

* the **nose width**, alare to alare, for the nose's actions;
* the **eye width**, inner to outer canthus on the action's side, for the brow's.

A bump is ``w = (1 − s²)²``, ``s = max(r − core, 0) / (1 − core)``: whole out to ``core`` of its
reach (a feature moved as one: the whole wing of the nose, not its middle), then falling smoothly to
0, with ``r`` measured over semi-axes that may differ on either side of its centre
(``reach_minus`` toward the midline, down and back; ``reach_plus`` away from the midline, up and
forward). That makes it one-sided where the anatomy is: the brow's head drags the forehead
above it but not the lid skin below it. Its motion at full activation is a vector in feature widths
(x toward the bump's own side), either slid onto the surface (skin sliding over bone: the brow) or
the same for every vertex (a mass: the nose's cartilage and the tissue on it), plus a bulge along
the tissue normal (a mass's: the weighted mean of its normals, so it bulges as one).

The numbers in ``LOCAL_BUMPS`` are anatomical, not fitted to a captured shape: each centre is a
landmark (or the mean of two), each reach about the extent of the tissue the muscle inserts into,
and each amplitude what the literature and ordinary observation give for the motion (the brow's
head drops 3–5 mm in a frown, a flared wing moves out about 2 mm, a nose tip pulled down about
2 mm). In feature widths they carry to every head unchanged.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from mimetic.rig.anatomy.creases import Crease

if TYPE_CHECKING:
    from mimetic.rig.anatomy.actions import Surface

MIN_WEIGHT = 1e-3
"""Vertices a field moves by less than this share of its amplitude are left out (here and in
``actions``)."""


@dataclass(frozen=True)
class LocalBump:
    """A tissue action sized by the feature it moves (one per side when ``sided``).

    Attributes
    ----------
    name : str
        Action name; ``_L``/``_R`` is appended for sided bumps.
    channel : str
        The channel driving it (side appended for sided bumps).
    anchors : tuple of str
        Landmarks whose mean places the bump (side appended to each sided landmark that the rig
        has only per side, e.g. ``alare`` → ``alare_L``).
    feature : str
        ``"nose"`` or ``"eye"``: the width (``feature_widths``) every length below is a fraction of.
    centre : (3,) float
        Bump centre from the anchors' mean, × the feature width; x toward the bump's own side.
    reach_minus, reach_plus : (3,) float
        Semi-axes (× the feature width) on the −/+ side of the centre along x (toward the midline /
        away from it), y (down / up) and z (back / forward).
    motion : (3,) float
        Motion at the centre at full activation, × the feature width; x toward the bump's own side.
    bulge : float
        Motion along the outward tissue normal at the centre at full activation, × the feature width.
    slide : bool
        The motion is slid onto the surface (skin over bone), else the same for every vertex (a mass).
    core : float
        Share of the reach, in [0, 1), moved whole before the falloff begins.
    sided : bool
        One bump per side (``_L``, ``_R``) or one on the midline.
    """

    name: str
    channel: str
    anchors: tuple[str, ...]
    feature: str
    centre: tuple[float, float, float]
    reach_minus: tuple[float, float, float]
    reach_plus: tuple[float, float, float]
    motion: tuple[float, float, float]
    bulge: float = 0.0
    slide: bool = False
    core: float = 0.0
    sided: bool = True


# The wing of the nose is placed from the mean of its outermost point (alare) and its nostril, a little
# above: the lobule around them is what the alar muscles move, whole; its reach spans the wing from the
# nostril's middle out past the alar groove and from the nostril sill up to the wing's top.
_WING = ("alare", "nostril")
_WING_CENTRE, _WING_MINUS, _WING_PLUS = (0.0, 0.05, 0.0), (0.24, 0.24, 0.35), (0.33, 0.24, 0.35)

LOCAL_BUMPS: tuple[LocalBump, ...] = (
    # the brow lowerer's own muscle: the brow's head drawn down over the inner canthus (AU4); the
    # forehead above follows, the lid below does not (a short reach down), the brow's tail barely
    LocalBump(
        "brow_head_lower",
        "depressor_supercilii",
        ("brow_inner",),
        "eye",
        (0.05, 0.0, 0.0),
        (0.35, 0.2, 0.5),
        (0.6, 0.6, 0.5),
        (-0.03, -0.15, 0.0),
        bulge=0.015,
        slide=True,
        core=0.2,
    ),
    # the depressor septi nasi: the tip and columella drawn down (and back), the top of the upper lip
    # below them shortened; the wings and the lip's red do not follow
    LocalBump(
        "nose_tip_lower",
        "depressor_septi",
        ("nose_tip", "subnasale"),
        "nose",
        (0.0, 0.0, 0.0),
        (0.25, 0.5, 0.5),
        (0.25, 0.55, 0.45),
        (0.0, -0.06, -0.015),
        core=0.3,
        sided=False,
    ),
    # the alar nasalis (depressor alae nasi): the whole wing drawn down
    LocalBump(
        "wing_lower",
        "nasalis_alar",
        _WING,
        "nose",
        _WING_CENTRE,
        _WING_MINUS,
        _WING_PLUS,
        (0.01, -0.05, 0.0),
        core=0.45,
    ),
    # the dilator naris: the whole wing flared outward, the nostril opening with it
    LocalBump(
        "wing_flare",
        "dilator_naris",
        _WING,
        "nose",
        _WING_CENTRE,
        _WING_MINUS,
        _WING_PLUS,
        (0.06, 0.005, 0.0),
        bulge=0.01,
        core=0.45,
    ),
    # the transverse nasalis (compressor naris): the side of the nose over the bridge drawn in toward
    # the dorsum, the wing's top with it (the nostril narrows); the dorsum itself cannot move inward
    LocalBump(
        "nose_side_compress",
        "nasalis_transverse",
        ("nose_bridge_lower", "alare"),
        "nose",
        (0.0, -0.05, 0.0),
        (0.25, 0.45, 0.35),
        (0.3, 0.65, 0.35),
        (-0.045, 0.005, 0.0),
        core=0.3,
    ),
)
"""The feature-local actions; see ``LocalBump`` and the module docstring for where the numbers come from."""

CHANNELS: dict[str, tuple[str, str]] = {
    **{
        f"{name}_{side}": (group, doc)
        for side in "LR"
        for name, group, doc in (
            (
                "depressor_supercilii",
                "brows",
                "the depressor supercilii draws the brow's head down over the inner canthus (AU4)",
            ),
            ("nasalis_alar", "nose", "the alar nasalis (depressor alae nasi) draws the nostril's wing down"),
            (
                "nasalis_transverse",
                "nose",
                "the transverse nasalis (compressor naris) narrows the nose's side over the bridge (AU39)",
            ),
        )
    },
    "depressor_septi": (
        "nose",
        "the depressor septi nasi draws the nose's tip down and shortens the upper lip",
    ),
}
"""The channels only feature-local actions drive: name -> (group, what it does). All run 0..1.
(``dilator_naris_L/R`` is ``actions.CHANNELS``'s; its field is built here.)"""


def feature_widths(surface: Surface, side: str) -> dict[str, float]:
    """The widths (rig units) the local actions of ``side`` ("L", "R" or "" for the midline) are
    sized by: ``"nose"`` alare to alare, ``"eye"`` the side's inner to outer canthus (the mean of
    both eyes on the midline). Features whose landmarks the rig lacks are missing."""
    out = {}
    if {"alare_L", "alare_R"} <= surface.landmarks:
        out["nose"] = float(np.linalg.norm(surface.landmark("alare_L") - surface.landmark("alare_R")))
    eyes = [
        float(
            np.linalg.norm(
                surface.landmark(f"eye_outer_corner_{s}") - surface.landmark(f"eye_inner_corner_{s}")
            )
        )
        for s in ((side,) if side else ("L", "R"))
        if {f"eye_outer_corner_{s}", f"eye_inner_corner_{s}"} <= surface.landmarks
    ]
    if eyes:
        out["eye"] = float(np.mean(eyes))
    return out


def local_weights(
    points: np.ndarray,
    centre: np.ndarray,
    reach_minus: np.ndarray,
    reach_plus: np.ndarray,
    sx: float,
    core: float = 0.0,
) -> np.ndarray:
    """Weights (k,) in [0, 1] of the bump ``(1 − s²)²``, ``s = max(r − core, 0) / (1 − core)``, at
    ``points`` (k, 3) around ``centre`` (3,).

    ``r`` is the offset over the semi-axes ``reach_minus`` (3,) on the side of the centre toward the
    midline, below and behind, ``reach_plus`` (3,) on the other, in the units of ``points``; ``sx``
    is +1 on the subject's left and the midline, −1 on the right (so x away from the midline is +x·sx).
    """
    d = (points - centre) * np.array([sx, 1.0, 1.0])
    r = np.linalg.norm(d / np.where(d < 0.0, reach_minus, reach_plus), axis=1)
    s = np.clip((r - core) / (1.0 - core), 0.0, 1.0)
    return (1.0 - s * s) ** 2


def _sided(surface: Surface, name: str, suffix: str) -> str:
    """``name`` with the side ``suffix`` when the rig has the landmark only per side."""
    return name if name in surface.landmarks or not suffix else name + suffix


def mass_normals(weights: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """One outward normal for a mass (k, 3): the ``weights`` (k,) weighted mean of its vertices'
    ``normals`` (k, 3), normalised, for every vertex, so the mass bulges as one."""
    if not len(weights):
        return normals
    outward = weights @ normals
    return np.broadcast_to(outward / np.linalg.norm(outward), normals.shape)


def local_actions(surface: Surface, bump: LocalBump, channels: Iterable[str]) -> list[Crease]:
    """The actions (one per side, or one) of ``bump`` on ``surface``, for the channels the rig has;
    none where the rig lacks a landmark it is placed or sized from."""
    channels, out = set(channels), []
    for suffix, sx in (("_L", 1.0), ("_R", -1.0)) if bump.sided else (("", 1.0),):
        channel = bump.channel + suffix
        anchors = [_sided(surface, a, suffix) for a in bump.anchors]
        width = feature_widths(surface, suffix[1:]).get(bump.feature)
        if channel not in channels or width is None or not set(anchors) <= surface.landmarks:
            continue
        mirror = np.array([sx, 1.0, 1.0])
        anchor = np.mean([surface.landmark(a) for a in anchors], axis=0)
        centre = anchor + np.asarray(bump.centre) * mirror * width
        w = local_weights(
            surface.vertices[surface.skin],
            centre,
            np.asarray(bump.reach_minus) * width,
            np.asarray(bump.reach_plus) * width,
            sx,
            bump.core,
        )
        keep = w > MIN_WEIGHT
        ids, w = surface.skin[keep], w[keep]
        normals = surface.normals[ids]
        motion = np.asarray(bump.motion) * mirror * width
        if bump.slide:
            motion = motion[None, :] - (normals @ motion)[:, None] * normals
        else:  # a mass bulges as one
            normals = mass_normals(w, normals)
        field = motion + bump.bulge * width * normals
        out.append(Crease(bump.name + suffix, {channel: 1.0}, ids, w[:, None] * field / surface.scale))
    return out
