"""What the web viewer edits, without the browser: layered slider values → a pose → vertices.

A ``Session`` holds one rig and the viewer's controls, in the thesis's layers (seed-000 §6):

* **channels**: one absolute value per rig channel (muscles, jaw, lids, gaze, tongue, head), the
  low-level sliders; they start at the channel defaults;
* **expression**: one library expression at an intensity;
* **descriptive**, **FACS**, **ARKit**: the higher-level sliders, each a table over channels.

The pose is ``clip(channels + expression·intensity + descriptive + FACS + ARKit − defaults)`` in
channel ranges: every layer adds its offset from the rest pose, so a smile from the expression
library plus a little more ``jaw_open`` on the channel slider reads as both. ``Timeline`` keeps the
keys a user sets (or a loaded clip, which key edits then reshape with the B-spline displacement of
``KeyframeClip.edit``). ``Deformers`` prepares each engine once and poses the mesh by the engine
itself when that is interactive, else by its baked basis. ``pick`` intersects a click's ray with
the mesh, for landmark picking. ``LivePlayback`` plays a video (or camera) on the rig as it arrives,
solved frame by frame by ``capture.stream.live_frames``.

Over 600 lines because it is the whole viewer's state (layers, timeline, engines, picks, live
playback) kept out of the browser, so that tests drive it directly.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import tempfile
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mimetic.animate.arkit import arkit_table, arkit_values
from mimetic.animate.clipfiles import save_clip
from mimetic.animate.controls import descriptive_controls
from mimetic.animate.expressions import ExpressionLibrary, expression_pose, load_library
from mimetic.animate.facs import action_units, au_values
from mimetic.animate.keyframes import KeyframeClip, from_poses
from mimetic.engines import ENGINES, make_engine
from mimetic.engines.bake import bake, evaluate_rigid
from mimetic.errors import MimeticError, MissingExtraError, install_hint
from mimetic.rig.model import Rig
from mimetic.tasks.prepared import Prepared

log = logging.getLogger(__name__)

SIDES = (("_L", "_R"), ("Left", "Right"))
"""Name endings of a left/right pair (rig channels and FACS keys; ARKit names)."""

BAKED_ENGINES = frozenset({"tissue"})
"""Engines posed through their baked basis in the viewer: a quasi-static tissue solve takes about
half a second per pose, the basis a few milliseconds. The others deform directly (4–9 ms)."""

FPS = 30.0
"""Frames per second of timeline playback and exported clips."""


def mirror_name(name: str) -> str | None:
    """The other side's name of a left/right control (``zygomatic_major_L`` ↔ ``_R``,
    ``AU12_L`` ↔ ``AU12_R``, ``mouthSmileLeft`` ↔ ``mouthSmileRight``); None for a midline one."""
    for left, right in SIDES:
        if name.endswith(left):
            return name[: -len(left)] + right
        if name.endswith(right):
            return name[: -len(right)] + left
    return None


def facs_keys() -> tuple[str, ...]:
    """The FACS sliders: every supported action unit, per side where FACS allows one."""
    keys: list[str] = []
    for unit in action_units().values():
        if not unit.supported:
            continue
        sides = {"none": ("",), "optional": ("L", "R"), "required": ("L", "R")}[unit.sides]
        keys += [unit.code(side) for side in sides]
    return tuple(keys)


def arkit_keys() -> tuple[str, ...]:
    """The ARKit sliders: every ARKit-52 shape the rig realises."""
    return tuple(name for name, shape in arkit_table().items() if shape.status != "unsupported")


class Session:
    """A rig and the viewer's layered controls; ``pose()`` (c,) is what the face shows.

    Not thread-safe by itself: the web app serialises changes through its own lock.
    """

    def __init__(self, rig: Rig, library: ExpressionLibrary | None = None) -> None:
        self.rig = rig
        self.library = library or load_library(channels=rig)
        self.names = rig.channel_names
        self.index = {name: j for j, name in enumerate(self.names)}
        self.defaults = np.array([c.default for c in rig.channels], dtype=np.float64)
        self.lower = np.array([c.minimum for c in rig.channels], dtype=np.float64)
        self.upper = np.array([c.maximum for c in rig.channels], dtype=np.float64)
        self.channels = self.defaults.copy()
        self.expression: str | None = None
        self.intensity = 1.0
        self.descriptive: dict[str, float] = {}
        self.facs: dict[str, float] = {}
        self.arkit: dict[str, float] = {}
        self.symmetric = False

    # ---- the layers

    def set_channel(self, name: str, value: float) -> list[str]:
        """Set a channel slider (and its mirror when ``symmetric``); the channels changed."""
        changed = [name]
        self.channels[self.index[name]] = value
        other = mirror_name(name) if self.symmetric else None
        if other in self.index:
            self.channels[self.index[other]] = value
            changed.append(other)
        return changed

    def set_layer(self, layer: str, key: str, value: float) -> list[str]:
        """Set a descriptive channel, FACS key or ARKit name in ``layer`` ("descriptive", "facs",
        "arkit"), and its mirror when ``symmetric``; the keys changed."""
        values: dict[str, float] = getattr(self, layer)
        changed = [key]
        values[key] = value
        other = mirror_name(key) if self.symmetric else None
        if other is not None and self._has(layer, other):
            values[other] = value
            changed.append(other)
        return changed

    def _has(self, layer: str, key: str) -> bool:
        if layer == "descriptive":
            return any(key in c.channels for c in descriptive_controls()) and key in self.index
        return key in (facs_keys() if layer == "facs" else arkit_keys())

    def set_expression(self, name: str | None, intensity: float | None = None) -> None:
        """Choose a library expression (None for none) and optionally its intensity."""
        if name is not None and name not in self.library:
            raise KeyError(f"unknown expression {name!r}; the library has {', '.join(self.library.names)}")
        self.expression = name
        if intensity is not None:
            self.intensity = float(intensity)

    def reset(self) -> None:
        """Every layer back to rest."""
        self.channels = self.defaults.copy()
        self.expression, self.intensity = None, 1.0
        self.descriptive, self.facs, self.arkit = {}, {}, {}

    def offsets(self) -> np.ndarray:
        """The higher layers' summed offset (c,) from the rest pose."""
        total = np.zeros(len(self.names))
        if self.expression is not None:
            total += self.intensity * (
                expression_pose(self.rig, self.library[self.expression]) - self.defaults
            )
        layered: dict[str, float] = dict(self.descriptive)
        for key, value in self.facs.items():
            if value:
                for channel, v in au_values(key, value).items():
                    layered[channel] = layered.get(channel, 0.0) + v
        for channel, v in arkit_values({k: w for k, w in self.arkit.items() if w}).items():
            layered[channel] = layered.get(channel, 0.0) + v
        for channel, v in layered.items():
            if channel in self.index:
                total[self.index[channel]] += v
        return total

    def pose(self) -> np.ndarray:
        """The face's pose (c,) float64: channel sliders plus the layers' offsets, in range."""
        return np.clip(self.channels + self.offsets(), self.lower, self.upper)

    def show(self, pose: np.ndarray) -> None:
        """Make ``pose`` (c,) what the face shows: the channel sliders take it, the layers clear."""
        self.reset()
        self.channels = np.clip(np.asarray(pose, dtype=np.float64), self.lower, self.upper)


