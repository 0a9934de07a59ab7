"""Fit the reference head to a user's mesh: landmarks → conformation and similarity → registration.

Everything is solved in the reference's own frame (cm, +Y up, +Z forward, the default head's
size), where the rig recipe's anatomy is defined: the target is mapped there by the landmark
similarity, the reference is generated with the fitted ``HeadParams`` and its skin registered
onto the mapped target. The reference's separate parts (eyeballs, teeth, tongue, mouth
cavity, ears) follow the skin: each part moves by the mean displacement of the skin vertices
nearest to it, so eyeballs stay spheres and the teeth stay rigid.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.spatial import cKDTree

from mimetic.errors import LandmarkError
from mimetic.fit.conform import Conformation, fit_conformation, landmark_model
from mimetic.fit.register import Curve, Registration, TargetSurface, register, sample_surface
from mimetic.head.model import DEFAULT_RESOLUTION, Head, make_head
from mimetic.head.topology import build_topology
from mimetic.mesh.geometry import vertex_normals
from mimetic.mesh.model import Mesh
from mimetic.mesh.openings import (
    Opening,
    eye_opening,
    eyeball,
    mouth_opening,
    opening_margins,
    skin_faces,
)

MIN_LANDMARKS = 8
FOLLOW_NEIGHBOURS = 24  # skin vertices whose displacement a separate part follows


@dataclass(frozen=True)
class ReferenceFit:
    """The reference head fitted to a target mesh.

    Attributes
    ----------
    head : Head
        The fitted reference, in the reference frame (cm, +Y up, +Z forward): its landmarks,
        regions and mirror map are the generated head's, its vertices fitted.
    start : Head
        The conformed reference before registration (same frame).
    conformation : Conformation
        Fitted ``HeadParams`` and ``to_model``, the similarity from the target's frame to the
        reference frame.
    target : Mesh
        The target mesh mapped into the reference frame by ``to_model``.
    surface : TargetSurface
        The samples of the mapped target that the registration used.
    registration : Registration
    landmark_names : tuple of str
        The landmarks used, with their mapped target positions ``landmark_targets`` (k, 3).
    flipped : bool
        True when the target's faces wound inward (normals into the head, as after a mirroring
        export): ``target`` has them turned the right way round.
    openings : Mapping[str, Opening]
        The target's openings ("eye_L", "eye_R", "mouth") found from its geometry, reference frame;
        the registration bound the reference's margins to them.
    margins : Mapping[str, ((a,), (b,) int64)]
        The reference's upper and lower margin vertices of each opening (``opening_margins``).
    """

    head: Head
    start: Head
    conformation: Conformation
    target: Mesh
    surface: TargetSurface
    registration: Registration
    landmark_names: tuple[str, ...]
    landmark_targets: np.ndarray
    flipped: bool = False
    openings: Mapping[str, Opening] = field(default_factory=dict)
    margins: Mapping[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)


def projectable_vertices(head: Head) -> np.ndarray:
    """Skin vertices (n_skin,) bool that may take data terms: not the inner lips, lip contact or
    the eyes' conjunctiva skirt, which a scan cannot see."""
    topo = build_topology(head.resolution)
    ok = np.ones(head.n_skin, dtype=bool)
    for k, u in enumerate(topo.mouth.u):
        if u <= 0:
            ok[topo.mouth.index[k]] = False
    for rings in (topo.eye_L, topo.eye_R):
        for k, u in enumerate(rings.u):
            if u < 0:
                ok[rings.index[k]] = False
    return ok


def winding_inverted(head: Head, target: Mesh) -> bool:
    """True when ``target``'s normals point into the head: over the reference face, the normals of
    the nearest target vertices mostly oppose the (aligned, conformed) reference skin's."""
    skin = head.mesh.vertices[: head.n_skin]
    face = projectable_vertices(head) & (build_topology(head.resolution).directions[:, 2] > 0.3)
    used = np.unique(target.faces)
    _, near = cKDTree(target.vertices[used]).query(skin[face])
    target_normals = vertex_normals(target.vertices, target.faces)[used[near]]
    skin_normals = vertex_normals(head.mesh.vertices, head.mesh.faces)[: head.n_skin][face]
    return bool(np.median(np.einsum("kd,kd->k", skin_normals, target_normals)) < 0)


def follow_skin(head: Head, skin: np.ndarray) -> np.ndarray:
    """All vertices (n, 3) of ``head`` when its skin moves to ``skin`` (n_skin, 3): each separate
    part translates with the mean displacement of its ``FOLLOW_NEIGHBOURS`` nearest skin vertices
    (eyeballs, teeth and ears keep their shapes)."""
    rest = head.mesh.vertices
    n_skin = head.n_skin
    out = rest.copy()
    out[:n_skin] = skin
    moved = skin - rest[:n_skin]
    tree = cKDTree(rest[:n_skin])
    for name, faces in head.mesh.parts.items():
        if name == "skin":
            continue
        ids = np.unique(head.mesh.faces[faces])
        if name == "mouth":  # the cavity bends with the lips: per vertex, distance-weighted
            dist, near = tree.query(rest[ids], k=8)
            w = 1.0 / np.maximum(dist, 1e-6) ** 2
            out[ids] = rest[ids] + np.einsum("kj,kjd->kd", w / w.sum(axis=1, keepdims=True), moved[near])
            continue
        _, near = tree.query(rest[ids].mean(axis=0), k=FOLLOW_NEIGHBOURS)
        out[ids] = rest[ids] + moved[near].mean(axis=0)
    return out


FEATURES = {
    "eye_L": ("eye_inner_corner_L", "eye_outer_corner_L"),
    "eye_R": ("eye_inner_corner_R", "eye_outer_corner_R"),
    "mouth": ("mouth_corner_R", "mouth_corner_L"),
}
"""The openings whose margins the registration follows, and the landmarks that say where they are."""


