"""Which side of an opening (the lips, the lids) each of a user's vertices takes its rig data from.

A user vertex nearer an opening's upper seeds than its lower ones along its surface
(``mesh.openings.opening_sides``, a geodesic Voronoi split) takes its data from the reference's side
of that opening's upper margin, and likewise below (``fit.transfer``): overlapping lips, or a
fitted lip line a few millimetres off, would otherwise hand the upper lip's inner surface the lower
lip's weights and wires, and its triangles fold as the lips part. The lids' split is seeded by their
margins, the lips' by their fronts (``lip_seeds``): a lip's margin can hide behind the other lip.
"""

from __future__ import annotations

import numpy as np

from mimetic.mesh.openings import Opening, opening_margins, opening_sides

SIDE_REACH = {"eye": 0.4, "mouth": 0.6}
"""Data keeps to its side of an opening within this × the opening's width of its seeds, along the
surface (1.2 cm around an eye, 3 cm around the mouth: the lips' inner surfaces and the cavity's front)."""
CORNER_FREE_REL = 0.1
"""... except within this × the width of either corner (along the line through them), where the
margins meet and which side a vertex is on is a matter of millimetres (the corners blend both)."""
LIP_FRONT_REL = (0.12, 0.18)
"""Each lip's front seeds lie this far (× the mouth's width) above or below the opening's line
(``lip_seeds``): about the vermilion's border, set from ICT's lip heights (upper 0.17, lower 0.19 ×
its 5.1 cm mouth width), not fitted on any head's motion."""
SEAL_DEPTH_REL, SEAL_BAND_REL = 0.1, 0.1
"""A mouth with a surface this far (× its width) behind its lips' line, within this of that line up or
down between the corners, has insides (``seal_faces``): ICT's lips' inner surfaces and cavity run 2 cm
back; MediaPipe's mask has nothing behind its lips."""
LIP_FRONT_INSET = 0.15
"""... and this far (× the width) in from either corner, where the lips' fronts meet."""


def _from_lips(points: np.ndarray, mouth: Opening) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """How far each of ``points`` (k, 3) lies above ``mouth``'s upper line, below its lower line and
    behind its upper line, seen from the front at its own x: three (k,) arrays, mesh units."""
    above = points[:, 1] - np.interp(points[:, 0], mouth.upper[:, 0], mouth.upper[:, 1])
    below = np.interp(points[:, 0], mouth.lower[:, 0], mouth.lower[:, 1]) - points[:, 1]
    depth = np.interp(points[:, 0], mouth.upper[:, 0], mouth.upper[:, 2]) - points[:, 2]
    return above, below, depth


def lip_seeds(
    points: np.ndarray, faces: np.ndarray, normals: np.ndarray, mouth: Opening
) -> tuple[np.ndarray, np.ndarray]:
    """The seeds (a,), (b,) int64 of the lips' geodesic split (``opening_sides``): each lip's front.

    A lip's front is the forward-facing skin (``normals`` (n, 3)) of ``points`` (n, 3) between
    ``LIP_FRONT_REL`` × the mouth's width above the opening's upper line (upper) or below its lower
    line (lower), seen from the front, away from the corners and not behind the lips: on any head it
    is where the lip shows. Its margin is not: where a lower lip rises behind the upper lip's edge
    (lips that overlap), no lower margin is found over a stretch, or its hidden top is taken for the
    upper margin (the rim's normal points down); an upper margin seeded there, with no lower one
    across from it, is nearer the lower lip's inner surface along the mesh than the lower lip's front
    is, and hands it the upper lip's side (s112 σ 3: 30 lip triangles turned over in the library).
    """
    used = np.zeros(len(points), dtype=bool)
    used[faces.ravel()] = True
    used = np.flatnonzero(used)
    p = points[used]
    near, far = LIP_FRONT_REL[0] * mouth.width, LIP_FRONT_REL[1] * mouth.width
    above, below, depth = _from_lips(p, mouth)
    front = mouth.between_corners(p, LIP_FRONT_INSET) & (normals[used, 2] > 0.5) & (depth < far)
    return used[front & (above > near) & (above < far)], used[front & (below > near) & (below < far)]


def seal_faces(points: np.ndarray, faces: np.ndarray, mouth: Opening) -> np.ndarray:
    """(m,) bool: the ``faces`` (m, 3) of ``points`` (n, 3) that close a mouth modelled shut.

    A mouth is modelled shut when nothing lies behind its lips (no inner surface, no cavity: a
    mask such as MediaPipe's canonical mesh, or a scan); its sealing faces are those with a vertex
    above the lips' line (``mouth``'s upper margin, seen from the front) and one below it, between
    the corners (``CORNER_FREE_REL`` in from each). A head with a mouth inside has none: its lips
    curl over that line where they touch (ICT's), and they are the lips' own faces. MediaPipe's
    seal runs from the upper lip's inner edge to the lower's, 0.55 cm apart; the lips' split and the
    jaw weight's diffusion ran through it and handed the upper lip's inner edge the lower lip's side
    (its jaw weight 0.5-0.6)."""
    above, below, depth = _from_lips(points, mouth)
    between = mouth.between_corners(points, CORNER_FREE_REL)
    used = np.zeros(len(points), dtype=bool)
    used[faces.ravel()] = True
    near_line = (above < SEAL_BAND_REL * mouth.width) & (below < SEAL_BAND_REL * mouth.width)
    if (used & between & near_line & (depth > SEAL_DEPTH_REL * mouth.width)).any():
        return np.zeros(len(faces), dtype=bool)  # the lips have insides: a mouth, not a seal
    return (between & (above > 0))[faces].any(axis=1) & (between & (below > 0))[faces].any(axis=1)


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
    ref_reach = reach
    if feature == "mouth":
        seeds = lip_seeds(points, faces, normals, opening)
        ref_reach += LIP_FRONT_REL[1] * opening.width  # every sided user vertex finds its side there
        split = faces[~seal_faces(points, faces, opening)]  # the lips of a mouth modelled shut part
    else:
        seeds = opening_margins(points, faces, {feature: opening})[feature]
        split = faces
    user_side = opening_sides(points, split, *seeds, reach)
    user_side[~opening.between_corners(points, CORNER_FREE_REL)] = 0
    return user_side, opening_sides(ref_vertices, ref_faces, *ref_margins, ref_reach)
