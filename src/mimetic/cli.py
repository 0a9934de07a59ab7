"""The ``mimetic`` command (typer + rich): thin wrappers over the library.

Results go to stdout; progress, warnings and errors go to stderr. Exit codes:

* 0: success;
* 1: a problem with the input (a broken mesh, a rig without that channel, an unwritable folder),
  shown as one line that says what is wrong and how to fix it; anything unexpected is one line too,
  asking for a report (``mimetic --debug …`` shows the traceback);
* 2: a usage error: an unknown option, a malformed or out-of-range value, an output type the
  command does not write (typer's own message).

Output paths are checked before any work starts, and every file is written atomically.
"""

from __future__ import annotations

import functools
import json
import sys
import tempfile
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from enum import Enum
from pathlib import Path

import typer
from rich.console import Console
from rich.progress import (
    BarColumn,
    Progress,
    ProgressColumn,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)
from rich.table import Table
from rich.text import Text

from mimetic import __version__
from mimetic.engines import ENGINES
from mimetic.errors import MimeticError

app = typer.Typer(
    help="mimetic: turn any 3D head mesh into a muscle-driven, animatable face.",
    no_args_is_help=True,
    pretty_exceptions_show_locals=False,
    add_completion=False,
    rich_markup_mode=None,  # help texts hold literal brackets ([track], [0, 1]) and no markup
)
PIPED_WIDTH = 200
"""Line width when stdout or stderr is not a terminal (rich would wrap at 80)."""
stdout = Console(soft_wrap=True, highlight=False, width=None if sys.stdout.isatty() else PIPED_WIDTH)
stderr = Console(
    stderr=True, soft_wrap=True, highlight=False, width=None if sys.stderr.isatty() else PIPED_WIDTH
)
_state = {"debug": False}

ViewName = Enum("ViewName", {v: v for v in ("front", "three_quarter", "profile")}, type=str)
SheetView = Enum("SheetView", {v: v for v in ("front", "three_quarter", "profile", "all")}, type=str)
EngineName = Enum("EngineName", {e: e for e in ENGINES}, type=str)
Interpolation = Enum("Interpolation", {i: i for i in ("step", "linear", "cubic", "tcb")}, type=str)
Units = Enum("Units", {u: u for u in ("mm", "cm", "dm", "m", "in")}, type=str)


def _version(value: bool) -> None:
    if value:
        stdout.print(f"mimetic {__version__}")
        raise typer.Exit()


@app.callback()
def main(
    debug: bool = typer.Option(False, "--debug", help="Show the traceback of an error."),
    version: bool = typer.Option(
        False, "--version", callback=_version, is_eager=True, help="Print the version and exit."
    ),
) -> None:
    """mimetic: turn any 3D head mesh into a muscle-driven, animatable face.

    Examples:

    \b
      mimetic demo
      mimetic rig my_head.obj -o my_head.mrig
      mimetic pose my_head.mrig --expr joy -o joy.png
    """
    _state["debug"] = debug


# --------------------------------------------------------------------------- the error boundary


