"""Tests for mimetic.rig.anatomy.local: feature-local actions move their feature, the right way, and
nothing far from it, on the default head and on random heads (``case``, from conftest)."""

from __future__ import annotations

import numpy as np
import pytest

from mimetic.engines import make_engine
from mimetic.rig.activations import pose
from mimetic.rig.anatomy.local import CHANNELS, LOCAL_BUMPS, local_weights
from mimetic.testing import small_head, small_rig


def _at(rig, vertices, name: str) -> np.ndarray:
    return rig.landmarks[name].position(vertices, rig.mesh.faces)


def _moved(rig, rest, d, name: str) -> np.ndarray:
    """Motion (3,) of landmark ``name`` under the displacement ``d`` (n, 3)."""
    return _at(rig, rest + d, name) - _at(rig, rest, name)


def _widths(rig, rest) -> tuple[float, float]:
    nose = np.linalg.norm(_at(rig, rest, "alare_L") - _at(rig, rest, "alare_R"))
    eye = np.linalg.norm(_at(rig, rest, "eye_outer_corner_L") - _at(rig, rest, "eye_inner_corner_L"))
    return float(nose), float(eye)


def _share_within(rest, d, centre, radius) -> float:
    """Share of the summed displacement length of ``d`` (n, 3) within ``radius`` of ``centre``."""
    size = np.linalg.norm(d, axis=1)
    near = np.linalg.norm(rest - centre, axis=1) < radius
    return float(size[near].sum() / size.sum())


def test_local_channels_are_channels_of_the_recipe_and_drive_one_action_per_side():
    rig = small_rig()
    assert set(CHANNELS) <= set(rig.channel_names)
    assert all(rig.channel(c).minimum == 0.0 and rig.channel(c).maximum == 1.0 for c in CHANNELS)
    names = [a.name for a in rig.anatomy.actions]
    for bump in LOCAL_BUMPS:
        expected = [bump.name + s for s in ("_L", "_R")] if bump.sided else [bump.name]
        assert all(names.count(n) == 1 for n in expected), bump.name


def test_depressor_supercilii_lowers_the_brows_head_not_its_tail_nor_the_lid(case):
    rig, rest, motion = case
    _, eye = _widths(rig, rest)
    for side, inward in (("L", -1.0), ("R", 1.0)):
        d = motion({f"depressor_supercilii_{side}": 1.0})
        head = _moved(rig, rest, d, f"brow_inner_{side}")
        assert head.shape == (3,) and head.dtype == np.float64
        assert head[1] < -0.08 * eye  # down by 2 mm or more on a 2.6 cm eye
        assert head[0] * inward > 0.01 * eye  # and toward the midline
        for still in (
            f"brow_outer_{side}",
            f"eye_upper_lid_inner_{side}",
            f"eye_upper_lid_{side}",
            "glabella",
        ):
            assert np.linalg.norm(_moved(rig, rest, d, still)) < 0.1 * np.linalg.norm(head), still
        lid = rig.regions[f"eyelid_upper_{side}"]
        assert np.linalg.norm(d[lid], axis=1).max() < 0.25 * np.linalg.norm(head)
        assert _share_within(rest, d, _at(rig, rest, f"brow_inner_{side}"), eye) > 0.97


def test_depressor_septi_lowers_the_tip_and_shortens_the_upper_lip(case):
    rig, rest, motion = case
    nose, _ = _widths(rig, rest)
    d = motion({"depressor_septi": 1.0})
    tip, sub, lip = (_moved(rig, rest, d, n) for n in ("nose_tip", "subnasale", "upper_lip_top"))
    assert tip[1] < -0.025 * nose and sub[1] < -0.025 * nose
    assert abs(tip[0]) < 1e-9  # on the midline
    assert np.linalg.norm(lip) < 0.1 * np.linalg.norm(sub)  # the lip's red stays: the lip above it shortens
    for wing in ("alare_L", "alare_R"):
        assert np.linalg.norm(_moved(rig, rest, d, wing)) < 0.1 * np.linalg.norm(tip)
    centre = (_at(rig, rest, "nose_tip") + _at(rig, rest, "subnasale")) / 2
    assert _share_within(rest, d, centre, nose) > 0.97


@pytest.mark.parametrize(
    "channel, direction",
    [("dilator_naris", np.array([1.0, 0.0, 0.0])), ("nasalis_alar", np.array([0.0, -1.0, 0.0]))],
    ids=["flares out", "lowers"],
)
def test_wing_actions_move_the_whole_wing(case, channel, direction):
    """The wing's outermost point, its base and its nostril rim all move, alike in direction."""
    rig, rest, motion = case
    nose, _ = _widths(rig, rest)
    for side, sx in (("L", 1.0), ("R", -1.0)):
        d = motion({f"{channel}_{side}": 1.0})
        toward = direction * np.array([sx, 1.0, 1.0])
        along = {n: _moved(rig, rest, d, f"{n}_{side}") @ toward for n in ("alare", "alar_base")}
        assert min(along.values()) > 0.015 * nose, along  # ~0.5 mm or more on a 3.6 cm nose
        assert np.linalg.norm(_moved(rig, rest, d, "nose_tip")) < 0.1 * max(along.values())
        assert np.linalg.norm(_moved(rig, rest, d, f"alare_{'R' if side == 'L' else 'L'}")) == 0.0
        wing = (_at(rig, rest, f"alare_{side}") + _at(rig, rest, f"nostril_{side}")) / 2
        assert _share_within(rest, d, wing, nose) > 0.97


