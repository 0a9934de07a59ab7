"""``mimetic capture solve|video|retarget``: captured motion solved onto a rig, and played on another.

The solve (one place for it): the rig's engine baked linearly (``prepared.CAPTURE_BAKE``), the
marker layout placed on the rig, the channels chosen (``capture.expression.resolve_channels``),
``capture.performance.solve_performance`` (head motion removed, the layout moved to where this
performer's markers are), then the clip delivered by ``outputs.write_clip`` with its plausibility
report beside it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from mimetic.capture.markers import LAYOUTS
from mimetic.capture.smooth import CUTOFF_HZ
from mimetic.capture.trajectories import LENGTH_UNITS
from mimetic.tasks.animate import DeliverOptions, PlayOptions
from mimetic.tasks.base import (
    Progress,
    Result,
    Task,
    TaskError,
    announce,
    beside,
    check_output,
    option,
    stage,
)
from mimetic.tasks.outputs import CLIPS, SCENES, VIDEOS

CAPTURE_OUTPUTS = (".json", ".csv", *VIDEOS, *SCENES)
"""What a capture writes: the clip first (its default), or the clip delivered."""


@dataclass(frozen=True)
class SolveOptions(DeliverOptions):
    """What every capture solve takes (see ``option`` for the fields' metadata)."""

    rig: Path | None = option(None, "The .mrig rig to solve on.")
    markers: str | None = option(
        None,
        "Marker layout: paper, ibug68, mediapipe or a marker .json (default: from the point names). A "
        "file written by --markers-out holds one performer's markers, placed on an earlier take: not "
        "placed again.",
        names=LAYOUTS,
    )
    neutral_frame: int = option(0, "A frame with a neutral face.", minimum=0)
    channels: str = option(
        "all",
        "Channels to solve: all (every channel the markers see but the gaze and the nose's small "
        "muscles), determined (those the markers pin down at 1 mm noise) or a comma-separated list.",
    )
    cutoff: float = option(CUTOFF_HZ, "Smoothing cutoff in Hz (0: none).", minimum=0.0)
    report: bool = option(True, "Write the plausibility report, NAME.report.json, beside the clip.")
    markers_out: Path | None = option(
        None,
        "Also write the markers as placed on this performer (.json), for their next takes (--markers).",
        batch=False,
    )
    fov: float | None = option(
        None,
        "Camera's vertical field of view in degrees (image landmarks; default: estimated from the take).",
        minimum=1.0,
        maximum=170.0,
    )
    focal: float | None = option(
        None, "Camera's focal length in pixels (image landmarks; instead of fov).", minimum=1.0
    )


@dataclass(frozen=True)
class CaptureSolveOptions(SolveOptions):
    """A capture file's solve (see ``option`` for the fields' metadata)."""

    fps: float | None = option(None, "Frame rate, when the file has none.", minimum=1e-3)
    units: str | None = option(None, "Units, when the file has none.", choices=LENGTH_UNITS)
    robust: bool = option(True, "Reject spikes and unexplained markers.")
    sparsity: float | None = option(
        None,
        "L1 weight of the markers' solve, per unit of each channel's effect (default: the library's, 0.005).",
        minimum=0.0,
    )
    refine: int = option(0, "Gauss-Newton steps against the engine.", minimum=0, maximum=5)
    edits: Path | None = option(
        None, "An edited clip JSON of an earlier solve: its edit layers go over this solve.", batch=False
    )


@dataclass(frozen=True)
class CaptureVideoOptions(SolveOptions):
    """A face video's tracking and solve (see ``option`` for the fields' metadata)."""

    landmarks_out: Path | None = option(None, "Also write the tracked landmarks (.csv or .trc).", batch=False)
    max_frames: int | None = option(None, "Track only the first N frames.", minimum=1)


def report_files(main: Path, options: SolveOptions) -> tuple[Path, ...]:
    """The plausibility report beside the clip (NAME.report.json), unless ``report`` is off."""
    return (beside(main, ".report.json"),) if options.report else ()


def _checked(output: Path, options: SolveOptions) -> None:
    check_output(output, CAPTURE_OUTPUTS)
    SOLVE.check(options)
    if options.markers_out is not None:
        check_output(options.markers_out, (".json",), "marker file")


def _solve(trajectories, output: Path, options: SolveOptions, progress: Progress | None, **solve) -> Result:
    """Solve ``trajectories`` on ``options.rig`` and deliver the clip (see the module docstring)."""
    from mimetic.capture.expression import resolve_channels
    from mimetic.capture.markers import layout_for, save_marker_set
    from mimetic.capture.performance import solve_performance
    from mimetic.tasks.outputs import write_clip
    from mimetic.tasks.prepared import CAPTURE_BAKE, prepared_rig

    prepared = prepared_rig(options.rig)
    rig = prepared.rig
    unknown = [
        name.strip()
        for name in options.channels.split(",")
        if options.channels not in ("all", "determined") and name.strip() not in set(rig.channel_names)
    ]
    if unknown:
        raise TaskError(f"channels: the rig has no channel {', '.join(unknown[:5])}")
    engine = prepared.engine(options.engine, stage(progress, f"prepare {options.engine}"))
    basis = prepared.basis(options.engine, stage(progress, f"bake {options.engine}"), **CAPTURE_BAKE)
    announce(progress, "markers")
    placed = prepared.markers(options.markers or layout_for(trajectories.names))
    cutoff = options.cutoff or None
    active = resolve_channels(rig, basis, placed, options.channels, fps=trajectories.fps, cutoff_hz=cutoff)
    performance = solve_performance(
        rig,
        trajectories,
        basis=basis,
        markers=placed,
        neutral_frame=options.neutral_frame,
        active=active,
        cutoff_hz=cutoff,
        engine=engine,
        fov_deg=options.fov,
        focal=options.focal,
        progress=progress,
        **solve,
    )
    clip = performance.clip
    edits = getattr(options, "edits", None)
    if edits is not None:
        from mimetic.animate.clipfiles import load_clip
        from mimetic.capture.retarget import keep_edits

        clip = keep_edits(load_clip(edits), performance.clip)
    written = [
        write_clip(
            prepared,
            clip,
            output,
            engine=options.engine,
            size=options.size,
            fps=performance.clip.fps,
            progress=progress,
        )
    ]
    summary = performance.report(rig)
    for path in report_files(Path(output), options):
        from mimetic.atomic import atomic_write

        with atomic_write(path, "w") as handle:
            handle.write(json.dumps(summary, indent=2) + "\n")
        written.append(path)
    if options.markers_out is not None:
        note = f"placed on {trajectories.source}"
        written.append(save_marker_set(performance.markers, rig, options.markers_out, note=note))
    line = (
        f"{summary['frames']} frames at {summary['fps']:g} fps, {summary['channels_solved']} channels from "
        f"{summary['markers']} {summary['layout']} markers; marker RMS {summary['marker_rms_median']:.3g} "
        f"{rig.units or 'units'}, {summary['flagged_frames']} frames flagged"
    )
    return Result(tuple(Path(p) for p in written), line, float(summary["marker_rms_median"]), summary)


def solve(
    source: Path, output: Path, options: CaptureSolveOptions, progress: Progress | None = None
) -> Result:
    """Solve the capture file ``source`` (.c3d .trc, mimetic or OpenFace .csv) on ``options.rig`` into
    the rig's channel activations, head motion removed; ``output`` a clip file, video or scene. The
    residual is the median marker RMS in rig units."""
    from mimetic.capture.formats import read_trajectories

    _checked(output, options)
    announce(progress, "read")
    trajectories = read_trajectories(source, fps=options.fps, units=options.units)
    return _solve(
        trajectories,
        output,
        options,
        progress,
        robust=options.robust,
        refine=options.refine,
        **({} if options.sparsity is None else {"sparsity": options.sparsity}),
    )


def video(
    source: Path, output: Path, options: CaptureVideoOptions, progress: Progress | None = None
) -> Result:
    """Track the face video ``source`` with MediaPipe FaceMesh (the ``[track]`` extra) and solve it on
    ``options.rig`` through a perspective camera; the landmarks too when ``landmarks_out`` is given."""
    from dataclasses import replace

    from mimetic.capture.formats import write_trajectories
    from mimetic.capture.video import track_video

    _checked(output, options)
    if options.landmarks_out is not None:
        check_output(options.landmarks_out, (".csv", ".trc"), "landmark file")
    trajectories = track_video(source, max_frames=options.max_frames, progress=stage(progress, "track"))
    extra = ()
    if options.landmarks_out is not None:
        extra = (write_trajectories(trajectories, options.landmarks_out),)
    result = _solve(trajectories, output, replace(options, markers=options.markers or "mediapipe"), progress)
    return replace(result, outputs=(*result.outputs, *(Path(p) for p in extra)))


@dataclass(frozen=True)
class RetargetOptions(PlayOptions):
    """The rig a solved clip plays on (see ``option`` for the fields' metadata)."""

    rig: Path | None = option(None, "The .mrig rig to play the clip on.")


def retarget(
    source: Path, output: Path, options: RetargetOptions, progress: Progress | None = None
) -> Result:
    """Play the solved clip ``source`` on ``options.rig`` (channels matched by name, clipped to its
    ranges), delivered as ``output`` says."""
    from mimetic.animate.clipfiles import load_clip
    from mimetic.capture.retarget import retarget as play_on
    from mimetic.tasks.outputs import write_clip
    from mimetic.tasks.prepared import prepared_rig

    check_output(output, CLIPS)
    RETARGET.check(options)
    prepared = prepared_rig(options.rig)
    announce(progress, "retarget")
    played = play_on(load_clip(source).sample(options.fps), prepared.rig)
    write_clip(prepared, played, output, engine=options.engine, size=options.size, progress=progress)
    return Result((Path(output),), f"{played.n_frames} frames at {options.fps:g} fps")


RIG_REQUIRED = (("rig",),)
SOLVE = Task("capture solve", CaptureSolveOptions, solve, CAPTURE_OUTPUTS, report_files, "take", RIG_REQUIRED)
VIDEO = Task(
    "capture video", CaptureVideoOptions, video, CAPTURE_OUTPUTS, report_files, "video", RIG_REQUIRED
)
RETARGET = Task("capture retarget", RetargetOptions, retarget, CLIPS, source="clip", required=RIG_REQUIRED)
