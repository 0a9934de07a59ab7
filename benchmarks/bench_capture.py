"""Benchmark performance capture (``mimetic.capture``): the per-frame marker solve, the whole-clip
temporal solve, the whole ``solve_performance`` chain and video tracking.

    python benchmarks/bench_capture.py [--quick]

The problem: ``mimetic.testing.small_rig()`` baked by the wire engine (``bake(..., correctives=0,
samples=2)``), its 68 iBUG markers (``marker_set(rig, "ibug68")``; the 17 jaw-line markers slide)
and the 50 channels that move them most (of the channels the markers see). A synthetic clip at
60 fps (``clip_activations``): sparse, slowly varying activations (each channel at rest most of
the time, raised by smooth bumps of 0.6-3 s, about a quarter of the channels active at once),
neutral for the first half second; the markers are the baked basis evaluated on the rig
(``evaluate_basis`` then ``MarkerSet.positions``) plus Gaussian noise of 1 mm per coordinate.

Tables, after the load average at the start (the machine is shared; times move with it):

1. Per-frame solve, ``MarkerSolver.solve`` (``prepare_marker_solver``, regularization 1e-3,
   sparsity 0) on every frame, all markers seen (one shared normal matrix), and
   ``box_qp_frames`` alone on its normal equations. Baseline, in the same run:
   ``scipy.optimize.lsq_linear(method="bvls")`` per frame on the same objective (the projected
   marker rows with the damping rows sqrt(damping)·I stacked under them, the projected markers
   over zeros), timed on ``BASELINE_FRAMES`` frames spread over the clip and extrapolated per
   frame (BLAS limited to ``BASELINE_BLAS_THREADS`` thread); the largest |difference| of the
   answers on those frames. Beside the goal problem (raw markers, 1 mm noise): the same frames
   without noise, and the markers smoothed at 8 Hz (what ``solve_performance`` solves), since the
   cost of a frame grows with the number of channels whose bound changes from the frame before.
   Goals: >= 10,000 frames/s, >= 20x the baseline, answers within 1e-6.
2. Whole-clip temporal solve, ``smooth_markers`` (robust, cutoff 8 Hz) then ``MarkerSolver.solve``
   on the smoothed markers (the module docstring of ``capture.performance`` shows that this is
   the clip-wide solve with the markers' acceleration penalised): on the noisy markers, and on
   the same with 10 % of the samples dropped (in runs of 1-30 frames) and 2 % spikes of 1-3 cm.
   Baseline: the per-frame solve of the raw noisy markers (what smoothing adds). Goal: 10,000
   frames in <= 2 s. Then the whole ``solve_performance`` chain on the spiked, gappy clip with
   head motion (yaw ±0.25, pitch ±0.12, roll ±0.08 rad, translation ±1.5 cm), in millimetres,
   with no goal: its time, its stages from the ``progress`` callback's timestamps, the time
   inside ``MarkerSolver.solve`` and ``head_motion`` (one instrumented call, the functions
   wrapped by timers), and its errors against the truth.
3. Video: ``track_video`` on a clip of the small rig rendered by ``render_clip`` (the wire engine,
   so the head turns; 60 frames at 30 fps, at 256² and 512²), against decoding alone
   (``imageio_ffmpeg.read_frames``) in the same run; throughput of whole calls and after the
   first frame (FaceMesh's graph is built per call). Skipped with a note without mediapipe
   (extra ``[track]``).

Then a summary: goal | measured | met. The share of the cores other processes used while the
goals were timed is printed beside them (from ``/proc/stat``): the machine is shared, and a busy
neighbour slows the compiled solve (two threads) about twofold. ``--quick``: ``QUICK_FRAMES``
frames, ``QUICK_BASELINE_FRAMES`` baseline frames, one round of the chain, 30 video frames at
256² only (under a minute); the temporal goal is then judged on the time scaled to 10,000
frames (every step is linear in the frame count).
"""

from __future__ import annotations

import argparse
import importlib.util
import itertools
import os
import statistics
import tempfile
import time
import warnings
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numba
import numpy as np
from scipy.linalg import cho_factor, cho_solve
from scipy.optimize import lsq_linear
from threadpoolctl import threadpool_limits

import mimetic.capture.performance as performance
import mimetic.capture.smooth as smoothing
import report
from bench_basis import print_table, round_robin, table
from mimetic.capture.expression import MIN_MOVE_REL, MarkerSolver, prepare_marker_solver
from mimetic.capture.markers import MarkerSet, marker_set
from mimetic.capture.performance import CUTOFF_HZ, solve_performance
from mimetic.capture.qp import box_qp_frames
from mimetic.capture.trajectories import Trajectories
from mimetic.engines import make_engine
from mimetic.engines.bake import bake
from mimetic.engines.basis import Basis, evaluate_basis
from mimetic.errors import MimeticWarning, MissingExtraError
from mimetic.mesh.units import UNIT_SCALE
from mimetic.rig.activations import Clip
from mimetic.rig.model import Rig
from mimetic.testing import small_rig

