"""The skin around an eye follows the eye: a soft turn of the lids and the orbit's skin with the gaze.

When an eye turns, its lids and the skin around the orbit go part of the way with it: the cornea's
bulge carries the lid margins, the conjunctiva and the orbit's fat draw the lids' skin after them,
and the inner corner, tied to the nose by the medial canthal tendon, moves least. ICT-FaceKit's
captured ``eyeLookIn``/``eyeLookOut`` shapes show it as a smooth turn about the eyeball, largest a
little toward the outer corner and fading over about an eye width; a lid plate turned rigidly with
the eye (what the lid bones did) moves a band with hard edges, tears the corners, and reproduced
those shapes to 54–61 %.

``gaze_follow_actions`` builds, per eye, two tissue actions linear in the gaze: each skin vertex turns
about the vertical (yaw) or the horizontal (pitch) through the eyeball's centre by
``GAZE_SKIN_FOLLOW`` of the eye's turn times a bump ``local.local_weights`` (whole at its centre, 0
at its reach), linearised. Each eye's yaw is ``gaze_yaw`` plus or minus half of
``gaze_convergence``, its pitch ``gaze_pitch`` plus or minus half of ``gaze_vertical_vergence``
(``engines.skinning``), so the actions' gains are those. The upper lid's
bone follows a little more of the pitch (``skinning.LID_FOLLOWS_GAZE``), so its margin rides the
cornea down about half-way. Everything is sized by the eye's own width, inner to outer canthus
(``local.feature_widths``), so it carries to every head.

Fitted as a mechanism (place, reach, pivot; not as shapes) on ICT's neutral and its identity s1 σ1
with the rest of the rig in place (free least squares of ICT's eight ``eyeLook`` shapes on the baked
basis plus the yaw field: mean residual 47.6 → 33.9 % on the neutral, 34.1 % on s1 σ1, against
41.6 % with the same field centred between the corners and 45 % for a plain sideways slide; 31 %
with the pitch field too). The amount it follows is not fitted (ICT's eyeballs do not turn in its
shapes): half the eye's turn at the centre, what the lid plates followed of the pitch before.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import TYPE_CHECKING

import numpy as np

from mimetic.rig.anatomy.creases import Crease
from mimetic.rig.anatomy.local import MIN_WEIGHT, feature_widths, local_weights

if TYPE_CHECKING:
    from mimetic.rig.anatomy.actions import Surface

GAZE_SKIN_FOLLOW = 0.5
"""How far the skin at the field's centre turns with its eye, rad per rad of the eye's turn (the lid
margins, a little off the centre, follow about a third: a few millimetres at a full look aside)."""
GAZE_SKIN_CENTRE = (0.2, 0.0, 0.0)
"""The field's centre from the midpoint of the eye's corners, × the eye width; x toward the outer
corner (the inner corner is held by the medial canthal tendon)."""
GAZE_SKIN_REACH = (0.9, 0.9, 1.0)
"""The field's semi-axes along x, y and z, × the eye width: it fades to 0 about an eye width away."""
GAZE_PIVOT_BACK = 0.45
"""The eyeball's centre, the pivot of the turn, behind the corners' midpoint, × the eye width (its
radius: 1.25 cm on ICT's 2.85 cm wide eyes)."""


def gaze_follow_actions(surface: Surface, channels: Iterable[str]) -> list[Crease]:
    """Two actions per eye: ``gaze_follow_yaw_L`` turns the skin around the left eye outward with the
    eye's yaw, ``gaze_follow_pitch_L`` up with its pitch (likewise ``_R``). None for an eye whose
    corners the rig lacks, or for a gaze channel the rig lacks."""
    channels = set(channels)
    out = []
    for side, sx in (("L", 1.0), ("R", -1.0)):
        width = feature_widths(surface, side).get("eye")
        if width is None:
            continue
        inner, outer = (surface.landmark(f"eye_{c}_corner_{side}") for c in ("inner", "outer"))
        mid = 0.5 * (inner + outer)
        reach = np.asarray(GAZE_SKIN_REACH) * width
        centre = mid + np.asarray(GAZE_SKIN_CENTRE) * np.array([sx, 1.0, 1.0]) * width
        w = local_weights(surface.vertices[surface.skin], centre, reach, reach, sx)
        keep = w > MIN_WEIGHT
        ids = surface.skin[keep]
        arm = surface.vertices[ids] - (mid - np.array([0.0, 0.0, GAZE_PIVOT_BACK * width]))
        follow = GAZE_SKIN_FOLLOW * w[keep, None] / surface.scale  # per rad, × head height
        if "gaze_yaw" in channels:
            # the eye turns outward (to its own side) by gaze_yaw on the left and −gaze_yaw on the
            # right, and inward by half the convergence on both
            gains = {"gaze_yaw": sx} | ({"gaze_convergence": -0.5} if "gaze_convergence" in channels else {})
            outward = follow * np.cross([0.0, sx, 0.0], arm)
            out.append(Crease(f"gaze_follow_yaw_{side}", gains, ids, outward))
        if "gaze_pitch" in channels:  # looking up turns the eye about −X
            upward = follow * np.cross([-1.0, 0.0, 0.0], arm)
            # and up by gaze_pitch plus half the vertical vergence on the left, minus on the right
            vertical = {"gaze_vertical_vergence": 0.5 * sx} if "gaze_vertical_vergence" in channels else {}
            gains = {"gaze_pitch": 1.0} | vertical
            out.append(Crease(f"gaze_follow_pitch_{side}", gains, ids, upward))
    return out
