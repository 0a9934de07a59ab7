"""Validate performance capture (issue 14): synthetic ground truth, a video round trip, a real OpenFace file.

    python benchmarks/validate_capture.py [--quick] [--parts abc]

Prints rich tables and writes every number to ``benchmarks/out/capture/validation.json``; the videos
and the frame this script writes go to the same folder (outputs, never committed).

a. **Synthetic ground truth.** For each head (``mimetic.testing.small_rig()`` and one random generated
   identity, ``HeadParams.random(1)``) and each layout (``paper`` 24, ``ibug68`` 68, ``mediapipe`` 468,
   the last needing the extra ``[track]``): the wire engine baked (``bake(make_engine(rig, "wire"),
   correctives=0, samples=2).basis``); the channels the layout determines (``determined_channels`` at
   tolerance 0.01 of each range, for 1 mm RMS 3D marker noise, i.e. 0.1/√3 cm per coordinate, as given,
   and, in a second table, for that noise after the solver's temporal smoothing, × ``SMOOTH_GAIN``, which
   is how ``determined_channels`` documents its ``noise``); a random smooth clip over those channels at
   60 fps (``NEUTRAL_S`` of neutral, then a ramp; each channel a cubic spline through uniform knots
   within 0.9 × its range); the basis evaluated → ``MarkerSet.positions``; a random smooth head motion
   (yaw, pitch, roll within ±``HEAD_RAD`` rad, translation within ±``HEAD_CM`` cm per axis, zero at frame
   0) applied about the head joint as the skinning composes it, R_y(yaw) R_x(pitch) R_z(−roll); then
   millimetres, 1 mm RMS Gaussian noise, 10 % of the samples dropped (NaN) and 2 % spikes of 2 cm (a
   random direction). ``solve_performance(rig, Trajectories(names, mm, 60, "mm"), basis=basis,
   active=determined)`` against the truth: activation RMS and max error over the determined channels
   (goal RMS ≤ 0.02), marker fit (the library's ``marker_error`` median, against its smoothed markers,
   and ours: the solved expression's markers against the noise-free stabilised truth), head-angle RMS
   error, spikes found / planted (false alarms in brackets), the spikes planted in the neutral period
   and how far the smoothed neutral frame (the solver's reference) ends up from the truth, solve time;
   and the all-channels solve (``active=None``) for contrast. Table a3 takes the small rig apart, one
   switch at a time (noise-free data; no spikes, then no noise, in the neutral period; more
   head/expression alternations, ``HEAD_ROUNDS`` patched in this process), to say where the error
   beyond the noise comes from.
b. **Video round trip.** A generated head (the default ``HeadParams()``; small resolution with
   ``--quick``) and ICT-FaceKit's neutral rigged from its file landmarks (as ``bench_quality.Heads``
   does; full run only) play ``video_clip`` (smile, jaw open, brow raise, head yaw) through the wire
   engine; ``render_clip`` writes the MP4, ``track_video`` tracks it, and ``solve_performance`` solves it
   on the same rig with ``marker_set(rig, "mediapipe")``: all channels (the default), the determined
   ones, and the animated ones only (an oracle active set, the best case). Error per channel group
   (``GROUPS``), the correlation of true and solved curves for the channels that move, the head yaw.
   Table b3 (full run): head yaw alone rendered at three fields of view, to separate the camera's
   perspective from the solve in the yaw error.
c. **OpenFace sample.** ``read_trajectories(OpenFace_Test.csv, fps=30)`` (its timestamps step by
   1 ms) → ``solve_performance`` on the default generated rig (``build_rig(make_head(HeadParams(),
   DEFAULT_RESOLUTION))``, as ``mimetic.demo`` builds it; small resolution with ``--quick``):
   ``Performance.report``, the head rotation against OpenFace's own ``pose_Rx/Ry/Rz`` (OpenFace's
   R = Rx Ry Rz in its camera frame, +Y down, +Z away, turned into the capture's +Y up, +Z toward the
   camera by diag(1, −1, −1), taken relative to the neutral frame and into the rig's frame by the
   calibration, then read as yaw / pitch / roll exactly as ``HeadMotion.angles`` reads them), then
   OpenFace's own action units against the channels that make them (a plausibility check), then
   ``retarget`` onto another identity (``HeadParams.random(3)``) rendered to
   ``openface_retargeted.mp4``, its most active frame saved as ``openface_retargeted.png`` (and the
   neutral frame as ``openface_retargeted_neutral.png``).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import tempfile
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from rich.console import Console
from rich.table import Table
from scipy.interpolate import CubicSpline

import mimetic.capture.performance as performance_module
from mimetic.capture import (
    MarkerSet,
    Performance,
    Trajectories,
    marker_set,
    read_trajectories,
    retarget,
    solve_performance,
)
from mimetic.capture.performance import HEAD_CHANNELS, determined_channels, smoothing_weight
from mimetic.engines import make_engine
from mimetic.engines.bake import bake
from mimetic.engines.basis import Basis, evaluate_basis
from mimetic.engines.skinning import rotation_x, rotation_y, rotation_z
from mimetic.head.model import DEFAULT_RESOLUTION, make_head
from mimetic.head.params import HeadParams
from mimetic.mesh.units import UNIT_SCALE
from mimetic.rig.activations import Clip
from mimetic.rig.model import Rig
from mimetic.rig.recipe import build_rig
from mimetic.testing import SMALL_RESOLUTION, shared_data_dir, small_rig

OUT = Path(__file__).resolve().parent / "out" / "capture"
LAYOUTS = ("paper", "ibug68", "mediapipe")
FPS = 60.0
NEUTRAL_S = 0.5
RAMP_S = 0.5
KNOT_S = 0.4
"""Spacing of the activation curves' spline knots: motion up to about 1/(2 KNOT_S) Hz."""
HEAD_KNOT_S = 0.8
HEAD_RAD = 0.2
HEAD_CM = 3.0
NOISE_MM = 1.0
"""RMS of the 3D marker noise; per coordinate NOISE_MM / √3."""
DROP = 0.10
SPIKE = 0.02
SPIKE_MM = 20.0
TOLERANCE = 0.01
GOAL_RMS = 0.02
RANDOM_SEED = 1
"""The random generated identity of part a (``HeadParams.random``)."""
RETARGET_SEED = 3
"""The identity part c retargets onto."""
CUTOFF_HZ = performance_module.CUTOFF_HZ
VIDEO_FPS = 30.0
VIDEO_SIZE = 512
MOVING = 0.05
"""A channel whose true curve spans more than this moves (its correlation is reported)."""
OPENFACE = "landmarks/OpenFace_Test.csv"
OPENFACE_FPS = 30.0
GROUPS = {
    "brows/eyes": ("frontalis", "corrugator", "procerus", "orbicularis_oculi", "levator_palpebrae", "eyelid",
                   "gaze"),
    "cheeks/nose": ("zygomatic", "levator_labii", "risorius", "buccinator", "cheek_puff", "nasalis",
                    "dilator_naris"),
    "mouth": ("orbicularis_oris", "triangularis", "depressor_labii", "mentalis", "platysma", "mouth_slide",
              "tongue"),
    "jaw": ("jaw_",),
}  # fmt: skip
"""Channel groups by name prefix; a channel matching none falls back to its ``Channel.group``."""

