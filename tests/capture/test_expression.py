"""Tests for mimetic.capture.expression's choice of the channels a capture solves by default."""

from __future__ import annotations

import numpy as np

from mimetic.capture.expression import GAZE_CHANNELS, NOSE_CHANNELS, library_directions, visible_channels
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


def test_library_directions_are_the_arkit_shapes_on_the_free_channels():
    channels = ("orbicularis_oris", "frontalis_inner_L", "frontalis_inner_R", "gaze_pitch", "jaw_open")
    basis, _ = _basis(channels)
    free = np.array([0, 1, 2, 4])  # the gaze is not free
    rows = {tuple(row) for row in library_directions(basis, free)}
    assert (1.0, 0.0, 0.0, 0.0) in rows  # mouthPucker: its incisivis channels are not in this basis
    assert (0.0, 1.0, 0.0, 0.0) in rows and (0.0, 0.0, 1.0, 0.0) in rows  # browInnerUp's halves
    assert all(any(v != 0.0 for v in row) for row in rows)  # eyeLookDown (gaze only) is left out
    assert len(rows) == len(library_directions(basis, free))  # no shape twice
