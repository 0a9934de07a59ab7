"""Face landmarks tracked through a video with MediaPipe FaceMesh, and where they sit on a rig.

``track_video(path)`` decodes a video with the ffmpeg binary of ``imageio-ffmpeg`` (run directly:
upright by the video's display rotation, on a constant frame-rate grid by the frames' timestamps,
scaled down to ``WORK_SIZE_PX`` when larger) and runs MediaPipe FaceMesh in video mode
(``mimetic.fit.detect.video_face_mesh``) on every frame, each frame gated by the FaceDetection
short-range score as ``mimetic.fit.detect.detect_face`` gates one image. The result is a
``Trajectories`` of the 478 FaceMesh points ``mediapipe_0`` … ``mediapipe_477`` (468 face points,
then 2 x 5 iris points), d = 3, in pixels of the video's frame as a player shows it:

* x = FaceMesh's x · width: pixels right of the image's left edge;
* y = -(FaceMesh's y · height): the image's top edge at 0, the rest of the image below it
  (y ≤ 0), so +Y is up as everywhere in mimetic;
* z = -(FaceMesh's z · width): depth at the scale of x (MediaPipe gives z in units of the image
  width, smaller toward the camera, about 0 at the head's centre), so +Z points toward the
  viewer. The three axes are right-handed.

``mediapipe_markers(rig)`` puts the 468 face points on the rig's neutral head, as
``mimetic.fit.autolandmarks`` finds its landmarks (renders, FaceMesh, ray casting, a vote
across views), so tracked points can be matched with the rig's surface.

Both need the optional extra ``mimetic[track]`` (mediapipe), imported on first use.

Over 600 lines because decoding, tracking and placing the landmarks on the rig are one chain that
shares the frames' timing and size.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import re
import stat
import subprocess
import tempfile
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

import imageio_ffmpeg
import numpy as np

from mimetic.capture.trajectories import CaptureError, Trajectories
from mimetic.errors import LandmarkError, MimeticWarning
from mimetic.fit.autolandmarks import lift_mediapipe_points
from mimetic.fit.detect import N_LANDMARKS, face_detection_score, video_face_mesh
from mimetic.mesh.closest import closest_points
from mimetic.mesh.model import Mesh, SurfacePoint
from mimetic.render.renderer import Renderer
from mimetic.rig.model import Rig, coerce_surface_point

log = logging.getLogger(__name__)

__all__ = [
    "MEDIAPIPE_NAMES",
    "N_FACE_POINTS",
    "face_landmarks",
    "mediapipe_markers",
    "track_video",
    "video_frames",
]

N_FACE_POINTS = 468
"""FaceMesh points on the face surface (0..467); 468..477 are the irises, inside the eyes."""
MEDIAPIPE_NAMES = tuple(f"mediapipe_{k}" for k in range(N_LANDMARKS))
"""Names of the 478 tracked points, in FaceMesh's order."""
FPS_TOLERANCE = 0.01
"""A given ``fps`` this far (relative) above the file's own rate is warned about: frames repeat."""
SHOW_FRAMES = 5
"""Frame numbers listed in a warning about frames (no face, a turned face, several faces)."""
WORK_SIZE_PX = 1280
"""Long side, in pixels, of the frames the face models see: ffmpeg scales a larger video down to it
while decoding (a 3840 x 2160 video to 1280 x 720), and the points are scaled back to the video's
own pixels. FaceMesh crops the face and resizes it to 192 x 192 anyway, so this loses nothing
while the face is at least ~200 px tall in the smaller frame."""
MAX_FACES = 2
"""Faces FaceMesh looks for in each frame; the largest is tracked and the others are counted."""
SAME_FACE_IOU = 0.5
"""Two FaceMesh faces whose landmark boxes overlap more than this (intersection over union) are
one face found twice, not two faces."""
MAX_YAW_RAD = math.radians(50.0)
"""A face turned further than this from the camera (left or right) is taken as seen in profile:
its far half is hidden and FaceMesh guesses it, so the frame gets NaN points and confidence 0.
On renders of the small rig FaceMesh's angle (``_yaw_rad``) follows the true one within 3° up to
60°, then stays at 57-64° while the head turns on to 75°; from 80° FaceMesh finds no face, though
FaceDetection still scores it about 0.7."""
PROBE_TIMEOUT_S = 120.0
"""Time ffmpeg may take to read a file's header before the file is reported as unreadable."""
_NTSC_BASES = (24, 30, 48, 60, 120, 240)
"""Rates ffmpeg prints rounded (29.97 for 30000/1001): snapped back to n·1000/1001."""


