"""Benchmark baked-basis evaluation: dense numpy products against ``CompactBasis``, one frame and batches.

    python benchmarks/bench_basis.py [--quick] [--synthetic]

The grid is two bases of the generated head's rig (13.4k vertices, 50 channels): "baked", the
rig baked by the wire engine (``realistic_basis``; head rotation stays a rigid bone, so its
channels move nothing), and "synthetic", deltas with the supports the goals were set for
(``synthetic_basis``: muscles over 5-10 % of the vertices, the jaw over a third, head rotation
over all). ``--quick`` runs the baked basis only, ``--synthetic`` the synthetic one. Prints one table:
case | median time | throughput | baseline | ratio, where ratio = median / baseline (below 1 is
better), then the goals. Times are per frame; outputs are preallocated for every case, so page
faults of fresh 80 MB batch outputs are not measured. Everything is deterministic: a rerun gives
the same numbers up to timing noise (on a 2-core machine, other busy processes make OpenBLAS's
threads wait; the load average is printed).

The bandwidth limit of a single frame (the goal) is the bytes any float32 evaluation must move,
``nonzero_bytes``: the (n, 3) output (as many bytes as the neutral it starts from) plus the
non-zero delta components of the active channels and correctives, divided by a read bandwidth
measured in the same run (``np.sum`` over 256 MB), alternately with the frame (``interleaved``):
the goal is the median over the rounds of the ratio of the two. The "layout" rows divide instead the bytes
``evaluate`` actually reads (``plan(a).bytes_read``: the float32 neutral plus the stored runs it
touches, zero padding included), i.e. how fast the layout streams its own data.
"""

from __future__ import annotations

import argparse
import functools
import os
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from mimetic.engines.basis import Basis, CompactBasis, Corrective
from mimetic.head.model import make_head
from mimetic.rig.model import Rig
from mimetic.rig.recipe import build_rig

GOAL_SINGLE_FPS = 3_000
GOAL_BANDWIDTH_FRACTION = 0.8
GOAL_BATCH_FPS = 20_000
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


def baked_basis(rig: Rig) -> Basis | None:
    """``bake(WireEngine(rig))``'s basis, or None when ``mimetic.engines.bake`` is not there."""
    try:
        from mimetic.engines.bake import bake
        from mimetic.engines.wire import WireEngine
    except ImportError:
        return None
    result = bake(WireEngine(rig))
    return getattr(result, "basis", result)


def realistic_basis(rig: Rig) -> Basis:
    """The rig baked by the wire engine when the bake exists, else ``synthetic_basis(rig)``."""
    basis = baked_basis(rig)
    return synthetic_basis(rig) if basis is None else basis


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


# --------------------------------------------------------------------------- timing


