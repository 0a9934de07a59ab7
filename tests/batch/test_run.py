"""End-to-end tests of ``mimetic batch rig`` and ``rig_many``: a local Dask cluster, failures, resume,
the process-pool fallback, retries.

The heads are generated at the smallest resolution (1,500 skin vertices, 3,170 in all) and rigged on a
reference of the same size, with landmark files, so the whole file takes well under a minute.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import threading
import time
import warnings
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import pytest

from mimetic.batch import BatchError, rig_many, run, run_batch
from mimetic.errors import MimeticError, MissingExtraError
from mimetic.fit.landmarks import write_landmarks
from mimetic.mesh.io import save_mesh
from mimetic.rig.format import load_rig
from mimetic.rig.model import rigs_equal
from mimetic.tasks import BATCH_TASKS
from mimetic.tasks.base import Result, Task, TaskOptions
from mimetic.testing import head_landmarks, run_cli, small_head

RESOLUTION = 1_500
SEEDS = (0, 1, 2)
BROKEN = "broken.glb: not a GLB file (it does not start with 'glTF'). Check the file's format."


@pytest.fixture(scope="module")
def heads(tmp_path_factory) -> Path:
    """Three generated heads (GLB) with their landmark files, and a corrupt GLB among them."""
    folder = tmp_path_factory.mktemp("heads")
    for seed in SEEDS:
        head = small_head(seed, RESOLUTION)
        save_mesh(head.mesh, folder / f"head{seed}.glb")
        write_landmarks(head_landmarks(head), folder / f"head{seed}.json")
    (folder / "broken.glb").write_bytes(b"not a mesh at all")
    return folder


@pytest.fixture(scope="module")
def rigged(heads, cluster, tmp_path_factory):
    """``mimetic batch rig`` of the four heads on the 2-worker cluster: (CLI result, OUTDIR)."""
    out = tmp_path_factory.mktemp("rigs")
    result = run_cli(
        "batch", "rig", heads / "*.glb", "--landmarks", heads / "{stem}.json", "--resolution", RESOLUTION,
        "--scheduler", cluster.scheduler_address, "-o", out,
    )  # fmt: skip
    return result, out


def test_batch_rig_fails_the_corrupt_head_alone_and_exits_1(rigged, heads):
    result, out = rigged
    assert result.exit_code == 1
    assert f"failed  broken: {heads / BROKEN}" in result.output
    assert "Traceback" not in result.output
    assert "rig: 3 ok, 1 failed, 0 skipped" in result.output
    manifest = json.loads((out / "batch-rig.json").read_text())
    assert manifest["counts"] == {"ok": 3, "failed": 1, "skipped": 0}
    rows = {row["item"]: row for row in manifest["rows"]}
    assert list(rows) == ["broken", "head0", "head1", "head2"]  # input order: the sorted glob
    assert rows["broken"]["status"] == "failed" and rows["broken"]["outputs"] == []
    assert rows["broken"]["error"] == str(heads / BROKEN)  # the MeshError's own line
    for seed in SEEDS:
        row = rows[f"head{seed}"]
        assert row["status"] == "ok" and row["error"] == "" and row["seconds"] > 0
        assert row["outputs"] == [f"head{seed}.mrig", f"head{seed}.fit.json", f"head{seed}.fit.png"]
        assert 0 < row["residual"] < 0.1  # mean surface residual, % of the head diagonal
        report = json.loads((out / f"head{seed}.fit.json").read_text())
        assert report["accepted"] and report["mean_pct"] == row["residual"]
        assert (out / ".mimetic-batch" / f"head{seed}.json").is_file()
    assert not (out / ".mimetic-batch" / "broken.json").exists()  # a failure leaves no record
    lines = (out / "batch-rig.csv").read_text().splitlines()
    assert lines[0] == "item,status,seconds,error,residual,input,outputs,warnings" and len(lines) == 5
    assert lines[1].startswith("broken,failed,")


def test_batch_rig_writes_what_mimetic_rig_writes_bit_for_bit(rigged, heads, tmp_path):
    """save_rig is deterministic (fixed zip times, no clock in the file), so the bytes are compared."""
    _, out = rigged
    single = tmp_path / "head1.mrig"
    result = run_cli(
        "rig",
        heads / "head1.glb",
        "--landmarks",
        heads / "head1.json",
        "--resolution",
        RESOLUTION,
        "-o",
        single,
    )
    assert result.exit_code == 0, result.output
    for name in ("head1.mrig", "head1.fit.json", "head1.fit.png"):
        assert (out / name).read_bytes() == (tmp_path / name).read_bytes(), name
    assert rigs_equal(load_rig(out / "head1.mrig"), load_rig(single))


def test_rig_many_resumes_only_the_items_left_unfinished(rigged, heads, client, tmp_path):
    _, done = rigged
    out = tmp_path / "moved"
    shutil.copytree(done, out)  # a finished run, in a folder that moved
    (out / "head1.mrig").unlink()  # interrupted: an output and its record gone,
    (out / ".mimetic-batch" / "head1.json").unlink()
    stale = out / ".head1.mrig.x7k2p9.tmp"  # and a writer's half-written temporary file left behind
    stale.write_bytes(b"half a rig")
    picture = out / "head2.fit.png"  # an output changed after its record was written
    picture.write_bytes(picture.read_bytes()[:100])
    seen = []
    manifest = rig_many(
        heads / "head*.glb", out, client=client, landmarks="{dir}/{stem}.json", resolution=RESOLUTION,
        on_result=lambda row: seen.append((row.item, row.status)),
    )  # fmt: skip
    assert [(r.item, r.status) for r in manifest.rows] == [
        ("head0", "skipped"),
        ("head1", "ok"),
        ("head2", "ok"),
    ]
    assert seen[0] == ("head0", "skipped") and sorted(seen[1:]) == [("head1", "ok"), ("head2", "ok")]
    before = {row["item"]: row for row in json.loads((done / "batch-rig.json").read_text())["rows"]}
    assert manifest.rows[0].residual == before["head0"]["residual"]  # a skipped item's, from its record
    assert not stale.exists()  # cleared when its item ran again
    for name in ("head1.mrig", "head2.fit.png"):
        assert (out / name).read_bytes() == (done / name).read_bytes()
    assert manifest.executor.startswith("dask tcp://") and "2 workers" in manifest.executor
    again = rig_many(
        heads / "head*.glb", out, client=client, landmarks="{dir}/{stem}.json", resolution=RESOLUTION
    )
    assert [r.status for r in again.rows] == ["skipped"] * 3 and again.executor == "nothing to run"
    assert json.loads(again.json_path.read_text())["counts"]["skipped"] == 3


def test_rig_many_without_dask_runs_on_a_process_pool(rigged, heads, tmp_path, monkeypatch):
    _, done = rigged
    monkeypatch.setitem(sys.modules, "distributed", None)  # `import distributed` now fails
    with pytest.raises(MissingExtraError, match=r"extra \[batch\]"):
        rig_many([heads / "head0.glb"], tmp_path / "never", client="tcp://127.0.0.1:8786")
    manifest = rig_many(
        [heads / "head0.glb", heads / "broken.glb"], tmp_path, workers=2, landmarks="{dir}/{stem}.json",
        resolution=RESOLUTION,
    )  # fmt: skip
    assert manifest.executor == "ProcessPoolExecutor, 2 workers"
    assert [(r.item, r.status) for r in manifest.rows] == [("head0", "ok"), ("broken", "failed")]
    assert manifest.failed[0].error == str(heads / BROKEN)
    assert (tmp_path / "head0.mrig").read_bytes() == (done / "head0.mrig").read_bytes()


# --------------------------------------------------------------------------- retries, without meshes


@dataclass(frozen=True)
class FlakyOptions(TaskOptions):
    """A task with no options of its own."""


@pytest.fixture
def flaky(monkeypatch, tmp_path):
    """A batch kind "flaky" whose items fail unexpectedly on their first attempt (an OSError), or with
    bad input every time (a MimeticError) when their input's name says "bad"; counts attempts per item."""
    attempts: dict[str, int] = {}

    def run(source, output, options, progress=None) -> Result:
        name = Path(source).stem
        attempts[name] = attempts.get(name, 0) + 1
        if "bad" in name:
            raise MimeticError(f"{name}: bad input, fix it")
        if attempts[name] == 1:
            raise OSError("the file server hiccuped\n(try again)")
        Path(output).write_text("done")
        return Result((Path(output),), "done", 0.5)

    monkeypatch.setitem(BATCH_TASKS, "flaky", Task("flaky", FlakyOptions, run, (".txt",)))
    for name in ("a", "b", "bad"):
        (tmp_path / f"{name}.in").write_text("x")
    return tmp_path, attempts


