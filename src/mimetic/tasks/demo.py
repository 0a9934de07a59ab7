"""``mimetic demo`` and ``make demo``: real outputs from the built-in head, in about two minutes.

Writes, into one folder (named steps report progress as they go):

* **heads**: the default head as ``head.glb``, its rig ``default.mrig``, eight random heads with
  their rigs (``heads/seed_N.glb``, ``rigs/seed_N.mrig``), the default head from three angles
  (``default_views.png``) and a contact sheet of all nine heads with their muscles drawn
  (``heads_muscles.png``);
* **sheets** (wire and vector engines): every muscle at full contraction (``muscles_wire.png``,
  ``muscles_vector.png``), the expression library (``expressions.png`` with the wire engine,
  ``expressions_vector.png``), the library on both engines side by side
  (``expressions_engines.png``), the close-ups of every expression's eyes and mouth corners
  (``expressions_closeup.png``, wire engine);
* **expressions**: each library expression as a posed mesh and a face render
  (``expressions/NAME.obj``, ``NAME.png``, wire engine);
* **animation**: an expression sequence as a keyframed clip (``animation.clip.json``), an animated
  GLB with one named morph target per muscle and the skeleton (``animation.glb``), the same clip
  rendered (``animation.mp4``), the ARKit-52 blendshapes baked from the muscle rig
  (``head_arkit.glb``);
* **talking head**: a sentence lip-synced with coarticulation, blinks and saccades
  (``talk.clip.json``), rendered with its sound (``talk.mp4``, spoken by espeak-ng into
  ``talk.wav`` when that program is installed; with ``all``, the same sound lip-synced from the
  audio alone, without its text: ``talk_audio_only.mp4``);
* **capture**: the default head plays the expression sequence while its head turns and nods
  (``capture.mp4``); MediaPipe tracks it and the landmarks are solved back into channels with the
  head's motion removed (``capture.clip.json``; ``capture_compare.png`` sets the performed and the
  captured joy, surprise and anger side by side) and played on the first random head
  (``capture_retargeted.mp4``, ``capture_retargeted.glb``).

With ``all`` (``mimetic demo --all``, ``make demo-all``) the physics engines, which take minutes
to prepare and pose, are shown too: their muscle and expression sheets (``muscles_fem.png``,
``expressions_tissue.png`` …), all four engines side by side, and a jaw drop simulated by the
tissue engine (``jaw_drop_tissue.mp4``: the lips and cheeks lag the jaw and settle); and the
animation as FBX beside its GLB (``animation.fbx``, through Blender, installed on first use; a
note says why when it cannot be). Real scanned heads (ICT-FaceKit, from the shared test data) are
rigged by ``examples/real_heads.py``, which ``make demo-all`` runs after this (with a dense one,
ICT subdivided, posed by the tissue engine through its proxy); the library itself knows no
particular head.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mimetic.animate.expressions import expression_pose, load_library
from mimetic.engines import ENGINES, Engine, make_engine
from mimetic.head.model import DEFAULT_RESOLUTION, make_head
from mimetic.head.params import HeadParams
from mimetic.mesh.io import save_mesh
from mimetic.render.renderer import Renderer
from mimetic.rig.activations import pose
from mimetic.rig.format import save_rig
from mimetic.rig.model import Rig
from mimetic.rig.recipe import build_rig
from mimetic.tasks.base import Progress, Result, Task, TaskOptions, check_folder, option, stage
from mimetic.tasks.rig import RESOLUTIONS
from mimetic.view.drawing import contact_sheet, save_png
from mimetic.view.muscles import render_rig
from mimetic.view.sheets import closeup_sheet, expression_sheet, muscle_sheet, pose_tiles, render_pose

FAST_ENGINES = ("wire", "vector")
"""Engines ready at once: the main demo's sheets. The others (fem, tissue) wait for ``all``."""


@dataclass(frozen=True)
class DemoOptions(TaskOptions):
    """What the demo makes (see ``option`` for the fields' metadata)."""

    resolution: int = option(
        DEFAULT_RESOLUTION, "Approximate skin vertex count.", minimum=RESOLUTIONS[0], maximum=RESOLUTIONS[1]
    )
    all: bool = option(
        False, "Also the physics engines' sheets (fem, tissue) and a simulated jaw drop: minutes more."
    )


