"""The viewer's state without a browser: layered sliders → pose, symmetry, keys, engines, picking."""

from __future__ import annotations

import numpy as np
import pytest

from mimetic.animate.arkit import arkit_pose
from mimetic.animate.clipfiles import load_clip
from mimetic.animate.controls import apply_descriptive
from mimetic.animate.expressions import expression_pose
from mimetic.animate.facs import facs_pose
from mimetic.animate.keyframes import from_poses
from mimetic.engines import make_engine
from mimetic.engines.bake import bake, evaluate_rigid
from mimetic.rig.activations import pose as rig_pose
from mimetic.view import session as session_module
from mimetic.view.session import (
    PICK_LANDMARKS,
    Deformers,
    Picks,
    Session,
    Timeline,
    arkit_keys,
    facs_keys,
    mirror_name,
    pick,
)


@pytest.fixture
def session(rig) -> Session:
    return Session(rig)


def test_mirror_name_pairs_sides_and_leaves_the_midline():
    assert mirror_name("zygomatic_major_L") == "zygomatic_major_R"
    assert mirror_name("AU12_R") == "AU12_L"
    assert mirror_name("mouthSmileLeft") == "mouthSmileRight"
    assert mirror_name("jaw_open") is None
    assert mirror_name("jawOpen") is None


def test_rest_session_shows_the_channel_defaults(session, rig):
    np.testing.assert_array_equal(session.pose(), rig_pose(rig))


def test_expression_layer_scales_the_library_pose_by_intensity(session, rig):
    session.set_expression("joy", 0.5)
    rest = rig_pose(rig)
    expected = rest + 0.5 * (expression_pose(rig, "joy") - rest)
    np.testing.assert_allclose(session.pose(), expected, atol=1e-12)
    with pytest.raises(KeyError, match="unknown expression"):
        session.set_expression("glee")


def test_channel_sliders_add_to_the_layers(session, rig):
    session.set_expression("joy", 1.0)
    jaw = session.index["jaw_open"]
    before = session.pose()[jaw]
    session.set_channel("jaw_open", 0.1)
    assert session.pose()[jaw] == pytest.approx(min(before + 0.1, rig.channel("jaw_open").maximum))


@pytest.mark.parametrize(
    ("layer", "key", "reference"),
    [
        ("facs", "AU12_L", lambda rig: facs_pose(rig, {"AU12_L": 0.6})),
        ("arkit", "mouthSmileLeft", lambda rig: arkit_pose(rig, {"mouthSmileLeft": 0.6})),
        (
            "descriptive",
            "zygomatic_major_R",
            lambda rig: rig_pose(rig, apply_descriptive(rig, {"Smile/Wide": (0.6, 0.0)}), clip=True),
        ),
    ],
)
def test_each_table_layer_matches_its_own_pose_function(session, rig, layer, key, reference):
    session.set_layer(layer, key, 0.6)
    np.testing.assert_allclose(session.pose(), reference(rig), atol=1e-12)


@pytest.mark.parametrize(
    ("layer", "key", "other"),
    [
        ("channels", "zygomatic_major_L", "zygomatic_major_R"),
        ("facs", "AU12_L", "AU12_R"),
        ("arkit", "mouthSmileLeft", "mouthSmileRight"),
        ("descriptive", "zygomatic_major_R", "zygomatic_major_L"),
    ],
)
def test_symmetry_lock_moves_the_other_side_only_when_on(session, layer, key, other):
    def move(value: float) -> list[str]:
        if layer == "channels":
            return session.set_channel(key, value)
        return session.set_layer(layer, key, value)

    assert move(0.4) == [key]
    left_only = session.pose()
    session.symmetric = True
    assert move(0.7) == [key, other]
    both = session.pose()
    assert not np.allclose(both, left_only)
    mirrored = (both[session.index["zygomatic_major_L"]], both[session.index["zygomatic_major_R"]])
    assert mirrored[0] == pytest.approx(mirrored[1])


def test_midline_controls_have_no_mirror_to_move(session):
    session.symmetric = True
    assert session.set_channel("jaw_open", 0.2) == ["jaw_open"]
    assert session.set_layer("facs", "AU26", 0.5) == ["AU26"]


def test_pose_is_clipped_to_the_channel_ranges(session, rig):
    session.set_channel("jaw_open", 0.4)
    session.set_layer("facs", "AU26", 1.0)
    session.set_layer("facs", "AU27", 1.0)
    assert session.pose()[session.index["jaw_open"]] == rig.channel("jaw_open").maximum
    assert np.all(session.pose() <= session.upper) and np.all(session.pose() >= session.lower)


def test_show_makes_a_pose_the_channel_sliders_and_clears_the_layers(session, rig):
    target = expression_pose(rig, "surprise")
    session.set_layer("arkit", "jawOpen", 1.0)
    session.show(target)
    assert session.arkit == {} and session.expression is None
    np.testing.assert_allclose(session.pose(), target)


def test_slider_tables_list_only_supported_entries():
    assert "AU12_L" in facs_keys() and "AU12_R" in facs_keys() and "AU12" not in facs_keys()
    assert "AU17" in facs_keys()  # a midline unit has one slider
    assert len(arkit_keys()) >= 50 and "jawOpen" in arkit_keys()


# ---- timeline


