"""Benchmark offscreen rendering of the generated head: GL (warm and cold) and the CPU fallback, 512².

    python benchmarks/bench_render.py [--quick]

Prints one table: case | median time | throughput | baseline | ratio. The baseline is the
0.5 s-per-image goal, except for the last rows, which compare GL with the CPU rasterizer
measured in the same run. "GL cold" includes creating the EGL context; the very first one in
a process also loads the GL libraries.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import report
from mimetic.head.model import make_head
from mimetic.mesh.model import Mesh
from mimetic.view import Renderer, frame_camera, rasterize

GOAL_S = 0.5  # per 512² image of a ~20k-triangle head, context reuse included
SIZE = (512, 512)


def head_case(resolution: int) -> Mesh:
    """The default generated head with all its parts (10k skin vertices: 13.4k vertices, 26.5k triangles)."""
    return make_head(resolution=resolution).mesh


def median_time(fn: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def cold_render(mesh: Mesh, camera) -> None:
    renderer = Renderer("egl")
    renderer.render(mesh, camera, size=SIZE)
    renderer.release()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer cases and repeats (for CI)")
    args = parser.parse_args()
    grid = [10_000] if args.quick else [10_000, 30_000]
    repeats, cold_repeats = (3, 2) if args.quick else (20, 5)

    rows: list[tuple[str, float, float, str, float]] = []  # case, median s, tris, baseline label, baseline s
    first_mesh = head_case(grid[0])
    first_camera = frame_camera(first_mesh.vertices.min(0), first_mesh.vertices.max(0))
    first = median_time(lambda: cold_render(first_mesh, first_camera), 1)
    rows.append(
        (
            f"GL cold, first in process, {first_mesh.n_faces // 1000}k tris",
            first,
            first_mesh.n_faces,
            "goal",
            GOAL_S,
        )
    )

    warm = Renderer("egl")
    comparisons = []
    for resolution in grid:
        mesh = head_case(resolution)
        camera = frame_camera(mesh.vertices.min(0), mesh.vertices.max(0))
        tris = mesh.n_faces
        label = f"{tris / 1000:.0f}k tris"
        warm.render(mesh, camera, size=SIZE)  # context, buffers, framebuffer
        gl = median_time(lambda: warm.render(mesh, camera, size=SIZE), repeats)  # noqa: B023
        rows.append((f"GL warm, msaa 4, {label}", gl, tris, "goal", GOAL_S))
        if not args.quick:
            gl0 = median_time(lambda: warm.render(mesh, camera, size=SIZE, msaa=0), repeats)  # noqa: B023
            rows.append((f"GL warm, msaa 0, {label}", gl0, tris, "goal", GOAL_S))
            wire = median_time(lambda: warm.render(mesh, camera, size=SIZE, wireframe=True), repeats)  # noqa: B023
            rows.append((f"GL warm, wireframe, {label}", wire, tris, "goal", GOAL_S))
        cold = median_time(lambda: cold_render(mesh, camera), cold_repeats)  # noqa: B023
        rows.append((f"GL cold, new context, {label}", cold, tris, "goal", GOAL_S))
        cpu = median_time(lambda: rasterize(mesh, camera, size=SIZE), max(2, repeats // 4))  # noqa: B023
        rows.append((f"CPU fallback, {label}", cpu, tris, "goal", GOAL_S))
        comparisons.append((f"GL warm vs CPU, {label}", gl, tris, f"CPU {cpu * 1e3:.0f} ms", cpu))
    warm.release()
    rows += comparisons

    header = ("case", "median time", "throughput", "baseline", "ratio")
    body = [
        (
            case,
            f"{t * 1e3:.1f} ms",
            f"{1 / t:.1f} img/s ({tris / t / 1e6:.2f} Mtri/s)",
            f"{base_s * 1e3:.0f} ms" if base == "goal" else base,
            f"{t / base_s:.3f}",
        )
        for case, t, tris, base, base_s in rows
    ]
    table = report.show(
        f"512x512 renders of the generated head; goal {GOAL_S} s per image",
        header,
        body,
        "ratio = median / baseline (below 1 is better)",
    )
    report.save("render", [table])


if __name__ == "__main__":
    main()
