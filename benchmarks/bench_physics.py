"""Benchmark the physically based engines (issue 12): the tissue volume, the fem engine's
factorisation and basis, the tissue engine's quasi-static and dynamic solves, on the default head and
on ICT-FaceKit (when the shared data is there).

    python benchmarks/bench_physics.py [--quick]

One table per head: case | median time | throughput | baseline | ratio. Baselines, measured in the
same run: for the fem engine's frame, solving ``K u = Σ aᵢ Fᵢ`` directly each frame (the factorised
system's back-substitution, what a basis saves); for the tissue engine, the vector engine's frame (the
geometric engine it replaces) and the real-time budget of a 30 fps frame (33.3 ms). Setup times
(volume, factorisation, basis, calibration) are printed once per head.
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

import numpy as np

from bench_basis import print_table, round_robin
from mimetic.engines import make_engine
from mimetic.engines.fem import fem_deltas, prepare_fem
from mimetic.engines.loads import muscle_loads
from mimetic.engines.volume import build_volume
from mimetic.head.model import make_head
from mimetic.rig.activations import pose
from mimetic.rig.recipe import build_rig
from mimetic.testing import ict_folder, ict_landmarks, load_ict

REALTIME_S = 1 / 30
SMILE = {
    "zygomatic_major_L": 0.8,
    "zygomatic_major_R": 0.8,
    "orbicularis_oculi_outer_L": 0.4,
    "orbicularis_oculi_outer_R": 0.4,
    "levator_labii_mid_L": 0.3,
    "levator_labii_mid_R": 0.3,
    "jaw_open": 0.1,
}


def timed(fn):
    start = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - start


def heads(quick: bool):
    yield "default head", build_rig(make_head())
    folder = ict_folder()
    if folder is None:
        print("ICT-FaceKit not in the shared data: ICT skipped")
        return
    from mimetic.fit.pipeline import rig_head

    neutral, meta = load_ict(folder)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield "ICT-FaceKit", rig_head(neutral, ict_landmarks(neutral, meta)).rig


def bench_head(label: str, rig, rounds: int) -> None:
    values = pose(rig, SMILE)
    volume, volume_s = timed(lambda: build_volume(rig))
    solver, prepare_s = timed(lambda: prepare_fem(volume))
    _, basis_s = timed(lambda: fem_deltas(rig, volume, solver))
    fem, fem_s = timed(lambda: make_engine(rig, "fem"))
    vector = make_engine(rig, "vector")
    loads = muscle_loads(rig, volume)
    active = loads.active
    forces = loads.forces[:, active] @ values[active]
    cases = {
        "fem engine, one frame": (lambda: fem.deform(values), 5),
        "direct solve K u = Σ a F, one frame": (lambda: solver.solve(forces), 1),
        "vector engine, one frame": (lambda: vector.deform(values), 5),
    }
    tissue_setup = ""
    try:
        tissue, tissue_s = timed(lambda: make_engine(rig, "tissue"))
    except Exception as error:  # the tissue engine is optional in this benchmark
        tissue = None
        tissue_setup = f"; tissue engine unavailable ({type(error).__name__}: {error})"
    if tissue is not None:
        clip = np.tile(values, (10, 1))
        cases["tissue engine, quasi-static frame"] = (lambda: tissue.deform(values), 1)
        cases["tissue engine, dynamic frame (10-frame clip)"] = (lambda: tissue.simulate(clip, 30), 1)
        tissue_setup = f"; tissue engine {tissue_s:.2f} s"
    seconds = round_robin(cases, rounds)
    per_frame = dict(seconds)
    if tissue is not None:
        per_frame["tissue engine, dynamic frame (10-frame clip)"] /= 10
    direct = per_frame["direct solve K u = Σ a F, one frame"]
    vector_s = per_frame["vector engine, one frame"]
    rows = [
        ("fem engine, one frame", per_frame["fem engine, one frame"], "direct solve per frame", direct),
        ("baseline: direct solve K u = Σ a F, one frame", direct, "", None),
        ("vector engine, one frame", vector_s, "", None),
    ]
    if tissue is not None:
        for case in ("tissue engine, quasi-static frame", "tissue engine, dynamic frame (10-frame clip)"):
            rows.append((case, per_frame[case], "vector engine", vector_s))
            rows.append((f"{case} vs 30 fps", per_frame[case], "real time (33.3 ms)", REALTIME_S))
    print(
        f"\n{label}: {rig.n_vertices:,} vertices; tissue volume {volume.n_nodes:,} nodes, "
        f"{len(volume.tets):,} tetrahedra ({2 * len(volume.triangles):,} prisms); "
        f"load average {os.getloadavg()[0]:.2f}"
    )
    print(
        f"setup: volume {volume_s:.2f} s; fem assembly + factorisation {prepare_s:.2f} s; one solve per "
        f"muscle ({len(active)}) + calibration {basis_s:.2f} s; whole fem engine {fem_s:.2f} s{tissue_setup}"
    )
    print_table(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer rounds, the default head only")
    args = parser.parse_args()
    rounds = 3 if args.quick else 7
    begin = time.perf_counter()
    for label, rig in heads(args.quick):
        bench_head(label, rig, rounds)
        if args.quick:
            break
    print(f"\nbenchmark wall time {time.perf_counter() - begin:.0f} s")


if __name__ == "__main__":
    main()
