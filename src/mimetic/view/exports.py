"""The web viewer's downloads, made by the same tasks as the command line (``mimetic.tasks``).

The GLB or FBX is ``mimetic export`` (no clip on the timeline) or ``mimetic animate`` (the timeline's
clip sampled at ``session.FPS``) of the viewer's rig and engine; the PNG is ``mimetic pose`` of what the
page shows, a front close-up posed by the viewer's own prepared engine. Each is written into a
temporary folder (removed afterwards) and handed to the browser as bytes.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np

from mimetic.animate.keyframes import KeyframeClip
from mimetic.view.session import FPS

PNG_SIZE = 768


def scene_bytes(rig_file: Path, engine: str, clip: KeyframeClip | None = None, suffix: str = ".glb") -> bytes:
    """The rig file as a GLB (or ``suffix`` ".fbx": FBX through Blender) with one morph target per
    muscle (``engine`` baked) and, when given, ``clip`` sampled at ``FPS`` as its animation: what
    ``mimetic export`` / ``mimetic animate`` write."""
    from mimetic.animate.clipfiles import save_clip
    from mimetic.tasks import animate, export

    with tempfile.TemporaryDirectory(prefix="mimetic-view-") as folder:
        out = Path(folder) / f"head{suffix}"
        if clip is None:
            export.run(rig_file, out, export.ExportOptions(engine=engine))
        else:
            clip_file = save_clip(clip, Path(folder) / "clip.json")
            animate.run(rig_file, out, animate.AnimateOptions(clip=clip_file, fps=FPS, engine=engine))
        return out.read_bytes()


def png_bytes(
    rig_file: Path,
    engine: str,
    pose: np.ndarray,
    channels: tuple[str, ...],
    deform: Callable[[np.ndarray], np.ndarray],
    size: int = PNG_SIZE,
) -> bytes:
    """``mimetic pose`` of ``pose`` (c,) over ``channels`` as a front close-up PNG (size × size), posed
    by ``deform`` (the viewer's prepared engine: pose → vertices (n, 3))."""
    from mimetic.tasks import pose as pose_task

    values = tuple(zip(channels, (float(v) for v in pose), strict=True))
    options = pose_task.PoseOptions(values=values, engine=engine, view="front", size=size)
    with tempfile.TemporaryDirectory(prefix="mimetic-view-") as folder:
        out = Path(folder) / "pose.png"
        pose_task.run(rig_file, out, options, deform=lambda _: np.asarray(deform(pose), dtype=np.float64))
        return out.read_bytes()
