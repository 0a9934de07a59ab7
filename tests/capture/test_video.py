"""Tests for mimetic.capture.video: FaceMesh tracked through a rendered video, and its points on a rig.

The small rig's neutral face turning by head_yaw is rendered to a 256² MP4 (``render_clip``,
``face_camera``); the tracked mouth corners must land near the rig's own mouth corners projected
with that camera. The videos real users bring are made from its frames with numpy and the bundled
ffmpeg: a phone video stored on its side with a display rotation, a variable frame rate, 4K, two
faces, a face lost mid-take, a head turned into profile. Tests that run mediapipe skip without the
``[track]`` extra, except on CI.
"""

from __future__ import annotations

import gc
import math
import re
import subprocess
import warnings
from fractions import Fraction
from pathlib import Path

import imageio_ffmpeg
import numpy as np
import pytest

from mimetic.capture import video
from mimetic.capture.trajectories import CaptureError
from mimetic.capture.video import N_FACE_POINTS, WORK_SIZE_PX, mediapipe_markers, track_video
from mimetic.engines import make_engine
from mimetic.errors import MimeticWarning, MissingExtraError
from mimetic.fit import detect
from mimetic.fit.detect import MEDIAPIPE_POINTS, N_LANDMARKS
from mimetic.mesh.model import SurfacePoint
from mimetic.render.camera import project
from mimetic.render.renderer import default_renderer
from mimetic.rig.activations import Clip
from mimetic.testing import require_extra, small_rig
from mimetic.view.look import rig_look
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
GAP_FRAMES = 8  # frames without a face between two takes of the face clip
BACKGROUND = 90  # grey level around the face in composed frames
TOL_ROTATED_PX = 5.0  # phone (rotated by metadata) vs upright video, any point (measured: max 2.6 px)
TOL_4K_PX = 12.0  # 4K vs 3 x the 720p points, in 4K px (measured: max 7.2; FaceMesh on whole 4K frames: 7.1)
TOL_4K_MEAN_PX = 2.0  # the same, averaged over a frame's points: a scaling bias (measured: max 1.0 px)
VFR_SLOW_FPS, VFR_FAST_FPS = 10, 30  # the VFR video: grey frames at 10 fps, then the face at 30 fps
VFR_GREY = 10  # grey frames, so the face appears at 1.0 s
PROFILE_YAWS_DEG = (0, 0, 20, 40, 60, 75, 90, 90, 90, 60, 30, 0, 0)  # camera yaw per frame


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


