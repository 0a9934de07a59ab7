"""The ``mimetic`` command (typer + rich): thin wrappers over the library.

Results go to stdout; progress and errors go to stderr. Exit codes: 0 success, 1 a problem
with the input (shown as one line, ``--debug`` for the traceback), 2 a usage error.
"""

from __future__ import annotations

import json
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import typer
from rich.console import Console
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from mimetic.errors import MimeticError

app = typer.Typer(
    help="mimetic: turn any 3D head mesh into a muscle-driven, animatable face.",
    no_args_is_help=True,
    pretty_exceptions_show_locals=False,
    add_completion=False,
)
stdout = Console()
stderr = Console(stderr=True)
_state = {"debug": False}


@app.callback()
def main(debug: bool = typer.Option(False, "--debug", help="Show tracebacks for input errors.")) -> None:
    _state["debug"] = debug


@contextmanager
def _user_errors() -> Iterator[None]:
    """Turn a MimeticError into one red line on stderr and exit code 1."""
    try:
        yield
    except MimeticError as error:
        if _state["debug"]:
            raise
        stderr.print(f"[red]error:[/] {error}", highlight=False, soft_wrap=True)
        raise typer.Exit(1) from None


@contextmanager
def _progress(label: str) -> Iterator[Callable[[int, int], None]]:
    with Progress(
        TextColumn(label),
        BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(),
        console=stderr,
        transient=True,
    ) as bar:
        task = bar.add_task(label, total=None)

        def update(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        yield update


def _name_values(
    items: list[str], option: str, form: str, example: str, error: type[MimeticError]
) -> dict[str, float]:
    """Repeated ``NAME=VALUE`` options -> {name: value}; a malformed item raises ``error``."""
    values = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            values[name.strip()] = float(value)
        except ValueError:
            sep = ""
        if not sep or not name.strip():
            raise error(f"{option} {item!r}: expected {form}, e.g. {option} {example}")
    return values


def _parse_params(items: list[str]) -> dict[str, float]:
    from mimetic.head.params import HeadParamError

    return _name_values(items, "--param", "NAME=VALUE", "nose_length=1.1", HeadParamError)


@app.command()
def head(
    out: Path = typer.Option(..., "-o", "--out", help="Mesh file to write (.glb, .gltf, .obj, .ply, .stl)."),
    seed: int | None = typer.Option(None, "--seed", help="Random conformation from this seed."),
    param: list[str] = typer.Option(
        [], "--param", help="Set a conformation parameter, NAME=VALUE (repeatable)."
    ),
    resolution: int = typer.Option(
        10_000, "--resolution", help="Approximate skin vertex count (1,500..250,000)."
    ),
    rig: Path | None = typer.Option(None, "--rig", help="Also write the head's rig to this .mrig file."),
) -> None:
    """Generate a parametric reference head and write it as a mesh (and optionally its rig)."""
    from mimetic.head.model import make_head
    from mimetic.head.params import HeadParams
    from mimetic.mesh.io import save_mesh

    with _user_errors():
        if not 1_500 <= resolution <= 250_000:
            raise MimeticError(f"--resolution {resolution} is outside 1,500..250,000 skin vertices")
        params = HeadParams() if seed is None else HeadParams.random(seed)
        params = params.with_values(**_parse_params(param))
        generated = make_head(params, resolution)
        written = [save_mesh(generated.mesh, out)]
        if rig is not None:
            from mimetic.rig.format import save_rig
            from mimetic.rig.recipe import build_rig

            written.append(save_rig(build_rig(generated), rig))
    for path in written:
        stdout.print(f"wrote {path}", highlight=False)


@app.command()
def info(
    file: Path = typer.Argument(..., help="A mesh (.obj .ply .stl .glb .gltf) or a rig (.mrig)."),
    units: str | None = typer.Option(None, "--units", help="Override the units: mm, cm, dm or m."),
    as_json: bool = typer.Option(False, "--json", help="Print the report as JSON."),
) -> None:
    """Validate a mesh or rig and report its units, parts and landmarks."""
    with _user_errors():
        if file.suffix.lower() == ".mrig":
            report = _rig_report(file)
            ok = True
        else:
            report, ok = _mesh_report(file, units)
    if as_json:
        stdout.print_json(json.dumps(report))
    else:
        _print_report(report)
    if not ok:
        raise typer.Exit(1)


def _mesh_report(file: Path, units: str | None) -> tuple[dict, bool]:
    from mimetic.mesh.io import load_mesh
    from mimetic.mesh.validate import validate_mesh

    mesh = load_mesh(file, units=units, check=False)
    report = validate_mesh(mesh)
    data = {
        "file": str(file),
        "kind": "mesh",
        **report.as_dict(),
        "parts": list(mesh.parts),
        "landmarks": "none (a plain mesh; `mimetic rig` will find them)",
        "lines": report.lines(),
    }
    return data, report.ok


def _rig_report(file: Path) -> dict:
    from mimetic.mesh.validate import validate_mesh
    from mimetic.rig.format import load_rig

    rig = load_rig(file)
    report = validate_mesh(rig.mesh)
    kinds: dict[str, int] = {}
    for m in rig.muscles:
        kinds[m.kind] = kinds.get(m.kind, 0) + 1
    lines = [
        *report.lines(),
        f"scale             {rig.scale:.4g} {rig.units} (head height)",
        f"muscles           {len(rig.muscles)} ({', '.join(f'{n} {k}' for k, n in kinds.items())})",
        f"wires             {len(rig.wires)}",
        f"bones             {', '.join(rig.bone_names)}",
        f"channels          {len(rig.channels)}",
    ]
    return {
        "file": str(file),
        "kind": "rig",
        **report.as_dict(),
        "units": rig.units,
        "parts": list(rig.mesh.parts),
        "landmarks": sorted(rig.landmarks),
        "regions": sorted(rig.regions),
        "muscles": [m.name for m in rig.muscles],
        "channels": list(rig.channel_names),
        "lines": lines,
    }


def _print_report(report: dict) -> None:
    stdout.print(f"[bold]{report['file']}[/] ({report['kind']})", highlight=False)
    for line in report["lines"]:
        stdout.print(f"  {line}", highlight=False, soft_wrap=True)
    landmarks = report["landmarks"]
    text = landmarks if isinstance(landmarks, str) else f"{len(landmarks)}: {', '.join(landmarks)}"
    stdout.print(f"  landmarks         {text}", highlight=False, soft_wrap=True)


@app.command()
def render(
    file: Path = typer.Argument(..., help="A mesh or a .mrig rig."),
    out: Path = typer.Option(..., "-o", "--out", help="PNG file to write."),
    view: str = typer.Option(
        "all", "--view", help="front, three_quarter, profile, or all (a labelled sheet)."
    ),
    size: int = typer.Option(512, "--size", help="Image size in pixels (per view)."),
    wireframe: bool = typer.Option(False, "--wireframe", help="Draw the triangle edges."),
    muscles: bool = typer.Option(True, "--muscles/--no-muscles", help="Draw a rig's muscles."),
    units: str | None = typer.Option(None, "--units", help="Override a mesh's units: mm, cm, dm or m."),
) -> None:
    """Render a mesh or rig to a PNG, from one angle or three."""
    from mimetic.view import VIEWS, contact_sheet, save_png
    from mimetic.view import render as render_mesh

    with _user_errors():
        views = list(VIEWS) if view == "all" else [view]
        unknown = [v for v in views if v not in VIEWS]
        if unknown:
            raise MimeticError(f"--view {view!r} is not one of: all, {', '.join(VIEWS)}")
        if not 64 <= size <= 4096:
            raise MimeticError(f"--size {size} is outside 64..4096 pixels")
        if file.suffix.lower() == ".mrig":
            from mimetic.rig.format import load_rig
            from mimetic.view.muscles import render_rig

            rig = load_rig(file)
            tiles = [(v, render_rig(rig, v, size=size, muscles=muscles, wireframe=wireframe)) for v in views]
        else:
            from mimetic.mesh.io import load_mesh

            mesh = load_mesh(file, units=units)
            tiles = [(v, render_mesh(mesh, v, size=size, wireframe=wireframe)) for v in views]
        image = tiles[0][1] if len(tiles) == 1 else contact_sheet(tiles, columns=len(tiles))
        save_png(image, out)
    stdout.print(f"wrote {out}", highlight=False)


@contextmanager
def _step_progress() -> Iterator[Callable[[str, int, int], None]]:
    """A progress callback ``(step, done, total)`` showing one bar per named step."""
    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TextColumn("{task.completed}/{task.total}"),
        TimeElapsedColumn(),
        console=stderr,
        transient=True,
    ) as bar:
        tasks: dict[str, int] = {}

        def update(step: str, done: int, total: int) -> None:
            if step not in tasks:
                tasks[step] = bar.add_task(step, total=total)
            bar.update(tasks[step], completed=done, total=total)

        yield update


