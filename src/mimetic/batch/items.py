"""The items of a batch: inputs (paths, globs or a manifest file) and options → one ``Item`` per job.

Everything here runs on the machine that submits the batch, before any work starts. Every path is
made absolute, so a worker on another machine finds the same files through a shared filesystem
mounted at the same place. An item's outputs are named after its input (``scans/alice.obj`` →
``OUTDIR/alice.mrig``) or by the manifest's ``output`` column; two items that would write the same
file are refused here, with the fix.

A manifest file is a CSV (a header row, then one row per item) or a JSON list of objects. Each row
has ``input`` (relative paths are relative to the manifest's folder), optionally ``output`` (the
main output, relative to OUTDIR; its suffix chooses the format) and options: in a CSV any other
column, in JSON any other key or an ``options`` object. A row's options override the batch's;
empty CSV cells are not set.
"""

from __future__ import annotations

import csv
import glob
import hashlib
import json
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mimetic.errors import MimeticError
from mimetic.inputs import read_text
from mimetic.tasks.base import OptionSpec, TaskError, specs

RECORDS = ".mimetic-batch"
"""The folder in OUTDIR that holds one completion record per finished item."""

FORMAT = "format"
"""The one batch option that is not its task's: the main output's format (its suffix, no dot)."""

MANIFEST_NAMES = ("batch-{kind}.json", "batch-{kind}.csv")
"""The manifest of results a batch writes into OUTDIR (JSON and CSV)."""

PathLike = str | os.PathLike[str]


class BatchError(MimeticError, ValueError):
    """A batch that cannot start: no inputs, a glob that matches nothing, an unknown option, a malformed
    manifest file, two items writing the same file."""


@dataclass(frozen=True)
class Item:
    """One job of a batch, as sent to a worker (small: paths, not meshes).

    Attributes
    ----------
    kind : str
        "rig", "animate", "render", "speak" or "capture".
    name : str
        The main output's path relative to ``out_dir`` without its suffix ("alice", "takes/t1"):
        unique in the batch, the row's name in the manifest.
    input : str
        The input file, absolute.
    outputs : tuple of str
        The files the item writes, absolute, the main one first.
    options : dict
        Every option of the job, typed; paths absolute.
    out_dir : str
        The batch's output folder, absolute.
    key : str
        A digest of the input and options (and the sizes and times of the files they name): a
        completion record with another key does not count.
    row : int or None
        The item's row in the manifest file (1 is the first after a CSV header), if it came from one.
    """

    kind: str
    name: str
    input: str
    outputs: tuple[str, ...]
    options: dict = field(hash=False)
    out_dir: str
    key: str
    row: int | None = None

    @property
    def record(self) -> Path:
        """The item's completion record: ``OUTDIR/.mimetic-batch/<name>.json`` ("/" in the name as "%")."""
        return Path(self.out_dir) / RECORDS / (self.name.replace("/", "%") + ".json")


def expand_inputs(paths: Iterable[PathLike]) -> list[Path]:
    """Paths as given, and globs (``*``, ``?``, ``[``, ``**``) expanded in sorted order.

    A path that does not exist stays in the list (its item fails with the loader's message); a glob
    that matches nothing is refused, since it is most likely a typo.
    """
    found = []
    for path in paths:
        text = os.fspath(path)
        if not os.path.exists(text) and glob.has_magic(text):
            matches = sorted(glob.glob(text, recursive=True))
            if not matches:
                raise BatchError(f"no file matches {text!r}; check the pattern (quote it for the shell)")
            found.extend(Path(m) for m in matches)
        else:
            found.append(Path(text))
    return found


def read_manifest(path: PathLike) -> list[tuple[int, str, str | None, dict[str, Any]]]:
    """The rows of a manifest file: (row number, input, output or None, options as written).

    Raises
    ------
    BatchError
        A missing or unreadable file, another suffix than .csv or .json, a row without ``input``.
    """
    path = Path(path)
    if not path.is_file():
        raise BatchError(f"manifest {path}: no such file")
    suffix = path.suffix.lower()
    text = read_text(path, BatchError, "manifest")
    if suffix == ".csv":
        reader = csv.DictReader(text.splitlines())
        if reader.fieldnames is None or "input" not in reader.fieldnames:
            raise BatchError(f"manifest {path.name}: the first row must name the columns, one 'input'")
        rows = [{k: v for k, v in row.items() if k and v not in (None, "")} for row in reader]
    elif suffix == ".json":
        try:
            rows = json.loads(text)
        except json.JSONDecodeError as error:
            raise BatchError(f"manifest {path.name}: not valid JSON ({error})") from None
        if isinstance(rows, dict) and isinstance(rows.get("items"), list):
            rows = rows["items"]
        if not isinstance(rows, list) or not all(isinstance(r, dict) for r in rows):
            raise BatchError(f"manifest {path.name}: expected a list of objects with an 'input' key")
    else:
        raise BatchError(f"manifest {path.name}: use a .csv or .json file (input, output, options per row)")
    parsed = []
    for number, row in enumerate(rows, 1):
        row = dict(row)
        source = row.pop("input", None)
        if not isinstance(source, str) or not source.strip():
            raise BatchError(f"manifest {path.name}, row {number}: no 'input'")
        output = row.pop("output", None)
        if output is not None and not isinstance(output, str):
            raise BatchError(f"manifest {path.name}, row {number}: 'output' must be a file name")
        options = row.pop("options", None) or {}
        if not isinstance(options, dict):
            raise BatchError(f"manifest {path.name}, row {number}: 'options' must be an object")
        parsed.append((number, source.strip(), output, {**row, **options}))
    return parsed


