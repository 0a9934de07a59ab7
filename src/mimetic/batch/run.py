"""Running a batch: ``run_batch`` and the five ``*_many`` functions, on Dask or a process pool.

Where the items run (``client``):

* None: a local Dask cluster (``LocalCluster``) of ``workers`` processes with one thread each,
  started for the run and closed after it; without Dask installed (the ``[batch]`` extra), a
  ``concurrent.futures.ProcessPoolExecutor`` of as many processes;
* a scheduler address ("tcp://HOST:8786"): that Dask cluster (needs the ``[batch]`` extra);
* a ``distributed.Client``: its cluster (a multi-node one, ``dask_jobqueue.SLURMCluster``, …);
* any ``concurrent.futures.Executor``: that pool (kept open; the caller owns it).

One thread per process, because the jobs are CPU-bound numpy and numba (fits, bakes, renders): N
single-threaded processes keep N cores busy without fighting over them, where threads would share
one interpreter and multi-threaded BLAS in every process would oversubscribe the cores.

Items are sent as small ``Item`` records (paths, not meshes). Workers read and write the files
themselves, so on several machines the inputs and OUTDIR must be on a filesystem every worker
mounts at the same path; every path is made absolute before submission.
"""

from __future__ import annotations

import logging
import os
import time
import uuid
import warnings
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, BrokenExecutor, Executor, ProcessPoolExecutor, wait
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from mimetic.batch.items import BatchError, Item, PathLike, collect_items
from mimetic.batch.jobs import WORKER_THREADS, ItemFailed, Outcome, execute, init_worker, one_line
from mimetic.batch.manifest import Manifest, Row, completed
from mimetic.errors import MimeticWarning, MissingExtraError, install_hint

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None]
OnResult = Callable[[Row], None]


def run_batch(
    kind: str,
    paths: PathLike | Iterable[PathLike],
    out_dir: PathLike,
    *,
    manifest: PathLike | None = None,
    client: Any = None,
    workers: int | None = None,
    retries: int = 0,
    resume: bool = True,
    progress: Progress | None = None,
    on_result: OnResult | None = None,
    **options: Any,
) -> Manifest:
    """Run one job per input on a cluster and return (and write) the manifest of results.

    Parameters
    ----------
    kind : {"rig", "animate", "render", "speak", "capture"}
    paths : path, glob or iterable of them
        Inputs; globs (``"scans/*.obj"``) are expanded in sorted order.
    out_dir : path
        Output folder, created if missing. Each item writes its outputs here (named after its
        input), its completion record into ``.mimetic-batch/``, and the run writes the manifest
        ``batch-KIND.json`` and ``.csv``.
    manifest : path, optional
        A CSV or JSON file of more items: input, output and options per row
        (``mimetic.batch.items``).
    client : None, str, distributed.Client or concurrent.futures.Executor
        Where to run (see the module docstring).
    workers : int, optional
        Processes of the local cluster (default: the usable cores, at most one per item).
    retries : int
        Attempts more for an item that fails unexpectedly (Dask's ``retries=``). Bad input (a
        ``MimeticError``) is not retried.
    resume : bool
        Skip items an earlier run finished (``mimetic.batch.manifest``).
    progress : callable(done, total), optional
        Called as items finish; ``total`` counts the items this run works on (not the skipped).
    on_result : callable(Row), optional
        Called with each item's row as soon as it is known (skipped ones first).
    **options
        The job's options (``mimetic.batch.jobs.JOBS[kind].options``); a manifest row's override them.

    Returns
    -------
    Manifest
        One row per item in input order; ``manifest.failed`` lists the failures.

    Raises
    ------
    BatchError
        The batch cannot start (see ``collect_items``); nothing has run.
    MissingExtraError
        ``client`` is a scheduler address and Dask is not installed.
    """
    start = time.perf_counter()
    if client is not None and workers is not None:
        raise BatchError("give workers (a local cluster) or client (an existing one), not both")
    if workers is not None and workers < 1:
        raise BatchError(f"workers={workers}: give at least 1")
    if retries < 0:
        raise BatchError(f"retries={retries}: give 0 or more")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise BatchError(f"{out} is a file; give a folder for the outputs")
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    items = collect_items(kind, paths, out, manifest=manifest, options=options)
    created = not out.exists()
    out.mkdir(parents=True, exist_ok=True)
    try:
        return _run(kind, items, out, start, client, workers, retries, resume, progress, on_result)
    except BaseException:  # unreachable scheduler, Ctrl-C before anything ran: leave no empty folder
        if created and out.is_dir() and not any(out.iterdir()):
            out.rmdir()
        raise