TABLES: list[str] = []
"""The tables written to ``out/capture.md`` (``report.save``), in order."""
FPS = 60.0
FRAMES, QUICK_FRAMES = 10_000, 2_000
BASELINE_FRAMES, QUICK_BASELINE_FRAMES = 300, 100
CHANNELS = 50
LAYOUT = "ibug68"
NOISE_M = 1e-3
"""Marker noise, standard deviation per coordinate (1 mm)."""
DROPPED = 0.10
"""Share of marker samples missing, in runs of 1 to 2 · DROP_RUN_MEAN − 1 frames."""
DROP_RUN_MEAN = 15
SPIKES = 0.02
"""Share of the seen marker samples moved by SPIKE_M (uniform) in a random direction."""
SPIKE_M = (0.01, 0.03)
BUMP_HALF_S = (0.3, 1.5)
"""Half-widths of the raised-cosine bumps that move a channel."""
BUMP_EVERY_S = 6.0
"""One bump per channel every this many seconds, on average."""
NEUTRAL_S = 0.5
"""The clip starts neutral (activations 0, head still) for this long: frame 0 calibrates."""
HEAD_AMPLITUDE_RAD = (0.25, 0.12, 0.08)
"""yaw, pitch, roll."""
HEAD_TRANSLATION_M = 0.015
CAPTURE_UNITS = "mm"
CAPTURE_OFFSET = np.array([120.0, 1600.0, -40.0])
"""Where the capture's origin puts the rig's, in capture units (the capture is not in the rig's frame)."""
REGULARIZATION = 1e-3
BASELINE_BLAS_THREADS = 1
"""BLAS threads of the lsq_linear baseline: its products are small, so OpenBLAS's threads gain nothing on
an idle machine and made it 7-17× slower while another process held a core (which would flatter the ratio)."""
GOAL_FPS = 10_000
GOAL_SPEEDUP = 20.0
GOAL_DIFFERENCE = 1e-6
GOAL_TEMPORAL_S = 2.0
GOAL_TEMPORAL_FRAMES = 10_000
GOAL_QUICK_S = 60.0
VIDEO_FPS = 30.0


@dataclass(frozen=True)
class Problem:
    """The rig, its basis and markers, and the channels solved for."""

    rig: Rig
    basis: Basis
    markers: MarkerSet
    free: np.ndarray  # (k,) int64: the solved channels, indices into basis.channels
    deltas: np.ndarray  # (k, m, 3): their marker displacements per unit, rig units
    lower: np.ndarray  # (k,)
    upper: np.ndarray  # (k,)
    solver: MarkerSolver
    metre: float  # rig units per metre
    left_out: tuple[str, ...]  # channels the markers see (as solve_performance decides) not solved for

    @property
    def names(self) -> list[str]:
        return [self.basis.channels[j] for j in self.free]


@dataclass(frozen=True)
class Capture:
    """A synthetic clip: the truth and the markers made from it."""

    activations: np.ndarray  # (f, k) on Problem.free
    motion: np.ndarray  # (f, m, 3) marker displacements from rest, rig units, noise-free
    noise: np.ndarray  # (f, m, 3) the noise added to them, rig units
    missing: np.ndarray  # (f, m) bool: dropped samples
    spikes: np.ndarray  # (f, m) bool
    spike_offsets: np.ndarray  # (f, m, 3) rig units (zero but at spikes)

    def noisy(self) -> np.ndarray:
        return self.motion + self.noise

    def damaged(self) -> np.ndarray:
        """Noisy markers with the spikes added and NaN where dropped."""
        y = self.motion + self.noise + self.spike_offsets
        return np.where(self.missing[..., None], np.nan, y)


# --------------------------------------------------------------------------- cases


def prepare(rig: Rig) -> Problem:
    basis = bake(make_engine(rig, "wire"), correctives=0, samples=2).basis
    markers = marker_set(rig, LAYOUT)
    all_deltas = np.einsum("mn,cnd->cmd", markers.weights(rig).toarray(), basis.deltas)  # (c, m, 3)
    effect = np.sqrt(np.einsum("cmd,cmd->c", all_deltas, all_deltas))
    free = np.sort(np.argsort(-effect, kind="stable")[:CHANNELS])
    seen = np.flatnonzero(effect > MIN_MOVE_REL * effect.max())
    left_out = tuple(basis.channels[j] for j in np.setdiff1d(seen, free))
    by_name = {ch.name: ch for ch in rig.channels}
    lower = np.array([by_name[basis.channels[j]].minimum for j in free])
    upper = np.array([by_name[basis.channels[j]].maximum for j in free])
    deltas = all_deltas[free]
    solver = prepare_marker_solver(deltas, markers, lower, upper, regularization=REGULARIZATION, sparsity=0.0)
    metre = 1.0 / UNIT_SCALE[rig.units]
    return Problem(rig, basis, markers, free, deltas, lower, upper, solver, metre, left_out)