@app.command("rig")
def rig_command(
    mesh_file: Path = typer.Argument(..., help="The head mesh to rig (.obj .ply .stl .glb .gltf)."),
    out: Path = typer.Option(..., "-o", "--out", help="The .mrig file to write."),
    landmarks: Path | None = typer.Option(
        None, "--landmarks", help="Landmark file (JSON or CSV; project or ibug68_NN names)."
    ),
    auto_landmarks: bool = typer.Option(
        False, "--auto-landmarks", help="Find landmarks with MediaPipe (the default without --landmarks)."
    ),
    units: str | None = typer.Option(None, "--units", help="The mesh's units if the file does not say."),
    report: Path | None = typer.Option(
        None, "--report", help="Fit report JSON (default: next to the rig, NAME.fit.json)."
    ),
    picture: Path | None = typer.Option(
        None, "--picture", help="Residual-coloured PNG of the fit (default: NAME.fit.png)."
    ),
    force: bool = typer.Option(False, "--force", help="Write the rig even if the fit looks wrong."),
    resolution: int = typer.Option(10_000, "--resolution", help="Skin vertex count of the reference head."),
) -> None:
    """Fit the reference head to a mesh and write a muscle rig on the mesh's own vertices."""
    from mimetic.fit.autolandmarks import auto_landmarks as find_landmarks
    from mimetic.fit.landmarks import read_landmarks
    from mimetic.fit.pipeline import rig_head
    from mimetic.mesh.io import load_mesh
    from mimetic.rig.format import save_rig

    with _user_errors():
        if landmarks is not None and auto_landmarks:
            raise MimeticError("give --landmarks FILE or --auto-landmarks, not both")
        if out.suffix.lower() != ".mrig":
            raise MimeticError(f"-o {out}: a rig is written as .mrig")
        mesh = load_mesh(mesh_file, units=units)
        with _step_progress() as progress:
            if landmarks is not None:
                found = read_landmarks(landmarks, mesh_units=mesh.units)
            else:
                progress("landmarks (MediaPipe)", 0, 1)
                found = find_landmarks(mesh)
                progress("landmarks (MediaPipe)", 1, 1)
            result = rig_head(
                mesh,
                found,
                resolution=resolution,
                force=force,
                progress=progress,
                metadata={"source": mesh_file.name},
            )
        stem = out.with_suffix("")
        written = [save_rig(result.rig, out)]
        written.append(result.report.save(report or stem.with_name(stem.name + ".fit.json")))
        from mimetic.view import save_png
        from mimetic.view.fitreport import fit_report_image

        written.append(save_png(fit_report_image(result), picture or stem.with_name(stem.name + ".fit.png")))
    stdout.print(result.report.summary(), highlight=False)
    for path in written:
        stdout.print(f"wrote {path}", highlight=False)


