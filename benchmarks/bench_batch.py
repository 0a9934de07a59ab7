"""Benchmark batch rigging and 1,000 small jobs on a local Dask cluster: scaling, overhead per job.

    python benchmarks/bench_batch.py [--quick] [--part all|rig|jobs] [--heads N] [--resolution N] [--jobs N]

Rigging (``--part rig``):

Generated heads (seeds 0 … N-1, GLB, with their landmark files; 40 heads, 10 with --quick) at the
default resolution (10,000 skin vertices) are rigged by ``mimetic.batch.rig_many`` on a fresh
LocalCluster of 1 and of 2 worker processes (one thread each), every output written as ``mimetic
rig`` writes it (rig, fit report, fit picture). Times are wall times of one run each, cluster start
and the workers' first (cold) item included, as a user sees them. One table: case | time |
throughput | baseline | ratio:

* 2 workers against 1: the ratio is the scaling (goal ≥ 1.7 on 2 cores);
* the plain CLI in the same run: the first 5 heads by ``mimetic rig`` subprocesses one after another
  (each pays Python's start, the imports and a cold first fit), against the same 5 heads by
  ``rig_many`` with 1 worker, and the per-item overhead of a batch (its wall time per head minus the
  job's own time on the worker);
* Dask's scheduling cost per task (1,000 no-op tasks on the 2-worker cluster).

A second table estimates 10,000 heads on N machines from these numbers (see ``estimate``).

Small jobs (``--part jobs``): 1,000 ``animate`` items (100 with --quick), each playing a one-second
clip of its own (rest → a blend of joy and surprise → rest, 30 frames) on the small rig (2,500 skin
vertices) and writing a GLB, about 0.15 s of work each, given as a manifest file and run by
``mimetic.batch.animate_many`` on a fresh LocalCluster of 1 and of 2 workers. Cluster start is timed
to the batch's first ``progress(0, n)`` call (the cluster is up, nothing submitted yet); the rest of
the wall time is the items'. One table: the two runs (scaling efficiency at 2 workers = speed-up / 2,
goal ≥ 85 %) with the same for the items alone, cluster start and close, the job's own time on a
worker, the batch's overhead per job (the items' wall time × workers minus the sum of the jobs' own
times, per job: submitting, Dask's hand-offs, the manifest row, idle workers at the end) and the
fraction of the workers' time spent in jobs; then the same items on a scheduler and 2 worker
processes of their own on 127.0.0.1 (``mimetic.testing.cluster``, as on several machines), against
the 2-worker LocalCluster. Other processes on the cores slow the jobs themselves
(the job's time with 2 workers against 1 shows it) and so the scaling, not the overhead.
"""

from __future__ import annotations

import argparse
import csv
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import report
from bench_rig import print_table
from mimetic.animate.clipfiles import save_clip
from mimetic.animate.keyframes import from_expressions
from mimetic.batch import Manifest, animate_many, rig_many
from mimetic.fit.landmarks import write_landmarks
from mimetic.head.model import DEFAULT_RESOLUTION
from mimetic.mesh.io import save_mesh
from mimetic.rig.format import save_rig
from mimetic.testing import head_landmarks, small_head, small_rig
from mimetic.testing.cluster import loopback_cluster

SCALING_GOAL = 1.7
CLI_HEADS = 5
PAPER_HEADS = 10_000
EFFICIENCY_GOAL = 0.85
"""Scaling efficiency of the small jobs at 2 workers: (1-worker time / 2-worker time) / 2."""


def write_heads(folder: Path, n: int, resolution: int) -> list[Path]:
    """Heads of seeds 0 … n-1 as ``head_SEED.glb`` with ``head_SEED.json`` landmarks beside them."""
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for seed in range(n):
        head = small_head(seed, resolution)
        paths.append(save_mesh(head.mesh, folder / f"head_{seed:03d}.glb"))
        write_landmarks(head_landmarks(head), folder / f"head_{seed:03d}.json")
    return paths


def batch(paths: list[Path], out: Path, workers: int) -> tuple[float, object]:
    """Wall time of ``rig_many`` on a fresh LocalCluster of ``workers`` processes, and its manifest."""
    start = time.perf_counter()
    manifest = rig_many(paths, out, workers=workers, landmarks="{dir}/{stem}.json", resume=False)
    wall = time.perf_counter() - start
    if manifest.failed:
        raise SystemExit(f"{len(manifest.failed)} heads failed: {manifest.failed[0].error}")
    return wall, manifest


