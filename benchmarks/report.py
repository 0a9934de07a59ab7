"""Benchmark tables printed with rich and kept as Markdown for ``docs/benchmarks.md``.

A benchmark prints each table with ``show(title, columns, rows)``, which returns the table as
Markdown; at its end it hands those tables to ``save(name, tables)``, which writes
``benchmarks/out/<name>.md``: a line saying when, where and how the run was made, then the tables.
``write_docs.py`` (the last step of ``make bench``) copies each such file between the markers
``<!-- bench:<name> -->`` and ``<!-- /bench:<name> -->`` of ``docs/benchmarks.md``.
"""

from __future__ import annotations

import os
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from mimetic.atomic import atomic_write

OUT = Path(__file__).resolve().parent / "out"
"""Where ``save`` writes (ignored by git; ``make bench`` empties it first)."""

console = Console(width=None if sys.stdout.isatty() else 160)  # logs keep whole rows

_STARTED = (time.time(), os.getloadavg()[0])  # when this benchmark's process began, load then


def markdown(columns: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    """A Markdown table: a header of ``columns``, one line per row (cells already formatted)."""

    def line(cells: Sequence[str]) -> str:
        return "| " + " | ".join(str(c).replace("|", "\\|") for c in cells) + " |"

    return "\n".join([line(columns), "|" + "---|" * len(columns), *(line(r) for r in rows)])


def show(title: str, columns: Sequence[str], rows: Sequence[Sequence[str]], caption: str = "") -> str:
    """Print a rich table (``title`` above, ``caption`` below); return it as Markdown (the table,
    then the caption as a paragraph; the title is left to the document's prose)."""
    table = Table(title=title, title_justify="left", caption=caption or None, caption_justify="left")
    for name in columns:
        table.add_column(name)
    for row in rows:
        table.add_row(*(escape(str(c)) for c in row))  # a cell's [brackets] are text, not markup
    console.print(table)
    return markdown(columns, rows) + (f"\n\n{caption}" if caption else "")


def stamp() -> str:
    """When and where this run was made: start date (UTC), cores, load average at start and now,
    and the command, e.g. ``Run 2026-12-06 10:58 UTC · 2 cores · load 0.61 → 1.40 · `python …```."""
    start, load = _STARTED
    when = time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime(start))
    command = " ".join(["python", f"benchmarks/{Path(sys.argv[0]).name}", *sys.argv[1:]])
    return (
        f"*Run {when} · {os.cpu_count()} cores · load average {load:.2f} at the start, "
        f"{os.getloadavg()[0]:.2f} at the end · `{command}`*"
    )


def save(name: str, tables: Sequence[str], out: Path = OUT) -> Path:
    """Write ``out/<name>.md`` atomically: ``stamp()``, then ``tables`` (Markdown), blank-line separated."""
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{name}.md"
    with atomic_write(path, "w") as handle:
        handle.write("\n\n".join([stamp(), *tables]) + "\n")
    console.print(f"tables written to {path}")
    return path
