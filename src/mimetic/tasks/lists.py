"""``mimetic list``: the names commands take (expressions, channels, muscles, controls, FACS, ARKit)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from mimetic.tasks.base import Progress, Result, Task, TaskOptions, option

LISTS = ("expressions", "channels", "muscles", "controls", "facs", "arkit")
"""What ``list`` lists; channels and muscles are a rig's (the built-in head's without one)."""


@dataclass(frozen=True)
class ListOptions(TaskOptions):
    """What to list (see ``option`` for the fields' metadata)."""

    what: str = option(
        "expressions", "expressions, channels, muscles, controls, facs or arkit.", choices=LISTS
    )


def run(
    source: Path | None,
    output: None = None,
    options: ListOptions = ListOptions(),
    progress: Progress | None = None,
) -> Result:
    """The rows of ``options.what``: ``details`` holds ``columns`` (names) and ``rows`` (tuples);
    ``source`` is the rig whose channels or muscles are listed (default: the built-in head's)."""
    columns, rows = _rows(options.what, source)
    return Result((), f"{len(rows)} {options.what}", details={"columns": columns, "rows": rows})


def _rows(what: str, rig_file: Path | None) -> tuple[tuple[str, ...], list[tuple]]:
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
        from mimetic.tasks.prepared import prepared_rig

        return prepared_rig(rig_file).rig
    from mimetic.head.model import make_head
    from mimetic.rig.recipe import build_rig

    return build_rig(make_head(resolution=1_500), anatomy=False)  # its channels and muscles only


TASK = Task("list", ListOptions, run, (), source="rig")
