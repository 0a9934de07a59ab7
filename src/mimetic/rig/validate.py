"""Consistency checks for a whole ``Rig``.

``validate_rig`` runs every time a ``Rig`` is built (and after loading a ``.mrig`` file). Each
failure raises ``RigError`` whose message starts with the path of the offending field, e.g.
``muscles[3] 'zygomatic_major_L'.origin.face=99999 is out of range (the mesh has 20000 faces)``,
and says how to fix it. The checks are vectorised: a 30k-vertex rig validates in a few ms.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable

import numpy as np
import scipy.sparse as sp

from mimetic.errors import RigError
from mimetic.mesh.model import SurfacePoint
from mimetic.rig.model import UNITS, Rig, coerce_surface_point, freeze_json

log = logging.getLogger(__name__)

MAX_INFLUENCES = 4
"""Largest number of bones that may weight one vertex."""

WEIGHT_SUM_TOL = 1e-6
"""Tolerance on the sum of each vertex's skin weights (must be 1)."""


def validate_rig(rig: Rig) -> None:
    """Raise ``RigError`` naming the first inconsistent field of ``rig``; return None if it is sound.

    Checks, in order: the mesh (finite vertices, faces and parts in range), ``units`` and
    ``scale``; landmarks; regions (sorted unique vertex indices in range); channels (unique
    names, min < max, default in range); muscles (surface points on existing faces, ranges, a
    channel of the same name with unit "activation", a known region, non-zero length); wires
    (points, deformation sets in range, weights per control point, known muscles); bones
    (unique names, parents listed first, one root); skin weights ((n_vertices, n_bones),
    non-negative, ≤ 4 non-zeros and summing to 1 per vertex); metadata (JSON-safe).
    """
    mesh = rig.mesh
    n_vertices, n_faces = mesh.n_vertices, mesh.n_faces

    # ---- mesh, units, scale
    if n_vertices == 0 or n_faces == 0:
        raise RigError(f"mesh has {n_vertices} vertices and {n_faces} faces; a rig needs a non-empty mesh")
    if not np.isfinite(mesh.vertices).all():
        bad = int(np.argmax(~np.isfinite(mesh.vertices).all(axis=1)))
        raise RigError(f"mesh.vertices[{bad}]={mesh.vertices[bad].tolist()} is not finite; repair the mesh")
    _check_indices(mesh.faces.ravel(), n_vertices, "mesh.faces", "vertices")
    for name, faces in mesh.parts.items():
        _check_indices(faces, n_faces, f"mesh.parts[{name!r}]", "faces")
    if mesh.colors is not None and not np.isfinite(mesh.colors).all():
        raise RigError("mesh.colors has non-finite values; use RGB in [0, 1]")
    if rig.units not in UNITS:
        raise RigError(f"units={rig.units!r} must be one of {', '.join(UNITS)}")
    if mesh.units is not None and mesh.units != rig.units:
        raise RigError(
            f"mesh.units={mesh.units!r} differs from units={rig.units!r}; convert the mesh or set its units"
        )
    if not (np.isfinite(rig.scale) and rig.scale > 0):
        raise RigError(f"scale={rig.scale} must be a finite head height > 0 in {rig.units}")

    # ---- landmarks and regions
    for name, point in rig.landmarks.items():
        _check_point(point, f"landmarks[{name!r}]", n_faces)
    for name, vertices in rig.regions.items():
        where = f"regions[{name!r}]"
        if not isinstance(vertices, np.ndarray) or vertices.ndim != 1 or vertices.dtype != np.int64:
            raise RigError(f"{where} must be a (k,) int64 array of vertex indices")
        _check_indices(vertices, n_vertices, where, "vertices", sorted_unique=True)

    # ---- channels
    _check_unique([c.name for c in rig.channels], "channels")
    for i, channel in enumerate(rig.channels):
        channel.check(f"channels[{i}] {channel.name!r}")
    channels = {c.name: c for c in rig.channels}

    # ---- muscles
    _check_unique([m.name for m in rig.muscles], "muscles")
    for i, muscle in enumerate(rig.muscles):
        where = f"muscles[{i}] {muscle.name!r}"
        muscle.check(where)
        _check_point(muscle.origin, f"{where}.origin", n_faces)
        _check_point(muscle.insertion, f"{where}.insertion", n_faces)
        channel = channels.get(muscle.name)
        if channel is None:
            raise RigError(
                f"{where} has no channel of the same name; add Channel({muscle.name!r}, 0.0, 1.0) to channels"
            )
        if channel.unit != "activation":
            raise RigError(
                f"{where}: its channel has unit={channel.unit!r}; a muscle channel's unit is 'activation'"
            )
        if muscle.region is not None and muscle.region not in rig.regions:
            raise RigError(f"{where}.region={muscle.region!r} is not in regions ({_names(rig.regions)})")
        origin = muscle.origin.position(mesh.vertices, mesh.faces)
        insertion = muscle.insertion.position(mesh.vertices, mesh.faces)
        if np.linalg.norm(insertion - origin) <= 1e-9 * rig.scale:
            raise RigError(f"{where}: origin and insertion are at the same point; a muscle needs a length")

    # ---- wires
    _check_unique([w.name for w in rig.wires], "wires")
    muscles = {m.name for m in rig.muscles}
    for i, wire in enumerate(rig.wires):
        where = f"wires[{i}] {wire.name!r}"
        wire.check(where)
        for j, point in enumerate(wire.points):
            _check_point(point, f"{where}.points[{j}]", n_faces)
        _check_indices(wire.vertices, n_vertices, f"{where}.vertices", "vertices", sorted_unique=True)
        for name in wire.muscle_weights:
            if name not in muscles:
                raise RigError(
                    f"{where}.muscle_weights[{name!r}] names no muscle; muscles are {_names(muscles)}"
                )

    # ---- bones
    if not rig.bones:
        raise RigError("bones is empty; a rig needs at least a root bone (e.g. 'head') to skin the mesh")
    _check_unique([b.name for b in rig.bones], "bones")
    position = {b.name: i for i, b in enumerate(rig.bones)}
    roots = []
    for i, bone in enumerate(rig.bones):
        where = f"bones[{i}] {bone.name!r}"
        bone.check(where)
        if bone.parent is None:
            roots.append(bone.name)
        elif bone.parent not in position:
            raise RigError(f"{where}.parent={bone.parent!r} is not a bone; bones are {_names(position)}")
        elif position[bone.parent] > i:
            raise RigError(
                f"{where}.parent={bone.parent!r} is listed after it (bones[{position[bone.parent]}]); "
                "list every parent before its children"
            )
    if len(roots) != 1:
        raise RigError(f"bones must form one tree with a single root (parent=None); found roots {roots}")

    # ---- skin weights
    _check_skin_weights(rig.skin_weights, n_vertices, rig.bones)

    # ---- metadata
    freeze_json(rig.metadata, "metadata")

    # ---- anatomy
    _check_anatomy(rig)


