"""Tests for mimetic.export.gltf: the .glb read back with pygltflib, field by field.

``file_vertices`` below is an independent glTF client in numpy (node TRS, animation samplers at a
keyframe, morph targets, joint matrices × inverse bind matrices, linear blend skinning); it must
agree with ``gltf_vertices`` (the library's own statement of what a client shows), and that with
the engine within the documented approximation.
"""

from __future__ import annotations

import contextlib
import dataclasses
import warnings

import numpy as np
import pygltflib as gl
import pytest
from scipy.spatial.transform import Rotation

import mimetic.export.gltf as gltf_module
from mimetic.engines import make_engine
from mimetic.engines.bake import bake, random_poses
from mimetic.engines.basis import evaluate_basis
from mimetic.engines.skinning import bone_transforms
from mimetic.errors import ActivationError, MeshError, MimeticWarning
from mimetic.export import (
    ExportError,
    bone_channels,
    export_glb,
    gltf_vertices,
    morph_targets_from_basis,
    read_accessor,
    read_glb_summary,
)
from mimetic.mesh.model import Mesh
from mimetic.rig.activations import Clip
from mimetic.rig.model import thaw_json
from mimetic.testing import small_rig

CM = 0.01  # metres per centimetre: the small rig is in cm
F32 = 2e-7  # relative float32 rounding, with margin
MOVING = {  # channel: (amplitude, angular frequency rad/s) of the test clip
    "jaw_open": (0.3, 3.0),
    "jaw_slide": (0.02, 2.0),
    "gaze_yaw": (0.4, 2.5),
    "head_yaw": (0.5, 1.0),
    "zygomatic_major_L": (1.0, 2.0),
    "orbicularis_oculi_L": (0.8, 4.0),
}


# --------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def rig():
    return small_rig()


@pytest.fixture(scope="module")
def basis(rig):
    return bake(make_engine(rig, "wire"), correctives=0, samples=2).basis


@pytest.fixture(scope="module")
def targets(rig, basis):
    return morph_targets_from_basis(basis, rig)


def make_clip(rig, frames: int = 31, fps: float = 30.0, channels=None) -> Clip:
    """Smooth curves on the MOVING channels (rig channel order), all others at their defaults."""
    t = np.arange(frames) / fps
    values = np.tile([c.default for c in rig.channels], (frames, 1))
    for name, (amplitude, omega) in MOVING.items():
        curve = np.sin(omega * t) ** 2 if rig.channel(name).minimum >= 0 else np.sin(omega * t)
        values[:, rig.channel_index(name)] = amplitude * curve
    clip = Clip(rig.channel_names, values, fps)
    return clip if channels is None else clip.select(channels)


@pytest.fixture(scope="module")
def clip(rig):
    return make_clip(rig)


@pytest.fixture(scope="module")
def exported(tmp_path_factory, rig, targets, clip):
    """The small rig with its basis targets and the test clip, written once; (path, document)."""
    path = tmp_path_factory.mktemp("glb") / "face.glb"
    export_glb(rig, path, morph_targets=targets, clip=clip)
    return path, gl.GLTF2.load(path)


def rotated(rig, rotation: np.ndarray):
    metadata = {**thaw_json(rig.metadata), "source_rotation": np.asarray(rotation).tolist()}
    return dataclasses.replace(rig, metadata=metadata)


# --------------------------------------------------------------------------- a numpy glTF client


def concat(doc: gl.GLTF2, attribute: str, blob=None) -> np.ndarray:
    """An attribute of the first mesh's primitives, concatenated in primitive order."""
    return np.concatenate(
        [read_accessor(doc, getattr(p.attributes, attribute), blob) for p in doc.meshes[0].primitives]
    )


def concat_target(doc: gl.GLTF2, t: int, attribute: str = "POSITION") -> np.ndarray:
    return np.concatenate([read_accessor(doc, p.targets[t][attribute]) for p in doc.meshes[0].primitives])


