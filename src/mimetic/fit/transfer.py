"""Transfer a rig from the fitted reference onto the user's own mesh (the Maskle idea).

Every user vertex finds its closest point on the fitted reference, skipping reference triangles
that face away from the vertex's normal (so the underside of the upper lip never takes the lower
lip's weights, even where the lips nearly touch), and takes the barycentric interpolation of the
reference's per-vertex data there: skin weights (then the 4 largest, renormalised), region and
wire-set membership (kept where the interpolated indicator is ≥ 0.5, and each lip vertex in one
lip only). Surface points (landmarks, muscle ends, wire control points) move the other way: each
becomes the closest point of the user's deformable surface. Separate user parts that land on the
reference's eyeballs or teeth become rigid: an eyeball follows its eye bone (placed at the centre
of a sphere fitted to the user's eyeball), lower teeth and tongue the jaw, upper teeth the head.
The user's vertices, faces and their order are never changed; the rig lives in the user's frame
turned by the nearest axis-aligned rotation to +Y up, +Z forward (the identity for meshes already
in that convention), which ``metadata["source_rotation"]`` undoes.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.sparse as sp

from mimetic.fit.similarity import Similarity, nearest_axis_rotation
from mimetic.mesh.closest import closest_points
from mimetic.mesh.geometry import connected_components, vertex_normals
from mimetic.mesh.model import Mesh, SurfacePoint
from mimetic.rig.model import Bone, Rig, Wire

MAX_INFLUENCES = 4
MEMBERSHIP = 0.5  # interpolated indicator from which a vertex belongs to a region or wire set
RIGID_SHARE = 0.6  # share of a separate part's vertices landing on one rigid reference part
RIGID_PARTS = {
    "eye_L": "eye_L",
    "eye_R": "eye_R",
    "teeth_upper": "head",
    "teeth_lower": "jaw",
    "tongue": "jaw",
}
DEFORMABLE_PARTS = ("skin", "mouth", "ear_L", "ear_R")


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


def _top_influences(weights: sp.csr_matrix, limit: int) -> sp.csr_matrix:
    """Keep each row's ``limit`` largest weights and renormalise the rows to sum 1."""
    dense = weights.toarray()
    if dense.shape[1] > limit:
        cut = -np.partition(-dense, limit - 1, axis=1)[:, limit - 1 : limit]
        dense = np.where(dense >= cut, dense, 0.0)
    dense[dense < 1e-6] = 0.0
    dense /= dense.sum(axis=1, keepdims=True)
    return sp.csr_matrix(dense)


