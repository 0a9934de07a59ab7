"""Tests for mimetic.export.usd: the stage read back with usd-core (pxr), prim by prim.

The pose checks evaluate the file with UsdSkel itself (``UsdSkel.Cache`` → skeleton and skinning
queries, ``UsdSkel.BlendShapeQuery``, and ``UsdSkel.BakeSkinning``), so they test what a USD
client shows; that must agree with ``gltf_vertices``, the library's statement of
``skinning(rest + Σ weights · targets)``. Skipped without usd-core, except on CI (CI=true), where
a missing usd-core fails.
"""

from __future__ import annotations

import dataclasses
import sys
import warnings
from types import SimpleNamespace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mimetic.animate.keyframes import from_expressions
from mimetic.atomic import WriteError
from mimetic.engines import make_engine
from mimetic.engines.bake import bake
from mimetic.engines.skinning import bone_transforms
from mimetic.errors import ActivationError, MimeticWarning, MissingExtraError
from mimetic.export.gltf import ExportError, gltf_vertices, morph_targets_from_basis
from mimetic.export.usd import check_usd, export_usd, usd_names
from mimetic.mesh.model import Mesh
from mimetic.rig.activations import Clip
from mimetic.rig.model import thaw_json
from mimetic.testing import require_extra, small_rig

CM = 0.01  # metres per centimetre: the small rig is in cm
F32 = 2e-7  # relative float32 rounding, with margin
POSE_TOL_M = 1e-6  # UsdSkel's float32 evaluation against gltf_vertices' float64 (head ≈ 0.23 m)


# --------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def usd():
    """The pxr modules; skips when usd-core is missing, except on CI, where it fails."""
    require_extra("pxr", "usd")
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdSkel, Vt

    return SimpleNamespace(Gf=Gf, Sdf=Sdf, Usd=Usd, UsdGeom=UsdGeom, UsdSkel=UsdSkel, Vt=Vt)


@pytest.fixture(scope="module")
def rig():
    return small_rig()


@pytest.fixture(scope="module")
def targets(rig):
    basis = bake(make_engine(rig, "wire"), samples=8).basis
    return morph_targets_from_basis(basis, rig)


@pytest.fixture(scope="module")
def clip(rig):
    """Rest → joy → rest over one second at 24 fps (25 frames), every rig channel."""
    return from_expressions(rig, [(0, "rest"), (0.5, "joy"), (1, "rest")]).sample(24, channels=rig)


def moving_clip(rig, frames: int = 9, fps: float = 30.0) -> Clip:
    """Jaw (rotation and slide), gaze, head and one lid muscle in motion: every kind of joint track."""
    t = np.arange(frames) / fps
    values = np.tile([c.default for c in rig.channels], (frames, 1))
    for name, amplitude in {
        "jaw_open": 0.3,
        "jaw_slide": 0.02,
        "gaze_yaw": 0.4,
        "head_yaw": 0.5,
        "orbicularis_oculi_L": 0.8,
        "zygomatic_major_R": 1.0,
    }.items():
        values[:, rig.channel_index(name)] = amplitude * np.sin(3.0 * t) ** 2
    return Clip(rig.channel_names, values, fps)


@pytest.fixture(scope="module")
def exported(usd, tmp_path_factory, rig, targets, clip):
    """The small rig with its basis targets and the joy clip as .usda; (path, stage)."""
    path = tmp_path_factory.mktemp("usd") / "face.usda"
    copies = {k: v.copy() for k, v in targets.items()}
    export_usd(rig, path, morph_targets=targets, clip=clip)
    for name, delta in targets.items():  # inputs untouched
        np.testing.assert_array_equal(delta, copies[name])
    return path, usd.Usd.Stage.Open(str(path))


def rotated(rig, rotation: np.ndarray):
    metadata = {**thaw_json(rig.metadata), "source_rotation": np.asarray(rotation).tolist()}
    return dataclasses.replace(rig, metadata=metadata)


# --------------------------------------------------------------------------- a UsdSkel client


