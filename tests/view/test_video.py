"""Tests for mimetic.view.video: MP4 files with the right frames, size and audio, written atomically."""

from __future__ import annotations

import math
import subprocess
import warnings
import wave

import imageio_ffmpeg
import numpy as np
import pytest

from mimetic.animate.keyframes import from_expressions
from mimetic.engines import bake, evaluate_basis, make_engine
from mimetic.errors import MimeticWarning
from mimetic.rig.activations import Clip
from mimetic.testing import small_rig
from mimetic.view.video import VideoError, render_clip, write_mp4


def _streams(path) -> str:
    """ffmpeg's description of a file's streams (there is no ffprobe in the wheel)."""
    run = subprocess.run(
        [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-i", str(path)], capture_output=True
    )
    return run.stderr.decode()


def _tone(path, seconds: float, rate: int = 16_000) -> None:
    t = np.arange(int(seconds * rate)) / rate
    samples = (0.3 * np.sin(2 * np.pi * 220 * t) * 32767).astype("<i2")
    with wave.open(str(path), "wb") as out:
        out.setnchannels(1)
        out.setsampwidth(2)
        out.setframerate(rate)
        out.writeframes(samples.tobytes())


def _frames(path) -> list[np.ndarray]:
    reader = imageio_ffmpeg.read_frames(str(path))
    w, h = next(reader)["size"]
    return [np.frombuffer(f, np.uint8).reshape(h, w, 3) for f in reader]


@pytest.fixture(scope="module")
def clip() -> Clip:
    rig = small_rig()
    keys = from_expressions(rig, [(0.0, "rest"), (0.4, "joy"), (0.8, "surprise"), (1.2, "rest")])
    return keys.sample(25, channels=rig)


def test_render_clip_writes_h264_with_every_frame(clip: Clip, tmp_path) -> None:
    out = render_clip(small_rig(), clip, tmp_path / "clip.mp4", size=128)
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(out))
    assert frames == clip.n_frames == 31
    assert seconds == pytest.approx(clip.n_frames / clip.fps, abs=0.05)
    info = _streams(out)
    assert "h264" in info and "128x128" in info and "yuv420p" in info


def test_frames_show_the_motion(clip: Clip, tmp_path) -> None:
    """The rest frame and the joy frame differ around the mouth; two rest frames do not."""
    out = render_clip(small_rig(), clip, tmp_path / "clip.mp4", size=128)
    reader = imageio_ffmpeg.read_frames(str(out))
    meta = next(reader)
    w, h = meta["size"]
    frames = [np.frombuffer(f, np.uint8).reshape(h, w, 3).astype(float) for f in reader]
    rest, joy, end = frames[0], frames[10], frames[-1]
    assert np.abs(joy - rest).mean() > 2 * np.abs(end - rest).mean() + 1.0  # end ≈ rest up to coding noise


def test_sizes_are_rounded_to_macro_blocks_and_checked(clip: Clip, tmp_path) -> None:
    out = render_clip(small_rig(), clip, tmp_path / "odd.mp4", size=100)
    assert "112x112" in _streams(out)
    with pytest.raises(VideoError, match="outside"):
        render_clip(small_rig(), clip, tmp_path / "x.mp4", size=32)


def test_audio_shorter_than_the_clip_is_muxed_and_the_video_keeps_every_frame(clip: Clip, tmp_path) -> None:
    tone = tmp_path / "tone.wav"
    _tone(tone, 0.6)
    with warnings.catch_warnings():
        warnings.simplefilter("error", MimeticWarning)  # nothing to warn about
        out = render_clip(small_rig(), clip, tmp_path / "talk.mp4", size=64, audio=tone)
    assert "Audio: aac" in _streams(out)
    count, _ = imageio_ffmpeg.count_frames_and_secs(str(out))
    assert count == len(clip.values)  # the animation is not cut to the sound


def test_audio_longer_than_the_clip_holds_the_last_frame_and_says_so(clip: Clip, tmp_path) -> None:
    tone = tmp_path / "tone.wav"
    _tone(tone, 2.0)
    with pytest.warns(MimeticWarning, match=r"audio lasts 2\.00 s .* last frame is held"):
        out = render_clip(small_rig(), clip, tmp_path / "talk.mp4", size=64, audio=tone)
    count, _ = imageio_ffmpeg.count_frames_and_secs(str(out))
    assert count == math.ceil(2.0 * clip.fps)  # the sound is not cut
    frames = _frames(out)
    assert np.abs(frames[-1].astype(int) - frames[len(clip.values) - 1]).mean() < 1.0  # the held frame


def test_audio_that_is_not_sound_is_refused_and_nothing_is_written(clip: Clip, tmp_path) -> None:
    fake = tmp_path / "notes.wav"
    fake.write_text("not a sound file")
    with pytest.raises(VideoError, match="no audio stream"):
        render_clip(small_rig(), clip, tmp_path / "talk.mp4", size=64, audio=fake)
    assert not (tmp_path / "talk.mp4").exists()


def test_missing_audio_and_bad_frames_leave_a_good_file(tmp_path) -> None:
    target = tmp_path / "keep.mp4"
    target.write_bytes(b"an old good video")
    with pytest.raises(VideoError, match="no such file"):
        write_mp4([], target, fps=25, size=(64, 64), audio=tmp_path / "none.wav")
    frames = [np.zeros((64, 64, 3), np.uint8), np.zeros((32, 32, 3), np.uint8)]  # the second is wrong
    with pytest.raises(VideoError, match="frame 1"):
        write_mp4(frames, target, fps=25, size=(64, 64))
    assert target.read_bytes() == b"an old good video"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.mp4"]  # no temporary file left behind


class _Recorder:
    """A renderer that keeps the vertices of every mesh it is asked to draw (and draws grey)."""

    def __init__(self) -> None:
        self.vertices: list[np.ndarray] = []

    def render(self, mesh, camera, *, size, look=None):
        self.vertices.append(mesh.vertices.copy())
        return np.full((size[1], size[0], 3), 128, np.uint8)


def test_render_clip_poses_frames_by_the_basis_in_float32(clip: Clip, tmp_path) -> None:
    """With a basis, each frame is ``evaluate_basis`` in float32 (the path the renderer draws)."""
    rig = small_rig()
    basis = bake(make_engine(rig, "wire"), correctives=0, samples=1).basis
    recorder = _Recorder()
    render_clip(rig, clip, tmp_path / "clip.mp4", basis=basis, size=64, renderer=recorder)
    values = clip.select(basis.channels).values  # (f, c)
    assert len(recorder.vertices) == clip.n_frames
    for drawn, pose in zip(recorder.vertices, values, strict=True):
        np.testing.assert_array_equal(drawn, evaluate_basis(basis, pose, dtype=np.float32))
    exact = evaluate_basis(basis, values[10])
    assert 0 < np.abs(recorder.vertices[10] - exact).max() < 1e-5 * rig.scale  # float32, not float64
