"""Write a rig as a UsdSkel asset (.usda, .usdc or .usd): mesh, blend shapes, skeleton and a clip.

Needs the optional extra ``mimetic[usd]`` (``usd-core``); ``pxr`` is imported on first use, never
at import time, and its absence raises ``MissingExtraError``.

What the file holds
-------------------
One stage whose default prim is a ``SkelRoot`` named after the file (``/face`` for ``face.usda``):

* **Stage metadata.** ``upAxis = "Y"``, ``metersPerUnit`` from ``units`` (default metres: 1.0),
  and with a clip ``timeCodesPerSecond = framesPerSecond = clip.fps``, ``startTimeCode = 0``,
  ``endTimeCode = frames - 1``: frame k of the clip is time code k.
* **Frame.** The stage's own declared convention, ``upAxis = "Y"`` with the face looking down +Z,
  and the rig's points as they are (no transform on the SkelRoot): a rig fitted to a Z-up scan
  already lives in that frame (``Rig.source_rotation`` records the turn), so usdview, Blender,
  Maya and Unreal, which convert a Y-up stage to their own up axis, show the head upright.
* **Mesh** (``/face/mesh``). One ``Mesh`` holding all the rig's vertices in the rig's order,
  scaled to ``units`` (float32 ``points``); triangles (``faceVertexCounts`` all 3,
  ``subdivisionScheme = "none"``, right-handed as the rig's counter-clockwise faces); area-weighted
  rest ``normals`` (vertex interpolation); ``primvars:displayColor`` (the mesh's vertex colours,
  else one skin tone); ``extent``. Each mesh part is a ``GeomSubset`` of faces in the family
  ``"part"`` (a partition when the parts cover every face once). USD needs no blocks of
  consecutive vertices, so the parts need not be laid out as ``Mesh.concatenate`` builds them.
* **Skin.** ``UsdSkel.BindingAPI`` on the mesh: ``skel:skeleton``, ``primvars:skel:jointIndices``
  and ``primvars:skel:jointWeights`` (vertex interpolation, ``elementSize`` 4, or the most
  influences of any vertex when that is more) from ``rig.skin_weights`` with float32 rows that
  sum to 1, and an identity ``primvars:skel:geomBindTransform``.
* **Skeleton** (``/face/skeleton``). One joint per ``rig.bones`` entry, in that order; joint paths
  follow the hierarchy (``head``, ``head/jaw``, ``head/eye_L``, …) and ``jointNames`` keeps the bone
  names. Each joint sits at its bone's ``head`` with an identity rotation, as in the glTF export:
  ``bindTransforms`` (skeleton space) and ``restTransforms`` (parent space) are translations.
* **Blend shapes.** One ``BlendShape`` child of the mesh per morph target, with ``offsets`` (in
  ``units``) and, unless ``target_normals=False``, ``normalOffsets`` (the change of the
  area-weighted normal at weight 1); ``pointIndices`` lists the points that move when they are at
  most ``SPARSE_MAX_SHARE`` of the mesh. The mesh's ``skel:blendShapes`` tokens and its
  ``skel:blendShapeTargets`` relationships are in ``morph_targets`` order. Prim names and tokens are
  ``usd_names(morph_targets)``: a name that is not a valid USD identifier (``[A-Za-z_][A-Za-z0-9_]*``)
  or is taken is changed, and the original is kept as the prim's ``displayName``.
* **Animation** (``/face/skeleton/<clip_name>``), when a clip is given. A ``SkelAnimation`` bound by
  the skeleton's ``skel:animationSource``: ``blendShapes`` (the targets named after a clip channel)
  with time-sampled ``blendShapeWeights``; ``joints`` (the bones that move during the clip) with
  time-sampled ``rotations`` and, when a joint's position moves (jaw slide and protrusion),
  ``translations`` (otherwise their rest values); ``scales`` are 1. Joint motion comes from
  ``mimetic.engines.skinning.bone_transforms``, as in the glTF export.

USD evaluates ``skinning(rest + Σ weights · offsets)`` with linear blend skinning, exactly what
``mimetic.export.gltf.gltf_vertices`` computes for a glTF file (see ``mimetic.export.gltf`` for
what the file loses against the engine, and ``morph_targets_from_basis`` for targets from a baked
basis). ``check_usd`` runs ``usdchecker``'s validators on a file.
"""

from __future__ import annotations

