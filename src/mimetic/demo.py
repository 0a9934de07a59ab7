"""The demo job behind ``mimetic demo`` and ``make demo``: real outputs from the built-in head.

Writes, into one folder: the default head as ``head.glb``, its rig ``default.mrig``, eight
random heads with their rigs (``heads/seed_N.glb``, ``rigs/seed_N.mrig``), the default head from
three angles (``default_views.png``) and a contact sheet of all nine heads with their muscles
drawn (``heads_muscles.png``). For the default head it also writes the muscle sheet of every
engine (``muscles_wire.png``, ``muscles_vector.png``, ``muscles_fem.png`` …: every muscle at full
contraction), its expression sheet (``expressions.png`` with the wire engine,
``expressions_vector.png``, ``expressions_fem.png`` …), the library on every engine side by side
(``expressions_engines.png``), a jaw drop simulated by the tissue engine (``jaw_drop_tissue.mp4``:
the lips and cheeks lag the jaw and settle), the close-ups
of every expression's eyes and mouth corners (``expressions_closeup.png``, wire engine) and each
library expression as a posed mesh and a face render (``expressions/NAME.obj``, ``NAME.png``,
wire engine).

It also animates the default head: an expression sequence as a keyframed clip
(``animation.clip.json``), an animated GLB with one named morph target per muscle and the
skeleton (``animation.glb``), the same clip rendered to ``animation.mp4``, the ARKit-52
blendshapes baked from the muscle rig as a GLB (``head_arkit.glb``), and a talking head: a sentence
lip-synced with coarticulation, blinks and saccades (``talk.clip.json``), rendered with its sound
(``talk.mp4``, spoken by espeak-ng into ``talk.wav`` when that program is installed). Finally a
performance capture from video: the default head plays the expression sequence while its head
turns and nods (``capture.mp4``); MediaPipe tracks it and the landmarks are solved back into
channels with the head's motion removed (``capture.clip.json``; ``capture_compare.png`` sets the
performed and the captured joy, surprise and anger side by side) and played on the first random head
(``capture_retargeted.mp4``, ``capture_retargeted.glb``).

Real scanned heads (ICT-FaceKit, from the shared test data) are rigged by ``examples/real_heads.py``,
which ``make demo`` runs after this job; the library itself knows no particular head.
"""

from __future__ import annotations

from collections.abc import Callable
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
from mimetic.view.muscles import render_rig
from mimetic.view.sheet import contact_sheet, save_png
from mimetic.view.sheets import closeup_sheet, expression_sheet, muscle_sheet, pose_tiles, render_pose

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class DemoResult:
    out_dir: Path
    files: tuple[Path, ...]
    notes: tuple[str, ...] = ()


def run_demo(
    out_dir: str | Path = "mimetic-demo",
    *,
    seeds: tuple[int, ...] = tuple(range(1, 9)),
    resolution: int = DEFAULT_RESOLUTION,
    size: int = 384,
    progress: Progress | None = None,
) -> DemoResult:
    """Generate the default head and ``seeds`` random heads, rig and render them into ``out_dir``.

    ``progress(done, total)`` is called after each head, each sheet, each expression and each
    animation output (about 35 steps of similar length).
    """
    out = Path(out_dir)
    (out / "heads").mkdir(parents=True, exist_ok=True)
    (out / "rigs").mkdir(parents=True, exist_ok=True)
    renderer = Renderer()
    files: list[Path] = []
    tiles = []
    jobs: list[int | None] = [None, *seeds]
    sheets = 2 * len(ENGINES) + 3  # each engine's muscle and expression sheets, side by side, close-ups, MP4
    total = len(jobs) + sheets + len(load_library().names) + len(ANIMATION_STEPS)
    steps = iter(range(1, total + 1))

    def tick() -> None:
        if progress:
            progress(next(steps), total)

    default_rig: Rig | None = None
    other_rig: Rig | None = None
    for seed in jobs:
        params = HeadParams() if seed is None else HeadParams.random(seed)
        head = make_head(params, resolution)
        rig = build_rig(head)
        if seed is None:
            default_rig = rig
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
            other_rig = other_rig or rig
        tiles.append((f"{label}: front", render_rig(rig, "front", size=size, renderer=renderer)))
        tiles.append(
            (f"{label}: three-quarter", render_rig(rig, "three_quarter", size=size, renderer=renderer))
        )
        tick()
    files.append(save_png(contact_sheet(tiles, columns=6), out / "heads_muscles.png"))
    assert default_rig is not None  # jobs start with the default head
    engines = {name: make_engine(default_rig, name) for name in ENGINES}
    files += _action_sheets(default_rig, engines, out, renderer, tick)
    files += _expressions(default_rig, engines["wire"], out / "expressions", size, renderer, tick)
    animated, notes = _animation(default_rig, other_rig or default_rig, engines["wire"], out, renderer, tick)
    return DemoResult(out, tuple(files + animated), tuple(notes))


