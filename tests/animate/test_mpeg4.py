"""MPEG-4 FAPs on the muscle rig: the table, FAP units, calibrated low-level FAPs that move their
feature point by value × FAPU, gaze and head FAPs, unsupported FAPs, visemes and expressions."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from mimetic.animate.expressions import blend
from mimetic.animate.mpeg4 import (
    AU_RAD,
    BLEND_MAX,
    EXPRESSIONS,
    ONE_WAY,
    UNSUPPORTED,
    FapError,
    calibrate_faps,
    fap,
    fap_expression_pose,
    fap_pose,
    fap_table,
    feature_point_positions,
    measure_fapu,
    viseme_pose,
    visemes,
)
from mimetic.errors import MimeticWarning
from mimetic.head.model import make_head
from mimetic.rig.recipe import build_rig
from mimetic.testing import small_rig

LANDMARK_OF = {
    "2.1": "menton", "2.2": "upper_lip_inner", "2.3": "lower_lip_inner", "2.4": "mouth_corner_L",
    "2.5": "mouth_corner_R", "3.1": "eye_upper_lid_L", "3.3": "eye_lower_lid_L", "4.1": "brow_inner_L",
    "4.5": "brow_outer_L", "8.2": "lower_lip_bottom",
}  # fmt: skip


@pytest.fixture(scope="module")
def rig():
    """The default head at full resolution (13k vertices), as the FAPU are defined on a real face."""
    return build_rig(make_head())


@pytest.fixture(scope="module")
def calibration(rig, engine):
    return calibrate_faps(rig, engine=engine)


@pytest.fixture(scope="module")
def rest(rig, engine):
    return engine.deform(np.array([c.default for c in rig.channels]))


def _at(rig, vertices, name):
    point = rig.landmarks[name]
    return np.asarray(point.bary) @ vertices[rig.mesh.faces[point.face]]


# ---- the table


def test_table_numbers_and_names_follow_the_standard():
    table = fap_table()
    assert sorted(table) == list(range(3, 69))
    named = {
        3: "open_jaw", 4: "lower_t_midlip", 5: "raise_b_midlip", 6: "stretch_l_cornerlip",
        12: "raise_l_cornerlip", 19: "close_t_l_eyelid", 23: "yaw_l_eyeball", 31: "raise_l_i_eyebrow",
        37: "squeeze_l_eyebrow", 41: "lift_l_cheek", 48: "head_pitch", 51: "lower_t_midlip_o",
        59: "raise_l_cornerlip_o", 63: "raise_nose", 68: "pull_r_ear",
    }  # fmt: skip
    for number, name in named.items():
        assert table[number].name == name
        assert fap(name) is table[number] and fap(str(number)) is table[number]
    assert (table[3].fapu, table[6].fapu, table[19].fapu, table[31].fapu, table[49].fapu) == (
        "MNS", "MW", "IRISD", "ENS", "AU"
    )  # fmt: skip
    assert not table[3].bidirectional and table[12].bidirectional
    assert table[6].positive == "left" and table[7].positive == "right" and table[19].positive == "down"


def test_unsupported_faps_are_listed_with_reasons():
    assert {18, 27, 28, 29, 30, 39, 40, 43, 44, 45, 46, 47, 64, 65, 66, 67, 68} == set(UNSUPPORTED)
    assert all(UNSUPPORTED.values()) and all(ONE_WAY.values())
    assert 4 in ONE_WAY  # the upper lip cannot be lowered
    assert 63 in ONE_WAY and 61 not in ONE_WAY  # the depressor septi lowers the tip; the nostril narrows


def test_unknown_faps_raise():
    with pytest.raises(FapError, match="3-68"):
        fap(99)
    with pytest.raises(FapError, match="open_jaw"):
        fap("open_jow")
    with pytest.raises(FapError, match="high-level"):
        fap(1)


# ---- FAP units


def test_fapu_are_the_rest_landmark_distances(rig):
    fapu = measure_fapu(rig)
    lm = rig.landmark_positions
    pupils = lm(["pupil_L", "pupil_R"])
    assert fapu.es0 == pytest.approx(pupils[0, 0] - pupils[1, 0])
    assert fapu.mw0 == pytest.approx(np.subtract(*lm(["mouth_corner_L", "mouth_corner_R"])[:, 0]))
    assert fapu.mns0 == pytest.approx(np.subtract(*lm(["subnasale", "upper_lip_inner"])[:, 1]))
    assert fapu.ens0 == pytest.approx(pupils[:, 1].mean() - lm(["subnasale"])[0, 1])
    assert fapu.irisd0 == pytest.approx(np.subtract(*lm(["eye_upper_lid_L", "eye_lower_lid_L"])[:, 1]))
    assert fapu.unit("MW") == fapu.mw0 / 1024 and fapu.unit("AU") == AU_RAD == 1e-5
    # plausible adult proportions (cm): pupils 5-7 apart, a mouth 4-6 wide, lid gap < 1.2
    assert 5 < fapu.es0 < 7 and 4 < fapu.mw0 < 6 and 0.5 < fapu.irisd0 < 1.2 and 1 < fapu.mns0 < 3


# ---- low-level FAPs


@pytest.mark.parametrize(
    ("number", "value"),
    [(3, 500), (5, 25), (5, -60), (6, 40), (6, -30), (12, 100), (12, -60), (14, 200), (15, -100),
     (16, -30), (19, 512), (19, -200), (21, 300), (31, 60), (35, 50), (41, 30), (52, 50), (61, 20)],
)  # fmt: skip
def test_a_fap_moves_its_feature_point_by_value_times_fapu(rig, engine, calibration, rest, number, value):
    spec = fap(number)
    pose = fap_pose(rig, {number: value}, calibration=calibration)
    fp = spec.feature_point
    motion = feature_point_positions(rig, engine.deform(pose))[fp] - feature_point_positions(rig, rest)[fp]
    if fp in LANDMARK_OF:  # the feature point is the landmark the table says
        np.testing.assert_allclose(
            feature_point_positions(rig)[fp], rig.landmark_positions([LANDMARK_OF[fp]])[0]
        )
    want = value * calibration.fapu.unit(spec.fapu)
    assert motion @ spec.axis == pytest.approx(want, rel=0.02, abs=0.002)  # cm


def test_left_and_right_faps_mirror(rig, engine, calibration, rest):
    pose = fap_pose(rig, {"raise_l_cornerlip": 80, "raise_r_cornerlip": 80}, calibration=calibration)
    moved = engine.deform(pose)
    left = _at(rig, moved, "mouth_corner_L") - _at(rig, rest, "mouth_corner_L")
    right = _at(rig, moved, "mouth_corner_R") - _at(rig, rest, "mouth_corner_R")
    np.testing.assert_allclose(left * [-1, 1, 1], right, atol=1e-9)
    assert left[1] > 0.1


def test_reach_and_calibration_curves_are_monotone(calibration):
    for (number, direction), (t, s) in calibration.curves.items():
        assert t[0] == 0.0 and t[-1] == 1.0 and s[0] == 0.0, number
        assert np.all(np.diff(s) >= 0) and s[-1] > 0, (number, direction)
    assert calibration.reach(3) > 1000  # open_jaw: over 1000 MNS (about 2 cm)
    assert calibration.reach(4, "+") == 0.0  # the upper lip cannot be lowered


def test_gaze_faps_turn_each_eye_as_they_say(rig, calibration):
    names = ("gaze_yaw", "gaze_convergence", "gaze_pitch", "gaze_vertical_vergence")

    def channels(pose):
        return [pose[rig.channel_index(c)] for c in names]

    both_left = fap_pose(rig, {23: 20000, 24: 20000}, calibration=calibration)
    assert channels(both_left) == pytest.approx([0.2, 0.0, 0.0, 0.0])
    inward = fap_pose(rig, {23: -10000, 24: 10000}, calibration=calibration)  # both toward the nose
    assert channels(inward) == pytest.approx([0.0, 0.2, 0.0, 0.0])
    down = fap_pose(rig, {25: 20000, 26: 20000}, calibration=calibration)
    assert channels(down) == pytest.approx([0.0, 0.0, -0.2, 0.0])
    outward = fap_pose(rig, {23: 10000, 24: -10000}, calibration=calibration)  # the eyes diverge
    assert channels(outward) == pytest.approx([0.0, -0.2, 0.0, 0.0])
    left_down = fap_pose(rig, {25: 30000}, calibration=calibration)  # the left eye alone, 0.3 rad
    assert channels(left_down) == pytest.approx([0.0, 0.0, -0.15, -0.3])  # left −0.15 − 0.15, right 0
    with pytest.warns(MimeticWarning, match="gaze_convergence's range"):  # 0.8 rad apart: clipped to 0.4
        apart = fap_pose(rig, {23: 40000, 24: -40000}, calibration=calibration)
    assert channels(apart)[1] == pytest.approx(rig.channel("gaze_convergence").minimum)


def test_head_faps_set_the_head_channels(rig):
    pose = fap_pose(rig, {"head_yaw": 20000, "head_pitch": 10000, "head_roll": 5000})
    assert pose[rig.channel_index("head_yaw")] == pytest.approx(0.2)  # left = the subject's left
    assert pose[rig.channel_index("head_pitch")] == pytest.approx(0.1)  # down
    assert pose[rig.channel_index("head_roll")] == pytest.approx(-0.05)  # to the face's right


def test_unsupported_and_unreachable_faps_warn_and_the_rest_still_plays(rig, calibration):
    request = {"open_jaw": 300, "raise_tongue": 50, "lower_t_midlip": 30, "close_t_l_eyelid": 5000}
    with pytest.warns(MimeticWarning) as caught:
        pose = fap_pose(rig, request, calibration=calibration)
    message = str(caught[0].message)
    assert "raise_tongue" in message and "tongue" in message
    assert "lower_t_midlip" in message and "exceeds" in message
    assert pose[rig.channel_index("jaw_open")] > 0
    assert pose[rig.channel_index("eyelid_upper_L")] == rig.channel("eyelid_upper_L").maximum
    assert request["open_jaw"] == 300


def test_fap_pose_refuses_bad_input(rig, calibration):
    with pytest.raises(FapError, match="twice"):
        fap_pose(rig, {3: 100, "open_jaw": 100}, calibration=calibration)
    with pytest.raises(FapError, match="finite"):
        fap_pose(rig, {3: float("nan")}, calibration=calibration)
    with pytest.raises(FapError):
        fap_pose(rig, {3: "wide"}, calibration=calibration)
    other = calibrate_faps(small_rig(), samples=3)
    with pytest.raises(FapError, match="another rig"):
        fap_pose(rig, {3: 100}, calibration=other)


def test_fap_pose_shape_and_zero(rig, calibration):
    pose = fap_pose(rig, {}, calibration=calibration)
    assert pose.shape == (len(rig.channels),) and pose.dtype == np.float64
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        np.testing.assert_array_equal(fap_pose(rig, {3: 0, 63: 0}, calibration=calibration), pose)


# ---- high-level FAPs


def test_visemes_cover_the_standards_fourteen(rig):
    table = visemes()
    assert len(table) == 15 and table[0].phonemes == ()
    assert (
        table[1].phonemes == ("p", "b", "m")
        and table[10].phonemes == ("A:",)
        and table[14].phonemes == ("U",)
    )
    for v in table:
        for channel, value in v.values.items():
            c = rig.channel(channel)
            assert c.minimum <= value <= c.maximum, (v.number, channel)


def test_viseme_blend_follows_the_standard(rig):
    one, two = viseme_pose(rig, 1), viseme_pose(rig, 10)
    b = 40
    mixed = viseme_pose(rig, 1, 10, b)
    np.testing.assert_allclose(mixed, b / BLEND_MAX * one + (1 - b / BLEND_MAX) * two)
    np.testing.assert_array_equal(viseme_pose(rig, "A:"), two)
    assert viseme_pose(rig, "p")[rig.channel_index("jaw_open")] == 0.0  # bilabials keep the jaw closed
    assert two[rig.channel_index("jaw_open")] > 0.2
    np.testing.assert_array_equal(fap_pose(rig, {1: (1, 10, b)}), mixed)
    with pytest.raises(FapError, match="viseme"):
        viseme_pose(rig, 15)
    with pytest.raises(FapError, match="63"):
        viseme_pose(rig, 1, 2, 64)


def test_expression_fap_uses_the_expression_library(rig):
    assert dict(EXPRESSIONS) == {1: "joy", 2: "sadness", 3: "anger", 4: "fear", 5: "disgust", 6: "surprise"}
    np.testing.assert_allclose(fap_expression_pose(rig, 1, 63), blend(rig, [("joy", 1.0)]))
    mixed = fap_expression_pose(rig, "joy", 42, 6, 21)
    np.testing.assert_allclose(mixed, blend(rig, [("joy", 42 / 63), ("surprise", 21 / 63)]))
    np.testing.assert_array_equal(fap_pose(rig, {}, expression=(1, 42, 6, 21)), mixed)
    assert not fap_expression_pose(rig, 0, 63).any()
    with pytest.raises(FapError, match="expression"):
        fap_expression_pose(rig, 7, 10)


def test_low_level_faps_add_to_the_high_level_base(rig, calibration):
    base = viseme_pose(rig, 10)
    pose = fap_pose(rig, {"raise_l_cornerlip": 60}, viseme=(10,), calibration=calibration)
    j = rig.channel_index("zygomatic_major_L")
    assert pose[j] > base[j]
    assert pose[rig.channel_index("jaw_open")] == base[rig.channel_index("jaw_open")]


def test_a_calibration_takes_a_deform_function_or_a_baked_basis(rig, engine, calibration):
    """A calibration needs poses deformed, not an engine of its own making: any deform function
    gives the engine's curves exactly, and a baked basis (what a capture or a batch already holds)
    reaches as far within a few per cent."""
    from mimetic.engines.bake import bake

    same = calibrate_faps(rig, engine=engine.deform)
    assert same.curves.keys() == calibration.curves.keys()
    for key, (_, motion) in calibration.curves.items():
        np.testing.assert_array_equal(same.curves[key][1], motion)
    baked = calibrate_faps(rig, engine=bake(engine, correctives=0, samples=2).basis)
    for number in (3, 6, 12, 31):  # the jaw, a lip corner, a mouth corner up, an inner brow
        assert baked.reach(number) == pytest.approx(calibration.reach(number), rel=0.05), number
    with pytest.raises(FapError, match="give an engine name, an engine, a baked Basis or a deform function"):
        calibrate_faps(rig, engine=42)
