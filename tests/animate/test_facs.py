"""FACS action units as data: the table, key and intensity parsing, sides, errors, and what each AU does."""

from __future__ import annotations

import numpy as np
import pytest

from mimetic.animate.expressions import load_library
from mimetic.animate.facs import (
    INTENSITY_LETTERS,
    FacsError,
    action_unit,
    action_units,
    au_values,
    facs_pose,
    facs_values,
    intensity,
    parse_facs,
    parse_key,
)
from mimetic.errors import MimeticError
from mimetic.mesh.model import surface_positions

REQUIRED = (
    1,
    2,
    4,
    5,
    6,
    7,
    9,
    10,
    11,
    12,
    13,
    14,
    15,
    16,
    17,
    18,
    20,
    22,
    23,
    24,
    25,
    26,
    27,
    28,
    43,
    45,
    46,
)
SIDED = (1, 2, 4, 5, 6, 7, 9, 10, 11, 12, 13, 14, 15, 16, 18, 20, 43, 46)  # L/R where the anatomy is paired
MOVE_TOL_CM = 0.02  # "does not move": well below a visible displacement on a 23 cm head


def _landmarks(rig, vertices, names):
    """Positions (k, 3) of the named landmarks on posed ``vertices``."""
    return surface_positions([rig.landmarks[n] for n in names], vertices, rig.mesh.faces)


# ---- the table


def test_table_holds_the_required_action_units_with_sides():
    units = action_units()
    for number in REQUIRED:
        unit = units[number]
        assert unit.supported, number
        assert unit.name and unit.values, number
    for number in SIDED:
        assert {"L", "R"} <= set(units[number].values), number
    assert units[46].sides == "required"  # a wink is one eye
    assert units[17].sides == "none"  # the mentalis is one midline muscle


def test_every_table_value_names_a_channel_and_lies_in_range(rig):
    for unit in action_units().values():
        for side, values in unit.values.items():
            for channel, value in values.items():
                c = rig.channel(channel)  # KeyError on a typo
                assert c.minimum - 1e-9 <= value <= c.maximum + 1e-9, (unit.number, side, channel, value)


def test_sided_values_mirror_each_other():
    for unit in action_units().values():
        if {"L", "R"} <= set(unit.values) and unit.number != 30:  # AU30's sides are directions
            left, right = unit.values["L"], unit.values["R"]
            mirrored = {c[:-2] + "_R" if c.endswith("_L") else c: v for c, v in left.items()}
            assert mirrored == dict(right), unit.number


def test_unsupported_action_units_say_why():
    unsupported = [u for u in action_units().values() if not u.supported]
    assert {36, 37} <= {u.number for u in unsupported}  # the tongue bulging the cheek, wiping the lips
    assert not {19, 22, 28, 33, 34, 35, 38, 39} & {u.number for u in unsupported}  # tissue actions
    assert all(u.note for u in unsupported)


# ---- keys and intensities


@pytest.mark.parametrize(
    ("key", "expected"),
    [
        ("AU12", (12, "")),
        ("12", (12, "")),
        (12, (12, "")),
        ("AU12L", (12, "L")),
        ("AU12_L", (12, "L")),
        ("12L", (12, "L")),
        ("L12", (12, "L")),
        ("au12_r", (12, "R")),
        (" AU 26 ", (26, "")),
    ],
)
def test_parse_key_accepts_the_usual_spellings(key, expected):
    assert parse_key(key) == expected


@pytest.mark.parametrize("key", ["AU12X", "L12R", "AU", "", "smile", 1.5, True])
def test_parse_key_rejects_malformed_keys(key):
    with pytest.raises(FacsError):
        parse_key(key)


def test_intensity_reads_numbers_and_letters():
    assert [intensity(c) for c in "ABCDE"] == pytest.approx([0.2, 0.4, 0.6, 0.8, 1.0])
    assert intensity("c") == INTENSITY_LETTERS["C"]
    assert intensity(0.35) == 0.35
    with pytest.raises(FacsError, match="divide OpenFace"):
        intensity(3)
    for bad in ("F", -0.5, float("nan"), None):
        with pytest.raises(FacsError):
            intensity(bad)


def test_parse_facs_reads_codes_with_sides_and_letters():
    assert parse_facs("AU1+2+4B+L12C") == {"AU1": 1.0, "AU2": 1.0, "AU4": 0.4, "AU12_L": 0.6}
    assert parse_facs("6+12", default="C") == {"AU6": 0.6, "AU12": 0.6}
    with pytest.raises(FacsError, match="twice"):
        parse_facs("12+AU12")
    with pytest.raises(FacsError):
        parse_facs("12++26")


def test_expression_library_facs_codes_name_known_action_units():
    library = load_library()
    for name in library.names:
        code = library[name].facs
        for key in parse_facs(code):
            number, side = parse_key(key)
            unit = action_unit(number)
            assert unit.supported, (name, key)
            assert side in unit.values, (name, key)


# ---- errors


