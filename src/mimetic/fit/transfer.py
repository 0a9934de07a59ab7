"""Transfer a rig from the fitted reference onto the user's own mesh (the Maskle idea).

Every user vertex finds its closest point on the fitted reference, skipping reference triangles
that face away from the vertex's normal (so the underside of the upper lip never takes the lower
lip's weights, even where the lips nearly touch), and takes the barycentric interpolation of the
reference's per-vertex data there: skin weights (then the 4 largest, renormalised), region and
wire-set membership (kept where the interpolated indicator is ≥ 0.5, and each lip vertex in one
lip only). Surface points (landmarks, muscle ends, wire control points) move the other way: each
becomes the closest point of the user's deformable surface. Separate user parts that land on the
reference's eyeballs or teeth become rigid (``mimetic.fit.parts``): an eyeball follows its eye bone
(placed at the centre of a sphere fitted to the user's eyeball), lower teeth and tongue the jaw,
upper teeth the head; soft mouth parts (gums joined to the tongue) follow their nearer tooth row,
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

from mimetic.fit.parts import RIGID_PARTS, separate_parts, soft_mouth_jaw
from mimetic.fit.sides import seal_faces, sides_of
from mimetic.fit.similarity import Similarity, nearest_axis_rotation
from mimetic.head.shape import smoothstep
from mimetic.mesh.closest import ClosestPoints, closest_points
from mimetic.mesh.geometry import smooth_field, vertex_normals
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
DEFORMABLE_PARTS = ("skin", "mouth", "ear_L", "ear_R")
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
    rigid, soft_mouth = separate_parts(reference, user, in_model, hit)
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
        jaw = soft_mouth_jaw(
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
    outer = ~inside[user.faces].any(axis=1)
    if openings and "mouth" in openings:  # nor across a mouth modelled shut
        outer &= ~seal_faces(in_model, user.faces, openings["mouth"])
    outer_faces = user.faces[outer]
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