import logging
import os
import re
import warnings
from collections.abc import Iterable, Mapping
from pathlib import Path
from types import SimpleNamespace
from typing import Literal, NamedTuple

import numpy as np

from mimetic.atomic import WriteError, atomic_path
from mimetic.engines.skinning import bone_transforms
from mimetic.errors import MimeticWarning, MissingExtraError, RigError, install_hint
from mimetic.export.gltf import (
    MAX_INFLUENCES,
    MOTION_TOL_REL,
    ROTATION_TOL,
    SPARSE_MAX_SHARE,
    ExportError,
    check_export_inputs,
    clip_values,
    quaternions,
)
from mimetic.mesh.geometry import vertex_normals
from mimetic.mesh.units import UNIT_SCALE
from mimetic.rig.activations import Clip
from mimetic.rig.model import Rig

log = logging.getLogger(__name__)

SUFFIXES = (".usda", ".usdc", ".usd")
"""File suffixes ``export_usd`` writes: text, binary (crate), and binary under the generic suffix."""

PART_FAMILY = "part"
"""``familyName`` of the GeomSubsets that hold the mesh's parts."""

SKIN_TONE = (0.8, 0.65, 0.58)
"""``displayColor`` of a mesh without vertex colours (linear RGB), as the glTF export's base colour."""

_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


def _import_pxr() -> SimpleNamespace:
    """The pxr modules used here; ``MissingExtraError`` when usd-core is not installed."""
    try:
        from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt
    except ImportError as error:
        raise MissingExtraError(
            f"USD export needs the optional extra [usd] (usd-core): {install_hint('usd')}; "
            f"importing pxr failed: {error}"
        ) from error
    return SimpleNamespace(Gf=Gf, Sdf=Sdf, Usd=Usd, UsdGeom=UsdGeom, UsdSkel=UsdSkel, Vt=Vt)


# --------------------------------------------------------------------------- names


def usd_names(names: Iterable[str], taken: Iterable[str] = ()) -> dict[str, str]:
    """Valid, distinct USD prim names for ``names``, in order: {name: identifier}.

    A name that is already a valid identifier (``[A-Za-z_][A-Za-z0-9_]*``) and not yet used keeps
    itself. Otherwise every other character becomes ``_``, a leading digit gets a ``_`` in front,
    and a name already used (in ``taken`` or earlier in ``names``) gets the first free suffix
    ``_2``, ``_3``, …. Used for blend shapes, parts and joints; ``export_usd`` applies it to the
    morph target names, so ``usd_names(targets)[name]`` is the blend shape a target became.
    """
    used = set(taken)
    out: dict[str, str] = {}
    for name in names:
        base = name if _IDENTIFIER.match(name) else re.sub(r"[^A-Za-z0-9_]", "_", name) or "_"
        if base[0].isdigit():
            base = f"_{base}"
        candidate, k = base, 1
        while candidate in used:
            k += 1
            candidate = f"{base}_{k}"
        used.add(candidate)
        out[name] = candidate
    return out


# --------------------------------------------------------------------------- export


