"""2D face landmarks in an image with MediaPipe FaceMesh, gated by MediaPipe FaceDetection.

This module needs the optional extra ``mimetic[track]`` (``mediapipe==0.10.14``); it imports
mediapipe on first use, never at import time. Only the legacy ``mediapipe.solutions`` API is
used, because its models ship in the wheel and run offline.

FaceMesh alone "finds" faces in spheres and blank backgrounds at low confidence, so its
landmarks are trusted only when the short-range FaceDetection model scores the image at or
above ``min_score`` (renders of heads score about 0.8-0.95, non-faces 0.0).

``detect_face`` looks at one image; a video is tracked with ``video_face_mesh`` (FaceMesh in video
mode, one per video) gated per frame by ``face_detection_score``.

``MEDIAPIPE_POINTS`` maps the project's landmark names to FaceMesh indices (eye corners
33/133/362/263, mouth corners 61/291, nose tip 4, menton 152), so
``detection.named(["nose_tip"])`` is comparable with ``head.landmark_positions(["nose_tip"])``
after projection.
"""

from __future__ import annotations

import contextlib
import functools
import logging
import os
import re
import sys
import tempfile
import threading
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from mimetic.errors import LandmarkError, MissingExtraError, install_hint
from mimetic.head.landmarks import MEDIAPIPE as MEDIAPIPE_POINTS

log = logging.getLogger(__name__)

__all__ = [
    "MEDIAPIPE_POINTS",
    "N_LANDMARKS",
    "FaceDetection",
    "MissingExtraError",
    "detect_face",
    "face_detection_score",
    "video_face_mesh",
]

N_LANDMARKS = 478  # FaceMesh with refine_landmarks=True: 468 face points + 2 x 5 iris points

# What mediapipe's C++ side (absl logging, TF Lite) writes to stderr while it builds its graphs
# and loads its models; the environment variables GLOG_minloglevel / TF_CPP_MIN_LOG_LEVEL do not
# reach it (measured with 0.10.14), so these lines are filtered out of a short fd-level capture.
_NOISE = re.compile(
    r"^(INFO: Created TensorFlow Lite XNNPACK delegate"
    r"|WARNING: All log messages before absl::InitializeLog\(\) is called"
    r"|[IW]\d{4} [\d:. ]+\d+ \w+\.cc:\d+\])"
)
_PROTOBUF_WARNING = r"SymbolDatabase\.GetPrototype\(\) is deprecated"


@dataclass(frozen=True, eq=False)
class FaceDetection:
    """The face found in one image, or the evidence that there is none.

    Attributes
    ----------
    score : float
        The best FaceDetection (short-range model) score in the image, 0.0 when it found nothing.
    landmarks : (478, 2) float64, or (0, 2) when ``found`` is False
        FaceMesh landmarks in pixels, x right and y down, the image's top-left corner at (0, 0)
        (the convention of ``mimetic.view.project``). Read-only.
    found : bool
        True when ``score >= min_score`` and FaceMesh returned a face.
    """

    score: float
    landmarks: np.ndarray
    found: bool

    def __post_init__(self) -> None:
        landmarks = np.array(self.landmarks, dtype=np.float64).reshape(-1, 2)
        landmarks.setflags(write=False)
        object.__setattr__(self, "landmarks", landmarks)
        object.__setattr__(self, "score", float(self.score))
        object.__setattr__(self, "found", bool(self.found))

    def named(self, names: Sequence[str] | None = None) -> np.ndarray:
        """Pixel positions (k, 2) float64 of landmarks named as in ``MEDIAPIPE_POINTS`` (all by default)."""
        names = list(MEDIAPIPE_POINTS) if names is None else list(names)
        unknown = [n for n in names if n not in MEDIAPIPE_POINTS]
        if unknown:
            known = ", ".join(MEDIAPIPE_POINTS)
            raise LandmarkError(f"no MediaPipe index for {', '.join(map(repr, unknown))}; known: {known}")
        if not self.found:
            raise LandmarkError(f"no face was found (detection score {self.score:.2f}), so no landmarks")
        return self.landmarks[[MEDIAPIPE_POINTS[n] for n in names]]