def _last_line(text: str) -> str:
    """The last non-empty line of ffmpeg's messages (its reason comes last), "" when there is none."""
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return lines[-1] if lines else ""


@dataclass(frozen=True, slots=True)
class _Stream:
    """What ffmpeg says of a file's first video stream (``ffmpeg -i``'s header).

    ``width`` and ``height`` are the stored (coded) frame's; ``rotation_deg`` the display
    rotation (0 when none); ``fps`` the average frame rate and ``duration_s`` the container's
    duration, each 0.0 when the header gives none.
    """

    index: int  # ffmpeg's stream number in the file, for -map 0:index
    width: int
    height: int
    rotation_deg: float
    fps: float
    duration_s: float

    @property
    def display_size(self) -> tuple[int, int]:
        """(width, height) of the frame as a player shows it: swapped by a quarter-turn rotation.

        ffmpeg turns the frame by multiples of 90° with transpose (within 1°) and by any other
        angle inside the same frame size; a mirror does not change the size.
        """
        turn = self.rotation_deg % 180.0
        return (self.height, self.width) if abs(turn - 90.0) < 1.0 else (self.width, self.height)


_STREAM = re.compile(r"^\s*Stream #0:(\d+)\S*: (\w+):(.*)$")
_SIZE = re.compile(r"(?:^|[ ,])(\d+)x(\d+)(?=[ ,\[]|$)")
_FPS = re.compile(r"(\d+(?:\.\d+)?)(k?) fps\b")
_ROTATION = re.compile(r"display ?matrix: rotation of (-?\d+(?:\.\d+)?) degrees", re.IGNORECASE)
_DURATION = re.compile(r"Duration: (\d+):(\d\d):(\d\d(?:\.\d+)?)")


def _parse_header(path: Path, text: str) -> _Stream:
    """The first video stream (not a cover picture) of ``ffmpeg -i``'s header ``text``."""
    if "Input #0" not in text:
        raise CaptureError(
            f"{path}: ffmpeg cannot read a video from it ({_last_line(text) or 'no header'}); check that "
            "the file is a complete video (MP4, MOV, AVI, MKV, WebM …) that plays in a video player"
        )
    blocks: list[tuple[int, str, list[str]]] = []  # (index, kind, [stream line, its metadata lines…])
    current: list[str] | None = None
    for line in text.splitlines():
        found = _STREAM.match(line)
        if found:
            current = [found[3]]
            blocks.append((int(found[1]), found[2], current))
        elif current is not None and line.startswith("    "):  # the stream's metadata and side data
            current.append(line)
        else:
            current = None
    video = [(i, lines) for i, kind, lines in blocks if kind == "Video" and "(attached pic)" not in lines[0]]
    if not video:
        raise CaptureError(
            f"{path}: ffmpeg finds no video stream in it (a sound or picture file?); pass a video"
        )
    index, lines = video[0]
    size, fps = _SIZE.search(lines[0]), _FPS.search(lines[0])
    width, height = (int(n) for n in size.groups()) if size else (0, 0)
    if width < 1 or height < 1:
        raise CaptureError(f"{path}: ffmpeg reports a frame size of {width}×{height}; is it a video?")
    rotation = _ROTATION.search("\n".join(lines[1:]))
    duration = _DURATION.search(text)
    hours, minutes, seconds = duration.groups() if duration else (0, 0, 0)
    return _Stream(
        index=index,
        width=width,
        height=height,
        rotation_deg=float(rotation[1]) if rotation else 0.0,
        fps=float(fps[1]) * (1000.0 if fps[2] else 1.0) if fps else 0.0,
        duration_s=int(hours) * 3600 + int(minutes) * 60 + float(seconds),
    )