class Timeline:
    """Keys the user sets, or a loaded clip that key edits reshape; ``clip()`` is what plays."""

    def __init__(self, session: Session) -> None:
        self.session = session
        self.keys: dict[float, np.ndarray] = {}
        self.loaded: KeyframeClip | None = None

    def load(self, clip: KeyframeClip) -> None:
        """Play ``clip`` (its channels must be the rig's, or a subset); keys are cleared."""
        unknown = [c for c in clip.channels if c not in self.session.index]
        if unknown:
            raise KeyError(f"the clip drives channels the rig does not have: {', '.join(unknown[:5])}")
        self.loaded, self.keys = clip, {}

    def set_key(self, time_s: float, pose: np.ndarray) -> None:
        """Key ``pose`` (c,) at ``time_s``; on a loaded clip, every channel that differs there is
        edited by a smooth displacement through the new value."""
        time_s = round(float(time_s), 4)
        if self.loaded is None:
            self.keys[time_s] = np.array(pose, dtype=np.float64)
            return
        now = self.loaded.evaluate(np.array([time_s]))[0]
        for j, channel in enumerate(self.loaded.channels):
            value = float(pose[self.session.index[channel]])
            if abs(value - now[j]) > 1e-6:
                self.loaded = self.loaded.edit(channel, {time_s: value})

    def delete_key(self, time_s: float) -> bool:
        """Remove the key nearest ``time_s`` within half a frame; whether one was removed."""
        near = [t for t in self.keys if abs(t - time_s) <= 0.5 / FPS]
        for t in near:
            del self.keys[t]
        return bool(near)

    def clear(self) -> None:
        self.keys, self.loaded = {}, None

    def clip(self) -> KeyframeClip | None:
        """The clip that plays: the loaded one, or one through the keys (None with no keys)."""
        if self.loaded is not None:
            return self.loaded
        if not self.keys:
            return None
        times = sorted(self.keys)
        return from_poses(
            [(t, self.keys[t]) for t in times], self.session.rig, duration_s=max(times[-1], 1e-3)
        )

    @property
    def duration_s(self) -> float:
        clip = self.clip()
        return 0.0 if clip is None else float(clip.duration_s)

    def pose_at(self, time_s: float) -> np.ndarray | None:
        """The clip's pose (c,) in rig channel order at ``time_s``, in range; None without a clip."""
        clip = self.clip()
        if clip is None:
            return None
        session = self.session
        out = session.defaults.copy()
        values = clip.evaluate(np.array([min(max(time_s, 0.0), clip.duration_s)]))[0]
        out[[session.index[c] for c in clip.channels]] = values
        return np.clip(out, session.lower, session.upper)

    def frames(self, fps: float = FPS) -> np.ndarray:
        """The clip sampled at ``fps``: poses (f, c) in rig channel order, in range, frame i at i / fps;
        (0, c) without a clip."""
        clip = self.clip()
        if clip is None:
            return np.zeros((0, len(self.session.names)))
        return clip.sample(fps, channels=self.session.rig).values

    def clip_json(self) -> bytes:
        """The clip as the JSON ``mimetic animate --clip`` reads; ValueError with no keys."""
        clip = self.clip()
        if clip is None:
            raise ValueError("the timeline is empty: set a key first")
        with tempfile.TemporaryDirectory() as folder:
            return save_clip(clip, Path(folder) / "clip.json").read_bytes()


