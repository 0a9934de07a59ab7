"""Calibration (similarity, mirror and unit checks) and head-motion removal with known answers."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mimetic.capture.head import HeadMotion, calibrate, head_motion, nearest_true
from mimetic.capture.trajectories import CaptureError
from mimetic.engines.skinning import rotation_x, rotation_y, rotation_z
from mimetic.fit.similarity import Similarity


def face_points(rng: np.random.Generator, k: int = 12) -> np.ndarray:
    """Points spread like markers on a 20 cm head (cm)."""
    return rng.normal(scale=[6.0, 8.0, 4.0], size=(k, 3))


def test_calibration_recovers_millimetres_and_z_up():
    rng = np.random.default_rng(0)
    rig = face_points(rng)
    z_up = Rotation.from_euler("x", 90, degrees=True).as_matrix()  # a Z-up export
    capture = 10.0 * rig @ z_up.T + np.array([100.0, -20.0, 5.0])  # mm
    similarity, units = calibrate(rig, capture, units="mm", rig_units="cm")
    assert units == "mm"
    np.testing.assert_allclose(similarity.apply(capture), rig, atol=1e-9)
    assert similarity.scale == pytest.approx(0.1)
    guessed = calibrate(rig, capture, units=None, rig_units="cm")[1]
    assert guessed == "mm"


def test_a_mirror_image_is_refused():
    rng = np.random.default_rng(1)
    rig = face_points(rng)
    mirrored = rig * np.array([1.0, 1.0, -1.0])  # z flipped: left-handed
    with pytest.raises(CaptureError, match="mirror image"):
        calibrate(rig, mirrored, units="cm", rig_units="cm")


def test_units_that_contradict_the_size_are_refused():
    rng = np.random.default_rng(2)
    rig = face_points(rng)
    with pytest.raises(CaptureError, match="looks like mm"):
        calibrate(rig, 10.0 * rig, units="m", rig_units="cm")  # millimetre numbers labelled metres


def test_head_motion_is_recovered_and_an_outlier_ignored():
    rng = np.random.default_rng(3)
    rest = face_points(rng, 10)
    pivot = np.array([0.0, 2.0, -3.0])
    f = 20
    angles = rng.uniform(-0.3, 0.3, (f, 3))  # yaw, pitch, roll
    angles[0] = 0.0
    shift = rng.normal(scale=2.0, size=(f, 3))
    shift[0] = 0.0
    frames = np.empty((f, 10, 3))
    for t in range(f):
        R = rotation_y(angles[t, 0]) @ rotation_x(angles[t, 1]) @ rotation_z(-angles[t, 2])
        frames[t] = (rest - pivot) @ R.T + pivot + shift[t]
    frames[5, 3] += 4.0  # a loose marker
    frames[7, 1] = np.nan  # a missing one
    motion = head_motion(frames, rest, Similarity.identity(), pivot=pivot, size=20.0, fixed_scale=True)
    assert isinstance(motion, HeadMotion)
    np.testing.assert_allclose(motion.angles(), angles, atol=1e-9)
    np.testing.assert_allclose(motion.translation, shift, atol=1e-9)
    assert not motion.inliers[5, 3] and motion.inliers[5].sum() == 9
    assert not motion.inliers[7, 1]
    assert motion.fitted.all()
    stabilised = frames @ motion.to_rig[:, :3, :3].transpose(0, 2, 1) + motion.to_rig[:, None, :3, 3]
    err = np.linalg.norm(stabilised - rest, axis=2)
    err[5, 3] = err[7, 1] = 0.0
    assert err.max() < 1e-9


def test_frames_without_enough_points_take_their_neighbours_motion():
    rng = np.random.default_rng(4)
    rest = face_points(rng, 5)
    frames = np.repeat(rest[None], 6, axis=0)
    frames[2:4, :3] = np.nan  # two points left: no fit
    motion = head_motion(frames, rest, Similarity.identity(), pivot=np.zeros(3), size=20.0, fixed_scale=True)
    assert motion.fitted.tolist() == [True, True, False, False, True, True]
    assert np.isnan(motion.residual[2]) and motion.residual[0] < 1e-9
    np.testing.assert_allclose(motion.rotation[2], np.eye(3), atol=1e-12)


def test_nearest_true():
    mask = np.array([False, True, False, False, False, False, True, False])
    assert nearest_true(mask).tolist() == [1, 1, 1, 1, 6, 6, 6, 6]