def trs(translation=None, rotation=None, scale=None) -> np.ndarray:
    m = np.eye(4)
    if rotation is not None:
        m[:3, :3] = Rotation.from_quat(rotation).as_matrix()  # x y z w
    if scale is not None:
        m[:3, :3] *= scale
    if translation is not None:
        m[:3, 3] = translation
    return m


def file_vertices(doc: gl.GLTF2, frame: int | None) -> np.ndarray:
    """World positions (n, 3) of the first mesh at keyframe ``frame`` of animation 0 (None: rest)."""
    local = [dict(translation=n.translation, rotation=n.rotation, scale=n.scale) for n in doc.nodes]
    weights = np.array(doc.meshes[0].weights or [], float)
    if frame is not None:
        anim = doc.animations[0]
        for channel in anim.channels:
            out = read_accessor(doc, anim.samplers[channel.sampler].output)
            if channel.target.path == "weights":
                weights = out.reshape(-1, len(weights))[frame]
            else:
                local[channel.target.node][channel.target.path] = out[frame]
    parent = {c: i for i, n in enumerate(doc.nodes) for c in (n.children or [])}

    def world(i: int) -> np.ndarray:
        m = trs(**local[i])
        return m if i not in parent else world(parent[i]) @ m

    v = concat(doc, "POSITION").astype(np.float64)
    for t, w in enumerate(weights):
        v += w * concat_target(doc, t)
    mesh_node = next(i for i, n in enumerate(doc.nodes) if n.mesh == 0)
    if doc.nodes[mesh_node].skin is None:
        return v @ world(mesh_node)[:3, :3].T + world(mesh_node)[:3, 3]
    skin = doc.skins[doc.nodes[mesh_node].skin]
    ibm = read_accessor(doc, skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)
    joint = np.stack([world(j) @ ibm[k] for k, j in enumerate(skin.joints)])  # (b, 4, 4)
    jw = concat(doc, "JOINTS_0").astype(np.int64)
    ww = concat(doc, "WEIGHTS_0").astype(np.float64)
    m = np.einsum("nk,nkij->nij", ww, joint[jw])  # (n, 4, 4) blended joint matrices
    return np.einsum("nij,nj->ni", m[:, :3, :3], v) + m[:, :3, 3]


# --------------------------------------------------------------------------- mesh


def test_export_glb_positions_keep_rig_vertex_order_in_metres(rig, exported):
    _, doc = exported
    positions = concat(doc, "POSITION")
    assert positions.shape == (rig.n_vertices, 3) and positions.dtype == np.float32
    np.testing.assert_allclose(positions, rig.mesh.vertices * CM, rtol=F32, atol=1e-9)
    normals = concat(doc, "NORMAL")
    np.testing.assert_allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-5)
    assert doc.asset.extras["units"] == "m" and doc.asset.extras["source_units"] == "cm"


def test_export_glb_parts_become_primitives_with_rig_faces(rig, exported):
    _, doc = exported
    prims = doc.meshes[0].primitives
    assert [doc.materials[p.material].name for p in prims] == list(rig.mesh.parts)
    faces = np.concatenate(
        [
            read_accessor(doc, p.indices).reshape(-1, 3).astype(np.int64) + p.extras["vertex_start"]
            for p in prims
        ]
    )
    assert faces.shape == rig.mesh.faces.shape
    np.testing.assert_array_equal(faces, rig.mesh.faces)


def test_export_glb_parts_not_in_blocks_give_one_primitive(rig, tmp_path):
    m = rig.mesh
    interleaved = Mesh(m.vertices, m.faces, {"even": np.arange(0, m.n_faces, 2)}, m.colors, m.units)
    other = dataclasses.replace(rig, mesh=interleaved)
    path = export_glb(other, tmp_path / "one.glb")
    doc = gl.GLTF2.load(path)
    assert len(doc.meshes[0].primitives) == 1
    np.testing.assert_array_equal(
        read_accessor(doc, doc.meshes[0].primitives[0].indices).reshape(-1, 3), m.faces
    )
    np.testing.assert_allclose(concat(doc, "POSITION"), m.vertices * CM, rtol=F32, atol=1e-9)


