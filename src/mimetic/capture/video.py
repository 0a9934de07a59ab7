"""Face landmarks tracked through a video with MediaPipe FaceMesh, and where they sit on a rig.

``track_video(path)`` decodes a video with the ffmpeg of ``imageio-ffmpeg`` and runs MediaPipe
FaceMesh in video mode (``mimetic.fit.detect.video_face_mesh``) on every frame, each frame gated
by the FaceDetection short-range score as ``mimetic.fit.detect.detect_face`` gates one image.
The result is a ``Trajectories`` of the 478 FaceMesh points ``mediapipe_0`` … ``mediapipe_477``
(468 face points, then 2 x 5 iris points), d = 3, in pixels:

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
"""

from __future__ import annotations

import logging
import math
import os
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from contextlib import closing
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

__all__ = ["MEDIAPIPE_NAMES", "N_FACE_POINTS", "mediapipe_markers", "track_video"]

N_FACE_POINTS = 468
"""FaceMesh points on the face surface (0..467); 468..477 are the irises, inside the eyes."""
MEDIAPIPE_NAMES = tuple(f"mediapipe_{k}" for k in range(N_LANDMARKS))
"""Names of the 478 tracked points, in FaceMesh's order."""
FPS_TOLERANCE = 0.01  # a given fps this far (relative) from the file's own is warned about
SHOW_FRAMES = 5  # frame numbers listed in the warning about frames without a face


def _last_line(error: BaseException) -> str:
    """The last non-empty line of an error's message (ffmpeg's reason comes last)."""
    lines = [line.strip() for line in str(error).splitlines() if line.strip()]
    return lines[-1] if lines else type(error).__name__


def _open(path: Path) -> tuple[dict, Iterator[bytes]]:
    """ffmpeg's metadata of the video at ``path`` and the generator of its RGB24 frames."""
    reader = imageio_ffmpeg.read_frames(str(path), pix_fmt="rgb24")
    try:
        meta = next(reader)
        width, height = (int(n) for n in meta["size"])
    except (OSError, RuntimeError, StopIteration, KeyError, TypeError, ValueError) as error:
        reader.close()
        raise CaptureError(
            f"{path}: ffmpeg cannot read a video from it ({_last_line(error)}); check that the file is a "
            "complete video (MP4, MOV, AVI, MKV, WebM …) that plays in a video player"
        ) from None
    if width < 1 or height < 1:
        reader.close()
        raise CaptureError(f"{path}: ffmpeg reports a frame size of {width}×{height}; is it a video?")
    return meta, reader


def _frames(path: Path, reader: Iterator[bytes], width: int, height: int) -> Iterator[np.ndarray]:
    """The frames of ``reader`` as read-only (height, width, 3) uint8 RGB arrays.

    ffmpeg failing part-way (a damaged stream) is a ``CaptureError`` naming ``path``.
    """
    try:
        for raw in reader:
            yield np.frombuffer(raw, np.uint8).reshape(height, width, 3)
    except RuntimeError as error:
        raise CaptureError(
            f"{path}: ffmpeg stopped decoding the video ({_last_line(error)}); the file may be damaged "
            "or cut short. Re-encode it (e.g. ffmpeg -i in.mp4 out.mp4) or pass max_frames to stop earlier."
        ) from None


def _frame_rate(path: Path, meta: dict, fps: float | None) -> float:
    """``fps`` when given (with a warning when the file says otherwise), else the file's own."""
    stored = float(meta.get("fps") or 0.0)
    if fps is None:
        if not (math.isfinite(stored) and stored > 0):
            raise CaptureError(f"{path}: the file gives no frame rate; pass it, e.g. fps=30")
        return stored
    if stored > 0 and abs(fps - stored) > FPS_TOLERANCE * stored:
        warnings.warn(
            f"{path}: fps={fps:g} given, but the file says {stored:g} frames per second; times follow "
            f"fps={fps:g}",
            MimeticWarning,
            stacklevel=3,
        )
    return float(fps)


def _expected_frames(meta: dict, max_frames: int | None) -> int:
    """The frame count the file's header implies (duration x fps), capped by ``max_frames``; 0 if unknown."""
    duration, stored = float(meta.get("duration") or 0.0), float(meta.get("fps") or 0.0)
    expected = round(duration * stored) if duration > 0 and stored > 0 else 0
    return expected if max_frames is None else min(expected, max_frames)


def _to_pixels(normalised: np.ndarray, width: int, height: int) -> np.ndarray:
    """FaceMesh's normalised landmarks (478, 3) as (478, 3) pixels, right-handed, +Y up, +Z toward the viewer.

    x = x_n · width, y = -y_n · height, z = -z_n · width (FaceMesh's z is in units of the width
    and grows away from the camera).
    """
    return normalised * np.array([width, -height, -width], dtype=np.float64)


