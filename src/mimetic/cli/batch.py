"""``mimetic batch KIND``: a task over many inputs on a local or multi-node Dask cluster."""

from __future__ import annotations

import inspect
import json
from pathlib import Path

import typer
from rich.text import Text

from mimetic.cli.app import _guarded, annotation, cli_words, group, stderr, stdout, typer_option
from mimetic.errors import MimeticError

batch_app = group(
    "batch", "Many heads and clips at once, on a local or multi-node Dask cluster (extra [batch])."
)

RUNNER = {
    "manifest": (
        Path | None,
        typer.Option(
            None, "--manifest", help="A CSV or JSON file of more items: input, output and options per row."
        ),
    ),
    "workers": (
        int | None,
        typer.Option(
            None, "--workers", min=1, help="Local worker processes, one thread each (default: one per core)."
        ),
    ),
    "scheduler": (
        str | None,
        typer.Option(
            None, "--scheduler", help="Run on an existing Dask cluster instead, e.g. tcp://HOST:8786."
        ),
    ),
    "retries": (
        int,
        typer.Option(
            0,
            "--retries",
            min=0,
            help="Run an item that fails unexpectedly up to N more times (not bad input).",
        ),
    ),
    "resume": (
        bool,
        typer.Option(
            True, "--resume/--no-resume", help="Skip the items an earlier run into OUTDIR finished (default)."
        ),
    ),
    "as_json": (bool, typer.Option(False, "--json", help="Print the manifest of results as JSON.")),
}
"""The options of every batch: where it runs and what it reports."""

COMMANDS = {
    "rig": (
        "HEADS",
        "Head meshes: paths or quoted globs ('scans/*.obj').",
        """Rig many heads: NAME.mrig, NAME.fit.json and NAME.fit.png in OUTDIR per head, as `mimetic rig`.

    Examples:

    \\b
      mimetic batch rig 'scans/*.obj' --landmarks '{dir}/{stem}.json' -o rigs/
      mimetic batch rig --manifest heads.csv -o rigs/ --scheduler tcp://10.0.0.1:8786 --retries 2
    """,
    ),
    "animate": (
        "RIGS",
        ".mrig rigs: paths or quoted globs.",
        """Play a clip on many rigs: NAME.glb (or .usda, .usdc, .mp4) in OUTDIR per rig, as `mimetic animate`.

    Examples:

    \\b
      mimetic batch animate 'rigs/*.mrig' --clip hello.json -o anims/
      mimetic batch animate 'rigs/*.mrig' --clip hello.json --format mp4 --size 256 -o videos/
    """,
    ),
    "render": (
        "FILES",
        "Meshes or .mrig rigs: paths or quoted globs.",
        """Render many meshes or rigs: NAME.png in OUTDIR per file, as `mimetic render`.

    Examples:

    \\b
      mimetic batch render 'rigs/*.mrig' -o pictures/
      mimetic batch render 'scans/*.obj' --view front --size 256 --format jpg -o thumbs/
    """,
    ),
    "speak": (
        "RIGS",
        ".mrig rigs: paths or quoted globs.",
        """Lip-sync many rigs: NAME.glb (or .mp4, .usda, .json, .csv) in OUTDIR per rig, as `mimetic speak`.

    Examples:

    \\b
      mimetic batch speak 'rigs/*.mrig' --text "Hello there" -o talk/
      mimetic batch speak --manifest lines.csv --format mp4 -o talk/   # input,text per row
    """,
    ),
    "capture": (
        "TAKES",
        "Trajectories (.c3d .trc .csv): paths or quoted globs.",
        """Solve many takes on one rig: NAME.json (the clip) and NAME.report.json in OUTDIR per take, as
    `mimetic capture solve`; each worker bakes the rig once.

    Examples:

    \\b
      mimetic batch capture head.mrig 'takes/*.c3d' -o clips/
      mimetic batch capture head.mrig 'openface/*.csv' --fps 30 --channels determined -o clips/
    """,
    ),
}
"""Per batch kind: the inputs' metavar and help, and the command's help."""