class _StderrFilter:
    """Capture file descriptor 2 for a moment; on exit, pass on every line but mediapipe's noise.

    The capture is at the descriptor level because the noise comes from C++. Anything else written
    to stderr meanwhile (by any thread) is re-emitted afterwards, so it is delayed, never lost.
    """

    def __enter__(self) -> _StderrFilter:
        self._file = self._saved = None
        try:
            sys.stderr.flush()
        except (AttributeError, OSError, ValueError):  # no usable sys.stderr
            pass
        try:
            self._saved = os.dup(2)
        except OSError:  # no descriptor 2 (e.g. a daemon): nothing to protect
            return self
        self._file = tempfile.TemporaryFile()
        os.dup2(self._file.fileno(), 2)
        return self

    def __exit__(self, *exc_info) -> None:
        if self._file is None:
            return
        os.dup2(self._saved, 2)
        os.close(self._saved)
        self._file.seek(0)
        text = self._file.read().decode(errors="replace")
        self._file.close()
        kept = []
        for line in text.splitlines(keepends=True):
            if _NOISE.match(line):
                log.debug("mediapipe: %s", line.rstrip())
            else:
                kept.append(line)
        if kept:
            os.write(2, "".join(kept).encode())


def _import_mediapipe():
    """The ``mediapipe`` module; ``MissingExtraError`` naming the extra [track] when it will not import."""
    try:
        import mediapipe as mp
    except ImportError as error:
        raise MissingExtraError(
            f"face tracking needs the optional extra [track] (mediapipe==0.10.14): {install_hint('track')}; "
            f"importing mediapipe failed: {error}"
        ) from error
    return mp


@functools.cache
def _detectors():
    """The process-wide (FaceDetection, FaceMesh, lock) triple, built and warmed up on first use.

    Importing mediapipe takes about 1 s and building the two graphs about 10 ms. The warm-up runs
    both graphs once on a blank image inside the stderr filter, because the models' start-up
    messages come on first use, not at construction. A failed import is not cached.
    """
    start = time.perf_counter()
    mp = _import_mediapipe()
    imported = time.perf_counter()
    with _StderrFilter(), warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=_PROTOBUF_WARNING, category=UserWarning)
        face_detection = mp.solutions.face_detection.FaceDetection(model_selection=0)
        face_mesh = mp.solutions.face_mesh.FaceMesh(
            static_image_mode=True, max_num_faces=1, refine_landmarks=True, min_detection_confidence=0.5
        )
        blank = np.zeros((64, 64, 3), np.uint8)
        face_detection.process(blank)
        face_mesh.process(blank)
    log.debug(
        "mediapipe imported in %.2f s, detectors ready in %.3f s",
        imported - start,
        time.perf_counter() - imported,
    )
    return face_detection, face_mesh, threading.Lock()


def _rgb(image: np.ndarray) -> np.ndarray:
    """``image`` as a C-contiguous (h, w, 3) uint8 array; ValueError for anything else."""
    array = np.asarray(image)
    if array.ndim != 3 or array.shape[2] != 3 or array.dtype != np.uint8 or 0 in array.shape:
        raise ValueError(
            f"image must be a non-empty (h, w, 3) uint8 RGB array; got {array.shape} {array.dtype}"
        )
    return np.ascontiguousarray(array)


def _best_score(face_detection, array: np.ndarray) -> float:
    """The best score FaceDetection gives a face in ``array``, 0.0 when it finds none."""
    detections = face_detection.process(array).detections or []
    return max((max(d.score, default=0.0) for d in detections), default=0.0)


def face_detection_score(image: np.ndarray) -> float:
    """The best FaceDetection (short-range model) score of a face in an RGB image.

    This is the score ``detect_face`` gates FaceMesh on (renders of heads score about 0.8-0.95,
    non-faces 0.0). It takes about 5 ms per image, from 256 x 256 to 1280 x 720 (two CPU cores).

    Parameters
    ----------
    image : (h, w, 3) uint8
        RGB, row 0 at the top.

    Returns
    -------
    score : float in [0, 1], 0.0 when no face is found.

    Raises
    ------
    MissingExtraError
        mediapipe is not installed (``pip install 'mimetic[track]'``).
    """
    array = _rgb(image)
    face_detection, _, lock = _detectors()
    with lock, warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=_PROTOBUF_WARNING, category=UserWarning)
        return _best_score(face_detection, array)


