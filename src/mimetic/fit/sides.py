"""Which side of an opening (the lips, the lids) each of a user's vertices takes its rig data from.

A user vertex nearer the upper margin of an opening than the lower along its surface
(``mesh.openings.opening_sides``, a geodesic Voronoi split) takes its data from the reference's side
of that opening's upper margin, and likewise below (``fit.transfer``): overlapping lips, or a
fitted lip line a few millimetres off, would otherwise hand the upper lip's inner surface the lower
lip's weights and wires, and its triangles fold as the lips part. The lips' split is seeded by
their fronts as well as their margins (``lip_seeds``), since a margin can hide.
"""

from __future__ import annotations

import numpy as np

from mimetic.mesh.openings import Opening, margin_distance, opening_margins, opening_sides

SIDE_REACH = {"eye": 0.4, "mouth": 0.6}
"""Data keeps to its side of an opening within this × the opening's width of its margins, along the
surface (1.2 cm around an eye, 3 cm around the mouth: the lips' inner surfaces and the cavity's front)."""
CORNER_FREE_REL = 0.1
"""... except within this × the width of either corner (along the line through them), where the
margins meet and which side a vertex is on is a matter of millimetres (the corners blend both)."""
LIP_FRONT_REL = (0.12, 0.18)
"""Each lip's front seeds lie this far (× the mouth's width) above or below the opening's line
(``lip_seeds``): about the vermilion's border, set from ICT's lip heights (upper 0.17, lower 0.19 ×
its 5.1 cm mouth width), not fitted on any head's motion."""
LIP_FRONT_INSET = 0.15
"""... and this far (× the width) in from either corner, where the lips' fronts meet."""
SEED_SIDE_RATIO = 0.5
"""A margin seed goes to the other lip's side when that lip's front is nearer than this × its own
along the skin (a lower lip's top hidden inside the upper lip, taken for the upper margin). Chosen
on the sweep's calibration heads: at 1 (the nearer front) ICT identities s1 σ 1 and σ 2 lost 0.5
and 0.8 points of fidelity and s4 σ 2 gained 2 lip flips; at 0.5 every calibration head is as
before. Check heads: s103 σ 3's widest edge at the jaw drop 0.59 → 0.39 cm, flips 44 → 7; no
other head moves."""


def lip_seeds(
    points: np.ndarray,
    faces: np.ndarray,
    normals: np.ndarray,
    mouth: Opening,
    upper: np.ndarray,
    lower: np.ndarray,
    reach: float,
) -> tuple[np.ndarray, np.ndarray]:
    """The seeds (a,), (b,) int64 of the lips' geodesic split (``opening_sides``): each lip's front
    and the margin seeds ``upper``, ``lower``, a margin seed moved to the other side where that
    side's front is clearly nearer along the surface of ``points`` (n, 3) (``SEED_SIDE_RATIO``,
    within ``reach``).

    A lip's front is the forward-facing skin (``normals`` (n, 3)) between ``LIP_FRONT_REL`` × the
    mouth's width above the opening's upper line (upper) or below its lower line (lower), seen from
    the front, away from the corners and not behind the lips: on any head it is where the lip
    shows. Its margin is not: where a lower lip rises behind the upper lip's edge (lips that
    overlap), no lower margin is found over a stretch, or its hidden top is taken for the upper
    margin (the rim's normal points down), and the split then hands that stretch of the lower lip,
    and the chin below it, the upper lip's side.
    """
    used = np.zeros(len(points), dtype=bool)
    used[faces.ravel()] = True
    used = np.flatnonzero(used)
    p = points[used]
    near, far = LIP_FRONT_REL[0] * mouth.width, LIP_FRONT_REL[1] * mouth.width
    above = p[:, 1] - np.interp(p[:, 0], mouth.upper[:, 0], mouth.upper[:, 1])
    below = np.interp(p[:, 0], mouth.lower[:, 0], mouth.lower[:, 1]) - p[:, 1]
    depth = np.interp(p[:, 0], mouth.upper[:, 0], mouth.upper[:, 2]) - p[:, 2]
    front = mouth.between_corners(p, LIP_FRONT_INSET) & (normals[used, 2] > 0.5) & (depth < far)
    front_upper = used[front & (above > near) & (above < far)]
    front_lower = used[front & (below > near) & (below < far)]
    to_front_upper = margin_distance(points, faces, front_upper, reach)
    to_front_lower = margin_distance(points, faces, front_lower, reach)
    up_moves = to_front_lower[upper] < SEED_SIDE_RATIO * to_front_upper[upper]
    lo_moves = to_front_upper[lower] < SEED_SIDE_RATIO * to_front_lower[lower]
    to_upper = np.concatenate([upper[~up_moves], lower[lo_moves]])
    to_lower = np.concatenate([lower[~lo_moves], upper[up_moves]])
    return np.union1d(to_upper, front_upper), np.union1d(to_lower, front_lower)


def sides_of(
    points: np.ndarray,
    faces: np.ndarray,
    normals: np.ndarray,
    ref_vertices: np.ndarray,
    ref_faces: np.ndarray,
    feature: str,
    opening: Opening,
    ref_margins: tuple[np.ndarray, np.ndarray],
) -> tuple[np.ndarray, np.ndarray]:
    """The side of opening ``feature`` (``"mouth"``, ``"eye_L"``, ...) of each user vertex
    (``points`` (n, 3), ``faces``, ``normals`` (n, 3), in the reference frame) and of each reference
    vertex (``ref_vertices`` (r, 3), ``ref_faces``; the reference's margins ``ref_margins``): (n,),
    (r,) int8, +1 upper, −1 lower, 0 neither (out of reach, or the user's within ``CORNER_FREE_REL``
    of a corner)."""
    reach = SIDE_REACH[feature.split("_")[0]] * opening.width
    seeds = opening_margins(points, faces, {feature: opening})[feature]
    ref_reach = reach
    if feature == "mouth":
        seeds = lip_seeds(points, faces, normals, opening, *seeds, reach)
        ref_reach += LIP_FRONT_REL[1] * opening.width  # every sided user vertex finds its side there
    user_side = opening_sides(points, faces, *seeds, reach)
    user_side[~opening.between_corners(points, CORNER_FREE_REL)] = 0
    return user_side, opening_sides(ref_vertices, ref_faces, *ref_margins, ref_reach)
