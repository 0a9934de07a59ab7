"""Commands that make motion: ``clip new|edit``, ``animate``, ``speak``."""

from __future__ import annotations

from mimetic.cli.app import app, group, task_command
from mimetic.tasks import animate, clip, speak

clip_app = group("clip", "Make and edit keyframed clips (JSON).")

task_command(
    clip_app,
    "new",
    clip.NEW,
    """Make a clip through expression poses.

    Examples:

    \b
      mimetic clip new head.mrig --pose 0:rest --pose 0.5:joy --pose 1:rest -o clip.json
      mimetic clip new head.mrig --pose 0:rest --pose 1:surprise=0.8+joy=0.2 --interpolation tcb -o c.json
    """,
    arguments=(("source", "RIG", "The .mrig rig whose channels the clip drives."),),
    output="The clip to write (.json; .csv for sampled curves).",
)

task_command(
    clip_app,
    "edit",
    clip.EDIT,
    """Edit curves by a smooth B-spline displacement through new keys, kept in its own layer.

    Examples:

    \b
      mimetic clip edit clip.json --key jaw_open@0.75=0.3 -o edited.json
      mimetic clip edit clip.json --key jaw_open@0.5=0.2 --key jaw_open@1=0 --knot-spacing 0.1 -o e.json
    """,
    arguments=(("source", "CLIP", "The clip JSON to edit."),),
    output="The edited clip JSON to write.",
)

task_command(
    app,
    "animate",
    animate.TASK,
    """Play a clip on a rig: render an MP4 (with optional audio) or export an animated GLB, FBX or USD.

    Examples:

    \b
      mimetic animate head.mrig --clip clip.json -o anim.mp4 --audio speech.wav
      mimetic animate head.mrig --clip clip.json --fps 60 -o anim.glb
      mimetic animate head.mrig --clip clip.json --fps 60 -o anim.fbx
    """,
    arguments=(("source", "RIG", "The .mrig rig to animate."),),
    output="anim.mp4 (a rendered video), anim.glb / .fbx / .usda / .usdc (UsdSkel), or the clip .json/.csv.",
)

task_command(
    app,
    "speak",
    speak.TASK,
    """Lip sync: text, phone timings or audio + transcript to a talking head (visemes, coarticulation).

    Examples:

    \b
      mimetic speak head.mrig --text "Hello there" -o hello.mp4
      mimetic speak head.mrig --audio take1.wav --text-file take1.txt -o take1.mp4
      mimetic speak head.mrig --timings take1.TextGrid --audio take1.wav -o take1.glb
      mimetic speak head.mrig --text "Dumela, o kae?" --language nso -o dumela.mp4
      mimetic speak head.mrig --text "Hello there" --synthesize -o hello.mp4
    """,
    arguments=(("source", "RIG", "The .mrig rig that speaks."),),
    output="talk.mp4 (video with the sound), talk.glb / .fbx / .usda / .usdc, or the clip as .json / .csv.",
)