def prims(usd, stage):
    root = stage.GetDefaultPrim()
    return (
        usd.UsdSkel.Root(root),
        usd.UsdSkel.Skeleton(root.GetChild("skeleton")),
        usd.UsdGeom.Mesh(root.GetChild("mesh")),
    )


def usd_pose(usd, stage, frame: float) -> np.ndarray:
    """World positions (n, 3) float64 of the mesh at time code ``frame``, as UsdSkel computes them.

    Blend shapes (animation weights mapped onto the mesh's ``skel:blendShapes``), then linear blend
    skinning with the skeleton's skinning transforms, then the skeleton's local-to-world transform.
    """
    root, skeleton, mesh = prims(usd, stage)
    time = usd.Usd.TimeCode(frame)
    cache = usd.UsdSkel.Cache()
    cache.Populate(root, usd.Usd.PrimDefaultPredicate)
    skel_query = cache.GetSkelQuery(skeleton)
    skinning = cache.GetSkinningQuery(mesh.GetPrim())
    points = mesh.GetPointsAttr().Get(time)
    anim = skel_query.GetAnimQuery()
    if anim and skinning.HasBlendShapes():
        weights = skinning.GetBlendShapeMapper().Remap(anim.ComputeBlendShapeWeights(time))
        shapes = usd.UsdSkel.BlendShapeQuery(usd.UsdSkel.BindingAPI(mesh.GetPrim()))
        sub_weights, shape_index, sub_index = shapes.ComputeSubShapeWeights(weights)
        assert shapes.ComputeDeformedPoints(
            sub_weights,
            shape_index,
            sub_index,
            shapes.ComputeBlendShapePointIndices(),
            shapes.ComputeSubShapePointOffsets(),
            points,
        )
    assert skinning.ComputeSkinnedPoints(skel_query.ComputeSkinningTransforms(time), points, time)
    world = np.array(usd.UsdGeom.Xformable(skeleton).ComputeLocalToWorldTransform(time))  # row-vector
    v = np.array(points, dtype=np.float64)
    return v @ world[:3, :3] + world[3, :3]


def baked_pose(usd, path, frames: list[int]) -> dict[int, np.ndarray]:
    """World positions of the mesh at ``frames`` after ``UsdSkel.BakeSkinning`` (in a session layer)."""
    stage = usd.Usd.Stage.Open(str(path), usd.Usd.Stage.LoadAll)
    session = stage.GetSessionLayer()
    # a layer's time samples are scaled by the ratio of its timeCodesPerSecond to the root layer's:
    # without this the session layer's default 24 would shift a 30 fps bake by a factor 1.25
    session.timeCodesPerSecond = stage.GetRootLayer().timeCodesPerSecond
    stage.SetEditTarget(session)
    root, _, mesh = prims(usd, stage)
    assert usd.UsdSkel.BakeSkinning(root, usd.Gf.Interval(min(frames), max(frames)))
    out = {}
    for f in frames:
        time = usd.Usd.TimeCode(f)
        world = np.array(mesh.ComputeLocalToWorldTransform(time))
        v = np.array(mesh.GetPointsAttr().Get(time), dtype=np.float64)
        out[f] = v @ world[:3, :3] + world[3, :3]
    return out


def frame_pose(clip: Clip, frame: int) -> dict[str, float]:
    return dict(zip(clip.channels, clip.values[frame], strict=True))


# --------------------------------------------------------------------------- validity


def test_export_usd_passes_usdchecker(usd, rig, targets, exported, tmp_path):
    path, _ = exported
    issues = check_usd(path)
    assert issues == [], "\n".join(i.message for i in issues)
    crate = export_usd(rig, tmp_path / "face.usdc", morph_targets=targets, clip=moving_clip(rig))
    assert check_usd(crate) == []


def test_check_usd_reports_broken_files(usd, tmp_path):
    path = tmp_path / "bad.usda"
    path.write_text(
        '#usda 1.0\n(\n    upAxis = "Z"\n)\ndef Mesh "m"\n{\n    rel skel:skeleton = </s>\n}\n',
        encoding="utf-8",
    )
    issues = check_usd(path)
    messages = "\n".join(i.message for i in issues if i.kind == "error")
    assert "MissingMetersPerUnitMetadata" in messages
    assert "MissingDefaultPrim" in messages
    assert "MissingSkelBindingAPI" in messages
    with pytest.raises(ExportError, match="cannot open"):
        check_usd(tmp_path / "missing.usda")