def _run(kind, items, out, start, client, workers, retries, resume, progress, on_result) -> Manifest:
    """``run_batch`` once its items are collected and ``out`` exists."""
    rows: dict[str, Row] = {}
    todo = []
    for item in items:
        row = completed(item) if resume else None
        if row is None:
            todo.append(item)
        else:
            rows[item.name] = row
            if on_result is not None:
                on_result(row)
    log.info("batch %s: %d items, %d to run, %d finished before", kind, len(items), len(todo), len(rows))
    executor = "nothing to run"
    if todo:
        finished = 0

        def done(item: Item, outcome: Outcome) -> None:
            nonlocal finished
            ok = outcome.status == "ok"
            outputs = tuple(Path(p) for p in item.outputs) if ok else ()
            row = Row(item.name, outcome.status, outcome.seconds, outcome.error, outcome.residual,
                      item.input, outputs, outcome.warnings)  # fmt: skip
            rows[item.name] = row
            finished += 1
            log.debug("batch %s: %s %s in %.2f s %s", kind, item.name, row.status, row.seconds, row.error)
            if progress is not None:
                progress(finished, len(todo))
            if on_result is not None:
                on_result(row)

        with _runner(client, workers, len(todo)) as runner:
            executor = runner.name
            if progress is not None:  # the cluster is up: the items start
                progress(0, len(todo))
            runner.run(todo, retries, done)
    ordered = tuple(rows[i.name] for i in items)
    result = Manifest(kind, out.resolve(), ordered, time.perf_counter() - start, executor)
    result.save()
    return result


# --------------------------------------------------------------------------- the five jobs


def rig_many(paths, out_dir, *, client=None, workers=None, retries=0, resume=True, progress=None,
             **options) -> Manifest:  # fmt: skip
    """Rig many head meshes: ``NAME.mrig``, ``NAME.fit.json`` and ``NAME.fit.png`` per head in
    ``out_dir``, each as ``mimetic rig`` writes it.

    Options (batch-wide, or per manifest row): ``landmarks`` (a file, or a template such as
    ``"{dir}/{stem}.json"`` for one file per head; default: found with MediaPipe),
    ``auto_landmarks``, ``units``, ``force``, ``resolution`` (10,000), ``picture`` (True),
    ``manifest``, ``on_result``. The rest as for ``run_batch``; a row's residual is the mean
    surface residual in % of the head diagonal.
    """
    return run_batch("rig", paths, out_dir, client=client, workers=workers, retries=retries,
                     resume=resume, progress=progress, **options)  # fmt: skip


def animate_many(rigs, out_dir, *, client=None, workers=None, retries=0, resume=True, progress=None,
                 **options) -> Manifest:  # fmt: skip
    """Play a clip on many rigs: ``NAME.glb`` (or ``.usda``, ``.usdc``, ``.mp4``) per rig, as
    ``mimetic animate`` writes it.

    Options: ``clip`` (required: a clip JSON, or per row), ``format`` ("glb"), ``fps`` (30),
    ``size`` (512, videos), ``audio``, ``engine`` ("wire"), ``manifest``, ``on_result``.
    """
    return run_batch("animate", rigs, out_dir, client=client, workers=workers, retries=retries,
                     resume=resume, progress=progress, **options)  # fmt: skip


def render_many(files, out_dir, *, client=None, workers=None, retries=0, resume=True, progress=None,
                **options) -> Manifest:  # fmt: skip
    """Render many meshes or rigs: ``NAME.png`` per file, as ``mimetic render`` writes it.

    Options: ``format`` ("png"), ``view`` ("all": a sheet of three), ``size`` (512), ``wireframe``,
    ``muscles`` (True), ``units``, ``manifest``, ``on_result``.
    """
    return run_batch("render", files, out_dir, client=client, workers=workers, retries=retries,
                     resume=resume, progress=progress, **options)  # fmt: skip


