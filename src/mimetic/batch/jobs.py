"""The five batch jobs, each what its single-file command does, and ``execute``: one item on a worker.

=========  ==========================  =========================================================
kind       input → outputs             the same as
=========  ==========================  =========================================================
rig        head mesh → NAME.mrig,      ``mimetic rig HEAD -o NAME.mrig`` (fit report and picture
           NAME.fit.json, .fit.png     beside it); residual: mean surface residual, % of the
                                       head diagonal
animate    rig → NAME.glb|usda|mp4     ``mimetic animate RIG --clip CLIP -o NAME.glb``
render     mesh or rig → NAME.png      ``mimetic render FILE -o NAME.png``
speak      rig → NAME.glb|mp4|json     ``mimetic speak RIG --text … -o NAME.glb``
capture    take → NAME.json,           ``mimetic capture solve RIG TAKE -o NAME.json --report
           NAME.report.json            NAME.report.json``; residual: median marker RMS, rig units
=========  ==========================  =========================================================

``execute`` runs on a worker process (Dask or a process pool). It imports the library lazily,
writes the item's outputs (each atomically, by the library's writers), then its completion record,
and returns an ``Outcome``. Bad input (a ``MimeticError``) is a verdict, returned as a failed
outcome and never retried; anything else is raised again as ``ItemFailed`` with its one-line
message, so that Dask's ``retries=`` can try the item again (a killed worker, a file server that
hiccuped).
"""

from __future__ import annotations

import functools
import glob
import json
import logging
import os
import tempfile
import time
import warnings
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path

from mimetic.batch.items import Item, Option
from mimetic.errors import MimeticError

log = logging.getLogger(__name__)

WORKER_THREADS = {
    "NUMBA_NUM_THREADS": "1",
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
}
"""One thread per worker process: the jobs are CPU-bound numpy and numba, so N single-threaded
processes on N cores beat N processes whose BLAS and numba pools each try to use every core."""

ENGINES = ("wire", "vector", "tissue", "fem")
UNITS = ("mm", "cm", "dm", "m", "in")
CAPTURE_UNITS = ("mm", "cm", "m", "px")
VIEWS = ("front", "three_quarter", "profile", "all")


@dataclass(frozen=True)
class Outcome:
    """What a worker reports for one item.

    Attributes
    ----------
    status : {"ok", "failed"}
    seconds : float
        Wall time of the job on the worker.
    error : str
        One line ("" when ok): a ``MimeticError``'s message, else ``TypeName: message``.
    residual : float or None
        The job's fit residual (rig, capture), else None.
    warnings : tuple of str
        The warnings the job raised, one line each.
    """

    status: str
    seconds: float
    error: str = ""
    residual: float | None = None
    warnings: tuple[str, ...] = ()


class ItemFailed(Exception):
    """An unexpected failure of one item, raised on the worker (so Dask may retry it): ``args`` are the
    one-line message and the seconds the attempt took."""

    def __init__(self, message: str, seconds: float) -> None:
        super().__init__(message, seconds)
        self.message, self.seconds = message, seconds

    def __str__(self) -> str:
        return self.message


def one_line(error: BaseException) -> str:
    """An error as one line: a ``MimeticError``'s message as it is, anything else ``TypeName: message``
    (an ``ItemFailed`` already is one)."""
    if isinstance(error, ItemFailed):
        return error.message
    text = " ".join(str(error).split())
    if isinstance(error, MimeticError):
        return text
    return f"{type(error).__name__}: {text}" if text else type(error).__name__


# --------------------------------------------------------------------------- running one item


def execute(item: Item) -> Outcome:
    """Run ``item``'s job, write its completion record, return its outcome (on a worker).

    Raises
    ------
    ItemFailed
        Anything but a ``MimeticError`` went wrong (retried when the batch allows it).
    """
    start = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            for output in item.outputs:
                _remove_stale_temporaries(Path(output))
                Path(output).parent.mkdir(parents=True, exist_ok=True)
            residual = JOBS[item.kind].run(item)
            outcome = Outcome("ok", time.perf_counter() - start, "", residual, _lines(caught))
            write_record(item, outcome)
        except MimeticError as error:
            return Outcome("failed", time.perf_counter() - start, one_line(error), None, _lines(caught))
        except Exception as error:
            raise ItemFailed(one_line(error), time.perf_counter() - start) from None
    return outcome