def test_export_glb_vertex_colors_written_as_color_0(rig, exported):
    _, doc = exported
    assert rig.mesh.colors is not None
    np.testing.assert_array_equal(concat(doc, "COLOR_0"), rig.mesh.colors)


def test_export_glb_units_cm_keeps_rig_coordinates(rig, tmp_path):
    doc = gl.GLTF2.load(export_glb(rig, tmp_path / "cm.glb", units="cm"))
    np.testing.assert_allclose(concat(doc, "POSITION"), rig.mesh.vertices, rtol=F32, atol=1e-7)
    assert doc.asset.extras["units"] == "cm"


# --------------------------------------------------------------------------- morph targets


def test_export_glb_targets_round_trip_with_names_and_zero_weights(rig, tmp_path):
    rng = np.random.default_rng(3)
    n = rig.n_vertices
    sparse = np.zeros((n, 3))
    sparse[rng.choice(n, 40, replace=False)] = rng.normal(size=(40, 3))
    given = {"dense": rng.normal(size=(n, 3)), "sparse": sparse, "zero": np.zeros((n, 3))}
    copies = {k: v.copy() for k, v in given.items()}
    doc = gl.GLTF2.load(export_glb(rig, tmp_path / "t.glb", morph_targets=given))
    mesh = doc.meshes[0]
    assert mesh.extras["targetNames"] == ["dense", "sparse", "zero"]
    assert mesh.weights == [0.0, 0.0, 0.0]
    for t, (name, delta) in enumerate(given.items()):
        back = concat_target(doc, t)
        assert back.shape == (n, 3) and back.dtype == np.float32
        np.testing.assert_allclose(back, delta * CM, rtol=F32, atol=1e-12, err_msg=name)
    skin = mesh.primitives[0]  # the largest part: dense stays dense, the others are sparse
    assert doc.accessors[skin.targets[0]["POSITION"]].sparse is None
    assert doc.accessors[skin.targets[1]["POSITION"]].sparse is not None
    assert doc.accessors[skin.targets[2]["POSITION"]].bufferView is None
    for name, delta in given.items():  # inputs untouched
        np.testing.assert_array_equal(delta, copies[name])


def test_export_glb_target_normals_are_the_change_of_normals(rig, tmp_path):
    from mimetic.mesh.geometry import vertex_normals

    bump = np.zeros((rig.n_vertices, 3))
    bump[:100, 2] = 0.5
    doc = gl.GLTF2.load(export_glb(rig, tmp_path / "n.glb", morph_targets={"bump": bump}))
    expected = vertex_normals(rig.mesh.vertices + bump, rig.mesh.faces) - vertex_normals(
        rig.mesh.vertices, rig.mesh.faces
    )
    np.testing.assert_allclose(concat_target(doc, 0, "NORMAL"), expected, atol=1e-6)
    doc = gl.GLTF2.load(
        export_glb(rig, tmp_path / "nn.glb", morph_targets={"bump": bump}, target_normals=False)
    )
    assert "NORMAL" not in doc.meshes[0].primitives[0].targets[0]


@pytest.mark.parametrize(
    ("targets", "message"),
    [
        (lambda n: {"short": np.zeros((10, 3))}, r"shape \(10, 3\); expected \({n}, 3\)"),
        (lambda n: {"flat": np.zeros(n * 3)}, r"shape \({n3},\)"),
        (lambda n: {"nan": np.full((n, 3), np.nan)}, "non-finite displacement at vertex 0"),
        (lambda n: {"": np.zeros((n, 3))}, "non-empty strings"),
        (lambda n: {"text": "abc"}, "cannot be read as float64"),
    ],
)
def test_export_glb_rejects_bad_targets_and_keeps_old_file(rig, tmp_path, targets, message):
    path = tmp_path / "keep.glb"
    path.write_bytes(b"good old file")
    n = rig.n_vertices
    with pytest.raises(ExportError, match=message.format(n=n, n3=3 * n)):
        export_glb(rig, path, morph_targets=targets(n))
    assert path.read_bytes() == b"good old file"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.glb"]