def export_usd(
    rig: Rig,
    path: str | os.PathLike[str],
    *,
    morph_targets: Mapping[str, np.ndarray] | None = None,
    clip: Clip | None = None,
    clip_name: str = "clip",
    target_normals: bool = True,
    units: str = "m",
    name: str | None = None,
) -> Path:
    """Write ``rig`` (and optionally morph targets and one animation) as a UsdSkel asset, atomically.

    Parameters
    ----------
    rig : Rig
        Its mesh, bones and skin weights; points are written in rig order.
    path : path-like
        The file to create or replace: ``.usda`` (text), ``.usdc`` or ``.usd`` (binary). Its folder
        must exist.
    morph_targets : Mapping[str, (n, 3) float], optional
        Displacements in rig units and rig vertex order, e.g.
        ``mimetic.export.morph_targets_from_basis(basis, rig)``. Written in mapping order as blend
        shapes named ``usd_names(morph_targets)``.
    clip : Clip, optional
        Channel values over time. Channels named like a morph target drive its weight; rig
        channels that move bones drive the joints. Every clip channel must be a rig channel or a
        target name.
    clip_name : str
        Name of the ``SkelAnimation`` prim (made a valid identifier).
    target_normals : bool
        Also write each blend shape's ``normalOffsets``.
    units : {"m", "dm", "cm", "mm"}
        Unit of the coordinates written, recorded as the stage's ``metersPerUnit``. USD tools scale
        by it, so any unit shows the head at its true size; "cm" suits Maya-style pipelines.
    name : str, optional
        Name of the SkelRoot (the default prim); defaults to the file's stem. Made a valid identifier.

    Returns
    -------
    path : Path
        The file written.

    Raises
    ------
    MissingExtraError
        usd-core is not installed (``pip install 'mimetic[usd]'``).
    ExportError
        An unknown suffix; a morph target of the wrong shape, non-finite or badly named; a clip
        that is not a ``Clip``.
    ActivationError
        Clip channels that are neither rig channels nor target names.
    WriteError
        The folder is missing or not writable; an existing file is left as it was.
    """
    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise ExportError(
            f"{path.name}: a USD file must end in {', '.join(SUFFIXES)} (got {path.suffix or 'no suffix'!r})"
        )
    units, scale, targets = check_export_inputs(rig, morph_targets, clip, clip_name, units)
    values = None if clip is None else clip_values(rig, clip, tuple(targets))  # (f, c) rig order
    pxr = _import_pxr()

    stage = pxr.Usd.Stage.CreateInMemory()
    pxr.UsdGeom.SetStageUpAxis(stage, pxr.UsdGeom.Tokens.y)
    pxr.UsdGeom.SetStageMetersPerUnit(stage, UNIT_SCALE[units])
    stage.SetMetadata(
        "customLayerData",
        {"generator": f"mimetic {_version()} (usd-core {_usd_version(pxr)})", "source_units": rig.units},
    )
    root_name = name or path.stem or "mimetic"
    root_path = pxr.Sdf.Path.absoluteRootPath.AppendChild(usd_names([root_name])[root_name])
    root = pxr.UsdSkel.Root.Define(stage, root_path)
    stage.SetDefaultPrim(root.GetPrim())
    pxr.Usd.ModelAPI(root).SetKind("component")

    skeleton, joint_paths = _define_skeleton(pxr, stage, rig, root_path.AppendChild("skeleton"), scale)
    shape_names = _define_mesh(
        pxr, stage, rig, root_path.AppendChild("mesh"), skeleton, targets, scale, target_normals
    )
    if clip is not None:
        assert values is not None
        anim_path = skeleton.GetPath().AppendChild(usd_names([clip_name])[clip_name])
        if _define_animation(pxr, stage, rig, anim_path, clip, values, shape_names, joint_paths, scale):
            pxr.UsdSkel.BindingAPI.Apply(skeleton.GetPrim()).CreateAnimationSourceRel().SetTargets(
                [anim_path]
            )
            stage.SetTimeCodesPerSecond(clip.fps)
            stage.SetFramesPerSecond(clip.fps)
            stage.SetStartTimeCode(0)
            stage.SetEndTimeCode(clip.n_frames - 1)
        else:
            warnings.warn(
                f"clip {clip_name!r} drives no blend shape and no joint; no animation written. Name the "
                "targets after the clip's channels (morph_targets_from_basis does).",
                MimeticWarning,
                stacklevel=2,
            )

    _export_layer_atomic(stage.GetRootLayer(), path)
    log.info(
        "wrote %s: %d points, %d blend shapes, %d joints, %s",
        path,
        rig.n_vertices,
        len(shape_names),
        rig.n_bones,
        f"clip {clip_name!r} of {clip.n_frames} frames" if clip is not None else "no animation",
    )
    return path


def _define_skeleton(pxr, stage, rig: Rig, where, scale: float):
    """The Skeleton prim: joints by hierarchy, bind (skeleton space) and rest (parent space) transforms."""
    names = usd_names(rig.bone_names)
    joint_paths: list[str] = []
    for bone in rig.bones:
        parent = "" if bone.parent is None else joint_paths[rig.bone_index(bone.parent)] + "/"
        joint_paths.append(parent + names[bone.name])
    heads = np.array([bone.head for bone in rig.bones]) * scale  # (b, 3)
    parents = np.array(
        [heads[rig.bone_index(b.parent)] if b.parent is not None else np.zeros(3) for b in rig.bones]
    )
    skeleton = pxr.UsdSkel.Skeleton.Define(stage, where)
    skeleton.CreateJointsAttr(joint_paths)
    skeleton.CreateJointNamesAttr(list(rig.bone_names))
    skeleton.CreateBindTransformsAttr(_translations(pxr, heads))
    skeleton.CreateRestTransformsAttr(_translations(pxr, heads - parents))
    return skeleton, joint_paths