def _lines(caught: list[warnings.WarningMessage]) -> tuple[str, ...]:
    """Distinct warning messages, one line each, in order."""
    return tuple(dict.fromkeys(" ".join(str(w.message).split()) for w in caught))


def _remove_stale_temporaries(output: Path) -> None:
    """Delete the temporary files an interrupted writer left beside ``output`` (``mimetic.atomic``
    names them ``.NAME.XXXX.tmp``): they never count as outputs, and are only litter."""
    for stale in output.parent.glob(f".{glob.escape(output.name)}.*.tmp*"):
        try:
            stale.unlink()
        except OSError:
            pass


def write_record(item: Item, outcome: Outcome) -> Path:
    """The item's completion record (JSON, atomically), written after all its outputs: their paths
    relative to OUTDIR and sizes, the key of the input and options, seconds, residual, warnings."""
    from mimetic import __version__
    from mimetic.atomic import atomic_write

    out_dir = Path(item.out_dir)
    record = {
        "item": item.name,
        "kind": item.kind,
        "key": item.key,
        "input": item.input,
        "outputs": [
            {"path": Path(p).relative_to(out_dir).as_posix(), "size": os.path.getsize(p)}
            for p in item.outputs
        ],
        "seconds": round(outcome.seconds, 4),
        "residual": outcome.residual,
        "warnings": list(outcome.warnings),
        "mimetic": __version__,
    }
    item.record.parent.mkdir(parents=True, exist_ok=True)
    with atomic_write(item.record, "w") as handle:
        handle.write(json.dumps(record, indent=1) + "\n")
    return item.record


def init_worker() -> None:
    """Process-pool initializer: one thread per worker (``WORKER_THREADS``), set before numpy and numba
    load and, where they already have, through threadpoolctl."""
    for name, value in WORKER_THREADS.items():
        os.environ.setdefault(name, value)
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)


# --------------------------------------------------------------------------- the jobs


def _rig(item: Item) -> float:
    from mimetic.fit.pipeline import rig_mesh
    from mimetic.rig.format import save_rig

    o = item.options
    result = rig_mesh(
        item.input, o["landmarks"], units=o["units"], resolution=o["resolution"], force=o["force"]
    )
    save_rig(result.rig, item.outputs[0])
    result.report.save(item.outputs[1])
    if o["picture"]:
        from mimetic.view import save_image
        from mimetic.view.fitreport import fit_report_image

        save_image(fit_report_image(result), item.outputs[2])
    return float(result.report.mean_pct)


def _animate(item: Item) -> None:
    from mimetic.animate.clip import load_clip
    from mimetic.rig.format import load_rig

    o = item.options
    loaded = load_rig(item.input)
    sampled = load_clip(o["clip"]).sample(o["fps"], channels=loaded)
    _write_clip(loaded, sampled, Path(item.outputs[0]), engine=o["engine"], size=o["size"], audio=o["audio"])


def _render(item: Item) -> None:
    from mimetic.render import VIEWS as RENDER_VIEWS
    from mimetic.render import render as render_mesh
    from mimetic.view import contact_sheet, save_image

    o = item.options
    views = list(RENDER_VIEWS) if o["view"] == "all" else [o["view"]]
    size, wireframe = o["size"], o["wireframe"]
    if item.input.lower().endswith(".mrig"):
        from mimetic.rig.format import load_rig
        from mimetic.view.muscles import render_rig

        rig = load_rig(item.input)
        tiles = [(v, render_rig(rig, v, size=size, muscles=o["muscles"], wireframe=wireframe)) for v in views]
    else:
        from mimetic.mesh.io import load_mesh

        mesh = load_mesh(item.input, units=o["units"])
        tiles = [(v, render_mesh(mesh, v, size=size, wireframe=wireframe)) for v in views]
    image = tiles[0][1] if len(tiles) == 1 else contact_sheet(tiles, columns=len(tiles))
    save_image(image, item.outputs[0])


