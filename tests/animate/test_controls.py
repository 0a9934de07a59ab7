"""Descriptive controls: the thesis's Table 6.2 as data, and its mirror convention."""

from __future__ import annotations

import numpy as np
import pytest

from mimetic.animate.controls import (
    ControlError,
    apply_descriptive,
    descriptive_control,
    descriptive_controls,
    descriptive_pose,
    read_descriptive,
)
from mimetic.errors import MimeticError
from mimetic.rig.activations import pose

# Fig. 6.15 row order and Table 6.2 muscles
THESIS_ROWS = [
    ("Lift Inner Brow", "frontalis_inner", True),
    ("Lift Outer Brow", "frontalis_outer", True),
    ("Squeeze Brow", "corrugator", True),
    ("Lower Brows", "procerus", False),
    ("Squint", "orbicularis_oculi_outer", True),
    ("Sneer", "levator_labii_nasal", True),
    ("Sneer Intensity", "orbicularis_oculi_inner", True),
    ("Sneer Width", "levator_labii_mid", True),
    ("Smile/Wide", "zygomatic_major", True),
    ("Stretch Lower Lip", "risorius", True),
    ("Mouth Narrow", "orbicularis_oris_incisivis", True),
    ("Lower Mouth Corner", "triangularis", True),
    ("Lower Lip Down", "depressor_labii", True),
    ("Lower Lip Up", "mentalis", False),
]


def test_descriptive_controls_match_table_6_2_in_row_order():
    controls = descriptive_controls()
    assert [(c.name, c.muscle, c.paired) for c in controls] == THESIS_ROWS
    assert sum(len(c.channels) for c in controls) == 26  # the thesis's 26 contraction parameters
    assert all(c.description for c in controls)


def test_descriptive_controls_drive_existing_muscle_channels(rig):
    for control in descriptive_controls():
        for channel in control.channels:
            assert channel in rig.muscle_names, (control.name, channel)


def test_apply_descriptive_left_slider_drives_the_right_side(rig):
    values = apply_descriptive(rig, {"Smile/Wide": (0.4, 1.0), "Lower Brows": 0.5})
    assert values == {"zygomatic_major_R": 0.4, "zygomatic_major_L": 1.0, "procerus": 0.5}


def test_apply_descriptive_reproduces_the_thesis_screenshot(rig):
    # Fig. 6.14: Lift Inner Brow shows 0.4016 | 1.0000 where the low-level tab has Rt 0.4016, Lt 1.0
    values = apply_descriptive(rig, {"Lift Inner Brow": (0.4016, 1.0)})
    assert values == {"frontalis_inner_R": 0.4016, "frontalis_inner_L": 1.0}


def test_apply_descriptive_number_on_a_pair_sets_both_sides(rig):
    assert apply_descriptive(rig, {"Squint": 0.3}) == {
        "orbicularis_oculi_outer_R": 0.3,
        "orbicularis_oculi_outer_L": 0.3,
    }


def test_apply_descriptive_single_row_rejects_a_pair(rig):
    with pytest.raises(ControlError, match="Lower Lip Up"):
        apply_descriptive(rig, {"Lower Lip Up": (0.2, 0.3)})


@pytest.mark.parametrize("bad", ["high", (0.1, 0.2, 0.3), float("nan"), (0.1, None)])
def test_apply_descriptive_rejects_malformed_settings(rig, bad):
    with pytest.raises(ControlError, match="Smile/Wide"):
        apply_descriptive(rig, {"Smile/Wide": bad})


def test_apply_descriptive_rejects_out_of_range_naming_the_slider(rig):
    with pytest.raises(ControlError, match=r"left slider 1\.5 is outside \[0, 1\]"):
        apply_descriptive(rig, {"Squeeze Brow": (1.5, 0.0)})


def test_unknown_control_raises_with_suggestions(rig):
    with pytest.raises(ControlError, match="did you mean 'Smile/Wide'") as info:
        apply_descriptive(rig, {"smile/wide": 1.0})
    assert isinstance(info.value, MimeticError) and isinstance(info.value, ValueError)
    with pytest.raises(ControlError, match="the controls are"):
        descriptive_control("Flare Nostrils Wildly xyz")


def test_descriptive_pose_equals_pose_of_the_values(rig):
    settings = {"Smile/Wide": (0.4, 1.0), "Lower Lip Up": 0.25}
    expected = pose(rig, apply_descriptive(rig, settings))
    result = descriptive_pose(rig, settings)
    assert result.shape == (len(rig.channels),) and result.dtype == np.float64
    np.testing.assert_array_equal(result, expected)


def test_read_descriptive_round_trips_settings(rig):
    settings = {"Lift Outer Brow": (0.25, 0.75), "Lower Brows": 0.5, "Mouth Narrow": (1.0, 0.0)}
    shown = read_descriptive(rig, descriptive_pose(rig, settings))
    for name, setting in settings.items():
        assert shown[name] == setting
    assert shown["Smile/Wide"] == (0.0, 0.0)
    assert len(shown) == 14