class Deformers:
    """Each engine prepared once; ``vertices(engine, pose)`` (n, 3) float32 in rig units.

    ``source`` is a rig, or a ``tasks.prepared.Prepared`` rig whose engines and bakes the viewer's
    downloads (the same tasks as the command line) then share.
    """

    def __init__(self, source: Rig | Prepared, engines: tuple[str, ...] = ENGINES) -> None:
        self.prepared = source if isinstance(source, Prepared) else Prepared(source)
        self.rig = self.prepared.rig
        self.engines = engines
        self._ready: dict[str, Callable[[np.ndarray], np.ndarray]] = {}
        self._lock = threading.Lock()

    def ready(self, name: str) -> bool:
        return name in self._ready

    def prepare(self, name: str, progress: Callable[[int, int], None] | None = None) -> None:
        """Build engine ``name`` (and bake it when it is posed by its basis): instant for wire and
        vector, 10–35 s for fem, 30–165 s for tissue (benchmarks/bench_view.py); ``progress(done,
        total)`` hears the preparation's stages, then the bake's poses."""
        if name not in self.engines:
            raise KeyError(f"unknown engine {name!r}; choose one of {', '.join(self.engines)}")
        with self._lock:
            if name in self._ready:
                return
            engine = self.prepared.engine(name, progress)
            if name in BAKED_ENGINES:
                basis = self.prepared.basis(name, progress)

                def deform(pose: np.ndarray) -> np.ndarray:
                    return evaluate_rigid(self.rig, basis, pose, dtype=np.float32)
            else:

                def deform(pose: np.ndarray) -> np.ndarray:
                    return engine.deform(pose).astype(np.float32)

            self._ready[name] = deform

    def vertices(self, name: str, pose: np.ndarray) -> np.ndarray:
        if name not in self._ready:
            self.prepare(name)
        return self._ready[name](pose)