def batch_options(kind: str) -> dict[str, OptionSpec]:
    """The options of batch ``kind``: its task's (``mimetic.tasks.BATCH_TASKS``) that a batch can share
    between items, and ``format`` (the main output's suffix, without the dot) when it writes more
    than one."""
    from mimetic.tasks import BATCH_TASKS

    if kind not in BATCH_TASKS:
        raise BatchError(f"unknown batch job {kind!r}; use one of {', '.join(BATCH_TASKS)}")
    task = BATCH_TASKS[kind]
    out = {name: spec for name, spec in specs(task.options).items() if spec.batch}
    if len(task.outputs) > 1:
        formats = tuple(dict.fromkeys(suffix[1:] for suffix in task.outputs))
        out[FORMAT] = OptionSpec(
            FORMAT, "text", formats[0], False, "What to write per item.", "--format", None, formats, (),
            None, None, None, True, None, None,
        )  # fmt: skip
    return out


def coerce(name: str, value: Any, spec: OptionSpec, base: Path, where: str) -> Any:
    """An option's value as its task takes it: text from a CSV cell or the command line parsed, a path
    made absolute against ``base`` (a ``{stem}`` or ``{dir}`` template is kept for ``resolve_template``)."""
    if value is None:
        return None
    try:
        if spec.kind == "bool":
            if isinstance(value, str):
                lowered = value.strip().lower()
                if lowered not in ("1", "0", "true", "false", "yes", "no", "on", "off"):
                    raise ValueError(value)
                return lowered in ("1", "true", "yes", "on")
            return bool(value)
        if spec.kind == "int":
            if isinstance(value, float) and not value.is_integer():
                raise ValueError(value)
            return int(value)
        if spec.kind == "float":
            return float(value)
    except (TypeError, ValueError):
        wanted = {"bool": "true or false", "int": "whole number", "float": "number"}[spec.kind]
        raise BatchError(f"{where}: option {name}={value!r} is not a {wanted}") from None
    text = os.fspath(value) if isinstance(value, os.PathLike) else str(value)
    if spec.kind == "path" or (spec.kind == "name_or_path" and text not in spec.names):
        return text if "{" in text else str((base / text).resolve())
    if spec.choices and text not in spec.choices:
        raise BatchError(f"{where}: option {name}={text!r}; use one of {', '.join(spec.choices)}")
    return text


def resolve_template(text: str, source: Path) -> str:
    """A path option written as a template for each input: ``{stem}`` (the input's name without its
    suffix) and ``{dir}`` (its folder), e.g. ``{dir}/{stem}.landmarks.json``; made absolute."""
    try:
        filled = text.format(stem=source.stem, dir=str(source.parent), name=source.name)
    except (KeyError, IndexError, ValueError) as error:
        raise BatchError(f"path template {text!r}: use {{stem}}, {{dir}} or {{name}} ({error})") from None
    return str(Path(filled).resolve())


def file_stats(paths: Iterable[str]) -> dict[str, list[int] | None]:
    """Size and modification time (ns) of each file, None for a missing one: what a record's key holds."""
    stats = {}
    for path in paths:
        try:
            s = os.stat(path)
            stats[path] = [s.st_size, s.st_mtime_ns]
        except OSError:
            stats[path] = None
    return stats


def item_key(kind: str, source: str, outputs: tuple[str, ...], options: Mapping[str, Any], paths) -> str:
    """The digest that ties a completion record to the input, options and outputs (relative to OUTDIR)
    it was made from, and to the sizes and times of the files in ``paths``."""
    document = {
        "kind": kind,
        "input": source,
        "outputs": list(outputs),
        "options": dict(sorted(options.items())),
        "files": file_stats(paths),
    }
    return hashlib.sha256(json.dumps(document, sort_keys=True, default=str).encode()).hexdigest()[:32]


