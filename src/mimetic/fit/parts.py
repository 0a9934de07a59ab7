"""The user's separate parts: which connected pieces of a mesh are eyeballs, teeth or a tongue.

A rig's eyeballs turn with their eye bones and its teeth with the head or the jaw; the rest of the
mesh deforms. ``separate_parts`` sorts the user's pieces by where they land on the fitted reference
(its eyeballs, or a box about the user's own mouth) and by their shape: an eyeball's piece is closed
or ends in circles (``_on_eyeball``), not along the lids as the films over an eye do; the mouth's
pieces fall into two rows of teeth, and one spanning both (gums joined to a tongue) is soft, its
jaw weight read from its nearer row (``soft_mouth_jaw``).
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from mimetic.head.shape import smoothstep
from mimetic.mesh.closest import ClosestPoints
from mimetic.mesh.geometry import boundary_paths, connected_components, vertex_areas
from mimetic.mesh.model import Mesh
from mimetic.rig.anatomy.lids import eye_sphere
from mimetic.rig.model import Rig

RIGID_PARTS = dict(eye_L="eye_L", eye_R="eye_R", teeth_upper="head", teeth_lower="jaw", tongue="jaw")
"""The bone each rigid part follows."""
RIGID_SHARE = 0.6  # share of a separate part's vertices landing on one rigid reference part
EYE_REACH = 1.5
"""An eye's piece lies within this × the radius of the sphere through the eye's largest piece from
its centre: a cornea's bulge reaches 1.22 on ICT (its sclera's sphere 1.42 cm); a lash strip reaches
past it (one of ICT's right upper lashes, 0.6 of whose vertices lie nearest the reference eyeball,
1.84) and rides its lid instead (``find_accessories``) rather than turning with the gaze and
staying open over a closed lid."""
RIM_ROUND_REL = 0.03
"""An eye's piece is closed or ends in circles: each rim within this × the eyeball's radius (RMS) of a
plane and of a round. ICT's eye films (tear line, occlusion shell, the inner corner's blend) end along
the lids, 3.8-17 % off their rims' planes on its identity heads and further off round; they ride the lids."""
MAX_TOOTH_SPAN = 2.0  # a mouth part taller than this × the distance between the tooth rows is soft
MOUTH_BOX_REL = ((-1.0, 1.0), (-0.1, 0.8), (-2.5, 0.5))
"""Where the user's mouth parts lie: (low, high) in x, y and z about the mouth's centre (the corners'
midpoint), × the mouth width, but y's low end about the menton. Read off ICT's neutral
and calibration heads s1 σ1 and s4 σ3 (teeth and gums within ±0.85 in x, 0.69 above the centre, 0.35
in front of it and 2.1 behind), with room to spare; checked on s103 and s148 σ3, whose teeth stand
1.5 cm higher than the fitted reference's and were half outside a box around its mouth parts."""


def _two_means(centres: np.ndarray, mesh_ref: Mesh) -> tuple[float, float]:
    """The upper and lower rows' mean heights: 1-D 2-means of the mouth parts' centroid heights
    (started at their widest gap), or the reference's teeth when there are fewer than 2 parts."""
    values = np.sort(centres)
    if len(values) < 2:
        rows = [
            mesh_ref.vertices[mesh_ref.part_vertices(p), 1].mean() for p in ("teeth_upper", "teeth_lower")
        ]
        return float(rows[0]), float(rows[1])
    k = int(np.argmax(np.diff(values)))
    split = 0.5 * (values[k] + values[k + 1])
    for _ in range(10):
        split = 0.5 * (values[values > split].mean() + values[values <= split].mean())
    return float(values[values > split].mean()), float(values[values <= split].mean())


def _on_eyeball(vertices: np.ndarray, faces: np.ndarray, ids: np.ndarray, radius: float) -> bool:
    """Whether the piece ``ids`` (k,) of ``vertices`` (n, 3), ``faces`` (m, 3) turns with an eyeball of
    ``radius``: it is closed, or each rim is a circle (``RIM_ROUND_REL``: a sclera's hole, a limbus, a
    pupil, a half globe's equator); a film ends along the lids and rides them."""
    rims = boundary_paths(faces[np.isin(faces[:, 0], ids)])
    for rim in (*rims.loops, *rims.chains):
        points = vertices[rim] - vertices[rim].mean(axis=0)
        off_plane = np.linalg.svd(points, compute_uv=False)[-1] / np.sqrt(len(points))  # RMS
        off_round = np.linalg.norm(points, axis=1).std()
        if max(off_plane, off_round) > RIM_ROUND_REL * radius:
            return False
    return True