def speak_many(rigs, out_dir, *, client=None, workers=None, retries=0, resume=True, progress=None,
               **options) -> Manifest:  # fmt: skip
    """Lip-sync many rigs: ``NAME.glb`` (or ``.mp4``, ``.usda``, ``.json``, ``.csv``) per rig, as
    ``mimetic speak`` writes it.

    Options: one of ``text``, ``text_file`` or ``timings`` (required; per row for a different line
    per head), ``audio``, ``synthesize``, ``language`` ("en"), ``visemes``, ``format`` ("glb"),
    ``fps``, ``rate``, ``jaw``, ``lips``, ``eyes`` (True), ``seed``, ``baseline``, ``size``,
    ``engine``, ``manifest``, ``on_result``.
    """
    return run_batch("speak", rigs, out_dir, client=client, workers=workers, retries=retries,
                     resume=resume, progress=progress, **options)  # fmt: skip


def capture_many(rig, takes, out_dir, *, client=None, workers=None, retries=0, resume=True, progress=None,
                 **options) -> Manifest:  # fmt: skip
    """Solve many captured takes on one rig: ``NAME.json`` (the clip) and ``NAME.report.json`` per take,
    as ``mimetic capture solve RIG TAKE -o NAME.json --report NAME.report.json`` writes them. Each
    worker bakes the rig once and reuses it for every take it solves.

    Options: ``format`` ("json"; or csv, glb, usda, mp4), ``markers``, ``fps``, ``units``,
    ``neutral_frame``, ``channels`` ("all"), ``cutoff`` (8 Hz), ``robust`` (True), ``sparsity``,
    ``refine``, ``report`` (True), ``size``, ``engine``, ``manifest``, ``on_result``; a row may
    name another ``rig``. A row's residual is the median marker RMS in rig units.
    """
    return run_batch("capture", takes, out_dir, client=client, workers=workers, retries=retries,
                     resume=resume, progress=progress, rig=rig, **options)  # fmt: skip


# --------------------------------------------------------------------------- executors


SCHEDULER_TIMEOUT_S = 5
"""How long to wait for a ``--scheduler`` to answer before giving up (Dask's own default is 30 s)."""


def usable_cores() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def _distributed():
    """The ``distributed`` module, or None when the ``[batch]`` extra is not installed."""
    try:
        import distributed
    except ImportError:
        return None
    return distributed


@contextmanager
def _runner(client: Any, workers: int | None, n_items: int) -> Iterator[_DaskRunner | _PoolRunner]:
    """A runner for ``client`` (see the module docstring), open for the ``with`` block."""
    if client is None:
        n = max(1, min(workers or usable_cores(), n_items))
        distributed = _distributed()
        if distributed is None:
            log.info("dask is not installed: running on a ProcessPoolExecutor of %d processes", n)
            yield from _owned_pool(n)
            return
        with warnings.catch_warnings():  # its HTTP server moves off a busy port 8787 by itself
            warnings.filterwarnings("ignore", message="Port .* is already in use")
            cluster = distributed.LocalCluster(
                n_workers=n,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                silence_logs=logging.CRITICAL,  # workers log a run's end as errors; items report theirs
                env=WORKER_THREADS,
                preload=["mimetic.batch.jobs"],  # its dask_setup: the workers leave Ctrl-C to us
            )
        try:
            with distributed.Client(cluster) as local:
                yield _DaskRunner(local, "dask LocalCluster")
        finally:
            try:
                cluster.close()
            except TimeoutError:  # a worker slow to exit on a loaded machine: its nanny killed it
                log.info("the local Dask cluster took too long to close; its workers were stopped")
    elif isinstance(client, (str, os.PathLike)):
        distributed = _distributed()
        if distributed is None:
            raise MissingExtraError(
                f"running on the Dask scheduler {os.fspath(client)} needs the extra [batch] (dask): "
                f"{install_hint('batch')}"
            )
        address = os.fspath(client)
        check_scheduler(address)
        try:
            remote = distributed.Client(address, timeout=f"{SCHEDULER_TIMEOUT_S}s")
        except (OSError, TimeoutError) as error:
            raise _unreachable(address, error) from None
        with remote:
            yield _DaskRunner(remote, f"dask {address}")
    elif isinstance(client, Executor):
        n = getattr(client, "_max_workers", None) or usable_cores()
        yield _PoolRunner(client, n, f"{type(client).__name__}, {n} workers")
    elif callable(getattr(client, "submit", None)) and callable(getattr(client, "scheduler_info", None)):
        address = getattr(getattr(client, "scheduler", None), "address", None)
        yield _DaskRunner(client, f"dask {address or type(client).__name__}")
    else:
        raise TypeError(
            "client must be None, a scheduler address, a distributed.Client or a concurrent.futures "
            f"Executor; got {type(client).__name__}"
        )