def _input(path: Path) -> list[str]:
    """ffmpeg's input arguments for ``path``: a file, or a camera device (``/dev/video0``: Video4Linux)."""
    return ["-f", "v4l2", "-i", str(path)] if _is_device(path) else ["-i", f"file:{path}"]


def _is_device(path: Path) -> bool:
    """``path`` is a character device, as a camera (``/dev/video0``) is."""
    try:
        return stat.S_ISCHR(os.stat(path).st_mode)
    except OSError:
        return False


def _probe(path: Path) -> _Stream:
    """``_Stream`` of the video at ``path``, from the header ``ffmpeg -i`` prints (it needs no ffprobe)."""
    command = [imageio_ffmpeg.get_ffmpeg_exe(), "-hide_banner", "-nostdin", *_input(path)]
    try:
        run = subprocess.run(command, stdin=subprocess.DEVNULL, capture_output=True, timeout=PROBE_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        raise CaptureError(
            f"{path}: ffmpeg did not read the file's header within {PROBE_TIMEOUT_S:g} s; copy the file "
            "to a local disk and try again"
        ) from None
    return _parse_header(path, run.stderr.decode(errors="replace"))


def _grid_rate(path: Path, stream: _Stream, fps: float | None) -> Fraction:
    """The frame rate of the result: ``fps`` when given, else the file's average rate.

    A rate ffmpeg prints rounded (29.97) is snapped to its exact NTSC value (30000/1001). A given
    ``fps`` above the file's own repeats frames, which is warned about.
    """
    stored = stream.fps
    if fps is None:
        if not (math.isfinite(stored) and stored > 0):
            raise CaptureError(f"{path}: the file gives no frame rate; pass it, e.g. fps=30")
        for base in _NTSC_BASES:
            if abs(stored - base * 1000 / 1001) < 0.006:
                return Fraction(base * 1000, 1001)
        return Fraction(stored).limit_denominator(1001)
    if stored > 0 and fps > stored * (1 + FPS_TOLERANCE):
        warnings.warn(
            f"{path}: fps={fps:g} given, but the file says {stored:g} frames per second; frames are "
            f"taken at {fps:g} fps by their timestamps, so some repeat (pass fps={stored:g} or less "
            "to track each frame once)",
            MimeticWarning,
            stacklevel=3,
        )
    return Fraction(fps).limit_denominator(1_000_000)


def _work_size(width: int, height: int) -> tuple[int, int]:
    """(w, h) of the frames the face models see: (width, height) scaled to a long side of at most
    ``WORK_SIZE_PX``, keeping the aspect ratio."""
    scale = min(1.0, WORK_SIZE_PX / max(width, height))
    return max(1, round(width * scale)), max(1, round(height * scale))


@contextlib.contextmanager
def _decoded(
    path: Path, stream: _Stream, rate: Fraction, size: tuple[int, int], max_frames: int | None
) -> Iterator[Iterator[np.ndarray]]:
    """The frames of ``path`` on a constant ``rate`` grid at ``size``, as read-only (h, w, 3) uint8 RGB.

    One ffmpeg process decodes the stream, turns it upright (ffmpeg's autorotation, from the
    display matrix), places its frames on their timestamps at ``rate`` frames per second (the
    ``fps`` filter repeats or drops frames: frame k shows the video at time k / rate), scales them
    to ``size`` = (w, h) with area averaging and pipes them as raw RGB. On exit the process is
    stopped and waited for and its pipes are closed, however the loop ended. ffmpeg failing
    part-way (a damaged stream) is a ``CaptureError`` naming ``path``.
    """
    width, height = size
    filters = f"fps={rate.numerator}/{rate.denominator}"
    if size != stream.display_size:
        filters += f",scale={width}:{height}:flags=area"
    command = [
        imageio_ffmpeg.get_ffmpeg_exe(),
        "-hide_banner", "-nostdin", "-loglevel", "error",
        *_input(path),
        "-map", f"0:{stream.index}", "-vf", filters,
        *(["-frames:v", str(max_frames)] if max_frames is not None else []),
        "-f", "rawvideo", "-pix_fmt", "rgb24", "pipe:1",
    ]  # fmt: skip
    log.debug("decoding: %s", " ".join(command))
    frame_bytes = width * height * 3
    with tempfile.TemporaryFile() as messages:  # ffmpeg's stderr: a file never blocks ffmpeg
        process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=messages)

        def failed(reason: str) -> CaptureError:
            messages.seek(0)
            said = _last_line(messages.read().decode(errors="replace"))
            return CaptureError(
                f"{path}: ffmpeg stopped decoding the video ({said or reason}); the file may be damaged "
                "or cut short. Re-encode it (e.g. ffmpeg -i in.mp4 out.mp4) or pass max_frames to stop "
                "earlier."
            )

        def frames() -> Iterator[np.ndarray]:
            while raw := process.stdout.read(frame_bytes):
                if len(raw) < frame_bytes:
                    raise failed(f"the last frame has {len(raw)} of {frame_bytes} bytes")
                yield np.frombuffer(raw, np.uint8).reshape(height, width, 3)
            if process.wait() != 0:
                raise failed(f"exit status {process.returncode}")

        try:
            yield frames()
        finally:
            process.stdout.close()
            if process.poll() is None:  # the caller stopped early: ffmpeg may be blocked writing
                process.terminate()
            try:
                process.wait(timeout=10)
            except subprocess.TimeoutExpired:  # pragma: no cover - ffmpeg ignoring SIGTERM
                process.kill()
                process.wait()


