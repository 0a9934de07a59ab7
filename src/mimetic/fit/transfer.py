"""Transfer a rig from the fitted reference onto the user's own mesh (the Maskle idea).

Every user vertex finds its closest point on the fitted reference, skipping reference triangles
that face away from the vertex's normal (so the underside of the upper lip never takes the lower
lip's weights, even where the lips nearly touch), and takes the barycentric interpolation of the
reference's per-vertex data there: skin weights (then the 4 largest, renormalised), region and
wire-set membership (kept where the interpolated indicator is ≥ 0.5, and each lip vertex in one
lip only). Surface points (landmarks, muscle ends, wire control points) move the other way: each
becomes the closest point of the user's deformable surface. Separate user parts that land on the
reference's eyeballs or teeth become rigid: an eyeball follows its eye bone (placed at the centre
of a sphere fitted to the user's eyeball), lower teeth and tongue the jaw, upper teeth the head;
soft mouth parts (gums joined to the tongue) follow their nearer tooth row (``_soft_mouth_jaw``),
and the jaw weight is diffused over the user's skin so its steps become slopes (``_smooth_jaw``). The
user's vertices, faces and their order are never changed; the rig lives in the user's frame turned
by the nearest axis-aligned rotation to +Y up, +Z forward (the identity for meshes already in that
convention), which ``metadata["source_rotation"]`` undoes.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from mimetic.fit.sides import sides_of
from mimetic.fit.similarity import Similarity, nearest_axis_rotation
from mimetic.head.shape import smoothstep
from mimetic.mesh.closest import ClosestPoints, closest_points
from mimetic.mesh.geometry import connected_components, smooth_field, vertex_areas, vertex_normals
from mimetic.mesh.model import Mesh, SurfacePoint, surface_positions
from mimetic.mesh.openings import Opening
from mimetic.rig.anatomy import closing_weights, find_accessories
from mimetic.rig.anatomy.lids import (
    LID_CLEARANCE_REL,
    LID_THICKNESS_REL,
    closing_pivot,
    eye_sphere,
    eyeball_sphere,
    lid_rims,
)
from mimetic.rig.model import Bone, Rig, Wire

MAX_INFLUENCES = 4
MIN_WEIGHT = 1e-6  # skin weights below this are 0 (no influence)
MEMBERSHIP = 0.5  # interpolated indicator from which a vertex belongs to a region or wire set
RIGID_SHARE = 0.6  # share of a separate part's vertices landing on one rigid reference part
EYE_REACH = 1.5
"""An eye's piece lies within this × the radius of the sphere through the eye's largest piece from
its centre: a cornea's bulge reaches 1.22 on ICT (its sclera's sphere 1.42 cm); a lash strip reaches
past it (one of ICT's right upper lashes, 0.6 of whose vertices lie nearest the reference eyeball,
1.84) and rides its lid instead (``find_accessories``) rather than turning with the gaze and
staying open over a closed lid."""
CAP_REL = 0.75
"""A cap in front of an eyeball's centre turns with it within this × its radius of the gaze axis: a
cornea's limbus lies at about 0.5 (11.5 mm across a 24 mm globe); ICT's eye films (tear line,
occlusion shell, inner corner's blend) reach 0.86-1.23 on its identity heads and ride the lids."""
MAX_TOOTH_SPAN = 2.0  # a mouth part taller than this × the distance between the tooth rows is soft
RIGID_PARTS = dict(eye_L="eye_L", eye_R="eye_R", teeth_upper="head", teeth_lower="jaw", tongue="jaw")
DEFORMABLE_PARTS = ("skin", "mouth", "ear_L", "ear_R")
MOUTH_BOX_REL = ((-1.0, 1.0), (-0.1, 0.8), (-2.5, 0.5))
"""Where the user's mouth parts lie: (low, high) in x, y and z about the mouth's centre (the corners'
midpoint), × the mouth width, but y's low end about the menton. Read off ICT's neutral
and calibration heads s1 σ1 and s4 σ3 (teeth and gums within ±0.85 in x, 0.69 above the centre, 0.35
in front of it and 2.1 behind), with room to spare; checked on s103 and s148 σ3, whose teeth stand
1.5 cm higher than the fitted reference's and were half outside a box around its mouth parts."""
CORNER_REACH = (
    0.5  # the mouth cavity within this × half the mouth width of a corner is smoothed with the lips
)
CAVITY_RAMP_REL = (0.25, -0.5)
"""The mouth cavity's jaw weight rises from 0 at this far above the lips' line to 1 this far below
it, × the mouth width (``_cavity_jaw``). Fitted on ICT's neutral (its jawOpen's implied weights in the
mouth socket: 0.06 at 1.5 cm above the line, 0.15 at 0.5 cm, 0.4 at 0.5 cm below, 0.7 below 1 cm);
checked on ICT identities (benchmarks/bench_weights.py)."""
JAW_SMOOTH_REL = 0.022  # diffusion length of the jaw weight over the user's skin, × the head height (5 mm)
NECK_SMOOTH_REL = 0.05
"""Diffusion length of the jaw weight below the menton, × the head height (1.1 cm: the neck's
edges are 0.7-1.1 cm on ICT's identities). Set from those edges, one value tried; the sweep's
calibration heads s4 σ3 and s6 σ2 went 0.38 → 0.31 and 0.42 → 0.45 cm widest, ICT's jaw weights
3.9 → 3.8 % off its jawOpen's."""


def rig_frame(to_model: Similarity) -> Similarity:
    """The map from the reference frame to the rig's frame (the user's, axis-aligned)."""
    turn = nearest_axis_rotation(to_model.rotation)
    return to_model.inverse().then(Similarity(1.0, turn, np.zeros(3)))


def _interpolate(values: sp.spmatrix | np.ndarray, corners: np.ndarray, bary: np.ndarray):
    """Σ_k bary[:, k] · values[corners[:, k]] for sparse (n_ref, c) or dense values → (q, c)."""
    q = len(corners)
    rows = np.repeat(np.arange(q), 3)
    pick = sp.csr_matrix((bary.ravel(), (rows, corners.ravel())), shape=(q, values.shape[0]))
    return pick @ values


def top_influences(weights: np.ndarray, limit: int) -> np.ndarray:
    """Each row (n, bones) with its ``limit`` largest weights kept and renormalised to sum 1."""
    dense = np.array(weights, dtype=np.float64)
    if dense.shape[1] > limit:
        cut = -np.partition(-dense, limit - 1, axis=1)[:, limit - 1 : limit]
        dense = np.where(dense >= cut, dense, 0.0)
    dense[dense < MIN_WEIGHT] = 0.0
    dense /= dense.sum(axis=1, keepdims=True)
    return dense


def _correspond(mesh_ref: Mesh, faces: np.ndarray, points: np.ndarray, normals: np.ndarray) -> ClosestPoints:
    """Closest points (as indices into ``mesh_ref.faces``) on the reference triangles ``faces`` that
    face the same way as each point's normal, or on any of them where none does."""
    hit = closest_points(
        mesh_ref.vertices, mesh_ref.faces[faces], points, query_normals=normals, min_cos=0.0, or_closest=True
    )
    hit.faces[:] = faces[hit.faces]
    return hit


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


def _on_eyeball(
    vertices: np.ndarray, faces: np.ndarray, ids: np.ndarray, centre: np.ndarray, radius: float
) -> bool:
    """Whether the separate piece of ``vertices`` (n, 3) (reference frame) ``ids`` (k,) turns with the
    eyeball at ``centre``: it reaches behind the centre (a sclera), or it is a cap the gaze (+Z)
    crosses, within ``CAP_REL`` × ``radius`` of it (a cornea, iris, pupil). A film over the eye spans
    the opening in front of the centre and rides the lids."""
    points = vertices[ids]
    if np.any(points[:, 2] < centre[2]):
        return True
    if np.linalg.norm(points[:, :2] - centre[:2], axis=1).max() > CAP_REL * radius:
        return False
    triangles = vertices[faces[np.isin(faces[:, 0], ids)]]  # (t, 3, 3)
    a, b, c = (triangles[:, k, :2] - centre[:2] for k in range(3))
    d1, d2, d3 = (p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0] for p, q in ((a, b), (b, c), (c, a)))
    return bool(np.any(((d1 >= 0) & (d2 >= 0) & (d3 >= 0)) | ((d1 <= 0) & (d2 <= 0) & (d3 <= 0))))