def track_video(
    path: str | os.PathLike[str],
    *,
    fps: float | None = None,
    max_frames: int | None = None,
    min_score: float = 0.5,
    progress: Callable[[int, int], None] | None = None,
) -> Trajectories:
    """Track one face through a video with MediaPipe FaceMesh: 478 points per frame, in pixels.

    Each frame is decoded to RGB (``imageio_ffmpeg.read_frames``) and scored by FaceDetection's
    short-range model (``face_detection_score``); when the score reaches ``min_score`` FaceMesh
    (video mode: it tracks the face from frame to frame, ``video_face_mesh``) gives its landmarks.
    A frame scoring less, or in which FaceMesh finds nothing, has no face: NaN points and
    confidence 0. FaceDetection runs on every frame, so each frame's confidence is its own score
    and a face that leaves the picture is not tracked onto the background: it costs about 5 ms a
    frame beside about 9 ms for FaceMesh and 5 ms to decode a 1280 x 720 frame (two CPU cores),
    so about a quarter of the time.

    Parameters
    ----------
    path : path
        A video file ffmpeg reads (MP4, MOV, AVI, MKV, WebM …).
    fps : float, optional
        Frames per second of the result; by default the file's own. A value more than 1 % away
        from the file's is used, with a ``MimeticWarning``.
    max_frames : int, optional
        Track only the first ``max_frames`` frames.
    min_score : float
        The FaceDetection score in [0, 1] below which a frame has no face.
    progress : callable(done, total), optional
        Called after each frame. ``total`` is the frame count the file's header implies (capped
        by ``max_frames``), raised to ``done`` if the file holds more; the last call is
        ``(n, n)``.

    Returns
    -------
    Trajectories
        ``names`` ``mediapipe_0`` … ``mediapipe_477`` (FaceMesh's order); ``positions``
        (f, 478, 3) float64 in pixels: x right from the image's left edge, y up from its top
        edge (so y ≤ 0 in the picture), z toward the viewer at the scale of x, NaN in frames
        without a face; ``units`` "px"; ``confidence`` (f,) the FaceDetection score, 0 in frames
        without a face; ``source`` the path.

    Raises
    ------
    CaptureError
        The file is missing or not a readable video, holds no frames, gives no frame rate (pass
        ``fps``), or shows no face in any frame.
    MissingExtraError
        mediapipe is not installed (``pip install 'mimetic[track]'``).
    ValueError
        ``max_frames`` < 1 or ``min_score`` outside [0, 1].

    Warns
    -----
    MimeticWarning
        Some frames have no face (how many, and the first few frame numbers), or ``fps``
        contradicts the file.
    """
    path = Path(path)
    if fps is not None and not (math.isfinite(fps) and fps > 0):
        raise CaptureError(f"fps={fps} must be a positive number of frames per second, e.g. 30")
    if max_frames is not None and (int(max_frames) != max_frames or max_frames < 1):
        raise ValueError(f"max_frames must be a whole number >= 1; got {max_frames!r}")
    if not 0.0 <= min_score <= 1.0:
        raise ValueError(f"min_score={min_score} must be in [0, 1]")
    if not path.is_file():
        raise CaptureError(f"{path}: no such video file")
    meta, reader = _open(path)
    width, height = (int(n) for n in meta["size"])
    positions, scores = [], []  # (478, 3) and the score per frame; None / 0.0 without a face
    with closing(reader), video_face_mesh() as track:
        rate = _frame_rate(path, meta, fps)
        expected = _expected_frames(meta, max_frames)
        start = time.perf_counter()
        for done, frame in enumerate(_frames(path, reader, width, height), start=1):
            score = face_detection_score(frame)
            normalised = track(frame) if score >= min_score else None
            positions.append(None if normalised is None else _to_pixels(normalised, width, height))
            scores.append(0.0 if normalised is None else score)
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
    missing = [k for k, p in enumerate(positions) if p is None]
    if len(missing) == n:
        raise CaptureError(
            f"no face found in any of the {n} frames of {path}; the video must show one face, large "
            f"and from the front (FaceDetection's short-range model, score >= min_score={min_score:g}). "
            "Crop the video to the face, or lower min_score."
        )
    if len(missing):
        shown = ", ".join(str(k) for k in missing[:SHOW_FRAMES]) + (
            ", …" if len(missing) > SHOW_FRAMES else ""
        )
        warnings.warn(
            f"{path}: no face in {len(missing)} of {n} frames (frames {shown}, counting from 0); "
            "their points are NaN and their confidence 0",
            MimeticWarning,
            stacklevel=2,
        )
    nowhere = np.full((N_LANDMARKS, 3), np.nan)
    stacked = np.stack([nowhere if p is None else p for p in positions])  # (f, 478, 3)
    return Trajectories(MEDIAPIPE_NAMES, stacked, rate, "px", np.array(scores), str(path))


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
