"""Commands on rigs: ``rig`` (fit and rig a mesh), ``pose``, ``export``, ``list``."""

from __future__ import annotations

import json

import typer
from rich.table import Table

from mimetic.cli.app import app, stdout, task_command
from mimetic.tasks import export, lists, pose, rig

task_command(
    app,
    "rig",
    rig.TASK,
    """Fit the reference head to a mesh and write a muscle rig on the mesh's own vertices, with its fit
    report (NAME.fit.json) and picture (NAME.fit.png) beside it.

    Examples:

    \b
      mimetic rig my_head.obj -o my_head.mrig
      mimetic rig scan.stl --units mm --landmarks dlib68.csv -o scan.mrig
    """,
    arguments=(("source", "MESH", "The head mesh to rig (.obj .ply .stl .glb .gltf .fbx)."),),
    output="The .mrig file to write.",
)

task_command(
    app,
    "pose",
    pose.TASK,
    """Pose RIG with expressions and channel values; write a face render or the posed mesh.

    Names: mimetic list expressions, mimetic list channels RIG.

    Examples:

    \b
      mimetic pose head.mrig --expr joy -o joy.png
      mimetic pose head.mrig --expr joy=0.7 --expr surprise=0.3 --set jaw_open=0.2 -o joy.obj
    """,
    arguments=(("source", "RIG", "A .mrig rig (e.g. from `mimetic head --rig` or `mimetic rig`)."),),
    output="An image (.png .jpg), or the posed mesh (.obj .ply .stl in your own frame; .glb .gltf).",
)

task_command(
    app,
    "export",
    export.TASK,
    """Export a rig as GLB, FBX or USD with named morph targets and its skeleton (ARKit-52 with --arkit).

    Examples:

    \b
      mimetic export head.mrig -o head.glb
      mimetic export head.mrig --arkit -o head_arkit.fbx
      mimetic export head.mrig --arkit -o head_arkit.usdc --obj-dir arkit_shapes/
    """,
    arguments=(("source", "RIG", "The .mrig rig to export."),),
    output="The .glb, .fbx (through Blender, installed on first use) or .usda/.usdc (UsdSkel) file to write.",
)


def _show_rows(result, as_json: bool) -> None:
    columns, rows = result.details["columns"], result.details["rows"]
    if as_json:
        stdout.print_json(json.dumps([dict(zip(columns, row, strict=True)) for row in rows]))
        return
    table = Table(*columns, title=result.summary, title_justify="left")
    for row in rows:
        table.add_row(*(str(c) for c in row))
    stdout.print(table)


task_command(
    app,
    "list",
    lists.TASK,
    """List the names a command takes: expressions, channels (with ranges and units), muscles,
    descriptive controls, FACS action units or ARKit-52 shapes.

    Examples:

    \b
      mimetic list expressions
      mimetic list channels my_head.mrig --json
    """,
    arguments=(
        ("what", "WHAT", "expressions, channels, muscles, controls, facs or arkit."),
        ("source", "RIG", "A .mrig rig (channels and muscles; default: the built-in head's rig).", False),
    ),
    output=None,
    extras={"as_json": (bool, typer.Option(False, "--json", help="Print the rows as JSON."))},
    show=_show_rows,
)