def _parse_weights(items: list[str]) -> list[tuple[str, float]]:
    """``--expr NAME`` or ``--expr NAME=WEIGHT`` (repeatable) → [(name, weight)]."""
    from mimetic.animate.expressions import ExpressionError

    out = []
    for item in items:
        name, sep, value = item.partition("=")
        name = name.strip()
        try:
            weight = float(value) if sep else 1.0
        except ValueError:
            name = ""
        if not name:
            raise ExpressionError(f"--expr {item!r}: expected NAME or NAME=WEIGHT, e.g. --expr joy=0.7")
        out.append((name, weight))
    return out


def _parse_values(items: list[str]) -> dict[str, float]:
    """``--set CHANNEL=VALUE`` (repeatable) → {channel: value}."""
    from mimetic.errors import ActivationError

    return _name_values(items, "--set", "CHANNEL=VALUE", "jaw_open=0.2", ActivationError)


POSE_OUTPUTS = (".png", ".obj", ".ply", ".stl", ".glb", ".gltf")


@app.command()
def pose(
    rig: Path = typer.Argument(..., help="A .mrig rig (e.g. from `mimetic head --rig`)."),
    out: Path = typer.Option(
        ..., "-o", "--out", help="A PNG render, or the posed mesh (.obj .ply .glb .gltf .stl)."
    ),
    expr: list[str] = typer.Option(
        [], "--expr", help="Blend an expression, NAME or NAME=WEIGHT (repeatable), e.g. --expr joy=0.7."
    ),
    set_: list[str] = typer.Option(
        [],
        "--set",
        help="Set a channel after the blend, CHANNEL=VALUE (repeatable), e.g. --set jaw_open=0.2.",
    ),
    engine: str = typer.Option("wire", "--engine", help="Deformation engine: wire or vector."),
    view: str = typer.Option("front", "--view", help="front, three_quarter, profile, or all (a sheet)."),
    size: int = typer.Option(512, "--size", help="Image size in pixels (per view)."),
    intensity: float = typer.Option(1.0, "--intensity", help="Scale the whole expression blend."),
    library: Path | None = typer.Option(
        None, "--library", help="An expression library JSON file (default: the built-in one)."
    ),
) -> None:
    """Pose RIG with expressions and channel values; write a face render or the posed mesh."""
    from mimetic.engines import ENGINES

    with _user_errors():
        kind = out.suffix.lower()
        if kind not in POSE_OUTPUTS:
            raise MimeticError(
                f"-o {out}: unsupported output {out.suffix or '(no extension)'!r}; "
                f"use {', '.join(POSE_OUTPUTS)}"
            )
        if engine not in ENGINES:
            raise MimeticError(f"--engine {engine!r} is not one of: {', '.join(ENGINES)}")
        if view != "all" and view not in ("front", "three_quarter", "profile"):
            raise MimeticError(f"--view {view!r} is not one of: all, front, three_quarter, profile")
        if not 64 <= size <= 4096:
            raise MimeticError(f"--size {size} is outside 64..4096 pixels")
        weights, values = _parse_weights(expr), _parse_values(set_)

        from mimetic.animate.expressions import compose_pose, load_library
        from mimetic.rig.format import load_rig
        from mimetic.view.sheets import posed_mesh, render_pose

        loaded = load_rig(rig)
        lib = load_library(library, channels=loaded) if library is not None else None
        values_c = compose_pose(loaded, weights, values, intensity=intensity, library=lib)
        if kind == ".png":
            from mimetic.view import save_png

            save_png(render_pose(loaded, engine, values_c, view=view, size=size), out)
        else:
            from mimetic.mesh.io import save_mesh

            posed = posed_mesh(loaded, engine, values_c)
            if kind in (".obj", ".ply", ".stl"):  # the user's own frame; glTF keeps its +Y up
                posed = loaded.source_mesh(posed.vertices)
            save_mesh(posed, out)
    stdout.print(f"wrote {out}", highlight=False)