def test_run_batch_retries_unexpected_failures_but_not_bad_input(flaky):
    folder, attempts = flaky
    with ThreadPoolExecutor(2) as pool:
        once = run_batch("flaky", folder / "*.in", folder / "once", client=pool)
        assert [(r.item, r.status, r.error) for r in once.rows] == [
            ("a", "failed", "OSError: the file server hiccuped (try again)"),  # one line
            ("b", "failed", "OSError: the file server hiccuped (try again)"),
            ("bad", "failed", "bad: bad input, fix it"),
        ]
        attempts.clear()
        twice = run_batch("flaky", folder / "*.in", folder / "twice", client=pool, retries=1)
    assert [r.status for r in twice.rows] == ["ok", "ok", "failed"] and twice.rows[0].residual == 0.5
    assert attempts == {"a": 2, "b": 2, "bad": 1}  # bad input is a verdict: not retried


def test_run_batch_retries_on_dask(flaky):
    distributed = pytest.importorskip("distributed")
    folder, attempts = flaky
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Port .* is already in use")  # the session cluster's
        cluster = distributed.LocalCluster(n_workers=1, processes=False, dashboard_address=None)
    with cluster:
        with distributed.Client(cluster) as client:  # threads in this process: the patched tasks
            manifest = run_batch("flaky", folder / "*.in", folder / "out", client=client, retries=2)
    assert [r.status for r in manifest.rows] == ["ok", "ok", "failed"]
    assert attempts == {"a": 2, "b": 2, "bad": 1}


