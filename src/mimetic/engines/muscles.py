"""Muscle geometry every engine reads: where a muscle pulls from and to, and which vertices muscles
may move (the skin and mouth cavity, less what the eyelid bones hold)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from mimetic.rig.anatomy.derive import skin_vertices
from mimetic.rig.model import Rig

LID_RIGID_WEIGHT = 0.35
"""Eyelid bone weight from which muscles leave a vertex to the lid."""


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