console = Console(width=200, highlight=False)


# --------------------------------------------------------------------------- helpers


def smooth_gain(fps: float, cutoff_hz: float) -> float:
    """Standard deviation of white noise after the solver's Whittaker smoother (``smoothing_weight``),
    per unit before: sqrt of the mean of |H(ω)|² over [0, π], H = 1 / (1 + λ (2 − 2 cos ω)²)."""
    lam = smoothing_weight(fps, cutoff_hz)
    omega = np.linspace(0.0, np.pi, 20001)
    response = 1.0 / (1.0 + lam * (2.0 - 2.0 * np.cos(omega)) ** 2)
    return float(np.sqrt(np.mean(response**2)))


SMOOTH_GAIN = smooth_gain(FPS, CUTOFF_HZ)


def mm_per_unit(rig: Rig) -> float:
    return UNIT_SCALE[rig.units] / UNIT_SCALE["mm"]


def wire_basis(rig: Rig) -> Basis:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return bake(make_engine(rig, "wire"), correctives=0, samples=2).basis


def smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def spline_curve(rng: np.random.Generator, t: np.ndarray, lo: float, hi: float, knot_s: float) -> np.ndarray:
    """(f,) a cubic spline through knots every ``knot_s`` seconds, uniform in [lo, hi]."""
    knots = np.arange(-knot_s, t[-1] + 2 * knot_s, knot_s)
    return CubicSpline(knots, rng.uniform(lo, hi, len(knots)))(t)


def head_rotations(angles: np.ndarray) -> np.ndarray:
    """(f, 3, 3): R_y(yaw) R_x(pitch) R_z(−roll) for angles (f, 3), as the skinning composes them."""
    return np.array([rotation_y(y) @ rotation_x(p) @ rotation_z(-r) for y, p, r in angles])


def angles_of(R: np.ndarray) -> np.ndarray:
    """(f, 3) yaw, pitch, roll of rotations (f, 3, 3), read as ``HeadMotion.angles`` reads them."""
    pitch = np.arcsin(np.clip(-R[:, 1, 2], -1.0, 1.0))
    yaw = np.arctan2(R[:, 0, 2], R[:, 2, 2])
    roll = -np.arctan2(R[:, 1, 0], R[:, 1, 1])
    return np.stack([yaw, pitch, roll], axis=1)


def correlation(a: np.ndarray, b: np.ndarray) -> float:
    """Pearson r of two (f,) curves; nan when either is constant."""
    return float(np.corrcoef(a, b)[0, 1]) if np.ptp(a) > 0 and np.ptp(b) > 0 else float("nan")


def rms(x: np.ndarray) -> float:
    x = np.asarray(x, dtype=np.float64)
    return float(np.sqrt(np.mean(x**2))) if x.size else float("nan")


def quiet(fn: Callable, *args, **kwargs):
    """``fn(*args, **kwargs)`` with warnings silenced, and the warnings' messages."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = fn(*args, **kwargs)
    return result, [str(w.message) for w in caught]


def table(title: str, header: Sequence[str], rows: Sequence[Sequence[object]], note: str = "") -> None:
    t = Table(title=title, title_justify="left", caption=note or None, caption_justify="left")
    for name in header:
        t.add_column(name, overflow="fold")
    for row in rows:
        t.add_row(*(str(c) for c in row))
    console.print(t)


def fmt(x: float, digits: int = 3) -> str:
    return "nan" if not np.isfinite(x) else f"{x:.{digits}f}"


def verdict(ok: bool) -> str:
    return "met" if ok else "NOT met"


def timed(fn: Callable, *args, **kwargs):
    begin = time.perf_counter()
    result = fn(*args, **kwargs)
    return result, time.perf_counter() - begin


def plain(value: object) -> object:
    """``value`` with numpy scalars as Python numbers and nan/inf as None (strict JSON)."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    if isinstance(value, np.integer | np.bool_):
        return value.item()
    if isinstance(value, float | np.floating):
        return float(value) if np.isfinite(value) else None
    return value


def write_json(data: dict, path: Path) -> None:
    """Write ``data`` as JSON to a temporary file beside ``path`` and move it into place."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    with os.fdopen(fd, "w", encoding="utf-8") as out:
        json.dump(plain(data), out, indent=1, allow_nan=False)
    os.replace(tmp, path)


# --------------------------------------------------------------------------- heads


@dataclass
class Head:
    """A rigged head, its wire basis and its marker sets (built on first use)."""

    name: str
    rig: Rig
    basis: Basis
    build_s: float
    markers: dict[str, MarkerSet | str]

    def layout(self, name: str) -> MarkerSet | str:
        """The marker set, or the reason it is unavailable (MediaPipe missing)."""
        if name not in self.markers:
            try:
                self.markers[name] = marker_set(self.rig, name)
            except ImportError as error:  # MissingExtraError: mediapipe, extra [track]
                self.markers[name] = f"skipped: needs the [track] extra ({error})"
        return self.markers[name]


def make_case(name: str, build: Callable[[], Rig]) -> Head:
    begin = time.perf_counter()
    rig = build()
    basis = wire_basis(rig)
    return Head(name, rig, basis, time.perf_counter() - begin, {})


def generated_rig(params: HeadParams | None, quick: bool) -> Rig:
    return build_rig(make_head(params, resolution=SMALL_RESOLUTION if quick else DEFAULT_RESOLUTION))


def ict_rig() -> Rig:
    """ICT-FaceKit's neutral rigged from its file landmarks, as ``bench_quality.Heads.ict_file``."""
    from mimetic.fit.pipeline import rig_head
    from mimetic.testing import ict_folder, ict_landmarks, load_ict

    neutral, meta = load_ict(ict_folder())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return rig_head(neutral, ict_landmarks(neutral, meta)).rig


# --------------------------------------------------------------------------- a. synthetic ground truth


@dataclass
class Synthetic:
    """A synthetic capture and its truth."""

    trajectories: Trajectories
    activations: np.ndarray  # (f, c) basis channels
    angles: np.ndarray  # (f, 3) yaw, pitch, roll
    stabilised: np.ndarray  # (f, m, 3) noise-free markers without head motion, rig units
    spikes: np.ndarray  # (f, m) bool, planted on seen samples
    seen: np.ndarray  # (f, m) bool


