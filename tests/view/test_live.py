"""Live capture in the viewer (``mimetic view --capture``), server-level, without a browser.

The take is the small rig rendered (``render_clip``): a neutral face for ``NEUTRAL_S``, then the
jaw opens, the face smiles and the head turns a little and back. Ground truth by construction: the
clip's own values. Every capture runs at the video's pace, so the file stays well under a minute.
"""

from __future__ import annotations

import socket
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from mimetic.capture.trajectories import CaptureError
from mimetic.engines import make_engine
from mimetic.engines.bake import bake
from mimetic.errors import MimeticError, MissingExtraError
from mimetic.rig.activations import Clip
from mimetic.testing import require_extra, run_cli

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")

FPS = 30.0
N_FRAMES = 75  # 2.5 s
NEUTRAL_S = 0.6
SIZE_PX = 384
MOVES = {"jaw_open": 0.35, "zygomatic_major_L": 0.8, "zygomatic_major_R": 0.8}
"""Channels ramped from 0 to these values over 1 s after the neutral start (a smoothstep)."""
YAW_RAD = 0.25
"""The head turns this far and back (a half sine from ``NEUTRAL_S`` to the end)."""
MIN_R = 0.8
"""Correlation of a solved channel with the truth, over the frames solved."""


@pytest.fixture(scope="module")
def web():
    require_extra("viser", "view")
    require_extra("mediapipe", "track")
    from mimetic.view import web

    return web


@pytest.fixture(scope="module")
def basis(rig):
    return bake(make_engine(rig, "wire")).basis


@pytest.fixture(scope="module")
def take(rig, basis, tmp_path_factory):
    """(the MP4's path, the clip it shows (N_FRAMES, c) over ``rig.channel_names``)."""
    from mimetic.view.video import render_clip

    t = np.arange(N_FRAMES) / FPS
    ramp = np.clip((t - NEUTRAL_S) / 1.0, 0.0, 1.0)
    ramp = ramp * ramp * (3 - 2 * ramp)
    values = np.zeros((N_FRAMES, len(rig.channel_names)))
    for name, peak in MOVES.items():
        values[:, rig.channel_index(name)] = peak * ramp
    turn = np.clip((t - NEUTRAL_S) / (t[-1] - NEUTRAL_S), 0.0, 1.0)
    values[:, rig.channel_index("head_yaw")] = YAW_RAD * np.sin(np.pi * turn)
    clip = Clip(rig.channel_names, values, FPS)
    path = render_clip(rig, clip, tmp_path_factory.mktemp("take") / "take.mp4", basis=basis, size=SIZE_PX)
    return path, clip


@pytest.fixture(scope="module")
def blank(tmp_path_factory):
    """A 0.7 s video of a grey wall: no face anywhere."""
    from mimetic.view.video import write_mp4

    frames = [np.full((SIZE_PX, SIZE_PX, 3), 90, np.uint8)] * 21
    return write_mp4(frames, tmp_path_factory.mktemp("blank") / "blank.mp4", fps=FPS, size=(SIZE_PX,) * 2)


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.corrcoef(a, b)[0, 1])


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def live_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == "mimetic-live-capture"]


def play(web, rig_file, capture, **options):
    """The viewer started on ``capture`` (port 0), once its capture has ended; the caller stops it."""
    viewer = web.start(rig_file, port=0, capture=capture, capture_options=options or None)
    status = viewer.live.wait(120)
    assert status.done, status
    return viewer


# ---- the solve the viewer plays


def test_live_frames_follow_the_jaw_and_the_head_once_calibrated(web, rig, basis, take):
    from mimetic.capture.stream import CALIBRATION_S, live_frames

    path, clip = take
    frames = list(live_frames(rig, basis, str(path)))
    assert len(frames) == N_FRAMES
    times = np.array([t for t, _ in frames])
    np.testing.assert_allclose(times, np.arange(N_FRAMES) / FPS, atol=1e-9)
    values = np.stack([f.values for _, f in frames])  # (f, c)
    assert values.shape == clip.values.shape and values.dtype == np.float64
    ready = np.array([f.ready for _, f in frames])
    assert not any(f.lost for _, f in frames)
    collected = round(CALIBRATION_S * FPS)  # the calibration's frames: the first 0.5 s
    assert not ready[: collected - 1].any()  # (the one that completes it is reported ready)
    assert ready[times >= CALIBRATION_S].all()
    np.testing.assert_array_equal(values[~ready], 0.0)
    for name in ("jaw_open", "head_yaw"):
        j = rig.channel_index(name)
        assert correlation(values[ready, j], clip.values[ready, j]) > MIN_R, name
    assert values[-1, rig.channel_index("jaw_open")] > 0.1  # open, not only correlated


# ---- the viewer


