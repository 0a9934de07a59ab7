"""Tests for mimetic.capture.expression's choice of the channels a capture solves by default."""

from __future__ import annotations

import numpy as np

from mimetic.capture.expression import GAZE_CHANNELS, NOSE_CHANNELS, visible_channels
from mimetic.engines.basis import Basis
from mimetic.rig.anatomy.actions import CHANNELS as ACTION_CHANNELS


def _basis(channels: tuple[str, ...]) -> tuple[Basis, np.ndarray]:
    """A basis whose every channel moves 4 markers (vertices) by 1 unit, and those markers' deltas."""
    deltas = np.ones((len(channels), 4, 3))
    return Basis(channels, np.zeros((4, 3)), deltas), deltas


def test_visible_channels_leave_out_the_gaze_and_the_nose_muscles_unless_named():
    channels = (
        "zygomatic_major_L",
        "depressor_septi",
        "dilator_naris_R",
        "nasalis_alar_L",
        "gaze_yaw",
        "nasalis_L",
    )
    basis, deltas = _basis(channels)
    chosen = visible_channels(basis, deltas)
    assert chosen.shape == (len(channels),) and chosen.dtype == bool
    assert [c for c, keep in zip(channels, chosen, strict=True) if keep] == ["zygomatic_major_L", "nasalis_L"]
    named = visible_channels(basis, deltas, active=["depressor_septi", "gaze_yaw"])
    assert [c for c, keep in zip(channels, named, strict=True) if keep] == ["depressor_septi", "gaze_yaw"]
    assert deltas.min() == 1.0  # untouched


def test_nose_channels_are_channels_of_the_rig():
    assert set(NOSE_CHANNELS) <= set(ACTION_CHANNELS) and not set(NOSE_CHANNELS) & set(GAZE_CHANNELS)