def run(
    source: None, output: Path, options: DemoOptions = DemoOptions(), progress: Progress | None = None
) -> Result:
    """Generate the default head and eight random heads, rig, render, animate, lip-sync and capture them
    into the folder ``output`` (see the module docstring); ``progress(step, done, total)`` names each
    step. ``details["out_dir"]`` is the folder."""
    out = check_folder(Path(output), create=True)
    (out / "heads").mkdir(parents=True, exist_ok=True)
    (out / "rigs").mkdir(parents=True, exist_ok=True)
    renderer = Renderer()
    say = progress or (lambda step, done, total: None)
    rigs, files = _heads(out, SEEDS, options.resolution, SIZE, renderer, say)
    default_rig, other_rig = rigs[0], rigs[1]
    names = ENGINES if options.all else FAST_ENGINES
    engines = {}
    for name in names:
        engines[name] = make_engine(default_rig, name, progress=stage(progress, f"prepare {name}"))
    files += _action_sheets(default_rig, engines, out, renderer, say)
    files += _expressions(default_rig, engines["wire"], out / "expressions", SIZE, renderer, say)
    animated, notes = _animation(
        default_rig, other_rig, engines["wire"], out, renderer, say, extras=options.all
    )
    files += animated
    summary = (
        f"{len(files)} files: {len(rigs)} heads rigged, {len(engines)} engines, animation, speech, capture"
    )
    return Result(tuple(files), summary, details={"out_dir": str(out)}, notes=tuple(notes))


SEEDS = tuple(range(1, 9))
"""The random heads' seeds."""
SIZE = 384
"""Tile size of the sheets, pixels."""


def _heads(
    out: Path, seeds: tuple[int, ...], resolution: int, size: int, renderer: Renderer, say: Progress
) -> tuple[list[Rig], list[Path]]:
    """The default head and the random ones made, rigged and saved; their views and muscle sheet."""
    files: list[Path] = []
    tiles = []
    rigs = []
    jobs: list[int | None] = [None, *seeds]
    for k, seed in enumerate(jobs):
        say("heads", k, len(jobs))
        params = HeadParams() if seed is None else HeadParams.random(seed)
        head = make_head(params, resolution)
        rig = build_rig(head)
        rigs.append(rig)
        if seed is None:
            files.append(save_mesh(head.mesh, out / "head.glb"))
            files.append(save_rig(rig, out / "default.mrig"))
            views = [
                (view, render_rig(rig, view, size=size, muscles=False, renderer=renderer))
                for view in ("front", "three_quarter", "profile")
            ]
            files.append(save_png(contact_sheet(views, columns=3), out / "default_views.png"))
            label = "default"
        else:
            files.append(save_mesh(head.mesh, out / "heads" / f"seed_{seed}.glb"))
            files.append(save_rig(rig, out / "rigs" / f"seed_{seed}.mrig"))
            label = f"seed {seed}"
        tiles.append((f"{label}: front", render_rig(rig, "front", size=size, renderer=renderer)))
        tiles.append(
            (f"{label}: three-quarter", render_rig(rig, "three_quarter", size=size, renderer=renderer))
        )
    say("heads", len(jobs), len(jobs))
    files.append(save_png(contact_sheet(tiles, columns=6), out / "heads_muscles.png"))
    return rigs, files


ANIMATION = ((0.0, "rest"), (1.0, "joy"), (2.0, "surprise"), (3.0, "anger"), (4.0, "sadness"), (5.0, "rest"))
ANIMATION_FPS = 30
VIDEO_SIZE = 512
"""The demo's videos, pixels square."""
TALK = (
    "Hello! I am a mimetic head. My muscles move my face when I speak, so the lips meet at every b, p and m."
)


