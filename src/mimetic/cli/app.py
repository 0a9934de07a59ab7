"""The ``mimetic`` app, its error boundary, its progress lines, and commands made from tasks.

Results go to stdout; progress, warnings and errors go to stderr. Exit codes:

* 0: success;
* 1: a problem with the input (a broken mesh, a rig without that channel, an unwritable folder),
  shown as one line that says what is wrong and how to fix it, in the command line's words (an
  option is ``--fps``, not ``fps=``); anything unexpected is one line too, asking for a report
  (``mimetic --debug …`` shows the traceback);
* 2: a usage error: an unknown option, a malformed or out-of-range value, an output type the
  command does not write (typer's own message);
* 130: interrupted (Ctrl-C), one line.

``task_command`` makes a command from a task (``mimetic.tasks``): its options, their defaults,
ranges, choices and help come from the task's options dataclass, declared there once.
"""

from __future__ import annotations

import functools
import inspect
import re
import sys
import time
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Literal

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
from rich.text import Text

from mimetic import __version__
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


def group(name: str, help: str) -> typer.Typer:
    """A command group (``mimetic clip …``) added to the app."""
    sub = typer.Typer(help=help, no_args_is_help=True, rich_markup_mode=None)
    app.add_typer(sub, name=name)
    return sub


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


def message(error: BaseException) -> str:
    """One line for the user: a MimeticError's own message, a file error with its file, else a bug."""
    if isinstance(error, MimeticError):
        return " ".join(str(error).split())
    if isinstance(error, OSError) and error.strerror:
        where = f"{error.filename}: " if error.filename else ""
        return f"{where}{error.strerror}"
    return (
        f"unexpected {type(error).__name__}: {error}. This is a bug in mimetic: run the command again "
        "with --debug (mimetic --debug …) for the traceback and report it."
    )


def cli_words(text: str, flags: dict[str, str]) -> str:
    """A library message in the command line's words: ``fps=30``, ``units='m'`` and ``force=True``
    become ``--fps 30``, ``--units m`` and ``--force`` for the options (name → flag) of the running
    command."""
    for name, flag in sorted(flags.items(), key=lambda item: -len(item[0])):
        value = r"""(?:'([^']*)'|"([^"]*)"|([^\s,;:()'"]+))?"""
        text = re.sub(
            rf"(?<![\w.-]){re.escape(name)}={value}",
            lambda m, flag=flag: (
                flag
                if m.group(0).endswith("=True")
                else f"{flag} {next((g for g in m.groups() if g), '')}".rstrip()
            ),
            text,
        )
    return text


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Python warnings as one line each on stderr, without the source path and code line."""
    stderr.print(Text.assemble(("warning: ", "yellow"), " ".join(str(message).split())))


def _quiet(unraisable) -> None:
    """After an interruption, clean-up errors (reported at exit) are not the user's business."""


def _guarded(command: Callable) -> Callable:
    """Run a command inside the error boundary: no traceback without --debug, warnings as lines."""

    @functools.wraps(command)
    def run(*args, **kwargs):
        with warnings.catch_warnings():
            warnings.simplefilter("default")
            warnings.filterwarnings("ignore", category=ResourceWarning)  # a library's, not the user's
            warnings.showwarning = _show_warning
            try:
                return command(*args, **kwargs)
            except (typer.Exit, typer.Abort, typer.BadParameter):
                raise
            except KeyboardInterrupt:
                stderr.print("interrupted")
                sys.unraisablehook = _quiet  # a cluster caught half-started complains at exit: not news
                raise typer.Exit(130) from None
            except Exception as error:
                if _state["debug"]:
                    raise
                stderr.print(Text.assemble(("error: ", "bold red"), message(error)))
                raise typer.Exit(1) from None

    return run


def command(name: str | None = None, parent: typer.Typer = app):
    """``@app.command()`` with the error boundary."""

    def register(function: Callable) -> Callable:
        return parent.command(name)(_guarded(function))

    return register


# --------------------------------------------------------------------------- progress


class _Count(ProgressColumn):
    """``done/total``, or nothing while the total is unknown."""

    def render(self, task) -> Text:
        return Text("" if task.total is None else f"{task.completed:g}/{task.total:g}")


def _interactive() -> bool:
    """Bars on a terminal; one plain line per step when stdout or stderr is piped or redirected."""
    return sys.stderr.isatty() and sys.stdout.isatty()


