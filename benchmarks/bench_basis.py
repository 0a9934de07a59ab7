"""Benchmark ``evaluate_basis`` (the evaluation every consumer calls) against dense products.

    python benchmarks/bench_basis.py [--quick]

Bases: "baked", the default head's rig baked by the wire engine (13,363 vertices, 50 channels, 24
correctives; head rotation stays a rigid bone, so its channels move nothing), and, without
``--quick``, "synthetic", deltas with the supports the goals were set for (``synthetic_basis``:
muscles over 5-10 % of the vertices, the jaw over a third, head rotation over all). Frames: one
realistic frame (``REALISTIC_FRAME``, 16 channels), every channel at once, and batches of 64
(what ``export_obj_sequence`` evaluates at a time) and 512 frames of a smooth clip.

Baselines, measured in the same run: dense float64, ``[t] @ [deltas; correctives] + neutral``
(what ``evaluate_basis`` computed before its blocked layout), and dense float32 over a cached
float32 copy of the same matrix (for one frame, only the rows of the non-zero terms). Every case
returns a new array, as a consumer gets it: the page faults of a fresh 80 MB batch are part of
the time. Cases are timed round-robin (each round runs every case once), so the drift of a
shared 2-core machine hits the case and its baseline alike; the median over the rounds is
reported. Single frames are timed again in a round-robin of their own whose rounds call each case
once untimed first: one frame after another, as a player or a solver's loop runs them, on the
caches their own case leaves (the table's rows); the first timing, where each round starts on the
caches an 80 MB batch left, is in a note. Without ``--quick``, a sweep of ``BLOCK_VERTICES`` follows.

One table: case | median time | throughput | baseline | ratio (median / baseline; below 1 is
faster), then the float32 error against float64 (with the bound of ``mimetic.engines.basis``) and
the goals: one frame >= 50,000 frames/s (issue 31), batches of 512 >= 20,000 frames/s (float32, the path
``mimetic.view`` uses; float64 is reported beside it).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from collections.abc import Callable

import numpy as np

import mimetic.engines.basis as basis_module
import report
from mimetic.engines import make_engine
from mimetic.engines.bake import bake
from mimetic.engines.basis import Basis, Corrective, evaluate_basis
from mimetic.head.model import make_head
from mimetic.rig.model import Rig
from mimetic.rig.recipe import build_rig

GOAL_SINGLE_FPS = 50_000  # issue 31: a sparse single-frame path ran 112k frames/s
GOAL_BATCH_FPS = 20_000
GOAL_BATCH_FRAMES = 512
MUSCLE_RADIUS_REL = 0.15  # synthetic muscles move the skin within this fraction of the head height
REALISTIC_FRAME = {  # 16 channels, as in speech with a little head motion and a blink
    "jaw_open": 0.22,
    "orbicularis_oris": 0.4,
    "zygomatic_major_L": 0.5,
    "zygomatic_major_R": 0.45,
    "risorius_L": 0.2,
    "depressor_labii_L": 0.3,
    "depressor_labii_R": 0.3,
    "levator_labii_mid_L": 0.25,
    "levator_labii_mid_R": 0.25,
    "mentalis": 0.15,
    "frontalis_inner_L": 0.3,
    "frontalis_inner_R": 0.3,
    "eyelid_upper_L": 0.1,
    "eyelid_upper_R": 0.1,
    "head_yaw": 0.05,
    "head_pitch": -0.03,
}


# --------------------------------------------------------------------------- cases


def _rotation_delta(
    axis: list[float], pivot: np.ndarray, vertices: np.ndarray, weight: np.ndarray
) -> np.ndarray:
    """Displacement per radian of a rotation about ``axis`` through ``pivot``: w (axis × (v - p)), (n, 3)."""
    return weight[:, None] * np.cross(np.asarray(axis, float), vertices - pivot)


def synthetic_basis(rig: Rig) -> Basis:
    """Deltas with realistic supports for every channel of ``rig`` (a stand-in for a baked basis).

    Muscles move the vertices within MUSCLE_RADIUS_REL · scale of their insertion, with a smooth
    falloff, toward their attachment (a sphincter toward its centre). The jaw channels move the
    vertices with jaw skin weight > 0 (rotation about +X, translations along +X and +Z per unit of
    head height); lid and gaze channels rotate their bones' vertices; head rotations move every
    vertex. Two correctives (jaw_open with orbicularis_oris and with mentalis) pull the lips back
    against the jaw.
    """
    v, f = rig.mesh.vertices, rig.mesh.faces
    weights = rig.skin_weights.toarray() if hasattr(rig.skin_weights, "toarray") else rig.skin_weights
    names = rig.channel_names
    deltas = np.zeros((len(names), rig.n_vertices, 3))
    everything = np.ones(rig.n_vertices)
    for k, name in enumerate(names):
        if name in rig.muscle_names:
            muscle = rig.muscle(name)
            insertion = muscle.insertion.position(v, f)
            towards = (
                muscle.origin.position(v, f) if muscle.kind == "sphincter" else rig.muscle_attachment(name)
            )
            direction = (towards - insertion) / np.linalg.norm(towards - insertion)
            distance = np.linalg.norm(v - insertion, axis=1) / (MUSCLE_RADIUS_REL * rig.scale)
            falloff = np.clip(1 - distance**2, 0, None) ** 2  # (n,)
            deltas[k] = 0.05 * rig.scale * falloff[:, None] * direction
        elif name.startswith("jaw_"):
            w = weights[:, rig.bone_index("jaw")]
            if name == "jaw_open":
                deltas[k] = _rotation_delta([1, 0, 0], rig.bone("jaw").head, v, w)
            else:
                axis = [1.0, 0, 0] if name == "jaw_slide" else [0, 0, 1.0]
                deltas[k] = rig.scale * w[:, None] * np.array(axis)
        elif name.startswith("eyelid_"):
            sign = 1.0 if "upper" in name else -1.0
            deltas[k] = _rotation_delta(
                [sign, 0, 0], rig.bone(name).head, v, weights[:, rig.bone_index(name)]
            )
        elif name.startswith("gaze_"):
            for side, toward_nose in (("L", -1.0), ("R", 1.0)):
                axis = {
                    "gaze_yaw": [0, 1, 0],
                    "gaze_pitch": [-1, 0, 0],
                    "gaze_convergence": [0, 0.5 * toward_nose, 0],
                    "gaze_vertical_vergence": [0.5 * toward_nose, 0, 0],  # the left eye up
                }
                bone = f"eye_{side}"
                deltas[k] += _rotation_delta(
                    axis[name], rig.bone(bone).head, v, weights[:, rig.bone_index(bone)]
                )
        elif name.startswith("head_"):
            axis = {"head_yaw": [0, 1, 0], "head_pitch": [1, 0, 0], "head_roll": [0, 0, -1]}[name]
            deltas[k] = _rotation_delta(axis, rig.bone("head").head, v, everything)
    jaw = deltas[names.index("jaw_open")]
    correctives = tuple(
        Corrective(
            ("jaw_open", lip), -0.5 * jaw * (np.abs(deltas[names.index(lip)]).sum(1, keepdims=True) > 0)
        )
        for lip in ("orbicularis_oris", "mentalis")
        if lip in names and "jaw_open" in names
    )
    return Basis(names, v, deltas, correctives)


def baked_basis(rig: Rig) -> Basis:
    """The rig baked by the wire engine (``bake``, 24 correctives)."""
    return bake(make_engine(rig, "wire")).basis


def realistic_frame(basis: Basis) -> np.ndarray:
    """REALISTIC_FRAME as a (c,) vector (16 channels active, including the jaw)."""
    a = np.zeros(basis.n_channels)
    for name, value in REALISTIC_FRAME.items():
        if name in basis.channels:
            a[basis.channels.index(name)] = value
    return a


def realistic_clip(basis: Basis, frames: int, seed: int = 0) -> np.ndarray:
    """(frames, c): the realistic frame's channels varying smoothly, a few others flickering on."""
    rng = np.random.default_rng(seed)
    base = realistic_frame(basis)
    phase = rng.uniform(0, 2 * np.pi, basis.n_channels)
    t = np.arange(frames)[:, None] / 30.0
    clip = base * (1 + 0.5 * np.sin(2 * np.pi * t + phase))
    extra = rng.random((frames, basis.n_channels)) < 0.05
    return np.where(extra & (base == 0), 0.1, clip)


