"""MP4 video of a clip: each frame posed, rendered offscreen and piped to ffmpeg (H.264, AAC).

The ffmpeg binary comes with the ``imageio-ffmpeg`` wheel (libx264 and AAC built in), so nothing
is needed from the system. Frames are posed by the baked basis when one is given (fast), else by
an engine, and rendered by the shared offscreen renderer. The file is written through
``mimetic.atomic.atomic_path``, so a failure never leaves half a video over a good one.
"""

from __future__ import annotations

import math
import os
import re
import subprocess
import tempfile
import warnings
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import numpy as np

from mimetic.atomic import atomic_path
from mimetic.engines import Engine, make_engine
from mimetic.engines.bake import evaluate_rigid
from mimetic.engines.basis import Basis
from mimetic.errors import MimeticError, MimeticWarning, MissingExtraError
from mimetic.render.renderer import Renderer, default_renderer
from mimetic.rig.activations import Clip
from mimetic.rig.model import Rig
from mimetic.view.look import rig_look
from mimetic.view.sheets import face_camera

MIN_SIZE, MAX_SIZE = 64, 2160
CRF = 18  # x264 constant quality: visually lossless for smooth-shaded renders
MACRO_BLOCK = 16  # H.264 sizes are rounded up to multiples of this


class VideoError(MimeticError, ValueError):
    """A video cannot be written as asked (size, fps, audio file, ffmpeg failure)."""


def _ffmpeg():
    try:
        import imageio_ffmpeg
    except ImportError as error:  # pragma: no cover - a core dependency
        raise MissingExtraError(
            f"writing MP4 needs imageio-ffmpeg ({error}); pip install imageio-ffmpeg"
        ) from None
    return imageio_ffmpeg


def write_mp4(
    frames: Iterable[np.ndarray],
    path: str | os.PathLike[str],
    *,
    fps: float,
    size: tuple[int, int],
    audio: str | os.PathLike[str] | None = None,
) -> Path:
    """Encode RGB frames (h, w, 3) uint8 (``size`` = (w, h), multiples of 16) to an H.264 MP4.

    With ``audio`` (a WAV or any file ffmpeg reads), its track is muxed in as AAC in a second pass.
    Nothing is cut: audio longer than the frames holds the last frame until the sound ends (with a
    ``MimeticWarning`` saying by how much), shorter audio leaves the rest of the video silent.
    """
    path = Path(path)
    if audio is not None and not Path(audio).is_file():
        raise VideoError(f"--audio {audio}: no such file")
    width, height = size
    if width % MACRO_BLOCK or height % MACRO_BLOCK:
        raise VideoError(f"video size {width}×{height} must be a multiple of {MACRO_BLOCK} pixels")
    path.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(path, keep_suffix=True) as tmp:
        if audio is None:
            _encode(frames, tmp, fps, (width, height))
        else:
            sound_s = _duration_s(Path(audio))
            with tempfile.TemporaryDirectory(dir=path.parent, prefix=f".{path.stem}.") as scratch:
                silent = Path(scratch) / "video.mp4"
                _encode(_held(frames, fps, sound_s), silent, fps, (width, height))
                _mux(silent, Path(audio), tmp)
    return path


def _duration_s(audio: Path) -> float:
    """Length of the first audio stream of ``audio`` in seconds, as ffmpeg reads it."""
    run = subprocess.run([_ffmpeg().get_ffmpeg_exe(), "-hide_banner", "-i", str(audio)], capture_output=True)
    found = re.search(r"Duration: (\d+):(\d\d):(\d\d(?:\.\d+)?)", run.stderr.decode(errors="replace"))
    if found is None or b"Audio:" not in run.stderr:
        raise VideoError(f"--audio {audio}: ffmpeg finds no audio stream in it (is it a sound file?)")
    hours, minutes, seconds = found.groups()
    return 3600 * int(hours) + 60 * int(minutes) + float(seconds)


def _held(frames: Iterable[np.ndarray], fps: float, seconds: float) -> Iterator[np.ndarray]:
    """``frames``, then the last one again until they last ``seconds`` at ``fps`` (with a warning)."""
    count, last = 0, None
    for frame in frames:
        count, last = count + 1, frame
        yield frame
    missing = math.ceil(seconds * fps - 1e-6) - count
    if missing > 0 and last is not None:
        warnings.warn(
            f"the audio lasts {seconds:.2f} s and the clip {count / fps:.2f} s: the last frame is held "
            f"for {missing / fps:.2f} s so the sound is not cut (lengthen the clip to animate it)",
            MimeticWarning,
            stacklevel=4,
        )
        for _ in range(missing):
            yield last