def _message(error: BaseException) -> str:
    """One line for the user: a MimeticError's own message, a file error with its file, else a bug."""
    if isinstance(error, MimeticError):
        return str(error)
    if isinstance(error, OSError) and error.strerror:
        where = f"{error.filename}: " if error.filename else ""
        return f"{where}{error.strerror}"
    return (
        f"unexpected {type(error).__name__}: {error}. This is a bug in mimetic: run the command again "
        "with --debug (mimetic --debug …) for the traceback and report it."
    )


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Python warnings as one line each on stderr, without the source path and code line."""
    stderr.print(Text.assemble(("warning: ", "yellow"), str(message)))


def _guarded(command: Callable) -> Callable:
    """Run a command inside the error boundary: no traceback without --debug, warnings as lines."""

    @functools.wraps(command)
    def run(*args, **kwargs):
        with warnings.catch_warnings():
            warnings.simplefilter("default")
            warnings.showwarning = _show_warning
            try:
                return command(*args, **kwargs)
            except (typer.Exit, typer.Abort, typer.TyperException):
                raise
            except KeyboardInterrupt:
                stderr.print("interrupted")
                raise typer.Exit(130) from None
            except Exception as error:
                if _state["debug"]:
                    raise
                stderr.print(Text.assemble(("error: ", "bold red"), _message(error)))
                raise typer.Exit(1) from None

    return run


def command(name: str | None = None, parent: typer.Typer = app):
    """``@app.command()`` with the error boundary."""

    def register(function: Callable) -> Callable:
        return parent.command(name)(_guarded(function))

    return register


def _output(path: Path, suffixes: tuple[str, ...], option: str = "-o") -> Path:
    """Check an output file before any work: a suffix the command writes (else a usage error, exit 2)
    and an existing, writable folder (else exit 1)."""
    if path.suffix.lower() not in suffixes:
        raise typer.BadParameter(
            f"{path.name}: unsupported output {path.suffix or '(no suffix)'!r}; use {', '.join(suffixes)}",
            param_hint=f"'{option}'",
        )
    return _folder_of(path)


def _folder_of(path: Path) -> Path:
    """Check an output file's folder before any work: it exists and can be written; ``path`` is not a
    folder."""
    if path.is_dir():
        raise MimeticError(f"{path} is a folder; give a file name")
    _writable(path.parent if str(path.parent) else Path("."))
    return path


def _output_folder(path: Path) -> Path:
    """Check an output folder before any work: an existing folder to write into (its files are
    replaced one by one), or a new one whose parent exists; not a file."""
    if path.exists() and not path.is_dir():
        raise MimeticError(f"{path} is a file; give a folder")
    _writable(path if path.is_dir() else (path.parent if str(path.parent) else Path(".")))
    return path


def _writable(folder: Path) -> None:
    import os

    if not folder.is_dir():
        raise MimeticError(f"the folder {folder} does not exist; create it first (mkdir -p {folder})")
    if not os.access(folder, os.W_OK):
        raise MimeticError(f"cannot write into {folder}: permission denied")


# --------------------------------------------------------------------------- progress


class _Count(ProgressColumn):
    """``done/total``, or nothing while the total is unknown."""

    def render(self, task) -> Text:
        return Text("" if task.total is None else f"{task.completed:g}/{task.total:g}")


def _bar(description: str = "{task.description}") -> Progress:
    return Progress(
        TextColumn(description),
        BarColumn(),
        _Count(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=stderr,
        transient=True,
    )


@contextmanager
def _progress(label: str) -> Iterator[Callable[[int, int], None]]:
    """A progress callback ``(done, total)`` showing one bar."""
    with _bar(label) as bar:
        task = bar.add_task(label, total=None)

        def update(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        yield update


@contextmanager
def _step_progress() -> Iterator[Callable[[str, int, int], None]]:
    """A progress callback ``(step, done, total)`` showing one bar per named step."""
    with _bar() as bar:
        tasks: dict[str, int] = {}

        def update(step: str, done: int, total: int) -> None:
            if step not in tasks:
                tasks[step] = bar.add_task(step, total=total)
            bar.update(tasks[step], completed=done, total=total)

        yield update


# --------------------------------------------------------------------------- option parsing


def _name_value(item: str, option: str, form: str, example: str) -> tuple[str, float]:
    """``NAME=VALUE`` → (name, value); a malformed item is a usage error (exit 2)."""
    name, sep, value = item.partition("=")
    try:
        number = float(value)
    except ValueError:
        sep = ""
    if not sep or not name.strip():
        raise typer.BadParameter(
            f"{item!r}: expected {form}, e.g. {option} {example}", param_hint=f"'{option}'"
        )
    return name.strip(), number


def _params(items: list[str]) -> list[str]:
    for item in items:
        _name_value(item, "--param", "NAME=VALUE", "nose_length=1.05")
    return items


def _values(items: list[str]) -> list[str]:
    for item in items:
        _name_value(item, "--set", "CHANNEL=VALUE", "jaw_open=0.2")
    return items


def _weights(items: list[str]) -> list[str]:
    for item in items:
        if "=" in item:
            _name_value(item, "--expr", "NAME or NAME=WEIGHT", "joy=0.7")
        elif not item.strip():
            raise typer.BadParameter("an empty expression name", param_hint="'--expr'")
    return items


def _as_values(items: list[str]) -> dict[str, float]:
    """Checked ``--set`` items → {channel: value}."""
    return dict(_name_value(item, "--set", "", "") for item in items)


def _as_weights(items: list[str]) -> list[tuple[str, float]]:
    """Checked ``--expr`` items → [(expression, weight)]."""
    return [_name_value(i, "--expr", "", "") if "=" in i else (i.strip(), 1.0) for i in items]


def _poses(items: list[str]) -> list[str]:
    for item in items:
        _pose_spec(item)
    return items


def _pose_spec(item: str) -> tuple[float, dict[str, float] | None]:
    """``TIME:EXPR[=W][+EXPR[=W]...]`` or ``TIME:rest`` → (time_s, {expression: weight} or None)."""
    time_text, sep, rest = item.partition(":")
    try:
        time_s = float(time_text.strip().removesuffix("s"))
    except ValueError:
        sep = ""
    if not sep or not rest.strip():
        raise typer.BadParameter(
            f"{item!r}: expected TIME:EXPRESSION[=WEIGHT][+...], e.g. --pose 0.5:joy=0.8",
            param_hint="'--pose'",
        )
    if rest.strip() == "rest":
        return time_s, None
    weights = {}
    for part in rest.split("+"):
        name, eq, value = part.partition("=")
        try:
            weights[name.strip()] = float(value) if eq else 1.0
        except ValueError:
            raise typer.BadParameter(
                f"{item!r}: weight {value!r} of {name.strip()!r} is not a number", param_hint="'--pose'"
            ) from None
    return time_s, weights


def _keys(items: list[str]) -> list[str]:
    from mimetic.animate.clip import ClipError, parse_key_spec

    for item in items:
        try:
            parse_key_spec(item)
        except ClipError as error:
            raise typer.BadParameter(str(error), param_hint="'--key'") from None
    return items


# --------------------------------------------------------------------------- commands


@command()
def head(
    out: Path = typer.Option(..., "-o", "--out", help="Mesh file to write (.glb, .gltf, .obj, .ply, .stl)."),
    seed: int | None = typer.Option(None, "--seed", help="Random conformation from this seed."),
    param: list[str] = typer.Option(
        [],
        "--param",
        metavar="NAME=VALUE",
        callback=_params,
        help="Set a conformation parameter (repeatable).",
    ),
    resolution: int = typer.Option(
        10_000, "--resolution", min=1_500, max=250_000, help="Approximate skin vertex count."
    ),
    rig: Path | None = typer.Option(None, "--rig", help="Also write the head's rig to this .mrig file."),
) -> None:
    """Generate a parametric reference head and write it as a mesh (and optionally its rig).

    Examples:

    \b
      mimetic head -o head.glb
      mimetic head --seed 7 --param nose_length=1.05 -o head.obj --rig head.mrig
    """
    from mimetic.head.model import make_head
    from mimetic.head.params import HeadParams
    from mimetic.mesh.io import SUPPORTED_FORMATS, save_mesh

    _output(out, SUPPORTED_FORMATS)
    if rig is not None:
        _output(rig, (".mrig",), "--rig")
    params = HeadParams() if seed is None else HeadParams.random(seed)
    params = params.with_values(**dict(_name_value(p, "--param", "", "") for p in param))
    generated = make_head(params, resolution)
    written = [save_mesh(generated.mesh, out)]
    if rig is not None:
        from mimetic.rig.format import save_rig
        from mimetic.rig.recipe import build_rig

        written.append(save_rig(build_rig(generated), rig))
    for path in written:
        stdout.print(f"wrote {path}")


@command()
def info(
    file: Path = typer.Argument(
        ..., metavar="FILE", help="A mesh (.obj .ply .stl .glb .gltf) or a rig (.mrig)."
    ),
    units: Units | None = typer.Option(None, "--units", help="The mesh's units if the file does not say."),
    as_json: bool = typer.Option(False, "--json", help="Print the report as JSON."),
) -> None:
    """Validate a mesh or rig and report its units, parts, seams, winding and landmarks.

    Exit code 1 when the mesh cannot be rigged as it is.

    Examples:

    \b
      mimetic info scan.obj
      mimetic info scan.stl --units mm --json
    """
    if file.suffix.lower() == ".mrig":
        report, ok = _rig_report(file), True
    else:
        report, ok = _mesh_report(file, None if units is None else units.value)
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
        f"channels          {len(rig.channels)} (mimetic list channels {file.name})",
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
    stdout.print(Text.assemble((report["file"], "bold"), f" ({report['kind']})"))
    for line in report["lines"]:
        stdout.print(f"  {line}", markup=False)
    landmarks = report["landmarks"]
    text = landmarks if isinstance(landmarks, str) else f"{len(landmarks)}: {', '.join(landmarks)}"
    stdout.print(f"  landmarks         {text}", markup=False)


IMAGE_OUTPUTS = (".png", ".jpg", ".jpeg", ".webp")


@command()
def render(
    file: Path = typer.Argument(..., metavar="FILE", help="A mesh or a .mrig rig."),
    out: Path = typer.Option(..., "-o", "--out", help="Image to write (.png, .jpg, .webp)."),
    view: SheetView = typer.Option(
        SheetView.all, "--view", help="front, three_quarter, profile, or all (a labelled sheet of the three)."
    ),
    size: int = typer.Option(512, "--size", min=64, max=4096, help="Image size in pixels (per view)."),
    wireframe: bool = typer.Option(False, "--wireframe", help="Draw the triangle edges."),
    muscles: bool = typer.Option(True, "--muscles/--no-muscles", help="Draw a rig's muscles."),
    units: Units | None = typer.Option(None, "--units", help="A mesh's units if the file does not say."),
) -> None:
    """Render a mesh or rig to an image, from one angle or three.

    Examples:

    \b
      mimetic render scan.obj -o scan.png
      mimetic render head.mrig --view front --no-muscles --size 1024 -o face.jpg
    """
    from mimetic.render import VIEWS
    from mimetic.render import render as render_mesh
    from mimetic.view import contact_sheet, save_image

    _output(out, IMAGE_OUTPUTS)
    views = list(VIEWS) if view.value == "all" else [view.value]
    if file.suffix.lower() == ".mrig":
        from mimetic.rig.format import load_rig
        from mimetic.view.muscles import render_rig

        rig = load_rig(file)
        tiles = [(v, render_rig(rig, v, size=size, muscles=muscles, wireframe=wireframe)) for v in views]
    else:
        from mimetic.mesh.io import load_mesh

        mesh = load_mesh(file, units=None if units is None else units.value)
        tiles = [(v, render_mesh(mesh, v, size=size, wireframe=wireframe)) for v in views]
    image = tiles[0][1] if len(tiles) == 1 else contact_sheet(tiles, columns=len(tiles))
    save_image(image, out)
    stdout.print(f"wrote {out}")


@command("rig")
def rig_command(
    mesh_file: Path = typer.Argument(
        ..., metavar="MESH", help="The head mesh to rig (.obj .ply .stl .glb .gltf)."
    ),
    out: Path = typer.Option(..., "-o", "--out", help="The .mrig file to write."),
    landmarks: Path | None = typer.Option(
        None, "--landmarks", help="Landmark file (JSON or CSV; project names or ibug68_01..ibug68_68)."
    ),
    auto_landmarks: bool = typer.Option(
        False, "--auto-landmarks", help="Find landmarks with MediaPipe (the default without --landmarks)."
    ),
    units: Units | None = typer.Option(
        None, "--units", help="The mesh's units if the file does not say (else guessed from its size)."
    ),
    report: Path | None = typer.Option(
        None, "--report", help="Fit report JSON (default: next to the rig, NAME.fit.json)."
    ),
    picture: Path | None = typer.Option(
        None, "--picture", help="Residual-coloured PNG of the fit (default: NAME.fit.png)."
    ),
    force: bool = typer.Option(False, "--force", help="Write the rig even if the fit looks wrong."),
    resolution: int = typer.Option(
        10_000, "--resolution", min=1_500, max=250_000, help="Skin vertex count of the reference head."
    ),
) -> None:
    """Fit the reference head to a mesh and write a muscle rig on the mesh's own vertices.

    Examples:

    \b
      mimetic rig my_head.obj -o my_head.mrig
      mimetic rig scan.stl --units mm --landmarks dlib68.csv -o scan.mrig
    """
    from mimetic.fit.pipeline import rig_mesh
    from mimetic.rig.format import save_rig

    if landmarks is not None and auto_landmarks:
        raise typer.BadParameter(
            "give --landmarks FILE or --auto-landmarks, not both", param_hint="'--landmarks'"
        )
    _output(out, (".mrig",))
    stem = out.with_suffix("")
    report = _output(report or stem.with_name(stem.name + ".fit.json"), (".json",), "--report")
    picture = _output(picture or stem.with_name(stem.name + ".fit.png"), IMAGE_OUTPUTS, "--picture")
    with _step_progress() as progress:
        result = rig_mesh(
            mesh_file,
            landmarks,
            units=None if units is None else units.value,
            resolution=resolution,
            force=force,
            progress=progress,
        )
    from mimetic.view import save_image
    from mimetic.view.fitreport import fit_report_image

    written = [save_rig(result.rig, out), result.report.save(report)]
    written.append(save_image(fit_report_image(result), picture))
    stdout.print(result.report.summary())
    for path in written:
        stdout.print(f"wrote {path}")


POSE_OUTPUTS = (*IMAGE_OUTPUTS, ".obj", ".ply", ".stl", ".glb", ".gltf")


@command()
def pose(
    rig: Path = typer.Argument(
        ..., metavar="RIG", help="A .mrig rig (e.g. from `mimetic head --rig` or `mimetic rig`)."
    ),
    out: Path = typer.Option(
        ...,
        "-o",
        "--out",
        help="An image (.png .jpg), or the posed mesh (.obj .ply .stl in your own frame; .glb .gltf).",
    ),
    expr: list[str] = typer.Option(
        [], "--expr", metavar="NAME[=WEIGHT]", callback=_weights, help="Blend an expression (repeatable)."
    ),
    set_: list[str] = typer.Option(
        [],
        "--set",
        metavar="CHANNEL=VALUE",
        callback=_values,
        help="Set a channel after the blend (repeatable).",
    ),
    engine: EngineName = typer.Option(EngineName.wire, "--engine", help="Deformation engine."),
    view: SheetView = typer.Option(
        SheetView.front, "--view", help="For images: one view, or all three in a sheet."
    ),
    size: int = typer.Option(512, "--size", min=64, max=4096, help="Image size in pixels (per view)."),
    intensity: float = typer.Option(1.0, "--intensity", help="Scale the whole expression blend."),
    library: Path | None = typer.Option(
        None, "--library", help="An expression library JSON file (default: the built-in one)."
    ),
) -> None:
    """Pose RIG with expressions and channel values; write a face render or the posed mesh.

    Names: mimetic list expressions, mimetic list channels RIG.

    Examples:

    \b
      mimetic pose head.mrig --expr joy -o joy.png
      mimetic pose head.mrig --expr joy=0.7 --expr surprise=0.3 --set jaw_open=0.2 -o joy.obj
    """
    from mimetic.animate.expressions import compose_pose, load_library
    from mimetic.rig.format import load_rig
    from mimetic.view.sheets import posed_mesh, render_pose

    _output(out, POSE_OUTPUTS)
    loaded = load_rig(rig)
    lib = load_library(library, channels=loaded) if library is not None else None
    values = compose_pose(loaded, _as_weights(expr), _as_values(set_), intensity=intensity, library=lib)
    kind = out.suffix.lower()
    if kind in IMAGE_OUTPUTS:
        from mimetic.view import save_image

        save_image(render_pose(loaded, engine.value, values, view=view.value, size=size), out)
    else:
        from mimetic.mesh.io import save_mesh

        posed = posed_mesh(loaded, engine.value, values)
        if kind in (".obj", ".ply", ".stl"):  # the user's own frame; glTF keeps its +Y up
            posed = loaded.source_mesh(posed.vertices)
        save_mesh(posed, out)
    stdout.print(f"wrote {out}")


clip_app = typer.Typer(
    help="Make and edit keyframed clips (JSON).", no_args_is_help=True, rich_markup_mode=None
)
app.add_typer(clip_app, name="clip")


@command("new", parent=clip_app)
def clip_new(
    rig: Path = typer.Argument(..., metavar="RIG", help="The .mrig rig whose channels the clip drives."),
    pose: list[str] = typer.Option(
        ...,
        "--pose",
        metavar="TIME:EXPR[=W][+...]",
        callback=_poses,
        help="A key pose, or TIME:rest (repeatable).",
    ),
    out: Path = typer.Option(..., "-o", "--out", help="The clip JSON to write."),
    interpolation: Interpolation = typer.Option(Interpolation.cubic, "--interpolation", help="Between keys."),
) -> None:
    """Make a clip through expression poses.

    Examples:

    \b
      mimetic clip new head.mrig --pose 0:rest --pose 0.5:joy --pose 1:rest -o clip.json
      mimetic clip new head.mrig --pose 0:rest --pose 1:surprise=0.8+joy=0.2 --interpolation tcb -o c.json
    """
    from mimetic.animate.clip import from_expressions, save_clip
    from mimetic.rig.format import load_rig

    _output(out, (".json",))
    sequence = [_pose_spec(item) for item in pose]
    clip = from_expressions(load_rig(rig), sequence, interpolation=interpolation.value)
    save_clip(clip, out)
    stdout.print(f"wrote {out} ({clip.duration_s:g} s, {len(clip.channels)} channels)")


@command("edit", parent=clip_app)
def clip_edit(
    clip_file: Path = typer.Argument(..., metavar="CLIP", help="The clip JSON to edit."),
    key: list[str] = typer.Option(
        ...,
        "--key",
        metavar="CHANNEL@TIME=VALUE",
        callback=_keys,
        help="A new key the edited curve must pass through (repeatable).",
    ),
    out: Path = typer.Option(..., "-o", "--out", help="The edited clip JSON to write."),
    knot_spacing: float = typer.Option(
        0.25, "--knot-spacing", min=1e-3, help="B-spline knot spacing in seconds: how far each edit reaches."
    ),
    layer: str = typer.Option("edit", "--layer", help="The edit layer to add the displacement to."),
) -> None:
    """Edit curves by a smooth B-spline displacement through new keys, kept in its own layer.

    Examples:

    \b
      mimetic clip edit clip.json --key jaw_open@0.75=0.3 -o edited.json
      mimetic clip edit clip.json --key jaw_open@0.5=0.2 --key jaw_open@1=0 --knot-spacing 0.1 -o e.json
    """
    from mimetic.animate.clip import load_clip, parse_key_spec, save_clip

    _output(out, (".json",))
    clip = load_clip(clip_file)
    by_channel: dict[str, dict[float, float]] = {}
    for item in key:
        channel, time_s, value = parse_key_spec(item)
        by_channel.setdefault(channel, {})[time_s] = value
    for channel, constraints in by_channel.items():
        clip = clip.edit(channel, constraints, knot_spacing_s=knot_spacing, layer=layer)
    save_clip(clip, out)
    stdout.print(f"wrote {out} ({len(key)} keys in layer {layer!r})")


ANIMATE_OUTPUTS = (".mp4", ".glb", ".usda", ".usdc", ".usd")
SCENE_OUTPUTS = (".glb", ".usda", ".usdc", ".usd")


def _write_scene(rig, out: Path, targets: dict, clip=None) -> Path:
    """A GLB, or USD (UsdSkel; needs the [usd] extra), by the suffix of ``out``."""
    if out.suffix.lower() == ".glb":
        from mimetic.export.gltf import export_glb

        return export_glb(rig, out, morph_targets=targets, clip=clip)
    from mimetic.export.usd import export_usd

    return export_usd(rig, out, morph_targets=targets, clip=clip)


@command()
def animate(
    rig: Path = typer.Argument(..., metavar="RIG", help="The .mrig rig to animate."),
    clip: Path = typer.Option(..., "--clip", help="A clip JSON (from `mimetic clip new` or the API)."),
    out: Path = typer.Option(
        ..., "-o", "--out", help="anim.mp4 (a rendered video), anim.glb or anim.usda/.usdc (UsdSkel)."
    ),
    fps: float = typer.Option(30.0, "--fps", min=1e-3, max=240.0, help="Frames per second of the output."),
    size: int = typer.Option(512, "--size", min=64, max=2160, help="Video size in pixels (square)."),
    audio: Path | None = typer.Option(None, "--audio", help="A sound track for the video (WAV, …)."),
    engine: EngineName = typer.Option(EngineName.wire, "--engine", help="Deformation engine."),
) -> None:
    """Play a clip on a rig: render an MP4 (with optional audio) or export an animated GLB or USD.

    Examples:

    \b
      mimetic animate head.mrig --clip clip.json -o anim.mp4 --audio speech.wav
      mimetic animate head.mrig --clip clip.json --fps 60 -o anim.glb
    """
    from mimetic.animate.clip import load_clip
    from mimetic.rig.format import load_rig

    _output(out, ANIMATE_OUTPUTS)
    loaded = load_rig(rig)
    sampled = load_clip(clip).sample(fps, channels=loaded)
    if out.suffix.lower() == ".mp4":
        from mimetic.view.video import render_clip

        with _progress("video") as progress:
            render_clip(loaded, sampled, out, engine=engine.value, size=size, audio=audio, progress=progress)
    else:
        with _progress("bake") as progress:
            targets = _muscle_targets(loaded, engine.value, progress)
        _write_scene(loaded, out, targets, sampled)
    stdout.print(f"wrote {out} ({sampled.n_frames} frames at {fps:g} fps)")


SPEAK_OUTPUTS = (*ANIMATE_OUTPUTS, ".json", ".csv")
Language = Enum("Language", {"en": "en", "nso": "nso"}, type=str)


@command()
def speak(
    rig: Path = typer.Argument(..., metavar="RIG", help="The .mrig rig that speaks."),
    out: Path = typer.Option(
        ...,
        "-o",
        "--out",
        help="talk.mp4 (video with the sound), talk.glb / .usda / .usdc, or the clip as .json / .csv.",
    ),
    text: str | None = typer.Option(None, "--text", help="What is said (the transcript, with --audio)."),
    text_file: Path | None = typer.Option(None, "--text-file", help="Read the text from a file."),
    timings: Path | None = typer.Option(
        None, "--timings", help="Phone timings: Praat/MFA TextGrid, CSV or JSON (phoneme, start, end)."
    ),
    audio: Path | None = typer.Option(
        None, "--audio", help="A recording (WAV): aligned to the text offline, and muxed into an MP4."
    ),
    synthesize: bool = typer.Option(
        False, "--synthesize", help="Speak the text with the espeak-ng program and sync to its sound."
    ),
    language: Language = typer.Option(
        Language.en, "--language", help="en (English) or nso (Northern Sotho, Sesotho sa Leboa)."
    ),
    visemes: str | None = typer.Option(
        None, "--visemes", help="Viseme map: en, nso, mpeg4 or a map .json (default: the language's)."
    ),
    fps: float = typer.Option(30.0, "--fps", min=1.0, max=240.0, help="Frames per second."),
    rate: float = typer.Option(1.0, "--rate", min=0.2, max=5.0, help="Speaking rate for text alone."),
    jaw: float = typer.Option(1.0, "--jaw", min=0.0, max=2.0, help="Jaw intensity (JALI dial)."),
    lips: float = typer.Option(1.0, "--lips", min=0.0, max=2.0, help="Lip intensity (JALI dial)."),
    eyes: bool = typer.Option(True, "--eyes/--no-eyes", help="Add blinks and small gaze saccades."),
    seed: int = typer.Option(0, "--seed", help="Seed of the blinks and saccades."),
    baseline: bool = typer.Option(
        False, "--baseline", help="Linear interpolation between visemes instead of coarticulation."
    ),
    timings_out: Path | None = typer.Option(
        None, "--timings-out", help="Also write the phone timings (.TextGrid, .csv or .json)."
    ),
    size: int = typer.Option(512, "--size", min=64, max=2160, help="Video size in pixels (square)."),
    engine: EngineName = typer.Option(EngineName.wire, "--engine", help="Deformation engine."),
) -> None:
    """Lip sync: text, phone timings or audio + transcript to a talking head (visemes, coarticulation).

    Examples:

    \b
      mimetic speak head.mrig --text "Hello there" -o hello.mp4
      mimetic speak head.mrig --audio take1.wav --text-file take1.txt -o take1.mp4
      mimetic speak head.mrig --timings take1.TextGrid --audio take1.wav -o take1.glb
      mimetic speak head.mrig --text "Dumela, o kae?" --language nso -o dumela.mp4
      mimetic speak head.mrig --text "Hello there" --synthesize -o hello.mp4
    """
    from mimetic.rig.format import load_rig
    from mimetic.speech.lipsync import lip_sync
    from mimetic.speech.timings import save_timings
    from mimetic.speech.visemes import BUILT_IN, load_viseme_map

    _output(out, SPEAK_OUTPUTS)
    if timings_out is not None:
        _output(timings_out, (".textgrid", ".csv", ".json"), "--timings-out")
    if text_file is not None:
        if text is not None:
            raise typer.BadParameter("give --text or --text-file, not both")
        text = text_file.read_text(encoding="utf-8")
    loaded = load_rig(rig)
    vmap = visemes if visemes is None or visemes in BUILT_IN else load_viseme_map(visemes, channels=loaded)
    with tempfile.TemporaryDirectory() as scratch:
        spoken = Path(scratch) / "synthesized.wav" if synthesize else None
        speech = lip_sync(
            loaded,
            text=text,
            timings=timings,
            audio=audio,
            synthesize_to=spoken,
            language=language.value,
            fps=fps,
            visemes=vmap,
            jaw=jaw,
            lips=lips,
            rate=rate,
            eyes=eyes,
            seed=seed,
            baseline=baseline,
        )
        clip = speech.clip
        _write_clip(loaded, clip, out, engine=engine.value, size=size, audio=speech.audio)
    if timings_out is not None:
        save_timings(speech.timings, timings_out)
    spoken_phones = len(speech.timings.spoken())
    stdout.print(
        f"wrote {out} ({clip.n_frames} frames at {fps:g} fps, {spoken_phones} phones, {speech.source})"
    )


capture_app = typer.Typer(
    help="Performance capture: markers, landmarks or video → activations; retarget to another head.",
    no_args_is_help=True,
)
app.add_typer(capture_app, name="capture")
CAPTURE_OUTPUTS = (".json", ".csv", *ANIMATE_OUTPUTS)
CaptureUnits = Enum("CaptureUnits", {u: u for u in ("mm", "cm", "m", "px")}, type=str)


def _capture_channels(channels: str, rig) -> None:
    """--channels: "all", "determined" or names the rig has (checked here, so a typo is a usage error)."""
    if channels in ("all", "determined"):
        return
    unknown = [
        n.strip() for n in channels.split(",") if n.strip() and n.strip() not in set(rig.channel_names)
    ]
    if unknown:
        raise typer.BadParameter(f"unknown channel(s) {', '.join(unknown[:5])}", param_hint="--channels")


def _solve_capture(
    loaded,
    trajectories,
    *,
    markers,
    engine,
    neutral_frame,
    channels,
    cutoff,
    robust,
    sparsity,
    refine=0,
    fov=None,
    focal=None,
    markers_out=None,
):
    """Bake the rig, place the layout, pick the channels, solve (``refine`` Gauss-Newton steps against
    the engine); progress bars per stage; the placed markers to ``markers_out`` when given."""
    from mimetic.capture.expression import resolve_channels
    from mimetic.capture.markers import layout_for, marker_set, save_marker_set
    from mimetic.capture.performance import solve_performance
    from mimetic.engines import make_engine
    from mimetic.engines.bake import bake

    _capture_channels(channels, loaded)
    deformer = make_engine(loaded, engine)
    with _progress("bake") as progress:
        basis = bake(deformer, correctives=0, samples=2, progress=progress).basis
    layout = markers or layout_for(trajectories.names)
    with _progress("markers") as progress:
        progress(0, 1)
        placed = marker_set(loaded, layout)
        progress(1, 1)
    active = resolve_channels(loaded, basis, placed, channels, fps=trajectories.fps, cutoff_hz=cutoff or None)
    with _step_progress() as progress:
        performance = solve_performance(
            loaded,
            trajectories,
            basis=basis,
            markers=placed,
            neutral_frame=neutral_frame,
            active=active,
            cutoff_hz=cutoff or None,
            robust=robust,
            sparsity=sparsity,
            refine=refine,
            engine=deformer,
            fov_deg=fov,
            focal=focal,
            progress=progress,
        )
    if markers_out is not None:
        save_marker_set(performance.markers, loaded, markers_out, note=f"placed on {trajectories.source}")
    return performance


def _capture_outputs(
    loaded, performance, out: Path, report: Path | None, engine: str, size: int, edits: Path | None = None
) -> None:
    """The solved clip (under the edit layers of ``edits``, a clip JSON, when given) and its report."""
    from mimetic.atomic import atomic_write

    if edits is None:
        _write_clip(loaded, performance.clip, out, engine=engine, size=size)
    else:
        from mimetic.animate.clip import load_clip, save_clip
        from mimetic.capture.retarget import keep_edits

        edited = keep_edits(load_clip(edits), performance.clip)
        if out.suffix.lower() == ".json":
            save_clip(edited, out)
        else:
            clip = edited.sample(performance.clip.fps, channels=loaded)
            _write_clip(loaded, clip, out, engine=engine, size=size)
    summary = performance.report(loaded)
    if report is not None:
        with atomic_write(report, "w") as handle:
            handle.write(json.dumps(summary, indent=2) + "\n")
    stdout.print(
        f"wrote {out} ({summary['frames']} frames at {summary['fps']:g} fps, "
        f"{summary['channels_solved']} channels from {summary['markers']} {summary['layout']} markers; "
        f"marker RMS {summary['marker_rms_median']:.3g} {loaded.units or 'units'}, "
        f"{summary['flagged_frames']} frames flagged)"
    )


_MARKERS_HELP = (
    "Marker layout: paper, ibug68, mediapipe or a marker .json (default: from the point names). A file "
    "written by --markers-out holds one performer's markers, placed on an earlier take: not placed again."
)
_MARKERS_OUT_HELP = (
    "Also write the markers as placed on this performer (.json), for their next takes (--markers)."
)
_FOV_HELP = "Camera's vertical field of view in degrees (image landmarks; default: estimated from the take)."
_FOCAL_HELP = "Camera's focal length in pixels (image landmarks; instead of --fov)."
_CHANNELS_HELP = (
    "Channels to solve: all (every channel the markers see but the gaze), determined (those the markers "
    "pin down at 1 mm noise) or a comma-separated list."
)


@command("solve", parent=capture_app)
def capture_solve(
    rig: Path = typer.Argument(..., metavar="RIG", help="The .mrig rig to solve on."),
    markers_file: Path = typer.Argument(
        ..., metavar="MARKERS", help="Trajectories: .c3d, .trc, mimetic .csv or an OpenFace .csv."
    ),
    out: Path = typer.Option(..., "-o", "--out", help="clip.json / .csv, or anim.mp4 / .glb / .usda."),
    markers: str | None = typer.Option(None, "--markers", help=_MARKERS_HELP),
    fps: float | None = typer.Option(None, "--fps", min=1e-3, help="Frame rate, when the file has none."),
    units: CaptureUnits | None = typer.Option(None, "--units", help="Units, when the file has none."),
    neutral_frame: int = typer.Option(0, "--neutral-frame", min=0, help="A frame with a neutral face."),
    channels: str = typer.Option("all", "--channels", help=_CHANNELS_HELP),
    cutoff: float = typer.Option(8.0, "--cutoff", min=0.0, help="Smoothing cutoff in Hz (0: none)."),
    robust: bool = typer.Option(True, "--robust/--no-robust", help="Reject spikes and unexplained markers."),
    sparsity: float = typer.Option(0.0, "--sparsity", min=0.0, help="L1 weight (activation units)."),
    refine: int = typer.Option(0, "--refine", min=0, max=5, help="Gauss-Newton steps against the engine."),
    edits: Path | None = typer.Option(
        None, "--edits", help="An edited clip JSON of an earlier solve: its edit layers go over this solve."
    ),
    report: Path | None = typer.Option(None, "--report", help="Also write the plausibility report (.json)."),
    markers_out: Path | None = typer.Option(None, "--markers-out", help=_MARKERS_OUT_HELP),
    fov: float | None = typer.Option(None, "--fov", min=1.0, max=170.0, help=_FOV_HELP),
    focal: float | None = typer.Option(None, "--focal", min=1.0, help=_FOCAL_HELP),
    size: int = typer.Option(512, "--size", min=64, max=2160, help="Video size in pixels (square)."),
    engine: EngineName = typer.Option(EngineName.wire, "--engine", help="Engine to solve against."),
) -> None:
    """Solve a marker or landmark capture into the rig's channel activations (head motion removed).

    The layout's markers are first moved to where this performer's are (from the neutral frame);
    --markers-out keeps that placement for the performer's next takes.

    Examples:

    \b
      mimetic capture solve head.mrig take1.c3d -o take1.json
      mimetic capture solve head.mrig openface.csv --fps 30 -o take.mp4 --report take.json
      mimetic capture solve head.mrig take1.trc --markers markers.json --channels determined -o take1.glb
      mimetic clip edit take1.json --key jaw_open@1.2=0.3 -o take1-edited.json
      mimetic capture solve head.mrig take1-fixed.c3d --edits take1-edited.json -o take1-edited.json
    """
    from mimetic.capture.formats import read_trajectories
    from mimetic.rig.format import load_rig

    _output(out, CAPTURE_OUTPUTS)
    if report is not None:
        _output(report, (".json",), "--report")
    if markers_out is not None:
        _output(markers_out, (".json",), "--markers-out")
    loaded = load_rig(rig)
    trajectories = read_trajectories(markers_file, fps=fps, units=units.value if units else None)
    performance = _solve_capture(
        loaded,
        trajectories,
        markers=markers,
        engine=engine.value,
        neutral_frame=neutral_frame,
        channels=channels,
        cutoff=cutoff,
        robust=robust,
        sparsity=sparsity,
        refine=refine,
        fov=fov,
        focal=focal,
        markers_out=markers_out,
    )
    _capture_outputs(loaded, performance, out, report, engine.value, size, edits)


@command("video", parent=capture_app)
def capture_video(
    rig: Path = typer.Argument(..., metavar="RIG", help="The .mrig rig to solve on."),
    video: Path = typer.Argument(..., metavar="VIDEO", help="A video of one face (MP4, MOV, …)."),
    out: Path = typer.Option(..., "-o", "--out", help="clip.json / .csv, or anim.mp4 / .glb / .usda."),
    landmarks_out: Path | None = typer.Option(
        None, "--landmarks-out", help="Also write the tracked landmarks (.csv or .trc)."
    ),
    max_frames: int | None = typer.Option(None, "--max-frames", min=1, help="Track only the first N frames."),
    neutral_frame: int = typer.Option(0, "--neutral-frame", min=0, help="A frame with a neutral face."),
    channels: str = typer.Option("all", "--channels", help=_CHANNELS_HELP),
    cutoff: float = typer.Option(8.0, "--cutoff", min=0.0, help="Smoothing cutoff in Hz (0: none)."),
    report: Path | None = typer.Option(None, "--report", help="Also write the plausibility report (.json)."),
    markers: str | None = typer.Option(
        None, "--markers", help="A marker .json placed on an earlier video of this face (--markers-out)."
    ),
    markers_out: Path | None = typer.Option(None, "--markers-out", help=_MARKERS_OUT_HELP),
    fov: float | None = typer.Option(None, "--fov", min=1.0, max=170.0, help=_FOV_HELP),
    focal: float | None = typer.Option(None, "--focal", min=1.0, help=_FOCAL_HELP),
    size: int = typer.Option(512, "--size", min=64, max=2160, help="Video size in pixels (square)."),
    engine: EngineName = typer.Option(EngineName.wire, "--engine", help="Engine to solve against."),
) -> None:
    """Track a face video with MediaPipe FaceMesh (extra [track]) and solve it into activations.

    The head's motion is taken out through a perspective camera (its field of view estimated from
    the take, or --fov / --focal); the landmarks are placed on the rig where this face's are.

    Examples:

    \b
      mimetic capture video head.mrig face.mp4 -o face.json
      mimetic capture video head.mrig face.mp4 -o face-on-head.mp4 --landmarks-out face.csv
    """
    from mimetic.capture.formats import write_trajectories
    from mimetic.capture.video import track_video
    from mimetic.rig.format import load_rig

    _output(out, CAPTURE_OUTPUTS)
    if report is not None:
        _output(report, (".json",), "--report")
    if landmarks_out is not None:
        _output(landmarks_out, (".csv", ".trc"), "--landmarks-out")
    if markers_out is not None:
        _output(markers_out, (".json",), "--markers-out")
    loaded = load_rig(rig)
    _capture_channels(channels, loaded)
    with _progress("track") as progress:
        trajectories = track_video(video, max_frames=max_frames, progress=progress)
    if landmarks_out is not None:
        write_trajectories(trajectories, landmarks_out)
    performance = _solve_capture(
        loaded,
        trajectories,
        markers=markers or "mediapipe",
        engine=engine.value,
        neutral_frame=neutral_frame,
        channels=channels,
        cutoff=cutoff,
        robust=True,
        sparsity=0.0,
        fov=fov,
        focal=focal,
        markers_out=markers_out,
    )
    _capture_outputs(loaded, performance, out, report, engine.value, size)


@command("retarget", parent=capture_app)
def capture_retarget(
    clip: Path = typer.Argument(..., metavar="CLIP", help="A solved clip (.json from `capture solve`)."),
    rig: Path = typer.Argument(..., metavar="RIG", help="The .mrig rig to play it on."),
    out: Path = typer.Option(
        ..., "-o", "--out", help="anim.mp4 / .glb / .usda, or the clip as .json / .csv."
    ),
    fps: float = typer.Option(30.0, "--fps", min=1e-3, max=240.0, help="Frames per second of the output."),
    size: int = typer.Option(512, "--size", min=64, max=2160, help="Video size in pixels (square)."),
    engine: EngineName = typer.Option(EngineName.wire, "--engine", help="Deformation engine."),
) -> None:
    """Play a solved clip on another rigged head (channels matched by name, clipped to its ranges).

    Examples:

    \b
      mimetic capture retarget take1.json other.mrig -o take1-other.mp4
      mimetic capture retarget take1.json other.mrig --fps 60 -o take1-other.glb
    """
    from mimetic.animate.clip import load_clip
    from mimetic.capture.retarget import retarget
    from mimetic.rig.format import load_rig

    _output(out, CAPTURE_OUTPUTS)
    loaded = load_rig(rig)
    played = retarget(load_clip(clip).sample(fps), loaded)
    _write_clip(loaded, played, out, engine=engine.value, size=size)
    stdout.print(f"wrote {out} ({played.n_frames} frames at {fps:g} fps)")


def _write_clip(rig, clip, out: Path, *, engine: str, size: int, audio: Path | None = None) -> None:
    """A clip as out's suffix says: a rendered MP4 (with ``audio``), a clip .json or .csv, or an animated
    GLB / USD scene."""
    from mimetic.animate.clip import from_clip, save_clip, save_csv

    suffix = out.suffix.lower()
    if suffix == ".mp4":
        from mimetic.view.video import render_clip

        with _progress("video") as progress:
            render_clip(rig, clip, out, engine=engine, size=size, audio=audio, progress=progress)
    elif suffix == ".json":
        save_clip(from_clip(clip), out)
    elif suffix == ".csv":
        save_csv(clip, out)
    else:
        with _progress("bake") as progress:
            targets = _muscle_targets(rig, engine, progress)
        _write_scene(rig, out, targets, clip)


def _muscle_targets(rig, engine: str, progress) -> dict:
    """One morph target per muscle channel (the baked basis), for GLB and USD export."""
    from mimetic.export.gltf import morph_targets

    progress(0, 1)
    targets = morph_targets(rig, engine)
    progress(1, 1)
    return targets


@command("export")
def export_command(
    rig: Path = typer.Argument(..., metavar="RIG", help="The .mrig rig to export."),
    out: Path = typer.Option(..., "-o", "--out", help="The .glb (or .usda/.usdc, UsdSkel) file to write."),
    arkit: bool = typer.Option(
        False, "--arkit", help="Morph targets are the 52 ARKit blendshapes (else one per muscle)."
    ),
    obj_dir: Path | None = typer.Option(
        None,
        "--obj-dir",
        help="Also write each morph target as a posed OBJ (your own frame) into this folder.",
    ),
    engine: EngineName = typer.Option(EngineName.wire, "--engine", help="Deformation engine."),
) -> None:
    """Export a rig as GLB or USD with named morph targets and its skeleton (ARKit-52 with --arkit).

    Examples:

    \b
      mimetic export head.mrig -o head.glb
      mimetic export head.mrig --arkit -o head_arkit.usdc --obj-dir arkit_shapes/
    """
    from mimetic.rig.format import load_rig

    _output(out, SCENE_OUTPUTS)
    if obj_dir is not None:
        _output_folder(obj_dir)
    loaded = load_rig(rig)
    with _progress("bake") as progress:
        if arkit:
            from mimetic.export.arkit import arkit_shapes

            progress(0, 1)
            targets = arkit_shapes(loaded, engine=engine.value)
            progress(1, 1)
        else:
            targets = _muscle_targets(loaded, engine.value, progress)
    written = [_write_scene(loaded, out, targets)]
    if obj_dir is not None:
        from mimetic.mesh.io import save_mesh

        obj_dir.mkdir(exist_ok=True)
        rest = loaded.mesh.vertices
        for name, delta in targets.items():  # in the user's own frame, on top of their mesh at rest
            written.append(save_mesh(loaded.source_mesh(rest + delta), obj_dir / f"{name}.obj"))
    stdout.print(f"wrote {out} ({len(targets)} morph targets)")
    if obj_dir is not None:
        stdout.print(f"wrote {len(written) - 1} OBJs to {obj_dir}")


LISTS = ("expressions", "channels", "muscles", "controls", "facs", "arkit")
ListName = Enum("ListName", {n: n for n in LISTS}, type=str)


@command("list")
def list_command(
    what: ListName = typer.Argument(
        ..., metavar="WHAT", help="expressions, channels, muscles, controls, facs or arkit."
    ),
    rig: Path | None = typer.Argument(
        None, metavar="RIG", help="A .mrig rig (channels and muscles; default: the built-in head's rig)."
    ),
    as_json: bool = typer.Option(False, "--json", help="Print the rows as JSON."),
) -> None:
    """List the names a command takes: expressions, channels (with ranges and units), muscles,
    descriptive controls, FACS action units or ARKit-52 shapes.

    Examples:

    \b
      mimetic list expressions
      mimetic list channels my_head.mrig --json
    """
    columns, rows = _list_rows(what.value, rig)
    if as_json:
        stdout.print_json(json.dumps([dict(zip(columns, row, strict=True)) for row in rows]))
        return
    table = Table(*columns, title=f"{len(rows)} {what.value}", title_justify="left")
    for row in rows:
        table.add_row(*(str(c) for c in row))
    stdout.print(table)


def _list_rows(what: str, rig_file: Path | None) -> tuple[tuple[str, ...], list[tuple]]:
    if what == "expressions":
        from mimetic.animate.expressions import load_library

        library = load_library()
        return ("name", "facs", "description"), [
            (n, library[n].facs, library[n].description) for n in library.names
        ]
    if what == "controls":
        from mimetic.animate.controls import descriptive_controls

        return ("name", "muscle", "paired", "description"), [
            (c.name, c.muscle, "L/R" if c.paired else "-", c.description) for c in descriptive_controls()
        ]
    if what == "facs":
        from mimetic.animate.facs import action_units

        return ("au", "name", "sides", "status", "note"), [
            (f"AU{u.number}", u.name, u.sides, u.status, u.note) for u in action_units().values()
        ]
    if what == "arkit":
        from mimetic.animate.arkit import arkit_table

        return ("name", "status", "description"), [
            (name, s.status, s.description) for name, s in arkit_table().items()
        ]
    rig = _rig_or_default(rig_file)
    if what == "channels":
        return ("name", "minimum", "maximum", "default", "unit", "group"), [
            (c.name, c.minimum, c.maximum, c.default, c.unit, c.group) for c in rig.channels
        ]
    return ("name", "kind", "side", "region"), [(m.name, m.kind, m.side, m.region or "") for m in rig.muscles]


def _rig_or_default(rig_file: Path | None):
    if rig_file is not None:
        from mimetic.rig.format import load_rig

        return load_rig(rig_file)
    from mimetic.head.model import make_head
    from mimetic.rig.recipe import build_rig

    return build_rig(make_head(resolution=1_500))


@command()
def view(
    source: Path = typer.Argument(
        ..., metavar="RIG", help="A .mrig rig, or a mesh (.obj .ply .stl .glb) to pick landmarks on."
    ),
    port: int = typer.Option(8080, "--port", min=1, max=65535, help="The port to serve the page on."),
    host: str = typer.Option(
        "127.0.0.1", "--host", help="The address to listen on (0.0.0.0 shares the page on your network)."
    ),
    engine: EngineName = typer.Option(EngineName.wire, "--engine", help="The engine shown first."),
    clip: Path | None = typer.Option(None, "--clip", help="A clip JSON to load on the timeline."),
    audio: Path | None = typer.Option(None, "--audio", help="The clip's sound (WAV), played with it."),
    landmarks: Path | None = typer.Option(
        None,
        "--landmarks",
        help="Where picked landmarks are saved (default: beside SOURCE).",
    ),
    capture: Path | None = typer.Option(
        None,
        "--capture",
        metavar="VIDEO",
        help="Play a video's face on the rig as it arrives, at the video's pace: the first 0.5 s "
        "calibrate (hold a neutral face). A camera device such as /dev/video0 is passed on the same "
        "way (untested: no camera was at hand). Needs the [track] extra.",
    ),
) -> None:
    """Open RIG in a local web page: sliders, expressions, keys and playback, landmark picking.

    Needs the [view] extra (pip install 'mimetic[view]'). Stop it with Ctrl-C.

    Examples:

    \b
      mimetic view head.mrig
      mimetic view head.mrig --clip speech.clip.json --audio speech.wav --port 8081
      mimetic view scan.obj --landmarks scan.json
      mimetic view head.mrig --capture take.mp4
    """
    import time

    from mimetic.view.web import PREPARE_NOTE, check_capture, start

    for given, option in ((clip, "--clip"), (audio, "--audio")):
        if given is not None and not given.is_file():
            raise MimeticError(f"{option} {given}: no such file")
    if capture is not None:
        check_capture(source, capture)
    if engine.value in PREPARE_NOTE:
        stderr.print(f"preparing the {engine.value} engine: {PREPARE_NOTE[engine.value]}, once")
    viewer = start(
        source,
        host=host,
        port=port,
        engine=engine.value,
        clip=clip,
        audio=audio,
        landmarks_out=landmarks,
        capture=capture,
    )
    if viewer.error:
        stderr.print(Text.assemble(("error: ", "bold red"), viewer.error))
        stderr.print("the page shows the error too; Ctrl-C to stop")
    shown = "localhost" if host in ("127.0.0.1", "::1") else host
    stdout.print(f"mimetic view: http://{shown}:{viewer.server.get_port()}  (Ctrl-C to stop)")
    told = False  # the capture's end was said
    try:
        while True:
            time.sleep(0.25 if viewer.live is not None else 1.0)
            status = viewer.live.status if viewer.live is not None else None
            if status is not None and status.done and not told:
                told = True
                if status.state == "failed":
                    stderr.print(Text.assemble(("error: ", "bold red"), status.error))
                    stderr.print("the page shows the error too; Ctrl-C to stop")
                else:
                    stderr.print(f"live capture {status.text()}")
    finally:
        viewer.stop()


@command()
def demo(
    out: Path = typer.Option(Path("mimetic-demo"), "-o", "--out", help="Folder for the demo outputs."),
    resolution: int = typer.Option(
        10_000, "--resolution", min=1_500, max=250_000, help="Approximate skin vertex count."
    ),
) -> None:
    """Generate the default head and 8 random heads, rig, pose and animate them, and write meshes,
    rigs, sheets, an animated GLB, an MP4 and the ARKit-52 bake.

    Examples:

    \b
      mimetic demo
      mimetic demo -o demo-small --resolution 4000
    """
    from mimetic.demo import run_demo

    _output_folder(out)
    with _progress("demo") as progress:
        result = run_demo(out, resolution=resolution, progress=progress)
    table = Table("file", "size", title=f"mimetic demo → {result.out_dir}")
    for path in result.files:
        table.add_row(str(path), f"{path.stat().st_size / 1024:,.0f} KB")
    stdout.print(table)
    for note in result.notes:
        stdout.print(f"note: {note}")
    stdout.print(f"play with it: mimetic view {result.out_dir / 'default.mrig'}")


# --------------------------------------------------------------------------- batch

batch_app = typer.Typer(
    help="Many heads and clips at once, on a local or multi-node Dask cluster (extra [batch]).",
    no_args_is_help=True,
    rich_markup_mode=None,
)
app.add_typer(batch_app, name="batch")
BatchClipFormat = Enum("BatchClipFormat", {f: f for f in ("glb", "usda", "usdc", "mp4")}, type=str)
BatchSpeakFormat = Enum(
    "BatchSpeakFormat", {f: f for f in ("glb", "usda", "usdc", "mp4", "json", "csv")}, type=str
)
BatchCaptureFormat = Enum(
    "BatchCaptureFormat", {f: f for f in ("json", "csv", "glb", "usda", "mp4")}, type=str
)
BatchImageFormat = Enum("BatchImageFormat", {f: f for f in ("png", "jpg", "webp")}, type=str)

_BATCH_OUT = typer.Option(..., "-o", "--out", help="Output folder (created if missing).")
_BATCH_MANIFEST = typer.Option(
    None, "--manifest", help="A CSV or JSON file of more items: input, output and options per row."
)
_BATCH_WORKERS = typer.Option(
    None, "--workers", min=1, help="Local worker processes, one thread each (default: one per core)."
)
_BATCH_SCHEDULER = typer.Option(
    None, "--scheduler", help="Run on an existing Dask cluster instead, e.g. tcp://HOST:8786."
)
_BATCH_RETRIES = typer.Option(
    0, "--retries", min=0, help="Run an item that fails unexpectedly up to N more times (not bad input)."
)
_BATCH_RESUME = typer.Option(
    True, "--resume/--no-resume", help="Skip the items an earlier run into OUTDIR finished (default)."
)
_BATCH_JSON = typer.Option(False, "--json", help="Print the manifest of results as JSON.")


def _batch(kind: str, inputs: list[str] | None, out: Path, manifest: Path | None, workers: int | None,
           scheduler: str | None, retries: int, resume: bool, as_json: bool, **options) -> None:  # fmt: skip
    """Run a batch with a progress bar (counts, ETA; failures as they happen), print its summary, exit 1
    when any item failed."""
    from mimetic.batch import run_batch

    if workers is not None and scheduler is not None:
        raise typer.BadParameter("give --workers or --scheduler, not both", param_hint="'--workers'")
    if not inputs and manifest is None:
        raise typer.BadParameter("give input files (paths or quoted globs) or --manifest")
    _output_folder(out)
    counts = dict.fromkeys(("ok", "failed", "skipped"), 0)
    with _bar() as bar:
        task = bar.add_task(kind, total=None)

        def describe() -> str:
            return f"{kind}: " + ", ".join(f"{n} {status}" for status, n in counts.items() if n) or kind

        def progress(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total, description=describe())

        def on_result(row) -> None:
            counts[row.status] += 1
            if row.status == "failed":
                bar.console.print(Text.assemble(("failed ", "red"), f"{row.item}: {row.error}"))
            bar.update(task, description=describe())

        result = run_batch(
            kind,
            inputs or [],
            out,
            manifest=manifest,
            client=scheduler,
            workers=workers,
            retries=retries,
            resume=resume,
            progress=progress,
            on_result=on_result,
            **options,
        )
    if as_json:
        stdout.print_json(json.dumps(result.as_dict()))
    else:
        for row in result.failed:
            stdout.print(f"failed  {row.item}: {row.error}", markup=False)
        done = result.counts()
        warned = sum(bool(row.warnings) for row in result.rows)
        stdout.print(
            f"{kind}: {done['ok']} ok, {done['failed']} failed, {done['skipped']} skipped (finished before) "
            f"of {len(result.rows)} in {result.seconds:.1f} s on {result.executor}"
            + (f"; {warned} with warnings (see the manifest)" if warned else ""),
            markup=False,
        )
        stdout.print(f"wrote {result.json_path} and {result.csv_path.name}", markup=False)
    if result.failed:
        raise typer.Exit(1)


@command("rig", parent=batch_app)
def batch_rig(
    heads: list[str] | None = typer.Argument(
        None, metavar="HEADS...", help="Head meshes: paths or quoted globs ('scans/*.obj')."
    ),
    out: Path = _BATCH_OUT,
    landmarks: str | None = typer.Option(
        None, "--landmarks", help="A landmark file for every head, or one per head: '{dir}/{stem}.json'."
    ),
    auto_landmarks: bool = typer.Option(
        False, "--auto-landmarks", help="Find landmarks with MediaPipe (the default without --landmarks)."
    ),
    units: Units | None = typer.Option(None, "--units", help="The meshes' units if the files do not say."),
    force: bool = typer.Option(False, "--force", help="Write a rig even if its fit looks wrong."),
    resolution: int = typer.Option(
        10_000, "--resolution", min=1_500, max=250_000, help="Skin vertex count of the reference head."
    ),
    picture: bool = typer.Option(True, "--picture/--no-picture", help="Write NAME.fit.png for each head."),
    manifest: Path | None = _BATCH_MANIFEST,
    workers: int | None = _BATCH_WORKERS,
    scheduler: str | None = _BATCH_SCHEDULER,
    retries: int = _BATCH_RETRIES,
    resume: bool = _BATCH_RESUME,
    as_json: bool = _BATCH_JSON,
) -> None:
    """Rig many heads: NAME.mrig, NAME.fit.json and NAME.fit.png in OUTDIR per head, as `mimetic rig`.

    Examples:

    \b
      mimetic batch rig 'scans/*.obj' --landmarks '{dir}/{stem}.json' -o rigs/
      mimetic batch rig --manifest heads.csv -o rigs/ --scheduler tcp://10.0.0.1:8786 --retries 2
    """
    if landmarks is not None and auto_landmarks:
        raise typer.BadParameter("give --landmarks or --auto-landmarks, not both", param_hint="'--landmarks'")
    _batch("rig", heads, out, manifest, workers, scheduler, retries, resume, as_json,
           landmarks=landmarks, auto_landmarks=auto_landmarks, units=units.value if units else None,
           force=force, resolution=resolution, picture=picture)  # fmt: skip


@command("animate", parent=batch_app)
def batch_animate(
    rigs: list[str] | None = typer.Argument(
        None, metavar="RIGS...", help=".mrig rigs: paths or quoted globs."
    ),
    out: Path = _BATCH_OUT,
    clip: str | None = typer.Option(None, "--clip", help="The clip JSON to play on every rig."),
    format_: BatchClipFormat = typer.Option(BatchClipFormat.glb, "--format", help="What to write per rig."),
    fps: float = typer.Option(30.0, "--fps", min=1e-3, max=240.0, help="Frames per second of the output."),
    size: int = typer.Option(512, "--size", min=64, max=2160, help="Video size in pixels (square)."),
    audio: str | None = typer.Option(None, "--audio", help="A sound track for the videos (WAV, …)."),
    engine: EngineName = typer.Option(EngineName.wire, "--engine", help="Deformation engine."),
    manifest: Path | None = _BATCH_MANIFEST,
    workers: int | None = _BATCH_WORKERS,
    scheduler: str | None = _BATCH_SCHEDULER,
    retries: int = _BATCH_RETRIES,
    resume: bool = _BATCH_RESUME,
    as_json: bool = _BATCH_JSON,
) -> None:
    """Play a clip on many rigs: NAME.glb (or .usda, .usdc, .mp4) in OUTDIR per rig, as `mimetic animate`.

    Examples:

    \b
      mimetic batch animate 'rigs/*.mrig' --clip hello.json -o anims/
      mimetic batch animate 'rigs/*.mrig' --clip hello.json --format mp4 --size 256 -o videos/
    """
    _batch("animate", rigs, out, manifest, workers, scheduler, retries, resume, as_json,
           clip=clip, format=format_.value, fps=fps, size=size, audio=audio, engine=engine.value)  # fmt: skip


@command("render", parent=batch_app)
def batch_render(
    files: list[str] | None = typer.Argument(
        None, metavar="FILES...", help="Meshes or .mrig rigs: paths or quoted globs."
    ),
    out: Path = _BATCH_OUT,
    format_: BatchImageFormat = typer.Option(BatchImageFormat.png, "--format", help="Image type."),
    view: SheetView = typer.Option(SheetView.all, "--view", help="One view, or all three in a sheet."),
    size: int = typer.Option(512, "--size", min=64, max=4096, help="Image size in pixels (per view)."),
    wireframe: bool = typer.Option(False, "--wireframe", help="Draw the triangle edges."),
    muscles: bool = typer.Option(True, "--muscles/--no-muscles", help="Draw a rig's muscles."),
    units: Units | None = typer.Option(None, "--units", help="The meshes' units if the files do not say."),
    manifest: Path | None = _BATCH_MANIFEST,
    workers: int | None = _BATCH_WORKERS,
    scheduler: str | None = _BATCH_SCHEDULER,
    retries: int = _BATCH_RETRIES,
    resume: bool = _BATCH_RESUME,
    as_json: bool = _BATCH_JSON,
) -> None:
    """Render many meshes or rigs: NAME.png in OUTDIR per file, as `mimetic render`.

    Examples:

    \b
      mimetic batch render 'rigs/*.mrig' -o pictures/
      mimetic batch render 'scans/*.obj' --view front --size 256 --format jpg -o thumbs/
    """
    _batch("render", files, out, manifest, workers, scheduler, retries, resume, as_json,
           format=format_.value, view=view.value, size=size, wireframe=wireframe, muscles=muscles,
           units=units.value if units else None)  # fmt: skip


@command("speak", parent=batch_app)
def batch_speak(
    rigs: list[str] | None = typer.Argument(
        None, metavar="RIGS...", help=".mrig rigs: paths or quoted globs."
    ),
    out: Path = _BATCH_OUT,
    text: str | None = typer.Option(None, "--text", help="What every head says (or a 'text' column)."),
    text_file: str | None = typer.Option(None, "--text-file", help="Read the text from a file."),
    timings: str | None = typer.Option(None, "--timings", help="Phone timings (TextGrid, CSV or JSON)."),
    audio: str | None = typer.Option(None, "--audio", help="A recording (WAV) of the text."),
    synthesize: bool = typer.Option(False, "--synthesize", help="Speak the text with espeak-ng."),
    language: Language = typer.Option(Language.en, "--language", help="en or nso (Northern Sotho)."),
    visemes: str | None = typer.Option(None, "--visemes", help="Viseme map: en, nso, mpeg4 or a .json."),
    format_: BatchSpeakFormat = typer.Option(BatchSpeakFormat.glb, "--format", help="What to write per rig."),
    fps: float = typer.Option(30.0, "--fps", min=1.0, max=240.0, help="Frames per second."),
    rate: float = typer.Option(1.0, "--rate", min=0.2, max=5.0, help="Speaking rate for text alone."),
    jaw: float = typer.Option(1.0, "--jaw", min=0.0, max=2.0, help="Jaw intensity (JALI dial)."),
    lips: float = typer.Option(1.0, "--lips", min=0.0, max=2.0, help="Lip intensity (JALI dial)."),
    eyes: bool = typer.Option(True, "--eyes/--no-eyes", help="Add blinks and small gaze saccades."),
    seed: int = typer.Option(0, "--seed", help="Seed of the blinks and saccades."),
    baseline: bool = typer.Option(False, "--baseline", help="Linear interpolation between visemes."),
    size: int = typer.Option(512, "--size", min=64, max=2160, help="Video size in pixels (square)."),
    engine: EngineName = typer.Option(EngineName.wire, "--engine", help="Deformation engine."),
    manifest: Path | None = _BATCH_MANIFEST,
    workers: int | None = _BATCH_WORKERS,
    scheduler: str | None = _BATCH_SCHEDULER,
    retries: int = _BATCH_RETRIES,
    resume: bool = _BATCH_RESUME,
    as_json: bool = _BATCH_JSON,
) -> None:
    """Lip-sync many rigs: NAME.glb (or .mp4, .usda, .json, .csv) in OUTDIR per rig, as `mimetic speak`.

    Examples:

    \b
      mimetic batch speak 'rigs/*.mrig' --text "Hello there" -o talk/
      mimetic batch speak --manifest lines.csv --format mp4 -o talk/   # input,text per row
    """
    _batch("speak", rigs, out, manifest, workers, scheduler, retries, resume, as_json,
           text=text, text_file=text_file, timings=timings, audio=audio, synthesize=synthesize,
           language=language.value, visemes=visemes, format=format_.value, fps=fps, rate=rate, jaw=jaw,
           lips=lips, eyes=eyes, seed=seed, baseline=baseline, size=size, engine=engine.value)  # fmt: skip


@command("capture", parent=batch_app)
def batch_capture(
    rig: str = typer.Argument(..., metavar="RIG", help="The .mrig rig to solve every take on."),
    takes: list[str] | None = typer.Argument(
        None, metavar="TAKES...", help="Trajectories (.c3d .trc .csv): paths or quoted globs."
    ),
    out: Path = _BATCH_OUT,
    format_: BatchCaptureFormat = typer.Option(BatchCaptureFormat.json, "--format", help="Per take."),
    markers: str | None = typer.Option(None, "--markers", help=_MARKERS_HELP),
    fps: float | None = typer.Option(None, "--fps", min=1e-3, help="Frame rate, when a file has none."),
    units: CaptureUnits | None = typer.Option(None, "--units", help="Units, when a file has none."),
    neutral_frame: int = typer.Option(0, "--neutral-frame", min=0, help="A frame with a neutral face."),
    channels: str = typer.Option("all", "--channels", help=_CHANNELS_HELP),
    cutoff: float = typer.Option(8.0, "--cutoff", min=0.0, help="Smoothing cutoff in Hz (0: none)."),
    robust: bool = typer.Option(True, "--robust/--no-robust", help="Reject spikes and unexplained markers."),
    sparsity: float = typer.Option(0.0, "--sparsity", min=0.0, help="L1 weight (activation units)."),
    refine: int = typer.Option(0, "--refine", min=0, max=5, help="Gauss-Newton steps against the engine."),
    report: bool = typer.Option(True, "--report/--no-report", help="Write NAME.report.json per take."),
    size: int = typer.Option(512, "--size", min=64, max=2160, help="Video size in pixels (square)."),
    engine: EngineName = typer.Option(EngineName.wire, "--engine", help="Engine to solve against."),
    manifest: Path | None = _BATCH_MANIFEST,
    workers: int | None = _BATCH_WORKERS,
    scheduler: str | None = _BATCH_SCHEDULER,
    retries: int = _BATCH_RETRIES,
    resume: bool = _BATCH_RESUME,
    as_json: bool = _BATCH_JSON,
) -> None:
    """Solve many takes on one rig: NAME.json (the clip) and NAME.report.json in OUTDIR per take, as
    `mimetic capture solve`; each worker bakes the rig once.

    Examples:

    \b
      mimetic batch capture head.mrig 'takes/*.c3d' -o clips/
      mimetic batch capture head.mrig 'openface/*.csv' --fps 30 --channels determined -o clips/
    """
    _batch("capture", takes, out, manifest, workers, scheduler, retries, resume, as_json,
           rig=rig, format=format_.value, markers=markers, fps=fps, units=units.value if units else None,
           neutral_frame=neutral_frame, channels=channels, cutoff=cutoff, robust=robust, sparsity=sparsity,
           refine=refine, report=report, size=size, engine=engine.value)  # fmt: skip