def test_the_viewer_plays_the_capture_as_it_arrives(web, rig, rig_file, take, monkeypatch, capfd):
    path, clip = take
    shown: list[tuple[float, np.ndarray]] = []
    show = web.Viewer._show_live

    def recorded(self, time_s, values):
        shown.append((time_s, values.copy()))
        show(self, time_s, values)

    monkeypatch.setattr(web.Viewer, "_show_live", recorded)
    began = time.perf_counter()
    viewer = play(web, rig_file, path)
    took = time.perf_counter() - began
    try:
        status = viewer.live.status
        assert status.state == "finished" and status.frames == N_FRAMES, status
        assert "finished" in viewer.live_text.content and f"{N_FRAMES} frames" in viewer.live_text.content
        assert "ms per frame" in viewer.live_text.content and status.solve_ms > 0
        assert took >= clip.duration_s - 1.0 / FPS  # at the video's pace, not as fast as it decodes
        # what was shown: solved frames only, in order, following the truth
        times = np.array([t for t, _ in shown])
        # a busy machine makes the viewer drop frames to keep the video's pace (9 shown under load)
        assert len(shown) >= 5 and (np.diff(times) > 0).all() and times[0] >= NEUTRAL_S - 0.2
        assert times[-1] == pytest.approx((N_FRAMES - 1) / FPS)  # the last frame is always shown
        poses = np.stack([v for _, v in shown])  # (k, c)
        truth = clip.values[np.round(times * FPS).astype(int)]
        for name in ("jaw_open", "head_yaw"):
            j = rig.channel_index(name)
            assert correlation(poses[:, j], truth[:, j]) > MIN_R, name
        # the face ends on the last pose, and the sliders show it
        np.testing.assert_allclose(viewer.pose, poses[-1], atol=1e-12)
        jaw = rig.channel_index("jaw_open")
        assert viewer.pose[jaw] > 0.1
        assert viewer.sliders[("channels", "jaw_open")].value == pytest.approx(poses[-1, jaw], abs=0.01)
        expected = make_engine(rig, "wire").deform(viewer.pose)  # the head turned, as the page shows
        np.testing.assert_allclose(viewer.vertices, expected, atol=1e-4)
    finally:
        viewer.stop()
    assert not live_threads()
    assert "Traceback" not in capfd.readouterr().err


def test_stopping_the_viewer_mid_capture_ends_the_thread_and_its_callbacks(web, rig_file, take, basis):
    path, _ = take
    viewer = web.start(rig_file, port=0, capture=path, capture_options={"basis": basis})
    try:
        deadline = time.monotonic() + 60
        while viewer.live.status.frames < 3 and time.monotonic() < deadline:
            time.sleep(0.05)
        assert viewer.live.status.frames >= 3 and not viewer.live.status.done
    finally:
        viewer.stop()
    assert not viewer.live.running and not live_threads()
    assert viewer.live.status.state == "stopped"
    text = viewer.live_text.content
    time.sleep(0.3)
    assert viewer.live_text.content == text  # nothing reported after stop()


def test_without_a_capture_the_viewer_has_no_live_line(web, rig_file):
    viewer = web.start(rig_file, port=0)
    try:
        assert viewer.live is None and viewer.live_text is None
    finally:
        viewer.stop()


# ---- bad input: one line, no traceback


def test_a_file_that_is_not_a_video_is_explained_in_the_page(web, rig_file, basis, tmp_path, capfd):
    bad = tmp_path / "notes.mp4"
    bad.write_text("these are notes, not a video\n")
    with pytest.raises(CaptureError, match=r"notes\.mp4: ffmpeg cannot read a video"):
        web.check_capture(rig_file, bad)
    viewer = play(web, rig_file, bad, basis=basis)
    try:
        status = viewer.live.status
        assert status.state == "failed" and "notes.mp4" in status.error and "\n" not in status.error
        assert "ffmpeg cannot read" in status.error
        assert "error" in viewer.live_text.content and "notes.mp4" in viewer.live_text.content
    finally:
        viewer.stop()
    assert "Traceback" not in capfd.readouterr().err


def test_a_video_without_a_face_is_explained_in_the_page(web, rig, rig_file, basis, blank, capfd):
    web.check_capture(rig_file, blank)  # a readable video: found out only by playing it
    viewer = play(web, rig_file, blank, basis=basis)
    try:
        status = viewer.live.status
        assert status.state == "failed" and status.frames == 21, status
        assert "no face found in any of its 21 frames" in status.error and "\n" not in status.error
        assert "no face found" in viewer.live_text.content
        np.testing.assert_array_equal(viewer.pose, viewer.session.defaults)  # the face was kept
    finally:
        viewer.stop()
    assert "Traceback" not in capfd.readouterr().err


def test_without_mediapipe_the_capture_says_what_to_install(web, rig_file, take, basis, monkeypatch):
    monkeypatch.setitem(sys.modules, "mediapipe", None)  # import mediapipe fails
    with pytest.raises(MissingExtraError, match=r"\[track\]"):
        web.check_capture(rig_file, take[0])
    viewer = play(web, rig_file, take[0], basis=basis)
    try:
        assert viewer.live.status.state == "failed" and "[track]" in viewer.live.status.error
    finally:
        viewer.stop()


def test_a_capture_on_a_mesh_is_refused(web, rig, tmp_path, take):
    from mimetic.mesh.io import save_mesh

    mesh_file = save_mesh(rig.mesh, tmp_path / "scan.obj")
    with pytest.raises(MimeticError, match=r"scan\.obj is a mesh"):
        web.check_capture(mesh_file, take[0])


# ---- the command line


def test_cli_capture_of_a_missing_or_unreadable_video_fails_in_one_line(web, rig_file, tmp_path):
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(b"\x00" * 1000)
    for capture, words in ((tmp_path / "missing.mp4", "missing.mp4: no such video file"),
                           (bad, "bad.mp4: ffmpeg cannot read a video")):  # fmt: skip
        result = run_cli("view", rig_file, "--capture", capture, "--port", free_port())
        assert result.exit_code == 1, result.output
        (line,) = result.output.strip().splitlines()
        assert line.startswith("error:") and words in line, line


def test_cli_reports_a_video_without_a_face_in_the_terminal(web, rig_file, blank):
    command = [sys.executable, "-c", "from mimetic.cli import app; app()", "view", str(rig_file),
               "--port", str(free_port()), "--capture", str(blank)]  # fmt: skip
    viewer = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        line = ""
        while not line.startswith("error:") and time.monotonic() < deadline and viewer.poll() is None:
            line = viewer.stderr.readline()
    finally:
        viewer.terminate()
        _, rest = viewer.communicate(timeout=30)
    assert line.startswith("error:") and "no face found in any of its 21 frames" in line, line
    assert "Traceback" not in rest