def test_nasalis_transverse_narrows_the_side_of_the_nose_not_its_dorsum(case):
    rig, rest, motion = case
    nose, _ = _widths(rig, rest)
    for side, sx in (("L", 1.0), ("R", -1.0)):
        d = motion({f"nasalis_transverse_{side}": 1.0})
        side_point = (_at(rig, rest, "nose_bridge_lower") + _at(rig, rest, f"alare_{side}")) / 2
        nearest = int(np.argmin(np.linalg.norm(rest[: len(d)] - side_point, axis=1)))
        assert d[nearest, 0] * sx < -0.02 * nose  # toward the midline
        dorsum = _moved(rig, rest, d, "nose_bridge_lower")
        assert abs(dorsum[0]) < 0.1 * abs(d[nearest, 0])
        assert _share_within(rest, d, side_point, nose) > 0.97


def test_local_actions_mirror_each_other_through_the_engine():
    rig, head = small_rig(), small_head()
    engine = make_engine(rig, "wire")
    rest = engine.deform(pose(rig))
    flip = np.array([-1.0, 1.0, 1.0])
    for stem in ("depressor_supercilii", "nasalis_alar", "nasalis_transverse", "dilator_naris"):
        left = engine.deform(pose(rig, {f"{stem}_L": 1.0})) - rest
        right = engine.deform(pose(rig, {f"{stem}_R": 1.0})) - rest
        assert np.abs(left).max() > 0.05  # 0.5 mm
        np.testing.assert_allclose(left[head.mirror] * flip, right, atol=1e-9)
    septi = engine.deform(pose(rig, {"depressor_septi": 1.0})) - rest
    np.testing.assert_allclose(septi[head.mirror] * flip, septi, atol=1e-9)


@pytest.mark.parametrize(
    "agonist, antagonist, landmark",
    [
        ("frontalis_inner_L", "depressor_supercilii_L", "brow_inner_L"),
        ("levator_labii_nasal_L", "depressor_septi", "nose_tip"),
        ("levator_labii_nasal_L", "nasalis_alar_L", "alare_L"),
        ("dilator_naris_L", "nasalis_transverse_L", "alar_base_L"),
    ],
)
def test_antagonists_oppose_each_other_by_adding_their_motions(case, agonist, antagonist, landmark):
    """Both at once move the face by the sum of their motions (within 5 % of the stronger: the skull
    push and the lid contact are the chain's only non-linear stages), and at the feature they fight
    over the two cancel in part: less motion there than the stronger alone."""
    rig, rest, motion = case
    a, b, both = motion({agonist: 1.0}), motion({antagonist: 1.0}), motion({agonist: 1.0, antagonist: 1.0})
    stronger = max(np.linalg.norm(a, axis=1).max(), np.linalg.norm(b, axis=1).max())
    assert np.linalg.norm(both - (a + b), axis=1).max() < 0.05 * stronger
    pa, pb, pab = (_moved(rig, rest, x, landmark) for x in (a, b, both))
    if landmark != "alar_base_L":  # the vertical pairs
        assert pa[1] > 0 > pb[1]
        assert abs(pab[1]) < max(abs(pa[1]), abs(pb[1]))


def test_feature_widths_scale_the_footprint_not_the_head_height():
    """Doubling a width of the weights' reach doubles the footprint: a wider nose's wing moves more skin."""
    points = np.array([[0.5, 0.0, 0.0], [1.5, 0.0, 0.0], [-0.5, 0.0, 0.0]])
    narrow = local_weights(points, np.zeros(3), np.ones(3), np.ones(3), 1.0)
    wide = local_weights(points, np.zeros(3), 2 * np.ones(3), 2 * np.ones(3), 1.0)
    assert narrow.shape == (3,) and narrow[1] == 0.0 < wide[1]
    assert narrow[0] == narrow[2]  # symmetric reaches
    one_sided = local_weights(points, np.zeros(3), np.full(3, 0.5), np.ones(3), 1.0)
    assert one_sided[2] == 0.0 < one_sided[0]  # the short reach on the −x side ends at 0.5
    left, right = (
        local_weights(points * [s, 1, 1], np.zeros(3), np.full(3, 0.5), np.ones(3), s) for s in (1, -1)
    )
    np.testing.assert_array_equal(left, right)  # x is toward the bump's own side on either
    cored = local_weights(points, np.zeros(3), np.ones(3), np.ones(3), 1.0, core=0.6)
    assert cored[0] == 1.0 and narrow[0] < 1.0


@pytest.mark.parametrize("engine_name", ["vector", "fem", "tissue"])
def test_every_engine_moves_the_local_channels_as_the_wire_engine_does(engine_name):
    """The actions run in the chain every engine shares: the same motion at the features."""
    rig = small_rig()
    wire, other = make_engine(rig, "wire"), make_engine(rig, engine_name)
    rest_w, rest_o = wire.deform(pose(rig)), other.deform(pose(rig))
    for channel, landmark in (
        ("depressor_supercilii_L", "brow_inner_L"),
        ("depressor_septi", "nose_tip"),
        ("nasalis_alar_L", "alar_base_L"),
        ("dilator_naris_L", "alare_L"),
    ):
        values = pose(rig, {channel: 1.0})
        expected = _moved(rig, rest_w, wire.deform(values) - rest_w, landmark)
        got = _moved(rig, rest_o, other.deform(values) - rest_o, landmark)
        assert np.linalg.norm(expected) > 0.05
        np.testing.assert_allclose(got, expected, atol=0.05 * np.linalg.norm(expected))