def pick(
    vertices: np.ndarray, faces: np.ndarray, origin: np.ndarray, direction: np.ndarray
) -> tuple[int, np.ndarray, float] | None:
    """The first triangle a ray hits: (face index, barycentric weights (3,), distance along the
    unit ray), or None when it misses. Möller–Trumbore over every face at once, both sides.

    vertices (n, 3), faces (m, 3), origin (3,), direction (3,) in the mesh's frame.
    """
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    a, b, c = (vertices[faces[:, k]].astype(np.float64) for k in range(3))
    e1, e2 = b - a, c - a
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-12
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = np.asarray(origin, dtype=np.float64) - a
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = (q @ d) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    if not hit.any():
        return None
    face = int(np.flatnonzero(hit)[np.argmin(t[hit])])
    return face, np.array([1.0 - u[face] - v[face], u[face], v[face]]), float(t[face])


PICK_LANDMARKS: tuple[str, ...] = (
    "eye_outer_corner_R",
    "eye_inner_corner_R",
    "eye_inner_corner_L",
    "eye_outer_corner_L",
    "nose_tip",
    "subnasale",
    "alare_R",
    "alare_L",
    "mouth_corner_R",
    "mouth_corner_L",
    "upper_lip_top",
    "lower_lip_bottom",
    "pogonion",
    "nasion",
)
"""The landmarks the picker asks for, in order: well spread, easy to find on any face, more than
``fit.landmarks.MIN_LANDMARKS``; any project landmark can be chosen instead."""


class Picks:
    """Landmarks picked on a mesh: name → (face, barycentric (3,)); positions follow the mesh."""

    def __init__(self, faces: np.ndarray) -> None:
        self.faces = faces
        self.points: dict[str, tuple[int, np.ndarray]] = {}

    def add(self, name: str, face: int, bary: np.ndarray) -> None:
        self.points[name] = (int(face), np.asarray(bary, dtype=np.float64))

    def remove(self, name: str) -> None:
        self.points.pop(name, None)

    def next_name(self, order: tuple[str, ...] = PICK_LANDMARKS) -> str | None:
        """The first landmark of ``order`` not picked yet."""
        return next((name for name in order if name not in self.points), None)

    def positions(self, vertices: np.ndarray) -> dict[str, np.ndarray]:
        """Each picked landmark's position (3,) on ``vertices`` (n, 3)."""
        return {name: bary @ vertices[self.faces[face]] for name, (face, bary) in self.points.items()}


# --------------------------------------------------------------------------- live capture

LIVE_STATES = {
    "starting": "starting: preparing the solve (the rig's basis, the tracker's points on the face)",
    "calibrating": "calibrating — hold a neutral face",
    "live": "live",
    "lost": "face lost — holding the last pose",
    "finished": "finished",
    "stopped": "stopped",
    "failed": "error",
}
"""What a live capture can be doing, as the page says it."""

LIVE_STATUS_INTERVAL_S = 0.25
"""The live status is reported at once when its state changes, else at most this often: a line
rewritten 30 times a second tells no more than one rewritten 4 times."""

LIVE_SOLVE_WINDOW = 30
"""The status's ms per frame is the median solve time of this many latest frames (1 s at 30 fps)."""

LIVE_LATE_S = 0.1
"""A capture is behind when its frame comes this long after the source's clock says it should. It
starts behind: the frame that completes the calibration takes about 0.8 s on the default head
(benchmarks/bench_live.py), and ``live_frames`` drops no frame to catch up."""

LIVE_CATCH_UP_FPS = 10.0
"""While a capture is behind, at most this many frames a second are shown (the others are solved
but not drawn), so that drawing takes less of the time the capture needs to catch up."""

LIVE_STOP_TIMEOUT_S = 10.0
"""How long ``LivePlayback.stop`` waits for its thread: one frame's tracking and solve, or ffmpeg's
exit (the bake of the rig is cut short at its next channel)."""