def test_export_glb_failure_while_writing_keeps_old_file(rig, tmp_path, monkeypatch):
    path = tmp_path / "keep.glb"
    export_glb(rig, path)
    good = path.read_bytes()

    real = gltf_module.atomic_write

    class Full:  # the disk fills up after the header and the JSON: the binary chunk fails
        def __init__(self, handle):
            self.handle, self.writes = handle, 0

        def write(self, data):
            self.writes += 1
            if self.writes > 4:
                raise OSError("disk full")
            return self.handle.write(data)

    @contextlib.contextmanager
    def filling(path, mode="wb"):
        with real(path, mode) as handle:
            yield Full(handle)

    monkeypatch.setattr(gltf_module, "atomic_write", filling)
    with pytest.raises(OSError, match="disk full"):
        export_glb(rig, path, morph_targets={"x": np.ones((rig.n_vertices, 3))})
    assert path.read_bytes() == good
    assert [p.name for p in tmp_path.iterdir()] == ["keep.glb"]


def test_morph_targets_from_basis_one_per_muscle_channel(rig, basis, targets):
    muscles = [c.name for c in rig.channels if c.unit == "activation"]
    assert list(targets) == muscles
    assert not set(targets) & {"jaw_open", "gaze_yaw", "eyelid_upper_L", "head_yaw"}
    for delta in targets.values():
        assert delta.shape == (rig.n_vertices, 3) and delta.dtype == np.float64
    # muscles that move no bone keep their delta exactly
    k = basis.channels.index("zygomatic_major_L")
    np.testing.assert_array_equal(targets["zygomatic_major_L"], basis.deltas[k])
    assert "orbicularis_oculi_L" in bone_channels(rig)
    k = basis.channels.index("orbicularis_oculi_L")
    assert not np.allclose(targets["orbicularis_oculi_L"], basis.deltas[k])


def test_morph_targets_from_basis_rejects_other_rig(rig, basis):
    from mimetic.engines.basis import Basis

    small = Basis(basis.channels, basis.neutral[:10], basis.deltas[:, :10])
    with pytest.raises(ExportError, match=f"10 vertices but the rig has {rig.n_vertices}"):
        morph_targets_from_basis(small, rig)


@pytest.mark.parametrize("name", ["zygomatic_major_L", "orbicularis_oculi_L", "levator_palpebrae_R"])
def test_gltf_vertices_single_muscle_gives_baked_shape(rig, basis, targets, name):
    pose = np.zeros(basis.n_channels)
    pose[basis.channels.index(name)] = 1.0
    got = gltf_vertices(rig, targets, {name: 1.0}, units="cm")
    np.testing.assert_allclose(got, evaluate_basis(basis, pose), rtol=0, atol=1e-9 * rig.scale)


def test_gltf_vertices_close_to_engine_on_random_poses(rig, targets):
    engine = make_engine(rig, "wire")
    poses = random_poses(engine, 12, np.random.default_rng(1))
    errors = []
    for pose in poses:
        got = gltf_vertices(rig, targets, dict(zip(rig.channel_names, pose, strict=True)), units="cm")
        errors.append(np.linalg.norm(got - engine.deform(pose), axis=1))
    errors = np.concatenate(errors) / rig.scale
    # measured: rms 0.10 %, max 2.5 % of the head height (the lid sculptor and lip contact)
    assert np.sqrt(np.mean(errors**2)) < 0.003
    assert errors.max() < 0.05


# --------------------------------------------------------------------------- skeleton


def test_export_glb_skin_weights_match_rig(rig, exported):
    _, doc = exported
    joints = concat(doc, "JOINTS_0").astype(np.int64)
    weights = concat(doc, "WEIGHTS_0")
    assert joints.shape == weights.shape == (rig.n_vertices, 4) and weights.dtype == np.float32
    np.testing.assert_allclose(weights.sum(axis=1, dtype=np.float32), 1.0, rtol=0, atol=2e-7)
    dense = np.zeros((rig.n_vertices, rig.n_bones))
    np.add.at(dense, (np.repeat(np.arange(rig.n_vertices), 4), joints.ravel()), weights.ravel())
    np.testing.assert_allclose(dense, rig.skin_weights.toarray(), atol=2e-7)
    skin = doc.skins[0]
    assert [doc.nodes[j].name for j in skin.joints] == list(rig.bone_names)