def cli(paths: list[Path], out: Path) -> float:
    """Wall time of ``mimetic rig`` on each path, one subprocess after another."""
    command = Path(sys.executable).with_name("mimetic")
    out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    for path in paths:
        subprocess.run(
            [command, "rig", path, "--landmarks", path.with_suffix(".json"), "-o", out / f"{path.stem}.mrig"],
            check=True,
            capture_output=True,
        )
    return time.perf_counter() - start


def scheduling_cost(tasks: int = 1_000) -> float:
    """Seconds per no-op task on a 2-worker LocalCluster (submit, run, gather)."""
    import logging
    from operator import neg

    import distributed

    with (
        distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, dashboard_address=None, silence_logs=logging.ERROR
        ) as cluster,
        distributed.Client(cluster) as client,
    ):
        client.gather(client.map(neg, range(10)))  # warm
        start = time.perf_counter()
        client.gather(client.map(neg, range(tasks)))
        return (time.perf_counter() - start) / tasks


def estimate(per_core_s: float, mb_per_head: float, per_task_s: float) -> list[tuple[str, ...]]:
    """10,000 heads on N machines of C cores, on paper: each core rigs a head in ``per_core_s`` (the
    2-worker run's wall time per head times 2: its measured efficiency included), the scheduler adds
    ``per_task_s`` per head, and the shared filesystem carries ``mb_per_head`` per head."""
    rows = []
    for machines, cores in ((1, 2), (1, 32), (10, 32), (50, 32)):
        slots = machines * cores
        hours = (PAPER_HEADS * per_core_s / slots + PAPER_HEADS * per_task_s) / 3600
        rate = PAPER_HEADS / (hours * 3600)
        rows.append(
            (
                f"{machines} machine{'s' * (machines > 1)} × {cores} cores ({slots} workers)",
                f"{rate * 3600:,.0f} heads/h",
                f"{hours:.2f} h" if hours >= 1 else f"{hours * 60:.0f} min",
                f"{rate * mb_per_head:.1f} MB/s",
            )
        )
    return rows


def write_jobs(folder: Path, n: int) -> Path:
    """The small rig, ``n`` one-second clips and a manifest ``jobs.csv`` of ``n`` animate items (clip k
    on the rig → ``clip_K.glb``); returns the manifest's path. Clip k goes rest → joy·w + surprise·(1-w)
    at 0.5 s → rest at 1 s, with w = k / n, so every item poses different frames."""
    folder.mkdir(parents=True, exist_ok=True)
    rig = small_rig()
    save_rig(rig, folder / "small.mrig")
    manifest = folder / "jobs.csv"
    with manifest.open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(("input", "output", "clip"))
        for k in range(n):
            w = k / n
            clip = from_expressions(rig, [(0.0, "rest"), (0.5, {"joy": w, "surprise": 1 - w}), (1.0, "rest")])
            save_clip(clip, folder / f"clip_{k:04d}.json")
            writer.writerow(("small.mrig", f"clip_{k:04d}.glb", f"clip_{k:04d}.json"))
    return manifest


@dataclass(frozen=True)
class JobsRun:
    """One ``animate_many`` run of the small jobs; times in seconds from the call."""

    workers: int
    wall: float  # the whole call, as a user waits for it
    ready: float  # the cluster is up: the batch's first progress call, before any item is submitted
    last: float  # the last item is back: its progress call (then the cluster closes, the manifest is written)
    load: float  # the 1-minute load average when the run began
    manifest: Manifest

    @property
    def items(self) -> float:
        """Seconds from the first item submitted to the last one back."""
        return self.last - self.ready

    def busy(self) -> float:
        """The fraction of the workers' time spent in jobs while the items run (what the batch leaves
        of the machine; another load on the cores slows the jobs themselves, not this)."""
        return sum(r.seconds for r in self.manifest.rows) / (self.items * self.workers)

    def overhead(self) -> float:
        """Seconds per job the batch adds to the job's own time while the items run: all workers'
        time in that phase minus the sum of the jobs' times on the workers, per job."""
        rows = self.manifest.rows
        return (self.items * self.workers - sum(r.seconds for r in rows)) / len(rows)


def run_jobs(manifest: Path, out: Path, workers: int, scheduler: str | None = None) -> JobsRun:
    """``animate_many`` of the manifest's items on a fresh LocalCluster of ``workers`` processes, or on
    the cluster of ``scheduler`` (an address; it has ``workers`` workers)."""
    load = os.getloadavg()[0]
    where = {"client": scheduler} if scheduler else {"workers": workers}
    calls = []
    start = time.perf_counter()
    result = animate_many(
        [], out, manifest=manifest, resume=False,
        progress=lambda done, total: calls.append(time.perf_counter() - start), **where,
    )  # fmt: skip
    wall = time.perf_counter() - start
    if result.failed:
        raise SystemExit(f"{len(result.failed)} jobs failed: {result.failed[0].error}")
    missing = [p for r in result.rows for p in r.outputs if not p.is_file()]
    if missing or not result.rows:
        raise SystemExit(f"the batch lost outputs: {missing[:3]}")
    return JobsRun(workers, wall, calls[0], calls[-1], load, result)