@pytest.mark.parametrize(
    ("suffix", "magic"), [(".usda", b"#usda 1.0"), (".usdc", b"PXR-USDC"), (".usd", b"PXR-USDC")]
)
def test_export_usd_format_follows_suffix(usd, rig, tmp_path, suffix, magic):
    path = export_usd(rig, tmp_path / f"head{suffix}")
    assert path == tmp_path / f"head{suffix}"
    assert path.read_bytes().startswith(magic)
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary file left


def test_export_usd_stage_metadata(usd, rig, clip, exported):
    _, stage = exported
    assert usd.UsdGeom.GetStageUpAxis(stage) == "Y"
    assert usd.UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetDefaultPrim().GetPath() == "/face"
    assert stage.GetDefaultPrim().GetTypeName() == "SkelRoot"
    assert stage.GetTimeCodesPerSecond() == clip.fps == stage.GetFramesPerSecond()
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0, clip.n_frames - 1)
    assert stage.GetRootLayer().customLayerData["source_units"] == "cm"


# --------------------------------------------------------------------------- mesh


def test_export_usd_points_are_rig_vertices_in_metres(usd, rig, exported):
    _, stage = exported
    _, _, mesh = prims(usd, stage)
    points = np.array(mesh.GetPointsAttr().Get())
    assert points.shape == (rig.n_vertices, 3) and points.dtype == np.float32
    np.testing.assert_allclose(points, rig.mesh.vertices * CM, rtol=F32, atol=1e-9)
    counts = np.array(mesh.GetFaceVertexCountsAttr().Get())
    indices = np.array(mesh.GetFaceVertexIndicesAttr().Get())
    assert counts.shape == (rig.mesh.n_faces,) and np.all(counts == 3)
    np.testing.assert_array_equal(indices.reshape(-1, 3), rig.mesh.faces)
    assert mesh.GetSubdivisionSchemeAttr().Get() == "none"
    normals = np.array(mesh.GetNormalsAttr().Get())
    assert normals.shape == (rig.n_vertices, 3) and mesh.GetNormalsInterpolation() == "vertex"
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-5)
    color = mesh.GetDisplayColorPrimvar()
    assert color.GetInterpolation() == "vertex"
    np.testing.assert_array_equal(np.array(color.Get()), rig.mesh.colors)


def test_export_usd_units_cm_keeps_rig_coordinates(usd, rig, tmp_path):
    stage = usd.Usd.Stage.Open(str(export_usd(rig, tmp_path / "cm.usdc", units="cm")))
    assert usd.UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.01)
    _, skeleton, mesh = prims(usd, stage)
    np.testing.assert_allclose(np.array(mesh.GetPointsAttr().Get()), rig.mesh.vertices, rtol=F32, atol=1e-7)
    bind = np.array(skeleton.GetBindTransformsAttr().Get())
    np.testing.assert_allclose(bind[:, 3, :3], [b.head for b in rig.bones], rtol=F32, atol=1e-7)


def test_export_usd_parts_become_a_partition_of_face_subsets(usd, rig, exported):
    _, stage = exported
    _, _, mesh = prims(usd, stage)
    subsets = usd.UsdGeom.Subset.GetGeomSubsets(mesh, "face", "part")
    assert [s.GetPrim().GetName() for s in subsets] == list(rig.mesh.parts)
    for subset in subsets:
        faces = np.array(subset.GetIndicesAttr().Get())
        np.testing.assert_array_equal(faces, rig.mesh.parts[subset.GetPrim().GetName()])
    assert usd.UsdGeom.Subset.GetFamilyType(mesh, "part") == "partition"
    valid, reason = usd.UsdGeom.Subset.ValidateFamily(mesh, "face", "part")
    assert valid, reason