def _ffmpeg(*arguments) -> bytes:
    """Run the bundled ffmpeg quietly; its stdout."""
    command = [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-nostdin", "-loglevel", "error", "-y"]
    return subprocess.run([*command, *map(str, arguments)], capture_output=True, check=True).stdout


def _frames(path, size=(SIZE, SIZE)) -> list[np.ndarray]:
    """The frames (h, w, 3) uint8 of a video of ``size`` = (w, h) (no imageio reader: it leaks pipes)."""
    w, h = size
    raw = _ffmpeg("-i", path, "-f", "rawvideo", "-pix_fmt", "rgb24", "-")
    return list(np.frombuffer(raw, np.uint8).reshape(-1, h, w, 3))


@pytest.fixture(scope="module")
def faces(turning) -> list[np.ndarray]:
    """The rendered clip's frames as decoded: (256, 256, 3) uint8 each."""
    return _frames(turning[0])


def _canvas(width: int, height: int) -> np.ndarray:
    return np.full((height, width, 3), BACKGROUND, np.uint8)


def _image_xy(result, index: int) -> np.ndarray:
    """(f, 2) image pixels (x right, y down) of point ``mediapipe_<index>``."""
    return result.positions[:, index, :2] * [1.0, -1.0]


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
    with pytest.raises(ValueError, match="max_yaw_rad"):
        track_video(path, max_yaw_rad=2.0)


def test_track_video_rejects_a_file_without_a_video_stream(tmp_path):
    sound = tmp_path / "sound.wav"
    _ffmpeg("-f", "lavfi", "-i", "sine=duration=0.2", sound)
    with pytest.raises(CaptureError, match=r"sound\.wav: ffmpeg finds no video stream"):
        track_video(sound)


@pytest.mark.parametrize(
    "side_data",
    [
        "      Display Matrix: rotation of -90.00 degrees",  # ffmpeg >= 7
        "      displaymatrix: rotation of 90.00 degrees",  # ffmpeg 5-6
    ],
)
def test_parse_header_swaps_the_size_of_a_quarter_turned_video(side_data):
    header = "\n".join(
        [
            "Input #0, mov,mp4,m4a,3gp,3g2,mj2, from 'phone.mov':",
            "  Duration: 00:00:02.50, start: 0.000000, bitrate: 9000 kb/s",
            "  Stream #0:0[0x1](und): Audio: aac (LC) (mp4a / 0x6134706D), 48000 Hz, stereo, fltp",
            "  Stream #0:1[0x2](und): Video: hevc (Main) (hvc1 / 0x31637668), yuv420p(tv, bt709), "
            "1920x1080, 8000 kb/s, 29.97 fps, 29.97 tbr, 600 tbn (default)",
            "    Metadata:",
            "      handler_name    : Core Media Video",
            "    Side data:",
            side_data,
            "At least one output file must be specified",
        ]
    )
    stream = video._parse_header(Path("phone.mov"), header)
    assert (stream.index, stream.width, stream.height) == (1, 1920, 1080)
    assert stream.display_size == (1080, 1920) and stream.fps == 29.97 and stream.duration_s == 2.5
    assert video._grid_rate(Path("phone.mov"), stream, None) == Fraction(30000, 1001)
    assert video._work_size(*stream.display_size) == (720, WORK_SIZE_PX)


def test_track_video_turns_a_rotated_phone_video_upright(mediapipe, faces, tmp_path, capfd):
    width, height = SIZE, SIZE + 128  # portrait, as the phone shows it
    upright = []
    for face in faces:
        frame = _canvas(width, height)
        frame[32 : 32 + SIZE] = face
        upright.append(frame)
    write_mp4(upright, tmp_path / "upright.mp4", fps=FPS, size=(width, height))
    stored = [np.ascontiguousarray(np.rot90(frame, k=-1)) for frame in upright]  # landscape, face on its side
    write_mp4(stored, tmp_path / "stored.mp4", fps=FPS, size=(height, width))
    # ffmpeg >= 6 honours -display_rotation (-metadata:s:v rotate=90 is dropped when muxing MP4)
    _ffmpeg("-display_rotation", 90, "-i", tmp_path / "stored.mp4", "-c", "copy", tmp_path / "phone.mp4")

    reference = track_video(tmp_path / "upright.mp4")
    capfd.readouterr()
    phone = track_video(tmp_path / "phone.mp4")
    assert capfd.readouterr().err == ""  # imageio-ffmpeg logged "The frame size for reading … is different"
    assert phone.positions.shape == reference.positions.shape == (N_FRAMES, N_LANDMARKS, 3)
    x, y = phone.positions[..., 0], phone.positions[..., 1]
    assert (x >= 0).all() and (x <= width).all() and (y <= 0).all() and (y >= -height).all()
    p = {k: phone.positions[:, MEDIAPIPE_POINTS[k]] for k in MEDIAPIPE_POINTS}  # (f, 3) each
    assert (p["eye_outer_corner_L"][:, 1] > p["mouth_corner_L"][:, 1] + 20).all()  # upright
    assert (p["mouth_corner_L"][:, 0] > p["mouth_corner_R"][:, 0]).all()  # not mirrored
    error = np.linalg.norm(phone.positions[..., :2] - reference.positions[..., :2], axis=2)  # (f, 478)
    assert error.max() < TOL_ROTATED_PX, f"rotated video off the upright one by up to {error.max():.1f} px"


def test_track_video_places_variable_frame_rate_frames_on_their_timestamps(mediapipe, faces, tmp_path):
    grey = _canvas(SIZE, SIZE)
    write_mp4([grey] * VFR_GREY + faces, tmp_path / "even.mp4", fps=VFR_FAST_FPS, size=(SIZE, SIZE))
    # frame n at n / 10 s while grey, then every 1/30 s: the face appears at exactly 1.0 s
    slow = VFR_FAST_FPS // VFR_SLOW_FPS
    timing = f"if(lt(N,{VFR_GREY}),N*{slow},{VFR_GREY * slow}+N-{VFR_GREY})/({VFR_FAST_FPS}*TB)"
    path = tmp_path / "vfr.mp4"
    _ffmpeg("-i", tmp_path / "even.mp4", "-vf", f"setpts='{timing}'", "-fps_mode", "vfr", "-c:v", "libx264",
            "-preset", "ultrafast", "-crf", "18", path)  # fmt: skip
    appears_s = VFR_GREY / VFR_SLOW_FPS  # 1.0
    duration_s = appears_s + len(faces) / VFR_FAST_FPS  # 1.4

    with pytest.warns(MimeticWarning, match="no face in"):
        average = track_video(path)  # the file's average rate (its header says about 15 fps)
    with pytest.warns(MimeticWarning) as caught:
        fast = track_video(path, fps=VFR_FAST_FPS)
    said = " | ".join(str(w.message) for w in caught)
    assert re.search(r"fps=30 given, but the file says 1\d\.\d+ frames per second", said), said
    assert fast.fps == VFR_FAST_FPS
    for result in (average, fast):
        assert result.positions.shape[1:] == (N_LANDMARKS, 3) and result.positions.dtype == np.float64
        first = np.flatnonzero(result.confidence > 0)[0]
        assert abs(first / result.fps - appears_s) <= 1 / result.fps, f"face at {first / result.fps:.2f} s"
        assert abs(result.duration_s - duration_s) <= 1 / result.fps, f"{result.duration_s:.2f} s long"
        assert np.isnan(result.positions[:first]).all() and np.isfinite(result.positions[first:]).all()


def test_track_video_scales_a_4k_video_down_and_reports_its_own_pixels(
    mediapipe, faces, tmp_path, monkeypatch
):
    frames = []
    for face in faces[::3]:
        frame = _canvas(1280, 720)
        frame[100:612, 500:1012] = face.repeat(2, axis=0).repeat(2, axis=1)  # the face 512 px tall
        frames.append(frame)
    hd = write_mp4(frames, tmp_path / "hd.mp4", fps=FPS, size=(1280, 720))
    uhd = tmp_path / "uhd.mp4"
    _ffmpeg("-i", hd, "-vf", "scale=3840:2160", "-c:v", "libx264", "-preset", "ultrafast", "-crf", "18", uhd)
    seen = []  # the frames' shapes as the face models get them
    score = video.face_detection_score
    monkeypatch.setattr(video, "face_detection_score", lambda frame: seen.append(frame.shape) or score(frame))

    small = track_video(hd)
    large = track_video(uhd)
    assert large.positions.shape == small.positions.shape == (len(frames), N_LANDMARKS, 3)
    assert set(seen) == {(720, 1280, 3)}  # 4K was scaled down to WORK_SIZE_PX by ffmpeg
    assert np.isfinite(large.positions).all() and np.nanmax(large.positions[..., 0]) > 1280
    offset = large.positions[..., :2] - 3 * small.positions[..., :2]  # (f, 478, 2) 4K pixels
    error, bias = (
        np.linalg.norm(offset, axis=2),
        np.linalg.norm(offset.mean(axis=1), axis=1),
    )  # (f, 478), (f,)
    assert error.max() < TOL_4K_PX, f"4K points off 3 x the 720p points by up to {error.max():.1f} px"
    assert bias.max() < TOL_4K_MEAN_PX, f"4K points shifted by {bias.max():.1f} px on average"
    assert np.allclose(large.positions[..., 2], 3 * small.positions[..., 2], atol=TOL_4K_PX)  # z at x's scale


def test_track_video_of_two_faces_tracks_the_largest_and_warns(mediapipe, faces, turning, tmp_path):
    _, expected = turning
    left = 176  # the large face's left edge; a half-size face sits left of it from the first frame
    frames = []
    for k, face in enumerate(faces):
        frame = _canvas(448, SIZE)
        frame[64:192, 16:144] = face[::2, ::2]
        if k >= GREY_FRAMES:  # the large face comes in later: FaceMesh already tracks the small one
            frame[:, left : left + SIZE] = face
        frames.append(frame)
    path = write_mp4(frames, tmp_path / "two.mp4", fps=FPS, size=(448, SIZE))
    with pytest.warns(
        MimeticWarning,
        match=rf"more than one face in {N_FRAMES - GREY_FRAMES} of {N_FRAMES} frames \(frames 3, 4, 5,",
    ):
        result = track_video(path)
    assert np.isfinite(result.positions).all()
    assert (result.positions[:GREY_FRAMES, :, 0] < 144).all()  # alone, the small face is tracked
    corners = np.stack([_image_xy(result, 61), _image_xy(result, 291)], axis=1)[GREY_FRAMES:]  # (f, 2, 2)
    error = np.linalg.norm(corners - (expected[GREY_FRAMES:] + np.array([left, 0])), axis=2)
    assert error.max() < TOL_MOUTH_PX, f"not the large face: mouth corners off by {error.max():.1f} px"


def test_largest_face_counts_overlapping_finds_as_one():
    rng = np.random.default_rng(0)
    unit = rng.uniform(0.0, 1.0, (N_LANDMARKS, 3))  # a face filling a unit box
    big, small = unit * [0.4, 0.4, 1] + [0.5, 0.3, 0], unit * [0.2, 0.2, 1] + [0.1, 0.1, 0]
    twice = unit * [0.38, 0.39, 1] + [0.51, 0.31, 0]  # the big face found again, a little shifted
    faces = np.stack([small, big, twice])
    before = faces.copy()
    chosen, distinct = video._largest(faces, 640, 480)
    assert chosen.shape == (N_LANDMARKS, 3) and np.array_equal(chosen, big) and distinct == 2
    assert video._largest(faces[1:], 640, 480)[1] == 1
    np.testing.assert_array_equal(faces, before)


def test_track_video_recovers_after_the_face_is_lost_mid_take(mediapipe, faces, turning, tmp_path):
    _, expected = turning
    grey = _canvas(SIZE, SIZE)
    path = write_mp4(faces + [grey] * GAP_FRAMES + faces, tmp_path / "gap.mp4", fps=FPS, size=(SIZE, SIZE))
    gap = slice(N_FRAMES, N_FRAMES + GAP_FRAMES)
    total = 2 * N_FRAMES + GAP_FRAMES
    with pytest.warns(
        MimeticWarning, match=rf"no face in {GAP_FRAMES} of {total} frames \(frames 12, 13, 14, 15, 16, …,"
    ):
        result = track_video(path)
    assert result.positions.shape == (2 * N_FRAMES + GAP_FRAMES, N_LANDMARKS, 3)
    assert np.isnan(result.positions[gap]).all() and (result.confidence[gap] == 0).all()
    after = slice(N_FRAMES + GAP_FRAMES, None)
    assert np.isfinite(result.positions[after]).all() and (result.confidence[after] >= MIN_SCORE).all()
    corners = np.stack([_image_xy(result, 61), _image_xy(result, 291)], axis=1)[after]  # (f, 2, 2)
    error = np.linalg.norm(corners - expected, axis=2)
    assert error.max() < TOL_MOUTH_PX, f"mouth corners after the gap off by up to {error.max():.1f} px"


def test_track_video_drops_faces_seen_in_profile(mediapipe, tmp_path):
    rig = small_rig()
    renderer, look = default_renderer(), rig_look(rig)
    frames = [
        renderer.render(rig.mesh, face_camera(rig, yaw_deg=yaw), size=(SIZE, SIZE), look=look)
        for yaw in PROFILE_YAWS_DEG
    ]
    path = write_mp4(frames, tmp_path / "profile.mp4", fps=FPS, size=(SIZE, SIZE))
    yaws = np.radians(PROFILE_YAWS_DEG)
    turned = (yaws > video.MAX_YAW_RAD) & (yaws < math.radians(80))  # FaceMesh still finds a face there
    with pytest.warns(MimeticWarning) as caught:
        result = track_video(path)
    messages = " | ".join(str(w.message) for w in caught)
    assert f"turned more than 50° from the camera in {turned.sum()} of {len(yaws)} frames" in messages
    assert "no face in" in messages  # at 90° FaceMesh finds nothing
    assert result.positions.shape == (len(yaws), N_LANDMARKS, 3)
    front = yaws <= math.radians(40)
    assert np.isfinite(result.positions[front]).all() and (result.confidence[front] >= MIN_SCORE).all()
    assert np.isnan(result.positions[~front]).all() and (result.confidence[~front] == 0).all()


def test_track_video_leaves_no_unclosed_files_or_stray_warnings(mediapipe, turning):
    path, _ = turning
    gc.collect()  # earlier tests' garbage is not this test's
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        track_video(path)  # to the end: ffmpeg exits on its own
        track_video(path, max_frames=2)  # stopped early: ffmpeg is stopped
        gc.collect()
    assert not [w for w in caught if issubclass(w.category, ResourceWarning)], [
        str(w.message) for w in caught
    ]
    assert not caught, [str(w.message) for w in caught]  # one face, all frames: nothing to say


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