def test_export_glb_inverse_bind_matrices_invert_joint_bind_transforms(rig, exported):
    _, doc = exported
    skin = doc.skins[0]
    ibm = read_accessor(doc, skin.inverseBindMatrices).reshape(-1, 4, 4).transpose(0, 2, 1)  # column-major
    parent = {c: i for i, n in enumerate(doc.nodes) for c in (n.children or [])}

    def world(i):
        m = trs(doc.nodes[i].translation, doc.nodes[i].rotation, doc.nodes[i].scale)
        return m if i not in parent else world(parent[i]) @ m

    for k, j in enumerate(skin.joints):
        np.testing.assert_allclose(world(j) @ ibm[k], np.eye(4), atol=1e-7)
        np.testing.assert_allclose(world(j)[:3, 3], rig.bones[k].head * CM, rtol=F32, atol=1e-8)
    np.testing.assert_allclose(file_vertices(doc, None), rig.mesh.vertices * CM, rtol=1e-6, atol=1e-8)


# --------------------------------------------------------------------------- animation


def test_export_glb_animation_times_and_weights_match_clip(rig, targets, clip, exported):
    _, doc = exported
    (anim,) = doc.animations
    assert anim.name == "clip"
    names = list(targets)
    weights = [c for c in anim.channels if c.target.path == "weights"]
    assert len(weights) == 1 and weights[0].target.node == 0
    sampler = anim.samplers[weights[0].sampler]
    assert sampler.interpolation == "LINEAR"
    times = read_accessor(doc, sampler.input)
    np.testing.assert_allclose(times, np.arange(clip.n_frames) / clip.fps, rtol=F32)
    w = read_accessor(doc, sampler.output).reshape(clip.n_frames, len(names))
    for t, name in enumerate(names):
        expected = clip.values[:, clip.channels.index(name)]
        np.testing.assert_allclose(w[:, t], expected, rtol=F32, atol=1e-12, err_msg=name)
    assert np.count_nonzero(np.abs(w).max(axis=0)) == 2  # zygomatic_major_L, orbicularis_oculi_L


def expected_tracks(rig, clip) -> set[tuple[str, str]]:
    """(joint, path) of every joint whose rotation or position relative to its parent changes."""
    world = np.stack([bone_transforms(rig, v) for v in clip.select(rig.channel_names).values])  # (f, b, 4, 4)

    def at_head(k):  # (f, 3) where bone k's head is, and (f, 3, 3) its rotation
        return world[:, k, :3, :3] @ rig.bones[k].head + world[:, k, :3, 3], world[:, k, :3, :3]

    out = set()
    for k, bone in enumerate(rig.bones):
        position, rotation = at_head(k)
        rest = bone.head
        if bone.parent is not None:
            p = rig.bone_index(bone.parent)
            parent_position, parent_rotation = at_head(p)
            inverse = parent_rotation.transpose(0, 2, 1)
            position = np.einsum("fij,fj->fi", inverse, position - parent_position)
            rotation = inverse @ rotation
            rest = bone.head - rig.bones[p].head
        if not np.allclose(rotation, np.eye(3), atol=1e-12):
            out.add((bone.name, "rotation"))
        if np.abs(position - rest).max() > 1e-9 * rig.scale:
            out.add((bone.name, "translation"))
    return out


