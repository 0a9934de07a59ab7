"""The manifest of a batch's results (``Manifest``, one ``Row`` per item), and resuming from the
per-item completion records.

A worker writes an item's completion record (``OUTDIR/.mimetic-batch/NAME.json``) after all its
outputs, so the record is the proof that the item finished: an item counts as done, and is skipped
on the next run, only when its record reads back, was made from the same input and options (the
``key``: their values and the input files' sizes and times), and every output it lists exists with
the size it had. An interrupted run leaves no record for the items it was writing (and the
library's writers leave no half files under the final names: only ``.NAME.XXXX.tmp`` files, which
never count and are cleared when the item runs again), so those items run again. Failed items have
no record and run again too.

The manifest of results is written into OUTDIR as ``batch-KIND.json`` and ``batch-KIND.csv``, each
atomically, at the end of every run (skipped items included, with the residual and outputs their
record holds). Output paths in these files are relative to OUTDIR, so the folder can be moved.
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass
from pathlib import Path

from mimetic.batch.items import MANIFEST_NAMES, Item

STATUSES = ("ok", "failed", "skipped")
COLUMNS = ("item", "status", "seconds", "error", "residual", "input", "outputs", "warnings")
"""The manifest's columns, in order (CSV: ``outputs`` joined by ";" and ``warnings`` by " | ")."""


@dataclass(frozen=True)
class Row:
    """The result of one item.

    Attributes
    ----------
    item : str
        The item's name: its main output relative to OUTDIR without the suffix.
    status : {"ok", "failed", "skipped"}
        "skipped": finished by an earlier run (its completion record is intact).
    seconds : float
        Wall time of the job on its worker in this run (0 when skipped).
    error : str
        One line when failed, else "".
    residual : float or None
        The fit residual where the job has one (rig: mean surface residual in % of the head
        diagonal; capture: median marker RMS in rig units), else None.
    input : str
        The input file, absolute.
    outputs : tuple of Path
        The files the item wrote (absolute); empty when it failed.
    warnings : tuple of str
        The warnings the job raised, one line each.
    """

    item: str
    status: str
    seconds: float
    error: str
    residual: float | None
    input: str
    outputs: tuple[Path, ...]
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True)
class Manifest:
    """A batch's results, one row per item in input order.

    Attributes
    ----------
    kind : str
        The job: "rig", "animate", "render", "speak" or "capture".
    out_dir : Path
    rows : tuple of Row
    seconds : float
        Wall time of the run (cluster start included).
    executor : str
        Where it ran, e.g. "dask LocalCluster, 2 workers" or "ProcessPoolExecutor, 2 workers".
    """

    kind: str
    out_dir: Path
    rows: tuple[Row, ...]
    seconds: float
    executor: str

    @property
    def ok(self) -> tuple[Row, ...]:
        return tuple(r for r in self.rows if r.status == "ok")

    @property
    def failed(self) -> tuple[Row, ...]:
        return tuple(r for r in self.rows if r.status == "failed")

    @property
    def skipped(self) -> tuple[Row, ...]:
        return tuple(r for r in self.rows if r.status == "skipped")

    @property
    def json_path(self) -> Path:
        return self.out_dir / MANIFEST_NAMES[0].format(kind=self.kind)

    @property
    def csv_path(self) -> Path:
        return self.out_dir / MANIFEST_NAMES[1].format(kind=self.kind)

    def counts(self) -> dict[str, int]:
        """{"ok": n, "failed": n, "skipped": n}."""
        return {s: sum(r.status == s for r in self.rows) for s in STATUSES}

    def as_dict(self) -> dict:
        """The manifest as the JSON file holds it (output paths relative to ``out_dir``)."""
        return {
            "kind": self.kind,
            "out_dir": str(self.out_dir),
            "seconds": round(self.seconds, 3),
            "executor": self.executor,
            "counts": self.counts(),
            "rows": [self._row_dict(r) for r in self.rows],
        }

    def _row_dict(self, row: Row) -> dict:
        residual = row.residual if row.residual is None or math.isfinite(row.residual) else None
        return {
            "item": row.item,
            "status": row.status,
            "seconds": round(row.seconds, 3),
            "error": row.error,
            "residual": residual,
            "input": row.input,
            "outputs": [_relative(p, self.out_dir) for p in row.outputs],
            "warnings": list(row.warnings),
        }

    def to_csv(self) -> str:
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(COLUMNS)
        for row in self.rows:
            d = self._row_dict(row)
            residual = "" if d["residual"] is None else f"{d['residual']:.6g}"
            writer.writerow(
                [d["item"], d["status"], f"{d['seconds']:g}", d["error"], residual, d["input"],
                 ";".join(d["outputs"]), " | ".join(d["warnings"])]
            )  # fmt: skip
        return buffer.getvalue()

    def save(self) -> tuple[Path, Path]:
        """Write ``json_path`` and ``csv_path`` (each atomically); return them."""
        from mimetic.atomic import atomic_write

        with atomic_write(self.json_path, "w") as handle:
            handle.write(json.dumps(self.as_dict(), indent=1) + "\n")
        with atomic_write(self.csv_path, "w") as handle:
            handle.write(self.to_csv())
        return self.json_path, self.csv_path


def _relative(path: Path, folder: Path) -> str:
    try:
        return Path(path).relative_to(folder).as_posix()
    except ValueError:
        return str(path)


def completed(item: Item) -> Row | None:
    """The ``skipped`` row of an item an earlier run finished, or None when it must run.

    It counts as finished when its completion record reads back with the item's key and lists
    exactly the item's outputs, each existing with its recorded size.
    """
    try:
        record = json.loads(item.record.read_text(encoding="utf-8"))
        if record.get("key") != item.key:
            return None
        out_dir = Path(item.out_dir)
        listed = [(out_dir / o["path"], o["size"]) for o in record["outputs"]]
        if sorted(str(p) for p, _ in listed) != sorted(item.outputs):
            return None
        if any(not p.is_file() or p.stat().st_size != size for p, size in listed):
            return None
        residual = record.get("residual")
        return Row(
            item.name,
            "skipped",
            0.0,
            "",
            None if residual is None else float(residual),
            item.input,
            tuple(Path(p) for p in item.outputs),
            tuple(record.get("warnings", ())),
        )
    except (OSError, ValueError, KeyError, TypeError):
        return None
