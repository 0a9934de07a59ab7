"""Benchmark exporting and rendering animation of the default head: GLB, FBX, OBJ sequence, MP4 frames.

    python benchmarks/bench_export.py [--quick]

Prints one table: case | median time | throughput | baseline | ratio. The clip is an expression
sequence (rest → joy → surprise → anger → rest, cubic keys) of 10 s at 60 fps (600 frames), on the
default head (13,363 vertices) with its baked basis as 37 named morph targets (one per muscle).
--quick times each case once and renders fewer video frames.
The GLB goal is the issue's 2 s for the 10 s clip; the FBX (Blender's exporter through bpy in its own
process: GLB, Blender start, glTF import, FBX export) is compared with the GLB; rendering is measured
per frame (512², GL warm, no MSAA) against the 0.5 s-per-image goal of the renderer, and the MP4 case
includes encoding.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import report
from bench_render import median_time  # the same timing helper as the render benchmark
from mimetic.animate.keyframes import from_expressions
from mimetic.blender import BlenderError, blender
from mimetic.engines import make_engine
from mimetic.engines.bake import bake
from mimetic.export.fbx import export_fbx
from mimetic.export.gltf import export_glb, morph_targets_from_basis
from mimetic.export.obj_sequence import export_obj_sequence
from mimetic.head.model import make_head
from mimetic.render.renderer import Renderer
from mimetic.rig.activations import Clip
from mimetic.rig.recipe import build_rig
from mimetic.view.video import render_clip

GLB_GOAL_S = 2.0  # a 10 s, 60 fps clip
FRAME_GOAL_S = 0.5  # per rendered 512² image
FPS = 60


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="a 2 s clip and fewer repeats (for CI)")
    args = parser.parse_args()
    seconds = 10.0
    repeats = 1 if args.quick else 3
    rig = build_rig(make_head())
    basis = bake(make_engine(rig, "wire"), samples=8 if args.quick else 32).basis
    targets = morph_targets_from_basis(basis, rig)
    step = seconds / 4
    keys = from_expressions(
        rig, [(0.0, "rest"), (step, "joy"), (2 * step, "surprise"), (3 * step, "anger"), (seconds, "rest")]
    )
    clip = keys.sample(FPS, channels=rig)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        t = median_time(
            lambda: export_glb(rig, folder / "anim.glb", morph_targets=targets, clip=clip), repeats
        )
        size_mb = (folder / "anim.glb").stat().st_size / 1e6
        rows.append(
            (
                f"GLB: {len(targets)} morph targets + {seconds:g} s clip at {FPS} fps ({size_mb:.1f} MB)",
                t,
                f"{clip.n_frames / t:,.0f} frames/s",
                f"goal {GLB_GOAL_S:g} s",
                t / GLB_GOAL_S,
            )
        )
        glb_s = t
        try:
            blender()  # installed before timing, not during
            t = median_time(
                lambda: export_fbx(rig, folder / "anim.fbx", morph_targets=targets, clip=clip), repeats
            )
            size_mb = (folder / "anim.fbx").stat().st_size / 1e6
            rows.append(
                (
                    f"FBX (Blender 5.0 exporter): the same rig and clip ({size_mb:.1f} MB)",
                    t,
                    f"{clip.n_frames / t:,.0f} frames/s",
                    "the GLB above",
                    t / glb_s,
                )
            )
        except BlenderError as error:
            rows.append((f"FBX: not measured ({error})", float("nan"), "—", "—", float("nan")))
        n_obj = 20 if args.quick else 60
        part = Clip(clip.channels, clip.values[:n_obj], FPS)
        t = median_time(lambda: export_obj_sequence(rig, part, folder / "obj", basis=basis), repeats)
        rows.append(
            (f"OBJ sequence, {n_obj} frames (basis)", t, f"{n_obj / t:,.1f} frames/s", "—", float("nan"))
        )
        renderer = Renderer()
        n_video = 30 if args.quick else 120
        video = Clip(clip.channels, clip.values[:n_video], FPS)
        render_clip(rig, Clip(clip.channels, clip.values[:2], FPS), folder / "warm.mp4", basis=basis,
                    renderer=renderer)  # fmt: skip
        t = median_time(
            lambda: render_clip(rig, video, folder / "clip.mp4", basis=basis, size=512, renderer=renderer),
            repeats,
        )
        rows.append(
            (
                f"MP4 512², {n_video} frames (pose + render + H.264)",
                t,
                f"{n_video / t:,.1f} frames/s",
                f"goal {FRAME_GOAL_S:g} s/frame",
                (t / n_video) / FRAME_GOAL_S,
            )
        )
    body = [
        (
            case,
            "—" if t != t else f"{t:.3f} s",
            throughput,
            baseline,
            "" if ratio != ratio else f"{ratio:.3f}",
        )
        for case, t, throughput, baseline, ratio in rows
    ]
    table = report.show(
        "Export of the default head's rig", ("case", "median time", "throughput", "baseline", "ratio"), body
    )
    report.save("export", [table])


if __name__ == "__main__":
    main()