def check_scheduler(address: str) -> None:
    """Check that a Dask scheduler answers at ``address`` ("tcp://HOST:PORT"), within
    about ``SCHEDULER_TIMEOUT_S``: the address is well formed, its host name resolves, its port is
    open and what listens there speaks Dask (a handshake, then the connection is closed).

    ``distributed.Client`` alone waits for ever on a port that is open but silent (its handshake read
    has no time limit), and reports an HTTP server (such as the dashboard's port 8787) as a memory error.

    Raises
    ------
    BatchError
        One line: what is wrong with the address and how to fix it.
    """
    import asyncio
    import socket
    from concurrent.futures import ThreadPoolExecutor

    from distributed import Security
    from distributed.comm import connect, parse_address, parse_host_port
    from distributed.comm.registry import get_backend

    scheme = ""
    try:
        scheme, location = parse_address(address)
        get_backend(scheme)
        if scheme in HOST_PORT_SCHEMES:
            host, port = parse_host_port(location)
            if not 0 < port < 65536:
                raise ValueError(f"port {port} is not in 1 … 65535")
    except ValueError as error:
        raise BatchError(
            f"{address!r} is not a Dask scheduler address ({' '.join(str(error).split())}); give "
            "tcp://HOST:PORT as `dask scheduler` prints it (its port is 8786 unless --port says otherwise)"
        ) from None
    if scheme in HOST_PORT_SCHEMES:
        try:
            socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)
        except socket.gaierror as error:
            raise BatchError(
                f"cannot reach the Dask scheduler at {address}: the host {host!r} is unknown "
                f"({error.strerror}); check its name, or give its IP address"
            ) from None
        try:  # Dask retries a refused connection until its timeout: say so at once
            socket.create_connection((host, port), timeout=SCHEDULER_TIMEOUT_S).close()
        except ConnectionRefusedError:
            raise BatchError(
                f"cannot reach the Dask scheduler at {address}: nothing listens on port {port} of {host} "
                "(connection refused); start `dask scheduler` there, or give the port it prints"
            ) from None
        except OSError as error:  # no route, or no answer in time (the host is down, or a firewall)
            raise _unreachable(address, error) from None

    security = Security().get_connection_args("client")  # TLS settings from Dask's config, as a Client's

    async def handshake() -> None:
        # connect's own timeout covers the connection (refused or dropped: OSError), not the handshake
        connecting = connect(address, timeout=SCHEDULER_TIMEOUT_S, **security)
        comm = await asyncio.wait_for(connecting, SCHEDULER_TIMEOUT_S + 1)
        await comm.close()

    try:
        with ThreadPoolExecutor(1) as thread:  # an event loop of its own: the caller may run one (Jupyter)
            thread.submit(asyncio.run, handshake()).result()
    except TimeoutError:  # connected, then nothing came back
        raise BatchError(
            f"the port of {address} is open but nothing answered within {SCHEDULER_TIMEOUT_S + 1} s; is it "
            "the scheduler's port (8786 by default; 8787 is its dashboard), and is the scheduler not stuck?"
        ) from None
    except OSError as error:
        raise _unreachable(address, error) from None
    except Exception:  # it answered, but not in Dask's protocol (an HTTP reply reads as a huge frame)
        raise BatchError(
            f"{address} answered, but not as a Dask scheduler; is it the scheduler's port (8786 by "
            "default; 8787 is its dashboard)?"
        ) from None


