"""Tests for mimetic.capture.video: FaceMesh tracked through a rendered video, and its points on a rig.

The small rig's neutral face turning by head_yaw is rendered to a 256² MP4 (``render_clip``,
``face_camera``); the tracked mouth corners must land near the rig's own mouth corners projected
with that camera. Tests that run mediapipe skip without the ``[track]`` extra, except on CI.
"""

from __future__ import annotations

import warnings

import imageio_ffmpeg
import numpy as np
import pytest

from mimetic.capture.trajectories import CaptureError
from mimetic.capture.video import N_FACE_POINTS, mediapipe_markers, track_video
from mimetic.engines import make_engine
from mimetic.errors import MimeticWarning, MissingExtraError
from mimetic.fit import detect
from mimetic.fit.detect import MEDIAPIPE_POINTS, N_LANDMARKS
from mimetic.mesh.model import SurfacePoint
from mimetic.render.camera import project
from mimetic.rig.activations import Clip
from mimetic.testing import require_extra, small_rig
from mimetic.view.sheets import face_camera
from mimetic.view.video import render_clip, write_mp4

SIZE = 256  # pixels, a multiple of 16 so render_clip keeps it
FPS = 25.0
N_FRAMES = 12
MAX_YAW_RAD = 0.15  # the head turns from -0.15 to +0.15 rad (about ±9°)
MIN_SCORE = 0.5
TOL_MOUTH_PX = 5.0  # tracked vs projected rig mouth corners at 256² (measured: max 3.1 px; mouth ~77 px wide)
TOL_MARKER_CM = 1.0  # mediapipe_markers vs the rig's landmarks of the same meaning
MIN_MARKERS = 400
GREY_FRAMES = 3  # frames without a face before the face clip in the partly-faceless video


@pytest.fixture(scope="module")
def mediapipe():
    return require_extra("mediapipe", "track")


@pytest.fixture(scope="module")
def turning(tmp_path_factory):
    """The rendered clip: (path, expected (f, 2, 2) pixels of mouth_corner_R and _L per frame)."""
    rig = small_rig()
    names = list(rig.channel_names)
    values = np.tile([c.default for c in rig.channels], (N_FRAMES, 1))  # (f, c)
    values[:, names.index("head_yaw")] = np.linspace(-MAX_YAW_RAD, MAX_YAW_RAD, N_FRAMES)
    path = render_clip(
        rig, Clip(tuple(names), values, FPS), tmp_path_factory.mktemp("video") / "turn.mp4", size=SIZE
    )
    engine = make_engine(rig, "wire")  # render_clip's default engine
    corners = [rig.landmarks[n] for n in ("mouth_corner_R", "mouth_corner_L")]
    faces = rig.mesh.faces[[p.face for p in corners]]  # (2, 3)
    bary = np.array([p.bary for p in corners])  # (2, 3)
    camera = face_camera(rig)
    expected = np.stack(
        [
            project(np.einsum("kj,kjd->kd", bary, engine.deform(pose)[faces]), camera, SIZE).pixels
            for pose in values
        ]
    )  # (f, 2, 2), x right, y down
    return path, expected


@pytest.fixture(scope="module")
def tracked(mediapipe, turning):
    path, _ = turning
    calls = []
    result = track_video(path, progress=lambda done, total: calls.append((done, total)))
    return result, calls


def _frames(path) -> list[np.ndarray]:
    reader = imageio_ffmpeg.read_frames(str(path))
    w, h = next(reader)["size"]
    return [np.frombuffer(f, np.uint8).reshape(h, w, 3) for f in reader]


def test_track_video_gives_478_points_in_pixels_for_every_frame(tracked):
    result, calls = tracked
    assert result.positions.shape == (N_FRAMES, N_LANDMARKS, 3) and result.positions.dtype == np.float64
    assert result.names == tuple(f"mediapipe_{k}" for k in range(N_LANDMARKS))
    assert result.units == "px" and result.fps == FPS and result.dims == 3
    assert np.isfinite(result.positions).all()
    assert (result.confidence >= MIN_SCORE).all() and (result.confidence <= 1.0).all()
    assert calls == [(k, N_FRAMES) for k in range(1, N_FRAMES + 1)]


def test_track_video_mouth_corners_match_the_rendered_rig(tracked, turning):
    result, _ = tracked
    _, expected = turning
    xy = result.select(["mediapipe_61", "mediapipe_291"]).positions[..., :2]  # (f, 2, 2), +y up
    pixels = xy * [1.0, -1.0]  # back to image pixels, y down
    error = np.linalg.norm(pixels - expected, axis=2)  # (f, 2)
    assert error.max() < TOL_MOUTH_PX, f"mouth corners off by up to {error.max():.1f} px"