def test_export_usd_parts_need_not_be_blocks(usd, rig, tmp_path):
    m = rig.mesh
    parts = {"even": np.arange(0, m.n_faces, 2), "bad name!": np.arange(1, 30, 2)}
    other = dataclasses.replace(rig, mesh=Mesh(m.vertices, m.faces, parts, None, m.units))
    path = export_usd(other, tmp_path / "odd.usda")
    assert check_usd(path) == []
    stage = usd.Usd.Stage.Open(str(path))  # keep it alive: prims only hold a weak reference
    _, _, mesh = prims(usd, stage)
    subsets = usd.UsdGeom.Subset.GetGeomSubsets(mesh, "face", "part")
    assert [s.GetPrim().GetName() for s in subsets] == ["even", "bad_name_"]
    assert usd.UsdGeom.Subset.GetFamilyType(mesh, "part") == "nonOverlapping"
    assert mesh.GetDisplayColorPrimvar().GetInterpolation() == "constant"


# --------------------------------------------------------------------------- blend shapes


def shape_offsets(usd, stage, n: int) -> dict[str, tuple[np.ndarray, np.ndarray | None]]:
    """{blend shape token: (offsets (n, 3), normal offsets (n, 3) or None)}, sparse ones expanded."""
    _, _, mesh = prims(usd, stage)
    binding = usd.UsdSkel.BindingAPI(mesh.GetPrim())
    tokens = binding.GetBlendShapesAttr().Get()
    out = {}
    for token, target in zip(tokens, binding.GetBlendShapeTargetsRel().GetTargets(), strict=True):
        shape = usd.UsdSkel.BlendShape(stage.GetPrimAtPath(target))
        index = shape.GetPointIndicesAttr().Get()
        index = np.arange(n) if index is None else np.array(index)
        offsets = np.zeros((n, 3), np.float32)
        offsets[index] = np.array(shape.GetOffsetsAttr().Get())
        normals = None
        if shape.GetNormalOffsetsAttr().HasAuthoredValue():
            normals = np.zeros((n, 3), np.float32)
            normals[index] = np.array(shape.GetNormalOffsetsAttr().Get())
        out[token] = (offsets, normals)
    return out


def test_export_usd_blend_shapes_are_the_targets_in_metres(usd, rig, targets, exported):
    _, stage = exported
    shapes = shape_offsets(usd, stage, rig.n_vertices)
    assert list(shapes) == list(targets)  # channel names are valid identifiers: kept as they are
    for name, (offsets, normals) in shapes.items():
        np.testing.assert_allclose(offsets, targets[name] * CM, rtol=F32, atol=1e-12, err_msg=name)
        assert normals is not None
    mesh = prims(usd, stage)[2].GetPrim()
    sparse = [t for t in shapes if mesh.GetChild(t).GetAttribute("pointIndices").HasAuthoredValue()]
    assert sparse == list(shapes)  # each muscle moves less than half of the points


def test_export_usd_blend_shape_at_weight_one_gives_rest_plus_target(usd, rig, targets, exported):
    _, stage = exported
    _, _, mesh = prims(usd, stage)
    query = usd.UsdSkel.BlendShapeQuery(usd.UsdSkel.BindingAPI(mesh.GetPrim()))
    names = list(targets)
    for name in ("zygomatic_major_L", "orbicularis_oris"):
        weights = np.zeros(len(names), np.float32)
        weights[names.index(name)] = 1.0
        sub_weights, shape_index, sub_index = query.ComputeSubShapeWeights(
            usd.Vt.FloatArray.FromNumpy(weights)
        )
        points = mesh.GetPointsAttr().Get()
        assert query.ComputeDeformedPoints(
            sub_weights,
            shape_index,
            sub_index,
            query.ComputeBlendShapePointIndices(),
            query.ComputeSubShapePointOffsets(),
            points,
        )
        expected = (rig.mesh.vertices + targets[name]) * CM
        np.testing.assert_allclose(np.array(points), expected, rtol=0, atol=1e-8, err_msg=name)