def jobs_table(n: int) -> str:
    """Run ``n`` small animate jobs on 1 and on 2 workers; print and return the table (Markdown)."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        manifest = write_jobs(folder / "inputs", n)
        runs = []
        for workers in (1, 2):
            runs.append(run_jobs(manifest, folder / "out", workers))
            shutil.rmtree(folder / "out")  # ~0.9 MB per GLB: not two runs' worth on disk at once
        with loopback_cluster(Path(tempfile.mkdtemp(dir=folder))) as cluster:
            apart = run_jobs(manifest, folder / "out", 2, cluster.address)
    one, two = runs
    speedup = one.wall / two.wall
    rows = []
    for run in runs:
        label = f"{run.workers} worker{'s' * (run.workers > 1)}"
        job_s = statistics.median(r.seconds for r in run.manifest.rows)
        first = run is one
        rows += [
            (f"animate_many, {n:,} jobs, {label}", f"{run.wall:.1f} s", f"{n / run.wall:.1f} jobs/s",
             "—" if first else f"1 worker ({one.wall:.1f} s)",
             "1" if first else f"{speedup:.2f}× = {speedup / 2:.0%} efficiency (goal {EFFICIENCY_GOAL:.0%})"),
            (f"the items alone, {label}", f"{run.items:.1f} s", f"{n / run.items:.1f} jobs/s",
             "—" if first else f"1 worker ({one.items:.1f} s)",
             "1" if first else f"{one.items / two.items:.2f}× = {one.items / two.items / 2:.0%} efficiency"),
            (f"cluster start + close and manifest, {label}", f"{run.ready:.1f} + {run.wall - run.last:.1f} s",
             "—", f"the run ({run.wall:.1f} s)", f"{(run.wall - run.items) / run.wall:.3f}"),
            (f"job on a worker (median), {label}", f"{job_s * 1000:.0f} ms", f"{1 / job_s:.1f} jobs/s",
             "—", "1"),
            (f"batch overhead per job, {label}", f"{run.overhead() * 1000:.1f} ms", "—",
             f"job on a worker ({job_s * 1000:.0f} ms)", f"{run.overhead() / job_s:.3f}"),
            (f"workers busy with jobs, {label}", f"{run.busy():.1%}", "—", "the items' time × workers",
             f"{run.busy():.3f}"),
        ]  # fmt: skip
    rows += [
        (f"animate_many, {n:,} jobs, scheduler + 2 worker processes on 127.0.0.1", f"{apart.wall:.1f} s",
         f"{n / apart.wall:.1f} jobs/s", f"LocalCluster, 2 workers ({two.wall:.1f} s)",
         f"{apart.wall / two.wall:.2f}"),
        ("the items alone, scheduler + 2 worker processes", f"{apart.items:.1f} s",
         f"{n / apart.items:.1f} jobs/s", f"LocalCluster, 2 workers ({two.items:.1f} s)",
         f"{apart.items / two.items:.2f}"),
        ("batch overhead per job, scheduler + 2 worker processes", f"{apart.overhead() * 1000:.1f} ms", "—",
         f"LocalCluster, 2 workers ({two.overhead() * 1000:.1f} ms)",
         f"{apart.overhead() / two.overhead():.2f}"),
    ]  # fmt: skip
    table = print_table(
        f"batch animate: {n:,} one-second clips (30 fps) on the small rig (2,500 skin vertices), a GLB each",
        ("case", "time", "throughput", "baseline", "ratio"),
        rows,
    )
    goal = (
        f"Scaling efficiency goal ≥ {EFFICIENCY_GOAL:.0%} at 2 workers: {speedup / 2:.0%} — "
        f"{'met' if speedup / 2 >= EFFICIENCY_GOAL else 'NOT met'}; load average {one.load:.2f} as the "
        f"1-worker run began, {two.load:.2f} as the 2-worker run began (2 cores)"
    )
    print(f"   {goal}")
    return table + f"\n\n{goal}."


def rig_tables(n: int, resolution: int) -> None:
    """Rig ``n`` heads of ``resolution`` skin vertices (see the module docstring); print and save the
    rigging table and the 10,000 heads on paper."""
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        paths = write_heads(folder / "heads", n, resolution)
        mesh_mb = (
            statistics.mean(p.stat().st_size + p.with_suffix(".json").stat().st_size for p in paths) / 1e6
        )
        one, first = batch(paths, folder / "one", 1)
        two, second = batch(paths, folder / "two", 2)
        job_s = statistics.median(r.seconds for r in second.rows)
        out_mb = statistics.mean(sum(p.stat().st_size for p in r.outputs) for r in second.rows) / 1e6
        few = paths[:CLI_HEADS]
        plain = cli(few, folder / "cli")
        small, _ = batch(few, folder / "few", 1)
        for path in few:  # the batch wrote what the CLI wrote
            name = f"{path.stem}.mrig"
            assert (folder / "cli" / name).read_bytes() == (folder / "few" / name).read_bytes(), name
        per_task = scheduling_cost()
        shutil.rmtree(folder / "one")
    one_job_s = statistics.median(r.seconds for r in first.rows)
    cold = max(r.seconds for r in first.rows) - one_job_s
    overhead = (one - sum(r.seconds for r in first.rows)) / n  # cluster start and hand-offs, per head
    k = len(few)
    rows = [
        (f"rig_many, {n} heads, 1 worker", f"{one:.1f} s", f"{n / one * 3600:,.0f} heads/h", "—", "1"),
        (
            f"rig_many, {n} heads, 2 workers",
            f"{two:.1f} s",
            f"{n / two * 3600:,.0f} heads/h",
            f"1 worker ({one:.1f} s); goal ≥ {SCALING_GOAL:g}×",
            f"{one / two:.2f}× (scaling)",
        ),
        (f"mimetic rig × {k}, one subprocess each", f"{plain:.1f} s", f"{plain / k:.2f} s/head", "—", "1"),
        (
            f"rig_many, the same {k} heads, 1 worker",
            f"{small:.1f} s",
            f"{small / k:.2f} s/head",
            f"mimetic rig × {k} ({plain:.1f} s)",
            f"{small / plain:.2f}",
        ),
        (
            f"batch overhead per head ({n} heads, 1 worker)",
            f"{overhead * 1000:.0f} ms",
            "—",
            f"job on the worker ({one_job_s:.2f} s)",
            f"{overhead / one_job_s:.2f}",
        ),
        (
            "Dask scheduling per task (1,000 no-ops)",
            f"{per_task * 1000:.2f} ms",
            f"{1 / per_task:,.0f} tasks/s",
            f"job ({job_s:.2f} s, 2 workers)",
            f"{per_task / job_s:.1e}",
        ),
    ]
    measured = print_table(
        f"batch rig: {n} generated heads of {resolution:,} skin vertices; rig, fit report, picture each",
        ("case", "time", "throughput", "baseline", "ratio"),
        rows,
    )
    goal = (
        f"Scaling goal ≥ {SCALING_GOAL:g}× on 2 cores: {one / two:.2f}× — "
        f"{'met' if one / two >= SCALING_GOAL else 'NOT met'}; a worker's first head takes {cold:.1f} s "
        f"longer (imports, numba's cache); {mesh_mb:.2f} MB in and {out_mb:.2f} MB out per head"
    )
    print(f"   {goal}")
    report.save("batch", [measured, goal + "."])
    per_core_s = 2 * two / n
    paper = print_table(
        f"{PAPER_HEADS:,} heads on paper (each core as fast as these: {per_core_s:.2f} s per head, the "
        "2-worker run's wall time per head × 2)",
        ("cluster", "throughput", f"{PAPER_HEADS:,} heads", "shared filesystem"),
        estimate(per_core_s, mesh_mb + out_mb, per_task),
    )
    report.save("batch-paper", [paper])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10 heads and 100 jobs (for CI)")
    parser.add_argument("--part", choices=("all", "rig", "jobs"), default="all", help="which tables to make")
    parser.add_argument("--heads", type=int, help="how many heads (default 40, --quick 10)")
    parser.add_argument("--resolution", type=int, default=DEFAULT_RESOLUTION, help="skin vertices per head")
    parser.add_argument("--jobs", type=int, help="how many small jobs (default 1,000, --quick 100)")
    args = parser.parse_args()
    heads = args.heads or (10 if args.quick else 40)
    jobs = args.jobs or (100 if args.quick else 1_000)
    begin = time.perf_counter()
    print(f"load average {os.getloadavg()[0]:.2f} at start; {os.cpu_count()} cores")
    if args.part in ("all", "rig"):
        rig_tables(heads, args.resolution)
    if args.part in ("all", "jobs"):
        report.save("batch-jobs", [jobs_table(jobs)])
    print(f"\nbenchmark wall time {time.perf_counter() - begin:.0f} s")


if __name__ == "__main__":
    main()