def _speak(item: Item) -> None:
    from mimetic.rig.format import load_rig
    from mimetic.speech.lipsync import lip_sync
    from mimetic.speech.visemes import BUILT_IN, load_viseme_map

    o = item.options
    text = o["text"]
    if o["text_file"] is not None:
        text = Path(o["text_file"]).read_text(encoding="utf-8")
    loaded = load_rig(item.input)
    visemes = o["visemes"]
    if visemes is not None and visemes not in BUILT_IN:
        visemes = load_viseme_map(visemes, channels=loaded)
    with tempfile.TemporaryDirectory() as scratch:
        speech = lip_sync(
            loaded,
            text=text,
            timings=o["timings"],
            audio=o["audio"],
            synthesize_to=Path(scratch) / "synthesized.wav" if o["synthesize"] else None,
            language=o["language"],
            fps=o["fps"],
            visemes=visemes,
            jaw=o["jaw"],
            lips=o["lips"],
            rate=o["rate"],
            eyes=o["eyes"],
            seed=o["seed"],
            baseline=o["baseline"],
        )
        out = Path(item.outputs[0])
        _write_clip(loaded, speech.clip, out, engine=o["engine"], size=o["size"], audio=speech.audio)


def _capture(item: Item) -> float:
    from mimetic.atomic import atomic_write
    from mimetic.capture.expression import resolve_channels
    from mimetic.capture.formats import read_trajectories
    from mimetic.capture.markers import layout_for
    from mimetic.capture.performance import solve_performance

    o = item.options
    trajectories = read_trajectories(item.input, fps=o["fps"], units=o["units"])
    layout = o["markers"] or layout_for(trajectories.names)
    stat = os.stat(o["rig"])
    prepared = _prepared_rig(o["rig"], stat.st_size, stat.st_mtime_ns, o["engine"], layout)
    loaded, deformer, basis, placed = prepared
    cutoff = o["cutoff"] or None
    active = resolve_channels(loaded, basis, placed, o["channels"], fps=trajectories.fps, cutoff_hz=cutoff)
    performance = solve_performance(
        loaded,
        trajectories,
        basis=basis,
        markers=placed,
        neutral_frame=o["neutral_frame"],
        active=active,
        cutoff_hz=cutoff,
        robust=o["robust"],
        sparsity=o["sparsity"],
        refine=o["refine"],
        engine=deformer,
    )
    _write_clip(loaded, performance.clip, Path(item.outputs[0]), engine=o["engine"], size=o["size"])
    summary = performance.report(loaded)
    if o["report"]:
        with atomic_write(item.outputs[1], "w") as handle:
            handle.write(json.dumps(summary, indent=2) + "\n")
    return float(summary["marker_rms_median"])


@functools.lru_cache(maxsize=2)
def _prepared_rig(path: str, size: int, mtime_ns: int, engine: str, layout: str):
    """A rig loaded, its engine made, baked (as ``mimetic capture solve`` bakes it) and its markers
    placed: once per worker for every take solved on the same rig (the file's size and time key it)."""
    from mimetic.capture.markers import marker_set
    from mimetic.engines import make_engine
    from mimetic.engines.bake import bake
    from mimetic.rig.format import load_rig

    loaded = load_rig(path)
    deformer = make_engine(loaded, engine)
    basis = bake(deformer, correctives=0, samples=2).basis
    return loaded, deformer, basis, marker_set(loaded, layout)


def _write_clip(rig, clip, out: Path, *, engine: str, size: int, audio=None) -> None:
    """A clip as ``out``'s suffix says (as the CLI writes it): an MP4, a clip .json or .csv, or an
    animated GLB or USD scene with one morph target per muscle channel."""
    from mimetic.animate.clip import from_clip, save_clip, save_csv

    suffix = out.suffix.lower()
    if suffix == ".mp4":
        from mimetic.view.video import render_clip

        render_clip(rig, clip, out, engine=engine, size=size, audio=audio)
    elif suffix == ".json":
        save_clip(from_clip(clip), out)
    elif suffix == ".csv":
        save_csv(clip, out)
    else:
        from mimetic.export.gltf import export_glb, morph_targets

        targets = morph_targets(rig, engine)
        if suffix == ".glb":
            export_glb(rig, out, morph_targets=targets, clip=clip)
        else:
            from mimetic.export.usd import export_usd

            export_usd(rig, out, morph_targets=targets, clip=clip)


# --------------------------------------------------------------------------- the table of jobs