def test_export_usd_target_names_become_valid_unique_prim_names(usd, rig, tmp_path):
    rng = np.random.default_rng(5)
    n = rig.n_vertices
    given = {
        "smile left": rng.normal(size=(n, 3)),
        "smile_left": rng.normal(size=(n, 3)),
        "1up": np.zeros((n, 3)),
        "skin": rng.normal(size=(n, 3)),  # a part (GeomSubset) has this name
    }
    path = export_usd(rig, tmp_path / "names.usda", morph_targets=given, target_normals=False)
    assert check_usd(path) == []
    stage = usd.Usd.Stage.Open(str(path))
    mapping = usd_names(given, taken=rig.mesh.parts)
    assert mapping == {
        "smile left": "smile_left",
        "smile_left": "smile_left_2",
        "1up": "_1up",
        "skin": "skin_2",
    }
    shapes = shape_offsets(usd, stage, n)
    assert list(shapes) == list(mapping.values())
    _, _, mesh = prims(usd, stage)
    for name, token in mapping.items():
        np.testing.assert_allclose(shapes[token][0], given[name] * CM, rtol=F32, atol=1e-12)
        assert shapes[token][1] is None  # target_normals=False
        prim = mesh.GetPrim().GetChild(token)
        assert prim.GetDisplayName() == (name if name != token else "")
    dense = usd.UsdSkel.BlendShape(mesh.GetPrim().GetChild("smile_left"))
    assert not dense.GetPointIndicesAttr().HasAuthoredValue()  # every point moves: no indices
    zero = usd.UsdSkel.BlendShape(mesh.GetPrim().GetChild("_1up"))
    assert list(zero.GetPointIndicesAttr().Get()) == [0]  # an empty list would mean every point


def test_usd_names_keeps_valid_names_and_fixes_the_rest():
    assert usd_names(["jaw", "eye_L"]) == {"jaw": "jaw", "eye_L": "eye_L"}
    assert usd_names(["a-b", "a_b", "a.b", "9", ""], taken=["x"]) == {
        "a-b": "a_b",
        "a_b": "a_b_2",
        "a.b": "a_b_3",
        "9": "_9",
        "": "_",
    }
    assert usd_names(["x"], taken=["x", "x_2"]) == {"x": "x_3"}


# --------------------------------------------------------------------------- skeleton and skin


def test_export_usd_skeleton_joints_follow_bone_hierarchy(usd, rig, exported):
    _, stage = exported
    _, skeleton, _ = prims(usd, stage)
    assert list(skeleton.GetJointsAttr().Get()) == [
        "head",
        "head/jaw",
        "head/eyelid_upper_L",
        "head/eyelid_upper_R",
        "head/eyelid_lower_L",
        "head/eyelid_lower_R",
        "head/eye_L",
        "head/eye_R",
    ]
    assert list(skeleton.GetJointNamesAttr().Get()) == list(rig.bone_names)
    heads = np.array([b.head for b in rig.bones]) * CM
    bind = np.array(skeleton.GetBindTransformsAttr().Get())  # (b, 4, 4), translation in row 3
    rest = np.array(skeleton.GetRestTransformsAttr().Get())
    assert bind.shape == rest.shape == (rig.n_bones, 4, 4)
    np.testing.assert_allclose(bind[:, :3, :3], np.tile(np.eye(3), (rig.n_bones, 1, 1)), atol=0)
    np.testing.assert_allclose(bind[:, 3, :3], heads, rtol=1e-12)
    np.testing.assert_allclose(rest[0, 3, :3], heads[0], rtol=1e-12)
    np.testing.assert_allclose(rest[1:, 3, :3], heads[1:] - heads[0], rtol=1e-12, atol=1e-15)
    topology = usd.UsdSkel.Topology(skeleton.GetJointsAttr().Get())
    valid, reason = topology.Validate()
    assert valid, reason