def test_export_glb_joint_tracks_follow_bone_transforms(rig, clip, exported):
    _, doc = exported
    (anim,) = doc.animations
    tracks = {(doc.nodes[c.target.node].name, c.target.path): c.sampler for c in anim.channels}
    expected = expected_tracks(rig, clip)
    # at least jaw_open and jaw_slide, gaze, head, and the orbicularis closing the upper left lid
    assert {("head", "rotation"), ("jaw", "rotation"), ("jaw", "translation")} <= expected
    assert {("eye_L", "rotation"), ("eye_R", "rotation"), ("eyelid_upper_L", "rotation")} <= expected
    assert set(tracks) == {("face_mesh", "weights"), *expected}
    q = read_accessor(doc, anim.samplers[tracks["jaw", "rotation"]].output)
    assert q.shape == (clip.n_frames, 4)
    np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-6)
    assert np.all(np.einsum("fi,fi->f", q[1:], q[:-1]) > 0)  # no hemisphere flips
    for f in (0, 7, 20):
        world = bone_transforms(rig, clip.values[f])
        head = rig.bone_index("head")
        local = np.linalg.inv(world[head]) @ world[rig.bone_index("jaw")]  # rest-relative, about the jaw head
        np.testing.assert_allclose(Rotation.from_quat(q[f]).as_matrix(), local[:3, :3], atol=1e-6)


@pytest.mark.parametrize("frame", [0, 9, 17, 30])
def test_export_glb_file_pose_matches_gltf_vertices(rig, targets, clip, exported, frame):
    _, doc = exported
    expected = gltf_vertices(rig, targets, dict(zip(clip.channels, clip.values[frame], strict=True)))
    np.testing.assert_allclose(file_vertices(doc, frame), expected, rtol=0, atol=2e-6 * rig.scale * CM)


def test_export_glb_clip_with_some_channels_uses_defaults(rig, targets, tmp_path):
    clip = make_clip(rig, frames=5, channels=["jaw_open", "zygomatic_major_L"])
    doc = gl.GLTF2.load(
        export_glb(rig, tmp_path / "c.glb", morph_targets=targets, clip=clip, clip_name="talk")
    )
    summary = read_glb_summary(tmp_path / "c.glb")
    assert summary["animations"] == [
        {
            "name": "talk",
            "channels": 2,
            "weights_channels": 1,
            "rotation_channels": 1,
            "translation_channels": 0,
            "frames": 5,
            "duration_s": pytest.approx(4 / 30, rel=1e-6),
        }
    ]
    expected = gltf_vertices(rig, targets, dict(zip(clip.channels, clip.values[3], strict=True)))
    np.testing.assert_allclose(file_vertices(doc, 3), expected, atol=2e-6 * rig.scale * CM)


def test_export_glb_rejects_unknown_clip_channel(rig, targets, tmp_path):
    clip = Clip(("jaw_opne",), np.zeros((3, 1)), 30)
    with pytest.raises(ActivationError, match="'jaw_opne' \\(did you mean 'jaw_open'\\?\\)"):
        export_glb(rig, tmp_path / "x.glb", morph_targets=targets, clip=clip)
    with pytest.raises(ExportError, match=r"must be a mimetic\.rig\.activations\.Clip"):
        export_glb(rig, tmp_path / "x.glb", clip=np.zeros((3, 50)))
    assert not (tmp_path / "x.glb").exists()


def test_export_glb_without_skin_has_no_joints_and_warns_for_bone_channels(rig, targets, clip, tmp_path):
    with pytest.warns(MimeticWarning, match="move bones, but skin=False"):
        path = export_glb(rig, tmp_path / "noskin.glb", morph_targets=targets, clip=clip, skin=False)
    doc = gl.GLTF2.load(path)
    assert doc.skins == [] and doc.meshes[0].primitives[0].attributes.JOINTS_0 is None
    summary = read_glb_summary(path)
    assert summary["joint_names"] == [] and summary["animations"][0]["channels"] == 1
    pose = dict(zip(clip.channels, clip.values[9], strict=True))
    np.testing.assert_allclose(
        file_vertices(doc, 9), gltf_vertices(rig, targets, pose, skin=False), atol=1e-7
    )


def test_export_glb_clip_driving_nothing_writes_no_animation(rig, tmp_path):
    clip = make_clip(rig, frames=4, channels=["zygomatic_major_L"])
    with pytest.warns(MimeticWarning, match="drives no morph target and no joint"):
        path = export_glb(rig, tmp_path / "none.glb", clip=clip)
    assert read_glb_summary(path)["animations"] == []