clip_app = typer.Typer(help="Make and edit keyframed clips (JSON).", no_args_is_help=True)
app.add_typer(clip_app, name="clip")


def _parse_pose_spec(item: str) -> tuple[float, dict[str, float] | None]:
    """``TIME:EXPR[=W][+EXPR[=W]...]`` or ``TIME:rest`` → (time_s, {expression: weight} or None)."""
    from mimetic.animate.clip import ClipError

    time_text, sep, rest = item.partition(":")
    try:
        time_s = float(time_text.strip().removesuffix("s"))
    except ValueError:
        sep = ""
    if not sep or not rest.strip():
        raise ClipError(f"--pose {item!r}: expected TIME:EXPRESSION[=WEIGHT][+...], e.g. --pose 0.5:joy=0.8")
    if rest.strip() == "rest":
        return time_s, None
    weights = {}
    for part in rest.split("+"):
        name, eq, value = part.partition("=")
        try:
            weights[name.strip()] = float(value) if eq else 1.0
        except ValueError:
            raise ClipError(
                f"--pose {item!r}: weight {value!r} of {name.strip()!r} is not a number"
            ) from None
    return time_s, weights


@clip_app.command("new")
def clip_new(
    rig: Path = typer.Argument(..., help="The .mrig rig whose channels the clip drives."),
    pose: list[str] = typer.Option(
        ..., "--pose", help="A key pose TIME:EXPRESSION[=WEIGHT][+...] or TIME:rest (repeatable)."
    ),
    out: Path = typer.Option(..., "-o", "--out", help="The clip JSON to write."),
    interpolation: str = typer.Option("cubic", "--interpolation", help="step, linear, cubic or tcb."),
) -> None:
    """Make a clip through expression poses, e.g. --pose 0:rest --pose 0.5:joy --pose 1:rest."""
    from mimetic.animate.clip import from_expressions, save_clip
    from mimetic.rig.format import load_rig

    with _user_errors():
        sequence = [_parse_pose_spec(item) for item in pose]
        clip = from_expressions(load_rig(rig), sequence, interpolation=interpolation)
        save_clip(clip, out)
    stdout.print(f"wrote {out} ({clip.duration_s:g} s, {len(clip.channels)} channels)", highlight=False)