def collect_items(
    kind: str,
    paths: Iterable[PathLike],
    out_dir: PathLike,
    *,
    manifest: PathLike | None = None,
    options: Mapping[str, Any] | None = None,
) -> list[Item]:
    """The items of a batch: one per input path (globs expanded) and one per manifest row, in order.

    Parameters
    ----------
    kind : {"rig", "animate", "render", "speak", "capture"}
    paths : iterable of path or glob
    out_dir : path
        The output folder (made absolute).
    manifest : path, optional
        A manifest file (CSV or JSON; see the module docstring).
    options : dict, optional
        The batch's options (see ``mimetic.batch.jobs.JOBS``); a row's options override them. Path
        options are relative to the current folder (a manifest's, to its folder) and may be
        templates with ``{stem}`` and ``{dir}`` of each input.

    Raises
    ------
    BatchError
        Nothing to do, an unknown option or value, a required option missing, an output outside
        OUTDIR, two items writing the same file.
    """
    from mimetic.tasks import BATCH_TASKS

    accepted = batch_options(kind)
    task = BATCH_TASKS[kind]
    out_dir = Path(out_dir).resolve()
    batch = _options(kind, accepted, options or {}, Path.cwd(), f"batch {kind}")
    sources: list[tuple[int | None, Path, str | None, dict]] = [
        (None, path, None, {}) for path in expand_inputs(paths)
    ]
    if manifest is not None:
        base = Path(manifest).resolve().parent
        for number, source, output, row in read_manifest(manifest):
            where = f"manifest {Path(manifest).name}, row {number}"
            sources.append((number, base / source, output, _options(kind, accepted, row, base, where)))
    if not sources:
        raise BatchError(f"batch {kind}: nothing to do; give input files (paths or globs) or a manifest")
    defaults = {name: spec.default for name, spec in accepted.items()}
    items = [
        _item(
            kind, task, accepted, number, source.resolve(), output, defaults | batch | row, out_dir, manifest
        )
        for number, source, output, row in sources
    ]
    _check_unique(items, out_dir, kind)
    return items


def _options(kind: str, accepted: Mapping[str, OptionSpec], given: Mapping, base: Path, where: str) -> dict:
    unknown = sorted(set(given) - set(accepted))
    if unknown:
        raise BatchError(
            f"{where}: unknown option(s) {', '.join(unknown)}; batch {kind} takes {', '.join(accepted)}"
        )
    given = {name: value for name, value in given.items() if value is not None}
    return {name: coerce(name, value, accepted[name], base, where) for name, value in given.items()}


def _item(kind, task, accepted, number, source: Path, output, options: dict, out_dir: Path, manifest) -> Item:
    where = f"manifest {Path(manifest).name}, row {number}" if number is not None else f"{source.name}"
    files = [str(source)]
    for name, spec in accepted.items():
        value = options[name]
        if spec.kind in ("path", "name_or_path") and isinstance(value, str) and value not in spec.names:
            options[name] = value = resolve_template(value, source) if "{" in value else value
            files.append(value)
    group = task.missing(options)
    if group is not None:
        wanted = " or ".join(repr(name) for name in group)
        raise BatchError(f"{where}: batch {kind} needs {wanted} (an option, or a column of the manifest)")
    try:
        chosen = task.options(**{name: value for name, value in options.items() if name != FORMAT})
    except TaskError as error:
        raise BatchError(f"{where}: {error}") from None
    if output is None:
        suffix = "." + options[FORMAT] if FORMAT in options else task.outputs[0]
        main = out_dir / (source.stem + suffix)
    else:
        main = (out_dir / output).resolve()
        if not main.is_relative_to(out_dir):
            raise BatchError(f"{where}: output {output!r} is outside the output folder {out_dir}")
        if main.suffix.lower() not in task.outputs:
            raise BatchError(f"{where}: output {output!r}: batch {kind} writes {', '.join(task.outputs)}")
        if FORMAT in options:
            options[FORMAT] = main.suffix.lower()[1:]
    outputs = tuple(str(p) for p in task.files(main, chosen))
    relative = tuple(Path(o).relative_to(out_dir).as_posix() for o in outputs)  # OUTDIR may move
    key = item_key(kind, str(source), relative, options, files)
    name = main.with_suffix("").relative_to(out_dir).as_posix()
    return Item(kind, name, str(source), outputs, options, str(out_dir), key, number)


def _check_unique(items: list[Item], out_dir: Path, kind: str) -> None:
    """Refuse two items that write the same file, and an item that writes over the batch's manifest."""
    writers: dict[str, list[Item]] = {}
    for item in items:
        for output in item.outputs:
            writers.setdefault(output.lower(), []).append(item)
    for output, by in writers.items():
        if len(by) > 1:
            inputs = ", ".join(dict.fromkeys(item.input for item in by))
            raise BatchError(
                f"{Path(output).name} would be written by {len(by)} items ({inputs}); give them distinct "
                "names with a manifest file (its 'output' column)"
            )
    for name in MANIFEST_NAMES:
        reserved = str(out_dir / name.format(kind=kind)).lower()
        if reserved in writers:
            raise BatchError(
                f"{writers[reserved][0].input}: its output {Path(reserved).name} is the batch's manifest; "
                "rename it with a manifest file (its 'output' column)"
            )
