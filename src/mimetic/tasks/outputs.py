"""The one writer of clips and scenes, chosen by the output's suffix, and the suffix families.

``write_clip(prepared, clip, out, ...)`` is how every task that makes motion delivers it
(animate, speak, capture, retarget; the web viewer's downloads): a clip file (``.json``,
``.csv``), a rendered video (``.mp4``, with its sound), or an animated scene (``.glb``; ``.usda``,
``.usdc``, ``.usd`` with UsdSkel, the ``[usd]`` extra; ``.fbx`` through Blender's FBX exporter) with
one morph target per muscle channel.
``write_scene`` writes a scene with any morph targets (the ARKit-52 export).
"""

from __future__ import annotations

from pathlib import Path

from mimetic.animate.clipfiles import save_clip
from mimetic.animate.keyframes import KeyframeClip
from mimetic.mesh.io import SUPPORTED_FORMATS
from mimetic.rig.activations import Clip
from mimetic.tasks.base import Progress, stage
from mimetic.tasks.prepared import Prepared

IMAGES = (".png", ".jpg", ".jpeg", ".webp")
MESHES = SUPPORTED_FORMATS
CLIP_FILES = (".json", ".csv")
VIDEOS = (".mp4",)
SCENES = (".glb", ".fbx", ".usda", ".usdc", ".usd")
CLIPS = (*CLIP_FILES, *VIDEOS, *SCENES)
"""Everything ``write_clip`` writes."""


def write_scene(
    prepared: Prepared, out: Path, targets: dict, clip: Clip | None = None, progress: Progress | None = None
) -> Path:
    """The rig as a GLB, FBX (Blender's exporter, installed on first use: ``progress`` hears of it) or
    USD (UsdSkel; the ``[usd]`` extra), by ``out``'s suffix, with ``targets`` (name → (n, 3)
    displacements) as morph targets and ``clip`` as its animation."""
    suffix = Path(out).suffix.lower()
    if suffix == ".glb":
        from mimetic.export.gltf import export_glb

        return export_glb(prepared.rig, out, morph_targets=targets, clip=clip)
    if suffix == ".fbx":
        from mimetic.export.fbx import export_fbx

        return export_fbx(prepared.rig, out, morph_targets=targets, clip=clip, progress=progress)
    from mimetic.export.usd import export_usd

    return export_usd(prepared.rig, out, morph_targets=targets, clip=clip)


def write_clip(
    prepared: Prepared,
    clip: Clip | KeyframeClip,
    out: Path,
    *,
    engine: str = "wire",
    size: int = 512,
    fps: float = 30.0,
    audio: Path | None = None,
    progress: Progress | None = None,
) -> Path:
    """Write ``clip`` as ``out``'s suffix says (``CLIPS``); returns ``out``.

    Parameters
    ----------
    prepared : Prepared
        The rig (and its engines, baked once).
    clip : Clip or KeyframeClip
        Sampled values (frames, c) at their fps, or a keyframe clip: written as it is to ``.json``
        (its layers kept), else sampled at ``fps`` over the rig's channels.
    out : Path
        ``.json`` / ``.csv`` clip file, ``.mp4`` video, ``.glb`` / ``.fbx`` / ``.usd*`` animated scene.
    engine : str
        The engine that deforms the video's frames, or is baked into the scene's morph targets.
    size : int
        Video frame size in pixels (square).
    fps : float
        The rate a keyframe clip is sampled at.
    audio : Path, optional
        The video's sound track.
    progress : callable(step, done, total), optional
    """
    out = Path(out)
    suffix = out.suffix.lower()
    if isinstance(clip, KeyframeClip) and suffix == ".json":
        return save_clip(clip, out)
    sampled = clip.sample(fps, channels=prepared.rig) if isinstance(clip, KeyframeClip) else clip
    if suffix in CLIP_FILES:
        return save_clip(sampled, out)
    if suffix in VIDEOS:
        from mimetic.view.video import render_clip

        deformer = prepared.engine(engine, stage(progress, f"prepare {engine}"))
        return render_clip(
            prepared.rig,
            sampled,
            out,
            engine=deformer,
            size=size,
            audio=audio,
            progress=stage(progress, "video"),
        )
    targets = prepared.morph_targets(engine, stage(progress, f"bake {engine}"))
    return write_scene(prepared, out, targets, sampled, progress)