def test_batch_cli_refuses_bad_usage(heads, tmp_path):
    assert run_cli("batch", "rig", "-o", tmp_path).exit_code == 2  # no inputs
    both = run_cli(
        "batch", "rig", heads / "head0.glb", "--workers", 2, "--scheduler", "tcp://x:1", "-o", tmp_path
    )
    assert both.exit_code == 2 and "not both" in both.output
    nothing = run_cli("batch", "rig", heads / "*.stl", "-o", tmp_path)
    assert nothing.exit_code == 1 and "no file matches" in nothing.output
    with pytest.raises(BatchError, match="not both"):
        rig_many([heads / "head0.glb"], tmp_path, client="tcp://x:1", workers=2)


def test_every_batch_command_help_shows_examples():
    for sub in ("rig", "animate", "render", "speak", "capture"):
        result = run_cli("batch", sub, "--help")
        assert result.exit_code == 0 and "Examples:" in result.output, sub
        assert f"mimetic batch {sub}" in result.output, sub


# --------------------------------------------------------------- interrupts and unreachable clusters


def _free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_an_unreachable_scheduler_fails_within_10_s_and_leaves_nothing(heads, tmp_path):
    out = tmp_path / "never"
    start = time.monotonic()
    result = run_cli(
        "batch", "render", heads / "head0.glb", "--scheduler", f"tcp://127.0.0.1:{_free_port()}", "-o", out
    )
    assert time.monotonic() - start < 10
    assert result.exit_code == 1
    (line,) = result.output.strip().splitlines()
    assert "cannot reach the Dask scheduler at tcp://127.0.0.1:" in line
    assert not out.exists()  # no empty output folder left behind


@pytest.fixture
def listeners():
    """Two ports on 127.0.0.1 that are not a Dask scheduler's: one that accepts connections and never
    says anything (a stuck process, another service waiting for its client), one that answers as an
    HTTP server does (the dashboard's port): ``(silent port, http port)``."""
    silent, http = socket.socket(), socket.socket()
    for server in (silent, http):
        server.bind(("127.0.0.1", 0))
        server.listen()

    def answer() -> None:
        while True:
            try:
                connection, _ = http.accept()
            except OSError:  # closed at the end of the test
                return
            with connection:
                connection.sendall(b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\n\r\n")

    threading.Thread(target=answer, daemon=True).start()
    with silent, http:
        yield silent.getsockname()[1], http.getsockname()[1]


def test_check_scheduler_says_what_is_wrong_with_each_address(listeners, monkeypatch):
    pytest.importorskip("distributed")
    monkeypatch.setattr(run, "SCHEDULER_TIMEOUT_S", 1)
    silent, http = listeners
    cases = {
        "127.0.0.1": "is not a Dask scheduler address (missing port number",
        "http://127.0.0.1:8786": "is not a Dask scheduler address (unknown address scheme 'http'",
        "tcp://127.0.0.1:99999": "is not a Dask scheduler address (port 99999 is not in 1 … 65535)",
        f"tcp://127.0.0.1:{_free_port()}": "nothing listens on port",
        f"tcp://127.0.0.1:{silent}": "is open but nothing answered within 2 s",
        f"tcp://127.0.0.1:{http}": "answered, but not as a Dask scheduler",
    }
    for address, message in cases.items():
        start = time.monotonic()
        with pytest.raises(BatchError) as raised:
            run.check_scheduler(address)
        assert time.monotonic() - start < 5, address
        (line,) = str(raised.value).splitlines()
        assert message in line, line
        assert "8786" in line or "start `dask scheduler` there" in line, line  # and how to fix it


def test_ctrl_c_in_a_batch_is_one_line_and_exit_code_130(tmp_path):
    """SIGINT to the whole process group, as a terminal's Ctrl-C sends it, once the items run: the
    batch says "interrupted" and nothing else (its workers stay quiet), exit code 130."""
    if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:  # inherited by the batch, which then never hears it
        pytest.skip("SIGINT is ignored in this process (a shell's background job): Ctrl-C cannot be tested")
    head = small_head(0, RESOLUTION)
    for k in range(40):
        save_mesh(head.mesh, tmp_path / f"h{k:02d}.obj")
    command = [sys.executable, "-c", "from mimetic.command import main; main()", "batch", "render",
               str(tmp_path / "h*.obj"), "--workers", "2", "-o", str(tmp_path / "out")]  # fmt: skip
    batch = subprocess.Popen(command, stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                             start_new_session=True)  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        line = ""
        while "ok" not in line and time.monotonic() < deadline and batch.poll() is None:
            line = batch.stderr.readline()  # piped: one line per step ("render: 1 ok")
        assert "ok" in line, "the batch never reported a finished item"
        os.killpg(batch.pid, signal.SIGINT)
        _, err = batch.communicate(timeout=60)
    finally:
        if batch.poll() is None:
            os.killpg(batch.pid, signal.SIGKILL)
    assert batch.returncode == 130, err
    assert err.strip().splitlines()[-1] == "interrupted"
    assert "Traceback" not in err and "KeyboardInterrupt" not in err, err