@contextlib.contextmanager
def video_face_mesh(*, max_faces: int = 1) -> Iterator[Callable[[np.ndarray], np.ndarray]]:
    """A fresh FaceMesh in video mode for one video, closed on exit.

    FaceMesh runs with ``static_image_mode=False`` (a face found in one frame is tracked into the
    next; its face detector runs again only while it tracks fewer than ``max_faces`` faces),
    ``max_num_faces=max_faces``, ``refine_landmarks=True`` and detection and tracking confidences
    0.5. Its graph is built and warmed up inside the stderr filter, like ``detect_face``'s. Feed one
    video's frames in order; the graph keeps state between calls, so it is not shared and needs no
    lock. Looking for a second face costs about 1.5 ms a frame at 1280 x 720 (two CPU cores),
    because the detector then runs on every frame that shows one face.

    Parameters
    ----------
    max_faces : int
        The most faces FaceMesh reports per frame, >= 1.

    Yields
    ------
    track : callable
        ``track(image)`` with ``image`` (h, w, 3) uint8 RGB, row 0 at the top, returns FaceMesh's
        landmarks of every face it finds as (k, 478, 3) float64, 0 <= k <= ``max_faces`` (k = 0
        when it finds none), in FaceMesh's order of faces: x / width and y / height (so 0..1 with
        y down) and z in units of the image width, smaller toward the camera.

    Raises
    ------
    MissingExtraError
        mediapipe is not installed (``pip install 'mimetic[track]'``).
    ValueError
        ``max_faces`` < 1.
    """
    if int(max_faces) != max_faces or max_faces < 1:
        raise ValueError(f"max_faces must be a whole number >= 1; got {max_faces!r}")
    mp = _import_mediapipe()
    with _StderrFilter(), warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=_PROTOBUF_WARNING, category=UserWarning)
        face_mesh = mp.solutions.face_mesh.FaceMesh(
            static_image_mode=False,
            max_num_faces=int(max_faces),
            refine_landmarks=True,
            min_detection_confidence=0.5,
            min_tracking_confidence=0.5,
        )
        face_mesh.process(np.zeros((64, 64, 3), np.uint8))  # start-up messages come on first use

    def track(image: np.ndarray) -> np.ndarray:
        array = _rgb(image)
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=_PROTOBUF_WARNING, category=UserWarning)
            faces = face_mesh.process(array).multi_face_landmarks or []
        points = [[(p.x, p.y, p.z) for p in face.landmark] for face in faces]
        return np.array(points, dtype=np.float64).reshape(len(faces), N_LANDMARKS, 3)  # (k, 478, 3)

    try:
        yield track
    finally:
        face_mesh.close()


def detect_face(image: np.ndarray, *, min_score: float = 0.5) -> FaceDetection:
    """Find one face in an RGB image and its 478 FaceMesh landmarks.

    FaceMesh (``static_image_mode=True``, ``max_num_faces=1``, ``refine_landmarks=True``,
    ``min_detection_confidence=0.5``) runs only when FaceDetection scores the image at least
    ``min_score``. Not finding a face is a result (``found=False``), not an error.

    Parameters
    ----------
    image : (h, w, 3) uint8
        RGB, row 0 at the top (as ``mimetic.render.render`` returns).
    min_score : float
        The FaceDetection score below which FaceMesh's landmarks are not trusted.

    Returns
    -------
    FaceDetection(score, landmarks (478, 2) or (0, 2) float64 pixels, found).

    Raises
    ------
    MissingExtraError
        mediapipe is not installed (``pip install 'mimetic[track]'``).
    """
    array = _rgb(image)
    if not 0.0 <= min_score <= 1.0:
        raise ValueError(f"min_score={min_score} must be in [0, 1]")
    h, w = array.shape[:2]
    face_detection, face_mesh, lock = _detectors()
    with lock, warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=_PROTOBUF_WARNING, category=UserWarning)
        score = _best_score(face_detection, array)
        faces = face_mesh.process(array).multi_face_landmarks if score >= min_score else None
    if not faces:
        log.debug("no face: detection score %.3f (min_score %.2f)", score, min_score)
        return FaceDetection(score, np.empty((0, 2)), False)
    points = faces[0].landmark
    landmarks = np.array([(p.x * w, p.y * h) for p in points], dtype=np.float64)  # (478, 2)
    return FaceDetection(score, landmarks, True)
