"""``mimetic pose``: a rig posed by expressions and channel values, as an image or a mesh."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mimetic.engines import ENGINES
from mimetic.tasks.base import Progress, Result, Task, TaskOptions, announce, check_output, option, stage
from mimetic.tasks.outputs import IMAGES, MESHES
from mimetic.tasks.parsing import channel_values, proxy_spec, weights
from mimetic.tasks.render import SHEET_VIEWS

SOURCE_FRAME = (".obj", ".ply", ".stl")
"""Mesh outputs written in the user's own frame (glTF keeps the rig's +Y up, +Z forward)."""


@dataclass(frozen=True)
class PoseOptions(TaskOptions):
    """The pose and how it is shown (see ``option`` for the fields' metadata)."""

    expressions: tuple[tuple[str, float], ...] = option(
        (),
        "Blend an expression (repeatable).",
        flag="--expr",
        metavar="NAME[=WEIGHT]",
        parse=weights,
        cli_type=list[str],
    )
    values: tuple[tuple[str, float], ...] = option(
        (),
        "Set a channel after the blend (repeatable).",
        flag="--set",
        metavar="CHANNEL=VALUE",
        parse=channel_values,
        cli_type=list[str],
    )
    engine: str = option("wire", "Deformation engine.", choices=ENGINES)
    proxy: str | int = option(
        "auto",
        "fem and tissue: simulate on a decimated skin of N vertices (auto: 20000 above 30000), or off.",
        metavar="auto|off|N",
        parse=proxy_spec,
        cli_type=str,
    )
    view: str = option("front", "For images: one view, or all three in a sheet.", choices=SHEET_VIEWS)
    size: int = option(512, "Image size in pixels (per view).", minimum=64, maximum=4096)
    intensity: float = option(1.0, "Scale the whole expression blend.")
    library: Path | None = option(None, "An expression library JSON file (default: the built-in one).")


def run(
    source: Path,
    output: Path,
    options: PoseOptions = PoseOptions(),
    progress: Progress | None = None,
    *,
    deform: Callable[[np.ndarray], np.ndarray] | None = None,
) -> Result:
    """Pose the rig ``source`` and write ``output``: a face render (.png .jpg .webp) or the posed
    mesh (.obj .ply .stl in the user's own frame; .glb .gltf).

    ``deform`` (a pose (c,) → vertices (n, 3)) replaces the engine for a front end that holds one
    prepared (the web viewer).
    """
    from mimetic.animate.expressions import compose_pose, load_library
    from mimetic.tasks.prepared import prepared_rig

    check_output(output, (*IMAGES, *MESHES))
    prepared = prepared_rig(source)
    rig = prepared.rig
    library = load_library(options.library, channels=rig) if options.library is not None else None
    pose = compose_pose(
        rig, options.expressions, dict(options.values), intensity=options.intensity, library=library
    )
    if deform is None:
        announce(progress, f"prepare {options.engine}")  # at once: fem and tissue take seconds
        engine = prepared.engine(
            options.engine, stage(progress, f"prepare {options.engine}"), proxy=options.proxy
        )
        deform = engine.deform
    announce(progress, "pose")
    vertices = deform(pose)
    kind = Path(output).suffix.lower()
    if kind in IMAGES:
        from mimetic.view import save_image
        from mimetic.view.sheets import render_posed

        announce(progress, "render")
        save_image(render_posed(rig, vertices, view=options.view, size=options.size), output)
        what = f"{options.view} view" + ("s" if options.view == "all" else "")
    else:
        from mimetic.mesh.io import save_mesh

        posed = rig.mesh.with_vertices(vertices)
        if kind in SOURCE_FRAME:
            posed = rig.source_mesh(posed.vertices)
        save_mesh(posed, output)
        what = f"{posed.n_vertices:,} vertices"
    shown = ", ".join(f"{n}={w:g}" for n, w in options.expressions) or "rest"
    return Result((Path(output),), f"{shown} on the {options.engine} engine: {what}")


TASK = Task("pose", PoseOptions, run, (*IMAGES, *MESHES), source="rig")
