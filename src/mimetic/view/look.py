"""How a rig's mesh is drawn in any pose: its eyeballs around their eye bones, its films and lashes.

``rig_look`` runs ``mimetic.render.appearance.surface`` once on the rest mesh, with the centre and
gaze of each eyeball part taken from its eye bone, so that an eyeball without colours gets its
iris where the rig looks, and a posed mesh is drawn with the same faces, colours, iris and lash
cover riding on its vertices (``Renderer.render(..., look=...)``).
"""

from __future__ import annotations

import numpy as np

from mimetic.render.appearance import Surface, surface
from mimetic.render.raster import ALBEDO
from mimetic.rig.model import Rig

EYE_PARTS = ("eye_L", "eye_R")
"""Rig parts that are eyeballs, each turned by the bone of the same name."""


def eye_frames(rig: Rig) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Eyeball part → (centre (3,), gaze axis (3,)) at rest: its bone's head, and tail minus head."""
    bones = set(rig.bone_names)
    return {
        part: (rig.bone(part).head, rig.bone(part).tail - rig.bone(part).head)
        for part in EYE_PARTS
        if part in rig.mesh.parts and part in bones
    }


def rig_look(rig: Rig, albedo: tuple[float, float, float] = ALBEDO) -> Surface:
    """What to draw of ``rig.mesh`` (rest or posed) and how: ``surface`` of the rest mesh with the
    eyeballs' centres and gaze axes from their bones; ``albedo`` colours what the mesh does not."""
    return surface(rig.mesh, albedo, eyes=eye_frames(rig))
