"""A rig made on a welded mesh, moved back onto the user's own vertices across its unwelded seams.

``rig_head`` fits and transfers on the user's mesh with its seams merged (``mimetic.mesh.weld``)
and then moves the rig back onto the user's own vertices with ``unweld_rig``: coincident copies
take the same skin weights, regions and wire sets, so a skinned export moves them together, and
the anatomy is derived again across the seams (``mimetic.rig.anatomy``), so the engines, which
work from positions and that anatomy, move every copy to the same place in every pose.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from mimetic.mesh.model import Mesh, SurfacePoint
from mimetic.mesh.weld import Weld
from mimetic.rig.model import Rig


def _mapped(
    rig: Rig,
    mesh: Mesh,
    rows: np.ndarray,
    vertex_set: Callable[[np.ndarray], np.ndarray],
    point: Callable[[SurfacePoint], SurfacePoint],
) -> Rig:
    """``rig`` on ``mesh``: per-vertex rows taken at ``rows``, vertex sets and surface points mapped."""
    return dataclasses.replace(
        rig,
        mesh=mesh,
        landmarks={name: point(p) for name, p in rig.landmarks.items()},
        regions={name: vertex_set(ids) for name, ids in rig.regions.items()},
        muscles=tuple(
            dataclasses.replace(m, origin=point(m.origin), insertion=point(m.insertion)) for m in rig.muscles
        ),
        wires=tuple(
            dataclasses.replace(w, points=tuple(point(p) for p in w.points), vertices=vertex_set(w.vertices))
            for w in rig.wires
        ),
        skin_weights=rig.skin_weights[rows],
        anatomy=None,  # derived again on the new mesh
    )


def unweld_rig(rig: Rig, weld: Weld, mesh: Mesh) -> Rig:
    """A rig built on ``weld.mesh`` moved onto ``mesh``, the mesh ``weld`` merged (same vertex order
    and count as the user's, in the rig's frame and units): each copy of a merged vertex takes its
    welded vertex's data, parts are the welded parts' original faces (a face that collapsed joins
    the part of the first face that shares its first vertex)."""
    face_part = np.full(mesh.n_faces, "", dtype=object)
    for name, ids in rig.mesh.parts.items():
        face_part[weld.faces[ids]] = name
    lost = np.flatnonzero(face_part == "")
    if len(lost):
        kept_part = face_part[weld.faces]
        owner = np.full(len(weld.first), "", dtype=object)
        owner[rig.mesh.faces[:, 0]] = kept_part  # a kept face's part, at its first vertex
        face_part[lost] = owner[weld.index[mesh.faces[lost, 0]]]
    names = [n for n in rig.mesh.parts]
    parts = {name: np.flatnonzero(face_part == name) for name in names}
    if "skin" in parts:
        parts["skin"] = np.union1d(parts["skin"], np.flatnonzero(face_part == ""))
    user_mesh = dataclasses.replace(mesh, parts=parts, materials={})

    def point(p: SurfacePoint) -> SurfacePoint:
        return SurfacePoint(int(weld.faces[p.face]), p.bary)

    def vertex_set(ids: np.ndarray) -> np.ndarray:
        return np.flatnonzero(np.isin(weld.index, ids))

    return _mapped(rig, user_mesh, weld.index, vertex_set, point)