def _translations(pxr, t: np.ndarray):
    """A Matrix4dArray of pure translations t (k, 3), in USD's row-vector layout (translation in row 3)."""
    m = np.tile(np.eye(4), (len(t), 1, 1))
    m[:, 3, :3] = t
    return pxr.Vt.Matrix4dArray.FromNumpy(m)


def _define_mesh(pxr, stage, rig: Rig, where, skeleton, targets, scale: float, target_normals: bool):
    """The skinned Mesh with its parts (GeomSubsets) and blend shapes; returns {target: blend shape name}."""
    Vt, UsdGeom, UsdSkel = pxr.Vt, pxr.UsdGeom, pxr.UsdSkel
    source = rig.mesh
    n = rig.n_vertices
    points = np.ascontiguousarray(source.vertices * scale, dtype=np.float32)  # (n, 3)
    normals = vertex_normals(source.vertices, source.faces)  # (n, 3) unit, zero where no face
    unused = np.linalg.norm(normals, axis=1) == 0
    normals[unused] = (0.0, 1.0, 0.0)

    mesh = UsdGeom.Mesh.Define(stage, where)
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(source.n_faces, 3, np.int32)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(source.faces.astype(np.int32).ravel()))
    mesh.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(normals.astype(np.float32)))
    mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
    mesh.CreateExtentAttr(UsdGeom.PointBased.ComputeExtent(mesh.GetPointsAttr().Get()))
    color = mesh.CreateDisplayColorPrimvar()
    if source.colors is None:
        color.SetInterpolation(UsdGeom.Tokens.constant)
        color.Set(Vt.Vec3fArray([SKIN_TONE]))
    else:
        color.SetInterpolation(UsdGeom.Tokens.vertex)
        color.Set(Vt.Vec3fArray.FromNumpy(np.clip(source.colors, 0.0, 1.0).astype(np.float32)))

    part_names = usd_names(source.parts)
    for part, faces in source.parts.items():
        UsdGeom.Subset.CreateGeomSubset(
            mesh,
            part_names[part],
            UsdGeom.Tokens.face,
            Vt.IntArray.FromNumpy(faces.astype(np.int32)),
            PART_FAMILY,
        )
    if source.parts:
        counts = np.bincount(np.concatenate(list(source.parts.values())), minlength=source.n_faces)
        family = (
            UsdGeom.Tokens.partition
            if counts.min() == 1 and counts.max() == 1
            else UsdGeom.Tokens.nonOverlapping
            if counts.max() <= 1
            else UsdGeom.Tokens.unrestricted
        )
        UsdGeom.Subset.SetFamilyType(mesh, PART_FAMILY, family)

    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skeleton.GetPath()])
    joints, weights = _influences(rig)
    k = joints.shape[1]
    binding.CreateJointIndicesPrimvar(False, k).Set(Vt.IntArray.FromNumpy(joints.ravel()))
    binding.CreateJointWeightsPrimvar(False, k).Set(Vt.FloatArray.FromNumpy(weights.ravel()))
    binding.CreateGeomBindTransformAttr(pxr.Gf.Matrix4d(1.0))

    shape_names = usd_names(targets, taken=part_names.values())
    shape_paths = []
    for target, delta in targets.items():
        shape = UsdSkel.BlendShape.Define(stage, where.AppendChild(shape_names[target]))
        if shape_names[target] != target:
            shape.GetPrim().SetDisplayName(target)
        offsets = (delta * scale).astype(np.float32)  # (n, 3)
        moved = np.any(offsets != 0, axis=1)  # (n,)
        normal_offsets = None
        if target_normals:
            bent = vertex_normals(source.vertices + delta, source.faces)
            bent[unused] = normals[unused]
            normal_offsets = (bent - normals).astype(np.float32)
            moved |= np.any(normal_offsets != 0, axis=1)
        index = np.flatnonzero(moved)
        if len(index) > SPARSE_MAX_SHARE * n:
            index = None  # dense: offsets for every point, no pointIndices
        elif len(index) == 0:
            index = np.zeros(1, np.int64)  # an empty pointIndices would mean "every point"
        if index is not None:
            shape.CreatePointIndicesAttr(Vt.IntArray.FromNumpy(index.astype(np.int32)))
            offsets = offsets[index]
            normal_offsets = None if normal_offsets is None else normal_offsets[index]
        shape.CreateOffsetsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(offsets)))
        if normal_offsets is not None:
            shape.CreateNormalOffsetsAttr(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(normal_offsets)))
        shape_paths.append(shape.GetPath())
    if targets:
        binding.CreateBlendShapesAttr([shape_names[t] for t in targets])
        binding.CreateBlendShapeTargetsRel().SetTargets(shape_paths)
    return shape_names


