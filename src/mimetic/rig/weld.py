"""A rig across an unwelded seam: onto the welded mesh for the engines, and back onto the user's.

``rig_head`` fits and transfers on the user's mesh with its seams merged (``mimetic.mesh.weld``)
and then moves the rig back onto the user's own vertices with ``unweld_rig``: coincident copies
take the same skin weights, regions and wire sets, so a skinned export moves them together. The
engines run on ``weld_rig(rig)``, so what uses the topology (normals, neighbours, separate pieces)
sees one surface, and ``deform`` hands every copy its welded vertex's position: coincident
vertices stay coincident in every pose.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from mimetic.mesh.closest import closest_points
from mimetic.mesh.model import Mesh, SurfacePoint
from mimetic.mesh.weld import Weld, find_weld
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
    )


def weld_rig(rig: Rig) -> tuple[Rig, Weld]:
    """The rig on its mesh with the unwelded seams merged, and the weld (``weld.index`` maps the
    rig's vertices to the welded ones). The rig itself when there is no seam."""
    weld = find_weld(rig.mesh)
    if weld.n_merged == 0:
        return rig, weld
    welded_faces = weld.face_of(np.arange(rig.mesh.n_faces))
    mesh = weld.mesh

    def point(p: SurfacePoint) -> SurfacePoint:
        face = int(welded_faces[p.face])
        if face >= 0:
            return SurfacePoint(face, p.bary)
        # a sliver that collapsed: the nearest point of the welded surface
        hit = closest_points(mesh.vertices, mesh.faces, p.position(rig.mesh.vertices, rig.mesh.faces)[None])
        return SurfacePoint(int(hit.faces[0]), tuple(float(b) for b in hit.bary[0]))

    def vertex_set(ids: np.ndarray) -> np.ndarray:
        return np.unique(weld.index[ids])

    return _mapped(rig, mesh, weld.first, vertex_set, point), weld


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