@contextmanager
def steps() -> Iterator[Callable[[str, int, int], None]]:
    """A progress callback ``(step, done, total)``: on a terminal one bar per named step (with its
    count, elapsed and remaining time); piped, one line per step as it starts (``[  2.1 s] bake``)."""
    start = time.perf_counter()
    if not _interactive():
        seen: set[str] = set()

        def line(step: str, done: int, total: int) -> None:
            if step not in seen:
                seen.add(step)
                stderr.print(f"[{time.perf_counter() - start:6.1f} s] {step}", markup=False)

        yield line
        return
    columns = (
        TextColumn("{task.description}"),
        BarColumn(),
        _Count(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
    )
    with Progress(*columns, console=stderr, transient=True) as bar:
        tasks: dict[str, Any] = {}

        def update(step: str, done: int, total: int) -> None:
            if step not in tasks:
                tasks[step] = bar.add_task(step, total=total)
            bar.update(tasks[step], completed=done, total=total)

        yield update


# --------------------------------------------------------------------------- output checks


def check_output(path: Path, suffixes: tuple[str, ...], option: str = "-o") -> Path:
    """An output's suffix is one the command writes (else a usage error, exit 2)."""
    if path.suffix.lower() not in suffixes:
        raise typer.BadParameter(
            f"{path.name}: unsupported output {path.suffix or '(no suffix)'!r}; use {', '.join(suffixes)}",
            param_hint=f"'{option}'",
        )
    return path


# --------------------------------------------------------------------------- commands from tasks


def _parser(spec) -> Callable:
    """A typer callback turning a structured option's text into its value (a usage error if malformed)."""

    def parse(value):
        if value is None:
            return value
        try:
            return spec.parse(value)
        except ValueError as error:
            raise typer.BadParameter(str(error), param_hint=f"'{spec.flag}'") from None

    return parse


def typer_option(spec, *, default: Any = inspect.Parameter.empty, help: str | None = None):
    """The typer option of a task option (``tasks.base.OptionSpec``): its flags, default, range,
    choices, help and value parser, as the task declares them."""
    default = spec.default if default is inspect.Parameter.empty else default
    decls = (
        [spec.flag] if spec.kind != "bool" or default is not True else [f"{spec.flag}/--no-{spec.flag[2:]}"]
    )
    if spec.short:
        decls.append(spec.short)
    extra: dict[str, Any] = {}
    if spec.minimum is not None:
        extra["min"] = spec.minimum
    if spec.maximum is not None:
        extra["max"] = spec.maximum
    if spec.parse is not None:
        extra["callback"] = _parser(spec)
    if spec.cli_type is list[str] and default == ():
        default = []
    return typer.Option(default, *decls, help=help or spec.help, metavar=spec.metavar, **extra)


def annotation(spec) -> Any:
    """The type typer parses a task option as: its choices as a ``Literal``, else its own type."""
    if spec.cli_type is not None:
        return spec.cli_type
    base = {"bool": bool, "int": int, "float": float, "text": str, "path": Path, "name_or_path": str}[
        spec.kind
    ]
    if spec.choices:
        base = Literal[spec.choices]
    return base | None if spec.optional or spec.default is None else base


def task_command(
    parent: typer.Typer,
    name: str,
    task,
    doc: str,
    *,
    arguments: tuple[tuple, ...],
    output: str | None,
    output_default: Path | None = None,
    extras: dict[str, tuple[Any, Any]] | None = None,
    show: Callable | None = None,
) -> Callable:
    """Register ``task`` as command ``name`` and return it.

    ``arguments`` are the positional ones, ``(target, METAVAR, help)`` or ``(target, METAVAR, help,
    False)`` for an optional one: ``target`` is "source" (the task's input file) or the option it
    sets. ``output`` is the help of ``-o/--out`` (None: the task writes no file), required unless
    ``output_default`` is given. Every other option
    of the task follows, as the task declares it. ``extras`` are options of the command line only
    (name → (type, typer option)), handed to ``show(result, **extras)``, which prints the result
    (default ``print_result``: the files written and the summary).
    """
    from mimetic.tasks.base import TaskError, specs

    options = specs(task.options)
    positional = {argument[0] for argument in arguments}
    params = []
    for target, metavar, help_text, *required in arguments:
        needed = required[0] if required else True
        kind = Path if target == "source" else annotation(options[target])
        if not needed:
            kind = kind | None
        argument = typer.Argument(... if needed else None, metavar=metavar, help=help_text)
        params.append(
            inspect.Parameter(
                target, inspect.Parameter.POSITIONAL_OR_KEYWORD, default=argument, annotation=kind
            )
        )
    keyword = inspect.Parameter.KEYWORD_ONLY
    if output is not None:
        out_option = typer.Option(output_default or ..., "-o", "--out", help=output)
        params.append(inspect.Parameter("out", keyword, default=out_option, annotation=Path))
    for spec in options.values():
        if spec.name not in positional:
            params.append(
                inspect.Parameter(spec.name, keyword, default=typer_option(spec), annotation=annotation(spec))
            )
    for extra, (kind, param) in (extras or {}).items():
        params.append(inspect.Parameter(extra, keyword, default=param, annotation=kind))
    flags = {spec.name: spec.flag for spec in options.values()}

    def run(**given):
        shown = {extra: given.pop(extra) for extra in extras or {}}
        source = given.pop("source", None)
        out = given.pop("out", None)
        if out is not None and task.outputs:
            check_output(out, task.outputs)
        try:
            chosen = task.options(**given)
        except TaskError as error:
            raise typer.BadParameter(cli_words(str(error), flags)) from None
        try:
            with steps() as progress:
                result = task.run(source, out, chosen, progress)
        except TaskError as error:  # a misused option found once the inputs are read: a usage error
            raise typer.BadParameter(cli_words(str(error), flags)) from None
        except MimeticError as error:
            raise MimeticError(cli_words(str(error), flags)) from None
        (show or print_result)(result, **shown)

    run.__signature__ = inspect.Signature(params)
    run.__doc__ = doc
    run.__name__ = name.replace(" ", "_")
    parent.command(name)(_guarded(run))
    return run


def print_result(result, **_) -> None:
    """The files a task wrote, one ``wrote PATH`` line each, then its summary and notes."""
    for path in result.outputs:
        stdout.print(f"wrote {path}", markup=False)
    if result.summary:
        stdout.print(result.summary, markup=False)
    for note in result.notes:
        stdout.print(f"note: {note}", markup=False)