def _animation(
    rig: Rig, other: Rig, engine: Engine, out: Path, renderer: Renderer, say: Progress, *, extras: bool
) -> tuple[list[Path], list[str]]:
    """An expression sequence as a clip, an animated GLB, an MP4; the ARKit-52 GLB; a talking head; the
    sequence captured from ``rig`` and played on ``other``. With ``extras`` also the animation as FBX
    and a talking head from its sound alone."""
    from mimetic.animate.clipfiles import save_clip
    from mimetic.animate.keyframes import from_expressions
    from mimetic.engines.bake import bake
    from mimetic.export.arkit import arkit_shapes
    from mimetic.export.gltf import export_glb, morph_targets_from_basis
    from mimetic.view.video import render_clip

    keys = from_expressions(rig, list(ANIMATION))
    clip = keys.sample(ANIMATION_FPS, channels=rig)
    basis = bake(engine, progress=stage(say, "bake wire")).basis
    files = [save_clip(keys, out / "animation.clip.json")]
    say("animated GLB", 0, 1)
    targets = morph_targets_from_basis(basis, rig)
    files.append(export_glb(rig, out / "animation.glb", morph_targets=targets, clip=clip))
    fbx_notes = []
    if extras:
        from mimetic.blender import BlenderError
        from mimetic.export.fbx import export_fbx

        say("animated FBX", 0, 1)
        try:
            files.append(
                export_fbx(rig, out / "animation.fbx", morph_targets=targets, clip=clip, progress=say)
            )
        except BlenderError as error:
            fbx_notes.append(f"animation.fbx skipped: {error}")
    video = out / "animation.mp4"
    files.append(
        render_clip(
            rig,
            clip,
            video,
            basis=basis,
            size=VIDEO_SIZE,
            renderer=renderer,
            progress=stage(say, "animation video"),
        )
    )
    say("ARKit-52 shapes", 0, 1)
    files.append(export_glb(rig, out / "head_arkit.glb", morph_targets=arkit_shapes(engine)))
    talk, notes = _talk(rig, basis, out, renderer, say, extras)
    captured = _capture(rig, other, basis, clip, out, renderer, say)
    return files + talk + captured, fbx_notes + notes


CAPTURE_TURN_DEG = (15.0, 8.0, 4.0)
"""The demo performer's head: yaw, pitch and roll swing through these (degrees) while they act."""
CAPTURE_READBACK = (("joy", "zygomatic_major_L"), ("surprise", "jaw_open"), ("anger", "corrugator_L"))
"""The expressions ``capture_compare.png`` shows, each at the frame where this channel peaks."""


def _capture(rig: Rig, other: Rig, basis, clip, out: Path, renderer: Renderer, say: Progress) -> list[Path]:
    """A performance captured from video: ``rig`` plays ``clip`` while its head turns and nods
    (``capture.mp4``); MediaPipe tracks the video and the landmarks are solved back into channels with
    the head's motion removed (``capture.clip.json``), shown beside the truth (``capture_compare.png``)
    and played on ``other`` (``capture_retargeted.mp4`` and ``.glb``). Without the ``[track]`` extra
    nothing is written."""
    from mimetic.animate.clipfiles import save_clip
    from mimetic.animate.keyframes import from_clip
    from mimetic.capture import retarget, solve_performance
    from mimetic.capture.video import track_video
    from mimetic.engines.bake import bake
    from mimetic.errors import MissingExtraError
    from mimetic.export.gltf import export_glb, morph_targets_from_basis
    from mimetic.rig.activations import Clip
    from mimetic.view.video import render_clip

    t = np.arange(clip.n_frames) / clip.fps
    values = clip.values.copy()
    for name, degrees, hz in zip(
        ("head_yaw", "head_pitch", "head_roll"), CAPTURE_TURN_DEG, (0.3, 0.45, 0.2), strict=True
    ):
        values[:, rig.channel_index(name)] = (
            np.radians(degrees) * np.sin(2 * np.pi * hz * t) * np.clip(t - 0.3, 0, 1)
        )
    performed = Clip(clip.channels, values, clip.fps)
    video = render_clip(
        rig, performed, out / "capture.mp4", basis=basis, size=VIDEO_SIZE, renderer=renderer,
        progress=stage(say, "capture: the performance video"),
    )  # fmt: skip
    try:
        tracked = track_video(video, progress=stage(say, "capture: tracking (MediaPipe)"))
    except MissingExtraError:
        return [video]
    performance = solve_performance(
        rig, tracked, basis=basis, progress=lambda step, done, total: say(f"capture: {step}", done, total)
    )
    files = [video, save_clip(from_clip(performance.clip), out / "capture.clip.json")]
    files.append(_compare(rig, basis, performed, performance.clip, out / "capture_compare.png", renderer))
    played = retarget(performance.clip, other)
    other_basis = bake(make_engine(other, "wire"), progress=stage(say, "capture: bake the other head")).basis
    retargeted = out / "capture_retargeted.mp4"
    progress = stage(say, "capture: retargeted video")
    files.append(
        render_clip(
            other,
            played,
            retargeted,
            basis=other_basis,
            size=VIDEO_SIZE,
            renderer=renderer,
            progress=progress,
        )
    )
    targets = morph_targets_from_basis(other_basis, other)
    files.append(export_glb(other, out / "capture_retargeted.glb", morph_targets=targets, clip=played))
    return files


