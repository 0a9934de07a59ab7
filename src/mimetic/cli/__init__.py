"""The ``mimetic`` command (typer + rich): one module per command group, each a thin front end over
the task layer (``mimetic.tasks``).

Modules: ``app`` (the app, its error boundary, progress lines, commands made from tasks),
``meshes`` (head, info, render), ``rigging`` (rig, pose, export, list), ``motion`` (clip new|edit,
animate, speak), ``capture`` (capture solve|video|retarget), ``view``, ``demo``, ``batch``, ``setup``
(setup fbx).
"""

from mimetic.cli import batch, capture, demo, meshes, motion, rigging, setup, view  # noqa: F401  (they register)
from mimetic.cli.app import app

__all__ = ["app"]
