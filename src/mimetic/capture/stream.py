"""Live capture: a face's landmarks, or video frames, pushed one at a time → activations as they arrive.

``LiveSolver.push(landmarks)`` solves each frame as ``capture.reprojection`` solves a take, with
what a live stream allows: only the frames so far.

1. **Calibration**: the first ``calibration_s`` of frames (the performer holds a neutral face) are
   collected; their median is the neutral, which places the markers on the rig and fixes the
   references and the neutral pose (``reprojection.calibrate_image``). Until then ``push`` returns
   frames with ``ready`` False.
2. **Smoothing**: a one-euro filter per landmark coordinate (Casiez, Roussel and Vogel 2012): a
   low-pass whose cutoff rises with the landmark's speed, so a still face does not jitter and a fast
   one does not lag (the cutoff ``MIN_CUTOFF_HZ`` at rest, + ``SPEED_GAIN`` · speed).
3. **Pose and expression**, warm-started from the previous frame: a pose step, the expression's
   linearised box QP, the pose again (``ImageModel``), each landmark trusted by the noise, by how far
   the expression moves it and by how far it has strayed from the solved face so far (an
   exponential average of its residual). The shape prior's weight follows the misfit the same way.
4. A frame without a face (or too few landmarks) holds the previous frame's answer, flagged ``lost``.

``LiveCapture.push(image)`` tracks an RGB frame with MediaPipe FaceMesh first (extra ``[track]``);
``live_frames(rig, basis, source)`` runs a whole video file or camera device through it, paced at the
source's frame rate when asked (as a camera would deliver it).
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from mimetic.capture.camera import DEFAULT_FOV_DEG, PinholeCamera
from mimetic.capture.expression import marker_deltas, visible_channels
from mimetic.capture.markers import MarkerSet
from mimetic.capture.reprojection import PIXEL_FLOOR, ImageModel, calibrate_image, prepare_image_model
from mimetic.capture.smooth import CHI_MEDIAN
from mimetic.capture.trajectories import CaptureError
from mimetic.engines.basis import Basis
from mimetic.rig.model import Rig

CALIBRATION_S = 0.5
"""How long the performer holds a neutral face at the start."""
MIN_CUTOFF_HZ = 3.0
SPEED_GAIN = 0.02
"""The one-euro filter: cutoff = ``MIN_CUTOFF_HZ`` + ``SPEED_GAIN`` · |speed| (pixels per second)."""
DERIVATIVE_CUTOFF_HZ = 1.0
STRAY_HALF_LIFE_S = 2.0
"""Each landmark's stray (its residual) and the misfit are exponential averages with this half-life."""
MIN_LANDMARKS = 6


def _alpha(cutoff_hz: np.ndarray | float, fps: float) -> np.ndarray | float:
    """The exponential smoother's weight for a first-order low-pass at ``cutoff_hz``."""
    tau = 1.0 / (2.0 * math.pi * np.asarray(cutoff_hz))
    return 1.0 / (1.0 + tau * fps)


@dataclass(frozen=True)
class LiveFrame:
    """One pushed frame's answer.

    Attributes
    ----------
    values : (c,) float64
        Every rig channel (``rig.channel_names``): the solved activations and ``head_*`` angles
        relative to the neutral; zeros while calibrating.
    ready : bool
        False while the calibration collects its neutral frames.
    lost : bool
        No face (or too few landmarks) in this frame: ``values`` are the last frame's.
    seconds : float
        Time the solve took (not counting tracking).
    """

    values: np.ndarray
    ready: bool
    lost: bool
    seconds: float