HOST_PORT_SCHEMES = ("tcp", "tls", "ws", "wss")
"""Dask's address schemes whose location is HOST:PORT."""


def _unreachable(address: str, error: BaseException) -> BatchError:
    """The error for a scheduler that refused the connection or did not accept it in time."""
    reason = " ".join(str(error).split()) or f"no answer within {SCHEDULER_TIMEOUT_S} s"
    return BatchError(
        f"cannot reach the Dask scheduler at {address} ({reason}); is `dask scheduler` running there, "
        "and its port open to this machine?"
    )


def _owned_pool(n: int) -> Iterator[_PoolRunner]:
    """A ProcessPoolExecutor of ``n`` spawned processes (one thread each), rebuilt when a worker dies."""
    from multiprocessing import get_context

    def make() -> ProcessPoolExecutor:
        return ProcessPoolExecutor(n, mp_context=get_context("spawn"), initializer=init_worker)

    runner = _PoolRunner(make(), n, f"ProcessPoolExecutor, {n} worker{'s' * (n != 1)}", make)
    clean = False
    try:
        yield runner
        clean = True
    finally:
        runner.pool.shutdown(wait=clean, cancel_futures=True)


def _failure(error: BaseException) -> Outcome:
    seconds = error.seconds if isinstance(error, ItemFailed) else 0.0
    return Outcome("failed", seconds, one_line(error))


class _DaskRunner:
    """Items as Dask futures (``retries=``), gathered as they complete."""

    def __init__(self, client: Any, name: str) -> None:
        self.client, self.name = client, name
        try:
            threads = client.nthreads()  # {worker address: threads}
        except Exception:  # a client that cannot say: only the name suffers
            return
        n = len(threads)
        total = sum(threads.values())
        self.name += f", {n} worker{'s' * (n != 1)} ({total} thread{'s' * (total != 1)})"
        if n == 0:
            warnings.warn(
                "the Dask scheduler has no workers yet; the items wait until one connects",
                MimeticWarning,
                stacklevel=4,
            )

    def run(self, items: list[Item], retries: int, done: Callable[[Item, Outcome], None]) -> None:
        from distributed import as_completed

        token = uuid.uuid4().hex[:10]
        keys = [f"mimetic-{item.kind}-{token}-{i}" for i, item in enumerate(items)]
        futures = self.client.map(execute, items, key=keys, retries=retries, pure=False)
        pending = {f.key: item for f, item in zip(futures, items, strict=True)}
        try:
            for future in as_completed(futures):
                item = pending.pop(future.key)
                try:
                    outcome = future.result()
                except Exception as error:
                    outcome = _failure(error)
                future.release()
                done(item, outcome)
        finally:
            if pending:
                self.client.cancel([f for f in futures if f.key in pending])


class _PoolRunner:
    """Items on a ``concurrent.futures`` executor, at most one per worker in flight (so a worker that
    dies fails only the items it and its neighbours were running; ``make`` rebuilds the pool)."""

    def __init__(self, pool: Executor, workers: int, name: str, make: Callable[[], Executor] | None = None):
        self.pool, self.workers, self.name, self.make = pool, workers, name, make

    def run(self, items: list[Item], retries: int, done: Callable[[Item, Outcome], None]) -> None:
        queue = deque(items)
        attempts: dict[str, int] = {}
        running: dict = {}  # future -> (item, pool generation)
        generation = 0
        while queue or running:
            while queue and len(running) < self.workers:
                item = queue.popleft()
                running[self.pool.submit(execute, item)] = (item, generation)
            finished, _ = wait(running, return_when=FIRST_COMPLETED)
            broken = False
            for future in finished:
                item, made_by = running.pop(future)
                try:
                    outcome = future.result()
                except Exception as error:
                    broken |= isinstance(error, BrokenExecutor) and made_by == generation
                    if attempts.get(item.name, 0) < retries:
                        attempts[item.name] = attempts.get(item.name, 0) + 1
                        queue.appendleft(item)
                        continue
                    outcome = _failure(error)
                done(item, outcome)
            if broken and self.make is not None:
                log.warning("a worker process died; starting a new pool for the remaining items")
                self.pool.shutdown(wait=False, cancel_futures=True)
                self.pool = self.make()
                generation += 1
