"""The task layer: one module per command, what every front end calls.

Each task is a frozen options dataclass that declares every default and choice once, and
``run(source, output, options, progress) -> Result`` (see ``mimetic.tasks.base``). The command
line parses its arguments into the options and calls ``run``; ``mimetic batch`` runs a task per
input on a cluster; the web viewer's downloads call the same tasks; Python can too::

    from mimetic.tasks import TASKS

    task = TASKS["animate"]
    result = task.run("head.mrig", "hello.glb", task.options(clip="hello.json", fps=60))
    print(result.summary)                     # "120 frames at 60 fps"

Modules: ``base`` (options, ``Task``, ``Result``), ``outputs`` (the clip and scene writer chosen by
suffix), ``prepared`` (a rig loaded once per process with its engines and bakes), ``parsing`` (text
forms of structured options), and one per command: ``head``, ``info``, ``render``, ``rig``,
``pose``, ``clip``, ``animate``, ``speak``, ``capture``, ``export``, ``lists``, ``demo``.
"""

from __future__ import annotations

from mimetic.tasks import animate, capture, clip, demo, export, head, info, lists, pose, render, rig, speak
from mimetic.tasks.base import OutputError, Progress, Result, Task, TaskError, TaskOptions, option, specs

TASKS: dict[str, Task] = {
    task.name: task
    for task in (
        head.TASK,
        info.TASK,
        render.TASK,
        rig.TASK,
        pose.TASK,
        clip.NEW,
        clip.EDIT,
        animate.TASK,
        speak.TASK,
        capture.SOLVE,
        capture.VIDEO,
        capture.RETARGET,
        export.TASK,
        lists.TASK,
        demo.TASK,
    )
}
"""Every task by its command's name ("rig", "capture solve", …)."""

BATCH_TASKS: dict[str, Task] = {
    "rig": rig.TASK,
    "render": render.TASK,
    "animate": animate.TASK,
    "speak": speak.TASK,
    "capture": capture.SOLVE,
}
"""The tasks ``mimetic batch`` runs, by batch kind: one item per input file."""

__all__ = [
    "BATCH_TASKS",
    "TASKS",
    "OutputError",
    "Progress",
    "Result",
    "Task",
    "TaskError",
    "TaskOptions",
    "option",
    "specs",
]