def test_export_usd_joint_weights_match_skin_weights(usd, rig, exported):
    _, stage = exported
    _, skeleton, mesh = prims(usd, stage)
    binding = usd.UsdSkel.BindingAPI(mesh.GetPrim())
    assert binding.GetSkeletonRel().GetTargets() == [skeleton.GetPath()]
    indices, weights = binding.GetJointIndicesPrimvar(), binding.GetJointWeightsPrimvar()
    assert indices.GetElementSize() == weights.GetElementSize() == 4
    assert indices.GetInterpolation() == weights.GetInterpolation() == "vertex"
    joints = np.array(indices.Get()).reshape(-1, 4)
    w = np.array(weights.Get()).reshape(-1, 4)
    assert joints.shape == w.shape == (rig.n_vertices, 4) and w.dtype == np.float32
    np.testing.assert_allclose(w.sum(axis=1, dtype=np.float32), 1.0, rtol=0, atol=2e-7)
    dense = np.zeros((rig.n_vertices, rig.n_bones))
    np.add.at(dense, (np.repeat(np.arange(rig.n_vertices), 4), joints.ravel()), w.ravel())
    np.testing.assert_allclose(dense, rig.skin_weights.toarray(), atol=2e-7)
    np.testing.assert_array_equal(np.array(binding.GetGeomBindTransformAttr().Get()), np.eye(4))


# --------------------------------------------------------------------------- animation


def test_export_usd_animation_samples_and_weights_match_clip(usd, rig, targets, clip, exported):
    _, stage = exported
    _, skeleton, _ = prims(usd, stage)
    (source,) = usd.UsdSkel.BindingAPI(skeleton.GetPrim()).GetAnimationSourceRel().GetTargets()
    assert source == skeleton.GetPath().AppendChild("clip")
    anim = usd.UsdSkel.Animation(stage.GetPrimAtPath(source))
    names = list(anim.GetBlendShapesAttr().Get())
    assert names == [t for t in targets if t in clip.channels] == list(targets)
    attr = anim.GetBlendShapeWeightsAttr()
    assert attr.GetTimeSamples() == list(range(clip.n_frames))
    for f in range(clip.n_frames):
        expected = clip.values[f, [clip.channels.index(t) for t in names]]
        np.testing.assert_allclose(
            np.array(attr.Get(f)), expected, rtol=F32, atol=1e-12, err_msg=f"frame {f}"
        )
    joints = list(anim.GetJointsAttr().Get())
    assert "head/jaw" in joints and "head" not in joints  # joy opens the jaw; the head stays still
    assert anim.GetRotationsAttr().GetTimeSamples() == list(range(clip.n_frames))
    assert anim.GetTranslationsAttr().GetNumTimeSamples() == 0  # no joint slides
    assert np.all(np.array(anim.GetScalesAttr().Get()) == 1)


def test_export_usd_moving_joints_get_rotation_and_translation_samples(usd, rig, targets, tmp_path):
    clip = moving_clip(rig)
    stage = usd.Usd.Stage.Open(str(export_usd(rig, tmp_path / "m.usdc", morph_targets=targets, clip=clip)))
    anim = usd.UsdSkel.Animation(stage.GetDefaultPrim().GetChild("skeleton").GetChild("clip"))
    joints = list(anim.GetJointsAttr().Get())
    assert {"head", "head/jaw", "head/eye_L", "head/eye_R", "head/eyelid_upper_L"} <= set(joints)
    assert anim.GetTranslationsAttr().GetTimeSamples() == list(range(clip.n_frames))  # jaw_slide
    rotations = anim.GetRotationsAttr().Get(5)
    assert len(rotations) == len(joints)
    jaw = joints.index("head/jaw")
    real, imag = rotations[jaw].GetReal(), rotations[jaw].GetImaginary()
    world = bone_transforms(rig, clip.values[5])
    local = np.linalg.inv(world[rig.bone_index("head")]) @ world[rig.bone_index("jaw")]
    expected = Rotation.from_matrix(local[:3, :3]).as_quat()  # x y z w
    got = np.array([*imag, real])
    np.testing.assert_allclose(got * np.sign(got @ expected), expected, atol=1e-6)


@pytest.mark.parametrize("frame", [0, 6, 12, 19])
def test_export_usd_skinned_pose_matches_gltf_vertices(usd, rig, targets, clip, exported, frame):
    _, stage = exported
    expected = gltf_vertices(rig, targets, frame_pose(clip, frame))
    got = usd_pose(usd, stage, frame)
    assert got.shape == expected.shape == (rig.n_vertices, 3)
    np.testing.assert_allclose(got, expected, rtol=0, atol=POSE_TOL_M)
    if frame == 12:  # joy's peak: the face really moved
        assert np.abs(expected - rig.mesh.vertices * CM).max() > 5e-3