def _expected_frames(stream: _Stream, rate: Fraction, max_frames: int | None) -> int:
    """The frame count the header implies (duration x rate), capped by ``max_frames``; 0 if unknown."""
    expected = round(stream.duration_s * rate) if stream.duration_s > 0 else 0
    return expected if max_frames is None else min(expected, max_frames)


def _to_pixels(normalised: np.ndarray, width: int, height: int) -> np.ndarray:
    """FaceMesh's normalised landmarks (478, 3) as (478, 3) pixels, right-handed, +Y up, +Z toward the viewer.

    x = x_n · width, y = -y_n · height, z = -z_n · width (FaceMesh's z is in units of the width
    and grows away from the camera).
    """
    return normalised * np.array([width, -height, -width], dtype=np.float64)


def _boxes(faces: np.ndarray, width: int, height: int) -> np.ndarray:
    """Pixel bounding boxes (k, 4) (x0, y0, x1, y1) of FaceMesh faces (k, 478, 3) normalised."""
    xy = faces[..., :2] * (width, height)  # (k, 478, 2)
    return np.concatenate([xy.min(axis=1), xy.max(axis=1)], axis=1)


def _largest(faces: np.ndarray, width: int, height: int) -> tuple[np.ndarray, int]:
    """The face (478, 3) of ``faces`` (k >= 1, 478, 3) with the largest landmark box, and how many
    distinct faces there are (boxes overlapping by more than ``SAME_FACE_IOU`` are one face)."""
    boxes = _boxes(faces, width, height)  # (k, 4) pixels
    areas = np.prod(boxes[:, 2:] - boxes[:, :2], axis=1)  # (k,)
    order = np.argsort(-areas)
    distinct: list[int] = []
    for i in order:
        lo = np.maximum(boxes[i, :2], boxes[distinct, :2])  # (d, 2)
        hi = np.minimum(boxes[i, 2:], boxes[distinct, 2:])
        overlap = np.prod(np.clip(hi - lo, 0.0, None), axis=1)  # (d,)
        if not (overlap > SAME_FACE_IOU * (areas[i] + areas[distinct] - overlap)).any():
            distinct.append(int(i))
    return faces[order[0]], len(distinct)


_SIDE_PAIRS = ((33, 263), (133, 362), (61, 291), (234, 454))
"""FaceMesh points on the face's right and left: eye outer and inner corners, mouth corners, cheeks."""