class LiveSolver:
    """Frame-by-frame capture of image landmarks (see the module docstring).

    Parameters
    ----------
    rig : Rig
    basis : Basis
        The rig baked with the engine to solve against.
    markers : MarkerSet
        The tracker's layout on the rig (``marker_set(rig, "mediapipe")``), in the order of the
        landmarks pushed.
    image_size : (2,) int
        Width and height of the images, pixels.
    fps : float
        The stream's frame rate.
    focal, fov_deg : float, optional
        The camera's focal length in pixels or vertical field of view; ``camera.DEFAULT_FOV_DEG``
        when neither is given.
    tracked : bool
        The landmarks are a tracker's (their contour points slide).
    calibration_s : float
    active : sequence of str, optional
        Channels to solve (default: every channel the markers see but the gaze and the nose's small
        muscles, ``expression.NOSE_CHANNELS``).
    place : bool
        Move the markers to the performer's at the calibration.
    """

    def __init__(
        self,
        rig: Rig,
        basis: Basis,
        markers: MarkerSet,
        *,
        image_size: tuple[int, int],
        fps: float,
        focal: float | None = None,
        fov_deg: float | None = None,
        tracked: bool = True,
        calibration_s: float = CALIBRATION_S,
        active=None,
        place: bool = True,
        regularization: float = 1e-3,
    ) -> None:
        from mimetic.capture.performance import SHAPE_MOTION_REL

        if not (math.isfinite(fps) and fps > 0):
            raise CaptureError(f"fps={fps} must be a positive frame rate")
        w, h = image_size
        if focal is not None:
            self.camera = PinholeCamera(float(focal), (w / 2, h / 2), (int(w), int(h)))
        else:
            self.camera = PinholeCamera.from_fov(DEFAULT_FOV_DEG if fov_deg is None else fov_deg, image_size)
        self.rig, self.basis, self.fps, self.place = rig, basis, float(fps), place
        if not tracked:
            markers = markers.replace(
                sliding=np.zeros(markers.n_markers, bool), tangents=np.zeros((markers.n_markers, 3))
            )
        self.markers = markers
        self.free = np.flatnonzero(visible_channels(basis, marker_deltas(rig, basis, markers), active))
        self.regularization = regularization
        self.tau = SHAPE_MOTION_REL * rig.scale
        self.calibration_frames = max(1, round(calibration_s * fps))
        self.collected: list[np.ndarray] = []
        self.model: ImageModel | None = None
        self.columns = np.array([rig.channel_index(basis.channels[j]) for j in self.free])
        self.head_columns = [rig.channel_index(n) if n in rig.channel_names else -1
                             for n in ("head_yaw", "head_pitch", "head_roll")]  # fmt: skip
        self.values = np.array([ch.default for ch in rig.channels])  # until the first solve
        self.filtered: np.ndarray | None = None
        self.speed = np.zeros((markers.n_markers, 2))
        self.stray = np.zeros(markers.n_markers)
        self.misfit = PIXEL_FLOOR * CHI_MEDIAN[2]
        self.decay = 0.5 ** (1.0 / (STRAY_HALF_LIFE_S * fps))

    @property
    def ready(self) -> bool:
        return self.model is not None

    def _filter(self, u: np.ndarray) -> np.ndarray:
        """The one-euro filter of this frame's landmarks (m, 2), NaN where missing (those hold)."""
        if self.filtered is None:
            self.filtered = u.copy()
            return u
        seen = np.isfinite(u).all(axis=1)
        previous = np.where(np.isfinite(self.filtered), self.filtered, u)
        raw_speed = (u - previous) * self.fps
        self.speed = np.where(
            seen[:, None],
            self.speed + _alpha(DERIVATIVE_CUTOFF_HZ, self.fps) * (raw_speed - self.speed),
            self.speed,
        )
        cutoff = MIN_CUTOFF_HZ + SPEED_GAIN * np.linalg.norm(self.speed, axis=1, keepdims=True)
        a = _alpha(cutoff, self.fps)
        self.filtered = np.where(seen[:, None], previous + a * (u - previous), self.filtered)
        return np.where(seen[:, None], self.filtered, np.nan)

    def _calibrate(self) -> None:
        neutral = np.nanmedian(np.stack(self.collected), axis=0)
        calibration, R0, t0 = calibrate_image(self.rig, self.markers, self.camera, neutral, place=self.place,
                                              source="live capture")  # fmt: skip
        self.calibration = calibration
        self.model = prepare_image_model(
            self.rig, self.basis, calibration.markers, self.camera, calibration.reference, self.free,
            regularization=self.regularization, shape_prior=True,
        )  # fmt: skip
        self.R0, self.t0 = R0, t0
        self.R, self.t = R0[None].copy(), t0[None].copy()
        self.x = np.zeros((1, len(self.free)))

    def push(self, landmarks: np.ndarray) -> LiveFrame:
        """Solve one frame's landmarks (m, 2) in pixels (x right, y down; NaN where missing, or all NaN
        when the tracker found no face)."""
        start = time.perf_counter()
        u = np.asarray(landmarks, dtype=np.float64)
        if u.shape != (self.markers.n_markers, 2):
            raise CaptureError(f"push takes ({self.markers.n_markers}, 2) landmarks in pixels; got {u.shape}")
        seen = np.isfinite(u).all(axis=1)
        if not self.ready:
            enough = seen.sum() >= MIN_LANDMARKS
            if enough:
                self.collected.append(u)
            if len(self.collected) < self.calibration_frames:
                if enough:
                    self._filter(u)
                return LiveFrame(self.values.copy(), False, not enough, time.perf_counter() - start)
            self._calibrate()  # this frame completes the neutral: it is solved below as the first
        u = self._filter(u)[None]  # (1, m, 2)
        usable = np.isfinite(u).all(axis=-1) & self.calibration.usable[None]
        if usable.sum() < MIN_LANDMARKS:
            return LiveFrame(self.values.copy(), True, True, time.perf_counter() - start)
        model, sigma = self.model, PIXEL_FLOOR
        scale = float(model.scale(self.R, self.t)[0])
        nu = (max(self.misfit / CHI_MEDIAN[2], sigma) / scale / self.tau) ** 2
        # 3. pose, expression, pose
        fixed = usable & ~model.markers.sliding
        weights = fixed * model.trust(self.x, self.R, self.t, sigma, self.stray)
        R, t, _ = model.pose(model.model(self.x), u, weights, self.R, self.t, steps=2)
        P = np.einsum("fij,fmj->fmi", R, model.model(self.x)) + t[:, None]
        confidence = model.visibility(R, P) * usable
        x = model.expression(R, t, self.x, u, confidence, nu)
        weights = confidence * model.trust(x, R, t, sigma, self.stray)
        R, t, residual = model.pose(model.model(x), u, weights, R, t, steps=2)
        # the running stray of each landmark and the misfit
        seen_now = usable[0] & np.isfinite(residual[0])
        self.stray[seen_now] = self.decay * self.stray[seen_now] + (1 - self.decay) * residual[0, seen_now]
        if seen_now.any():
            self.misfit = self.decay * self.misfit + (1 - self.decay) * float(
                np.median(residual[0, seen_now])
            )
        self.R, self.t, self.x = R, t, x
        values = self.values.copy()
        values[self.columns] = x[0]
        from mimetic.capture.head import rotation_angles

        angles = rotation_angles((self.R0.T @ R[0])[None])[0]
        for column, angle in zip(self.head_columns, angles, strict=True):
            if column >= 0:
                ch = self.rig.channels[column]
                values[column] = np.clip(angle, ch.minimum, ch.maximum)
        self.values = values
        return LiveFrame(values, True, False, time.perf_counter() - start)


