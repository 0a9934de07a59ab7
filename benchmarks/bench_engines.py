"""Benchmark the deformation engines and the baked basis on the default head.

    python benchmarks/bench_engines.py [--quick]

One table: case | median time | throughput | baseline | ratio. Rows: the nonlinear wire and
vector engines (frames/s, goal >= 200); the baked basis evaluated one frame at a time (goal
>= 3,000 frames/s and >= 80 % of its memory-bandwidth limit; by the compiled kernel, which
``evaluate`` runs, and by one BLAS GEMV per block for comparison) and in batches (goal
>= 20,000 frames/s); and the baseline, a dense float64 ``activations @ deltas`` product measured in the same
run. It also prints the bake error against the nonlinear engine and the float32 compaction error.

The bandwidth limit of a frame is the time to stream the bytes any float32 evaluation must move,
at a read bandwidth measured in the same run (``np.sum`` over 256 MB): the (n, 3) output written
once (as many bytes as the neutral it starts from) plus the non-zero delta components of the
active channels and correctives (``bench_basis.nonzero_bytes``). It does not depend on the layout:
zero padding that a layout reads (``CompactBasis.plan(a).bytes_read`` counts it) is not useful
work, so the rate at which the layout streams its own bytes is printed apart, not as the goal.
Bandwidth and evaluation are timed in alternation (``bench_basis.interleaved``) and the goal is
the median of their ratios, so that machine noise hits both sides.
"""

from __future__ import annotations

import argparse
import functools
import time

import numpy as np

from bench_basis import interleaved, nonzero_bytes, per_call  # the same helpers as the basis study
from mimetic.engines import make_engine
from mimetic.engines.bake import bake, random_poses
from mimetic.engines.basis import CompactBasis
from mimetic.head.model import make_head
from mimetic.rig.activations import pose
from mimetic.rig.recipe import build_rig