def _yaw_rad(face: np.ndarray, width: int, height: int) -> float:
    """How far FaceMesh's face (478, 3), normalised in a ``width`` x ``height`` image, is turned
    from the camera, in radians.

    The angle between the face's right-to-left direction (summed over ``_SIDE_PAIRS``, in pixels)
    and the image plane: 0 facing the camera, whatever the head's tilt in the picture, π/2 in
    profile. FaceMesh's own estimate tops out near 1.1 rad (about 63°) on a face turned further.
    """
    right, left = zip(*_SIDE_PAIRS, strict=True)
    across = (face[list(left)] - face[list(right)]).sum(axis=0) * (width, height, width)  # (3,) px
    return math.atan2(abs(across[2]), math.hypot(across[0], across[1]))


@contextlib.contextmanager
def video_frames(
    source: str | os.PathLike[str], *, fps: float | None = None, max_frames: int | None = None
) -> Iterator[tuple[Iterator[np.ndarray], float, tuple[int, int]]]:
    """A video file's frames as a player shows them, or a camera's (a Video4Linux device such as
    ``/dev/video0``, read with ffmpeg's ``v4l2`` input; not tested here, where there is no camera),
    for live capture: yields (the frames, read-only (h, w, 3) uint8 RGB at most ``WORK_SIZE_PX`` on
    their long side, on a constant grid; their frame rate; their (w, h)). The frames come as ffmpeg
    decodes them (not read ahead), so a consumer slower than the video sees each one late, as from a
    camera.

    Raises
    ------
    CaptureError
        The file is missing or not a readable video, or gives no frame rate (pass ``fps``).
    """
    path = Path(source)
    if not (path.is_file() or _is_device(path)):
        raise CaptureError(f"{path}: no such video file or camera device")
    stream = _probe(path)
    work = _work_size(*stream.display_size)
    rate = _grid_rate(path, stream, fps)
    with _decoded(path, stream, rate, work, max_frames) as frames:
        yield frames, float(rate), work


@contextlib.contextmanager
def face_landmarks(
    *, max_yaw_rad: float = MAX_YAW_RAD
) -> Iterator[Callable[[np.ndarray], np.ndarray | None]]:
    """FaceMesh in video mode for live capture: yields ``track(image)`` → the largest face's 478
    landmarks as (478, 2) pixels of ``image`` (x right, y down), or None when there is no face or it
    is turned further than ``max_yaw_rad`` (see ``track_video``; no FaceDetection gate, which would
    cost a third of the frame)."""
    with video_face_mesh(max_faces=MAX_FACES) as mesh:

        def track(image: np.ndarray) -> np.ndarray | None:
            height, width = image.shape[:2]
            faces = mesh(image)
            if not len(faces):
                return None
            face, _ = _largest(faces, width, height)
            if _yaw_rad(face, width, height) > max_yaw_rad:
                return None
            return face[:, :2] * (width, height)

        yield track


def _frame_list(frames: Sequence[int]) -> str:
    """'0, 1, 2' or '0, 1, 2, 3, 4, …': the first ``SHOW_FRAMES`` of ``frames``."""
    return ", ".join(str(k) for k in frames[:SHOW_FRAMES]) + (", …" if len(frames) > SHOW_FRAMES else "")


