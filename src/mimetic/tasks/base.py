"""What every task shares: option declarations, the ``Task`` record, its ``Result`` and progress.

A task is one command's work, behind every front end (the CLI, ``mimetic batch``, the web viewer,
Python). Each task module holds:

* a frozen options dataclass (a ``TaskOptions``): every option with its default, its help text,
  its range or choices, declared once with ``option(...)``. Front ends read these declarations:
  the CLI builds its typer options from them, a batch coerces manifest cells by them;
* ``run(source, output, options, progress) -> Result``: ``source`` the file the task works on
  (a mesh, a rig, a clip, a take; None for the tasks that generate), ``output`` the main file it
  writes (its suffix chooses the format), ``progress(step, done, total)`` told as it goes;
* ``TASK = Task(...)``: the name, the options type, ``run``, the output suffixes it writes and
  the other files it writes beside the main one.

Validation happens here, in library words (a ``TaskError`` names the option as Python spells it);
front ends only parse and translate.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import types
import typing
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mimetic.errors import MimeticError

Progress = Callable[[str, int, int], None]
"""``progress(step, done, total)``: ``step`` names what runs ("bake", "video"), ``done`` of
``total`` units of it are finished."""


class TaskError(MimeticError, ValueError):
    """A misused option: outside its range or choices, a required one missing, two that exclude each
    other, a name the rig lacks, an output of a type the task cannot write; the message names the
    option and the fix (the command line shows it as a usage error, exit code 2)."""


class OutputError(MimeticError):
    """An output folder that does not exist, is a file, or cannot be written into (a problem with the
    user's files, not with the options)."""


def option(
    default: Any = None,
    help: str = "",
    *,
    flag: str | None = None,
    short: str | None = None,
    choices: tuple[str, ...] = (),
    names: tuple[str, ...] = (),
    minimum: float | None = None,
    maximum: float | None = None,
    metavar: str | None = None,
    batch: bool = True,
    parse: Callable[[Any], Any] | None = None,
    cli_type: Any = None,
) -> Any:
    """Declare one task option (a dataclass field) with everything a front end needs.

    Parameters
    ----------
    default
        The option's value when not given (one place for it: front ends read it from here).
    help : str
        One line for ``--help`` and the docs.
    flag, short : str, optional
        The command-line spelling, default ``--<name with dashes>``; ``short`` e.g. ``-o``.
    choices : tuple of str
        The values a text option takes (none: any).
    names : tuple of str
        For a "name or file" option: the built-in names; any other value is a path.
    minimum, maximum : float, optional
        The range of a number.
    metavar : str, optional
        How ``--help`` shows the value.
    batch : bool
        False for options a batch cannot share between items (a per-item output path).
    parse : callable, optional
        Turns the command line's text (a list of strings for a repeatable option) into the value;
        raises ``ValueError`` with the expected form.
    cli_type : type, optional
        The command line's type when it differs from the field's (``list[str]`` for repeatable
        ``NAME=VALUE`` items).
    """
    meta = {
        "help": help,
        "flag": flag,
        "short": short,
        "choices": tuple(choices),
        "names": tuple(names),
        "minimum": minimum,
        "maximum": maximum,
        "metavar": metavar,
        "batch": batch,
        "parse": parse,
        "cli_type": cli_type,
    }
    return field(default=default, metadata=meta)


@dataclass(frozen=True)
class OptionSpec:
    """One declared option, as front ends read it: ``name`` (the field), ``kind`` ("bool", "int",
    "float", "text", "path", "name_or_path" or "value" for structured ones), ``default``, ``required``
    (no default: the task needs it given), ``optional`` (None allowed), and the ``option`` metadata."""

    name: str
    kind: str
    default: Any
    optional: bool
    help: str
    flag: str
    short: str | None
    choices: tuple[str, ...]
    names: tuple[str, ...]
    minimum: float | None
    maximum: float | None
    metavar: str | None
    batch: bool
    parse: Callable[[Any], Any] | None
    cli_type: Any


def _kind(annotation: Any) -> tuple[str, bool]:
    """("bool" | "int" | "float" | "text" | "path" | "value", None allowed) of a field's type."""
    optional = False
    if isinstance(annotation, types.UnionType) or typing.get_origin(annotation) is typing.Union:
        args = [a for a in typing.get_args(annotation) if a is not type(None)]
        optional = len(args) < len(typing.get_args(annotation))
        annotation = args[0] if len(args) == 1 else annotation
    kinds = {bool: "bool", int: "int", float: "float", str: "text", Path: "path"}
    return kinds.get(annotation, "value"), optional


@functools.cache
def specs(options_type: type) -> dict[str, OptionSpec]:
    """Every option of ``options_type`` (a ``TaskOptions`` dataclass), by name, in declaration order."""
    hints = typing.get_type_hints(options_type)
    out = {}
    for f in dataclasses.fields(options_type):
        kind, optional = _kind(hints[f.name])
        meta = f.metadata
        if meta.get("names"):
            kind = "name_or_path"
        out[f.name] = OptionSpec(
            name=f.name,
            kind=kind,
            default=f.default,
            optional=optional,
            help=meta.get("help", ""),
            flag=meta.get("flag") or "--" + f.name.replace("_", "-"),
            short=meta.get("short"),
            choices=meta.get("choices", ()),
            names=meta.get("names", ()),
            minimum=meta.get("minimum"),
            maximum=meta.get("maximum"),
            metavar=meta.get("metavar"),
            batch=meta.get("batch", True),
            parse=meta.get("parse"),
            cli_type=meta.get("cli_type"),
        )
    return out


@dataclass(frozen=True)
class TaskOptions:
    """Base of every task's options: checks each value against its declaration when made.

    Paths given as text become ``Path``; numbers outside their range, text outside its choices and
    values of the wrong type raise ``TaskError`` naming the option.
    """

    def __post_init__(self) -> None:
        for spec in specs(type(self)).values():
            value = getattr(self, spec.name)
            if value is None:
                continue
            if spec.kind == "path" and isinstance(value, (str, os.PathLike)):
                object.__setattr__(self, spec.name, Path(value))
            elif spec.kind == "name_or_path" and isinstance(value, os.PathLike):
                object.__setattr__(self, spec.name, os.fspath(value))
            elif spec.kind == "int" and (isinstance(value, bool) or not isinstance(value, int)):
                raise TaskError(f"{spec.name}={value!r} must be a whole number")
            elif spec.kind == "float" and (isinstance(value, bool) or not isinstance(value, (int, float))):
                raise TaskError(f"{spec.name}={value!r} must be a number")
            elif spec.kind == "bool" and not isinstance(value, bool):
                raise TaskError(f"{spec.name}={value!r} must be True or False")
            if spec.kind in ("int", "float"):
                if spec.minimum is not None and value < spec.minimum:
                    raise TaskError(f"{spec.name}={value:g} is below its minimum {spec.minimum:g}")
                if spec.maximum is not None and value > spec.maximum:
                    raise TaskError(f"{spec.name}={value:g} is above its maximum {spec.maximum:g}")
            if spec.choices and value not in spec.choices:
                raise TaskError(f"{spec.name}={value!r}: choose one of {', '.join(spec.choices)}")

    def changed(self) -> dict[str, Any]:
        """The options that differ from their defaults (what a front end would have to give)."""
        return {
            f.name: getattr(self, f.name)
            for f in dataclasses.fields(self)
            if getattr(self, f.name) != f.default
        }


@dataclass(frozen=True)
class Result:
    """What a task did.

    Attributes
    ----------
    outputs : tuple of Path
        The files written, the main output first.
    summary : str
        One line: what was made ("150 frames at 30 fps, 34 channels").
    residual : float or None
        The task's fit residual, where it has one (rig: mean surface residual, % of the head
        diagonal; capture: median marker RMS, rig units); a batch's manifest lists it.
    details : Mapping
        Structured facts for ``--json`` and reports (the fit or capture report, the rows of a list).
    notes : tuple of str
        Things the user should know that are not warnings (a silent video: espeak-ng missing).
    """

    outputs: tuple[Path, ...]
    summary: str
    residual: float | None = None
    details: Mapping[str, Any] = field(default_factory=dict)
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class Task:
    """A command's work, as every front end sees it.

    Attributes
    ----------
    name : str
        The command ("rig", "animate", "capture solve").
    options : type
        The task's ``TaskOptions`` dataclass.
    run : callable(source, output, options, progress) -> Result
    outputs : tuple of str
        Suffixes the main output may take (lower case, with the dot); the first is the default.
    extra : callable(main, options) -> tuple of Path
        The other files the task writes beside its main output (``NAME.fit.json``), given options.
    source : str
        What the task reads ("mesh", "rig", "take"); "" for a task that generates.
    """

    name: str
    options: type
    run: Callable[..., Result]
    outputs: tuple[str, ...]
    extra: Callable[[Path, Any], tuple[Path, ...]] = lambda main, options: ()
    source: str = ""
    required: tuple[tuple[str, ...], ...] = ()

    def files(self, main: Path, options: Any) -> tuple[Path, ...]:
        """Every file the task writes for ``main`` with ``options``, the main one first."""
        return (Path(main), *self.extra(Path(main), options))

    def missing(self, options: Mapping[str, Any] | Any) -> tuple[str, ...] | None:
        """The first group of ``required`` options of which none is set (a mapping or an options
        object), or None when every group has one."""
        get = options.get if isinstance(options, Mapping) else lambda name: getattr(options, name, None)
        return next((group for group in self.required if all(get(name) is None for name in group)), None)

    def check(self, options: Any) -> None:
        """``TaskError`` naming the required options ``options`` lacks."""
        group = self.missing(options)
        if group is not None:
            raise TaskError(f"{self.name} needs {' or '.join(group)}")


def beside(main: Path, suffix: str) -> Path:
    """The file beside ``main`` with ``suffix`` in place of its own (``take.json`` → ``take.report.json``)."""
    return main.with_name(main.with_suffix("").name + suffix)


def check_output(path: Path, suffixes: tuple[str, ...], what: str = "output") -> Path:
    """``path`` as an output of one of ``suffixes`` (else ``TaskError``) in an existing, writable folder
    (else ``OutputError``): checked before any work, so a bad output never costs a run."""
    path = Path(path)
    if path.suffix.lower() not in suffixes:
        raise TaskError(
            f"{path.name}: cannot write a {path.suffix or 'file without a suffix'} {what}; "
            f"use {', '.join(suffixes)}"
        )
    if path.is_dir():
        raise OutputError(f"{path} is a folder; give a file name")
    check_folder(path.parent)
    return path


def check_folder(folder: Path, *, create: bool = False) -> Path:
    """An existing, writable folder (or, with ``create``, one whose parent is); ``OutputError``
    otherwise."""
    folder = Path(folder) if str(folder) else Path(".")
    target = folder if folder.is_dir() or not create else folder.parent
    if folder.exists() and not folder.is_dir():
        raise OutputError(f"{folder} is a file; give a folder")
    if not target.is_dir():
        raise OutputError(f"the folder {target} does not exist; create it first (mkdir -p {target})")
    if not os.access(target, os.W_OK):
        raise OutputError(f"cannot write into {target}: permission denied")
    return folder


def stage(progress: Progress | None, step: str) -> Callable[[int, int], None]:
    """A ``(done, total)`` callback that reports as ``step`` (for the library's own progress)."""

    def report(done: int, total: int) -> None:
        if progress is not None:
            progress(step, done, total)

    return report


def announce(progress: Progress | None, step: str) -> None:
    """Say that ``step`` starts (a step with no finer progress of its own)."""
    if progress is not None:
        progress(step, 0, 1)