@dataclass(frozen=True)
class LiveStatus:
    """Where a live capture is.

    ``state`` is a key of ``LIVE_STATES``; ``frames`` the frames pushed so far; ``time_s`` the
    source's time of the latest one, seconds; ``solve_ms`` the median solve time of the latest
    ``LIVE_SOLVE_WINDOW`` frames, milliseconds, without tracking (NaN before the first); ``behind_s``
    how far the latest frame came after the source's clock said it should, seconds; ``error`` the
    one-line reason when ``state`` is "failed".
    """

    state: str = "starting"
    frames: int = 0
    time_s: float = 0.0
    solve_ms: float = math.nan
    behind_s: float = 0.0
    error: str | None = None

    @property
    def done(self) -> bool:
        """The capture has ended (finished, failed or stopped)."""
        return self.state in ("finished", "failed", "stopped")

    def text(self) -> str:
        """One line: the state, the frame count and the solve's ms per frame, or the error."""
        if self.state == "failed":
            return f"error: {self.error}"
        parts = [LIVE_STATES[self.state]]
        if self.frames:
            parts.append(f"{self.frames} frames ({self.time_s:.1f} s)")
        if math.isfinite(self.solve_ms):
            parts.append(f"solve {self.solve_ms:.1f} ms per frame")
        if self.behind_s > LIVE_LATE_S and not self.done:
            parts.append(f"{self.behind_s:.1f} s behind the source")
        return " · ".join(parts)


class _Stopped(Exception):
    """Raised inside the live thread to cut it short when ``stop`` is called."""


def check_live_source(source: str | os.PathLike[str]) -> None:
    """Fail now, before anything is served, when ``source`` cannot be captured live.

    Raises ``MissingExtraError`` when mediapipe (extra [track]) is missing and ``CaptureError`` when
    ``source`` is neither a file nor a device, or ffmpeg cannot decode a frame from it. A video
    without a face is only found by playing it (``LivePlayback`` reports it).
    """
    from mimetic.capture.trajectories import CaptureError
    from mimetic.capture.video import video_frames

    try:
        import mediapipe  # noqa: F401
    except ImportError as error:
        raise MissingExtraError(
            f"live capture tracks the face with mediapipe, in the optional extra [track]: "
            f"{install_hint('track')} (importing mediapipe failed: {error})"
        ) from None
    if not Path(source).exists():
        raise CaptureError(f"{source}: no such video file or camera device")
    with video_frames(source, max_frames=1) as (frames, _, _):
        if next(frames, None) is None:
            raise CaptureError(f"{source}: the video holds no frames")