def _define_animation(pxr, stage, rig, where, clip, values, shape_names, joint_paths, scale) -> bool:
    """The SkelAnimation for ``clip``; False (and nothing defined) when it drives nothing."""
    Vt = pxr.Vt
    column = {c: j for j, c in enumerate(clip.channels)}
    driven = [t for t in shape_names if t in column]
    moving, rotations, translations = _joint_motion(rig, values, scale)
    if not driven and not moving:
        return False
    anim = pxr.UsdSkel.Animation.Define(stage, where)
    if driven:
        weights = np.ascontiguousarray(clip.values[:, [column[t] for t in driven]], dtype=np.float32)
        anim.CreateBlendShapesAttr([shape_names[t] for t in driven])
        attr = anim.CreateBlendShapeWeightsAttr()
        for f in range(clip.n_frames):
            attr.Set(Vt.FloatArray.FromNumpy(weights[f]), f)
    if moving:
        anim.CreateJointsAttr([joint_paths[k] for k in moving])
        anim.CreateScalesAttr(Vt.Vec3hArray.FromNumpy(np.ones((len(moving), 3), np.float16)))
        r_attr = anim.CreateRotationsAttr()
        t_attr = anim.CreateTranslationsAttr()
        t = np.ascontiguousarray(translations[:, moving], dtype=np.float32)  # (f, j, 3)
        q = np.ascontiguousarray(rotations[:, moving], dtype=np.float32)  # (f, j, 4) x y z w
        still = np.abs(t - t[:1]).max(initial=0.0) <= MOTION_TOL_REL * rig.scale * scale
        if still:
            t_attr.Set(Vt.Vec3fArray.FromNumpy(t[0]))
        for f in range(clip.n_frames):
            r_attr.Set(Vt.QuatfArray.FromNumpy(q[f]), f)  # GfQuatf's memory layout is x y z w
            if not still:
                t_attr.Set(Vt.Vec3fArray.FromNumpy(t[f]), f)
    return True


def _joint_motion(rig: Rig, values: np.ndarray, scale: float) -> tuple[list[int], np.ndarray, np.ndarray]:
    """Bones that move over ``values`` (f, c), and every bone's local rotation (f, b, 4) and translation.

    A joint sits at its bone's head under its parent's joint, so its local transform is
    inv(P_parent) P_k with P = world pose x rest placement (as in the glTF export). Rotations are
    unit quaternions x y z w, each in the hemisphere of the frame before; translations (f, b, 3)
    are in file units.
    """
    world = np.stack([bone_transforms(rig, v) for v in values])  # (f, b, 4, 4)
    rest = np.tile(np.eye(4), (rig.n_bones, 1, 1))
    rest[:, :3, 3] = [bone.head for bone in rig.bones]
    placed = world @ rest  # (f, b, 4, 4)
    moving = []
    rotations = np.empty((len(values), rig.n_bones, 4))
    translations = np.empty((len(values), rig.n_bones, 3))
    for k, bone in enumerate(rig.bones):
        if bone.parent is None:
            local, rest_local = placed[:, k], rest[k]
        else:
            p = rig.bone_index(bone.parent)
            local = np.linalg.solve(placed[:, p], placed[:, k])  # (f, 4, 4)
            rest_local = np.linalg.solve(rest[p], rest[k])
        rot = local[:, :3, :3]
        if not np.allclose(rot @ rot.transpose(0, 2, 1), np.eye(3), atol=ROTATION_TOL):
            raise RigError(f"bone {bone.name!r}: its pose is not a rotation plus a translation")
        turned = not np.allclose(rot, np.eye(3), rtol=0.0, atol=1e-12)
        shifted = np.abs(local[:, :3, 3] - rest_local[:3, 3]).max(initial=0.0) > MOTION_TOL_REL * rig.scale
        if turned or shifted:
            moving.append(k)
        rotations[:, k] = quaternions(rot)
        translations[:, k] = local[:, :3, 3] * scale
    return moving, rotations, translations