def _check_anatomy(rig: Rig) -> None:
    """The anatomy's indices point at the rig's vertices, its arrays have the rig's sizes, each lid
    contact names an eye."""
    anatomy, n = rig.anatomy, rig.n_vertices
    fix = "re-derive it: dataclasses.replace(rig, anatomy=None)"
    fields = [("creases", i, c) for i, c in enumerate(anatomy.creases)]
    fields += [("actions", i, c) for i, c in enumerate(anatomy.actions)]
    for key, i, crease in fields:
        where = f"anatomy.{key}[{i}] {crease.name!r}"
        _check_indices(crease.vertices, n, f"{where}.vertices", "vertices")
        if crease.offsets_rel.shape != (len(crease.vertices), 3) or not np.isfinite(crease.offsets_rel).all():
            raise RigError(
                f"{where}.offsets_rel must be finite with shape ({len(crease.vertices)}, 3); {fix}"
            )
        unknown = [c for c in crease.gains if c not in rig.channel_names]
        if unknown:
            raise RigError(f"{where}.gains names channels the rig lacks: {unknown[:3]}; {fix}")
    skull = anatomy.skull
    _check_indices(skull.vertices, n, "anatomy.skull.vertices", "vertices")
    if skull.surface.shape != (len(skull.vertices), 3):
        raise RigError(f"anatomy.skull.surface must have shape ({len(skull.vertices)}, 3); {fix}")
    if anatomy.lip_contact.ndim != 2 or anatomy.lip_contact.shape[1] != 2:
        raise RigError(f"anatomy.lip_contact must have shape (k, 2); {fix}")
    _check_indices(anatomy.lip_contact.ravel(), n, "anatomy.lip_contact", "vertices")
    acc = anatomy.accessories
    a = len(acc.vertices)
    _check_indices(acc.vertices, n, "anatomy.accessories.vertices", "vertices")
    _check_indices(acc.triangles.ravel(), n, "anatomy.accessories.triangles", "vertices")
    for name, shape in (
        ("triangles", (a, 3)),
        ("bary", (a, 3)),
        ("offsets", (a, 3)),
        ("weights", (a, rig.n_bones)),
    ):
        if getattr(acc, name).shape != shape:
            raise RigError(f"anatomy.accessories.{name} must have shape {shape}; {fix}")
    if anatomy.thickness_rel.shape != (n,) or not np.isfinite(anatomy.thickness_rel).all():
        raise RigError(f"anatomy.thickness_rel must be finite with shape ({n},); {fix}")
    for i, contact in enumerate(anatomy.lids):
        where = f"anatomy.lids[{i}]"
        if contact.side not in ("L", "R"):
            raise RigError(f"{where}.side must be 'L' or 'R'; got {contact.side!r}; {fix}")
        _check_indices(contact.upper, n, f"{where}.upper", "vertices")
        _check_indices(contact.lower, n, f"{where}.lower", "vertices")


