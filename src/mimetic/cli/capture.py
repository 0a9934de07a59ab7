"""``mimetic capture solve|video|retarget``: captured motion solved onto a rig, played on another."""

from __future__ import annotations

from mimetic.cli.app import group, task_command
from mimetic.tasks import capture

capture_app = group(
    "capture", "Performance capture: markers, landmarks or video → activations; retarget to another head."
)
RIG = ("rig", "RIG", "The .mrig rig to solve on.")
OUT = "clip.json / .csv, or anim.mp4 / .glb / .usda / .fbx; the report NAME.report.json beside it."

task_command(
    capture_app,
    "solve",
    capture.SOLVE,
    """Solve a marker or landmark capture into the rig's channel activations (head motion removed).

    The layout's markers are first moved to where this performer's are (from the neutral frame);
    --markers-out keeps that placement for the performer's next takes.

    Examples:

    \b
      mimetic capture solve head.mrig take1.c3d -o take1.json
      mimetic capture solve head.mrig openface.csv --fps 30 -o take.mp4
      mimetic capture solve head.mrig take1.trc --markers markers.json --channels determined -o take1.glb
      mimetic clip edit take1.json --key jaw_open@1.2=0.3 -o take1-edited.json
      mimetic capture solve head.mrig take1-fixed.c3d --edits take1-edited.json -o take1-edited.json
    """,
    arguments=(RIG, ("source", "MARKERS", "Trajectories: .c3d, .trc, mimetic .csv or an OpenFace .csv.")),
    output=OUT,
)

task_command(
    capture_app,
    "video",
    capture.VIDEO,
    """Track a face video with MediaPipe FaceMesh (extra [track]) and solve it into activations.

    The head's motion is taken out through a perspective camera (its field of view estimated from
    the take, or --fov / --focal); the landmarks are placed on the rig where this face's are.

    Examples:

    \b
      mimetic capture video head.mrig face.mp4 -o face.json
      mimetic capture video head.mrig face.mp4 -o face-on-head.mp4 --landmarks-out face.csv
    """,
    arguments=(RIG, ("source", "VIDEO", "A video of one face (MP4, MOV, …).")),
    output=OUT,
)

task_command(
    capture_app,
    "retarget",
    capture.RETARGET,
    """Play a solved clip on another rigged head (channels matched by name, clipped to its ranges).

    Examples:

    \b
      mimetic capture retarget take1.json other.mrig -o take1-other.mp4
      mimetic capture retarget take1.json other.mrig --fps 60 -o take1-other.glb
    """,
    arguments=(
        ("source", "CLIP", "A solved clip (.json from `capture solve`)."),
        ("rig", "RIG", "The .mrig rig to play it on."),
    ),
    output="anim.mp4 / .glb / .usda / .fbx, or the clip as .json / .csv.",
)