def synthesize(
    head: Head,
    markers: MarkerSet,
    channels: Sequence[str],
    duration_s: float,
    seed: int,
    *,
    noise_mm: float = NOISE_MM,
    head_motion: bool = True,
    corrupt: bool = True,
    neutral_spikes: bool = True,
    neutral_noise: bool = True,
) -> Synthetic:
    """A random smooth performance of ``channels`` seen through ``markers`` (see the module docstring).

    Diagnostics (table a3): ``noise_mm`` 0, no ``head_motion``, no drops or spikes (``corrupt``), no
    spikes or no noise in the neutral period (``neutral_spikes``, ``neutral_noise``). The random draws
    are the same whatever the options, so the setups differ only in what they switch off.
    """
    rig, basis = head.rig, head.basis
    rng = np.random.default_rng(seed)
    f = round(duration_s * FPS)
    t = np.arange(f) / FPS
    face_envelope = smoothstep((t - NEUTRAL_S) / RAMP_S)
    head_envelope = smoothstep(t / (NEUTRAL_S + RAMP_S))
    by_name = {ch.name: ch for ch in rig.channels}
    activations = np.zeros((f, len(basis.channels)))
    for name in channels:
        ch = by_name[name]
        curve = spline_curve(rng, t, 0.9 * ch.minimum, 0.9 * ch.maximum, KNOT_S)
        activations[:, basis.channels.index(name)] = np.clip(curve, ch.minimum, ch.maximum) * face_envelope
    stabilised = np.empty((f, markers.n_markers, 3))
    for start in range(0, f, 256):  # the basis evaluated in chunks, then the markers on it
        vertices = evaluate_basis(basis, activations[start : start + 256])
        stabilised[start : start + 256] = markers.positions(rig, vertices)
    angles = np.stack([spline_curve(rng, t, -HEAD_RAD, HEAD_RAD, HEAD_KNOT_S) for _ in range(3)], axis=1)
    shift = np.stack([spline_curve(rng, t, -HEAD_CM, HEAD_CM, HEAD_KNOT_S) for _ in range(3)], axis=1)
    angles *= head_envelope[:, None] * head_motion
    shift *= head_envelope[:, None] * head_motion / (UNIT_SCALE[rig.units] / UNIT_SCALE["cm"])
    pivot = rig.bone("head").head
    moved = np.einsum("fij,fmj->fmi", head_rotations(angles), stabilised - pivot) + pivot + shift[:, None]
    points = moved * mm_per_unit(rig)
    noise = rng.normal(0.0, noise_mm / np.sqrt(3), points.shape)
    neutral = round(NEUTRAL_S * FPS)
    if not neutral_noise:
        noise[:neutral] = 0.0
    points += noise
    seen = rng.random((f, markers.n_markers)) >= DROP
    spikes = seen & (rng.random((f, markers.n_markers)) < SPIKE)
    direction = rng.normal(size=points.shape)
    direction /= np.linalg.norm(direction, axis=2, keepdims=True)
    if not corrupt:
        seen[:], spikes[:] = True, False
    if not neutral_spikes:
        spikes[:neutral] = False
    points[spikes] += SPIKE_MM * direction[spikes]
    points[~seen] = np.nan
    trajectories = Trajectories(markers.names, points, FPS, "mm", source=f"synthetic {head.name}")
    return Synthetic(trajectories, activations, angles, stabilised, spikes, seen)


def score_synthetic(head: Head, markers: MarkerSet, data: Synthetic, perf: Performance, channels) -> dict:
    """Activation, marker, head and spike errors of a solve against the truth."""
    basis = head.basis
    solved = perf.clip.select(basis.channels).values  # (f, c)
    index = [basis.channels.index(n) for n in channels]
    error = solved[:, index] - data.activations[:, index]
    free = [basis.channels.index(n) for n in perf.solved]
    W = markers.weights(head.rig)
    deltas = np.einsum("mn,cnd->cmd", W.toarray(), basis.deltas)  # (c, m, 3)
    predicted = W @ basis.neutral + np.einsum("fc,cmd->fmd", solved, deltas)
    vs_truth = np.linalg.norm(predicted - data.stabilised, axis=2)  # (f, m) rig units
    head_error = np.degrees(perf.head.angles() - data.angles)  # (f, 3)
    mm = mm_per_unit(head.rig)
    # the neutral frame as the solver's smoother leaves it (its reference), against the truth (no head
    # motion at frame 0, so capture and rig frames differ only by mm)
    smoothed, _ = performance_module.smooth_markers(
        data.trajectories.positions, FPS, CUTOFF_HZ, size=head.rig.scale * mm
    )
    reference_error = np.linalg.norm(smoothed[perf.neutral_frame] - data.stabilised[0] * mm, axis=1)
    planted = int(data.spikes.sum())
    found = int((perf.outliers & data.spikes).sum())
    false = int((perf.outliers & data.seen & ~data.spikes).sum())
    return {
        "rms": rms(error),
        "max": float(np.abs(error).max()) if error.size else float("nan"),
        "rms_per_channel": {n: rms(error[:, k]) for k, n in enumerate(channels)},
        "bias_per_channel": {n: float(error[:, k].mean()) for k, n in enumerate(channels)},
        "rms_all_solved": rms(solved[:, free] - data.activations[:, free]),
        "marker_rms_median_mm": float(np.nanmedian(perf.marker_error)) * mm_per_unit(head.rig),
        "marker_vs_truth_rms_mm": rms(vs_truth) * mm_per_unit(head.rig),
        "head_rms_deg": [rms(head_error[:, k]) for k in range(3)],
        "spikes_planted": planted,
        "spikes_neutral_period": int(data.spikes[: round(NEUTRAL_S * FPS)].sum()),
        "reference_error_max_mm": float(np.nanmax(reference_error)),
        "reference_error_over_2mm": int(np.sum(reference_error > 2.0)),
        "spikes_found": found,
        "false_outliers": false,
        "flagged_frames": int(perf.flagged.sum()),
        "solved_channels": len(perf.solved),
    }