def bumps(frames: int, amplitude: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """(frames, k): each column at 0, raised by raised-cosine bumps (one per BUMP_EVERY_S on average,
    half-width in BUMP_HALF_S, peak amplitude[k] · U(0.2, 1), sign random where ``amplitude`` is
    (2, k) [negative extreme; positive extreme])."""
    low, high = amplitude
    out = np.zeros((frames, len(high)))
    for k in range(len(high)):
        for _ in range(rng.poisson(frames / FPS / BUMP_EVERY_S)):
            centre = rng.uniform(0, frames)
            half = rng.uniform(*BUMP_HALF_S) * FPS
            a, b = max(0, int(centre - half)), min(frames, int(centre + half) + 1)
            u = (np.arange(a, b) - centre) / half
            toward = high[k] if rng.random() < high[k] / (high[k] - low[k]) else low[k]
            out[a:b, k] += toward * rng.uniform(0.2, 1.0) * 0.5 * (1 + np.cos(np.pi * np.clip(u, -1, 1)))
    return out


def neutral_start(frames: int) -> np.ndarray:
    """(frames,): 0 for NEUTRAL_S, then rising smoothly to 1 over the next NEUTRAL_S."""
    u = np.clip((np.arange(frames) / FPS - NEUTRAL_S) / NEUTRAL_S, 0, 1)
    return u * u * (3 - 2 * u)


def clip_activations(problem: Problem, frames: int, rng: np.random.Generator) -> np.ndarray:
    """(frames, k) sparse, slowly varying activations within the channels' ranges."""
    amplitude = np.stack([np.minimum(problem.lower, 0.0), problem.upper])
    a = bumps(frames, amplitude, rng) * neutral_start(frames)[:, None]
    return np.clip(a, problem.lower, problem.upper)


def marker_motion(problem: Problem, activations: np.ndarray, chunk: int = 500) -> np.ndarray:
    """(f, m, 3) displacements of the markers from rest: ``evaluate_basis`` on the rig, in chunks."""
    rig, basis = problem.rig, problem.basis
    rest = problem.markers.positions(rig)
    full = np.zeros((len(activations), basis.n_channels))
    full[:, problem.free] = activations
    out = np.empty((len(activations), problem.markers.n_markers, 3))
    for lo in range(0, len(full), chunk):
        vertices = evaluate_basis(basis, full[lo : lo + chunk])  # (chunk, n, 3)
        out[lo : lo + chunk] = problem.markers.positions(rig, vertices) - rest
    return out


def make_capture(problem: Problem, frames: int, seed: int = 0) -> Capture:
    rng = np.random.default_rng(seed)
    activations = clip_activations(problem, frames, rng)
    motion = marker_motion(problem, activations)
    f, m, _ = motion.shape
    noise = rng.normal(0.0, NOISE_M * problem.metre, motion.shape)
    missing = np.zeros((f, m), bool)
    runs = round(DROPPED * f * m / DROP_RUN_MEAN)
    for t, j, length in zip(
        rng.integers(1, f, runs),
        rng.integers(0, m, runs),
        rng.integers(1, 2 * DROP_RUN_MEAN, runs),
        strict=True,
    ):
        missing[t : t + length, j] = True
    spikes = ~missing & (rng.random((f, m)) < SPIKES)
    spikes[0] = False  # the neutral frame calibrates
    direction = rng.normal(size=(f, m, 3))
    direction /= np.linalg.norm(direction, axis=2, keepdims=True)
    size = rng.uniform(*SPIKE_M, (f, m, 1)) * problem.metre
    offsets = np.where(spikes[..., None], direction * size, 0.0)
    return Capture(activations, motion, noise, missing, spikes, offsets)


def rotations(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """(f, 3, 3) R_y(yaw) R_x(pitch) R_z(−roll), as the rig composes its head channels."""
    f = len(yaw)

    def axis(angle: np.ndarray, i: int, j: int) -> np.ndarray:
        R = np.tile(np.eye(3), (f, 1, 1))
        c, s = np.cos(angle), np.sin(angle)
        R[:, i, i], R[:, j, j], R[:, i, j], R[:, j, i] = c, c, -s, s
        return R

    return axis(yaw, 2, 0) @ axis(pitch, 1, 2) @ axis(-roll, 0, 1)


def head_clip(frames: int, scale: float, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Smooth head motion: angles (f, 3) yaw, pitch, roll in rad and translation (f, 3) in rig units
    (``scale``: rig units per metre), still for the first NEUTRAL_S."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None] / FPS
    ramp = neutral_start(frames)[:, None]

    def wander(amplitude: np.ndarray) -> np.ndarray:
        hz = rng.uniform(0.05, 0.3, (2, len(amplitude)))
        phase = rng.uniform(0, 2 * np.pi, (2, len(amplitude)))
        wave = 0.5 * (np.sin(2 * np.pi * hz[0] * t + phase[0]) + np.sin(2 * np.pi * hz[1] * t + phase[1]))
        return ramp * amplitude * wave

    return wander(np.array(HEAD_AMPLITUDE_RAD)), wander(np.full(3, HEAD_TRANSLATION_M * scale))


def capture_trajectories(
    problem: Problem, capture: Capture, angles: np.ndarray, shift: np.ndarray
) -> Trajectories:
    """The damaged markers moved by the head (about the rig's head joint) and put in millimetres."""
    rig = problem.rig
    pivot = rig.bone("head").head
    rest = problem.markers.positions(rig)
    R = rotations(*angles.T)  # (f, 3, 3)
    points = np.einsum(
        "fij,fmj->fmi", R, rest + capture.motion + capture.noise + capture.spike_offsets - pivot
    )
    points += pivot + shift[:, None]
    factor = UNIT_SCALE[rig.units] / UNIT_SCALE[CAPTURE_UNITS]
    points = np.where(capture.missing[..., None], np.nan, points * factor + CAPTURE_OFFSET)
    return Trajectories(problem.markers.names, points, FPS, CAPTURE_UNITS, source="synthetic")


# --------------------------------------------------------------------------- helpers


def smooth_markers(y: np.ndarray, fps: float, cutoff_hz: float, *, robust: bool = True, size: float = 1.0):
    """``capture.smooth.smooth_points``'s smoothed points and outliers."""
    result = smoothing.smooth_points(y, fps, cutoff_hz, robust=robust, size=size)
    return result.points, result.outliers


def projected(solver: MarkerSolver, y: np.ndarray) -> np.ndarray:
    """(f, m, 3): P_j y_tj (the sliding markers' motion along their contour taken out)."""
    out = y.copy()
    s = solver.sliding
    out[:, s] = np.einsum("mij,fmj->fmi", solver.projectors[s], y[:, s])
    return out


def normal_equations(solver: MarkerSolver, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """H (k, k) and g (f, k) of ``MarkerSolver.solve`` with every marker seen at weight 1."""
    f, m, _ = y.shape
    H = solver.normal(np.ones((1, m)))[0]
    g = projected(solver, y).reshape(f, 3 * m) @ solver.rows.reshape(3 * m, -1) - solver.linear
    return H, g


def bvls(solver: MarkerSolver, y: np.ndarray, frames: np.ndarray, out: np.ndarray) -> None:
    """``lsq_linear(method="bvls")`` on each of ``frames``: min ‖[R; sqrt(damping) I] a − [P y; 0]‖²
    within the bounds, the objective of ``MarkerSolver.solve`` (sparsity 0) as least squares."""
    m, k = solver.rows.shape[0], solver.rows.shape[2]
    A = np.vstack([solver.rows.reshape(3 * m, k), np.linalg.cholesky(solver.prior()).T])
    b = np.zeros(3 * m + k)
    targets = projected(solver, y[frames]).reshape(len(frames), 3 * m)
    with threadpool_limits(BASELINE_BLAS_THREADS, "blas"):
        for i in range(len(frames)):
            b[: 3 * m] = targets[i]
            out[i] = lsq_linear(A, b, bounds=(solver.lower, solver.upper), method="bvls").x


def bound_changes(x: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> tuple[float, float]:
    """Mean channels on a bound per frame, and mean channels whose bound changes from the frame before."""
    at = np.where(x <= lower, -1, np.where(x >= upper, 1, 0))
    return float((at != 0).sum(1).mean()), float((at[1:] != at[:-1]).sum(1).mean())


class Contention:
    """How busy the rest of the machine kept its cores since ``start`` (Linux ``/proc/stat`` less this
    process's own CPU time); None where ``/proc/stat`` is missing."""

    def __init__(self) -> None:
        self.start = self._sample()

    @staticmethod
    def _sample() -> tuple[float, float, float] | None:
        try:
            with open("/proc/stat") as file:
                ticks = [int(n) for n in file.readline().split()[1:]]
        except OSError:
            return None
        hz = os.sysconf("SC_CLK_TCK")
        own = os.times()
        return sum(ticks) / hz, (ticks[3] + ticks[4]) / hz, own.user + own.system  # total, idle, ours (s)

    def others(self) -> float | None:
        """Share of the cores' time used by other processes since ``start``."""
        end = self._sample()
        if self.start is None or end is None:
            return None
        total, idle, ours = (b - a for a, b in zip(self.start, end, strict=True))
        return max(0.0, (total - idle - ours) / max(total, 1e-9))

    def note(self) -> str:
        share = self.others()
        return "" if share is None else f"other processes kept {share:.0%} of the cores busy"


def rms(a: np.ndarray) -> float:
    return float(np.sqrt(np.nanmean(a**2)))


def verdict(met: bool) -> str:
    return "met" if met else "NOT met"


# --------------------------------------------------------------------------- 1. per-frame solve


def bench_per_frame(problem: Problem, capture: Capture, n_baseline: int, rounds: int) -> dict[str, float]:
    solver = problem.solver
    f, m, _ = capture.motion.shape
    print(
        f"\n1. Per-frame solve: {len(problem.free)} channels, {m} iBUG markers "
        f"({int(problem.markers.sliding.sum())} sliding), {f:,} frames at {FPS:g} fps, all markers seen"
    )
    raw = capture.noisy()
    clean = capture.motion
    smoothed, _ = smooth_markers(raw, FPS, CUTOFF_HZ, robust=False, size=problem.rig.scale)
    ones = np.ones((f, m))
    H, g = normal_equations(solver, raw)
    H_clean, g_clean = normal_equations(solver, clean)
    H_smooth, g_smooth = normal_equations(solver, smoothed)
    sample = np.linspace(0, f - 1, n_baseline).round().astype(np.int64)
    g_sample = g[sample]
    reference = np.empty((n_baseline, len(problem.free)))
    factor = cho_factor(H)

    start = time.perf_counter()
    box_qp_frames(H, g[:2], problem.lower, problem.upper)  # compile, or load numba's cache
    solver.solve(raw[:2], np.where(np.arange(m) == 0, 0.0, 1.0)[None].repeat(2, 0))  # per-frame H
    first_s = time.perf_counter() - start
    last: dict[str, np.ndarray] = {}

    def keep(name: str, fn: Callable[[], tuple[np.ndarray, np.ndarray]]) -> Callable[[], None]:
        """``fn`` that keeps its activations in ``last[name]``."""
        return lambda: last.__setitem__(name, fn()[0])

    bounds = (problem.lower, problem.upper)
    cases: dict[str, tuple[Callable[[], object], int]] = {
        "solve raw": (keep("solve raw", lambda: solver.solve(raw, ones)), 1),
        "qp raw": (keep("qp raw", lambda: box_qp_frames(H, g, *bounds)), 1),
        "qp sample": (keep("qp sample", lambda: box_qp_frames(H, g_sample, *bounds)), 1),
        "solve clean": (lambda: solver.solve(clean, ones), 1),
        "qp clean": (keep("qp clean", lambda: box_qp_frames(H_clean, g_clean, *bounds)), 1),
        "solve smooth": (keep("solve smooth", lambda: solver.solve(smoothed, ones)), 1),
        "qp smooth": (keep("qp smooth", lambda: box_qp_frames(H_smooth, g_smooth, *bounds)), 1),
        "unbounded": (lambda: cho_solve(factor, g.T), 1),
        "bvls": (lambda: bvls(solver, raw, sample, reference), 1),
    }
    busy = Contention()
    seconds = round_robin(cases, rounds)
    busy_note = busy.note()
    per = {case: s / (n_baseline if case in ("bvls", "qp sample") else f) for case, s in seconds.items()}
    x = last["solve raw"]
    difference = float(np.abs(x[sample] - reference).max())
    difference_sample = float(np.abs(last["qp sample"] - reference).max())
    base = per["bvls"]
    rows = [
        (
            f"MarkerSolver.solve, raw markers (1 mm noise), {f:,} frames",
            per["solve raw"],
            "lsq_linear bvls",
            base,
        ),
        ("   box_qp_frames alone, its normal equations", per["qp raw"], "lsq_linear bvls", base),
        (
            f"   box_qp_frames, the {n_baseline} baseline frames only",
            per["qp sample"],
            "lsq_linear bvls",
            base,
        ),
        ("MarkerSolver.solve, noise-free markers", per["solve clean"], "lsq_linear bvls", base),
        ("   box_qp_frames alone", per["qp clean"], "lsq_linear bvls", base),
        (
            f"MarkerSolver.solve, markers smoothed at {CUTOFF_HZ:g} Hz",
            per["solve smooth"],
            "lsq_linear bvls",
            base,
        ),
        ("   box_qp_frames alone", per["qp smooth"], "lsq_linear bvls", base),
        ("reference: unbounded solve (cho_solve, shared H)", per["unbounded"], "", None),
        (
            f"baseline: lsq_linear bvls per frame ({n_baseline} frames timed, per frame extrapolated)",
            base,
            "",
            None,
        ),
    ]
    stats = {
        name: bound_changes(last[f"qp {case}"], *bounds)
        for name, case in (("raw", "raw"), ("noise-free", "clean"), ("smoothed", "smooth"))
    }
    error = {"raw": rms(x - capture.activations), "smoothed": rms(last["solve smooth"] - capture.activations)}
    print(
        f"   numba threads {numba.get_num_threads()}; first call (numba compile or cache load) "
        f"{first_s:.2f} s; median of {rounds} rounds, one untimed call first"
        + (f"; meanwhile {busy_note}" if busy_note else "")
        + ";\n"
        f"   regularization {REGULARIZATION:g} (damping rows sqrt(damping)·I in the baseline, which runs "
        f"with {BASELINE_BLAS_THREADS} BLAS thread), sparsity 0; "
        f"noise {NOISE_M * 1e3:g} mm per coordinate;\n"
        f"   the baseline's {n_baseline} frames are spread over the clip ({f // n_baseline} apart), so the "
        f"third row warm-starts each from one {f // n_baseline} frames before (little use)"
    )
    TABLES.append(print_table(rows, "1. Per-frame solve"))
    print(
        f"   max |difference| from lsq_linear bvls over its {n_baseline} frames: {difference:.1e} "
        f"(solve of the whole clip), {difference_sample:.1e} (box_qp_frames on those frames alone)"
    )
    cells = "; ".join(
        f"{name} {on:.1f} on a bound, {changed:.1f} change from the frame before"
        for name, (on, changed) in stats.items()
    )
    print(f"   channels per frame ({len(problem.free)}): {cells}")
    print(
        f"   activation error against the truth, RMS over channels and frames: raw {error['raw']:.3f}, "
        f"smoothed {error['smoothed']:.3f}"
    )
    return {"fps": 1 / per["solve raw"], "speedup": base / per["solve raw"], "difference": difference}


# --------------------------------------------------------------------------- 2. whole-clip solve


def temporal(problem: Problem, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``smooth_markers`` then ``MarkerSolver.solve`` on the smoothed markers: activations (f, k) and
    the marker samples used (f, m)."""
    smoothed, outliers = smooth_markers(y, FPS, CUTOFF_HZ, robust=True, size=problem.rig.scale)
    used = np.isfinite(smoothed).all(axis=2) & ~outliers
    return problem.solver.solve(smoothed, used.astype(np.float64))[0], used


def bench_temporal(problem: Problem, capture: Capture, rounds: int) -> dict[str, float]:
    f, m, _ = capture.motion.shape
    print(
        f"\n2a. Whole-clip temporal solve: smooth_markers (robust, {CUTOFF_HZ:g} Hz) + MarkerSolver.solve, "
        f"{f:,} frames at {FPS:g} fps, {m} markers"
    )
    noisy, damaged = capture.noisy(), capture.damaged()
    seen = np.isfinite(damaged).all(axis=2)
    cases: dict[str, tuple[Callable[[], object], int]] = {
        "noisy": (lambda: temporal(problem, noisy), 1),
        "damaged": (lambda: temporal(problem, damaged), 1),
        "smooth noisy": (lambda: smooth_markers(noisy, FPS, CUTOFF_HZ, size=problem.rig.scale), 1),
        "smooth damaged": (lambda: smooth_markers(damaged, FPS, CUTOFF_HZ, size=problem.rig.scale), 1),
        "per-frame": (lambda: problem.solver.solve(noisy, np.ones((f, m))), 1),
        "per-frame damaged": (lambda: problem.solver.solve(damaged, seen.astype(np.float64)), 1),
    }
    busy = Contention()
    seconds = round_robin(cases, rounds)
    busy_note = busy.note()
    per = {case: s / f for case, s in seconds.items()}
    base, base_damaged = per["per-frame"], per["per-frame damaged"]
    rows = [
        ("temporal solve, noisy markers", per["noisy"], "per-frame solve, raw", base),
        ("   of which smooth_markers", per["smooth noisy"], "per-frame solve, raw", base),
        (
            f"temporal solve, + {DROPPED:.0%} dropped, {SPIKES:.0%} spikes",
            per["damaged"],
            "per-frame solve, raw (seen markers)",
            base_damaged,
        ),
        (
            "   of which smooth_markers",
            per["smooth damaged"],
            "per-frame solve, raw (seen markers)",
            base_damaged,
        ),
        ("baseline: per-frame solve of the raw noisy markers", base, "", None),
        ("baseline: per-frame solve of the raw damaged markers (seen ones)", base_damaged, "", None),
    ]
    x_noisy, _ = temporal(problem, noisy)
    x_damaged, used = temporal(problem, damaged)
    x_raw, _ = problem.solver.solve(noisy, np.ones((f, m)))
    scale_10k = GOAL_TEMPORAL_FRAMES / f
    print(
        f"   median of {rounds} rounds" + (f" ({busy_note} meanwhile)" if busy_note else "") + ";\n"
        "   times per frame, so throughput is frames/s; ratio = time / baseline (what the smoothing adds "
        "to a per-frame solve)"
    )
    TABLES.append(print_table(rows, "2a. Whole-clip temporal solve"))
    print(
        f"   whole clip: noisy {seconds['noisy']:.2f} s, damaged {seconds['damaged']:.2f} s for {f:,} frames"
        + (
            f" (scaled to {GOAL_TEMPORAL_FRAMES:,} frames: {seconds['noisy'] * scale_10k:.2f} s and "
            f"{seconds['damaged'] * scale_10k:.2f} s)"
            if f != GOAL_TEMPORAL_FRAMES
            else ""
        )
    )
    print(
        f"   damaged clip: {capture.missing.mean():.1%} of the samples dropped, {capture.spikes.mean():.1%} "
        f"spikes; the solve used {used.mean():.1%} of the samples (gaps over {smoothing.MAX_GAP_S:g} s "
        f"stay missing), every marker in {used.all(axis=1).mean():.1%} of the frames (the others:\n"
        f"   one normal matrix per frame); {(capture.spikes & used).sum()} of {capture.spikes.sum()} spikes "
        f"kept by the smoother (under its {smoothing.SPIKE_SIGMAS:g}σ cut, Cauchy-weighted)"
    )
    print(
        "   activation error against the truth, RMS: per-frame raw "
        f"{rms(x_raw - capture.activations):.3f}; temporal noisy {rms(x_noisy - capture.activations):.3f}, "
        f"damaged {rms(x_damaged - capture.activations):.3f}"
    )
    return {"noisy_s": seconds["noisy"] * scale_10k, "damaged_s": seconds["damaged"] * scale_10k}


STAGES = {
    ("start", "calibrate 0"): "markers matched, checks",
    ("calibrate 0", "smooth 0"): "calibration (neutral frame → rig)",
    ("smooth 0", "smooth 1"): "temporal smoothing (smooth_markers)",
    ("smooth 1", "calibrate 1"): "head motion, first fit",
    ("calibrate 1", "solve 0"): "marker deltas, solver prepared",
    ("solve 0", "solve 1"): "solve, then head/expression alternation (robust weights)",
    ("solve 1", "end"): "result assembled, flags",
}


@contextmanager
def timers(spent: dict[str, list[float]]):
    """Wrap ``MarkerSolver.solve`` and ``capture.performance.head_motion`` in timers (restored on exit)."""
    solve, head = MarkerSolver.solve, performance.head_motion

    def timed(name: str, fn):
        def wrapper(*args, **kwargs):
            start = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                spent.setdefault(name, []).append(time.perf_counter() - start)

        return wrapper

    MarkerSolver.solve = timed("MarkerSolver.solve", solve)
    performance.head_motion = timed("head_motion", head)
    try:
        yield
    finally:
        MarkerSolver.solve, performance.head_motion = solve, head


def bench_chain(problem: Problem, capture: Capture, rounds: int) -> None:
    f, m, _ = capture.motion.shape
    rig = problem.rig
    angles, shift = head_clip(f, problem.metre)
    trajectories = capture_trajectories(problem, capture, angles, shift)
    names = problem.names

    def run(progress=None):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MimeticWarning)
            return solve_performance(rig, trajectories, basis=problem.basis, active=names, progress=progress)

    print(
        f"\n2b. The whole solve_performance chain: {f:,} frames, {m} markers in {CAPTURE_UNITS}, head motion "
        f"(±{', ±'.join(f'{a:g}' for a in HEAD_AMPLITUDE_RAD)} rad, ±{HEAD_TRANSLATION_M * 100:g} cm), "
        f"{capture.missing.mean():.1%} dropped, {capture.spikes.mean():.1%} spikes; no goal"
    )
    seconds = round_robin({"chain": (run, 1)}, rounds)["chain"]
    events: list[tuple[str, float]] = [("start", time.perf_counter())]
    spent: dict[str, list[float]] = {}
    with timers(spent):
        result = run(lambda stage, done, total: events.append((f"{stage} {done}", time.perf_counter())))
    events.append(("end", time.perf_counter()))
    total = events[-1][1] - events[0][1]
    print(
        f"   median of {rounds} call(s), one untimed call first: {seconds:.2f} s, {f / seconds:,.0f} "
        f"frames/s; stages of one more call ({total:.2f} s, progress callback timestamps and timers):"
    )
    rows = []
    for (a, ta), (b, tb) in itertools.pairwise(events):
        rows.append((STAGES.get((a, b), f"{a} → {b}"), f"{tb - ta:.3f}", f"{(tb - ta) / total:.0%}"))
    for name, times in spent.items():
        rows.append((f"   inside: {name} × {len(times)}", f"{sum(times):.3f}", f"{sum(times) / total:.0%}"))
    TABLES.append(table(("stage", "s", "share"), rows, "2b. The solve_performance chain, by stage"))
    solved = result.clip.select(names).values
    head = result.clip.select(performance.HEAD_CHANNELS).values
    fit = result.report(rig)
    caught = result.outliers[capture.spikes].mean()
    false = (result.outliers & ~capture.spikes & ~capture.missing).sum()
    print(
        f"   errors against the truth: activations RMS {rms(solved - capture.activations):.3f}; head angles "
        f"RMS {np.degrees(rms(head - angles)):.2f}°; marker fit median "
        f"{fit['marker_rms_median'] / problem.metre * 1e3:.2f} mm;\n   spikes marked as outliers "
        f"{caught:.1%}, other samples marked {false} ({false / capture.missing.size:.2%}); flagged frames "
        f"{fit['flagged_frames']}"
    )


# --------------------------------------------------------------------------- 3. video


def video_clip(rig: Rig, frames: int) -> Clip:
    """The head turning (head_yaw ±0.15 rad) while the jaw opens and the mouth smiles."""
    names = list(rig.channel_names)
    values = np.tile([c.default for c in rig.channels], (frames, 1))
    t = np.linspace(0, 1, frames)
    values[:, names.index("head_yaw")] = 0.15 * np.sin(2 * np.pi * t)
    values[:, names.index("jaw_open")] = 0.3 * np.sin(np.pi * t) ** 2
    for side in "LR":
        values[:, names.index(f"zygomatic_major_{side}")] = 0.6 * np.sin(2 * np.pi * t) ** 2
    return Clip(tuple(names), values, VIDEO_FPS)


def decode(path: Path) -> int:
    """Frames decoded to RGB by ffmpeg, as ``track_video`` reads them (the baseline)."""
    import imageio_ffmpeg

    reader = imageio_ffmpeg.read_frames(str(path), pix_fmt="rgb24")
    meta = next(reader)
    width, height = meta["size"]
    count = 0
    for raw in reader:
        np.frombuffer(raw, np.uint8).reshape(height, width, 3)
        count += 1
    return count


def bench_video(rig: Rig, frames: int, sizes: tuple[int, ...], rounds: int) -> None:
    print(
        f"\n3. Video: track_video on {frames} frames of the small rig rendered by render_clip (wire engine)"
    )
    if importlib.util.find_spec("mediapipe") is None:
        print("   mediapipe not installed (extra [track]): table skipped")
        return
    from mimetic.capture.video import track_video
    from mimetic.view.video import render_clip

    clip = video_clip(rig, frames)
    rows, notes = [], []
    with tempfile.TemporaryDirectory() as folder:
        for size in sizes:
            start = time.perf_counter()
            path = render_clip(rig, clip, Path(folder) / f"clip_{size}.mp4", size=size)
            render_s = time.perf_counter() - start
            steady: list[float] = []
            found: list[int] = []

            def track(path=path, steady=steady, found=found):
                stamps: list[float] = []
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", MimeticWarning)
                    result = track_video(
                        path, progress=lambda done, total: stamps.append(time.perf_counter())
                    )
                steady.append((len(stamps) - 1) / (stamps[-1] - stamps[0]))
                found.append(int(np.isfinite(result.positions).all(axis=2).any(axis=1).sum()))

            try:
                seconds = round_robin(
                    {"track": (track, 1), "decode": (lambda path=path: decode(path), 1)}, rounds
                )
            except MissingExtraError as error:
                print(f"   {error}: table skipped")
                return
            per_track, per_decode = seconds["track"] / frames, seconds["decode"] / frames
            rows.append((f"track_video, {size}², whole call", per_track, "decode only", per_decode))
            rows.append((f"baseline: decode only, {size}²", per_decode, "", None))
            notes.append(
                f"   {size}²: render_clip {render_s:.2f} s ({frames / render_s:.0f} frames/s); face in "
                f"{found[-1]}/{frames} frames; after the first frame {statistics.median(steady):.0f} "
                f"frames/s (the rest of a call: FaceMesh's graph built, the first frame); whole call "
                f"{seconds['track']:.2f} s"
            )
    print(f"   median of {rounds} round(s), one untimed call first; times per video frame")
    TABLES.append(print_table(rows, "3. Video tracking"))
    print("\n".join(notes))


# --------------------------------------------------------------------------- main


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--quick", action="store_true", help="2,000 frames, 100 baseline frames, 30 video frames at 256² only"
    )
    args = parser.parse_args()
    frames = QUICK_FRAMES if args.quick else FRAMES
    n_baseline = QUICK_BASELINE_FRAMES if args.quick else BASELINE_FRAMES
    rounds = 5  # the quick clip's calls are short: as many rounds, for a steadier median
    begin = time.perf_counter()
    busy = Contention()
    load = os.getloadavg()
    print(f"load average at start {load[0]:.2f} / {load[1]:.2f} / {load[2]:.2f} (1 / 5 / 15 min; 2 cores)")
    rig = small_rig()
    problem = prepare(rig)
    capture = make_capture(problem, frames)
    print(
        f"rig: small_rig(), {rig.n_vertices:,} vertices, {len(rig.channels)} channels, units {rig.units}; "
        f"{len(problem.free)} solved for, the ones the {LAYOUT} markers move most (left out of the "
        f"{len(problem.free) + len(problem.left_out)} they see: {', '.join(problem.left_out) or 'none'});\n"
        f"clip: {frames:,} frames, {(capture.activations != 0).mean():.0%} of the channel samples active; "
        f"setup {time.perf_counter() - begin:.1f} s"
    )
    solve = bench_per_frame(problem, capture, n_baseline, rounds)
    whole = bench_temporal(problem, capture, rounds)
    bench_chain(problem, capture, 1 if args.quick else 3)
    bench_video(rig, 30 if args.quick else 60, (256,) if args.quick else (256, 512), 1 if args.quick else 3)
    wall = time.perf_counter() - begin
    print("\nSummary")
    rows = [
        (
            f"per-frame solve (MarkerSolver.solve, raw markers) >= {GOAL_FPS:,} frames/s",
            f"{solve['fps']:,.0f} frames/s",
            verdict(solve["fps"] >= GOAL_FPS),
        ),
        (
            f"per-frame solve >= {GOAL_SPEEDUP:g}× lsq_linear bvls",
            f"{solve['speedup']:,.0f}×",
            verdict(solve["speedup"] >= GOAL_SPEEDUP),
        ),
        (
            f"max |difference| from lsq_linear bvls <= {GOAL_DIFFERENCE:g}",
            f"{solve['difference']:.1e}",
            verdict(solve["difference"] <= GOAL_DIFFERENCE),
        ),
    ]
    per = "" if frames == GOAL_TEMPORAL_FRAMES else f" (scaled from {frames:,})"
    for label, key in (
        ("noisy markers", "noisy_s"),
        (f"{DROPPED:.0%} dropped, {SPIKES:.0%} spikes", "damaged_s"),
    ):
        rows.append(
            (
                f"temporal solve of {GOAL_TEMPORAL_FRAMES:,} frames <= {GOAL_TEMPORAL_S:g} s, {label}",
                f"{whole[key]:.2f} s{per}",
                verdict(whole[key] <= GOAL_TEMPORAL_S),
            )
        )
    if args.quick:
        rows.append((f"--quick runs in < {GOAL_QUICK_S:g} s", f"{wall:.0f} s", verdict(wall < GOAL_QUICK_S)))
    TABLES.append(table(("goal", "measured", "met"), rows, "Summary"))
    note = busy.note()
    print(
        f"\nload average at the end {os.getloadavg()[0]:.2f}; benchmark wall time {wall:.0f} s"
        + (f"; over the run {note} (times are inflated when this is large)" if note else "")
    )
    report.save("capture", TABLES)


if __name__ == "__main__":
    main()