def _compare(rig: Rig, basis, truth, solved, path: Path, renderer: Renderer) -> Path:
    """The performed face (top row) above the captured one (bottom), head motion removed, where each of
    ``CAPTURE_READBACK``'s channels peaks."""
    from mimetic.engines.basis import evaluate_basis
    from mimetic.view.drawing import contact_sheet, save_png
    from mimetic.view.look import rig_look
    from mimetic.view.sheets import face_camera

    camera, look = face_camera(rig), rig_look(rig)
    frames = [int(np.argmax(truth.select([channel]).values[:, 0])) for _, channel in CAPTURE_READBACK]
    tiles = []
    for label, clip in (("performed", truth), ("captured", solved)):
        for (name, _), frame in zip(CAPTURE_READBACK, frames, strict=True):
            pose = clip.select(basis.channels).values[frame]  # no head_*: a basis has no rigid turn
            vertices = evaluate_basis(basis, pose)
            image = renderer.render(rig.mesh.with_vertices(vertices), camera, size=(256, 256), look=look)
            tiles.append((f"{name}, {label}", image))
    return save_png(contact_sheet(tiles, columns=len(CAPTURE_READBACK)), path)


def _talk(
    rig: Rig, basis, out: Path, renderer: Renderer, say: Progress, audio_only: bool
) -> tuple[list[Path], list[str]]:
    """``TALK`` lip-synced (``talk.clip.json``) and rendered with its sound (``talk.mp4``): spoken by
    the espeak-ng program and aligned to it (``talk.wav``) when both it and the ``[speech]`` extra are
    here, else timed from the text alone and silent. With ``audio_only`` and the sound, the same
    sound lip-synced without its text (recognised: ``talk_audio_only.mp4``)."""
    import shutil

    from mimetic.animate.clipfiles import save_clip
    from mimetic.animate.keyframes import from_clip
    from mimetic.errors import MissingExtraError
    from mimetic.speech.lipsync import lip_sync
    from mimetic.view.video import render_clip

    notes = []
    speech = None
    say("talking head: speech", 0, 1)
    if shutil.which("espeak-ng") is None:
        notes.append("talk.mp4 is silent and timed from the text: install espeak-ng to hear it speak")
    else:
        try:
            speech = lip_sync(rig, text=TALK, synthesize_to=out / "talk.wav", eyes=True)
        except MissingExtraError as error:
            notes.append(f"talk.mp4 is timed from the text: {error}")
    speech = speech or lip_sync(rig, text=TALK, eyes=True)
    files = [] if speech.audio is None else [speech.audio]
    files.append(save_clip(from_clip(speech.clip), out / "talk.clip.json"))
    files.append(
        render_clip(
            rig,
            speech.clip,
            out / "talk.mp4",
            basis=basis,
            size=VIDEO_SIZE,
            audio=speech.audio,
            renderer=renderer,
            progress=stage(say, "talking head: video"),
        )
    )
    if audio_only and speech.audio is not None:
        say("talking head from its sound alone", 0, 1)
        heard = lip_sync(rig, audio=speech.audio, eyes=True)
        video = out / "talk_audio_only.mp4"
        files.append(
            render_clip(
                rig,
                heard.clip,
                video,
                basis=basis,
                size=VIDEO_SIZE,
                audio=heard.audio,
                renderer=renderer,
                progress=stage(say, "talking head from sound: video"),
            )
        )
    return files, notes