def part_a(heads: list[Head], duration_s: float, results: dict) -> None:
    console.rule("[bold]a. synthetic ground truth")
    gain = SMOOTH_GAIN
    raw = NOISE_MM / np.sqrt(3)  # mm per coordinate
    console.print(
        f"{duration_s:g} s at {FPS:g} fps ({NEUTRAL_S:g} s neutral, {RAMP_S:g} s ramp); noise "
        f"{NOISE_MM:g} mm RMS 3D ({raw:.3f} mm per coordinate), {DROP:.0%} dropped, {SPIKE:.0%} spikes "
        f"of {SPIKE_MM:g} mm; "
        f"head ±{HEAD_RAD:g} rad, ±{HEAD_CM:g} cm. The solver's smoother ({CUTOFF_HZ:g} Hz at {FPS:g} fps) "
        f"keeps {gain:.3f} of white noise (std), so table a2 asks determined_channels about "
        f"{raw * gain:.3f} mm per coordinate."
    )
    out = results.setdefault("a", {})
    out.update({"duration_s": duration_s, "smooth_gain": gain, "cases": []})
    variants = (
        ("a1", "noise as given: 1 mm RMS, 0.1/√3 cm per coordinate", 1.0),
        ("a2", f"noise after smoothing: × {gain:.3f}", gain),
    )
    for key, label, factor in variants:
        rows, skipped = [], []
        begin = time.perf_counter()
        for head in heads:
            for layout in LAYOUTS:
                markers = head.layout(layout)
                if isinstance(markers, str):
                    skipped.append(f"{head.name} {layout}: {markers}")
                    continue
                seed = 1000 * LAYOUTS.index(layout) + heads.index(head)
                case = synthetic_case(head, layout, markers, raw * factor, duration_s, seed)
                case["table"] = key
                out["cases"].append(case)
                every = case["all_channels"]
                channels = case["determined"]
                rows.append(
                    (
                        head.name,
                        layout,
                        markers.n_markers,
                        f"{len(channels)}: {', '.join(channels)}"
                        if len(channels) <= 3
                        else f"{len(channels)}",
                        fmt(case["rms"], 4),
                        fmt(case["max"], 3),
                        verdict(case["rms"] <= GOAL_RMS),
                        f"{fmt(case['marker_rms_median_mm'], 2)} / {fmt(case['marker_vs_truth_rms_mm'], 2)}",
                        " / ".join(fmt(x, 2) for x in case["head_rms_deg"]),
                        f"{case['spikes_found']}/{case['spikes_planted']} (+{case['false_outliers']})",
                        f"{case['spikes_neutral_period']}: {fmt(case['reference_error_max_mm'], 1)} "
                        f"({case['reference_error_over_2mm']})",
                        f"{case['solve_s']:.2f} s",
                        f"{every['solved_channels']}: {fmt(every['rms'], 4)} / "
                        f"{fmt(every['rms_all_solved'], 3)}",
                        f"{every['solve_s']:.2f} s",
                    )
                )
        table(
            f"{key}. synthetic, determined channels ({label}; tolerance {TOLERANCE:g} of the range); "
            f"goal: activation RMS ≤ {GOAL_RMS:g}",
            (
                "head",
                "layout",
                "markers",
                "channels determined",
                "act. RMS",
                "act. max",
                "goal",
                "marker mm: lib / truth",
                "head RMS ° y/p/r",
                "spikes found/planted (+false)",
                "neutral spikes: ref. err mm (> 2 mm)",
                "solve",
                "all channels: n: RMS det. / all",
                "all: solve",
            ),
            rows,
            "marker mm: the library's marker_error median (its fit vs its smoothed markers) / the solved "
            "expression's markers vs the noise-free truth (head motion removed). neutral spikes: planted in "
            "the neutral period; ref. err: the largest error of a marker's smoothed neutral-frame position "
            "(the solver's reference), in brackets how many exceed 2 mm. all channels: active=None; RMS over "
            "the determined channels / over every solved channel (truth 0 for those not animated). "
            f"{time.perf_counter() - begin:.0f} s.\n" + "\n".join(skipped),
        )
        for case in out["cases"]:
            if case["table"] == key and len(case["determined"]) > 3:
                worst = sorted(case["rms_per_channel"].items(), key=lambda kv: -kv[1])[:5]
                console.print(
                    f"   {case['head']} {case['layout']}: worst "
                    + ", ".join(f"{n} {v:.3f} (bias {case['bias_per_channel'][n]:+.3f})" for n, v in worst)
                )


def synthetic_case(
    head: Head, layout: str, markers: MarkerSet, noise_mm: float, duration_s: float, seed: int
) -> dict:
    """One row of tables a1/a2: determined channels for ``noise_mm`` per coordinate, synthesize, solve
    with them and with every channel, score both."""
    noise = noise_mm / mm_per_unit(head.rig)
    channels, det_s = timed(
        determined_channels, head.rig, head.basis, markers, noise=noise, tolerance=TOLERANCE
    )
    data = synthesize(head, markers, channels, duration_s, seed)
    solve = solve_performance
    (perf, _), solve_s = timed(quiet, solve, head.rig, data.trajectories, basis=head.basis, active=channels)
    (every, _), every_s = timed(quiet, solve, head.rig, data.trajectories, basis=head.basis)
    return {
        "head": head.name,
        "layout": layout,
        "markers": markers.n_markers,
        "noise_per_coordinate_mm": noise_mm,
        "determined": list(channels),
        "determined_s": det_s,
        "solve_s": solve_s,
        **score_synthetic(head, markers, data, perf, channels),
        "all_channels": {"solve_s": every_s, **score_synthetic(head, markers, data, every, channels)},
    }


DIAGNOSTICS = (
    (
        "floor: no noise, head motion, drops or spikes",
        dict(noise_mm=0.0, head_motion=False, corrupt=False),
        0,
    ),
    ("library defaults (as a2)", {}, 0),
    ("+ no spikes in the neutral period", dict(neutral_spikes=False), 0),
    ("+ no noise in the neutral period", dict(neutral_spikes=False, neutral_noise=False), 0),
    ("+ HEAD_ROUNDS 4 → 25", dict(neutral_spikes=False, neutral_noise=False), 25),
    ("HEAD_ROUNDS 4 → 25 alone", {}, 25),
)
"""Table a3's setups: a label, ``synthesize`` options and ``HEAD_ROUNDS`` (0: the library's)."""