def _separate_parts(
    reference: Rig, user: Mesh, in_model: np.ndarray, hit: ClosestPoints
) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The user's separate parts: the vertices (sorted) of those that move rigidly, by reference part
    name, and (n_user,) bool marking the soft ones inside the mouth.

    A connected component of the user's mesh is an eyeball when ``RIGID_SHARE`` of its vertices land
    on a reference eyeball, it lies within ``EYE_REACH`` of the sphere through that eye's largest
    such piece, and it is a globe or a cap on the gaze (``_on_eyeball``), not a film over the eye. It
    is in the mouth when that share lies in the box ``MOUTH_BOX_REL`` sets
    about the mouth's landmarks (on the user's skin, not the fitted reference's mouth parts, which stand
    off a σ 3 identity's teeth by 1.5 cm). The mouth parts' centroid heights fall into two rows
    (the user's upper and lower teeth; 1-D 2-means): a part no taller than ``MAX_TOOTH_SPAN`` times
    the distance between the rows follows the head when its centroid is in the upper row's half and
    the jaw otherwise; a taller one (gums joined to the tongue, a mouth cavity) is soft (see
    ``_soft_mouth_jaw``).

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
            and _on_eyeball(in_model, user.faces, ids, centre, radius)
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


def _soft_mouth_jaw(points: np.ndarray, upper_teeth: np.ndarray, lower_teeth: np.ndarray) -> np.ndarray:
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


def _cavity_jaw(points: np.ndarray, mouth: Opening) -> np.ndarray:
    """Jaw weight (k,) of mouth-cavity points (k, 3) (reference frame) from their height over the
    line where the lips meet (``mouth``, its lower margin): 0 from ``CAVITY_RAMP_REL[0]`` × the mouth
    width above it, 1 from ``CAVITY_RAMP_REL[1]`` below, a smoothstep between.

    The roof of the cavity rides the head and its floor the jaw, whatever part of the reference's
    (differently shaped) cavity lies nearest: nearest-point weights gave the roof of ICT's mouth
    socket 0.3-1 of the jaw where its captured jawOpen moves it 0-0.1."""
    line = mouth.lower[np.argsort(mouth.lower[:, 0])]
    seam = np.interp(points[:, 0], line[:, 0], line[:, 1])  # constant past the corners
    above, below = np.asarray(CAVITY_RAMP_REL) * mouth.width
    return smoothstep(above, below, points[:, 1] - seam)


def _smooth_jaw(
    weights: np.ndarray,
    vertices: np.ndarray,
    faces: np.ndarray,
    length: float,
    jaw: int,
    *,
    neck: np.ndarray | None = None,
    neck_length: float = 0.0,
) -> np.ndarray:
    """``weights`` (n, bones) with the jaw weight (column ``jaw``) diffused over ``faces`` by
    ``length`` (``mesh.geometry.smooth_field``), then over the ``neck`` (n,) bool vertices when given
    (those below the menton) by ``neck_length`` (the others held), the head bone (column 0) taking
    what the jaw leaves.

    The reference's lips meet at its mouth corners; a scan's lips often run on into a commissure
    fold, and its skin there takes the upper lip's weight on one side and the lower lip's on the
    other, across a row of faces that the jaw would tear open into a wall. Diffusing the jaw weight
    over the user's own skin turns every such step into a slope a few ``length`` wide, so no edge
    stretches much more than its neighbours; where the lips really part no face spans the opening,
    and their weights stay apart. Under the jaw a scan's edges are often ten times longer than on
    the lips (up to 1.1 cm on ICT's identities), and the reference's ramp from the chin down to the
    still neck falls 0.3 across one of them: a jaw drop opens it like a tear. The neck's weight is
    diffused again there, over about one such edge.
    """
    out = weights.copy()
    column = smooth_field(weights[:, jaw], vertices, faces, length)
    if neck is not None:
        near = faces[neck[faces].any(axis=1)]  # every face a neck vertex is on: the same system, built small
        column = smooth_field(column, vertices, near, neck_length, free=neck)
    out[:, jaw] = np.clip(column, 0.0, 1.0)
    out[out[:, jaw] < MIN_WEIGHT, jaw] = 0.0  # the diffusion's far tail: the forehead stays exactly still
    out[:, 0] = np.clip(1.0 - out[:, 1:].sum(axis=1), 0.0, None)
    return out / out.sum(axis=1, keepdims=True)


def close_lids(
    reference: Rig,
    mesh: Mesh,
    weights: np.ndarray,
    regions: dict[str, np.ndarray],
    bones: list[Bone],
    landmarks: dict[str, SurfacePoint],
    scale: float,
) -> tuple[np.ndarray, list[Bone]]:
    """``weights`` (n, b) with each upper lid's column closing onto ``mesh``'s own lower lid at the
    ``eyelid_upper`` channel's maximum, for the eyes whose bones, lid regions and corners the rig has,
    and ``bones`` with each upper lid's pivot where that angle can close its eye (``closing_pivot``)."""
    names = [b.name for b in bones]
    bones = list(bones)
    out = weights
    for side in ("L", "R"):
        corners = [f"eye_inner_corner_{side}", f"eye_outer_corner_{side}"]
        needed = ("head", f"eye_{side}", f"eyelid_upper_{side}")
        channel = f"eyelid_upper_{side}"
        if not all(c in landmarks for c in corners) or not all(b in names for b in needed):
            continue
        if channel not in reference.channel_names:
            continue
        eye, lid = bones[names.index(f"eye_{side}")], bones[names.index(f"eyelid_upper_{side}")]
        eye_corners = np.stack([landmarks[c].position(mesh.vertices, mesh.faces) for c in corners])
        radius = float(np.linalg.norm(eye.tail - eye.head))
        gaze = (eye.tail - eye.head) / radius
        closed = reference.channel(channel).maximum
        # a skirt is tucked inside the sclera's sphere too, as the lid contact finds it (the bone's
        # runs through the whole eye part, ICT's cornea and films with it, and is larger)
        rims = lid_rims(
            mesh.vertices,
            mesh.faces,
            regions,
            side,
            corners=eye_corners,
            centre=eye.head,
            radius=radius,
            gaze=gaze,
            sclera=eyeball_sphere(mesh.vertices, mesh.faces, mesh.parts, regions, side, eye_corners),
            carried=True,
        )
        if rims is not None:
            pivot = closing_pivot(rims, mesh.vertices, lid.head, closed)
            lid = Bone(lid.name, lid.parent, pivot, lid.tail + (pivot - lid.head))
            bones[names.index(lid.name)] = lid
        out = closing_weights(
            mesh.vertices,
            mesh.faces,
            out,
            regions,
            side,
            lid=names.index(f"eyelid_upper_{side}"),
            head=names.index("head"),
            pivot=lid.head,
            corners=eye_corners,
            centre=eye.head,
            radius=radius,
            gaze=gaze,
            closed_rad=closed,
            clearance=LID_CLEARANCE_REL * scale,
            thickness=LID_THICKNESS_REL * scale,
            rims=rims,
            eyeball_faces=mesh.faces[mesh.parts[f"eye_{side}"]] if f"eye_{side}" in mesh.parts else None,
        )
    return out, bones


def _sided(
    mesh_ref: Mesh,
    in_model: np.ndarray,
    faces: np.ndarray,
    normals: np.ndarray,
    hit: ClosestPoints,
    movable: np.ndarray,
    openings: Mapping[str, Opening],
    margins: Mapping[str, tuple[np.ndarray, np.ndarray]],
    candidates: np.ndarray,
) -> None:
    """Correspondences ``hit`` (changed in place) kept on the same side of each opening
    (``fit.sides``): a user vertex on a side that its closest reference face is not on finds its
    closest point again among the faces on its side. Only ``movable`` (n,) user vertices are moved,
    onto the reference faces ``candidates`` (f,).
    """
    ref_faces = mesh_ref.faces[candidates]
    ref_faces.setflags(write=False)  # its edge graph is built once for every opening (``mesh.memo``)
    for feature, opening in openings.items():
        if feature not in margins:
            continue
        user_side, ref_side = sides_of(
            in_model, faces, normals, mesh_ref.vertices, ref_faces, feature, opening, margins[feature]
        )
        face_side = np.sign(ref_side[ref_faces].astype(np.int64).sum(axis=1))
        for side in (1, -1):
            mine = candidates[face_side == side]
            wrong = np.flatnonzero(movable & (user_side == side) & ~np.isin(hit.faces, mine))
            if len(wrong) and len(mine):
                redo = _correspond(mesh_ref, mine, in_model[wrong], normals[wrong])
                hit.faces[wrong], hit.bary[wrong] = redo.faces, redo.bary


def transfer_rig(
    reference: Rig,
    user: Mesh,
    to_model: Similarity,
    *,
    openings: Mapping[str, Opening] | None = None,
    margins: Mapping[str, tuple[np.ndarray, np.ndarray]] | None = None,
    metadata: dict | None = None,
) -> Rig:
    """The rig of ``reference`` (built on the fitted reference, reference frame) on ``user``'s vertices.

    Parameters
    ----------
    reference : Rig
        The recipe's rig of the fitted reference head.
    user : Mesh
        The user's mesh in its own frame and units (``user.units`` must be known).
    to_model : Similarity
        The user frame → reference frame map the fit used.
    openings : Mapping[str, Opening], optional
        The user's openings (eyes, mouth) in the reference frame (``ReferenceFit.openings``), and
    margins : Mapping[str, ((a,), (b,) int64)], optional
        the reference's upper and lower margin vertices of each (``fit.reference.margin_rings``):
        with both, data never crosses an opening (``_sided``).
    metadata : dict, optional
        Extra provenance for ``Rig.metadata``.
    """
    to_rig = rig_frame(to_model)
    turn = nearest_axis_rotation(to_model.rotation)  # user → rig: a signed permutation
    rig_vertices = user.vertices @ turn.T
    mesh_ref = reference.mesh
    in_model = to_model.apply(user.vertices)
    in_model.setflags(write=False)  # so the user's edges, pieces and skin are found once (``mesh.memo``)
    normals = vertex_normals(in_model, user.faces)
    hit = _correspond(mesh_ref, np.arange(mesh_ref.n_faces), in_model, normals)
    rigid, soft_mouth = _separate_parts(reference, user, in_model, hit)
    # the skin takes its data from the reference's deformable surface only (a lid margin near the
    # reference eyeball must blink with the lid, not turn with the gaze)
    in_rigid = np.zeros(user.n_vertices, dtype=bool)
    for ids in rigid.values():
        in_rigid[ids] = True
    deformable = np.concatenate([mesh_ref.parts[p] for p in DEFORMABLE_PARTS if p in mesh_ref.parts])
    again = ~in_rigid & ~soft_mouth & ~np.isin(hit.faces, deformable)
    if again.any():
        redo = _correspond(mesh_ref, deformable, in_model[again], normals[again])
        hit.faces[again], hit.bary[again] = redo.faces, redo.bary
    if openings and margins:
        movable = ~in_rigid & ~soft_mouth
        _sided(mesh_ref, in_model, user.faces, normals, hit, movable, openings, margins, deformable)
    corners = mesh_ref.faces[hit.faces]  # (n_user, 3)

    # skin weights
    weights = top_influences(
        _interpolate(reference.skin_weights, corners, hit.bary).toarray(), MAX_INFLUENCES
    )
    for part, ids in rigid.items():
        weights[ids] = 0.0
        weights[ids, reference.bone_index(RIGID_PARTS[part])] = 1.0
    if soft_mouth.any() and "teeth_upper" in rigid and "teeth_lower" in rigid:
        jaw = _soft_mouth_jaw(
            in_model[soft_mouth], in_model[rigid["teeth_upper"]], in_model[rigid["teeth_lower"]]
        )
        weights[soft_mouth] = 0.0
        weights[soft_mouth, reference.bone_index("head")] = 1.0 - jaw
        weights[soft_mouth, reference.bone_index("jaw")] = jaw
    # the jaw weight is diffused over the skin but not the mouth's cavity away from its corners: the
    # cavity joins the upper lip's inner loops to the lower lip's, which must keep their own weights
    mouth = reference.landmark_positions(["mouth_corner_L", "mouth_corner_R"])
    half_width = 0.5 * np.linalg.norm(mouth[0] - mouth[1])
    reach = np.linalg.norm(in_model[:, None] - mouth[None], axis=2).min(axis=1) / half_width
    cavity = np.isin(hit.faces, mesh_ref.parts.get("mouth", np.zeros(0, np.int64))) & (reach > CORNER_REACH)
    if openings and "mouth" in openings:
        ids = np.flatnonzero(cavity & ~in_rigid & ~soft_mouth)
        jaw = _cavity_jaw(in_model[ids], openings["mouth"])
        weights[ids] = 0.0
        weights[ids, reference.bone_index("head")] = 1.0 - jaw
        weights[ids, reference.bone_index("jaw")] = jaw
    inside = in_rigid | soft_mouth | cavity
    outer_faces = user.faces[~inside[user.faces].any(axis=1)]
    scale = reference.scale * to_rig.scale  # the head height, rig units
    neck = in_model[:, 1] < reference.landmark_positions(["menton"])[0][1]
    weights = _smooth_jaw(
        weights,
        rig_vertices,
        outer_faces,
        JAW_SMOOTH_REL * scale,
        reference.bone_index("jaw"),
        neck=neck,
        neck_length=NECK_SMOOTH_REL * scale,
    )

    # regions and wire sets: membership by interpolated indicator, the rigid parts left out
    def members(ref_ids: np.ndarray) -> np.ndarray:
        """The user's deformable vertices (sorted) whose interpolated indicator of ``ref_ids`` is high."""
        indicator = np.zeros(mesh_ref.n_vertices)
        indicator[ref_ids] = 1.0
        value = (hit.bary * indicator[corners]).sum(axis=1)
        return np.nonzero((value >= MEMBERSHIP) & ~in_rigid)[0].astype(np.int64)

    regions = {name: members(ids) for name, ids in reference.regions.items()}
    if "upper_lip" in regions and "lower_lip" in regions:
        both = np.intersect1d(regions["upper_lip"], regions["lower_lip"])
        if len(both):
            up = np.zeros(mesh_ref.n_vertices)
            up[reference.regions["upper_lip"]] = 1.0
            low = np.zeros(mesh_ref.n_vertices)
            low[reference.regions["lower_lip"]] = 1.0
            to_upper = (hit.bary[both] * up[corners[both]]).sum(1) >= (
                hit.bary[both] * low[corners[both]]
            ).sum(1)
            regions["lower_lip"] = np.setdiff1d(regions["lower_lip"], both[to_upper])
            regions["upper_lip"] = np.setdiff1d(regions["upper_lip"], both[~to_upper])

    # parts of the user mesh: deformable surface, and the rigid parts found above
    face_first = user.faces[:, 0]
    part_of = np.full(len(rig_vertices), -1)
    for k, ids in enumerate(rigid.values()):
        part_of[ids] = k
    parts = {part: np.nonzero(part_of[face_first] == k)[0] for k, part in enumerate(rigid)}
    parts["skin"] = np.nonzero(~in_rigid[face_first])[0]
    user_rig_mesh = Mesh(
        rig_vertices, user.faces, parts=dict(sorted(parts.items())), colors=user.colors, units=user.units
    )
    # surface points: closest point on the user's deformable surface
    skin_faces = parts["skin"]
    skin_tri = user.faces[skin_faces]

    # every surface point of the reference rig, moved at once: landmarks, muscle ends, wire points
    reference_points = [
        *reference.landmarks.values(),
        *(p for m in reference.muscles for p in (m.origin, m.insertion)),
        *(p for w in reference.wires for p in w.points),
    ]
    found = closest_points(
        in_model, skin_tri, surface_positions(reference_points, mesh_ref.vertices, mesh_ref.faces)
    )
    moved = iter(
        SurfacePoint(int(skin_faces[f]), tuple(b.tolist()))
        for f, b in zip(found.faces, found.bary, strict=True)
    )
    landmarks = {name: next(moved) for name in reference.landmarks}
    muscles = [replace(m, origin=next(moved), insertion=next(moved)) for m in reference.muscles]
    wires = []
    for w in reference.wires:
        wires.append(
            Wire(
                name=w.name,
                side=w.side,
                points=tuple(next(moved) for _ in w.points),
                dropoff_rel=w.dropoff_rel,
                vertices=members(w.vertices),
                muscle_weights=dict(w.muscle_weights),
                rest_weight=w.rest_weight,
            )
        )

    # bones: mapped to the rig frame; eyes at the centre of the user's eyeballs when it has them
    bones = []
    for bone in reference.bones:
        head, tail = to_rig.apply(np.stack([bone.head, bone.tail]))
        side = bone.name[-1]
        eye = rigid.get(f"eye_{side}") if bone.name.startswith(("eye_", "eyelid_")) else None
        if eye is not None and len(eye) >= 10:
            centre, radius = eye_sphere(rig_vertices[eye])
            tail = centre + (tail - head) / np.linalg.norm(tail - head) * radius
            head = centre
        bones.append(Bone(bone.name, bone.parent, head, tail))

    # the upper lids close onto the user's own lower lids at the channel's maximum (a closing made on
    # the reference's lids lands short of or past a scan's): mimetic.rig.anatomy.closing_weights
    weights, bones = close_lids(reference, user_rig_mesh, weights, regions, bones, landmarks, scale)
    # accessories (eyelashes and the like) take the weights at their rivets: the engines place them
    # by their rivets anyway, and a skinned export then swings a lash with its lid as one piece
    riding = find_accessories(user_rig_mesh, scale, sp.csr_matrix(weights))
    weights[riding.vertices] = top_influences(riding.weights, MAX_INFLUENCES)
    weights = sp.csr_matrix(weights)

    return Rig(
        mesh=user_rig_mesh,
        units=user.units,
        scale=scale,
        landmarks=landmarks,
        regions=regions,
        muscles=tuple(muscles),
        wires=tuple(wires),
        bones=tuple(bones),
        skin_weights=weights,
        channels=reference.channels,
        metadata={
            "generator": "mimetic.fit",
            "source_rotation": turn.T.tolist(),
            **(metadata or {}),
        },
    )