def _influences(rig: Rig) -> tuple[np.ndarray, np.ndarray]:
    """Joint indices (n, k) int32 and weights (n, k) float32 from the rig's CSR skin weights.

    k is ``MAX_INFLUENCES`` or the most influences of any vertex, if more; unused slots are joint 0
    with weight 0. Each row sums to 1 in float32 (rounding goes into its largest weight).
    """
    w = rig.skin_weights
    n = rig.n_vertices
    counts = np.diff(w.indptr)
    k = max(MAX_INFLUENCES, int(counts.max(initial=0)))
    rows = np.repeat(np.arange(n), counts)
    slot = np.arange(len(w.indices)) - np.repeat(w.indptr[:-1], counts)
    joints = np.zeros((n, k), np.int32)
    weights = np.zeros((n, k), np.float64)
    joints[rows, slot] = w.indices
    weights[rows, slot] = w.data
    weights /= weights.sum(axis=1, keepdims=True)
    weights = weights.astype(np.float32)
    big = np.argmax(weights, axis=1)
    others = weights.sum(axis=1, dtype=np.float64) - weights[np.arange(n), big]
    weights[np.arange(n), big] = (1.0 - others).astype(np.float32)
    return joints, weights


def _export_layer(layer, path: str) -> bool:
    """Write ``layer`` to ``path`` in the format its suffix names (a seam for tests)."""
    return layer.Export(path)


def _export_layer_atomic(layer, path: Path) -> None:
    """Export to a temporary file beside ``path`` (same suffix, so USD picks the format), then
    replace ``path`` (``mimetic.atomic.atomic_path``)."""
    with atomic_path(path, keep_suffix=True) as tmp:
        try:
            ok = _export_layer(layer, str(tmp))
        except Exception as error:  # pxr raises Tf.ErrorException, a RuntimeError
            raise WriteError(f"cannot write {path}: USD failed to export the stage ({error})") from error
        if not ok:
            raise WriteError(f"cannot write {path}: USD failed to export the stage")


def _version() -> str:
    from mimetic import __version__

    return __version__


def _usd_version(pxr) -> str:
    return ".".join(map(str, pxr.Usd.GetVersion()[1:]))


# --------------------------------------------------------------------------- checking


class UsdIssue(NamedTuple):
    """One finding of ``check_usd``: ``kind`` is "error", "warning" or "info"."""

    kind: Literal["error", "warning", "info"]
    message: str


def check_usd(path: str | os.PathLike[str]) -> list[UsdIssue]:
    """What ``usdchecker`` reports for a USD file, run in-process with usd-core's validators.

    The validators are those ``usdchecker`` (new validation framework, no ``--arkit``) runs on a
    plain file: every registered validator except the USDZ-package and root-package ones. The
    file passes ``usdchecker`` when no issue has ``kind == "error"`` (with ``--strict``, when
    there is no "warning" either).

    Raises
    ------
    MissingExtraError
        usd-core is not installed.
    ExportError
        The file cannot be opened as a USD stage.
    """
    pxr = _import_pxr()
    try:
        from pxr import UsdValidation
    except ImportError as error:
        raise MissingExtraError(
            f"this usd-core has no UsdValidation ({error}); reinstall the [usd] extra: {install_hint('usd')}"
        ) from error
    path = Path(path)
    try:
        stage = pxr.Usd.Stage.Open(str(path))
    except Exception as error:
        raise ExportError(f"{path}: cannot open the USD stage ({error})") from None
    if not stage:
        raise ExportError(f"{path}: cannot open the USD stage")
    registry = UsdValidation.ValidationRegistry()
    names = sorted(
        m.name
        for m in registry.GetAllValidatorMetadata()
        if "UsdzValidators" not in m.GetKeywords() and not m.name.endswith(":RootPackageValidator")
    )
    kinds = {
        UsdValidation.ValidationErrorType.Error: "error",
        UsdValidation.ValidationErrorType.Warn: "warning",
    }
    errors = UsdValidation.ValidationContext(registry.GetOrLoadValidatorsByName(names)).Validate(stage)
    return [UsdIssue(kinds.get(e.GetType(), "info"), e.GetErrorAsString()) for e in errors]