def part_a_diagnostics(
    head: Head, layouts: Sequence[str], setups: Sequence[tuple], duration_s: float, results: dict
) -> None:
    """Where the error beyond the noise comes from, on one head (table a3)."""
    rows, cases = [], []
    raw = NOISE_MM / np.sqrt(3)
    default_rounds = performance_module.HEAD_ROUNDS
    begin = time.perf_counter()
    for layout in layouts:
        markers = head.layout(layout)
        if isinstance(markers, str):
            continue
        noise = raw * SMOOTH_GAIN / mm_per_unit(head.rig)
        channels = determined_channels(head.rig, head.basis, markers, noise=noise, tolerance=TOLERANCE)
        seed = 1000 * LAYOUTS.index(layout) + 7
        for label, options, rounds in setups:
            data = synthesize(head, markers, channels, duration_s, seed, **options)
            performance_module.HEAD_ROUNDS = rounds or default_rounds
            try:
                (perf, _), solve_s = timed(
                    quiet, solve_performance, head.rig, data.trajectories, basis=head.basis, active=channels
                )
            finally:
                performance_module.HEAD_ROUNDS = default_rounds
            score = score_synthetic(head, markers, data, perf, channels)
            bias = float(np.mean(np.abs(list(score["bias_per_channel"].values()))))
            cases.append(
                {
                    "layout": layout,
                    "setup": label,
                    "head_rounds": rounds or default_rounds,
                    "mean_abs_bias": bias,
                }
                | score
            )
            rows.append(
                (
                    layout,
                    len(channels),
                    label,
                    fmt(score["rms"], 4),
                    fmt(bias, 4),
                    fmt(score["max"], 3),
                    " / ".join(fmt(x, 3) for x in score["head_rms_deg"]),
                    f"{fmt(score['marker_rms_median_mm'], 2)} / {fmt(score['marker_vs_truth_rms_mm'], 2)}",
                    f"{solve_s:.2f} s",
                )
            )
    results.setdefault("a", {})["diagnostics"] = {"head": head.name, "cases": cases}
    table(
        f"a3. where the error comes from ({head.name}, the channels of a2, a fresh draw): '+' rows add to "
        "the row above",
        (
            "layout",
            "channels",
            "setup",
            "act. RMS",
            "mean |bias|",
            "act. max",
            "head RMS ° y/p/r",
            "marker mm: lib / truth",
            "solve",
        ),
        rows,
        "mean |bias|: the mean over channels of |mean error over the clip|, a constant offset rather than "
        "noise. HEAD_ROUNDS is mimetic.capture.performance's module constant, patched in this process only. "
        f"{time.perf_counter() - begin:.0f} s.",
    )


# --------------------------------------------------------------------------- b. video round trip


def bump(t: np.ndarray, start: float, peak: float, end: float) -> np.ndarray:
    """(f,) 0 before ``start`` and after ``end``, 1 at ``peak``, smooth in between."""
    up = smoothstep((t - start) / (peak - start))
    down = 1.0 - smoothstep((t - peak) / (end - peak))
    return np.where(t < peak, up, down)


def video_clip(rig: Rig, duration_s: float) -> Clip:
    """Smile, jaw open, brow raise and head yaw, each a smooth bump, after 0.5 s of neutral; times
    are fractions of ``duration_s`` past the neutral."""
    f = round(duration_s * VIDEO_FPS)
    t = np.arange(f) / VIDEO_FPS
    u = (t - NEUTRAL_S) / (duration_s - NEUTRAL_S)  # 0 .. 1 after the neutral
    values = np.zeros((f, len(rig.channels)))

    def put(name: str, curve: np.ndarray) -> None:
        if name in rig.channel_names:
            values[:, rig.channel_index(name)] = curve

    smile = 0.8 * bump(u, 0.0, 0.2, 0.55)
    jaw = 0.22 * bump(u, 0.25, 0.45, 0.7)
    brows = 0.9 * bump(u, 0.5, 0.7, 0.95)
    for side in ("L", "R"):
        put(f"zygomatic_major_{side}", smile)
        put(f"frontalis_inner_{side}", brows)
        put(f"frontalis_outer_{side}", brows)
    put("jaw_open", jaw)
    put("head_yaw", 0.25 * np.sin(2 * np.pi * np.clip(u, 0, 1)) * smoothstep(u / 0.1))
    return Clip(rig.channel_names, values, VIDEO_FPS)


def group_of(rig: Rig, name: str) -> str:
    for group, prefixes in GROUPS.items():
        if name.startswith(prefixes):
            return group
    return rig.channel(name).group


def score_video(rig: Rig, truth: Clip, perf: Performance) -> dict:
    """Error per channel group, correlation for moving channels, head yaw."""
    names = [n for n in rig.channel_names if n not in HEAD_CHANNELS]
    true = truth.select(names).values
    solved = perf.clip.select(names).values
    f = min(len(true), len(solved))
    true, solved = true[:f], solved[:f]
    groups: dict[str, list[int]] = {}
    for j, n in enumerate(names):
        groups.setdefault(group_of(rig, n), []).append(j)
    moving = [j for j in range(len(names)) if np.ptp(true[:, j]) > MOVING]
    per_group = {}
    for group, index in groups.items():
        err = solved[:, index] - true[:, index]
        moving_here = [j for j in index if j in moving]
        per_group[group] = {
            "channels": len(index),
            "rms": rms(err),
            "max": float(np.abs(err).max()),
            "moving": [names[j] for j in moving_here],
            "rms_moving": rms(solved[:, moving_here] - true[:, moving_here]) if moving_here else float("nan"),
            "r_group_sum": correlation(true[:, moving_here].sum(axis=1), solved[:, moving_here].sum(axis=1))
            if moving_here
            else float("nan"),
            "spurious_peak": max(
                (float(np.abs(solved[:, j]).max()) for j in index if j not in moving), default=0.0
            ),
        }
    curves_r = {names[j]: correlation(true[:, j], solved[:, j]) for j in moving}
    pooled = correlation(true[:, moving].ravel(), solved[:, moving].ravel()) if moving else float("nan")
    yaw_true = truth.select(["head_yaw"]).values[:f, 0]
    yaw = perf.head.angles()[:f, 0]
    return {
        "groups": per_group,
        "correlation": curves_r,
        "pooled_correlation": pooled,
        "yaw_rms_deg": rms(np.degrees(yaw - yaw_true)),
        "yaw_correlation": float(np.corrcoef(yaw_true, yaw)[0, 1]),
        "yaw_slope": float(np.polyfit(yaw_true, yaw, 1)[0]),
        "yaw_peak_deg": [float(np.degrees(np.abs(yaw_true).max())), float(np.degrees(np.abs(yaw).max()))],
        "flagged": int(perf.flagged.sum()),
        "marker_rms_median_rel": float(np.nanmedian(perf.marker_error) / rig.scale),
        "solved": len(perf.solved),
    }


