"""Running one batch item on a worker: ``execute`` runs its task and writes its completion record.

Each batch kind is a task (``mimetic.tasks.BATCH_TASKS``), run once per input exactly as its
single-file command runs it, with the same outputs:

=========  ==========================  =========================================================
kind       input → outputs             the same as
=========  ==========================  =========================================================
rig        head mesh → NAME.mrig,      ``mimetic rig HEAD -o NAME.mrig`` (fit report and picture
           NAME.fit.json, .fit.png     beside it); residual: mean surface residual, % of the
                                       head diagonal
animate    rig → NAME.glb|usda|mp4     ``mimetic animate RIG --clip CLIP -o NAME.glb``
render     mesh or rig → NAME.png      ``mimetic render FILE -o NAME.png``
speak      rig → NAME.glb|mp4|json     ``mimetic speak RIG --text … -o NAME.glb``
capture    take → NAME.json,           ``mimetic capture solve RIG TAKE -o NAME.json`` (its report
           NAME.report.json            beside it); residual: median marker RMS, rig units
=========  ==========================  =========================================================

``execute`` runs on a worker process (Dask or a process pool). It imports the library lazily,
writes the item's outputs (each atomically, by the task's writers), then its completion record,
and returns an ``Outcome``. Bad input (a ``MimeticError``) is a verdict, returned as a failed
outcome and never retried; anything else is raised again as ``ItemFailed`` with its one-line
message, so that Dask's ``retries=`` can try the item again (a killed worker, a file server that
hiccuped). A worker keeps the rigs it loaded and the bakes it made (``tasks.prepared``), so the
takes of one rig are solved on one bake.
"""

from __future__ import annotations

import glob
import json
import logging
import os
import signal
import time
import warnings
from dataclasses import dataclass
from pathlib import Path

from mimetic.batch.items import FORMAT, Item
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
            residual = run_item(item)
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


def ignore_interrupts() -> None:
    """Make this worker process deaf to Ctrl-C: a terminal sends SIGINT to every process of its group,
    and a worker that heard it printed its own traceback; the batch's own process says "interrupted"
    once and stops the workers."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the main thread (a worker run in threads): nothing of its own to quiet
        pass


def dask_setup(worker) -> None:
    """Dask's preload hook, run in each worker of the local cluster (``preload=["mimetic.batch.jobs"]``)."""
    ignore_interrupts()


def init_worker() -> None:
    """Process-pool initializer: one thread per worker (``WORKER_THREADS``), set before numpy and numba
    load and, where they already have, through threadpoolctl; Ctrl-C left to the parent."""
    ignore_interrupts()
    for name, value in WORKER_THREADS.items():
        os.environ.setdefault(name, value)
    from threadpoolctl import threadpool_limits

    threadpool_limits(1)


def run_item(item: Item) -> float | None:
    """Run the item's task on its input and main output with its options; its residual, if any."""
    from mimetic.tasks import BATCH_TASKS

    task = BATCH_TASKS[item.kind]
    options = task.options(**{name: value for name, value in item.options.items() if name != FORMAT})
    return task.run(Path(item.input), Path(item.outputs[0]), options).residual