class LiveCapture:
    """Video frames → MediaPipe FaceMesh → ``LiveSolver`` (extra ``[track]``); close it when done (or
    use it as a context manager).

    Parameters are ``LiveSolver``'s, without ``markers`` (MediaPipe's layout is placed on the rig, as
    ``marker_set(rig, "mediapipe")`` does, unless given) and ``tracked``.
    """

    def __init__(
        self, rig: Rig, basis: Basis, *, image_size: tuple[int, int], fps: float, markers=None, **options
    ):
        from mimetic.capture.markers import marker_set
        from mimetic.capture.video import MEDIAPIPE_NAMES, N_FACE_POINTS, face_landmarks

        self.markers = markers if markers is not None else marker_set(rig, "mediapipe")
        index = {name: k for k, name in enumerate(MEDIAPIPE_NAMES[:N_FACE_POINTS])}
        self.columns = np.array([index[n] for n in self.markers.names])
        self.solver = LiveSolver(
            rig, basis, self.markers, image_size=image_size, fps=fps, tracked=True, **options
        )
        self._tracker = face_landmarks()
        self._track = self._tracker.__enter__()

    def push(self, image: np.ndarray) -> LiveFrame:
        """Track and solve one RGB frame (h, w, 3) uint8, row 0 at the top."""
        points = self._track(image)  # (478, 2) pixels x right, y down, or None
        landmarks = np.full((len(self.columns), 2), np.nan) if points is None else points[self.columns]
        return self.solver.push(landmarks)

    def close(self) -> None:
        self._tracker.__exit__(None, None, None)

    def __enter__(self) -> LiveCapture:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def live_frames(
    rig: Rig,
    basis: Basis,
    source: str,
    *,
    realtime: bool = False,
    max_frames: int | None = None,
    **options,
) -> Iterator[tuple[float, LiveFrame]]:
    """Run a video file, or a camera device (``/dev/video0``), through ``LiveCapture``: yields (the
    frame's time in seconds, its ``LiveFrame``). ``realtime`` paces a file at its frame rate, as a
    camera delivers it (frames that arrive while the last is being solved are not skipped)."""
    from mimetic.capture.video import video_frames

    with video_frames(source, max_frames=max_frames) as (frames, fps, size):
        with LiveCapture(rig, basis, image_size=size, fps=fps, **options) as capture:
            begin = time.perf_counter()
            for k, image in enumerate(frames):
                if realtime:
                    wait = k / fps - (time.perf_counter() - begin)
                    if wait > 0:
                        time.sleep(wait)
                yield k / fps, capture.push(image)
