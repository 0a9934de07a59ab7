"""A batch on a cluster of separate processes, as on several machines: ``dask scheduler`` and two
``dask worker`` processes on 127.0.0.1 (``mimetic.testing.cluster``), and ``mimetic batch render
--scheduler tcp://127.0.0.1:PORT`` pointed at it; a worker killed in the middle of a batch.

The items render a small generated head (1,500 skin vertices) at 64 pixels: about 0.05 s each, so
the module's time is mostly the cluster's start (about 3 s) and the workers' first imports.
"""

from __future__ import annotations

import os
import shutil
import signal
import time
from pathlib import Path

import pytest

from mimetic.batch import render_many
from mimetic.mesh.io import save_mesh
from mimetic.testing import run_cli, small_head

ITEMS = 8
OPTIONS = ("--view", "front", "--size", "64")


@pytest.fixture(scope="module")
def heads(tmp_path_factory) -> Path:
    """``ITEMS`` copies of one small head (``h0.glb`` …) and its render by ``mimetic render``
    (``expected.png``), in this process."""
    folder = tmp_path_factory.mktemp("heads")
    save_mesh(small_head(0, 1_500).mesh, folder / "h0.glb")
    for k in range(1, ITEMS):
        shutil.copy(folder / "h0.glb", folder / f"h{k}.glb")
    result = run_cli("render", folder / "h0.glb", *OPTIONS, "-o", folder / "expected.png")
    assert result.exit_code == 0, result.output
    return folder


def executed(address: str) -> dict[str, int]:
    """Tasks each worker of the cluster at ``address`` has run so far, by worker name."""
    import distributed

    with distributed.Client(address, timeout="10s") as client:
        names = {a: w["name"] for a, w in client.scheduler_info()["workers"].items()}
        counts = client.run(lambda dask_worker: dask_worker.state.executed_count)
    return {names[a]: n for a, n in counts.items()}


def test_batch_cli_runs_on_a_scheduler_and_two_worker_processes(loopback, heads, tmp_path):
    before = executed(loopback.address)
    out = tmp_path / "out"
    result = run_cli(
        "batch", "render", heads / "h?.glb", *OPTIONS, "--scheduler", loopback.address, "-o", out
    )
    assert result.exit_code == 0, result.output
    assert f"render: {ITEMS} ok, 0 failed, 0 skipped" in result.output
    after = executed(loopback.address)
    ran = {name: after[name] - before.get(name, 0) for name in loopback.workers}
    assert sorted(after) == sorted(loopback.workers)
    assert sum(ran.values()) == ITEMS and min(ran.values()) >= 1, ran  # both workers did work
    expected = (heads / "expected.png").read_bytes()
    for k in range(ITEMS):
        assert (out / f"h{k}.png").read_bytes() == expected, k
        assert (out / ".mimetic-batch" / f"h{k}.json").is_file(), k
    assert (out / "batch-render.csv").read_text().count(",ok,") == ITEMS


def test_a_worker_killed_mid_batch_keeps_the_finished_outputs(loopback, heads, tmp_path):
    """Kill one worker process (SIGKILL) once the first item is back: Dask's nanny starts it again and
    its unfinished items run elsewhere; items reported before the kill are not run again."""
    import distributed

    with distributed.Client(loopback.address, timeout="10s") as client:
        pids = client.run(os.getpid)  # {worker address: pid of the worker process (not its nanny)}
    victim = max(pids.values())
    finished = {}  # item → mtime of its completion record when its row came back

    def on_result(row) -> None:
        record = row.outputs[0].parent / ".mimetic-batch" / f"{row.item}.json"
        finished[row.item] = record.stat().st_mtime_ns
        if len(finished) == 1:
            os.kill(victim, signal.SIGKILL)

    manifest = render_many(
        [heads / f"h{k}.glb" for k in range(ITEMS)], tmp_path, client=loopback.address, view="front",
        size=64, on_result=on_result,
    )  # fmt: skip
    assert [r.status for r in manifest.rows] == ["ok"] * ITEMS, [r.error for r in manifest.failed]
    expected = (heads / "expected.png").read_bytes()
    for k in range(ITEMS):
        assert (tmp_path / f"h{k}.png").read_bytes() == expected, k
        record = tmp_path / ".mimetic-batch" / f"h{k}.json"
        assert record.stat().st_mtime_ns == finished[f"h{k}"], f"h{k} ran again after it was reported"
    assert restarted(loopback, victim), f"no worker took the place of the killed one ({victim})"


def restarted(cluster, victim: int, timeout_s: float = 30) -> bool:
    """Whether the cluster has all its workers again, none of them process ``victim``, within
    ``timeout_s`` (the nanny restarts a killed worker; the scheduler may hear of it late)."""
    import distributed

    deadline = time.monotonic() + timeout_s
    with distributed.Client(cluster.address, timeout="10s") as client:
        while time.monotonic() < deadline:
            try:
                pids = client.run(os.getpid)
            except OSError:  # a worker the scheduler still lists, but gone
                pids = {}
            if len(pids) == len(cluster.workers) and victim not in pids.values():
                return True
            time.sleep(0.2)
    return False
