"""Pieces every engine shares: the deformation chain after the muscles, and muscle geometry.

The chain follows the automated rigging thesis (§4.3.2): muscles -> skull -> creases ->
skinning -> eyelid sculptors, then the accessories riveted to the skin (``attach``). The muscle
stage is engine-specific; the rest is here. What the chain acts on (the skull, the creases, the
lip contact pairs, the accessories) is the rig's anatomy (``Rig.anatomy``): the engines only read it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.interpolate import LinearNDInterpolator

from mimetic.engines.attach import ride
from mimetic.engines.skinning import bone_transforms, linear_blend_skinning
from mimetic.head.parts import eyeball_profile
from mimetic.rig.anatomy.anatomy import skin_vertices
from mimetic.rig.model import Rig

LID_RIGID_WEIGHT = 0.35  # eyelid bone weight from which muscles leave a vertex to the lid
SCULPTOR_MARGIN_REL = 0.0002  # lids stay this far outside the eyeball (0.005 cm on a 23 cm head)


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
    return skin_vertices(rig.mesh)


def muscle_mask(rig: Rig) -> np.ndarray:
    """How much (n,) of each vertex's motion the muscles may drive, from its eyelid bone weight.

    The lids are bones (as in the thesis): skin bound to a lid bone by LID_RIGID_WEIGHT or more
    follows the lid only, and the lid's blend into the surrounding skin blends the two, so nothing
    tears at the lid border and no muscle drags a closed lid into the eyeball.
    """
    lids = [rig.bone_index(b) for b in rig.bone_names if b.startswith("eyelid_")]
    if not lids:
        return np.ones(rig.n_vertices)
    lid = np.asarray(rig.skin_weights[:, lids].sum(axis=1)).ravel()
    return np.clip(1.0 - lid / LID_RIGID_WEIGHT, 0.0, 1.0)


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
    """The stages after the muscles: skull push, creases, skinning, eyelid sculptors, accessories
    riveted to the skin (prepared once)."""

    def __init__(self, rig: Rig, *, skull: bool = True, creases: bool = True) -> None:
        self.rig = rig
        anatomy = rig.anatomy
        folds = anatomy.creases if creases else ()
        rows, cols, vals = [], [], []
        for crease in folds:  # one row per channel: the summed crease offsets it drives
            offsets = (crease.offsets_rel * rig.scale).ravel()
            columns = (3 * crease.vertices[:, None] + np.arange(3)).ravel()
            for channel, gain in crease.gains.items():
                rows.append(np.full(len(columns), rig.channel_index(channel)))
                cols.append(columns)
                vals.append(gain * offsets)
        self.creases = sp.csr_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))) if vals else ([], ([], [])),
            shape=(len(rig.channels), 3 * rig.n_vertices),
        )
        self.weights = rig.skin_weights.tocsc()
        self.lip_pairs = anatomy.lip_contact
        self.skull_ids = anatomy.skull.vertices
        self.skull = None
        if skull and len(anatomy.skull):
            surface = anatomy.skull.surface
            self.skull = LinearNDInterpolator(surface[:, :2], surface[:, 2])
        v = rig.mesh.vertices
        self.lids = []
        for side in ("L", "R"):
            if f"eye_{side}" not in rig.bone_names:
                continue
            ids = np.concatenate(
                [rig.regions.get(f"eyelid_{lid}_{side}", np.zeros(0, np.int64)) for lid in ("upper", "lower")]
            )
            bone = rig.bone(f"eye_{side}")
            # only lid vertices clear of the eyeball at rest (the conjunctiva skirt is tucked inside)
            dist, limit = self._eyeball_clearance(v[ids], bone.head, bone.tail - bone.head)
            outside = dist >= limit
            self.lids.append(
                (ids[outside].astype(np.int64), rig.bone_index(f"eye_{side}"), bone.head, bone.tail)
            )
        self.accessories = anatomy.accessories

    def _eyeball_clearance(self, points: np.ndarray, centre: np.ndarray, gaze: np.ndarray) -> tuple:
        """Distances (k,) of points from the eye centre and the sculptor's limit (k,) for each."""
        radius = np.linalg.norm(gaze)
        d = points - centre
        dist = np.linalg.norm(d, axis=1)
        angle = np.arccos(np.clip(d @ gaze / np.maximum(dist * radius, 1e-30), -1.0, 1.0))
        limit = radius * eyeball_profile(angle) + SCULPTOR_MARGIN_REL * self.rig.scale
        return dist, limit

    def apply(self, deformed: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Lip contact, skull push (+Z onto the rest forehead), creases, skinning, lid sculptors,
        then the accessories (eyelashes and the like) placed on the skin they ride.

        ``deformed`` (n, 3) is the rest skin moved by the muscles; returns (n, 3).
        """
        v = deformed.copy()
        if len(self.lip_pairs):  # lips meet but never cross: a crossed pair is pressed together
            upper, lower = v[self.lip_pairs[:, 0]], v[self.lip_pairs[:, 1]]
            crossed = upper[:, 1] < lower[:, 1]
            mid = 0.5 * (upper[crossed, 1] + lower[crossed, 1])
            v[self.lip_pairs[crossed, 0], 1] = mid
            v[self.lip_pairs[crossed, 1], 1] = mid
        if self.skull is not None:
            p = v[self.skull_ids]
            z = self.skull(p[:, 0], p[:, 1])
            behind = np.isfinite(z) & (p[:, 2] < z - 1e-9 * self.rig.scale)
            v[self.skull_ids[behind], 2] = z[behind]
        if self.creases.nnz:
            v += (self.creases.T @ values).reshape(-1, 3)
        transforms = bone_transforms(self.rig, values)
        v = linear_blend_skinning(v, self.weights, transforms)
        for ids, bone, rest_centre, rest_tip in self.lids:
            # sculptor: lids never inside the eyeball (its profile, the cornea included)
            m = transforms[bone]
            centre = m[:3, :3] @ rest_centre + m[:3, 3]
            dist, limit = self._eyeball_clearance(v[ids], centre, m[:3, :3] @ (rest_tip - rest_centre))
            inside = dist < limit
            d = v[ids[inside]] - centre
            v[ids[inside]] = centre + d * (limit[inside] / dist[inside])[:, None]
        return ride(self.accessories, self.rig.mesh.vertices, v, transforms) if len(self.accessories) else v
