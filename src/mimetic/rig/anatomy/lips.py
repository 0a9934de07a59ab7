"""Where the lips touch at rest: pairs of upper- and lower-lip vertices that lie on each other.

The generated head's lips, and many modelled heads' closed mouths, are two sheets that meet along
a contact line of coincident vertices. The engines keep each pair from crossing (an upper-lip
vertex never below its lower-lip partner), so lips can press together but not pass through.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from scipy.spatial import cKDTree

CONTACT_TOL_REL = 1e-9
"""An upper- and a lower-lip vertex closer than this, × the head height, touch at rest."""


def lip_contact(vertices: np.ndarray, regions: Mapping[str, np.ndarray], scale: float) -> np.ndarray:
    """Pairs (k, 2) int64 of (upper lip, lower lip) vertices that coincide at rest.

    Parameters
    ----------
    vertices : (n, 3) float64
        The rest mesh, rig units.
    regions : Mapping[str, (m,) int64]
        Must hold ``upper_lip`` and ``lower_lip`` for any pair to be found.
    scale : float
        The head height, rig units.
    """
    upper, lower = regions.get("upper_lip"), regions.get("lower_lip")
    if upper is None or lower is None or not len(upper) or not len(lower):
        return np.zeros((0, 2), np.int64)
    dist, nearest = cKDTree(vertices[lower]).query(vertices[upper])
    touching = dist < CONTACT_TOL_REL * scale
    return np.column_stack([upper[touching], lower[nearest[touching]]]).astype(np.int64)