def test_errors_name_the_problem_and_the_fix():
    with pytest.raises(FacsError, match=r"unknown action unit AU40.*nearest"):
        au_values("AU40")
    with pytest.raises(FacsError, match="tongue"):
        au_values("AU36")
    with pytest.raises(FacsError, match="no sides; write 'AU17'"):
        au_values("AU17_L")
    with pytest.raises(FacsError, match="AU46_L"):
        au_values("AU46")
    with pytest.raises(FacsError, match="twice"):
        facs_values({"AU12": 1.0, "12": 0.5})
    assert issubclass(FacsError, MimeticError) and issubclass(FacsError, ValueError)


# ---- poses


def test_facs_pose_shape_dtype_and_inputs_untouched(rig):
    request = {"AU12_L": 0.8, "AU26": "C"}
    before = dict(request)
    pose = facs_pose(rig, request)
    assert pose.shape == (len(rig.channels),) and pose.dtype == np.float64
    assert request == before
    assert not facs_pose(rig, {}).any()


def test_one_side_drives_one_side_and_both_sides_sum(rig):
    left = facs_pose(rig, {"AU12_L": 1.0})
    assert left[rig.channel_index("zygomatic_major_L")] == 1.0
    assert left[rig.channel_index("zygomatic_major_R")] == 0.0
    both = facs_pose(rig, {"AU4": 1.0})
    one = facs_pose(rig, {"AU4_L": 1.0})
    j = rig.channel_index("procerus")
    assert both[j] == pytest.approx(2 * one[j])  # the midline muscle counts once per side
    assert one[rig.channel_index("corrugator_R")] == 0.0


def test_facs_pose_scales_linearly_then_clips(rig):
    half = facs_pose(rig, {"AU12": 0.5})
    full = facs_pose(rig, {"AU12": 1.0})
    np.testing.assert_allclose(2 * half, full)
    jaw = rig.channel("jaw_open")
    stacked = facs_pose(rig, {"AU26": 1.0, "AU27": 1.0})  # 0.2 + 0.45 rad > the channel's maximum
    assert stacked[rig.channel_index("jaw_open")] == jaw.maximum


def test_action_units_do_what_they_say_on_the_engine(rig, engine):
    rest = engine.deform(facs_pose(rig, {}))

    def moved(request, names):
        return _landmarks(rig, engine.deform(facs_pose(rig, request)), names) - _landmarks(rig, rest, names)

    corner = moved({"AU12_L": 1.0}, ["mouth_corner_L", "mouth_corner_R"])
    assert corner[0, 1] > 0.2 and corner[0, 0] > 0.05  # cm: up and out
    assert np.linalg.norm(corner[1]) < MOVE_TOL_CM
    down = moved({"AU15_R": 1.0}, ["mouth_corner_R"])
    assert down[0, 1] < -0.1
    brows = moved({"AU1": 1.0}, ["brow_inner_L", "brow_inner_R"])
    assert (brows[:, 1] > 0.3).all()
    chin = moved({"AU26": 1.0}, ["pogonion", "lower_lip_bottom"])  # (small heads misplace menton)
    assert chin[0, 1] < -0.1 and chin[1, 1] < -0.5  # the chin swings down and back, the lip drops
    closed = engine.deform(facs_pose(rig, {"AU43_L": 1.0}))
    lids_l = _landmarks(rig, closed, ["eye_upper_lid_L", "eye_lower_lid_L"])
    lids_r = _landmarks(rig, closed, ["eye_upper_lid_R", "eye_lower_lid_R"])
    rest_r = _landmarks(rig, rest, ["eye_upper_lid_R", "eye_lower_lid_R"])
    assert lids_l[0, 1] - lids_l[1, 1] < 0.05  # the left fissure shut (rest ~0.8 cm)
    np.testing.assert_allclose(lids_r, rest_r, atol=1e-9)


def test_nose_and_brow_action_units_move_their_feature(rig, engine):
    """AU4 lowers the brows' heads and draws them together; AU38 widens the nose at the wings and
    AU39 narrows its side; both one-sided units leave the other side alone."""
    rest = engine.deform(facs_pose(rig, {}))

    def moved(request, names):
        return _landmarks(rig, engine.deform(facs_pose(rig, request)), names) - _landmarks(rig, rest, names)

    brows = moved({"AU4": 1.0}, ["brow_inner_L", "brow_inner_R"])
    assert (brows[:, 1] < -0.3).all() and brows[0, 0] < -0.1 < 0.1 < brows[1, 0]  # cm: down and inward
    wings = moved({"AU38_L": 1.0}, ["alar_base_L", "alar_base_R"])
    assert wings[0, 0] > 0.1 and np.linalg.norm(wings[1]) < MOVE_TOL_CM
    values = facs_pose(rig, {"AU39_R": 1.0})
    assert values[rig.channel_index("nasalis_transverse_R")] == 1.0
    assert values[rig.channel_index("nasalis_transverse_L")] == 0.0
