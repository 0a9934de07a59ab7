"""The live solver: landmarks pushed one frame at a time (exact projections of the rig's own markers
while the head turns), calibration, a lost face, bad input."""

from __future__ import annotations

import numpy as np
import pytest

from mimetic.capture import CaptureError
from mimetic.capture.camera import FRONT, PinholeCamera
from mimetic.capture.stream import LiveSolver
from mimetic.engines.basis import evaluate_basis
from mimetic.engines.skinning import rotation_x, rotation_y

FPS = 30.0
SIZE = (1280, 720)


@pytest.fixture(scope="module")
def stream(rig, baked, ibug):
    """0.6 s of neutral, then 3 s of the jaw opening and closing while the head turns; the iBUG markers
    projected by a 40° camera 60 cm away."""
    f = 108
    t = np.arange(f) / FPS
    on = np.clip((t - 0.6) / 0.3, 0.0, 1.0)
    values = np.zeros((f, len(rig.channels)))
    values[:, rig.channel_index("jaw_open")] = 0.2 * on * (0.5 - 0.5 * np.cos(2 * np.pi * 0.6 * (t - 0.6)))
    yaw, pitch = 0.2 * on * np.sin(2 * np.pi * 0.3 * t), 0.1 * on * np.sin(2 * np.pi * 0.25 * t)
    values[:, rig.channel_index("head_yaw")] = yaw
    values[:, rig.channel_index("head_pitch")] = pitch
    points = ibug.positions(rig, evaluate_basis(baked, values))
    pivot = rig.bone("head").head
    R = np.array([rotation_y(y) @ rotation_x(p) for y, p in zip(yaw, pitch, strict=True)])
    world = np.einsum("fij,fmj->fmi", R, points - pivot) + pivot
    camera = PinholeCamera.from_fov(40.0, SIZE)
    return values, camera.project((world - points[0].mean(axis=0)) @ FRONT.T + np.array([0.0, 0.0, 60.0]))


def test_live_frames_follow_the_jaw_and_the_head_after_calibrating(rig, baked, ibug, stream):
    values, pixels = stream
    solver = LiveSolver(rig, baked, ibug, image_size=SIZE, fps=FPS, fov_deg=40.0, tracked=False)
    frames = [solver.push(p) for p in pixels]
    ready = np.array([frame.ready for frame in frames])
    assert not ready[:14].any() and ready[15:].all()  # 0.5 s at 30 fps calibrate
    solved = np.array([frame.values for frame in frames])
    j, yaw = rig.channel_index("jaw_open"), rig.channel_index("head_yaw")
    assert np.corrcoef(solved[20:, j], values[20:, j])[0, 1] > 0.95
    assert np.abs(solved[20:, j] - values[20:, j]).max() < 0.06  # the one-euro filter lags a little
    assert np.degrees(np.abs(solved[20:, yaw] - values[20:, yaw]).max()) < 1.5
    assert not any(frame.lost for frame in frames)
    assert max(frame.seconds for frame in frames[20:]) < 1.0  # not a speed test: each frame is solved alone


def test_a_lost_face_holds_the_last_answer(rig, baked, ibug, stream):
    _, pixels = stream
    solver = LiveSolver(rig, baked, ibug, image_size=SIZE, fps=FPS, fov_deg=40.0, tracked=False)
    for p in pixels[:40]:
        before = solver.push(p)
    lost = solver.push(np.full((68, 2), np.nan))
    assert lost.lost and lost.ready
    np.testing.assert_array_equal(lost.values, before.values)
    assert not solver.push(pixels[41]).lost  # found again


def test_live_solver_rejects_bad_input(rig, baked, ibug):
    with pytest.raises(CaptureError, match="fps"):
        LiveSolver(rig, baked, ibug, image_size=SIZE, fps=0.0)
    solver = LiveSolver(rig, baked, ibug, image_size=SIZE, fps=FPS)
    with pytest.raises(CaptureError, match=r"\(68, 2\)"):
        solver.push(np.zeros((67, 2)))