def _action_sheets(
    rig: Rig,
    engines: dict[str, Engine],
    out: Path,
    renderer: Renderer,
    say: Progress,
    tile: int = 256,
) -> list[Path]:
    """The muscle sheet and the expression sheet of each engine (the wire one is ``expressions.png``),
    and the wire engine's close-ups of the expressions' eyes and mouth corners."""
    files = []
    for name, engine in engines.items():
        sheet = muscle_sheet(
            rig, engine, size=tile, renderer=renderer, progress=stage(say, f"muscle sheet ({name})")
        )
        files.append(save_png(sheet, out / f"muscles_{name}.png"))
    library = load_library()
    for name, engine in engines.items():
        sheet = expression_sheet(
            rig,
            engine,
            library,
            size=tile,
            renderer=renderer,
            progress=stage(say, f"expression sheet ({name})"),
        )
        files.append(
            save_png(sheet, out / ("expressions.png" if name == "wire" else f"expressions_{name}.png"))
        )
    say("engines side by side", 0, 1)
    poses = [("rest", pose(rig), None)]
    poses += [(n, expression_pose(rig, library[n]), None) for n in library.names]
    columns = [
        pose_tiles(rig, engine, poses, views=("front",), size=tile, renderer=renderer)
        for engine in engines.values()
    ]
    tiles = [
        (f"{column[k][0]} ({name})", column[k][1])
        for k in range(len(poses))
        for name, column in zip(engines, columns, strict=True)
    ]
    files.append(save_png(contact_sheet(tiles, columns=len(engines)), out / "expressions_engines.png"))
    say("close-ups", 0, 1)
    sheet = closeup_sheet(rig, engines["wire"], library, size=tile, renderer=renderer)
    files.append(save_png(sheet, out / "expressions_closeup.png"))
    if "tissue" in engines:
        path = out / "jaw_drop_tissue.mp4"
        files.append(_jaw_drop(rig, engines["tissue"], path, renderer, stage(say, "jaw drop (tissue)")))
    return files


JAW_DROP = ((0.0, 0.0), (0.3, 0.0), (0.45, 1.0), (1.2, 1.0), (1.35, 0.0), (2.0, 0.0))
"""(time s, jaw_open as a fraction of its maximum) of the dynamic jaw drop: a fast drop, a hold, a
snap shut."""


def _jaw_drop(rig: Rig, engine: Engine, path: Path, renderer: Renderer, progress) -> Path:
    """A jaw drop simulated by the tissue engine (``simulate``: the lips and cheeks lag the jaw and
    settle), three-quarter view, 30 fps."""
    from mimetic.rig.activations import Clip
    from mimetic.view.video import render_clip

    times = np.arange(0.0, JAW_DROP[-1][0], 1.0 / ANIMATION_FPS)
    opening = np.interp(times, *zip(*JAW_DROP, strict=True)) * rig.channel("jaw_open").maximum
    values = np.zeros((len(times), len(rig.channels)))
    values[:, rig.channel_index("jaw_open")] = opening
    clip = Clip(rig.channel_names, values, ANIMATION_FPS)
    return render_clip(
        rig, clip, path, engine=engine, size=384, yaw_deg=35.0, renderer=renderer, progress=progress
    )


def _expressions(
    rig: Rig, engine: Engine, folder: Path, size: int, renderer: Renderer, say: Progress
) -> list[Path]:
    """Each library expression posed by ``engine``: ``NAME.obj`` (all parts) and a front ``NAME.png``."""
    folder.mkdir(parents=True, exist_ok=True)
    files = []
    names = load_library().names
    for k, name in enumerate(names):
        say("expressions", k, len(names))
        values = expression_pose(rig, name)
        files.append(save_mesh(rig.mesh.with_vertices(engine.deform(values)), folder / f"{name}.obj"))
        image = render_pose(rig, engine, values, view="front", size=size, renderer=renderer)
        files.append(save_png(image, folder / f"{name}.png"))
    say("expressions", len(names), len(names))
    return files


TASK = Task("demo", DemoOptions, run, ())