class LivePlayback:
    """A video file or camera device played on a rig as it arrives (extra [track]).

    ``start()`` runs a background thread that:

    1. bakes the rig's wire engine (the basis the live solve works against), unless ``basis`` is
       given;
    2. runs ``capture.stream.live_frames(rig, basis, source, realtime=True, **options)``: frames come
       at the source's pace; the first ``CALIBRATION_S`` calibrate (the performer holds a neutral
       face); each later frame with a face is solved and its values go to ``show``. Frames still
       calibrating or without a face are not shown, so the face keeps the last pose; while the
       capture is behind the source's clock (``LIVE_LATE_S``) only ``LIVE_CATCH_UP_FPS`` frames a
       second are shown (the last one always is);
    3. ends "finished", or "failed" when the source cannot be read, mediapipe is missing, or no
       frame calibrated (no face in the video, or too short a one).

    ``report`` hears of every change of state, and of the frames at most every
    ``LIVE_STATUS_INTERVAL_S``; ``status`` is the latest. Nothing is raised or printed from the
    thread: an error is ``status.error``, one line. ``stop()`` ends the thread (and ffmpeg); no
    callback runs once it has returned.

    Parameters
    ----------
    rig : Rig
    source : str or path
        A video file, or a camera device such as ``/dev/video0`` (passed on to ``live_frames``).
    show : callable(time_s, values)
        Called from the thread with the source's time of the frame (s) and its pose, (c,) float64
        in ``rig.channel_names`` order: the solved channels and the head's turn (``head_*``).
    report : callable(LiveStatus)
        Called from the thread.
    basis : Basis, optional
        The baked rig to solve against; by default the wire engine's, baked in the thread.
    **options
        More keywords for ``live_frames`` and its ``LiveSolver`` (``fov_deg``, ``calibration_s`` …).
    """

    def __init__(
        self,
        rig: Rig,
        source: str | os.PathLike[str],
        *,
        show: Callable[[float, np.ndarray], None],
        report: Callable[[LiveStatus], None],
        basis=None,
        **options,
    ) -> None:
        self.rig, self.source, self.basis, self.options = rig, str(source), basis, options
        self.show, self.report = show, report
        self.status = LiveStatus()
        self._halt = threading.Event()
        self._emitting = threading.Lock()  # held while a callback runs; stop() waits for it
        self._reported = -math.inf
        self._thread: threading.Thread | None = None

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> None:
        """Start the capture's thread (once)."""
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="mimetic-live-capture", daemon=True)
            self._thread.start()

    def stop(self, timeout_s: float = LIVE_STOP_TIMEOUT_S) -> None:
        """End the capture and wait up to ``timeout_s`` for its thread; no callback runs afterwards."""
        with self._emitting:
            self._halt.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout_s)
            if self._thread.is_alive():  # a camera that stopped sending: the daemon thread is left
                log.warning("the live capture did not stop within %g s", timeout_s)

    def wait(self, timeout_s: float | None = None) -> LiveStatus:
        """Wait for the capture to end (or ``timeout_s``); the status then."""
        if self._thread is not None:
            self._thread.join(timeout_s)
        return self.status

    # ---- the thread

    def _emit(self, callback: Callable, *args) -> None:
        with self._emitting:
            if not self._halt.is_set():
                callback(*args)

    def _update(self, status: LiveStatus) -> None:
        """Make ``status`` the latest; report it on a change of state or after the interval."""
        changed = status.state != self.status.state
        self.status = status
        now = time.perf_counter()
        if changed or now - self._reported >= LIVE_STATUS_INTERVAL_S:
            self._reported = now
            self._emit(self.report, status)

    def _check_stop(self, *_) -> None:
        if self._halt.is_set():
            raise _Stopped

    def _run(self) -> None:
        try:
            self._update(LiveStatus())
            self._play()
        except _Stopped:
            s = self.status
            self.status = LiveStatus("stopped", s.frames, s.time_s, s.solve_ms, s.behind_s)
        except MimeticError as error:  # unreadable source, no face, mediapipe missing
            self._update(self._failed(str(error)))
        except OSError as error:
            self._update(self._failed(f"{self.source}: {error.strerror or error}"))
        except Exception as error:  # a bug: said in the page; the traceback goes to the debug log
            log.debug("live capture of %s failed", self.source, exc_info=True)
            bug = f"unexpected {type(error).__name__}: {error}; this is a bug in mimetic, please report it"
            self._update(self._failed(bug))

    def _failed(self, message: str) -> LiveStatus:
        s = self.status
        return LiveStatus("failed", s.frames, s.time_s, s.solve_ms, s.behind_s, " ".join(message.split()))

    def _play(self) -> None:
        from mimetic.capture.stream import CALIBRATION_S, live_frames
        from mimetic.capture.trajectories import CaptureError

        # 1. the basis to solve against
        basis = self.basis
        if basis is None:
            basis = bake(make_engine(self.rig, "wire"), progress=self._check_stop).basis
        self._check_stop()
        # 2. the frames, at the source's pace
        solves: deque[float] = deque(maxlen=LIVE_SOLVE_WINDOW)  # seconds
        count, faces, calibrated = 0, 0, False
        unshown: tuple[float, np.ndarray] | None = None  # the latest solved frame, when skipped
        begin, shown = None, -math.inf  # perf_counter at the source's time 0, and at the last show
        frames = live_frames(self.rig, basis, self.source, realtime=True, **self.options)
        with contextlib.closing(frames):  # closing it stops ffmpeg and FaceMesh
            for time_s, frame in frames:
                self._check_stop()
                now = time.perf_counter()
                begin = now - time_s if begin is None else begin
                behind_s = now - begin - time_s
                count, faces, calibrated = count + 1, faces + (not frame.lost), calibrated or frame.ready
                if frame.ready and not frame.lost:
                    solves.append(frame.seconds)
                    unshown = (time_s, frame.values)
                    if behind_s <= LIVE_LATE_S or now - shown >= 1.0 / LIVE_CATCH_UP_FPS:
                        self._emit(self.show, *unshown)
                        unshown, shown = None, now
                state = "lost" if frame.lost else "live" if frame.ready else "calibrating"
                solve_ms = 1e3 * float(np.median(solves)) if solves else math.nan
                self._update(LiveStatus(state, count, time_s, solve_ms, behind_s))
        # 3. the end
        if unshown is not None:
            self._emit(self.show, *unshown)
        if count == 0:
            raise CaptureError(f"{self.source}: the video holds no frames")
        if not calibrated:
            needed = self.options.get("calibration_s", CALIBRATION_S)
            if faces == 0:
                raise CaptureError(
                    f"{self.source}: no face found in any of its {count} frames; the video must show one "
                    "face, large and from the front"
                )
            raise CaptureError(
                f"{self.source}: the video ended before the calibration: only {faces} of its {count} "
                f"frames show a face, and the calibration needs {needed:g} s of them (the performer "
                "holding a neutral face) first"
            )
        s = self.status
        self._update(LiveStatus("finished", count, s.time_s, s.solve_ms, s.behind_s))


