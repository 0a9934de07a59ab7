"""How a rig's mesh is drawn in any pose, in a PNG and in the web page alike.

``rig_look`` runs ``mimetic.render.appearance.surface`` once on the rest mesh, with the centre and
gaze of each eyeball part taken from its eye bone, so that an eyeball without colours gets its
iris where the rig looks, and a posed mesh is drawn with the same faces, colours, iris and lash
cover riding on its vertices (``Renderer.render(..., look=...)``).

The page draws the same ``Surface`` (``view.web.display_pieces``: one flat colour per piece, the
lips and the iris pieces of their own) under ``page_lights``, the renderer's shading constants
(``render.raster``: ambient, key and fill) turned into three.js lights. The constants live there,
below this module, because the renderers cannot import ``view``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from mimetic.render import raster
from mimetic.render.appearance import Surface, surface
from mimetic.render.raster import ALBEDO
from mimetic.rig.model import Rig

EYE_PARTS = ("eye_L", "eye_R")
"""Rig parts that are eyeballs, each turned by the bone of the same name."""

DISPLAY_GAMMA = 2.2
"""three.js lights in linear colour and shows sRGB; the renderers light the sRGB albedo directly."""


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


@dataclass(frozen=True)
class PageLights:
    """The page's lights, three.js units: an ambient intensity, and directional lights as
    (direction toward the light (3,) unit, world = view space of the page's first camera,
    intensity)."""

    ambient: float
    directional: tuple[tuple[np.ndarray, float], ...]


def page_lights() -> PageLights:
    """The renderers' ambient, key and fill (``render.raster``) as three.js lights.

    three.js divides a light's intensity by π (Lambert's BRDF) and lights linear colour: the key
    and fill keep their share × π; the ambient term is taken to ``DISPLAY_GAMMA`` so that a surface
    lit by it alone shows as dark as in a PNG (0.18 of the albedo's sRGB value).
    """
    return PageLights(
        ambient=math.pi * raster.AMBIENT**DISPLAY_GAMMA,
        directional=(
            (raster.LIGHT_DIR_VIEW, math.pi * raster.DIFFUSE),
            (raster.FILL_DIR_VIEW, math.pi * raster.FILL),
        ),
    )