def part_b(heads: list[Head], duration_s: float, results: dict, skipped: list[str]) -> None:
    console.rule("[bold]b. video round trip")
    from mimetic.capture.video import track_video
    from mimetic.view.video import render_clip

    out = results.setdefault(
        "b", {"duration_s": duration_s, "fps": VIDEO_FPS, "size": VIDEO_SIZE, "heads": []}
    )
    out["skipped"] = skipped
    group_rows, summary_rows = [], []
    for head in heads:
        markers = head.layout("mediapipe")
        if isinstance(markers, str):
            skipped.append(f"{head.name}: {markers}")
            continue
        begin = time.perf_counter()
        rig = head.rig
        truth = video_clip(rig, duration_s)
        path = OUT / f"roundtrip_{re.sub(r'[^A-Za-z0-9]+', '_', head.name).strip('_')}.mp4"
        _, render_s = timed(render_clip, rig, truth, path, engine="wire", size=VIDEO_SIZE)
        (tracked, notes), track_s = timed(quiet, track_video, path)
        noise = NOISE_MM / np.sqrt(3) * smooth_gain(VIDEO_FPS, CUTOFF_HZ) / mm_per_unit(rig)
        determined = determined_channels(rig, head.basis, markers, noise=noise, tolerance=TOLERANCE)
        animated = [
            n for n in rig.channel_names if n not in HEAD_CHANNELS and np.ptp(truth.select([n]).values) > 0
        ]
        record = {
            "head": head.name,
            "video": str(path),
            "frames": truth.n_frames,
            "render_s": render_s,
            "track_s": track_s,
            "tracked_fraction": float(tracked.seen.all(axis=1).mean()),
            "warnings": notes,
            "solves": {},
        }
        for label, active in (("all", None), ("determined", determined), ("animated (oracle)", animated)):
            (perf, _), solve_s = timed(
                quiet, solve_performance, rig, tracked, basis=head.basis, markers=markers, active=active
            )
            score = score_video(rig, truth, perf)
            score["solve_s"] = solve_s
            record["solves"][label] = score
            for group, g in score["groups"].items():
                if (
                    g["moving"]
                    or g["spurious_peak"] > 0.05
                    or group in ("brows/eyes", "cheeks/nose", "mouth", "jaw")
                ):
                    group_rows.append(
                        (
                            head.name,
                            label,
                            group,
                            g["channels"],
                            fmt(g["rms"]),
                            fmt(g["max"]),
                            ", ".join(g["moving"]) or "-",
                            fmt(g["rms_moving"]),
                            fmt(g["r_group_sum"], 2),
                            fmt(g["spurious_peak"], 2),
                        )
                    )
            corr = score["correlation"]
            summary_rows.append(
                (
                    head.name,
                    label,
                    score["solved"],
                    fmt(score["pooled_correlation"]),
                    ", ".join(f"{n} {fmt(r, 2)}" for n, r in corr.items()),
                    f"{fmt(score['yaw_rms_deg'], 2)} (r {fmt(score['yaw_correlation'], 3)}, slope "
                    f"{fmt(score['yaw_slope'], 2)}; peak {score['yaw_peak_deg'][0]:.1f}° → "
                    f"{score['yaw_peak_deg'][1]:.1f}°)",
                    fmt(100 * score["marker_rms_median_rel"], 2),
                    score["flagged"],
                    f"{solve_s:.2f} s",
                )
            )
        record["total_s"] = time.perf_counter() - begin
        out["heads"].append(record)
        console.print(
            f"   {head.name}: {truth.n_frames} frames rendered in {render_s:.1f} s, tracked in "
            f"{track_s:.1f} s "
            f"({record['tracked_fraction']:.0%} of frames with a face), determined: {', '.join(determined)}; "
            f"head total {record['total_s']:.0f} s (rig + bake {head.build_s:.0f} s before)"
        )
    table(
        "b1. video round trip: error per channel group (solved − true, activation units; jaw in rad/rel)",
        (
            "head",
            "active",
            "group",
            "channels",
            "RMS",
            "max",
            "moving channels",
            "RMS moving",
            "r of sums",
            "largest spurious",
        ),
        group_rows,
        "r of sums: correlation of the summed true and summed solved curves of the moving channels (whether "
        "the group's motion is found, however it is split between them). largest spurious: the largest "
        "|value| solved for a channel of the group that does not move in the truth.",
    )
    table(
        "b2. video round trip: correlation of true and solved curves (channels that move) and head yaw",
        (
            "head",
            "active",
            "solved",
            "pooled r",
            "r per moving channel",
            "yaw RMS ° (r, slope; peak true → solved)",
            "marker RMS % head",
            "flagged",
            "solve",
        ),
        summary_rows,
        "\n".join(skipped),
    )


PERSPECTIVE_FOVS_DEG = (28.0, 8.0, 3.0)
"""Vertical fields of view of table b3: ``render_clip``'s (``face_camera``'s default) and two narrower
ones, the camera moved back to frame the same face (3° is nearly orthographic)."""


def part_b_perspective(head: Head, results: dict) -> None:
    """Head yaw alone (0.3 rad peak, no expression) rendered at each of ``PERSPECTIVE_FOVS_DEG``, tracked
    and solved: how much of the yaw error is the camera's perspective (table b3)."""
    from mimetic.capture.video import track_video
    from mimetic.engines import make_engine
    from mimetic.render.renderer import default_renderer
    from mimetic.view.look import rig_look
    from mimetic.view.sheets import face_camera
    from mimetic.view.video import write_mp4

    rig = head.rig
    markers = head.layout("mediapipe")
    if isinstance(markers, str):
        return
    engine, renderer, look = make_engine(rig, "wire"), default_renderer(), rig_look(rig)
    t = np.arange(round(2.0 * VIDEO_FPS)) / VIDEO_FPS
    values = np.zeros((len(t), len(rig.channels)))
    yaw = 0.3 * np.sin(np.pi * np.clip((t - NEUTRAL_S) / 1.5, 0.0, 1.0))
    values[:, rig.channel_index("head_yaw")] = yaw
    rows, cases = [], []
    for fov in PERSPECTIVE_FOVS_DEG:
        camera = face_camera(rig, fov_y_deg=fov)
        frames = (
            renderer.render(
                rig.mesh.with_vertices(engine.deform(v)), camera, size=(VIDEO_SIZE, VIDEO_SIZE), look=look
            )
            for v in values
        )
        path = OUT / f"yaw_fov{fov:g}.mp4"
        write_mp4(frames, path, fps=VIDEO_FPS, size=(VIDEO_SIZE, VIDEO_SIZE))
        tracked, _ = quiet(track_video, path)
        perf, _ = quiet(
            solve_performance, rig, tracked, basis=head.basis, markers=markers, active=["jaw_open"]
        )
        solved = perf.head.angles()
        distance = float(np.linalg.norm(camera.eye - camera.target))
        case = {
            "fov_deg": fov,
            "distance": distance,
            "true_peak_deg": float(np.degrees(yaw.max())),
            "solved_peak_deg": float(np.degrees(solved[:, 0].max())),
            "slope": float(np.polyfit(yaw, solved[:, 0], 1)[0]),
            "pitch_roll_max_deg": [float(np.degrees(np.abs(solved[:, k]).max())) for k in (1, 2)],
        }
        cases.append(case)
        rows.append(
            (
                f"{fov:g}°",
                f"{distance:.0f} {rig.units}",
                f"{case['true_peak_deg']:.1f}° → {case['solved_peak_deg']:.1f}°",
                fmt(case["slope"], 3),
                " / ".join(fmt(x, 2) for x in case["pitch_roll_max_deg"]),
            )
        )
    results.setdefault("b", {})["perspective"] = {"head": head.name, "cases": cases}
    table(
        f"b3. head yaw alone ({head.name}), rendered at three fields of view (camera distance to frame the "
        "face), tracked, solved (active=jaw_open only)",
        (
            "fov",
            "camera distance",
            "yaw peak true → solved",
            "slope solved/true",
            "spurious |pitch| / |roll| max °",
        ),
        rows,
        "render_clip uses face_camera's default 28°. A slope near 1 at 3° and above 1 at 28° says the "
        "over-estimate comes from perspective, which the px-unit head fit (a similarity) does not model.",
    )