def test_track_video_is_right_handed_with_y_up_and_z_toward_the_viewer(tracked):
    result, _ = tracked
    p = {k: result.positions[:, MEDIAPIPE_POINTS[k]] for k in MEDIAPIPE_POINTS}  # (f, 3) each
    eyes_y = (p["eye_outer_corner_L"][:, 1] + p["eye_outer_corner_R"][:, 1]) / 2
    mouth_y = (p["mouth_corner_L"][:, 1] + p["mouth_corner_R"][:, 1]) / 2
    assert (eyes_y > mouth_y + 20).all()  # eyes above the mouth
    assert np.median(result.positions[..., 1]) < 0  # the image's top edge is y = 0
    assert (p["mouth_corner_L"][:, 0] > p["mouth_corner_R"][:, 0]).all()  # the subject's left is image right
    assert (p["nose_tip"][:, 2] > p["eye_outer_corner_L"][:, 2] + 10).all()  # the nose is nearer the camera


def test_track_video_marks_frames_without_a_face(mediapipe, turning, tmp_path):
    path, _ = turning
    faces = _frames(path)
    grey = np.full_like(faces[0], 128)
    mixed = write_mp4([grey] * GREY_FRAMES + faces, tmp_path / "mixed.mp4", fps=FPS, size=(SIZE, SIZE))
    with pytest.warns(
        MimeticWarning,
        match=rf"no face in {GREY_FRAMES} of {GREY_FRAMES + N_FRAMES} frames \(frames 0, 1, 2,",
    ):
        result = track_video(mixed)
    assert np.isnan(result.positions[:GREY_FRAMES]).all() and (result.confidence[:GREY_FRAMES] == 0).all()
    assert (
        np.isfinite(result.positions[GREY_FRAMES:]).all()
        and (result.confidence[GREY_FRAMES:] >= MIN_SCORE).all()
    )


def test_track_video_of_a_blank_video_raises_no_face(mediapipe, tmp_path):
    grey = np.full((64, 64, 3), 128, np.uint8)
    path = write_mp4([grey] * 4, tmp_path / "grey.mp4", fps=FPS, size=(64, 64))
    with pytest.raises(CaptureError, match=r"no face found in any of the 4 frames of .*grey\.mp4"):
        track_video(path)


def test_track_video_rejects_missing_and_corrupt_files(tmp_path):
    with pytest.raises(CaptureError, match=r"nothing\.mp4: no such video file"):
        track_video(tmp_path / "nothing.mp4")
    corrupt = tmp_path / "corrupt.mp4"
    corrupt.write_bytes(np.random.default_rng(0).integers(0, 256, 4096, dtype=np.uint8).tobytes())
    with pytest.raises(CaptureError, match=r"corrupt\.mp4: ffmpeg cannot read a video"):
        track_video(corrupt)


def test_track_video_fps_override_warns_and_max_frames_stops(mediapipe, turning):
    path, _ = turning
    with pytest.warns(MimeticWarning, match=r"fps=30 given, but the file says 25"):
        result = track_video(path, fps=30.0, max_frames=3)
    assert result.fps == 30.0 and result.n_frames == 3
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert track_video(path, fps=25.1, max_frames=1).n_frames == 1  # within 1 %: no warning


def test_track_video_keeps_stderr_free_of_mediapipe_noise(mediapipe, turning, capfd):
    path, _ = turning
    track_video(path, max_frames=2)
    err = capfd.readouterr().err
    assert "XNNPACK" not in err and "absl" not in err and "W0000" not in err, err


def test_track_video_without_mediapipe_raises_missing_extra(turning, monkeypatch):
    def missing():
        raise MissingExtraError(
            "face tracking needs the optional extra [track]: pip install 'mimetic[track]'"
        )

    monkeypatch.setattr(detect, "_import_mediapipe", missing)
    with pytest.raises(MissingExtraError, match=r"\[track\]"):
        track_video(turning[0])


def test_track_video_rejects_bad_arguments(turning):
    path, _ = turning
    with pytest.raises(CaptureError, match="fps"):
        track_video(path, fps=0.0)
    with pytest.raises(ValueError, match="max_frames"):
        track_video(path, max_frames=0)
    with pytest.raises(ValueError, match="min_score"):
        track_video(path, min_score=1.5)


@pytest.fixture(scope="module")
def markers(mediapipe):
    return mediapipe_markers(small_rig())


def test_mediapipe_markers_confirms_most_face_points(markers):
    names, points = markers
    assert len(names) == len(points) >= MIN_MARKERS
    indices = [int(n.removeprefix("mediapipe_")) for n in names]
    assert indices == sorted(indices) and max(indices) < N_FACE_POINTS  # no iris points
    mesh = small_rig().mesh
    skin = set(mesh.parts["skin"].tolist())
    assert all(isinstance(p, SurfacePoint) and p.face in skin for p in points)
    assert np.allclose([sum(p.bary) for p in points], 1.0)


def test_mediapipe_markers_match_the_rigs_named_landmarks(markers):
    rig = small_rig()
    names, points = markers
    by_name = dict(zip(names, points, strict=True))
    for landmark, index in MEDIAPIPE_POINTS.items():
        point = by_name[f"mediapipe_{index}"]
        distance = np.linalg.norm(
            point.position(rig.mesh.vertices, rig.mesh.faces) - rig.landmark_positions([landmark])[0]
        )
        assert distance < TOL_MARKER_CM, f"{landmark} (mediapipe_{index}) is {distance:.2f} cm off"