def _run(
    kind: str, inputs, out: Path, manifest, workers, scheduler, retries, resume, as_json, flags, **options
):
    """Run a batch with a progress bar (counts; failures as they happen), print its summary, exit 1 when
    any item failed; an error before it starts is said in the command line's words."""
    from mimetic.batch import run_batch

    if workers is not None and scheduler is not None:
        raise typer.BadParameter("give --workers or --scheduler, not both", param_hint="'--workers'")
    if not inputs and manifest is None:
        raise typer.BadParameter("give input files (paths or quoted globs) or --manifest")
    counts = dict.fromkeys(("ok", "failed", "skipped"), 0)
    from mimetic.cli.app import steps

    with steps() as progress:

        def done(finished: int, total: int) -> None:
            progress(
                f"{kind}: {', '.join(f'{n} {s}' for s, n in counts.items() if n) or 'starting'}",
                finished,
                total,
            )

        def on_result(row) -> None:
            counts[row.status] += 1
            if row.status == "failed":
                stderr.print(Text.assemble(("failed ", "red"), f"{row.item}: {row.error}"))

        try:
            result = run_batch(
                kind,
                inputs or [],
                out,
                manifest=manifest,
                client=scheduler,
                workers=workers,
                retries=retries,
                resume=resume,
                progress=done,
                on_result=on_result,
                **options,
            )
        except MimeticError as error:
            raise MimeticError(cli_words(str(error), flags)) from None
    if as_json:
        stdout.print_json(json.dumps(result.as_dict()))
    else:
        for row in result.failed:
            stdout.print(f"failed  {row.item}: {row.error}", markup=False)
        tally = result.counts()
        warned = sum(bool(row.warnings) for row in result.rows)
        stdout.print(
            f"{kind}: {tally['ok']} ok, {tally['failed']} failed, {tally['skipped']} skipped "
            f"(finished before) of {len(result.rows)} in {result.seconds:.1f} s on {result.executor}"
            + (f"; {warned} with warnings (see the manifest)" if warned else ""),
            markup=False,
        )
        stdout.print(f"wrote {result.json_path} and {result.csv_path.name}", markup=False)
    if result.failed:
        raise typer.Exit(1)


def _register(kind: str) -> None:
    """``mimetic batch KIND``: the task's batch options (``batch.items.batch_options``) as the command
    line spells them for the single command, then ``RUNNER``'s."""
    from mimetic.batch.items import batch_options

    metavar, help_inputs, doc = COMMANDS[kind]
    accepted = batch_options(kind)
    keyword = inspect.Parameter.KEYWORD_ONLY
    params = []
    if kind == "capture":  # the rig every take is solved on comes first, as in `capture solve`
        rig = typer.Argument(..., metavar="RIG", help="The .mrig rig to solve every take on.")
        params.append(
            inspect.Parameter("rig", inspect.Parameter.POSITIONAL_OR_KEYWORD, default=rig, annotation=str)
        )
    inputs = typer.Argument(None, metavar=f"{metavar}...", help=help_inputs)
    params.append(
        inspect.Parameter(
            "inputs", inspect.Parameter.POSITIONAL_OR_KEYWORD, default=inputs, annotation=list[str] | None
        )
    )
    params.append(
        inspect.Parameter(
            "out",
            keyword,
            default=typer.Option(..., "-o", "--out", help="Output folder (created if missing)."),
            annotation=Path,
        )
    )
    for spec in accepted.values():
        if spec.name == "rig" and kind == "capture":
            continue
        kind_ = annotation(spec)
        if spec.kind in ("path", "name_or_path"):
            kind_ = str | None  # a path, or a template of each input's ('{dir}/{stem}.json')
        params.append(inspect.Parameter(spec.name, keyword, default=typer_option(spec), annotation=kind_))
    for name, (kind_, option) in RUNNER.items():
        params.append(inspect.Parameter(name, keyword, default=option, annotation=kind_))
    flags = {spec.name: spec.flag for spec in accepted.values()}
    runner = tuple(RUNNER)

    def command(**given):
        settings = {name: given.pop(name) for name in runner}
        inputs, out = given.pop("inputs"), given.pop("out")
        _run(kind, inputs, out, flags=flags, **settings, **given)

    command.__signature__ = inspect.Signature(params)
    command.__doc__ = doc
    command.__name__ = f"batch_{kind}"
    batch_app.command(kind)(_guarded(command))


for _kind in COMMANDS:
    _register(_kind)