def feature_openings(head: Head, target: Mesh, names: list[str], points: np.ndarray) -> dict[str, Opening]:
    """The target's eye and mouth openings (``mimetic.mesh.openings``), found near the corners the
    landmarks ``names`` at ``points`` (k, 3) give (both in the reference frame), or the conformed
    reference's corners where a landmark is missing. Openings that are not found are left out."""
    where = dict(zip(names, points, strict=True))
    faces = skin_faces(target.vertices, target.faces)
    out = {}
    for feature, corner_names in FEATURES.items():
        corners = np.array(
            [where[n] if n in where else head.mesh.vertices[head.landmarks[n]] for n in corner_names]
        )
        if feature == "mouth":
            opening = mouth_opening(target.vertices, faces, corners)
        else:
            ball = eyeball(target.vertices, target.faces, corners)
            opening = eye_opening(target.vertices, faces, corners, ball)
        if opening is not None:
            out[feature] = opening
    return out


CURVE_CORNER_REL = 0.1
"""The margins are bound to the target's lines except within this × the opening's width of either
corner, where the lines meet and a millimetre's asymmetry in where the seam was found would pull one
corner and not the other."""


def fit_reference(
    mesh: Mesh,
    landmark_names: list[str],
    landmark_points: np.ndarray,
    *,
    landmark_weights: np.ndarray | None = None,
    resolution: int = DEFAULT_RESOLUTION,
    progress: Callable[[str, int, int], None] | None = None,
) -> ReferenceFit:
    """Fit the reference head to ``mesh``.

    Parameters
    ----------
    mesh : Mesh
        The user's head, any units and orientation (the landmarks fix both).
    landmark_names : list of str, length k ≥ 8
        Project landmark names. Outline points (iBUG 1-17, ``fit.conform.sliding_landmarks``)
        slide along the face outline in the conformation and take no part in the registration.
    landmark_points : (k, 3) float64
        Their positions on ``mesh``, in its units and frame.
    landmark_weights : (k,) float64, optional
        Confidences; 1 by default.
    resolution : int
        Skin resolution of the reference head.
    progress : callable(step, done, total), optional
    """
    names = list(landmark_names)
    known = set(landmark_model(resolution).names)
    unknown = [n for n in names if n not in known]
    if unknown:
        raise LandmarkError(
            f"unknown landmark name(s) {unknown[:5]}; see mimetic.head.landmarks for the names"
        )
    if len(names) < MIN_LANDMARKS:
        raise LandmarkError(
            f"got {len(names)} landmarks; fitting needs at least {MIN_LANDMARKS} spread over the face "
            "(eye corners, nose tip, mouth corners, chin)"
        )
    points = np.asarray(landmark_points, dtype=np.float64)
    weights = np.ones(len(names)) if landmark_weights is None else np.asarray(landmark_weights, float)

    def step(label: str, done: int = 0, total: int = 1) -> None:
        if progress is not None:
            progress(label, done, total)

    step("conformation")
    conformation = fit_conformation(names, points, weights=weights, resolution=resolution)
    start = make_head(conformation.params, resolution)
    to_model = conformation.to_model
    target = mesh.with_vertices(to_model.apply(mesh.vertices))
    flipped = winding_inverted(start, target)
    if flipped:
        target = Mesh(target.vertices, target.faces[:, ::-1], parts=target.parts, units=target.units)
    surface = sample_surface(target)
    skin_faces = start.mesh.faces[start.mesh.parts["skin"]]
    size = float(np.ptp(start.mesh.vertices[: start.n_skin, 1]))
    lm_vertices = np.array([start.landmarks[n] for n in names])
    # outline points only say where the face's outline is, which the surface term fits anyway;
    # bound to the reference's own outline vertices they would drag its jaw line to the file's
    # convention (ICT's and OpenFace's lie 1-2.5 cm in front of the silhouette)
    on_skin = (lm_vertices < start.n_skin) & ~conformation.sliding
    mapped = to_model.apply(points)
    openings = feature_openings(start, target, names, mapped)
    # the reference's own margins, found as the target's are (its rings run past what is seen)
    margins = opening_margins(
        start.mesh.vertices, start.mesh.faces, feature_openings(start, start.mesh, [], np.zeros((0, 3)))
    )
    margins = {f: m for f, m in margins.items() if f in openings and min(map(len, m)) > 0}
    curves = [
        Curve(ids[openings[f].between_corners(start.mesh.vertices[ids], CURVE_CORNER_REL)], line)
        for f, m in margins.items()
        for ids, line in zip(m, (openings[f].upper, openings[f].lower), strict=True)
    ]
    registration = register(
        start.mesh.vertices[: start.n_skin],
        skin_faces,
        surface,
        projectable=projectable_vertices(start),
        size=size,
        landmarks=lm_vertices[on_skin],
        landmark_targets=mapped[on_skin],
        landmark_weights=weights[on_skin],
        curves=curves,
        progress=lambda done, total: step("registration", done, total),
    )
    vertices = follow_skin(start, registration.vertices)
    eye_centres = np.array(start.eye_centres)
    for i, side in enumerate("LR"):
        ids = start.mesh.part_vertices(f"eye_{side}")
        eye_centres[i] += (vertices[ids] - start.mesh.vertices[ids]).mean(axis=0)
    eye_centres.setflags(write=False)
    head = replace(start, mesh=start.mesh.with_vertices(vertices), eye_centres=eye_centres)
    return ReferenceFit(
        head,
        start,
        conformation,
        target,
        surface,
        registration,
        tuple(names),
        mapped,
        flipped,
        {f: openings[f] for f in margins},
        margins,
    )
