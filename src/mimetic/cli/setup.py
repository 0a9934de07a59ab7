"""``mimetic setup fbx``: install what an optional format needs ahead of its first use."""

from __future__ import annotations

from mimetic.cli.app import command, group, stdout, steps

setup_app = group("setup", "Install what an optional feature needs, ahead of its first use.")


@command("fbx", parent=setup_app)
def fbx() -> None:
    """Install Blender's Python module (bpy) in its own venv, for FBX in and out (needs Python 3.11;
    about 1 GB in ~/.cache/mimetic). MIMETIC_BLENDER=/path/to/blender uses a Blender you have instead.

    Examples:

    \b
      mimetic setup fbx
    """
    from mimetic.blender import BPY_VERSION, blender, run_script
    from mimetic.errors import MimeticError

    with steps() as progress:
        tool = blender(progress)
    report = run_script("version.py", [], error=MimeticError)
    stdout.print(
        f"FBX ready: Blender {report['blender']} (bpy {BPY_VERSION}) at {tool.program}", markup=False
    )
