"""Benchmark the deformation engines and the baked basis on the default head.

    python benchmarks/bench_engines.py [--quick]

One table: case | median time | throughput | baseline | ratio. Rows: the nonlinear wire and
vector engines with the lids in contact (goal >= 1,000 frames/s, issue 31); ``evaluate_basis``, the
evaluation every consumer of a baked basis calls, for one realistic frame (goal >= 50,000 frames/s)
and batches of 512 frames
(goal >= 20,000 frames/s), in float32 (what ``mimetic.view`` renders from; the goals) and float64
(what exports, the ARKit fit and the bake's error report use); and its baselines, measured in the
same run and timed round-robin with it (``bench_basis.round_robin_frames``: single frames one after
another on their own warm caches): dense float64 and float32 products over every term (for one
frame, only the non-zero ones). Every case returns a new array,
as a consumer gets it. ``bench_basis.py`` studies the evaluation in more detail.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import report
from bench_basis import (
    GOAL_BATCH_FPS,
    GOAL_SINGLE_FPS,
    Dense,
    error_bound,
    print_table,
    round_robin,
    round_robin_frames,
)
from mimetic.engines import bake, evaluate_basis, make_engine
from mimetic.engines.bake import random_poses
from mimetic.head.model import make_head
from mimetic.rig.activations import pose
from mimetic.rig.recipe import build_rig

GOAL_ENGINE_FPS = 1_000  # issue 31: the wire engine ran 1,023 frames/s before the lid contact landed
BATCH_FRAMES = 512
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
    parser.add_argument("--quick", action="store_true", help="fewer rounds (for CI)")
    args = parser.parse_args()
    rounds = 7 if args.quick else 21
    load = os.getloadavg()[0]
    rig = build_rig(make_head())
    realistic = pose(rig, REALISTIC)
    everything = np.array(
        [0.5 * c.maximum if c.unit == "activation" else 0.3 * c.maximum for c in rig.channels]
    )
    for name in ("head_yaw", "head_pitch", "head_roll"):
        everything[rig.channel_index(name)] = 0.0

    engines = {name: make_engine(rig, name) for name in ("wire", "vector")}
    cases = {
        (f"{name} engine, {label}", 1): (lambda e=engine, v=values: e.deform(v), 5)
        for name, engine in engines.items()
        for label, values in (("realistic pose", realistic), ("every channel", everything))
    }
    engine_seconds = round_robin(cases, max(3, rounds // 3))

    start = time.perf_counter()
    baked = bake(engines["wire"], samples=16 if args.quick else 32)
    bake_s = time.perf_counter() - start
    basis = baked.basis
    dense = Dense(basis)
    clip = random_poses(engines["wire"], BATCH_FRAMES, np.random.default_rng(1))
    cases = {}
    for dtype in (np.float64, np.float32):
        name = np.dtype(dtype).name
        cases[f"dense {name}, 1 frame", 1] = (lambda d=dtype: dense.frame(realistic, d), 20)
        cases[f"dense {name}, {BATCH_FRAMES} frames", BATCH_FRAMES] = (
            lambda d=dtype: dense.batch(clip, d),
            1,
        )
        cases[f"evaluate_basis {name}, 1 frame", 1] = (
            lambda d=dtype: evaluate_basis(basis, realistic, dtype=d),
            20,
        )
        cases[f"evaluate_basis {name}, {BATCH_FRAMES} frames", BATCH_FRAMES] = (
            lambda d=dtype: evaluate_basis(basis, clip, dtype=d),
            1,
        )
    basis_seconds, _ = round_robin_frames(cases, [f for _, f in cases], rounds)  # single frames warm

    per_frame = {case: s / f for (case, f), s in {**engine_seconds, **basis_seconds}.items()}
    goal = 1 / GOAL_ENGINE_FPS
    rows = [
        (case, t, f"goal {GOAL_ENGINE_FPS:,} frames/s", goal)
        for case, t in per_frame.items()
        if "engine" in case
    ]
    for case, t in per_frame.items():
        if case.startswith("dense"):
            rows.append((f"baseline: {case}", t, "", None))
    for case, t in per_frame.items():
        if case.startswith("evaluate_basis"):
            base = case.replace("evaluate_basis", "dense")
            rows.append((case, t, base, per_frame[base]))

    print(
        f"default head: {basis.n_vertices:,} vertices, {basis.n_channels} channels, "
        f"{len(basis.correctives)} correctives; load average {load:.2f} at start, {os.getloadavg()[0]:.2f} "
        f"at the end (2 cores); times per frame; ratio = time / baseline (below 1 is faster)"
    )
    report.save("engines", [print_table(rows, "Engines and the baked basis on the default head")])
    print(f"bake of the wire engine: {bake_s:.1f} s; " + "; ".join(baked.report.lines()))
    error = np.abs(evaluate_basis(basis, clip, dtype=np.float32) - evaluate_basis(basis, clip)).max(
        axis=(1, 2)
    )
    bound = error_bound(basis, clip, 2.0**-24, 2.0**-148) + error_bound(basis, clip, 2.0**-53, 2.0**-1071)
    print(
        f"float32 - float64 over the {BATCH_FRAMES} random poses: max {error.max():.2g} rig units "
        f"(rigorous bound {bound.max():.2g}; every frame within it: {bool(np.all(error <= bound))})"
    )
    single = 1 / per_frame["evaluate_basis float32, 1 frame"]
    batch = 1 / per_frame[f"evaluate_basis float32, {BATCH_FRAMES} frames"]
    wire, vector = (1 / per_frame[f"{name} engine, realistic pose"] for name in ("wire", "vector"))

    def verdict(ok: bool) -> str:
        return "met" if ok else "NOT met"

    print(
        f"goals: basis one frame >= {GOAL_SINGLE_FPS:,} frames/s: {single:,.0f} "
        f"({verdict(single >= GOAL_SINGLE_FPS)}); "
        f"batched >= {GOAL_BATCH_FPS:,}: {batch:,.0f} ({verdict(batch >= GOAL_BATCH_FPS)}); "
        f"engines >= {GOAL_ENGINE_FPS:,}: {wire:,.0f} (wire), {vector:,.0f} (vector) "
        f"({verdict(min(wire, vector) >= GOAL_ENGINE_FPS)})"
    )


if __name__ == "__main__":
    main()
