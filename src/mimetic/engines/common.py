"""Pieces every engine shares: the deformation chain after the muscles, and muscle geometry.

The chain follows the automated rigging thesis (§4.3.2): muscles -> skull -> creases ->
skinning -> eyelid sculptors. The muscle stage is engine-specific; the rest is here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import LinearNDInterpolator

from mimetic.engines.skinning import bone_transforms, linear_blend_skinning
from mimetic.mesh.geometry import vertex_normals
from mimetic.rig.model import Rig

SKIN_PARTS = ("skin", "mouth")  # the deformable surface; other parts only follow bones
SKULL_CLEARANCE_REL = 0.0  # the skull surface lies on the rest forehead (as the thesis lofts it)
SCULPTOR_MARGIN_REL = 0.0015  # lids stay this far outside the cornea sphere


@dataclass(frozen=True)
class MuscleFrame:
    """Where a muscle pulls from and to, in rig units."""

    attachment: np.ndarray  # (3,) bony origin (linear, sheet) or centre (sphincter)
    insertion: np.ndarray  # (3,)
    length: float


def muscle_frame(rig: Rig, name: str) -> MuscleFrame:
    m = rig.muscle(name)
    v, f = rig.mesh.vertices, rig.mesh.faces
    insertion = m.insertion.position(v, f)
    attachment = m.origin.position(v, f) if m.kind == "sphincter" else rig.muscle_attachment(name)
    return MuscleFrame(attachment, insertion, float(np.linalg.norm(insertion - attachment)))


def deformable_vertices(rig: Rig) -> np.ndarray:
    """Sorted indices of the vertices muscles may move: the skin and the mouth cavity."""
    parts = [p for p in SKIN_PARTS if p in rig.mesh.parts]
    if not parts:
        return np.arange(rig.n_vertices)
    return np.unique(np.concatenate([rig.mesh.faces[rig.mesh.parts[p]].ravel() for p in parts]))


def lip_mask(rig: Rig, insertion_vertex_point) -> np.ndarray:
    """Vertices a muscle inserting at a point may move: not the opposite lip (n,) bool."""
    n = rig.n_vertices
    mask = np.ones(n, dtype=bool)
    upper, lower = rig.regions.get("upper_lip"), rig.regions.get("lower_lip")
    if upper is None or lower is None:
        return mask
    face = rig.mesh.faces[insertion_vertex_point.face]
    corner = face[int(np.argmax(insertion_vertex_point.bary))]
    if np.isin(corner, upper):
        mask[lower] = False
    elif np.isin(corner, lower):
        mask[upper] = False
    return mask


class Chain:
    """The stages after the muscles: skull push, skinning and eyelid sculptors (prepared once)."""

    def __init__(self, rig: Rig, *, skull: bool = True) -> None:
        self.rig = rig
        v = rig.mesh.vertices
        self.skull_ids = np.asarray(rig.regions.get("forehead", np.zeros(0, np.int64)))
        self.skull = None
        if skull and len(self.skull_ids) > 10:
            pts = v[self.skull_ids]
            self.skull = LinearNDInterpolator(pts[:, :2], pts[:, 2] - SKULL_CLEARANCE_REL * rig.scale)
        self.lids = []
        for side in ("L", "R"):
            if f"eye_{side}" not in rig.bone_names:
                continue
            ids = np.concatenate(
                [rig.regions.get(f"eyelid_upper_{side}", []), rig.regions.get(f"eyelid_lower_{side}", [])]
            )
            eye = (
                rig.mesh.faces[rig.mesh.parts[f"eye_{side}"]].ravel()
                if f"eye_{side}" in rig.mesh.parts
                else None
            )
            centre = rig.bone(f"eye_{side}").head
            radius = np.linalg.norm(v[np.unique(eye)] - centre, axis=1).max() if eye is not None else 0.0
            self.lids.append((ids.astype(np.int64), centre, radius + SCULPTOR_MARGIN_REL * rig.scale))

    def apply(self, deformed: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Skull push (+Z onto the rest forehead), skinning, then lid sculptors; (n, 3) -> (n, 3)."""
        v = deformed
        if self.skull is not None:
            p = v[self.skull_ids]
            z = self.skull(p[:, 0], p[:, 1])
            behind = np.isfinite(z) & (p[:, 2] < z)
            if behind.any():
                v = v.copy()
                v[self.skull_ids[behind], 2] = z[behind]
        transforms = bone_transforms(self.rig, values)
        moving = ~np.all(np.abs(transforms - np.eye(4)) < 1e-15, axis=(1, 2))
        if moving.any():
            v = linear_blend_skinning(v, self.rig.skin_weights, transforms)
        for ids, rest_centre, radius in self.lids:
            if len(ids) == 0:
                continue
            k = self.rig.bone_index(f"eye_{'L' if rest_centre[0] > 0 else 'R'}")
            centre = transforms[k, :3, :3] @ rest_centre + transforms[k, :3, 3]
            d = v[ids] - centre
            dist = np.linalg.norm(d, axis=1)
            inside = dist < radius
            if inside.any():
                v = v.copy() if v is deformed else v
                v[ids[inside]] = centre + d[inside] / dist[inside, None] * radius
        return v


def surface_normals(rig: Rig) -> np.ndarray:
    """Rest vertex normals (n, 3)."""
    return vertex_normals(rig.mesh.vertices, rig.mesh.faces)
