"""``mimetic animate``: a clip played on a rig, as a video, an animated scene or a clip file."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from mimetic.engines import ENGINES
from mimetic.tasks.base import Progress, Result, Task, TaskOptions, announce, check_output, option
from mimetic.tasks.outputs import CLIPS, SCENES, VIDEOS

FPS = (1e-3, 240.0)
"""The frame rates a clip is sampled at."""
VIDEO_SIZES = (64, 2160)
"""Video frame sizes in pixels (square)."""


@dataclass(frozen=True)
class DeliverOptions(TaskOptions):
    """How motion is delivered, shared by every task that writes a clip (``outputs.write_clip``)."""

    size: int = option(512, "Video size in pixels (square).", minimum=VIDEO_SIZES[0], maximum=VIDEO_SIZES[1])
    engine: str = option(
        "wire",
        "Deformation engine (of the video, the scene's morph targets, a capture's solve).",
        choices=ENGINES,
    )


@dataclass(frozen=True)
class PlayOptions(DeliverOptions):
    """Delivery of a clip sampled at a frame rate of the user's choosing."""

    fps: float = option(30.0, "Frames per second of the output.", minimum=FPS[0], maximum=FPS[1])


@dataclass(frozen=True)
class AnimateOptions(PlayOptions):
    """The clip to play (see ``option`` for the fields' metadata)."""

    clip: Path | None = option(None, "A clip file (.json from `mimetic clip new` or the API, or .csv).")
    audio: Path | None = option(None, "A sound track for the video (WAV, …).")


def run(source: Path, output: Path, options: AnimateOptions, progress: Progress | None = None) -> Result:
    """Play ``options.clip`` on the rig ``source``: ``output`` .mp4 (rendered, with ``audio``), .glb
    or .usda/.usdc/.usd (morph targets, skeleton and animation), or the sampled clip (.json .csv)."""
    from mimetic.animate.clipfiles import load_clip
    from mimetic.tasks.outputs import write_clip
    from mimetic.tasks.prepared import prepared_rig

    check_output(output, CLIPS)
    TASK.check(options)
    prepared = prepared_rig(source)
    announce(progress, "clip")
    sampled = load_clip(options.clip).sample(options.fps, channels=prepared.rig)
    write_clip(
        prepared,
        sampled,
        output,
        engine=options.engine,
        size=options.size,
        audio=options.audio,
        progress=progress,
    )
    return Result((Path(output),), f"{sampled.n_frames} frames at {options.fps:g} fps")


TASK = Task(
    "animate", AnimateOptions, run, (*SCENES, *VIDEOS, ".json", ".csv"), source="rig", required=(("clip",),)
)