@dataclass(frozen=True)
class Job:
    """A kind of batch job: what runs, the options it takes, and the files it writes.

    Attributes
    ----------
    run : callable(Item) -> float or None
        Writes the item's outputs; returns its residual, if it has one.
    options : dict of str to Option
    formats : tuple of str
        Suffixes the main output may take (the ``format`` option picks one, else the first).
    extra : callable(options) -> tuple of str
        Suffixes of the other outputs, each replacing the main output's suffix ("NAME.fit.json").
    required : tuple of tuple of str
        Groups of options of which one must be set (e.g. a clip; text, a text file or timings).
    """

    run: Callable[[Item], float | None]
    options: Mapping[str, Option]
    formats: tuple[str, ...]
    extra: Callable[[Mapping], tuple[str, ...]] = lambda options: ()
    required: tuple[tuple[str, ...], ...] = ()


def _rig_extra(options: Mapping) -> tuple[str, ...]:
    return (".fit.json", ".fit.png") if options["picture"] else (".fit.json",)


def _capture_extra(options: Mapping) -> tuple[str, ...]:
    return (".report.json",) if options["report"] else ()


_CLIP_FORMATS = (".glb", ".usda", ".usdc", ".usd", ".mp4")

JOBS: dict[str, Job] = {
    "rig": Job(
        _rig,
        {
            "landmarks": Option("path"),
            "auto_landmarks": Option("bool", False),
            "units": Option("text", None, UNITS),
            "force": Option("bool", False),
            "resolution": Option("int", 10_000),
            "picture": Option("bool", True),
        },
        (".mrig",),
        _rig_extra,
    ),
    "animate": Job(
        _animate,
        {
            "clip": Option("path"),
            "format": Option("text", "glb", tuple(s[1:] for s in _CLIP_FORMATS)),
            "fps": Option("float", 30.0),
            "size": Option("int", 512),
            "audio": Option("path"),
            "engine": Option("text", "wire", ENGINES),
        },
        _CLIP_FORMATS,
        required=(("clip",),),
    ),
    "render": Job(
        _render,
        {
            "format": Option("text", "png", ("png", "jpg", "jpeg", "webp")),
            "view": Option("text", "all", VIEWS),
            "size": Option("int", 512),
            "wireframe": Option("bool", False),
            "muscles": Option("bool", True),
            "units": Option("text", None, UNITS),
        },
        (".png", ".jpg", ".jpeg", ".webp"),
    ),
    "speak": Job(
        _speak,
        {
            "text": Option("text"),
            "text_file": Option("path"),
            "timings": Option("path"),
            "audio": Option("path"),
            "synthesize": Option("bool", False),
            "language": Option("text", "en", ("en", "nso")),
            "visemes": Option("name_or_path", None, ("en", "nso", "mpeg4")),
            "format": Option("text", "glb", (*(s[1:] for s in _CLIP_FORMATS), "json", "csv")),
            "fps": Option("float", 30.0),
            "rate": Option("float", 1.0),
            "jaw": Option("float", 1.0),
            "lips": Option("float", 1.0),
            "eyes": Option("bool", True),
            "seed": Option("int", 0),
            "baseline": Option("bool", False),
            "size": Option("int", 512),
            "engine": Option("text", "wire", ENGINES),
        },
        (*_CLIP_FORMATS, ".json", ".csv"),
        required=(("text", "text_file", "timings"),),
    ),
    "capture": Job(
        _capture,
        {
            "rig": Option("path"),
            "format": Option("text", "json", ("json", "csv", *(s[1:] for s in _CLIP_FORMATS))),
            "markers": Option("name_or_path", None, ("paper", "ibug68", "mediapipe")),
            "fps": Option("float"),
            "units": Option("text", None, CAPTURE_UNITS),
            "neutral_frame": Option("int", 0),
            "channels": Option("text", "all"),
            "cutoff": Option("float", 8.0),
            "robust": Option("bool", True),
            "sparsity": Option("float", 0.0),
            "refine": Option("int", 0),
            "report": Option("bool", True),
            "size": Option("int", 512),
            "engine": Option("text", "wire", ENGINES),
        },
        (".json", ".csv", *_CLIP_FORMATS),
        _capture_extra,
        required=(("rig",),),
    ),
}
"""Every batch job by kind."""