def test_export_usd_every_joint_kind_matches_gltf_vertices_with_bake_skinning(usd, rig, targets, tmp_path):
    clip = moving_clip(rig)
    path = export_usd(rig, tmp_path / "move.usdc", morph_targets=targets, clip=clip)
    frames = [0, 4, 8]
    baked = baked_pose(usd, path, frames)
    stage = usd.Usd.Stage.Open(str(path))
    for f in frames:
        expected = gltf_vertices(rig, targets, frame_pose(clip, f))
        np.testing.assert_allclose(baked[f], expected, rtol=0, atol=POSE_TOL_M, err_msg=f"frame {f}")
        np.testing.assert_allclose(usd_pose(usd, stage, f), expected, rtol=0, atol=POSE_TOL_M)


def test_export_usd_clip_with_some_channels_uses_defaults(usd, rig, targets, tmp_path):
    clip = moving_clip(rig, frames=5).select(["jaw_open", "zygomatic_major_R"])
    path = export_usd(rig, tmp_path / "some.usda", morph_targets=targets, clip=clip, clip_name="talk")
    stage = usd.Usd.Stage.Open(str(path))
    anim = usd.UsdSkel.Animation(stage.GetDefaultPrim().GetChild("skeleton").GetChild("talk"))
    assert list(anim.GetBlendShapesAttr().Get()) == ["zygomatic_major_R"]
    assert list(anim.GetJointsAttr().Get()) == ["head/jaw"]
    assert stage.GetTimeCodesPerSecond() == 30.0 and stage.GetEndTimeCode() == 4
    np.testing.assert_allclose(
        usd_pose(usd, stage, 3), gltf_vertices(rig, targets, frame_pose(clip, 3)), atol=POSE_TOL_M
    )


def test_export_usd_rejects_unknown_clip_channel(usd, rig, targets, tmp_path):
    clip = Clip(("jaw_opne",), np.zeros((3, 1)), 30)
    with pytest.raises(ActivationError, match="'jaw_opne' \\(did you mean 'jaw_open'\\?\\)"):
        export_usd(rig, tmp_path / "x.usda", morph_targets=targets, clip=clip)
    with pytest.raises(ExportError, match=r"must be a mimetic\.rig\.activations\.Clip"):
        export_usd(rig, tmp_path / "x.usda", clip=np.zeros((3, 50)))
    assert not (tmp_path / "x.usda").exists()


def test_export_usd_clip_driving_nothing_writes_no_animation(usd, rig, tmp_path):
    clip = moving_clip(rig, frames=4).select(["zygomatic_major_R"])  # a muscle, but no targets
    with pytest.warns(MimeticWarning, match="drives no blend shape and no joint"):
        path = export_usd(rig, tmp_path / "none.usda", clip=clip)
    stage = usd.Usd.Stage.Open(str(path))
    assert not any(p.GetTypeName() == "SkelAnimation" for p in stage.Traverse())
    assert not stage.HasAuthoredTimeCodeRange()
    assert check_usd(path) == []


# --------------------------------------------------------------------------- frame