def test_keys_make_a_clip_that_passes_through_them(session, rig):
    timeline = Timeline(session)
    assert timeline.clip() is None and timeline.pose_at(0.3) is None
    rest, joy = rig_pose(rig), expression_pose(rig, "joy")
    timeline.set_key(0.0, rest)
    timeline.set_key(1.0, joy)
    np.testing.assert_allclose(timeline.pose_at(0.0), rest, atol=1e-12)
    np.testing.assert_allclose(timeline.pose_at(1.0), joy, atol=1e-12)
    smile = session.index["zygomatic_major_L"]
    assert rest[smile] < timeline.pose_at(0.5)[smile] < joy[smile]
    np.testing.assert_allclose(timeline.pose_at(5.0), joy, atol=1e-12)  # held after the end
    assert timeline.delete_key(1.0 + 0.01) and not timeline.delete_key(0.5)
    assert sorted(timeline.keys) == [0.0]


def test_clip_json_reads_back_as_the_same_clip(session, rig, tmp_path):
    timeline = Timeline(session)
    with pytest.raises(ValueError, match="set a key"):
        timeline.clip_json()
    timeline.set_key(0.0, rig_pose(rig))
    timeline.set_key(0.75, expression_pose(rig, "anger"))
    path = tmp_path / "clip.json"
    path.write_bytes(timeline.clip_json())
    times = np.linspace(0, 0.75, 7)
    np.testing.assert_allclose(load_clip(path).evaluate(times), timeline.clip().evaluate(times), atol=1e-9)


def test_a_key_on_a_loaded_clip_reshapes_it_locally(session, rig):
    timeline = Timeline(session)
    rest = rig_pose(rig)
    clip = from_poses([(0.0, rest), (2.0, rest), (4.0, rest)], rig)
    timeline.load(clip)
    wanted = rest.copy()
    wanted[session.index["jaw_open"]] = 0.3
    timeline.set_key(2.0, wanted)
    assert timeline.pose_at(2.0)[session.index["jaw_open"]] == pytest.approx(0.3, abs=1e-6)
    np.testing.assert_allclose(timeline.pose_at(0.0), rest, atol=1e-9)  # beyond the edit's reach
    assert [layer.name for layer in timeline.clip().layers] == ["base", "edit"]


def test_loading_a_clip_for_other_channels_is_refused(session):
    foreign = from_poses([(0.0, {"wiggle": 0.0}), (1.0, {"wiggle": 1.0})], ["wiggle"])
    with pytest.raises(KeyError, match="wiggle"):
        Timeline(session).load(foreign)


# ---- engines


def test_direct_engines_pose_like_the_engine(rig):
    pose = expression_pose(rig, "joy")
    deformers = Deformers(rig)
    got = deformers.vertices("wire", pose)
    assert got.dtype == np.float32
    np.testing.assert_allclose(got, make_engine(rig, "wire").deform(pose), atol=1e-4)
    with pytest.raises(KeyError, match="unknown engine"):
        deformers.prepare("clay")


def test_baked_engines_pose_by_their_basis_with_the_head_turn(rig, monkeypatch):
    monkeypatch.setattr(session_module, "BAKED_ENGINES", frozenset({"vector"}))
    pose = expression_pose(rig, "surprise")
    pose[rig.channel_index("head_yaw")] = 0.4
    deformers = Deformers(rig, ("vector",))
    basis = bake(make_engine(rig, "vector")).basis
    np.testing.assert_allclose(
        deformers.vertices("vector", pose), evaluate_rigid(rig, basis, pose), atol=1e-4 * rig.scale
    )
    moved = np.linalg.norm(deformers.vertices("vector", pose) - rig.mesh.vertices, axis=1).max()
    assert moved > 0.05 * rig.scale  # the head turned


# ---- picking


def test_pick_finds_the_nearest_triangle_and_its_barycentric_point(unit_square):
    v, f = unit_square.vertices, unit_square.faces
    two_layers = np.vstack([v, v - [0, 0, 1.0]])
    faces = np.vstack([f, f + len(v)])
    hit = pick(two_layers, faces, np.array([0.25, 0.6, 5.0]), np.array([0.0, 0.0, -2.0]))
    assert hit is not None
    face, bary, distance = hit
    assert face < len(f)  # the front layer, not the one behind it
    np.testing.assert_allclose(bary @ two_layers[faces[face]], [0.25, 0.6, 0.0], atol=1e-12)
    assert distance == pytest.approx(5.0)
    assert pick(two_layers, faces, np.array([2.0, 2.0, 5.0]), np.array([0.0, 0.0, -1.0])) is None
    assert pick(two_layers, faces, np.array([0.5, 0.5, 5.0]), np.array([0.0, 0.0, 1.0])) is None


def test_picks_follow_the_mesh_and_ask_for_the_next_landmark(rig):
    picks = Picks(rig.mesh.faces)
    assert picks.next_name() == PICK_LANDMARKS[0]
    picks.add(PICK_LANDMARKS[0], 10, np.array([0.2, 0.3, 0.5]))
    assert picks.next_name() == PICK_LANDMARKS[1]
    shift = np.array([1.0, 2.0, 3.0])
    at_rest = picks.positions(rig.mesh.vertices)[PICK_LANDMARKS[0]]
    np.testing.assert_allclose(picks.positions(rig.mesh.vertices + shift)[PICK_LANDMARKS[0]], at_rest + shift)
    picks.remove(PICK_LANDMARKS[0])
    assert picks.points == {}