def _sphere(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Least-squares sphere (centre (3,), radius) through points (k, 3)."""
    a = np.column_stack([2 * points, np.ones(len(points))])
    b = (points**2).sum(axis=1)
    sol, *_ = np.linalg.lstsq(a, b, rcond=None)
    centre = sol[:3]
    return centre, float(np.sqrt(max(sol[3] + centre @ centre, 0.0)))


def transfer_rig(reference: Rig, user: Mesh, to_model: Similarity, *, metadata: dict | None = None) -> Rig:
    """The rig of ``reference`` (built on the fitted reference, reference frame) on ``user``'s vertices.

    Parameters
    ----------
    reference : Rig
        The recipe's rig of the fitted reference head.
    user : Mesh
        The user's mesh in its own frame and units (``user.units`` must be known).
    to_model : Similarity
        The user frame → reference frame map the fit used.
    metadata : dict, optional
        Extra provenance for ``Rig.metadata``.
    """
    to_rig = rig_frame(to_model)
    turn = nearest_axis_rotation(to_model.rotation)  # user → rig: a signed permutation
    rig_vertices = user.vertices @ turn.T
    mesh_ref = reference.mesh
    in_model = to_model.apply(user.vertices)
    normals = vertex_normals(in_model, user.faces)
    hit = closest_points(mesh_ref.vertices, mesh_ref.faces, in_model, query_normals=normals, min_cos=0.0)
    lost = hit.faces < 0
    if lost.any():  # no triangle facing the same way nearby (e.g. a stray inner surface): take any
        rescue = closest_points(mesh_ref.vertices, mesh_ref.faces, in_model[lost])
        hit.faces[lost], hit.bary[lost] = rescue.faces, rescue.bary
    corners = mesh_ref.faces[hit.faces]  # (n_user, 3)

    # which reference part each user vertex landed on, and separate user parts that are rigid
    ref_part = np.full(mesh_ref.n_faces, "", dtype=object)
    for name, faces in mesh_ref.parts.items():
        ref_part[faces] = name
    vertex_part = ref_part[hit.faces]
    n_comp, label = connected_components(user.faces, user.n_vertices)
    rigid: dict[str, np.ndarray] = {}
    for c in range(n_comp):
        ids = np.nonzero(label == c)[0]
        names, counts = np.unique(vertex_part[ids].astype(str), return_counts=True)
        top = names[np.argmax(counts)]
        if top in RIGID_PARTS and counts.max() >= RIGID_SHARE * len(ids):
            rigid[top] = np.union1d(rigid.get(top, np.zeros(0, np.int64)), ids)

    # skin weights
    weights = _top_influences(
        sp.csr_matrix(_interpolate(reference.skin_weights, corners, hit.bary)), MAX_INFLUENCES
    )
    weights = weights.tolil()
    for part, ids in rigid.items():
        weights[ids, :] = 0.0
        weights[ids, reference.bone_index(RIGID_PARTS[part])] = 1.0
    weights = weights.tocsr()

    # regions and wire sets: membership by interpolated indicator
    def members(ref_ids: np.ndarray) -> np.ndarray:
        indicator = np.zeros(mesh_ref.n_vertices)
        indicator[ref_ids] = 1.0
        value = (hit.bary * indicator[corners]).sum(axis=1)
        return np.nonzero(value >= MEMBERSHIP)[0].astype(np.int64)

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
    rigid_vertex = np.zeros(user.n_vertices, dtype=bool)
    parts: dict[str, np.ndarray] = {}
    for part, ids in rigid.items():
        rigid_vertex[ids] = True
        parts[part] = np.nonzero(np.isin(face_first, ids))[0]
    parts["skin"] = np.nonzero(~rigid_vertex[face_first])[0]
    user_rig_mesh = Mesh(
        rig_vertices, user.faces, parts=dict(sorted(parts.items())), colors=user.colors, units=user.units
    )

    # surface points: closest point on the user's deformable surface
    skin_faces = parts["skin"]
    skin_tri = user.faces[skin_faces]

    def surface_points(points_model: np.ndarray) -> list[SurfacePoint]:
        found = closest_points(in_model, skin_tri, points_model)
        return [
            SurfacePoint(int(skin_faces[f]), tuple(b.tolist()))
            for f, b in zip(found.faces, found.bary, strict=True)
        ]

    def ref_positions(points: list[SurfacePoint]) -> np.ndarray:
        return np.array([p.position(mesh_ref.vertices, mesh_ref.faces) for p in points])

    landmark_names = list(reference.landmarks)
    landmarks = dict(
        zip(landmark_names, surface_points(ref_positions(list(reference.landmarks.values()))), strict=True)
    )
    ends = surface_points(ref_positions([p for m in reference.muscles for p in (m.origin, m.insertion)]))
    muscles = [
        replace(m, origin=ends[2 * i], insertion=ends[2 * i + 1]) for i, m in enumerate(reference.muscles)
    ]
    wires = []
    for w in reference.wires:
        wires.append(
            Wire(
                name=w.name,
                side=w.side,
                points=tuple(surface_points(ref_positions(list(w.points)))),
                dropoff_rel=w.dropoff_rel,
                vertices=np.setdiff1d(members(w.vertices), np.nonzero(rigid_vertex)[0]),
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
            centre, radius = _sphere(rig_vertices[eye])
            tail = centre + (tail - head) / np.linalg.norm(tail - head) * radius
            head = centre
        bones.append(Bone(bone.name, bone.parent, head, tail))

    return Rig(
        mesh=user_rig_mesh,
        units=user.units,
        scale=reference.scale * to_rig.scale,
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