def _names(names: Iterable[str], limit: int = 6) -> str:
    names = list(names)
    shown = ", ".join(map(repr, names[:limit]))
    return (shown + f", … {len(names)} in all") if len(names) > limit else (shown or "none")


def _check_unique(names: list[str], where: str) -> None:
    seen: dict[str, int] = {}
    for i, name in enumerate(names):
        if name in seen:
            raise RigError(
                f"{where}[{i}] {name!r} has the same name as {where}[{seen[name]}]; names must be unique"
            )
        seen[name] = i


def _check_point(point: SurfacePoint, where: str, n_faces: int) -> None:
    coerce_surface_point(point, where)
    if point.face >= n_faces:
        raise RigError(f"{where}.face={point.face} is out of range (the mesh has {n_faces} faces)")


def _check_indices(
    indices: np.ndarray, n: int, where: str, what: str, *, sorted_unique: bool = False
) -> None:
    """Indices (k,) must lie in [0, n) (and be strictly increasing when ``sorted_unique``)."""
    if indices.size == 0:
        return
    if not np.issubdtype(indices.dtype, np.integer):
        raise RigError(f"{where} must hold integer indices; got dtype {indices.dtype}")
    low, high = int(indices.min()), int(indices.max())
    if low < 0 or high >= n:
        bad = low if low < 0 else high
        raise RigError(f"{where} has index {bad}, out of range (the mesh has {n} {what})")
    if sorted_unique and indices.size > 1 and not np.all(indices[1:] > indices[:-1]):
        raise RigError(f"{where} must be sorted and unique; pass np.unique(indices)")


def _check_skin_weights(weights: sp.csr_matrix, n_vertices: int, bones: tuple) -> None:
    if not (sp.issparse(weights) and weights.format == "csr"):
        raise RigError(f"skin_weights must be a scipy.sparse CSR matrix; got {type(weights).__name__}")
    expected = (n_vertices, len(bones))
    if weights.shape != expected:
        raise RigError(
            f"skin_weights has shape {weights.shape}; expected (n_vertices, n_bones) = {expected}, "
            "one column per bone in the order of bones"
        )
    if weights.dtype != np.float64:
        raise RigError(f"skin_weights has dtype {weights.dtype}; expected float64")
    data = weights.data
    if not np.isfinite(data).all():
        raise RigError("skin_weights has non-finite values")
    if (data < 0).any():
        row = int(np.searchsorted(weights.indptr, int(np.argmax(data < 0)), side="right") - 1)
        raise RigError(f"skin_weights row {row} (vertex {row}) has a negative weight; weights must be ≥ 0")
    counts = np.diff(weights.indptr)
    if counts.size and counts.max() > MAX_INFLUENCES:
        row = int(np.argmax(counts))
        raise RigError(
            f"skin_weights row {row} (vertex {row}) has {int(counts[row])} non-zero weights; at most "
            f"{MAX_INFLUENCES} bones may weight a vertex. Keep the largest {MAX_INFLUENCES} and renormalise."
        )
    sums = np.asarray(weights.sum(axis=1)).ravel()  # (n,)
    bad = np.abs(sums - 1.0) > WEIGHT_SUM_TOL
    if bad.any():
        row = int(np.argmax(bad))
        raise RigError(
            f"skin_weights row {row} (vertex {row}) sums to {sums[row]:.9g}; every vertex's weights must "
            f"sum to 1 (±{WEIGHT_SUM_TOL:g}) ({int(bad.sum())} rows do not). Divide each row by its sum, "
            "and give unweighted vertices to the root bone."
        )