# --------------------------------------------------------------------------- live lip sync


def check_speech_source(source: str | os.PathLike[str]) -> None:
    """Fail now, before anything is served, when ``source`` cannot be lip-synced live: pocketsphinx
    (extra [speech]) missing, or not a readable PCM WAV file (``SpeechError``)."""
    from mimetic.speech.align import read_wav
    from mimetic.speech.stream import phone_decoder

    read_wav(source)
    phone_decoder()


class SpeechPlayback(LivePlayback):
    """A WAV file lip-synced on a rig as it arrives, standing in for a microphone (extra [speech]).

    The thread pushes the file through ``speech.stream.live_lip_sync(realtime=True)`` in chunks of
    ``chunk_s`` at the sound's pace (the sound is not played); each frame the lip sync makes final
    goes to ``show`` (time_s, values (c,) in ``rig.channel_names`` order), skipped as
    ``LivePlayback`` skips frames while behind. The status's ``solve_ms`` is the median compute per
    frame; it ends "finished", or "failed" when the file cannot be read. Same parameters and
    callbacks as ``LivePlayback``; ``**options`` go to ``LiveLipSync`` (``fps``, ``lookahead_s`` …).
    """

    def _play(self) -> None:
        from mimetic.speech.stream import live_lip_sync

        solves: deque[float] = deque(maxlen=LIVE_SOLVE_WINDOW)  # seconds per frame
        count, begin, shown = 0, None, -math.inf  # begin: perf_counter at the sound's time 0
        unshown: tuple[float, np.ndarray] | None = None
        self._update(LiveStatus("live"))
        for out, heard_s in live_lip_sync(self.rig, self.source, realtime=True, **self.options):
            self._check_stop()
            if len(out.values):
                solves.append(out.seconds / len(out.values))
            now = time.perf_counter()
            begin = now - heard_s if begin is None else begin  # the first chunk: the recogniser is loaded
            behind_s = max(0.0, now - begin - heard_s)
            for time_s, values in zip(out.times_s, out.values, strict=True):
                count += 1
                unshown = (float(time_s), values)
                if behind_s <= LIVE_LATE_S or now - shown >= 1.0 / LIVE_CATCH_UP_FPS:
                    self._emit(self.show, *unshown)
                    unshown, shown = None, now
            solve_ms = 1e3 * float(np.median(solves)) if solves else math.nan
            self._update(LiveStatus("live", count, heard_s, solve_ms, behind_s))
        if unshown is not None:
            self._emit(self.show, *unshown)
        s = self.status
        self._update(LiveStatus("finished", count, s.time_s, s.solve_ms, s.behind_s))