def test_export_usd_of_a_z_up_scan_is_a_y_up_stage_with_the_head_upright(usd, rig, targets, tmp_path):
    """A rig fitted to a Z-up scan: the stage says Y up and UsdSkel's own skinning shows the head with
    +Y up and the face looking down +Z (no transform turning it back to Z-up)."""
    turn = Rotation.from_euler("x", -90, degrees=True).as_matrix()  # rig +Y up -> the user's +Z up
    user = rotated(rig, turn)
    clip = moving_clip(rig)
    path = export_usd(user, tmp_path / "z.usdc", morph_targets=targets, clip=clip)
    assert check_usd(path) == []
    stage = usd.Usd.Stage.Open(str(path))
    assert usd.UsdGeom.GetStageUpAxis(stage) == "Y"
    root, _, _ = prims(usd, stage)
    np.testing.assert_array_equal(
        np.array(root.ComputeLocalToWorldTransform(usd.Usd.TimeCode.Default())), np.eye(4)
    )
    shown = usd_pose(usd, stage, 6)
    np.testing.assert_allclose(shown, gltf_vertices(rig, targets, frame_pose(clip, 6)), atol=POSE_TOL_M)
    faces = rig.mesh.faces

    def at(name: str) -> np.ndarray:
        point = rig.landmarks[name]
        return np.asarray(point.bary) @ shown[faces[point.face]]

    up = at("glabella") - at("subnasale")
    assert up[1] > 0.9 * np.linalg.norm(up)  # lying on its back: about 0
    forward = at("nose_tip") - 0.5 * (at("tragion_L") + at("tragion_R"))
    assert forward[2] > 0.9 * np.linalg.norm(forward)


def test_export_usd_writes_no_transform_on_the_skel_root(usd, exported):
    _, stage = exported
    assert stage.GetDefaultPrim().GetAttribute("xformOpOrder").Get() is None


# --------------------------------------------------------------------------- errors and atomic writes


@pytest.mark.parametrize(
    ("targets", "message"),
    [
        (lambda n: {"short": np.zeros((10, 3))}, r"shape \(10, 3\); expected \({n}, 3\)"),
        (lambda n: {"nan": np.full((n, 3), np.nan)}, "non-finite displacement at vertex 0"),
        (lambda n: {"": np.zeros((n, 3))}, "non-empty strings"),
    ],
)
def test_export_usd_rejects_bad_targets_and_keeps_old_file(rig, tmp_path, targets, message):
    path = tmp_path / "keep.usda"
    path.write_bytes(b"good old file")
    n = rig.n_vertices
    with pytest.raises(ExportError, match=message.format(n=n)):
        export_usd(rig, path, morph_targets=targets(n))
    assert path.read_bytes() == b"good old file"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.usda"]


def test_export_usd_failure_while_writing_keeps_old_file(usd, rig, tmp_path, monkeypatch):
    import mimetic.export.usd as usd_module

    path = tmp_path / "keep.usdc"
    export_usd(rig, path)
    good = path.read_bytes()
    path.chmod(0o640)

    def fail(layer, tmp):
        with open(tmp, "wb") as handle:
            handle.write(b"half a fi")
        raise RuntimeError("disk full")

    monkeypatch.setattr(usd_module, "_export_layer", fail)
    with pytest.raises(WriteError, match="disk full"):
        export_usd(rig, path, morph_targets={"x": np.ones((rig.n_vertices, 3))})
    assert path.read_bytes() == good
    assert [p.name for p in tmp_path.iterdir()] == ["keep.usdc"]
    monkeypatch.undo()
    export_usd(rig, path, morph_targets={"x": np.ones((rig.n_vertices, 3))})
    assert path.read_bytes() != good and path.stat().st_mode & 0o777 == 0o640  # permissions kept


def test_export_usd_rejects_bad_paths(usd, rig, tmp_path):
    with pytest.raises(ExportError, match=r"must end in \.usda, \.usdc, \.usd"):
        export_usd(rig, tmp_path / "face.glb")
    with pytest.raises(WriteError, match="does not exist"):
        export_usd(rig, tmp_path / "missing" / "face.usda")
    (tmp_path / "dir.usda").mkdir()
    with pytest.raises(WriteError, match="it is a folder"):
        export_usd(rig, tmp_path / "dir.usda")


def test_export_usd_without_pxr_raises_missing_extra(rig, tmp_path, monkeypatch):
    for name in [m for m in sys.modules if m == "pxr" or m.startswith("pxr.")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "pxr", None)  # makes `import pxr` raise ImportError
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(MissingExtraError, match=r"pip install -e '\.\[usd\]'"):  # a source checkout
            export_usd(rig, tmp_path / "face.usda")
        with pytest.raises(MissingExtraError, match=r"\[usd\]"):
            check_usd(tmp_path / "face.usda")
    assert not (tmp_path / "face.usda").exists()
