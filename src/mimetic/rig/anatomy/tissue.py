"""Soft-tissue thickness: how deep the skull lies under each skin vertex.

Measured facial soft-tissue depths on adults (forensic tables such as Stephan & Simpson's) run
from about 2 mm on the eyelids and 3–4 mm over the nasal bones to 5–6 mm on the forehead,
10–12 mm at the lips and chin and 15–20 mm over the cheeks. ``REGION_THICKNESS_REL`` gives one
value per region as a fraction of the head height (22.5 cm for the default head), other skin
takes ``DEFAULT_THICKNESS_REL``, and diffusing the values over the skin by ``BLEND_REL`` blends the
regions into each other. The wire and vector engines do not use it; the layered tissue and FEM
engines lay their tissue between the skin and the skull this far under it.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mimetic.mesh.geometry import smooth_field

REGION_THICKNESS_REL: Mapping[str, float] = {
    "eyelid_upper_L": 0.010,
    "eyelid_upper_R": 0.010,
    "eyelid_lower_L": 0.012,
    "eyelid_lower_R": 0.012,
    "nose": 0.016,
    "forehead": 0.025,
    "scalp": 0.025,
    "brow_L": 0.028,
    "brow_R": 0.028,
    "upper_lip": 0.050,
    "lower_lip": 0.050,
    "chin": 0.048,
    "jaw_L": 0.055,
    "jaw_R": 0.055,
    "nasolabial_L": 0.065,
    "nasolabial_R": 0.065,
    "cheek_L": 0.070,
    "cheek_R": 0.070,
    "neck": 0.045,
}
"""Soft-tissue thickness per region, × the head height (eyelid 2.3 mm … cheek 16 mm on 22.5 cm)."""
DEFAULT_THICKNESS_REL = 0.030
"""Thickness of skin in no listed region (the sides of the head, the ears' roots), × the head height."""
BLEND_REL = 0.02
"""Diffusion length that blends the regions' values across their borders, × the head height (~5 mm)."""


def tissue_thickness(
    vertices: np.ndarray, faces: np.ndarray, skin: np.ndarray, regions: Mapping[str, np.ndarray], scale: float
) -> np.ndarray:
    """Soft-tissue thickness (n,) float64 under each vertex, × the head height; 0 off the skin.

    Parameters
    ----------
    vertices : (n, 3) float64
        The rest mesh, rig units.
    faces : (m, 3) int64
        The faces the blending follows: the outer skin (the ``skin`` part), whose triangles are as
        mirror-symmetric as the head, so the thickness is too (a mouth cavity's need not be).
    skin : (s,) int64
        The skin vertices.
    regions : Mapping[str, (k,) int64]
        The rig's regions; the names of ``REGION_THICKNESS_REL`` are used.
    scale : float
        The head height, rig units.
    """
    n_vertices = len(vertices)
    value = np.zeros(n_vertices)
    value[skin] = DEFAULT_THICKNESS_REL
    for name, thickness in REGION_THICKNESS_REL.items():
        ids = regions.get(name)
        if ids is not None and len(ids):
            value[ids] = thickness
    on_skin = np.zeros(n_vertices, dtype=bool)
    on_skin[skin] = True
    return smooth_field(value, vertices, faces, BLEND_REL * scale, free=on_skin)