# --------------------------------------------------------------------------- baselines


class Dense:
    """The dense baselines: ``[t] @ [deltas; correctives] + neutral`` over cached (T, 3n) copies."""

    def __init__(self, basis: Basis) -> None:
        n = basis.n_vertices
        self.pairs = basis.corrective_pairs  # (k, 2)
        terms = np.concatenate([basis.deltas, basis.corrective_deltas]).reshape(-1, 3 * n)  # (T, 3n)
        self.matrix = {np.float64: terms, np.float32: terms.astype(np.float32)}
        self.neutral = {dtype: basis.neutral.reshape(-1).astype(dtype) for dtype in self.matrix}
        self.shape = (n, 3)

    def terms(self, a: np.ndarray) -> np.ndarray:
        """Term activations (f, T): the channels, then the corrective products."""
        return np.concatenate([a, a[:, self.pairs[:, 0]] * a[:, self.pairs[:, 1]]], axis=1)

    def batch(self, a: np.ndarray, dtype: type) -> np.ndarray:
        """(f, c) -> (f, n, 3): one GEMM over every term."""
        out = self.terms(a).astype(dtype) @ self.matrix[dtype]  # (f, 3n)
        out += self.neutral[dtype]
        return out.reshape(len(a), *self.shape)

    def frame(self, a: np.ndarray, dtype: type) -> np.ndarray:
        """(c,) -> (n, 3): one GEMV over the rows of the non-zero terms only."""
        t = self.terms(a[None])[0]  # (T,)
        active = np.flatnonzero(t)
        out = t[active].astype(dtype) @ self.matrix[dtype][active]  # (3n,)
        out += self.neutral[dtype]
        return out.reshape(self.shape)


