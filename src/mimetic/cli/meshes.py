"""Commands on meshes: ``head`` (generate one), ``info`` (what a file holds), ``render`` (a picture)."""

from __future__ import annotations

import json

import typer
from rich.text import Text

from mimetic.cli.app import app, stdout, task_command
from mimetic.tasks import head, info, render

task_command(
    app,
    "head",
    head.TASK,
    """Generate a parametric reference head and write it as a mesh (and optionally its rig).

    Examples:

    \b
      mimetic head -o head.glb
      mimetic head --seed 7 --param nose_length=1.05 -o head.obj --rig head.mrig
    """,
    arguments=(),
    output="Mesh file to write (.glb, .gltf, .obj, .ply, .stl).",
)


def _show_info(result, as_json: bool) -> None:
    report = result.details
    if as_json:
        stdout.print_json(json.dumps({k: v for k, v in report.items()}))
    else:
        stdout.print(Text.assemble((report["file"], "bold"), f" ({report['kind']})"))
        for line in report["lines"]:
            stdout.print(f"  {line}", markup=False)
        landmarks = report["landmarks"]
        text = landmarks if isinstance(landmarks, str) else f"{len(landmarks)}: {', '.join(landmarks)}"
        stdout.print(f"  landmarks         {text}", markup=False)
    if not report["ok"]:
        raise typer.Exit(1)


task_command(
    app,
    "info",
    info.TASK,
    """Validate a mesh or rig and report its units, parts, seams, winding and landmarks.

    Exit code 1 when the mesh cannot be rigged as it is.

    Examples:

    \b
      mimetic info scan.obj
      mimetic info scan.stl --units mm --json
    """,
    arguments=(("source", "FILE", "A mesh (.obj .ply .stl .glb .gltf .fbx) or a rig (.mrig)."),),
    output=None,
    extras={"as_json": (bool, typer.Option(False, "--json", help="Print the report as JSON."))},
    show=_show_info,
)

task_command(
    app,
    "render",
    render.TASK,
    """Render a mesh or rig to an image, from one angle or three.

    Examples:

    \b
      mimetic render scan.obj -o scan.png
      mimetic render head.mrig --view front --no-muscles --size 1024 -o face.jpg
    """,
    arguments=(("source", "FILE", "A mesh or a .mrig rig."),),
    output="Image to write (.png, .jpg, .webp).",
)
