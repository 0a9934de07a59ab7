"""Accessories: small separate pieces of a mesh that ride the skin (eyelashes, brows, tear lines).

A scanned or modelled head often carries eyelashes, eyebrow cards or thin shells over the eyes as
separate connected components. Transferred rigs give them the weights of whatever reference
surface lies nearest to each vertex, so a lash's root and tip can follow different lid columns
and stretch into spikes when the eye closes. Here each accessory vertex is instead riveted to the
skin under its nearest root, as a rivet or proximity-wrap deformer would: the rivet moves with the
deformed skin, and the vertex's rest offset from it turns by the bones as weighted at the rivet
(``mimetic.engines.attach.ride``). A lash therefore stays on the lid margin and swings with the
lid as one piece.

An accessory is a connected component, other than the largest one, whose faces all belong to the
``skin`` part (eyeballs, teeth, tongue and the other named parts keep their bones), with at most
``ACCESSORY_MAX_FRACTION`` of the vertices, and that comes within ``ACCESSORY_GAP_REL`` of the
head height of the main skin. Its roots are its vertices within ``ROOT_BAND_REL`` of its closest
approach; every vertex follows the skin point under its nearest root.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from mimetic.mesh.closest import closest_points
from mimetic.mesh.geometry import connected_components
from mimetic.mesh.memo import per_arrays
from mimetic.mesh.model import Mesh

ACCESSORY_MAX_FRACTION = 0.02
"""Largest accessory, as a fraction of the mesh's vertices (an ICT eyelash strip: 0.4 %)."""
ACCESSORY_GAP_REL = 0.01
"""Farthest closest approach of an accessory to the skin, × the head height (~2 mm)."""
ROOT_BAND_REL = 0.003
"""Roots lie within this of an accessory's closest approach, × the head height (~0.7 mm)."""


@dataclass(frozen=True, eq=False)
class Accessories:
    """Accessory vertices and the skin points they ride.

    Attributes
    ----------
    vertices : (a,) int64
        The accessory vertices.
    triangles : (a, 3) int64
        The skin triangle (its three vertex indices) carrying each one's rivet.
    bary : (a, 3) float64
        The rivet: barycentric coordinates of the root's closest point on that triangle.
    offsets : (a, 3) float64
        Each rest vertex minus its rest rivet, in mesh units.
    weights : (a, bones) float64
        The skin weights at each rivet (interpolated from the triangle's corners), summing to 1.
    """

    vertices: np.ndarray
    triangles: np.ndarray
    bary: np.ndarray
    offsets: np.ndarray
    weights: np.ndarray

    def __post_init__(self) -> None:
        for name, dtype in (
            ("vertices", np.int64),
            ("triangles", np.int64),
            ("bary", np.float64),
            ("offsets", np.float64),
            ("weights", np.float64),
        ):
            array = np.array(getattr(self, name), dtype=dtype, copy=True)
            array.setflags(write=False)
            object.__setattr__(self, name, array)

    def __len__(self) -> int:
        return len(self.vertices)

    @staticmethod
    def none(bones: int) -> Accessories:
        """No accessories, for a rig with ``bones`` bones."""
        empty = np.zeros((0, 3))
        return Accessories(
            np.zeros(0, np.int64), np.zeros((0, 3), np.int64), empty, empty, np.zeros((0, bones))
        )


def find_accessories(mesh: Mesh, scale: float, weights: sp.spmatrix) -> Accessories:
    """The accessories of ``mesh`` (see the module docstring) riveted to its main skin, at rest.

    Parameters
    ----------
    mesh : Mesh
        The rig's mesh; ``parts["skin"]`` names its deformable faces.
    scale : float
        The head height (mesh units) the thresholds are relative to.
    weights : (n, bones) sparse
        The rig's skin weights.
    """
    none = Accessories.none(weights.shape[1])
    skin = mesh.parts.get("skin")
    if skin is None or mesh.n_faces == 0:
        return none
    riding = _rivets(mesh.vertices, mesh.faces, skin, scale)
    if riding is None:
        return none
    ids, triangles, bary = riding
    v = mesh.vertices
    rivets = np.einsum("ak,akd->ad", bary, v[triangles])
    dense = weights.tocsr()
    at_rivets = sum(bary[:, [k]] * dense[triangles[:, k]].toarray() for k in range(3))  # (a, bones)
    at_rivets /= at_rivets.sum(axis=1, keepdims=True)
    return Accessories(ids, triangles, bary, v[ids] - rivets, at_rivets)


@per_arrays(3)
def _rivets(
    v: np.ndarray, faces: np.ndarray, skin: np.ndarray, scale: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The accessory vertices (a,), the skin triangles (a, 3) and barycentric rivets (a, 3) they ride
    (``find_accessories``; None without accessories), found once per mesh (``mesh.memo``: the
    transfer and the anatomy both ask)."""
    n = len(v)
    _, label = connected_components(faces, n)
    sizes = np.bincount(label)
    main = int(np.argmax(sizes))
    in_skin = np.zeros(len(faces), dtype=bool)
    in_skin[skin] = True
    face_label = label[faces[:, 0]]
    outside_skin = np.unique(face_label[~in_skin])  # components with a face of another part
    candidates = [
        c
        for c in np.unique(face_label[in_skin])
        if c != main and c not in outside_skin and sizes[c] <= ACCESSORY_MAX_FRACTION * n
    ]
    main_faces = faces[(face_label == main) & in_skin]
    if not candidates or len(main_faces) == 0:
        return None
    members = [np.flatnonzero(label == c) for c in candidates]
    # one query for every candidate's vertices (each query's answer is its own: one search tree over
    # the skin instead of one per candidate, 36 trees of 50k triangles per ICT rig before)
    near = closest_points(v, main_faces, v[np.concatenate(members)])
    ends = np.cumsum([len(ids) for ids in members])
    pieces = []
    for ids, end in zip(members, ends, strict=True):
        at = slice(end - len(ids), end)
        distance, hit_faces, hit_bary = near.distance[at], near.faces[at], near.bary[at]
        gap = distance.min()
        if gap > ACCESSORY_GAP_REL * scale:
            continue  # floats free of the skin: not attached
        roots = np.flatnonzero(distance <= gap + ROOT_BAND_REL * scale)
        _, nearest = cKDTree(v[ids[roots]]).query(v[ids])
        root = roots[nearest]  # (k,) the root each vertex follows
        pieces.append((ids, hit_faces[root], hit_bary[root]))
    if not pieces:
        return None
    ids, hit_faces, bary = (np.concatenate(x) for x in zip(*pieces, strict=True))
    return ids, main_faces[hit_faces], bary
