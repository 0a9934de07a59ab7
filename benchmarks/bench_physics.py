"""Benchmark the physically based engines (issue 12): the tissue volume, the fem engine's
factorisation and basis, the tissue engine's quasi-static and dynamic solves, on a generated head
whose tissue has 10k nodes, on the default head (28k nodes) and on ICT-FaceKit (when the shared data is
there).

    python benchmarks/bench_physics.py [--quick]

One table per head: case | median time | throughput | baseline | ratio. Baselines, measured in the
same run: for the fem engine's frame, solving ``K u = Σ aᵢ Fᵢ`` directly each frame (the factorised
system's back-substitution, what a basis saves); for the tissue engine, the vector engine's frame (the
geometric engine it replaces) and the real-time budget of a 30 fps frame (33.3 ms). Also per head:
setup times (volume, factorisation, basis, calibration) against the goals (fem ≤ 10 s on the default
head, ≤ 30 s on ICT), peak memory of each engine's setup (``tracemalloc``), tissue steps/s and output
frames/s (goal ≥ 30 at 10k nodes), how far a smile's skin differs from the geometric engines', what
the physics adds (the cheeks' outward bulge in the smile and the lips' in a pucker, every engine), and
the solver choice: ``engines.cholesky``'s nested-dissection SuperLU (the fem engine's) and cholespy's
CHOLMOD (the tissue engine's) against scipy's ``splu`` on the fem and tissue systems.
"""

from __future__ import annotations

import argparse
import os
import time
import tracemalloc
import warnings

import numpy as np
from scipy.sparse.linalg import splu

import report
from bench_basis import print_table, round_robin
from bench_rig import print_table as print_titled
from mimetic.engines import make_engine
from mimetic.engines.cholesky import cholesky, nested_lu
from mimetic.engines.fem import fem_deltas, prepare_fem
from mimetic.engines.loads import muscle_loads
from mimetic.engines.volume import build_volume
from mimetic.head.model import make_head
from mimetic.mesh.geometry import vertex_normals
from mimetic.rig.activations import pose
from mimetic.rig.recipe import build_rig
from mimetic.testing import ict_folder, ict_landmarks, load_ict

TABLES: list[str] = []
"""The tables written to ``out/physics.md`` (``report.save``), in order."""
REALTIME_S = 1 / 30
CLIP_FRAMES = 30
"""The dynamic case: a smile that comes and goes in one second at 30 fps."""
TEN_K = "10k-node head"
TEN_K_RESOLUTION = 3400
"""Skin vertices of the generated head whose tissue volume has about 10,000 nodes (three layers)."""
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
PUCKER = {"orbicularis_oris": 1.0}
"""The lips' sphincter alone: the lips squeezed together bulge forward."""
BULGE_REGIONS = {"smile": ("cheek_L", "cheek_R"), "pucker": ("upper_lip", "lower_lip")}
"""Where each pose's outward bulge is measured (the rig's regions)."""


def bulges(rig, engines: dict) -> list[tuple[str, ...]]:
    """Rows (pose, engine, mean, p95, max): each pose's skin motion along the rest normal (outward
    positive, rig units) over its ``BULGE_REGIONS``: a smile's cheek bulk, a pucker's lip bulge."""
    normals = vertex_normals(rig.mesh.vertices, rig.mesh.faces)
    rows = []
    for name, chosen in (("smile", SMILE), ("pucker", PUCKER)):
        where = np.concatenate([rig.regions[r] for r in BULGE_REGIONS[name]])
        values = pose(rig, chosen)
        for engine_name, engine in engines.items():
            moved = engine.deform(values)[where] - rig.mesh.vertices[where]
            out = np.einsum("ij,ij->i", moved, normals[where])
            rows.append(
                (name, engine_name, *(f"{x:+.3f}" for x in (out.mean(), np.percentile(out, 95), out.max())))
            )
    return rows


def timed(fn):
    start = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - start


def heads(quick: bool):
    yield TEN_K, build_rig(make_head(resolution=TEN_K_RESOLUTION))
    yield "default head", build_rig(make_head())
    folder = ict_folder()
    if quick:
        return
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


def solver_choice(system, label: str, used: str, columns: int, block: int) -> None:
    """The factorisations of ``engines.cholesky`` against scipy's ``splu`` (minimum-degree order,
    symmetric mode) on ``system``: factorisation, and a solve of ``columns`` right-hand sides (the fem
    engine solves one per muscle once; the tissue engine 3 per iteration); ``block`` rows per node
    (3 in the fem system, 1 in the tissue's, whose x, y and z share it). ``used``: the engine's."""
    rhs = np.random.default_rng(0).normal(size=(system.shape[0], columns))
    chol, chol_factor_s = timed(lambda: cholesky(system))
    nested, nested_factor_s = timed(lambda: nested_lu(system, block))
    lu, splu_factor_s = timed(
        lambda: splu(
            system.tocsc(), permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True}
        )
    )
    solvers = {"cholespy": chol, "nested_lu": nested, "splu": lu}
    seconds = round_robin({name: (lambda f=f: f.solve(rhs), 3) for name, f in solvers.items()}, 3)
    factor_s = {"cholespy": chol_factor_s, "nested_lu": nested_factor_s, "splu": splu_factor_s}
    what = f"solver ({label}, {system.shape[0]:,} unknowns, {columns} right-hand sides)"
    rows = []
    for name in ("nested_lu", "cholespy"):
        tag = " (used)" if name == used else ""
        rows.append((f"{name} factorisation{tag}", factor_s[name], "splu", splu_factor_s))
        rows.append((f"{name} solve{tag}", seconds[name], "splu", seconds["splu"]))
    rows += [
        ("baseline: splu factorisation", splu_factor_s, "", None),
        ("baseline: splu solve", seconds["splu"], "", None),
    ]
    TABLES.append(f"{what[0].upper()}{what[1:]}, times per call:\n\n{print_table(rows, what)}")