def track_video(
    path: str | os.PathLike[str],
    *,
    fps: float | None = None,
    max_frames: int | None = None,
    min_score: float = 0.5,
    max_yaw_rad: float = MAX_YAW_RAD,
    progress: Callable[[int, int], None] | None = None,
) -> Trajectories:
    """Track one face through a video with MediaPipe FaceMesh: 478 points per frame, in pixels.

    1. ffmpeg (``imageio_ffmpeg.get_ffmpeg_exe``) reads the file's header: the video stream, its
       stored size, display rotation, average frame rate and duration.
    2. One ffmpeg process decodes the video as a player shows it: turned upright by its display
       rotation (a phone video stored landscape but shown portrait comes out portrait), placed on
       a constant grid of ``fps`` frames per second by the frames' timestamps (a variable-frame-rate
       phone video's frame k is the picture at time k / fps; frames are repeated or dropped to
       fill the grid) and scaled down to a long side of ``WORK_SIZE_PX`` (1280) pixels when
       larger, so a 4K video costs little more than 720p.
    3. Each frame is scored by FaceDetection's short-range model (``face_detection_score``); when
       the score reaches ``min_score`` FaceMesh (video mode: it tracks faces from frame to frame,
       ``video_face_mesh``) gives the landmarks of up to ``MAX_FACES`` faces, and the face with the
       largest landmark box is kept.
    4. A frame scoring less, or in which FaceMesh finds nothing, has no face: NaN points and
       confidence 0. So has a frame whose face is turned more than ``max_yaw_rad`` from the camera
       (FaceMesh's own estimate, from the depth of its left and right points): in profile, the far
       half of the face is hidden and FaceMesh's points for it are guesses, so they are dropped
       rather than passed on with a confidence they do not deserve.
    5. The points are scaled to the pixels of the video as shown (rotated, full size).

    FaceDetection runs on every frame, so each frame's confidence is its own score and a face that
    leaves the picture is not tracked onto the background. Measured on two CPU cores (150-frame
    H.264 clips, whole call): about 12 ms a frame at 1280 x 720 and 18 ms at 3840 x 2160, the
    difference being ffmpeg decoding 4K; 4K frames decoded whole and given to FaceMesh took
    27-33 ms.

    Parameters
    ----------
    path : path
        A video file ffmpeg reads (MP4, MOV, AVI, MKV, WebM …).
    fps : float, optional
        Frames per second of the result; by default the file's average rate (for a constant rate
        video, its own; 29.97 is taken as 30000/1001). Frames are taken by their timestamps at this
        rate, so a lower rate skips frames (faster) and a rate more than 1 % above the file's
        repeats some, with a ``MimeticWarning``.
    max_frames : int, optional
        Track only the first ``max_frames`` frames (of the ``fps`` grid).
    min_score : float
        The FaceDetection score in [0, 1] below which a frame has no face.
    max_yaw_rad : float
        The most a face may be turned from the camera, in radians in (0, π/2]; beyond it a frame's
        points are NaN (step 4). The default ``MAX_YAW_RAD`` is 50°; FaceMesh itself finds no face
        beyond about 80° and reports at most about 63°, so π/2 keeps every face it finds.
    progress : callable(done, total), optional
        Called after each frame. ``total`` is the frame count the file's header implies (capped
        by ``max_frames``), raised to ``done`` if the file holds more; the last call is
        ``(n, n)``.

    Returns
    -------
    Trajectories
        ``names`` ``mediapipe_0`` … ``mediapipe_477`` (FaceMesh's order); ``positions``
        (f, 478, 3) float64 in pixels of the frame as a player shows it (rotated upright, at the
        video's full size): x right from the image's left edge (0 ≤ x ≤ width), y up from its top
        edge (so -height ≤ y ≤ 0 in the picture), z toward the viewer at the scale of x, NaN in
        frames without a usable face; ``fps`` the grid's rate, frame k at time k / fps from the
        first frame; ``units`` "px"; ``confidence`` (f,) the FaceDetection score, 0 in frames
        without a usable face; ``source`` the path.

    Raises
    ------
    CaptureError
        The file is missing or not a readable video, holds no frames, gives no frame rate (pass
        ``fps``), or shows no usable face in any frame.
    MissingExtraError
        mediapipe is not installed (``pip install 'mimetic[track]'``).
    ValueError
        ``max_frames`` < 1, ``min_score`` outside [0, 1] or ``max_yaw_rad`` outside (0, π/2].

    Warns
    -----
    MimeticWarning
        Some frames have no face, or show the face turned past ``max_yaw_rad``, or show more than
        one face (each: how many, and the first few frame numbers); or ``fps`` is above the file's.
    """
    path = Path(path)
    if fps is not None and not (math.isfinite(fps) and fps > 0):
        raise CaptureError(f"fps={fps} must be a positive number of frames per second, e.g. 30")
    if max_frames is not None and (int(max_frames) != max_frames or max_frames < 1):
        raise ValueError(f"max_frames must be a whole number >= 1; got {max_frames!r}")
    if not 0.0 <= min_score <= 1.0:
        raise ValueError(f"min_score={min_score} must be in [0, 1]")
    if not 0.0 < max_yaw_rad <= math.pi / 2:
        raise ValueError(f"max_yaw_rad={max_yaw_rad} must be in (0, π/2] radians")
    if not path.is_file():
        raise CaptureError(f"{path}: no such video file")
    # 1. the header
    stream = _probe(path)
    width, height = stream.display_size  # the frame as shown: what the points are in
    work = _work_size(width, height)  # what the models see
    rate = _grid_rate(path, stream, fps)
    expected = _expected_frames(stream, rate, max_frames)
    log.debug(
        "%s: stream %d, %d×%d stored, rotation %g°, %g fps, %.2f s; tracked at %d×%d, %s fps",
        path, stream.index, stream.width, stream.height, stream.rotation_deg, stream.fps,
        stream.duration_s, *work, rate,
    )  # fmt: skip
    positions, scores = [], []  # (478, 3) and the score per frame; None / 0.0 without a usable face
    turned, crowded = [], []  # frames whose face is in profile; frames with more than one face
    start = time.perf_counter()
    # 2.-3. decode and track
    with (
        _decoded(path, stream, rate, work, max_frames) as frames,
        video_face_mesh(max_faces=MAX_FACES) as track,
    ):
        for done, frame in enumerate(frames, start=1):
            score = face_detection_score(frame)
            faces = track(frame) if score >= min_score else np.empty((0, N_LANDMARKS, 3))  # (k, 478, 3)
            face = None
            if len(faces):
                face, distinct = _largest(faces, *work)
                if distinct > 1:
                    crowded.append(done - 1)
                if _yaw_rad(face, *work) > max_yaw_rad:  # 4. in profile
                    turned.append(done - 1)
                    face = None
            # 5. to the pixels of the video as shown
            positions.append(None if face is None else _to_pixels(face, width, height))
            scores.append(0.0 if face is None else score)
            if progress is not None:
                progress(done, max(expected, done))
            if done == max_frames:
                break
    n = len(positions)
    if n == 0:
        raise CaptureError(f"{path}: the video holds no frames")
    if progress is not None and expected > n:
        progress(n, n)
    elapsed = time.perf_counter() - start
    log.debug("tracked %d frames of %d×%d in %.2f s (%.1f frames/s)", n, width, height, elapsed, n / elapsed)
    turned_set = set(turned)
    missing = [k for k, p in enumerate(positions) if p is None and k not in turned_set]
    if len(missing) + len(turned) == n:
        if not turned:
            raise CaptureError(
                f"no face found in any of the {n} frames of {path}; the video must show one face, large "
                f"and from the front (FaceDetection's short-range model, score >= min_score={min_score:g}). "
                "Crop the video to the face, or lower min_score."
            )
        raise CaptureError(
            f"no usable face in any of the {n} frames of {path}: {len(missing)} show no face and "
            f"{len(turned)} a face turned more than {math.degrees(max_yaw_rad):.0f}° from the camera; "
            "film the face from the front, or raise max_yaw_rad (up to π/2) to keep turned faces."
        )
    if missing:
        warnings.warn(
            f"{path}: no face in {len(missing)} of {n} frames (frames {_frame_list(missing)}, counting "
            "from 0); their points are NaN and their confidence 0",
            MimeticWarning,
            stacklevel=2,
        )
    if turned:
        warnings.warn(
            f"{path}: the face is turned more than {math.degrees(max_yaw_rad):.0f}° from the camera in "
            f"{len(turned)} of {n} frames (frames {_frame_list(turned)}, counting from 0); FaceMesh "
            "guesses the hidden half of a face in profile, so their points are NaN and their confidence 0",
            MimeticWarning,
            stacklevel=2,
        )
    if crowded:
        warnings.warn(
            f"{path}: more than one face in {len(crowded)} of {n} frames (frames {_frame_list(crowded)}, "
            "counting from 0); the largest face is tracked in each. Crop the video to one face if that "
            "is not the one you want.",
            MimeticWarning,
            stacklevel=2,
        )
    nowhere = np.full((N_LANDMARKS, 3), np.nan)
    stacked = np.stack([nowhere if p is None else p for p in positions])  # (f, 478, 3)
    return Trajectories(
        MEDIAPIPE_NAMES,
        stacked,
        float(rate),
        "px",
        np.array(scores),
        str(path),
        tracked=True,
        image_size=(width, height),
    )


