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
the mesh, for landmark picking.
"""

from __future__ import annotations

import tempfile
import threading
from collections.abc import Callable
from pathlib import Path

import numpy as np

from mimetic.animate.arkit import arkit_table, arkit_values
from mimetic.animate.clip import KeyframeClip, from_poses, save_clip
from mimetic.animate.controls import descriptive_controls
from mimetic.animate.expressions import ExpressionLibrary, expression_pose, load_library
from mimetic.animate.facs import action_units, au_values
from mimetic.engines import ENGINES, make_engine
from mimetic.engines.bake import bake, evaluate_rigid
from mimetic.rig.model import Rig

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
    """Each engine prepared once; ``vertices(engine, pose)`` (n, 3) float32 in rig units."""

    def __init__(self, rig: Rig, engines: tuple[str, ...] = ENGINES) -> None:
        self.rig = rig
        self.engines = engines
        self._ready: dict[str, Callable[[np.ndarray], np.ndarray]] = {}
        self._lock = threading.Lock()

    def ready(self, name: str) -> bool:
        return name in self._ready

    def prepare(self, name: str, progress: Callable[[int, int], None] | None = None) -> None:
        """Build engine ``name`` (and bake it when it is posed by its basis): instant for wire and
        vector, about 10 s for fem, 30–100 s for tissue (benchmarks/bench_view.py)."""
        if name not in self.engines:
            raise KeyError(f"unknown engine {name!r}; choose one of {', '.join(self.engines)}")
        with self._lock:
            if name in self._ready:
                return
            engine = make_engine(self.rig, name)
            if name in BAKED_ENGINES:
                basis = bake(engine, progress=progress).basis

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
