"""``mimetic clip new`` and ``mimetic clip edit``: keyframed clips through poses, and edits of them."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from mimetic.animate.curves import DEFAULT_KNOT_SPACING_S, INTERPOLATIONS
from mimetic.tasks.base import Progress, Result, Task, TaskError, TaskOptions, announce, check_output, option
from mimetic.tasks.outputs import CLIP_FILES
from mimetic.tasks.parsing import key_specs, pose_specs


@dataclass(frozen=True)
class ClipNewOptions(TaskOptions):
    """The key poses of a new clip (see ``option`` for the fields' metadata)."""

    poses: tuple[tuple[float, tuple[tuple[str, float], ...] | None], ...] = option(
        (),
        "A key pose, or TIME:rest (repeatable).",
        flag="--pose",
        metavar="TIME:EXPR[=W][+...]",
        parse=pose_specs,
        cli_type=list[str],
    )
    interpolation: str = option("cubic", "Between keys.", choices=INTERPOLATIONS)


def new(source: Path, output: Path, options: ClipNewOptions, progress: Progress | None = None) -> Result:
    """A clip on the rig ``source``'s channels through ``options.poses`` (time, expression blend or
    None for rest), written to ``output`` (.json, or sampled curves .csv at 30 fps)."""
    from mimetic.animate.clipfiles import save_clip
    from mimetic.animate.keyframes import from_expressions
    from mimetic.tasks.prepared import prepared_rig

    check_output(output, CLIP_FILES)
    if not options.poses:
        raise TaskError("a clip needs at least one key pose (time and expression)")
    announce(progress, "clip")
    sequence = [(t, None if blend is None else dict(blend)) for t, blend in options.poses]
    clip = from_expressions(prepared_rig(source).rig, sequence, interpolation=options.interpolation)
    save_clip(clip, output, fps=30.0)
    return Result((Path(output),), f"{clip.duration_s:g} s, {len(clip.channels)} channels")


@dataclass(frozen=True)
class ClipEditOptions(TaskOptions):
    """The keys an edit passes through (see ``option`` for the fields' metadata)."""

    keys: tuple[tuple[str, float, float], ...] = option(
        (),
        "A new key the edited curve must pass through (repeatable).",
        flag="--key",
        metavar="CHANNEL@TIME=VALUE",
        parse=key_specs,
        cli_type=list[str],
    )
    knot_spacing_s: float = option(
        DEFAULT_KNOT_SPACING_S,
        "B-spline knot spacing in seconds: how far each edit reaches.",
        flag="--knot-spacing",
        minimum=1e-3,
    )
    layer: str = option("edit", "The edit layer to add the displacement to.")


def edit(source: Path, output: Path, options: ClipEditOptions, progress: Progress | None = None) -> Result:
    """The clip file ``source`` edited by a smooth B-spline displacement through ``options.keys``
    (``KeyframeClip.edit``), kept in its own layer, written to ``output`` (.json)."""
    from mimetic.animate.clipfiles import load_clip, save_clip

    check_output(output, (".json",))
    if not options.keys:
        raise TaskError("an edit needs at least one key (channel, time, value)")
    announce(progress, "edit")
    clip = load_clip(source)
    by_channel: dict[str, dict[float, float]] = {}
    for channel, time_s, value in options.keys:
        by_channel.setdefault(channel, {})[time_s] = value
    for channel, constraints in by_channel.items():
        clip = clip.edit(channel, constraints, knot_spacing_s=options.knot_spacing_s, layer=options.layer)
    save_clip(clip, output)
    return Result((Path(output),), f"{len(options.keys)} keys in layer {options.layer!r}")


NEW = Task("clip new", ClipNewOptions, new, CLIP_FILES, source="rig")
EDIT = Task("clip edit", ClipEditOptions, edit, (".json",), source="clip")