def per_call(fn: Callable[[], object], calls: int, rounds: int) -> float:
    """Median over ``rounds`` of the mean time of ``calls`` back-to-back calls (s), after a warm-up."""
    for _ in range(max(1, calls // 4)):
        fn()
    times = []
    for _ in range(rounds):
        start = time.perf_counter()
        for _ in range(calls):
            fn()
        times.append((time.perf_counter() - start) / calls)
    return statistics.median(times)


BANDWIDTH_ARRAY_BYTES = 256 * 2**20  # 8× the 32 MB L3: np.sum over it streams from memory


def read_bandwidth(rounds: int) -> float:
    """Read bandwidth (bytes/s): median over ``rounds`` of ``np.sum`` over a 256 MB float64 array."""
    big = np.ones(BANDWIDTH_ARRAY_BYTES // 8)
    big.sum()
    return big.nbytes / per_call(big.sum, 1, rounds)


@dataclass(frozen=True)
class Interleaved:
    """Samples of the read bandwidth and of a frame's time, taken alternately.

    Attributes
    ----------
    bandwidth : (rounds,) float64, bytes/s
    seconds : (rounds,) float64, mean time of one frame in each round
    """

    bandwidth: np.ndarray
    seconds: np.ndarray

    def fraction(self, least_bytes: int) -> float:
        """Time of the bandwidth limit ÷ time of a frame: the median over the rounds of their ratio."""
        return float(np.median(least_bytes / self.bandwidth / self.seconds))

    def spread(self, least_bytes: int) -> tuple[float, float]:
        """The quartiles of the fraction reached in each round (the rounds' own noise)."""
        q1, q3 = np.percentile(least_bytes / self.bandwidth / self.seconds, [25, 75])
        return float(q1), float(q3)


def interleaved(fn: Callable[[], object], calls: int, rounds: int) -> Interleaved:
    """Alternately one ``np.sum`` over 256 MB and ``calls`` calls of ``fn`` (after ``calls // 4``
    untimed ones: the sum flushes the caches), ``rounds`` times.

    The machine's memory bandwidth and the speed of a cache-resident frame drift over seconds on a
    shared host (here 12-19 GB/s, and 16 or 23 µs for the same frame, minutes apart); a ratio of
    samples taken together does not pair a fast moment of one with a slow moment of the other.
    """
    big = np.ones(BANDWIDTH_ARRAY_BYTES // 8)
    big.sum()
    bandwidth, seconds = [], []
    for _ in range(rounds):
        start = time.perf_counter()
        big.sum()
        bandwidth.append(big.nbytes / (time.perf_counter() - start))
        for _ in range(max(1, calls // 4)):
            fn()
        start = time.perf_counter()
        for _ in range(calls):
            fn()
        seconds.append((time.perf_counter() - start) / calls)
    return Interleaved(np.array(bandwidth), np.array(seconds))


def nonzero_bytes(basis: Basis, a: np.ndarray) -> int:
    """The least bytes a float32 frame ``a`` (c,) must move: the (n, 3) output (the size of the neutral)
    and the non-zero delta components of the active channels and correctives."""
    deltas = [basis.deltas[j] for j in np.flatnonzero(a)]
    deltas += [
        k.delta
        for k in basis.correctives
        if a[basis.channels.index(k.channels[0])] * a[basis.channels.index(k.channels[1])]
    ]
    return 4 * (basis.neutral.size + sum(int(np.count_nonzero(d)) for d in deltas))


# --------------------------------------------------------------------------- main


def bench(basis: Basis, label: str, args: argparse.Namespace, bandwidth: float) -> tuple[list, dict]:
    """Rows (case, s per frame, throughput, baseline label, baseline s) and goal numbers for one basis."""
    calls, rounds = (50, 15) if args.quick else (200, 41)
    batch_sizes = [512] if args.quick else [256, 512, 1024]
    n, c = basis.n_vertices, basis.n_channels
    compact = {dtype: CompactBasis.build(basis, dtype=dtype) for dtype in (np.float32, np.float16)}
    frame = realistic_frame(basis)
    everything = np.full(c, 0.2)  # every channel (and corrective) non-zero
    clip = realistic_clip(basis, max(batch_sizes))
    rows: list[tuple[str, float, str, str, float]] = []

    def fps(seconds: float) -> str:
        return f"{1 / seconds:,.0f} frames/s"

    # 1. dense baselines: v = a @ deltas + neutral, as evaluate_basis computes it
    dense = {}
    for dtype in (np.float64, np.float32):
        D = basis.deltas.reshape(c, -1).astype(dtype)
        N = basis.neutral.reshape(-1).astype(dtype)
        a1 = frame.astype(dtype)
        out1 = np.empty(3 * n, dtype)

        def single(D=D, N=N, a1=a1, out1=out1) -> None:
            np.matmul(a1, D, out=out1)
            out1 += N

        t1 = per_call(single, max(5, calls // 4), rounds)
        dense[dtype, 1] = t1
        name = np.dtype(dtype).name
        rows.append((f"{label}: dense {name} a @ deltas, 1 frame", t1, fps(t1), "", 0.0))
        for f in batch_sizes:
            A = clip[:f].astype(dtype)
            out = np.empty((f, 3 * n), dtype)

            def batch(D=D, N=N, A=A, out=out) -> None:
                np.matmul(A, D, out=out)
                out += N

            tb = per_call(batch, 1, max(3, rounds // 4)) / f
            dense[dtype, f] = tb
            rows.append((f"{label}: dense {name} a @ deltas, batch of {f}", tb, fps(tb), "", 0.0))

    # 2. compact evaluation (a float32 frame alternately with the read bandwidth, for its limit below)
    times, samples = {}, {}
    for dtype, cb in compact.items():
        name = np.dtype(dtype).name
        out1 = np.empty((n, 3), np.float32)
        for case, a in (("realistic frame", frame), ("all channels", everything)):
            fn = functools.partial(cb.evaluate, a, out=out1)
            if dtype == np.float32:
                samples[case] = interleaved(fn, calls, rounds)
                t = float(np.median(samples[case].seconds))
            else:
                t = per_call(fn, calls, rounds)
            times[dtype, case] = t
            plan = cb.plan(a)
            what = f"{np.count_nonzero(a)} ch: {plan.runs} runs in 1 kernel call"
            rows.append(
                (
                    f"{label}: compact {name}, 1 frame, {case} ({what})",
                    t,
                    fps(t),
                    "dense float32, 1 frame",
                    dense[np.float32, 1],
                )
            )
        for f in batch_sizes:
            A = clip[:f]
            out = np.empty((f, n, 3), np.float32)
            tb = (
                per_call(lambda A=A, cb=cb, out=out: cb.evaluate_batch(A, out=out), 1, max(3, rounds // 4))
                / f
            )
            times[dtype, f] = tb
            rows.append(
                (
                    f"{label}: compact {name}, batch of {f}",
                    tb,
                    fps(tb),
                    f"dense float32, batch of {f}",
                    dense[np.float32, f],
                )
            )

    # 3. a float32 frame against its bandwidth limit (the bytes it must move ÷ the read bandwidth),
    # both measured alternately over the same rounds; and every frame against the bytes its layout reads
    fractions, spreads = {}, {}
    for dtype, cb in compact.items():
        name = np.dtype(dtype).name
        for case, a in (("realistic frame", frame), ("all channels", everything)):
            t, bw = times[dtype, case], bandwidth
            if dtype == np.float32:
                least = nonzero_bytes(basis, a)
                bw = float(np.median(samples[case].bandwidth))
                fractions[case], spreads[case] = samples[case].fraction(least), samples[case].spread(least)
                rows.append(
                    (
                        f"{label}: compact {name}, {case}, vs its bandwidth limit (interleaved)",
                        t,
                        f"{least / t / 1e9:.1f} GB/s effective",
                        f"{least / 1e3:,.0f} kB ÷ {bw / 1e9:.1f} GB/s",
                        least / bw,
                    )
                )
            read = cb.plan(a).bytes_read
            rows.append(
                (
                    f"{label}: compact {name}, {case}, vs the bytes its layout reads",
                    t,
                    f"{read / t / 1e9:.1f} GB/s effective",
                    f"{read / 1e3:,.0f} kB ÷ {bw / 1e9:.1f} GB/s",
                    read / bw,
                )
            )
    cb32 = compact[np.float32]
    notes = [
        f"{label}: {n:,} vertices, {c} channels, {len(basis.correctives)} correctives, non-zero deltas in "
        f"{np.count_nonzero(np.abs(basis.deltas).sum(2)) / (n * c):.1%} of vertex-channels; float32 layouts: "
        f"{cb32.n_runs} runs, {cb32.n_blocks} blocks, "
        f"{cb32.stored_nbytes / 1e6:.1f} MB stored "
        f"(dense float64 deltas {basis.deltas.nbytes / 1e6:.1f} MB)"
    ]
    for dtype, cb in compact.items():
        e = cb.compaction_error
        notes.append(
            f"{label}: compaction error {np.dtype(dtype).name}: {e.absolute:.3g} rig units "
            f"({e.relative:.2g} of the largest delta; storage {e.storage:.3g}, neutral {e.neutral:.3g}); "
            "error bound of the "
            f"realistic frame {cb.error_bound(frame):.3g}"
        )
    goals = {
        "fps": 1 / times[np.float32, "realistic frame"],
        "fps_all": 1 / times[np.float32, "all channels"],
        "fraction": fractions["realistic frame"],
        "fraction_all": fractions["all channels"],
        "spread": spreads["realistic frame"],
        "batch": max(1 / times[np.float32, f] for f in batch_sizes),
    }
    return rows, {"notes": notes, "goals": goals}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--quick", action="store_true", help="one basis, fewer batch sizes and repeats (for CI)"
    )
    parser.add_argument("--synthetic", action="store_true", help="only the synthetic basis")
    args = parser.parse_args()
    load = os.getloadavg()[0]
    rig = build_rig(make_head())
    baked = None if args.synthetic else baked_basis(rig)
    grid = [("baked", baked)] if baked is not None else []
    if baked is None or not args.quick:
        grid.append(("synthetic", synthetic_basis(rig)))
    bandwidth = read_bandwidth(5 if args.quick else 11)

    rows, notes, goals = [], [], {}
    for label, basis in grid:
        r, extra = bench(basis, label, args, bandwidth)
        rows += r
        notes += extra["notes"]
        goals[label] = extra["goals"]

    header = ("case", "median time", "throughput", "baseline", "ratio")
    body = [
        (
            case,
            f"{t * 1e6:,.1f} µs",
            throughput,
            f"{base_label} ({base * 1e6:,.1f} µs)" if base_label else "",
            f"{t / base:.3f}" if base_label else "",
        )
        for case, t, throughput, base_label, base in rows
    ]
    widths = [max(len(r[k]) for r in [header, *body]) for k in range(5)]
    print(
        f"read bandwidth (np.sum over 256 MB): {bandwidth / 1e9:.1f} GB/s; load average {load:.2f} at start; "
        f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}"
    )
    for note in notes:
        print(note)
    print("times are per frame; ratio = median / baseline (below 1 is better)")
    for k, row in enumerate([header, *body]):
        print(" | ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)))
        if k == 0:
            print("-+-".join("-" * w for w in widths))

    def verdict(ok: bool) -> str:
        return "met" if ok else "NOT met"

    for label, g in goals.items():
        print(
            f"{label}: 1 frame ≥ {GOAL_SINGLE_FPS:,} frames/s: {g['fps']:,.0f} realistic, "
            f"{g['fps_all']:,.0f} all channels — {verdict(g['fps'] >= GOAL_SINGLE_FPS)}; "
            f"≥ {GOAL_BANDWIDTH_FRACTION:.0%} of the "
            f"bandwidth limit: {g['fraction']:.0%} realistic (rounds' quartiles {g['spread'][0]:.0%}-"
            f"{g['spread'][1]:.0%}), {g['fraction_all']:.0%} all channels — "
            f"{verdict(g['fraction'] >= GOAL_BANDWIDTH_FRACTION)}; batches ≥ {GOAL_BATCH_FPS:,} frames/s: "
            f"{g['batch']:,.0f} — {verdict(g['batch'] >= GOAL_BATCH_FPS)}"
        )


if __name__ == "__main__":
    main()