# --------------------------------------------------------------------------- c. OpenFace sample


def openface_pose(path: Path) -> np.ndarray:
    """(f, 3) OpenFace's pose_Rx, pose_Ry, pose_Rz (radians) from its CSV."""
    data = np.genfromtxt(path, delimiter=",", names=True, autostrip=True)
    return np.stack([data["pose_Rx"], data["pose_Ry"], data["pose_Rz"]], axis=1)


def openface_head_angles(
    pose: np.ndarray, calibration_rotation: np.ndarray, neutral_frame: int
) -> np.ndarray:
    """OpenFace's head rotation as the rig's (yaw, pitch, roll) (f, 3) relative to ``neutral_frame``
    (see the module docstring, part c)."""
    Rc = np.array([rotation_x(x) @ rotation_y(y) @ rotation_z(z) for x, y, z in pose])  # camera frame
    flip = np.diag([1.0, -1.0, -1.0])  # camera (+Y down, +Z away) → capture (+Y up, +Z toward)
    motion = flip @ (Rc @ Rc[neutral_frame].T) @ flip  # (f, 3, 3) from the neutral, capture frame
    R0 = calibration_rotation
    return angles_of(R0 @ motion @ R0.T)


AU_CHANNELS = {
    "AU01_r": ("frontalis_inner_L", "frontalis_inner_R"),
    "AU02_r": ("frontalis_outer_L", "frontalis_outer_R"),
    "AU04_r": ("corrugator_L", "corrugator_R", "procerus"),
    "AU45_r": ("orbicularis_oculi_L", "orbicularis_oculi_R", "eyelid_upper_L", "eyelid_upper_R"),
    "AU26_r": ("jaw_open",),
    "AU23_r": ("orbicularis_oris", "orbicularis_oris_marginalis_upper", "orbicularis_oris_marginalis_lower"),
    "AU45_r ": ("gaze_pitch",),
}
"""OpenFace's active action units (its PROVENANCE) and the rig channels that make them. The second AU45
row (a trailing space keeps the key apart) is gaze_pitch, which iBUG-68 cannot see (no iris) but which
moves the rig's lids (they follow the gaze), so the solve uses it; > 0 looks up."""


def au_correlations(path: Path, perf: Performance) -> tuple[list[tuple], dict]:
    data = np.genfromtxt(path, delimiter=",", names=True, autostrip=True)
    rows, out = [], {}
    for au, channels in AU_CHANNELS.items():
        if au.strip() not in data.dtype.names:
            continue
        intensity = data[au.strip()]
        present = [n for n in channels if n in perf.clip.channels]
        curves = perf.clip.select(present).values  # (f, k)
        total = curves.sum(axis=1)

        per = {n: correlation(intensity, curves[:, k]) for k, n in enumerate(present)}
        peaks = {n: float(np.abs(curves[:, k]).max()) for k, n in enumerate(present)}
        r_sum = correlation(intensity, total)
        out[au] = {"range": [float(intensity.min()), float(intensity.max())], "r_sum": r_sum, "r": per}
        rows.append(
            (
                au,
                f"{intensity.min():.2f} .. {intensity.max():.2f}",
                len(present),
                fmt(r_sum, 2),
                ", ".join(f"{n} {fmt(per[n], 2)} ({peaks[n]:.2f})" for n in present),
            )
        )
    return rows, out


def extract_frame(video: Path, index: int) -> np.ndarray:
    import imageio_ffmpeg

    reader = imageio_ffmpeg.read_frames(str(video), pix_fmt="rgb24")
    meta = next(reader)
    width, height = meta["size"]
    try:
        for k, raw in enumerate(reader):
            if k == index:
                return np.frombuffer(raw, np.uint8).reshape(height, width, 3).copy()
    finally:
        reader.close()
    raise ValueError(f"{video}: no frame {index}")