def bench_head(label: str, rig, rounds: int) -> None:
    values = pose(rig, SMILE)
    volume, volume_s = timed(lambda: build_volume(rig))
    solver, prepare_s = timed(lambda: prepare_fem(volume))
    _, basis_s = timed(lambda: fem_deltas(rig, volume, solver))
    fem, fem_s = timed(lambda: make_engine(rig, "fem"))
    fem_mib = peak_mib(lambda: make_engine(rig, "fem"))[1]  # tracemalloc slows it: timed apart
    vector = make_engine(rig, "vector")
    loads = muscle_loads(rig, volume)
    active = loads.active
    forces = loads.forces[:, active] @ values[active]
    cases = {
        "fem engine, one frame": (lambda: fem.deform(values), 5),
        "direct solve K u = Σ a F, one frame": (lambda: solver.solve(forces), 1),
        "vector engine, one frame": (lambda: vector.deform(values), 5),
    }
    tissue, tissue_s = timed(lambda: make_engine(rig, "tissue"))
    tissue_mib = peak_mib(lambda: make_engine(rig, "tissue"))[1]
    clip = values * np.sin(np.linspace(0, np.pi, CLIP_FRAMES))[:, None] ** 2  # a smile in and out
    cases["tissue engine, quasi-static frame"] = (lambda: tissue.deform(values), 1)
    cases["tissue engine, dynamic frame (1 s clip)"] = (lambda: tissue.simulate(clip, 30), 1)
    tissue_setup = (
        f"; tissue engine {tissue_s:.2f} s; peak memory fem {fem_mib:.0f} MiB, tissue {tissue_mib:.0f} MiB"
    )
    steps = tissue.steps_per_frame(30)
    seconds = round_robin(cases, rounds)
    per_frame = dict(seconds)
    per_frame["tissue engine, dynamic frame (1 s clip)"] /= CLIP_FRAMES
    direct = per_frame["direct solve K u = Σ a F, one frame"]
    vector_s = per_frame["vector engine, one frame"]
    rows = [
        ("fem engine, one frame", per_frame["fem engine, one frame"], "direct solve per frame", direct),
        ("baseline: direct solve K u = Σ a F, one frame", direct, "", None),
        ("vector engine, one frame", vector_s, "", None),
    ]
    for case in ("tissue engine, quasi-static frame", "tissue engine, dynamic frame (1 s clip)"):
        rows.append((case, per_frame[case], "vector engine", vector_s))
        rows.append((f"{case} vs 30 fps", per_frame[case], "real time (33.3 ms)", REALTIME_S))
    intro = (
        f"**{label}**: {rig.n_vertices:,} vertices; tissue volume {volume.n_nodes:,} nodes, "
        f"{len(volume.tets):,} tetrahedra ({2 * len(volume.triangles):,} prisms); "
        f"load average {os.getloadavg()[0]:.2f}. Setup: volume {volume_s:.2f} s; fem assembly + "
        f"factorisation {prepare_s:.2f} s; one solve per muscle ({len(active)}) + calibration "
        f"{basis_s:.2f} s; whole fem engine {fem_s:.2f} s{tissue_setup}."
    )
    print(f"\n{intro}")
    dynamic = per_frame["tissue engine, dynamic frame (1 s clip)"]
    fps = 1 / dynamic
    verdict = (
        f"goal ≥ 30 frames/s: {'met' if fps >= 30 else 'NOT met'}" if label == TEN_K else "goal judged at 10k"
    )
    fem_goal = FEM_GOAL_S.get(label)
    fem_verdict = (
        ""
        if fem_goal is None
        else (f"; fem setup goal ≤ {fem_goal:.0f} s: {'met' if fem_s <= fem_goal else 'NOT met'}")
    )
    tissue_line = (
        f"Tissue at 30 fps, {volume.n_nodes:,} nodes: {steps} step(s) per frame, {steps / dynamic:,.0f} "
        f"steps/s, {fps:,.1f} output frames/s ({verdict}){fem_verdict}."
    )
    TABLES.append(intro)
    TABLES.append(print_table(rows, f"{label}: one frame", tissue_line))
    engines = {"wire": make_engine(rig, "wire"), "vector": vector, "fem": fem, "tissue": tissue}
    poses = {name: engine.deform(values) for name, engine in engines.items()}
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
    bulge_title = (
        f"{label}: what the physics adds: outward bulge along the rest normal, {rig.units}, of the "
        "smile over the cheeks and of a pucker (orbicularis_oris 1) over the lips"
    )
    bulge_table = print_titled(bulge_title, ("pose", "engine", "mean", "p95", "max"), bulges(rig, engines))
    TABLES.append(f"{bulge_title[0].upper()}{bulge_title[1:]}.\n\n{bulge_table}")
    solver_choice(solver.K[solver.free][:, solver.free], f"{label}, fem", "nested_lu", len(active), 3)
    solver_choice(tissue.model.global_matrix(), f"{label}, tissue", "cholespy", 3, 1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer rounds, the generated heads only")
    args = parser.parse_args()
    rounds = 3 if args.quick else 7
    begin = time.perf_counter()
    for label, rig in heads(args.quick):
        bench_head(label, rig, rounds)
    print(f"\nbenchmark wall time {time.perf_counter() - begin:.0f} s")
    report.save("physics", TABLES)


if __name__ == "__main__":
    main()