def _encode(frames: Iterable[np.ndarray], out: Path, fps: float, size: tuple[int, int]) -> None:
    """Pipe the frames to ffmpeg's libx264 into ``out``."""
    width, height = size
    writer = _ffmpeg().write_frames(
        str(out),
        (width, height),
        fps=fps,
        codec="libx264",
        pix_fmt_out="yuv420p",
        quality=None,
        output_params=["-crf", str(CRF), "-preset", "veryfast", "-movflags", "+faststart"],
        macro_block_size=MACRO_BLOCK,
        ffmpeg_log_level="error",
    )
    try:
        writer.send(None)
        for k, frame in enumerate(frames):
            frame = np.asarray(frame)
            if frame.shape != (height, width, 3) or frame.dtype != np.uint8:
                raise VideoError(
                    f"frame {k} is {frame.dtype}{frame.shape}; expected uint8 ({height}, {width}, 3)"
                )
            writer.send(np.ascontiguousarray(frame))
    except MimeticError:
        raise
    except Exception as error:
        raise VideoError(f"ffmpeg could not write {out}: {error}") from error
    finally:
        writer.close()


def _mux(video: Path, audio: Path, out: Path) -> None:
    """Write ``video`` with ``audio`` as an AAC track to ``out`` (both whole)."""
    command = [
        _ffmpeg().get_ffmpeg_exe(), "-loglevel", "error", "-y", "-i", str(video), "-i", str(audio),
        "-map", "0:v:0", "-map", "1:a:0", "-c:v", "copy", "-c:a", "aac",
        "-movflags", "+faststart", str(out),
    ]  # fmt: skip
    run = subprocess.run(command, capture_output=True)
    if run.returncode != 0:
        message = run.stderr.decode(errors="replace").strip().splitlines()
        raise VideoError(f"cannot add the audio {audio}: {message[-1] if message else 'ffmpeg failed'}")


def render_clip(
    rig: Rig,
    clip: Clip,
    path: str | os.PathLike[str],
    *,
    basis: Basis | None = None,
    engine: str | Engine = "wire",
    size: int = 512,
    yaw_deg: float = 0.0,
    audio: str | os.PathLike[str] | None = None,
    renderer: Renderer | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Path:
    """Render ``clip`` on ``rig`` to an MP4 of ``size``² pixels (64..2160) at the clip's fps.

    Each frame's pose comes from ``basis`` when given (``evaluate_rigid`` in float32: the basis, then
    the head's rotation), else from the engine ``engine`` (a name or a prepared engine); an engine
    that simulates (``tissue``) plays the whole clip
    through its dynamics, with inertia and follow-through. The camera frames the rest face
    (``face_camera``), turned by ``yaw_deg``.
    """
    if not MIN_SIZE <= size <= MAX_SIZE:
        raise VideoError(f"video size {size} is outside {MIN_SIZE}..{MAX_SIZE} pixels")
    size = -(-size // MACRO_BLOCK) * MACRO_BLOCK
    values = clip.select(rig.channel_names, {c.name: c.default for c in rig.channels}).values  # (f, c)
    renderer = renderer or default_renderer()
    camera = face_camera(rig, yaw_deg=yaw_deg)
    look = rig_look(rig)  # eyes, lashes and materials as the contact sheets draw them
    prepared = (
        None if basis is not None else (make_engine(rig, engine) if isinstance(engine, str) else engine)
    )
    simulates = hasattr(prepared, "simulate")
    total = 2 * len(values) if simulates else len(values)  # a simulation's frames, then the renders

    def simulating(done: int, _: int) -> None:
        if progress is not None:
            progress(done, total)

    simulated = prepared.simulate(values, clip.fps, progress=simulating) if simulates else None
    done = total - len(values)

    def frames():
        for k, pose in enumerate(values):
            if basis is not None:  # float32: far below a pixel, and what the GL renderer draws in
                vertices = evaluate_rigid(rig, basis, pose, dtype=np.float32)  # the head turns too
            elif simulated is not None:
                vertices = simulated[k]
            else:
                vertices = prepared.deform(pose)
            yield renderer.render(rig.mesh.with_vertices(vertices), camera, size=(size, size), look=look)
            if progress is not None:
                progress(done + k + 1, total)

    return write_mp4(frames(), path, fps=clip.fps, size=(size, size), audio=audio)