# --------------------------------------------------------------------------- frame, names, summary


def _landmark(rig, vertices: np.ndarray, name: str) -> np.ndarray:
    """The position (3,) of a rig landmark on ``vertices`` (n, 3) in rig order."""
    point = rig.landmarks[name]
    return np.asarray(point.bary) @ vertices[rig.mesh.faces[point.face]]


def test_export_glb_of_a_z_up_scan_stands_upright_as_clients_skin_it(rig, targets, clip, tmp_path):
    """A rig fitted to a Z-up scan (Blender's convention, face toward -Y) is written in glTF's own
    frame: the skinned head (joint world matrices x inverse bind matrices) has +Y up and faces +Z."""
    turn = Rotation.from_euler("x", -90, degrees=True).as_matrix()  # rig +Y up -> the user's +Z up
    user = rotated(rig, turn)
    doc = gl.GLTF2.load(export_glb(user, tmp_path / "z.glb", morph_targets=targets, clip=clip))
    plain = gl.GLTF2.load(export_glb(rig, tmp_path / "y.glb", morph_targets=targets, clip=clip))
    assert all(node.rotation is None and node.matrix is None for node in doc.nodes[:2])
    for frame in (None, 12):
        shown = file_vertices(doc, frame)
        np.testing.assert_array_equal(shown, file_vertices(plain, frame))
        up = _landmark(rig, shown, "glabella") - _landmark(rig, shown, "subnasale")
        assert up[1] > 0.9 * np.linalg.norm(up)  # nose below brow along +Y (lying down: about 0)
        forward = _landmark(rig, shown, "nose_tip") - 0.5 * (
            _landmark(rig, shown, "tragion_L") + _landmark(rig, shown, "tragion_R")
        )
        assert forward[2] > 0.9 * np.linalg.norm(forward)  # the face looks down +Z
    pose = dict(zip(clip.channels, clip.values[12], strict=True))
    np.testing.assert_array_equal(gltf_vertices(user, targets, pose), gltf_vertices(rig, targets, pose))


def test_export_glb_root_named_like_a_bone_gets_suffix(rig, tmp_path):
    doc = gl.GLTF2.load(export_glb(rig, tmp_path / "head.glb"))
    names = [n.name for n in doc.nodes]
    assert names.count("head") == 1 and "head_root" in names and "head_root_mesh" in names


def test_read_glb_summary_reports_what_was_written(rig, targets, clip, exported):
    path, _ = exported
    summary = read_glb_summary(path)
    assert summary["vertices"] == rig.n_vertices and summary["faces"] == rig.mesh.n_faces
    assert summary["primitives"] == list(rig.mesh.parts)
    assert summary["target_names"] == list(targets)
    assert summary["joint_names"] == list(rig.bone_names)
    assert summary["units"] == "m" and summary["root_rotation"] is None
    (anim,) = summary["animations"]
    assert anim["frames"] == clip.n_frames
    assert anim["duration_s"] == pytest.approx((clip.n_frames - 1) / clip.fps, rel=1e-6)
    paths = [path for _, path in expected_tracks(rig, clip)]
    assert anim["weights_channels"] == 1
    assert (anim["rotation_channels"], anim["translation_channels"]) == (
        paths.count("rotation"),
        paths.count("translation"),
    )
    assert summary["bytes"] == path.stat().st_size


def test_read_glb_summary_rejects_non_glb(tmp_path):
    path = tmp_path / "bad.glb"
    path.write_bytes(b"not a glb at all")
    with pytest.raises(MeshError, match="not a readable GLB"):
        read_glb_summary(path)
    with pytest.raises(MeshError, match="cannot read"):
        read_glb_summary(tmp_path / "missing.glb")


def test_export_glb_without_targets_or_clip_is_a_plain_skinned_mesh(rig, tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        path = export_glb(rig, tmp_path / "plain.glb")
    summary = read_glb_summary(path)
    assert summary["target_names"] == [] and summary["animations"] == []
    doc = gl.GLTF2.load(path)
    assert doc.meshes[0].primitives[0].targets in (None, [])