def part_c(rig: Rig, basis: Basis, target: Rig, rig_name: str, results: dict) -> None:
    console.rule("[bold]c. OpenFace sample")
    from mimetic.view.sheet import save_png
    from mimetic.view.video import render_clip

    root = shared_data_dir()
    if root is None or not (root / OPENFACE).is_file():
        console.print(f"OpenFace sample not found (shared data {root}): part c skipped")
        results["c"] = {"skipped": "no shared data"}
        return
    path = root / OPENFACE
    trajectories, read_notes = quiet(read_trajectories, path, fps=OPENFACE_FPS)
    (perf, solve_notes), solve_s = timed(quiet, solve_performance, rig, trajectories, basis=basis)
    report = perf.report(rig)
    table(
        f"c1. Performance.report on {rig_name} ({rig.n_vertices:,} vertices, head height "
        f"{rig.scale:.1f} {rig.units}), solve {solve_s:.2f} s",
        ("key", "value"),
        [
            (k, json.dumps(v) if isinstance(v, dict | list) else (fmt(v, 4) if isinstance(v, float) else v))
            for k, v in report.items()
        ],
        "\n".join(f"warning: {w}" for w in read_notes + solve_notes),
    )
    per_frame = perf.outliers.sum(axis=1)
    step = np.linalg.norm(np.diff(trajectories.positions, axis=0), axis=2)  # (f - 1, 68) mm
    typical = float(np.nanmedian(step))
    tz = np.genfromtxt(path, delimiter=",", names=True, autostrip=True)["pose_Tz"]
    jumps = {
        int(t): {
            "outliers": int(per_frame[t]),
            "median_step_mm": float(np.nanmedian(step[t - 1])) if t else float("nan"),
            "spread_step_mm": float(np.nanstd(step[t - 1])) if t else float("nan"),
            "pose_Tz_step_mm": float(tz[t] - tz[t - 1]) if t else float("nan"),
        }
        for t in np.flatnonzero(per_frame)
    }
    console.print(
        f"   outlier samples per frame: {jumps or 'none'}; flagged frames "
        f"{np.flatnonzero(perf.flagged).tolist()[:10]}; frames whose head fit failed "
        f"{int((~perf.head.fitted).sum())}; typical landmark step {typical:.2f} mm per frame. A frame whose "
        "landmarks all step alike (small spread) and step back moved rigidly for one frame (OpenFace's "
        "depth, pose_Tz): a tracker glitch, which the smoother (it runs on the captured points, before the "
        "head motion is taken out) rejects landmark by landmark."
    )
    pose = openface_pose(path)
    theirs = openface_head_angles(pose, perf.calibration.rotation, perf.neutral_frame)
    ours = perf.head.angles()
    axis_rows, axes = [], {}
    for k, axis in enumerate(("yaw", "pitch", "roll")):
        r = float(np.corrcoef(ours[:, k], theirs[:, k])[0, 1])
        raw_r = [float(np.corrcoef(ours[:, k], pose[:, j])[0, 1]) for j in range(3)]
        slope = float(np.polyfit(theirs[:, k], ours[:, k], 1)[0])
        diff = np.degrees(ours[:, k] - theirs[:, k])
        axes[axis] = {"r": r, "slope": slope, "rms_diff_deg": rms(diff), "r_with_pose_Rx_Ry_Rz": raw_r}
        axis_rows.append(
            (
                axis,
                fmt(np.degrees(np.ptp(ours[:, k])), 2),
                fmt(np.degrees(np.ptp(theirs[:, k])), 2),
                fmt(r),
                fmt(slope, 2),
                fmt(rms(diff), 2),
                " / ".join(fmt(x, 2) for x in raw_r),
            )
        )
    table(
        "c2. head rotation: solved vs OpenFace's pose_R* (mapped to the rig's yaw/pitch/roll, relative to "
        "the neutral frame)",
        (
            "axis",
            "solved range °",
            "OpenFace range °",
            "r",
            "slope",
            "RMS diff °",
            "r with raw pose_Rx / Ry / Rz",
        ),
        axis_rows,
        "Expected raw signs: yaw ↔ −pose_Ry, pitch ↔ +pose_Rx, roll ↔ +pose_Rz (the flip diag(1, −1, −1) "
        "and roll = −rotation about +Z).",
    )
    au_rows, au_out = au_correlations(path, perf)
    table(
        "c3. solved channels against OpenFace's own action units (its AUxx_r intensities), Pearson r",
        ("AU", "OpenFace range", "channels", "r of their sum", "r per channel (peak solved)"),
        au_rows,
        "A plausibility check only: OpenFace's AUs are another model's output, not ground truth.",
    )
    (clip, retarget_notes) = quiet(retarget, perf.clip, target)
    video = OUT / "openface_retargeted.mp4"
    _, render_s = timed(render_clip, target, clip, video, engine="wire", size=VIDEO_SIZE)
    solved = [perf.clip.channels.index(n) for n in perf.solved]
    frame = int(np.argmax(np.abs(perf.clip.values[:, solved]).sum(axis=1)))
    png = save_png(extract_frame(video, frame), OUT / "openface_retargeted.png")
    rest = save_png(extract_frame(video, perf.neutral_frame), OUT / "openface_retargeted_neutral.png")
    console.print(
        f"   retargeted onto {target.n_vertices:,}-vertex identity (HeadParams.random({RETARGET_SEED})); "
        f"{video.name} rendered in {render_s:.1f} s; frame {frame} (most active) → {png.name}, frame "
        f"{perf.neutral_frame} → {rest.name}" + ("; " + "; ".join(retarget_notes) if retarget_notes else "")
    )
    results["c"] = {
        "rig": rig_name,
        "solve_s": solve_s,
        "report": report,
        "warnings": read_notes + solve_notes,
        "outlier_frames": jumps,
        "head_vs_openface": axes,
        "action_units": au_out,
        "retarget_warnings": retarget_notes,
        "video": str(video),
        "frame": frame,
        "png": str(png),
    }


# --------------------------------------------------------------------------- main


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="small heads and short clips (< 90 s)")
    parser.add_argument("--parts", default="abc", help="which parts to run: any of a, b, c (default abc)")
    args = parser.parse_args()
    begin = time.perf_counter()
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / ".gitignore").write_text("*\n")  # outputs, never committed
    load = os.getloadavg()
    console.print(
        f"load average at start {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f} (1 / 5 / 15 min; 2 cores); "
        f"quick={args.quick}"
    )
    results: dict = {"quick": args.quick}
    resolution = "small" if args.quick else "full"
    if "a" in args.parts:
        small = make_case("small rig", small_rig)
        random_head = make_case(
            f"random s{RANDOM_SEED} ({resolution})",
            lambda: generated_rig(HeadParams.random(RANDOM_SEED), args.quick),
        )
        heads = [small, random_head]
        console.print(
            "heads: "
            + "; ".join(
                f"{h.name} {h.rig.n_vertices:,} vertices, {h.rig.scale:.1f} {h.rig.units} "
                f"({h.build_s:.1f} s rig + bake)"
                for h in heads
            )
        )
        duration = 3.0 if args.quick else 10.0
        part_a(heads, duration, results)
        layouts = ("ibug68", "mediapipe") if args.quick else LAYOUTS
        part_a_diagnostics(small, layouts, DIAGNOSTICS[:-1] if args.quick else DIAGNOSTICS, duration, results)
        results["a"]["wall_s"] = time.perf_counter() - begin
        console.print(f"   part a: {results['a']['wall_s']:.0f} s")
    default_head = None
    begin_b = time.perf_counter()
    if "b" in args.parts or "c" in args.parts:
        default_head = make_case(f"default ({resolution})", lambda: generated_rig(None, args.quick))
    if "b" in args.parts:
        heads, skipped = [default_head], []
        if args.quick:
            skipped.append("ICT: full run only (rig ~6 s, bake ~4 s, 0.2 s per rendered frame)")
        elif shared_data_dir() is None or not (shared_data_dir() / "ict-facekit").is_dir():
            skipped.append("ICT: the shared data's ict-facekit is missing")
        else:
            heads.append(make_case("ICT file", ict_rig))
        part_b(heads, 2.5 if args.quick else 4.0, results, skipped)
        if not args.quick:
            part_b_perspective(default_head, results)
        results["b"]["wall_s"] = time.perf_counter() - begin_b
        console.print(f"   part b: {results['b']['wall_s']:.0f} s (with the default head's rig + bake)")
    if "c" in args.parts:
        begin_c = time.perf_counter()
        target = generated_rig(HeadParams.random(RETARGET_SEED), args.quick)
        part_c(
            default_head.rig,
            default_head.basis,
            target,
            f"the default generated rig ({resolution} resolution)",
            results,
        )
        results["c"]["wall_s"] = time.perf_counter() - begin_c
        console.print(f"   part c: {results['c']['wall_s']:.0f} s")
    results["wall_s"] = time.perf_counter() - begin
    write_json(results, OUT / "validation.json")
    console.print(
        f"\nwrote {OUT / 'validation.json'}; wall time {results['wall_s']:.0f} s; load average at the end "
        f"{os.getloadavg()[0]:.2f}"
    )


if __name__ == "__main__":
    main()
