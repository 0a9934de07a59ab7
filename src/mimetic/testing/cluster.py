"""A Dask cluster of separate processes on 127.0.0.1, started as on several machines (tests and
``bench_batch``).

``loopback_cluster(folder)`` runs ``dask scheduler`` and one ``dask worker`` per name as processes
of their own (this interpreter, mimetic's source on their path, one thread each), yields a
``Loopback`` with the scheduler's address, and at the end shuts the cluster down through its
scheduler and checks that every process, its children too, exited by itself.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import mimetic


@dataclass(frozen=True)
class Loopback:
    """A Dask cluster of separate processes on 127.0.0.1, started as on several machines (``dask
    scheduler`` on one, ``dask worker`` on each of the others)."""

    address: str  # the scheduler's, "tcp://127.0.0.1:PORT" (a free port the scheduler chose)
    workers: tuple[str, ...]  # the workers' names, one ``dask worker`` process (and its nanny) each
    logs: Path  # each process's stderr, NAME.log


@contextmanager
def loopback_cluster(folder: Path, workers: tuple[str, ...] = ("worker-a", "worker-b")) -> Iterator[Loopback]:
    """Start ``dask scheduler`` and one ``dask worker`` per name as processes of their own, each in its
    own session, this interpreter and mimetic's source on their path; at the end shut the cluster down
    through its scheduler and check that every process exited by itself, its children too.

    Raises
    ------
    AssertionError
        A process did not start within ``START_S``, or was still running ``START_S`` after the
        shutdown (it is then killed).
    """
    import distributed

    from mimetic.batch.jobs import WORKER_THREADS

    source = str(Path(mimetic.__file__).resolve().parents[1])  # the workers import this mimetic
    path = os.pathsep.join(p for p in (source, os.environ.get("PYTHONPATH")) if p)
    env = {**os.environ, **WORKER_THREADS, "PYTHONPATH": path}
    scheduler_file = folder / "scheduler.json"
    started: list[subprocess.Popen] = []

    def start(name: str, *args: str) -> None:
        with (folder / f"{name}.log").open("w") as log:
            command = [sys.executable, "-m", "dask", *args, "--no-dashboard"]
            started.append(subprocess.Popen(command, env=env, cwd=folder, stdout=log, stderr=log,
                                            start_new_session=True))  # fmt: skip

    try:
        start(
            "scheduler",
            "scheduler",
            "--host",
            "127.0.0.1",
            "--port",
            "0",
            "--scheduler-file",
            str(scheduler_file),
        )
        deadline = time.monotonic() + START_S
        while not scheduler_file.is_file() and started[0].poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert scheduler_file.is_file(), (
            f"the scheduler did not start: {(folder / 'scheduler.log').read_text()}"
        )
        address = json.loads(scheduler_file.read_text())["address"]
        for name in workers:
            start(name, "worker", address, "--name", name, "--nthreads", "1", "--host", "127.0.0.1",
                  "--local-directory", str(folder / name))  # fmt: skip
        with distributed.Client(address, timeout=f"{START_S}s") as client:
            client.wait_for_workers(len(workers), timeout=START_S)
        yield Loopback(address, workers, folder)
        with distributed.Client(address, timeout=f"{START_S}s") as client:
            client.shutdown()  # the scheduler closes the workers and their nannies, then itself
    finally:
        leaked = _stop(started)
    assert not leaked, f"processes still running {START_S} s after the shutdown, killed: {leaked}"


START_S = 30
"""How long the loopback cluster's processes may take to start, and to exit after the shutdown."""


def _stop(processes: list[subprocess.Popen]) -> list[str]:
    """Wait for ``processes`` and their children to exit (each process leads a session, and so a process
    group, of its own); kill whatever is still running after ``START_S``. Returns what was killed."""
    deadline = time.monotonic() + START_S
    leaked = []
    for process in processes:
        name = " ".join(process.args[2:4])  # "dask scheduler", "dask worker"
        try:
            process.wait(timeout=max(0.1, deadline - time.monotonic()))
        except subprocess.TimeoutExpired:
            leaked.append(name)
        while _group_alive(process.pid) and time.monotonic() < deadline:  # children exit after it
            time.sleep(0.05)
        if _group_alive(process.pid):
            if process.returncode is not None:
                leaked.append(f"a child of {name}")
            os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    return leaked


def _group_alive(group: int) -> bool:
    """Whether any process of the process group ``group`` still runs."""
    try:
        os.killpg(group, 0)
    except ProcessLookupError:
        return False
    return True