@clip_app.command("edit")
def clip_edit(
    clip_file: Path = typer.Argument(..., help="The clip JSON to edit."),
    key: list[str] = typer.Option(
        ..., "--key", help="A new key CHANNEL@TIME=VALUE the edited curve must pass through (repeatable)."
    ),
    out: Path = typer.Option(..., "-o", "--out", help="The edited clip JSON to write."),
    knot_spacing: float = typer.Option(
        0.25, "--knot-spacing", help="B-spline knot spacing in seconds: how far each edit reaches."
    ),
    layer: str = typer.Option("edit", "--layer", help="The edit layer to add the displacement to."),
) -> None:
    """Edit curves by a smooth B-spline displacement through new keys, kept in its own layer."""
    from mimetic.animate.clip import load_clip, parse_key_spec, save_clip

    with _user_errors():
        clip = load_clip(clip_file)
        by_channel: dict[str, dict[float, float]] = {}
        for item in key:
            channel, time_s, value = parse_key_spec(item)
            by_channel.setdefault(channel, {})[time_s] = value
        for channel, constraints in by_channel.items():
            clip = clip.edit(channel, constraints, knot_spacing_s=knot_spacing, layer=layer)
        save_clip(clip, out)
    stdout.print(f"wrote {out} ({len(key)} keys in layer {layer!r})", highlight=False)


ANIMATE_OUTPUTS = (".mp4", ".glb", ".usda", ".usdc", ".usd")
SCENE_OUTPUTS = (".glb", ".usda", ".usdc", ".usd")


def _write_scene(rig, out: Path, targets: dict, clip=None) -> Path:
    """A GLB, or USD (UsdSkel; needs the [usd] extra), by the suffix of ``out``."""
    if out.suffix.lower() == ".glb":
        from mimetic.export.gltf import export_glb

        return export_glb(rig, out, morph_targets=targets, clip=clip)
    from mimetic.export.usd import export_usd

    return export_usd(rig, out, morph_targets=targets, clip=clip)


@app.command()
def animate(
    rig: Path = typer.Argument(..., help="The .mrig rig to animate."),
    clip: Path = typer.Option(..., "--clip", help="A clip JSON (from `mimetic clip new` or the API)."),
    out: Path = typer.Option(
        ..., "-o", "--out", help="anim.mp4 (a rendered video), anim.glb or anim.usda/.usdc (UsdSkel)."
    ),
    fps: float = typer.Option(30.0, "--fps", help="Frames per second of the output."),
    size: int = typer.Option(512, "--size", help="Video size in pixels (square, 64..2160)."),
    audio: Path | None = typer.Option(None, "--audio", help="A sound track for the video (WAV, …)."),
    engine: str = typer.Option("wire", "--engine", help="Deformation engine for the video: wire or vector."),
) -> None:
    """Play a clip on a rig: render an MP4 (with optional audio) or export an animated GLB or USD."""
    from mimetic.animate.clip import load_clip
    from mimetic.rig.format import load_rig

    with _user_errors():
        kind = out.suffix.lower()
        if kind not in ANIMATE_OUTPUTS:
            raise MimeticError(f"-o {out}: use one of {', '.join(ANIMATE_OUTPUTS)}")
        if not 0 < fps <= 240:
            raise MimeticError(f"--fps {fps} is outside (0, 240]")
        loaded = load_rig(rig)
        sampled = load_clip(clip).sample(fps, channels=loaded)
        if kind == ".mp4":
            from mimetic.engines import ENGINES
            from mimetic.view.video import render_clip

            if engine not in ENGINES:
                raise MimeticError(f"--engine {engine!r} is not one of: {', '.join(ENGINES)}")
            with _progress("video") as progress:
                render_clip(loaded, sampled, out, engine=engine, size=size, audio=audio, progress=progress)
        else:
            with _progress("bake") as progress:
                targets = _muscle_targets(loaded, engine, progress)
            _write_scene(loaded, out, targets, sampled)
    stdout.print(f"wrote {out} ({sampled.n_frames} frames at {fps:g} fps)", highlight=False)


