"""Accessories riding the skin, at run time: each accessory vertex placed by its rivet.

Which pieces are accessories, and where their rivets sit, is the rig's anatomy
(``mimetic.rig.anatomy.accessories``); ``ride`` moves them with the deformed skin, as a rivet or
proximity-wrap deformer would: the rivet moves with the skin, and the vertex's rest offset from it
turns by the bones as weighted at the rivet. A lash therefore stays on the lid margin and swings
with the lid as one piece; the skin triangles' own orientation is not used, as it is noisy at a
lid margin.
"""

from __future__ import annotations

import numpy as np

from mimetic.rig.anatomy import Accessories


def ride(
    accessories: Accessories, rest: np.ndarray, deformed: np.ndarray, transforms: np.ndarray
) -> np.ndarray:
    """``deformed`` with every accessory vertex placed by its rivet.

    Parameters
    ----------
    accessories : Accessories
        The rig's ``anatomy.accessories``.
    rest, deformed : (n, 3) float64
        The rest mesh and the deformed one (skin done), mesh units.
    transforms : (bones, 4, 4) float64
        The bone transforms of the frame (``skinning.bone_transforms``).

    Returns
    -------
    (n, 3) float64, a new array: each accessory vertex moved by its rivet's displacement plus its
    rest offset turned by the bones blended with the rivet's weights, written as displacements
    (like ``linear_blend_skinning``) so that the rest pose gives back the rest exactly.
    """
    out = deformed.copy()
    if len(accessories) == 0:
        return out
    tri = accessories.triangles
    shift = np.einsum("ak,akd->ad", accessories.bary, deformed[tri] - rest[tri])  # of the rivets
    turn = np.einsum("ab,bij->aij", accessories.weights, transforms[:, :3, :3] - np.eye(3))  # (a, 3, 3)
    ids = accessories.vertices
    out[ids] = rest[ids] + shift + np.einsum("aij,aj->ai", turn, accessories.offsets)
    return out