REALISTIC = {  # a talking, smiling face: 14 channels
    "zygomatic_major_L": 0.6,
    "zygomatic_major_R": 0.55,
    "orbicularis_oculi_outer_L": 0.4,
    "orbicularis_oculi_outer_R": 0.4,
    "frontalis_inner_L": 0.3,
    "frontalis_inner_R": 0.3,
    "levator_labii_mid_L": 0.2,
    "levator_labii_mid_R": 0.2,
    "orbicularis_oris": 0.2,
    "jaw_open": 0.15,
    "eyelid_upper_L": 0.2,
    "eyelid_upper_R": 0.2,
    "gaze_yaw": 0.1,
    "depressor_labii_L": 0.1,
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer repeats (for CI)")
    args = parser.parse_args()
    repeats = 5 if args.quick else 15
    rig = build_rig(make_head())
    realistic = pose(rig, REALISTIC)
    everything = np.array(
        [0.5 * c.maximum if c.unit == "activation" else 0.3 * c.maximum for c in rig.channels]
    )
    for name in ("head_yaw", "head_pitch", "head_roll"):
        everything[rig.channel_index(name)] = 0.0
    rows = []

    engines = {name: make_engine(rig, name) for name in ("wire", "vector")}
    for name, engine in engines.items():
        for label, values in (("realistic pose", realistic), ("every channel", everything)):
            t = per_call(lambda e=engine, v=values: e.deform(v), 20, repeats)
            rows.append((f"{name} engine, {label}", t, 1, "goal 200 frames/s", 1 / 200))

    start = time.perf_counter()
    baked = bake(engines["wire"], samples=16 if args.quick else 32)
    bake_s = time.perf_counter() - start
    basis = baked.basis
    c, n = len(basis.channels), basis.n_vertices
    dense64 = basis.deltas.reshape(c, -1)
    dense_single = per_call(lambda: realistic @ dense64, 20, repeats)
    clip = random_poses(engines["wire"], 512, np.random.default_rng(1))
    dense_batch = per_call(lambda: clip @ dense64, 1, repeats) / len(clip)
    rows.append(("baseline: dense float64 a @ deltas, 1 frame", dense_single, 1, "", dense_single))
    rows.append(("baseline: dense float64 a @ deltas, 512 frames", dense_batch, 1, "", dense_batch))

    compact = CompactBasis.build(basis, dtype=np.float32)
    out = np.empty((n, 3), np.float32)
    frame = functools.partial(compact.evaluate, realistic, out=out)
    samples = interleaved(frame, 200, 3 * repeats)  # the bandwidth limit (module docstring)
    single = float(np.median(samples.seconds))
    gemvs = per_call(functools.partial(compact.evaluate, realistic, out=out, method="blocks"), 50, repeats)
    batch = per_call(lambda: compact.evaluate_batch(clip), 1, repeats) / len(clip)
    least = nonzero_bytes(basis, realistic)  # output + non-zero deltas of the active terms
    layout = compact.plan(realistic).bytes_read  # what the runs actually read, padding included
    bandwidth = float(np.median(samples.bandwidth))
    paired, paired_layout = samples.fraction(least), samples.fraction(layout)
    rows.append(
        (
            "basis float32, 1 frame, realistic pose",
            single,
            1,
            f"dense 1 frame ({dense_single * 1e6:.0f} µs)",
            dense_single,
        )
    )
    rows.append(
        (
            "basis float32, 1 frame, realistic pose, one GEMV per block",
            gemvs,
            1,
            f"compiled kernel ({single * 1e6:.0f} µs)",
            single,
        )
    )
    rows.append(
        (
            "basis float32, 1 frame, vs its bandwidth limit",
            single,
            1,
            f"{least / 1e3:.0f} kB / {bandwidth / 1e9:.1f} GB/s",
            least / bandwidth,
        )
    )
    rows.append(
        (
            "basis float32, 1 frame, vs the bytes its layout reads",
            single,
            1,
            f"{layout / 1e3:.0f} kB / {bandwidth / 1e9:.1f} GB/s",
            layout / bandwidth,
        )
    )
    rows.append(
        ("basis float32, batches of 512", batch, 1, f"dense batch ({dense_batch * 1e6:.0f} µs)", dense_batch)
    )

    print(
        f"default head: {n:,} vertices, {c} channels, {len(basis.correctives)} correctives; "
        f"times per frame; ratio = time / baseline (below 1 is faster)"
    )
    header = ("case", "median time", "throughput", "baseline", "ratio")
    body = [
        (case, f"{t * 1e6:,.1f} µs", f"{1 / t:,.0f} frames/s", base, f"{t / ref:.3f}")
        for case, t, _, base, ref in rows
    ]
    widths = [max(len(r[k]) for r in [header, *body]) for k in range(5)]
    for k, row in enumerate([header, *body]):
        print(" | ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)))
        if k == 0:
            print("-+-".join("-" * w for w in widths))
    print(f"bake of the wire engine: {bake_s:.1f} s; " + "; ".join(baked.report.lines()))
    err = compact.compaction_error
    print(f"float32 compaction error: {err.absolute:.2g} rig units ({err.relative:.1e} of the largest delta)")
    print(
        f"single frame at {paired:.0%} of its bandwidth limit (goal 80 %; {least / 1e3:.0f} kB of output "
        f"and non-zero deltas; the median of {len(samples.seconds)} interleaved bandwidth and evaluation "
        "timings); "
        f"its layout reads {layout / 1e3:.0f} kB ({layout / least:.1f}× that: zero padding between "
        f"support runs) at {paired_layout:.0%} of the bandwidth; "
        f"{1 / single:,.0f} frames/s (goal 3,000); batched {1 / batch:,.0f} frames/s (goal 20,000); "
        f"engines {1 / rows[0][1]:,.0f} (wire) and {1 / rows[2][1]:,.0f} (vector) frames/s "
        "(goal 200)"
    )


if __name__ == "__main__":
    main()