def separate_parts(
    reference: Rig, user: Mesh, in_model: np.ndarray, hit: ClosestPoints
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The user's separate parts: the vertices (sorted) of those that move rigidly, by reference part
    name, and (n_user,) bool marking the soft ones inside the mouth.

    A connected component of the user's mesh is an eyeball when ``RIGID_SHARE`` of its vertices land
    on a reference eyeball, it lies within ``EYE_REACH`` of the sphere through that eye's largest
    such piece, and it is closed or ends in circles (``_on_eyeball``), not a film over the eye. It
    is in the mouth when that share lies in the box ``MOUTH_BOX_REL`` sets
    about the mouth's landmarks (on the user's skin, not the fitted reference's mouth parts, which stand
    off a σ 3 identity's teeth by 1.5 cm). The mouth parts' centroid heights fall into two rows
    (the user's upper and lower teeth; 1-D 2-means): a part no taller than ``MAX_TOOTH_SPAN`` times
    the distance between the rows follows the head when its centroid is in the upper row's half and
    the jaw otherwise; a taller one (gums joined to the tongue, a mouth cavity) is soft (see
    ``soft_mouth_jaw``).

    A centroid is the part's area centroid (``vertex_areas``), not the mean of its vertices: the
    rows are the surfaces' and do not move with how the teeth are sampled. A decimated copy keeps a
    tooth's vertices unevenly, which moved the vertex means of ICT's teeth (each decimated from
    5-13k vertices to 300 in a 1.68M head's working copy) 0.5 cm further apart: the rows
    stood 2.09 cm apart instead of 1.60, and the 4.1 cm tall gums-and-tongue piece turned with the
    jaw as lower teeth.
    """
    mesh_ref = reference.mesh
    ref_part = np.full(mesh_ref.n_faces, "", dtype=object)
    for name, faces in mesh_ref.parts.items():
        ref_part[faces] = name
    vertex_part = ref_part[hit.faces].astype(str)
    y = in_model[:, 1]  # the user's vertices in the reference frame
    corners, menton = np.split(
        reference.landmark_positions(["mouth_corner_L", "mouth_corner_R", "menton"]), [2]
    )
    width = np.linalg.norm(corners[0] - corners[1])
    centre = corners.mean(axis=0)
    low, high = (np.array(MOUTH_BOX_REL) * width).T
    box = (centre + low, centre + high)
    box[0][1] = menton[0, 1] + low[1]  # the lower teeth reach down to the chin
    _, label = connected_components(user.faces, user.n_vertices)
    order = np.argsort(label, kind="stable")
    starts = np.flatnonzero(np.diff(label[order], prepend=-1))
    rigid: dict[str, list[np.ndarray]] = {}
    eyes: dict[str, list[np.ndarray]] = {}
    mouth: list[tuple[np.ndarray, dict[str, float]]] = []
    soft = np.zeros(user.n_vertices, dtype=bool)
    for ids in np.split(order, starts[1:]):
        if len(ids) > user.n_vertices // 2:  # the skin
            continue
        names, counts = np.unique(vertex_part[ids], return_counts=True)
        share = dict(zip(names.tolist(), (counts / len(ids)).tolist(), strict=True))
        eye = max(("eye_L", "eye_R"), key=lambda p: share.get(p, 0.0))
        if share.get(eye, 0.0) >= RIGID_SHARE:
            eyes.setdefault(eye, []).append(ids)
        elif np.mean(np.all((in_model[ids] >= box[0]) & (in_model[ids] <= box[1]), axis=1)) >= RIGID_SHARE:
            mouth.append((ids, share))
    for eye, pieces in eyes.items():
        centre, radius = eye_sphere(in_model[max(pieces, key=len)])
        inside = [
            ids
            for ids in pieces
            if np.linalg.norm(in_model[ids] - centre, axis=1).max() <= EYE_REACH * radius
            and _on_eyeball(in_model, user.faces, ids, radius)
        ]
        if inside:
            rigid[eye] = inside
    if mouth:
        area = vertex_areas(in_model, user.faces)  # (n,) area centroids, whatever the sampling
        centres = np.array(
            [np.average(y[ids], weights=area[ids] if area[ids].any() else None) for ids, _ in mouth]
        )
        upper_mean, lower_mean = _two_means(centres, mesh_ref)
        occlusal = 0.5 * (upper_mean + lower_mean)
        for (ids, share), centre in zip(mouth, centres, strict=True):
            if np.ptp(y[ids]) > MAX_TOOTH_SPAN * (upper_mean - lower_mean):
                soft[ids] = True  # spans both rows: gums, tongue or cavity
                continue
            if centre > occlusal:
                rigid.setdefault("teeth_upper", []).append(ids)
            else:
                rigid.setdefault("tongue" if share.get("tongue", 0.0) > 0.5 else "teeth_lower", []).append(
                    ids
                )
    return {part: np.sort(np.concatenate(ids)) for part, ids in rigid.items()}, soft


def soft_mouth_jaw(points: np.ndarray, upper_teeth: np.ndarray, lower_teeth: np.ndarray) -> np.ndarray:
    """Jaw weight (k,) of soft mouth vertices ``points`` (k, 3) from their distances to the upper and
    lower teeth's vertices (reference frame): ``smoothstep(0.3, 0.7, d_upper / (d_upper + d_lower))``.

    Gums joined to the tongue in one piece (as in ICT-FaceKit) would otherwise take weights from
    whichever reference surface lies nearest, blended ones that drag the upper gums down into a
    grille when the jaw opens. The nearer row decides instead: the gums and their papillae between
    the teeth follow their own row, the tongue inside the lower arch rides the jaw, and only the
    back, where the two gums meet, stretches.
    """
    d_upper, _ = cKDTree(upper_teeth).query(points)
    d_lower, _ = cKDTree(lower_teeth).query(points)
    return smoothstep(0.3, 0.7, d_upper / np.maximum(d_upper + d_lower, 1e-12))
