"""Benchmark the physically based engines (issue 12): the tissue volume, the fem engine's
factorisation and basis, the tissue engine's quasi-static and dynamic solves, on the default head and
on ICT-FaceKit (when the shared data is there).

    python benchmarks/bench_physics.py [--quick]

One table per head: case | median time | throughput | baseline | ratio. Baselines, measured in the
same run: for the fem engine's frame, solving ``K u = Σ aᵢ Fᵢ`` directly each frame (the factorised
system's back-substitution, what a basis saves); for the tissue engine, the vector engine's frame (the
geometric engine it replaces) and the real-time budget of a 30 fps frame (33.3 ms). Also per head:
setup times (volume, factorisation, basis, calibration) against the goals (fem ≤ 10 s on the default
head, ≤ 30 s on ICT), peak memory of each engine's setup (``tracemalloc``), tissue steps/s and output
frames/s (goal ≥ 30), how far a smile's skin differs from the geometric engines', and the solver
choice: scipy's ``splu`` (used) against cholespy's CHOLMOD (when installed) on the fem system.
"""

from __future__ import annotations

import argparse
import os
import time
import tracemalloc
import warnings

import numpy as np
from scipy.sparse.linalg import splu

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
FEM_GOAL_S = {"default head": 10.0, "ICT-FaceKit": 30.0}
"""Issue 12's goals for the fem engine's whole setup (volume, factorisation, basis)."""
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


def peak_mib(fn):
    """``fn()`` and the peak of the memory Python allocated while it ran (numpy's arrays included), MiB."""
    tracemalloc.start()
    try:
        out = fn()
        return out, tracemalloc.get_traced_memory()[1] / 2**20
    finally:
        tracemalloc.stop()


def solver_choice(solver, label: str) -> None:
    """scipy's splu (what the engines use) against cholespy's CHOLMOD (when installed) on the fem system."""
    K = solver.K[solver.free][:, solver.free].tocsc()
    rhs = np.random.default_rng(0).normal(size=(K.shape[0], 3))
    factor, splu_factor_s = timed(
        lambda: splu(K, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    )
    splu_solve_s = round_robin({"s": (lambda: factor.solve(rhs), 3)}, 3)["s"]
    line = (
        f"solver ({label}, {K.shape[0]:,} unknowns, 3 right-hand sides): splu factor {splu_factor_s:.2f} s, "
        f"solve {splu_solve_s * 1e3:.1f} ms"
    )
    try:
        from cholespy import CholeskySolverD, MatrixType
    except ImportError:
        print(line + "; cholespy not installed (pip install cholespy to compare)")
        return
    coo = K.tocoo()
    chol, chol_factor_s = timed(
        lambda: CholeskySolverD(
            K.shape[0], coo.row.astype(np.int32), coo.col.astype(np.int32), coo.data, MatrixType.COO
        )
    )
    out = np.zeros_like(rhs)
    chol_solve_s = round_robin({"c": (lambda: chol.solve(rhs, out), 3)}, 3)["c"]
    print(
        line + f"; cholespy factor {chol_factor_s:.2f} s ({chol_factor_s / splu_factor_s:.2f}×), solve "
        f"{chol_solve_s * 1e3:.1f} ms ({chol_solve_s / splu_solve_s:.2f}×)"
    )


def bench_head(label: str, rig, rounds: int) -> None:
    values = pose(rig, SMILE)
    volume, volume_s = timed(lambda: build_volume(rig))
    solver, prepare_s = timed(lambda: prepare_fem(volume))
    _, basis_s = timed(lambda: fem_deltas(rig, volume, solver))
    (fem, fem_mib), fem_s = timed(lambda: peak_mib(lambda: make_engine(rig, "fem")))
    vector = make_engine(rig, "vector")
    loads = muscle_loads(rig, volume)
    active = loads.active
    forces = loads.forces[:, active] @ values[active]
    cases = {
        "fem engine, one frame": (lambda: fem.deform(values), 5),
        "direct solve K u = Σ a F, one frame": (lambda: solver.solve(forces), 1),
        "vector engine, one frame": (lambda: vector.deform(values), 5),
    }
    (tissue, tissue_mib), tissue_s = timed(lambda: peak_mib(lambda: make_engine(rig, "tissue")))
    clip = np.tile(values, (10, 1))
    cases["tissue engine, quasi-static frame"] = (lambda: tissue.deform(values), 1)
    cases["tissue engine, dynamic frame (10-frame clip)"] = (lambda: tissue.simulate(clip, 30), 1)
    tissue_setup = (
        f"; tissue engine {tissue_s:.2f} s; peak memory fem {fem_mib:.0f} MiB, tissue {tissue_mib:.0f} MiB"
    )
    steps = tissue.steps_per_frame(30)
    seconds = round_robin(cases, rounds)
    per_frame = dict(seconds)
    per_frame["tissue engine, dynamic frame (10-frame clip)"] /= 10
    direct = per_frame["direct solve K u = Σ a F, one frame"]
    vector_s = per_frame["vector engine, one frame"]
    rows = [
        ("fem engine, one frame", per_frame["fem engine, one frame"], "direct solve per frame", direct),
        ("baseline: direct solve K u = Σ a F, one frame", direct, "", None),
        ("vector engine, one frame", vector_s, "", None),
    ]
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
    dynamic = per_frame["tissue engine, dynamic frame (10-frame clip)"]
    print(
        f"tissue at 30 fps: {steps} step(s) per frame, {steps / dynamic:,.0f} steps/s, "
        f"{1 / dynamic:,.0f} output frames/s (goal ≥ 30 frames/s at ≥ 10k nodes: "
        f"{'met' if 1 / dynamic >= 30 else 'NOT met'}); "
        f"fem setup goal ≤ {FEM_GOAL_S[label]:.0f} s: {'met' if fem_s <= FEM_GOAL_S[label] else 'NOT met'}"
    )
    poses = {"wire": make_engine(rig, "wire").deform(values), "vector": vector.deform(values)}
    poses.update(fem=fem.deform(values), tissue=tissue.deform(values))
    rest = rig.mesh.vertices
    moved = {name: np.linalg.norm(v - rest, axis=1) for name, v in poses.items()}
    print(f"the smile ({', '.join(SMILE)}): largest motion and difference from the geometric engines, cm")
    for name in ("fem", "tissue"):
        diffs = [np.linalg.norm(poses[name] - poses[other], axis=1) for other in ("wire", "vector")]
        print(
            f"   {name}: moves up to {moved[name].max():.2f} (wire {moved['wire'].max():.2f}, vector "
            f"{moved['vector'].max():.2f}); differs from wire by rms {np.sqrt(np.mean(diffs[0] ** 2)):.3f}, "
            f"max {diffs[0].max():.2f}; from vector by rms {np.sqrt(np.mean(diffs[1] ** 2)):.3f}, "
            f"max {diffs[1].max():.2f}"
        )
    solver_choice(solver, label)


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
