"""``mimetic demo``: the built-in head rigged, posed, animated, speaking and captured."""

from __future__ import annotations

from pathlib import Path

from rich.table import Table

from mimetic.cli.app import app, stdout, task_command
from mimetic.tasks import demo


def _show(result) -> None:
    folder = result.outputs[0].parent if result.outputs else None
    table = Table("file", "size", title=f"mimetic demo → {result.details.get('out_dir', folder)}")
    for path in result.outputs:
        table.add_row(str(path), f"{path.stat().st_size / 1024:,.0f} KB")
    stdout.print(table)
    stdout.print(result.summary, markup=False)
    for note in result.notes:
        stdout.print(f"note: {note}", markup=False)
    stdout.print(f"play with it: mimetic view {result.details['out_dir']}/default.mrig", markup=False)


task_command(
    app,
    "demo",
    demo.TASK,
    """Generate the default head and 8 random heads, rig, pose, animate, lip-sync and capture them, and
    write meshes, rigs, sheets, an animated GLB, MP4s and the ARKit-52 bake (about two minutes);
    --all adds the physics engines' sheets and a simulated jaw drop (a few minutes more).

    Examples:

    \b
      mimetic demo
      mimetic demo --all -o demo-all
    """,
    arguments=(),
    output="Folder for the demo outputs.",
    output_default=Path("mimetic-demo"),
    show=_show,
)