def _skin_faces(mesh: Mesh) -> np.ndarray:
    """Indices (k,) of the faces markers may sit on: the "skin" part when the mesh has one, else all."""
    if "skin" in mesh.parts:
        return np.asarray(mesh.parts["skin"], dtype=np.int64)
    return np.arange(mesh.n_faces)


def mediapipe_markers(
    rig_or_mesh: Rig | Mesh,
    *,
    yaws_deg: Sequence[float] = (0.0, -25.0, 25.0),
    size: int = 512,
    renderer: Renderer | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> tuple[tuple[str, ...], tuple[SurfacePoint, ...]]:
    """Where MediaPipe FaceMesh's 468 face points lie on a rig's neutral head.

    The head is rendered from the front and at each of ``yaws_deg``; FaceMesh runs on each
    render, a ray through each landmark hits the surface, and a point is kept when two views
    agree (``mimetic.fit.autolandmarks.lift_mediapipe_points``). When the mesh has a "skin"
    part, each point is then moved to the closest point of the skin: a ray through an eyelid
    point (e.g. 159) may hit the eyeball just below the lid's edge, and a marker must move with
    the lid, not with the gaze. The iris points 468..477 are left out: they are inside the eye.

    Parameters
    ----------
    rig_or_mesh : Rig or Mesh
        A rig (its ``mesh``, at rest) or a head mesh.
    yaws_deg, size, renderer, progress
        As in ``mimetic.fit.autolandmarks.auto_landmarks``: the views' yaw angles in degrees,
        the renders' width and height in pixels, the renderer (the default one when None), and
        a ``progress(done, total)`` callback.

    Returns
    -------
    names : tuple of str, (k,)
        ``mediapipe_<index>`` of the confirmed points, by increasing index (k ≤ 468).
    points : tuple of SurfacePoint, (k,)
        Triangle of ``mesh.faces`` and barycentric weights (3,) of each point; positions are in
        the mesh's units.

    Raises
    ------
    LandmarkError
        No face is found in the renders, or no point is confirmed.
    MissingExtraError
        mediapipe is not installed (``pip install 'mimetic[track]'``).
    """
    mesh = rig_or_mesh.mesh if isinstance(rig_or_mesh, Rig) else rig_or_mesh
    if not isinstance(mesh, Mesh):
        raise TypeError(f"rig_or_mesh must be a Rig or a Mesh; got {type(rig_or_mesh).__name__}")
    indices = np.arange(N_FACE_POINTS)
    positions, _ = lift_mediapipe_points(
        mesh, indices, yaws_deg=yaws_deg, size=size, renderer=renderer, progress=progress
    )
    kept = np.isfinite(positions).all(axis=1)
    if not kept.any():
        raise LandmarkError(
            "no MediaPipe point could be put on the head's surface: the views disagree on all of "
            "them; check that the mesh is a whole head with its face toward an axis"
        )
    allowed = _skin_faces(mesh)
    closest = closest_points(mesh.vertices, mesh.faces[allowed], positions[kept])  # exact on skin hits
    faces = allowed[closest.faces]  # (k,) into mesh.faces
    names = tuple(MEDIAPIPE_NAMES[k] for k in indices[kept])
    points = tuple(
        coerce_surface_point(SurfacePoint(int(f), tuple(b)), name)
        for name, f, b in zip(names, faces, closest.bary, strict=True)
    )
    log.debug(
        "mediapipe markers: %d of %d confirmed, the farthest %.3g %s from the skin",
        len(names),
        N_FACE_POINTS,
        closest.distance.max(),
        mesh.units or "units",
    )
    return names, points
