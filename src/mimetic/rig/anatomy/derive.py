"""``Anatomy``, the rig's anatomical data, and ``derive_anatomy``, which computes it for a rig.

See the package docstring for what each element is.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from mimetic.mesh.geometry import smooth_field, vertex_normals
from mimetic.mesh.model import Mesh, SurfacePoint
from mimetic.mesh.weld import find_weld
from mimetic.rig.anatomy.accessories import Accessories, find_accessories
from mimetic.rig.anatomy.actions import MIN_WEIGHT, Action, find_actions
from mimetic.rig.anatomy.creases import Crease, find_creases
from mimetic.rig.anatomy.lids import LidContact, find_lid_contacts
from mimetic.rig.anatomy.lips import lip_contact
from mimetic.rig.anatomy.skull import Skull, forehead_skull
from mimetic.rig.anatomy.tissue import tissue_thickness

SKIN_PARTS = ("skin", "mouth")
"""The deformable surface: the parts muscles, creases and tissue act on (others follow bones)."""
CAVITY_REACH_REL = 0.03
"""Tissue actions carry on from the lips into the mouth cavity over this × the head height (6 mm)."""
NORMAL_SMOOTHING_REL = 0.02
"""Creases sink, and tissue actions slide and bulge, along the skin's normals smoothed over this × the
head height (4 mm), with the lips closed (``tissue_normals``)."""


@dataclass(frozen=True, eq=False)
class Anatomy:
    """The rig's anatomy (see the package docstring).

    Attributes
    ----------
    creases : tuple of Crease
    skull : Skull
    lip_contact : (k, 2) int64
        (upper lip, lower lip) vertex pairs that touch at rest.
    accessories : Accessories
    thickness_rel : (n,) float64
        Soft-tissue thickness under each vertex, × the head height; 0 off the skin.
    lids : tuple of LidContact
        Where each eye's upper lid meets its lower lid (``mimetic.rig.anatomy.lids``); empty for a
        mesh without lids.
    actions : tuple of Action
        Tissue actions (``mimetic.rig.anatomy.actions``): per-channel displacement fields added
        before skinning, as the creases are (frontalis sheet, cheek raise, lip roll, cheek puff,
        tongue …).
    """

    creases: tuple[Crease, ...]
    skull: Skull
    lip_contact: np.ndarray
    accessories: Accessories
    thickness_rel: np.ndarray
    lids: tuple[LidContact, ...] = ()
    actions: tuple[Action, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "creases", tuple(self.creases))
        object.__setattr__(self, "lids", tuple(self.lids))
        object.__setattr__(self, "actions", tuple(self.actions))
        for name, dtype in (("lip_contact", np.int64), ("thickness_rel", np.float64)):
            array = np.array(getattr(self, name), dtype=dtype, copy=True)
            array.setflags(write=False)
            object.__setattr__(self, name, array)
        if self.lip_contact.size == 0:
            object.__setattr__(self, "lip_contact", self.lip_contact.reshape(0, 2))

    @staticmethod
    def none(n_vertices: int, bones: int) -> Anatomy:
        """No anatomy for a rig of ``n_vertices`` vertices and ``bones`` bones: no creases, skull, lip
        contact, accessories, lids or actions, and no tissue. For a rig that is only a step on the way
        to another (``rig_head`` transfers the fitted reference's rig, and the transferred rig derives
        its own anatomy on the user's mesh), where deriving it would be wasted."""
        return Anatomy(
            (),
            Skull(np.zeros(0, np.int64), np.zeros((0, 3))),
            np.zeros((0, 2), np.int64),
            Accessories.none(bones),
            np.zeros(n_vertices),
        )


def skin_vertices(mesh: Mesh) -> np.ndarray:
    """Sorted indices of the deformable vertices (``SKIN_PARTS``), or all of them without parts."""
    parts = [p for p in SKIN_PARTS if p in mesh.parts]
    if not parts:
        return np.arange(mesh.n_vertices)
    return np.unique(np.concatenate([mesh.faces[mesh.parts[p]].ravel() for p in parts]))


def _anatomy(
    mesh: Mesh,
    landmarks: Mapping[str, SurfacePoint],
    regions: Mapping[str, np.ndarray],
    skin_weights: sp.spmatrix,
    scale: float,
    channel_names: set[str],
) -> Anatomy:
    """Every element of the anatomy of a mesh without unwelded seams."""
    v, f = mesh.vertices, mesh.faces
    skin = skin_vertices(mesh)
    deformable = [mesh.parts[p] for p in SKIN_PARTS if p in mesh.parts]
    skin_faces = f[np.concatenate(deformable)] if deformable else f

    def landmark(name: str) -> np.ndarray:
        return landmarks[name].position(v, f)

    crease_skin = mesh.part_vertices("skin") if "skin" in mesh.parts else skin
    lips = lip_contact(v, regions, scale)
    normals = tissue_normals(v, f[mesh.parts["skin"]] if "skin" in mesh.parts else f, lips, scale)
    corners = {
        side: np.stack([landmark(f"eye_inner_corner_{side}"), landmark(f"eye_outer_corner_{side}")])
        for side in ("L", "R")
        if f"eye_inner_corner_{side}" in landmarks and f"eye_outer_corner_{side}" in landmarks
    }
    return Anatomy(
        creases=find_creases(
            v,
            normals,
            crease_skin,
            landmark,
            set(landmarks),
            channel_names,
            scale,
            np.union1d(regions.get("upper_lip", ()), regions.get("lower_lip", ())).astype(np.int64),
        ),
        skull=forehead_skull(v, regions, scale),
        lip_contact=lips,
        accessories=find_accessories(mesh, scale, skin_weights),
        thickness_rel=tissue_thickness(
            v, f[mesh.parts["skin"]] if "skin" in mesh.parts else skin_faces, skin, regions, scale
        ),
        lids=find_lid_contacts(v, f, mesh.parts, regions, corners),
        actions=_into_cavity(
            find_actions(
                v,
                normals,
                crease_skin,
                mesh.part_vertices("tongue") if "tongue" in mesh.parts else np.zeros(0, np.int64),
                landmark,
                set(landmarks),
                dict(regions),
                channel_names,
                scale,
            ),
            v,
            skin_faces,
            np.setdiff1d(skin, crease_skin),
            CAVITY_REACH_REL * scale,
        ),
    )


def tissue_normals(vertices: np.ndarray, faces: np.ndarray, lips: np.ndarray, scale: float) -> np.ndarray:
    """Unit normals (n, 3) of the skin for the creases and tissue actions: tissue moves as a mass, so
    its normals are those of the skin with the lips closed (each lip-contact pair ``lips`` (k, 2) one
    vertex) and smoothed over ``NORMAL_SMOOTHING_REL`` of the head height. Where the lips fold into
    the mouth the two lips then slide and bulge alike instead of toward each other and across the lip
    line.
    ``faces``: the skin part alone, so a mouth cavity's own normals do not tilt the lips'."""
    one = np.arange(len(vertices))
    one[lips[:, 1]] = lips[:, 0]  # the lower lip's contact vertices become their upper partners
    closed = one[faces]
    closed = closed[
        (closed[:, 0] != closed[:, 1]) & (closed[:, 1] != closed[:, 2]) & (closed[:, 0] != closed[:, 2])
    ]
    smooth = smooth_field(vertex_normals(vertices, closed), vertices, closed, NORMAL_SMOOTHING_REL * scale)
    smooth[lips[:, 1]] = smooth[lips[:, 0]]
    size = np.linalg.norm(smooth, axis=1, keepdims=True)
    return np.divide(smooth, size, out=np.zeros_like(smooth), where=size > 1e-12)


def cavity_links(
    vertices: np.ndarray, faces: np.ndarray, cavity: np.ndarray, length: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """How the mouth cavity (``cavity`` (c,) vertices) follows the skin it continues.

    Each cavity vertex within ``length`` of the seam (the vertices of ``faces`` outside the cavity
    that share a face with it) follows its nearest seam vertex with the falloff ``(1 − (d /
    length)²)²``. By distance, not over the cavity's triangles, which need not be mirror-symmetric
    where the head is.

    Returns
    -------
    ids, source : (m,) int64
        The cavity vertices that follow, and the seam vertex each follows.
    fall : (m,) float64
        How much of its seam vertex's motion each takes, in (0, 1].
    """
    empty = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
    if not len(cavity):
        return empty
    inside = np.zeros(len(vertices), dtype=bool)
    inside[cavity] = True
    touching = faces[inside[faces].any(axis=1)].ravel()
    seam = np.unique(touching[~inside[touching]])
    if not len(seam):
        return empty
    dist, nearest = cKDTree(vertices[seam]).query(vertices[cavity])
    near = dist < length
    return cavity[near], seam[nearest[near]], (1.0 - (dist[near] / length) ** 2) ** 2


def _into_cavity(
    actions: tuple[Action, ...], vertices: np.ndarray, faces: np.ndarray, cavity: np.ndarray, length: float
) -> tuple[Action, ...]:
    """``actions`` carried on from the skin into the mouth cavity (``cavity_links``), so the cavity's
    rim moves with the lip it continues and the mouth does not open at the seam between them (a cheek
    puff tore the default head's mouth corner open there)."""
    ids, source, fall = cavity_links(vertices, faces, cavity, length)
    if not actions or not len(ids):
        return actions
    out = []
    for action in actions:
        row = np.full(len(vertices), -1)
        row[action.vertices] = np.arange(len(action.vertices))
        moved = row[source] >= 0
        carried = action.offsets_rel[row[source[moved]]] * fall[moved, None]
        size = np.linalg.norm(action.offsets_rel, axis=1).max(initial=0.0)
        keep = np.linalg.norm(carried, axis=1) > MIN_WEIGHT * size
        all_ids = np.concatenate([action.vertices, ids[moved][keep]])
        offsets = np.concatenate([action.offsets_rel, carried[keep]])
        order = np.argsort(all_ids, kind="stable")
        out.append(replace(action, vertices=all_ids[order], offsets_rel=offsets[order]))
    return tuple(out)


def derive_anatomy(
    mesh: Mesh,
    landmarks: Mapping[str, SurfacePoint],
    regions: Mapping[str, np.ndarray],
    skin_weights: sp.spmatrix,
    scale: float,
    channel_names: tuple[str, ...] | set[str],
) -> Anatomy:
    """The anatomy of a rig (the rig's rest mesh, landmarks, regions, skin weights and head height
    ``scale``), computed on the mesh with its unwelded seams merged and handed back to every copy
    of a merged vertex. Channels the rig lacks drive no crease or action."""
    weld = find_weld(mesh)
    channels = set(channel_names)
    if weld.n_merged == 0:
        return _anatomy(mesh, landmarks, regions, skin_weights, scale, channels)
    welded_faces = weld.face_of(np.arange(mesh.n_faces))
    points = {}
    for name, p in landmarks.items():
        face = int(welded_faces[p.face])
        if face >= 0:
            points[name] = SurfacePoint(face, p.bary)
    merged = {name: np.unique(weld.index[ids]) for name, ids in regions.items()}
    inner = _anatomy(weld.mesh, points, merged, sp.csr_matrix(skin_weights)[weld.first], scale, channels)
    # back onto the mesh: every copy of a welded vertex takes its data
    order = np.argsort(weld.index, kind="stable")
    starts = np.searchsorted(weld.index[order], np.arange(len(weld.first) + 1))

    def copies(ids: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The original vertices (k,) of welded vertices ``ids`` and, for each, its row in ``ids``."""
        counts = starts[ids + 1] - starts[ids]
        rows = np.repeat(np.arange(len(ids)), counts)
        first = np.repeat(starts[ids], counts)
        offset = np.arange(len(rows)) - np.repeat(np.cumsum(counts) - counts, counts)
        return order[first + offset], rows

    def spread(fields: tuple[Crease, ...]) -> tuple[Crease, ...]:
        out = []
        for field in fields:
            ids, rows = copies(field.vertices)
            out.append(replace(field, vertices=ids, offsets_rel=field.offsets_rel[rows]))
        return tuple(out)

    skull_ids, rows = copies(inner.skull.vertices)
    pairs = []
    for upper, lower in inner.lip_contact:
        ups, _ = copies(np.array([upper]))
        lows, _ = copies(np.array([lower]))
        pairs += [(u, low) for u in ups for low in lows]
    acc = inner.accessories
    acc_ids, rows_a = copies(acc.vertices)
    accessories = Accessories(
        acc_ids, weld.first[acc.triangles[rows_a]], acc.bary[rows_a], acc.offsets[rows_a], acc.weights[rows_a]
    )
    lids = tuple(
        replace(contact, upper=copies(contact.upper)[0], lower=weld.first[contact.lower])
        for contact in inner.lids
    )
    return Anatomy(
        creases=spread(inner.creases),
        skull=Skull(skull_ids, inner.skull.surface[rows]),
        lip_contact=np.array(pairs, dtype=np.int64).reshape(-1, 2),
        accessories=accessories,
        thickness_rel=inner.thickness_rel[weld.index],
        lids=lids,
        actions=spread(inner.actions),
    )