ANIMATION = ((0.0, "rest"), (1.0, "joy"), (2.0, "surprise"), (3.0, "anger"), (4.0, "sadness"), (5.0, "rest"))
ANIMATION_FPS = 30
ANIMATION_STEPS = ("bake", "clip and GLB", "MP4", "ARKit-52 GLB", "talking head", "capture")
TALK = (
    "Hello! I am a mimetic head. My muscles move my face when I speak, so the lips meet at every b, p and m."
)


def _animation(
    rig: Rig, other: Rig, engine: Engine, out: Path, renderer: Renderer, tick: Callable[[], None]
) -> tuple[list[Path], list[str]]:
    """An expression sequence as a clip, an animated GLB, an MP4; the ARKit-52 GLB; a talking head; the
    sequence captured from ``rig`` and played on ``other``."""
    from mimetic.animate.clip import from_expressions, save_clip
    from mimetic.engines.bake import bake
    from mimetic.export.arkit import arkit_shapes
    from mimetic.export.gltf import export_glb, morph_targets_from_basis
    from mimetic.view.video import render_clip

    keys = from_expressions(rig, list(ANIMATION))
    clip = keys.sample(ANIMATION_FPS, channels=rig)
    basis = bake(engine).basis
    tick()
    files = [save_clip(keys, out / "animation.clip.json")]
    targets = morph_targets_from_basis(basis, rig)
    files.append(export_glb(rig, out / "animation.glb", morph_targets=targets, clip=clip))
    tick()
    files.append(render_clip(rig, clip, out / "animation.mp4", basis=basis, size=512, renderer=renderer))
    tick()
    files.append(export_glb(rig, out / "head_arkit.glb", morph_targets=arkit_shapes(engine)))
    tick()
    talk, notes = _talk(rig, basis, out, renderer)
    tick()
    captured = _capture(rig, other, basis, clip, out, renderer)
    tick()
    return files + talk + captured, notes


CAPTURE_TURN_DEG = (15.0, 8.0, 4.0)
"""The demo performer's head: yaw, pitch and roll swing through these (degrees) while they act."""
CAPTURE_READBACK = (("joy", "zygomatic_major_L"), ("surprise", "jaw_open"), ("anger", "corrugator_L"))
"""The expressions ``capture_compare.png`` shows, each at the frame where this channel peaks."""


def _capture(rig: Rig, other: Rig, basis, clip, out: Path, renderer: Renderer) -> list[Path]:
    """A performance captured from video: ``rig`` plays ``clip`` while its head turns and nods
    (``capture.mp4``); MediaPipe tracks the video and the landmarks are solved back into channels with
    the head's motion removed (``capture.clip.json``), shown beside the truth (``capture_compare.png``)
    and played on ``other`` (``capture_retargeted.mp4`` and ``.glb``). Without the ``[track]`` extra
    nothing is written."""
    from mimetic.animate.clip import from_clip, save_clip
    from mimetic.capture import retarget, solve_performance
    from mimetic.capture.video import track_video
    from mimetic.errors import MissingExtraError
    from mimetic.export.gltf import export_glb, morph_targets
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
    video = render_clip(rig, performed, out / "capture.mp4", basis=basis, size=512, renderer=renderer)
    try:
        tracked = track_video(video)
    except MissingExtraError:
        return [video]
    performance = solve_performance(rig, tracked, basis=basis)
    files = [video, save_clip(from_clip(performance.clip), out / "capture.clip.json")]
    files.append(_compare(rig, basis, performed, performance.clip, out / "capture_compare.png", renderer))
    played = retarget(performance.clip, other)
    files.append(render_clip(other, played, out / "capture_retargeted.mp4", size=512, renderer=renderer))
    files.append(
        export_glb(other, out / "capture_retargeted.glb", morph_targets=morph_targets(other), clip=played)
    )
    return files