def error_bound(basis: Basis, a: np.ndarray, u: float, eta: float) -> np.ndarray:
    """The bound of ``mimetic.engines.basis`` ("Precision") on |evaluated - exact|, per frame (f,)."""
    a = np.atleast_2d(a)
    t = np.abs(
        np.concatenate([a, a[:, basis.corrective_pairs[:, 0]] * a[:, basis.corrective_pairs[:, 1]]], 1)
    )
    peaks = np.abs(np.concatenate([basis.deltas, basis.corrective_deltas])).max(axis=(1, 2))  # (T,) M_j
    K = 1 + t.shape[1]
    gamma = (K + 3) * u / (1 - (K + 3) * u)
    return gamma * (np.abs(basis.neutral).max() + t @ peaks) + eta * (K + t.sum(1) + peaks.sum())


# --------------------------------------------------------------------------- timing


def per_call(fn: Callable[[], object], calls: int, rounds: int) -> float:
    """Median over ``rounds`` of the mean time of ``calls`` back-to-back calls (s), after a warm-up."""
    return round_robin({"": (fn, calls)}, rounds)[""]


def round_robin(
    cases: dict[str, tuple[Callable[[], object], int]], rounds: int, *, warm: bool = False
) -> dict[str, float]:
    """Median seconds per call of each case {name: (fn, calls per round)}; every round runs every case.
    With ``warm``, each round first calls its case once untimed: the calls are timed on the caches
    their own case leaves, as a loop of frames meets them, not on what the case before it left (an
    80 MB batch evicts the whole basis)."""
    for fn, calls in cases.values():
        for _ in range(max(1, calls // 4)):
            fn()
    samples: dict[str, list[float]] = {name: [] for name in cases}
    for _ in range(rounds):
        for name, (fn, calls) in cases.items():
            if warm:
                fn()
            start = time.perf_counter()
            for _ in range(calls):
                fn()
            samples[name].append((time.perf_counter() - start) / calls)
    return {name: statistics.median(s) for name, s in samples.items()}


def round_robin_frames(
    cases: dict, frames: list[int], rounds: int
) -> tuple[dict[str, float], dict[str, float]]:
    """``round_robin`` of every case, then of the single-frame ones (``frames`` per case, in order)
    again with ``warm``: the seconds per call with single frames timed warm, and the first timing."""
    cold = round_robin(cases, rounds)
    single = {case: c for (case, c), f in zip(cases.items(), frames, strict=True) if f == 1}
    return {**cold, **round_robin(single, rounds, warm=True)}, cold


def table(header: tuple[str, ...], rows: list[tuple[str, ...]], title: str = "", caption: str = "") -> str:
    """A table of formatted cells printed with rich; returned as Markdown (``report.show``)."""
    return report.show(title, header, rows, caption)


def print_table(rows: list[tuple[str, float, str, float | None]], title: str = "", caption: str = "") -> str:
    """Rows (case, s per frame, baseline label, baseline s per frame or None) as one table,
    printed with rich (``caption`` under it); returned as Markdown."""
    header = ("case", "median time", "throughput", "baseline", "ratio")
    body = [
        (
            case,
            f"{t * 1e6:,.1f} µs" if t < 1e-3 else f"{t * 1e3:,.2f} ms",
            f"{1 / t:,.0f} frames/s",
            f"{label} ({base * 1e6:,.1f} µs)" if base is not None else label,
            f"{t / base:.3f}" if base is not None else "",
        )
        for case, t, label, base in rows
    ]
    return table(header, body, title, caption)


# --------------------------------------------------------------------------- main


def bench(basis: Basis, label: str, quick: bool) -> tuple[list, list[str], dict[str, float]]:
    """Rows for ``print_table``, notes and goal numbers (frames/s) for one basis."""
    calls, rounds = (20, 9) if quick else (50, 21)
    dense = Dense(basis)
    frame = realistic_frame(basis)
    everything = np.full(basis.n_channels, 0.5)
    clip = realistic_clip(basis, GOAL_BATCH_FRAMES)
    names = {np.float64: "float64", np.float32: "float32"}
    cases: dict[str, tuple[Callable[[], object], int]] = {}
    frames: dict[str, int] = {}
    for dtype, name in names.items():
        for what, a in (("realistic frame", frame), ("every channel", everything)):
            cases[f"dense {name}, {what}"] = (lambda a=a, d=dtype: dense.frame(a, d), calls)
            cases[f"evaluate_basis {name}, {what}"] = (
                lambda a=a, d=dtype: evaluate_basis(basis, a, dtype=d),
                calls,
            )
            frames[f"dense {name}, {what}"] = frames[f"evaluate_basis {name}, {what}"] = 1
        for f in (64, GOAL_BATCH_FRAMES):
            A = clip[:f]
            cases[f"dense {name}, batch of {f}"] = (lambda A=A, d=dtype: dense.batch(A, d), 1)
            cases[f"evaluate_basis {name}, batch of {f}"] = (
                lambda A=A, d=dtype: evaluate_basis(basis, A, dtype=d),
                1,
            )
            frames[f"dense {name}, batch of {f}"] = frames[f"evaluate_basis {name}, batch of {f}"] = f
    seconds, cold = round_robin_frames(cases, [frames[case] for case in cases], rounds)
    per_frame = {case: s / frames[case] for case, s in seconds.items()}
    rows = []
    for case, t in per_frame.items():
        if case.startswith("dense"):
            rows.append((f"{label}: {case}", t, "(the baseline)", None))
        else:
            base = case.replace("evaluate_basis", "dense")
            rows.append((f"{label}: {case}", t, base, per_frame[base]))
    order = ["realistic frame", "every channel", "batch of 64", f"batch of {GOAL_BATCH_FRAMES}"]
    rows.sort(key=lambda r: (order.index(r[0].split(", ", 1)[1]), r[0]))

    layout = basis._layout32
    stored = sum(matrix.size for *_, matrix in layout.blocks)
    error = np.abs(evaluate_basis(basis, clip, dtype=np.float32) - evaluate_basis(basis, clip)).max(
        axis=(1, 2)
    )
    bound = error_bound(basis, clip, 2.0**-24, 2.0**-148) + error_bound(basis, clip, 2.0**-53, 2.0**-1071)
    notes = [
        f"{label}: {basis.n_vertices:,} vertices, {basis.n_channels} channels, {len(basis.correctives)} "
        f"correctives; {len(layout.blocks)} blocks of {basis_module.BLOCK_VERTICES} vertices holding "
        f"{stored / ((1 + len(layout.peaks)) * 3 * basis.n_vertices):.0%} of the dense [neutral; deltas] "
        f"elements ({stored * 4 / 1e6:.1f} MB in float32)",
        f"{label}: one realistic float32 frame timed on the caches the case before it left (an 80 MB "
        f"batch): {1 / cold['evaluate_basis float32, realistic frame']:,.0f} frames/s "
        f"({1 / cold['evaluate_basis float64, realistic frame']:,.0f} float64)",
        f"{label}: float32 - float64 over the {len(clip)}-frame clip: max {error.max():.3g} rig units; "
        f"bound {bound.min():.3g}-{bound.max():.3g}; every frame within it: {bool(np.all(error <= bound))}",
    ]
    goals = {
        "single": 1 / per_frame["evaluate_basis float32, realistic frame"],
        "single64": 1 / per_frame["evaluate_basis float64, realistic frame"],
        "batch": 1 / per_frame[f"evaluate_basis float32, batch of {GOAL_BATCH_FRAMES}"],
        "batch64": 1 / per_frame[f"evaluate_basis float64, batch of {GOAL_BATCH_FRAMES}"],
    }
    return rows, notes, goals


def block_sweep(basis: Basis, sizes: tuple[int, ...]) -> list:
    """Rows: evaluate_basis float32 on fresh copies of ``basis`` laid out with each BLOCK_VERTICES."""
    frame = realistic_frame(basis)
    clip = realistic_clip(basis, GOAL_BATCH_FRAMES)
    default = basis_module.BLOCK_VERTICES
    copies = {}
    for size in sizes:
        basis_module.BLOCK_VERTICES = size
        copies[size] = Basis(basis.channels, basis.neutral, basis.deltas, basis.correctives)
        evaluate_basis(copies[size], frame, dtype=np.float32)  # builds its layout
    basis_module.BLOCK_VERTICES = default
    cases = {}
    for size, copy in copies.items():
        cases[size, 1] = (lambda b=copy: evaluate_basis(b, frame, dtype=np.float32), 50)
        cases[size, GOAL_BATCH_FRAMES] = (lambda b=copy: evaluate_basis(b, clip, dtype=np.float32), 1)
    seconds = round_robin(cases, 15)
    rows = []
    for (size, f), s in seconds.items():
        blocks = len(copies[size]._layout32.blocks)
        what = "realistic frame" if f == 1 else f"batch of {f}"
        base = seconds[default, f] / f
        rows.append(
            (f"sweep: {size} vertices a block ({blocks} blocks), float32, {what}", s / f, f"{default}", base)
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the baked basis only, fewer rounds (for CI)")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    rig = build_rig(make_head())
    grid = [("baked", baked_basis(rig))]
    if not args.quick:
        grid.append(("synthetic", synthetic_basis(rig)))
    rows, notes, goals = [], [], {}
    for label, basis in grid:
        r, n, g = bench(basis, label, args.quick)
        rows += r
        notes += n
        goals[label] = g
    if not args.quick:
        rows += block_sweep(grid[0][1], (128, 256, 512, 1024, 2048))
    print(
        f"load average {load:.2f} at start, {os.getloadavg()[0]:.2f} at the end (2 cores); "
        f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}"
    )
    for note in notes:
        print(note)
    goal_lines = []
    for label, g in goals.items():
        single, batch = g["single"] >= GOAL_SINGLE_FPS, g["batch"] >= GOAL_BATCH_FPS
        goal_lines.append(
            f"{label}: one frame >= {GOAL_SINGLE_FPS:,} frames/s: {g['single']:,.0f} float32 "
            f"({g['single64']:,.0f} float64) — {'met' if single else 'NOT met'}; batches of "
            f"{GOAL_BATCH_FRAMES} >= {GOAL_BATCH_FPS:,} frames/s: {g['batch']:,.0f} float32 "
            f"({g['batch64']:,.0f} float64) — {'met' if batch else 'NOT met'}"
        )
    caption = (
        "; ".join(notes)
        + ". Times are per frame; ratio = median / baseline (below 1 is faster). Goals: "
        + "; ".join(goal_lines)
    )
    report.save("basis", [print_table(rows, "evaluate_basis against dense products", caption)])


if __name__ == "__main__":
    main()