def _muscle_targets(rig, engine: str, progress) -> dict:
    """One morph target per muscle channel (the baked basis), for GLB export."""
    from mimetic.engines import ENGINES, make_engine
    from mimetic.engines.bake import bake
    from mimetic.export.gltf import morph_targets_from_basis

    if engine not in ENGINES:
        raise MimeticError(f"--engine {engine!r} is not one of: {', '.join(ENGINES)}")
    progress(0, 1)
    basis = bake(make_engine(rig, engine)).basis
    progress(1, 1)
    return morph_targets_from_basis(basis, rig)


@app.command("export")
def export_command(
    rig: Path = typer.Argument(..., help="The .mrig rig to export."),
    out: Path = typer.Option(..., "-o", "--out", help="The .glb (or .usda/.usdc, UsdSkel) file to write."),
    arkit: bool = typer.Option(
        False, "--arkit", help="Morph targets are the 52 ARKit blendshapes (else one per muscle)."
    ),
    obj_dir: Path | None = typer.Option(
        None, "--obj-dir", help="Also write each morph target as a posed OBJ into this folder."
    ),
    engine: str = typer.Option("wire", "--engine", help="Deformation engine: wire or vector."),
) -> None:
    """Export a rig as GLB or USD with named morph targets and its skeleton (ARKit-52 with --arkit)."""
    from mimetic.rig.format import load_rig

    with _user_errors():
        if out.suffix.lower() not in SCENE_OUTPUTS:
            raise MimeticError(f"-o {out}: export writes {', '.join(SCENE_OUTPUTS)}")
        loaded = load_rig(rig)
        with _progress("bake") as progress:
            if arkit:
                from mimetic.export.arkit import arkit_shapes

                progress(0, 1)
                targets = arkit_shapes(loaded, engine=engine)
                progress(1, 1)
            else:
                targets = _muscle_targets(loaded, engine, progress)
        written = [_write_scene(loaded, out, targets)]
        if obj_dir is not None:
            from mimetic.mesh.io import save_mesh

            obj_dir.mkdir(parents=True, exist_ok=True)
            rest = loaded.mesh.vertices
            for name, delta in targets.items():  # in the user's own frame, on top of their mesh at rest
                written.append(save_mesh(loaded.source_mesh(rest + delta), obj_dir / f"{name}.obj"))
    stdout.print(f"wrote {out} ({len(targets)} morph targets)", highlight=False)
    if obj_dir is not None:
        stdout.print(f"wrote {len(written) - 1} OBJs to {obj_dir}", highlight=False)


@app.command()
def demo(
    out: Path = typer.Option(Path("mimetic-demo"), "-o", "--out", help="Folder for the demo outputs."),
    resolution: int = typer.Option(10_000, "--resolution", help="Approximate skin vertex count."),
) -> None:
    """Generate the default head and 8 random heads, rig them, and write meshes, rigs and sheets."""
    from mimetic.demo import run_demo

    with _user_errors(), _progress("demo: heads and rigs") as progress:
        result = run_demo(out, resolution=resolution, progress=progress)
    table = Table("file", "size", title=f"mimetic demo → {result.out_dir}")
    for path in result.files:
        table.add_row(str(path), f"{path.stat().st_size / 1024:,.0f} KB")
    stdout.print(table)
    for note in result.notes:
        stdout.print(f"note: {note}", highlight=False)