def _compare(rig: Rig, basis, truth, solved, path: Path, renderer: Renderer) -> Path:
    """The performed face (top row) above the captured one (bottom), head motion removed, where each of
    ``CAPTURE_READBACK``'s channels peaks."""
    from mimetic.engines.basis import evaluate_basis
    from mimetic.view.look import rig_look
    from mimetic.view.sheet import contact_sheet, save_png
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


def _talk(rig: Rig, basis, out: Path, renderer: Renderer) -> tuple[list[Path], list[str]]:
    """``TALK`` lip-synced (``talk.clip.json``) and rendered with its sound (``talk.mp4``): spoken by
    the espeak-ng program and aligned to it (``talk.wav``) when both it and the ``[speech]`` extra are
    here, else timed from the text alone and silent."""
    import shutil

    from mimetic.animate.clip import from_clip, save_clip
    from mimetic.errors import MissingExtraError
    from mimetic.speech.lipsync import lip_sync
    from mimetic.view.video import render_clip

    notes = []
    speech = None
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
            rig, speech.clip, out / "talk.mp4", basis=basis, size=512, audio=speech.audio, renderer=renderer
        )
    )
    return files, notes


def _action_sheets(
    rig: Rig,
    engines: dict[str, Engine],
    out: Path,
    renderer: Renderer,
    tick: Callable[[], None],
    tile: int = 256,
) -> list[Path]:
    """The muscle sheet and the expression sheet of each engine (the wire one is ``expressions.png``),
    and the wire engine's close-ups of the expressions' eyes and mouth corners."""
    files = []
    for name, engine in engines.items():
        sheet = muscle_sheet(rig, engine, size=tile, renderer=renderer)
        files.append(save_png(sheet, out / f"muscles_{name}.png"))
        tick()
    library = load_library()
    for name, engine in engines.items():
        sheet = expression_sheet(rig, engine, library, size=tile, renderer=renderer)
        files.append(
            save_png(sheet, out / ("expressions.png" if name == "wire" else f"expressions_{name}.png"))
        )
        tick()
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
    tick()
    sheet = closeup_sheet(rig, engines["wire"], library, size=tile, renderer=renderer)
    files.append(save_png(sheet, out / "expressions_closeup.png"))
    tick()
    if "tissue" in engines:
        files.append(_jaw_drop(rig, engines["tissue"], out / "jaw_drop_tissue.mp4", renderer))
        tick()
    return files


JAW_DROP = ((0.0, 0.0), (0.3, 0.0), (0.45, 1.0), (1.2, 1.0), (1.35, 0.0), (2.0, 0.0))
"""(time s, jaw_open as a fraction of its maximum) of the dynamic jaw drop: a fast drop, a hold, a
snap shut."""


def _jaw_drop(rig: Rig, engine: Engine, path: Path, renderer: Renderer) -> Path:
    """A jaw drop simulated by the tissue engine (``simulate``: the lips and cheeks lag the jaw and
    settle), three-quarter view, 30 fps."""
    from mimetic.rig.activations import Clip
    from mimetic.view.video import render_clip

    times = np.arange(0.0, JAW_DROP[-1][0], 1.0 / ANIMATION_FPS)
    opening = np.interp(times, *zip(*JAW_DROP, strict=True)) * rig.channel("jaw_open").maximum
    values = np.zeros((len(times), len(rig.channels)))
    values[:, rig.channel_index("jaw_open")] = opening
    clip = Clip(rig.channel_names, values, ANIMATION_FPS)
    return render_clip(rig, clip, path, engine=engine, size=384, yaw_deg=35.0, renderer=renderer)


def _expressions(
    rig: Rig, engine: Engine, folder: Path, size: int, renderer: Renderer, tick: Callable[[], None]
) -> list[Path]:
    """Each library expression posed by ``engine``: ``NAME.obj`` (all parts) and a front ``NAME.png``."""
    folder.mkdir(parents=True, exist_ok=True)
    files = []
    for name in load_library().names:
        values = expression_pose(rig, name)
        files.append(save_mesh(rig.mesh.with_vertices(engine.deform(values)), folder / f"{name}.obj"))
        image = render_pose(rig, engine, values, view="front", size=size, renderer=renderer)
        files.append(save_png(image, folder / f"{name}.png"))
        tick()
    return files
