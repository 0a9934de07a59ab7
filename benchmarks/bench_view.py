"""Benchmark the viewer's slider → mesh update (``mimetic view``, ``mimetic.view.web``).

    python benchmarks/bench_view.py [--quick] [--no-browser]

Heads: the default head (``make_head()`` rigged by ``build_rig``) and, without ``--quick``, the
fitted ICT-FaceKit head (``rig_head`` on ``../shared/data``; skipped with a note when the data is
absent). Each rig is saved as .mrig and opened with ``start(path, port=0)``, as ``mimetic view``
does. Engines: wire, vector, fem and tissue (posed by its baked basis, ``session.BAKED_ENGINES``),
each prepared once and timed apart ("engine preparation, once"). ``--quick``: the default head,
the wire engine, fewer moves (under a minute).

A move sets a channel slider's value from Python (``viewer.sliders[("channels", name)].value``,
which runs the same callback as a browser's move), alternating ``zygomatic_major_L`` and
``jaw_open`` over ``FRACTIONS`` of their ranges, after a warm-up. Measured per move:

1. without a client: the callback's time, from just before the assignment to its return (session
   pose, deformation, the vertex updates queued to viser, the status text), and
   ``viewer.last_update_ms`` (the viewer's own clock over pose, deformation and queueing);
2. with a headless chromium on the page (playwright; skipped with a note without it): the
   callback again, the time until the server hands the frame carrying the vertices to the socket
   ("frame sent": ``websockets``' ``Connection.send`` is wrapped to log each call), and until the
   browser has it ("frame in the browser": viser's client worker, which holds the websocket, is
   given a prelude that timestamps each message; its clock is mapped to ``perf_counter`` by the
   fastest of ``CALIBRATIONS`` round trips to the worker). Moves are ``GAP_S`` apart, so each
   frame travels alone. The same with ``viewer.server.flush()`` right after the assignment,
   which skips viser's message window (what ``_refresh`` would gain by flushing).

Why a client matters: ``queue_message`` only pushes a message into viser's broadcast buffer
(``AsyncMessageBuffer.push``: a dict insert and de-duplication), client or not. Serialisation
(msgpack + zstd, arrays appended raw) happens per connected client in ``_message_producer`` on the
event-loop thread, after the callback has returned; and the producer, woken by a message, first
waits one window (``window_duration_sec`` = 1/60 s) unless flushed. The callback time is thus the
same code path with or without a client, but leaves out serialisation and the window, which
"frame sent" includes. The page's main thread is not timed: chromium draws WebGL with SwiftShader
here (no GPU), which takes most of a core and holds the main thread for up to ~0.5 s at a time,
so when the page has the batch says more about software rendering than about the viewer.

Baselines, measured in the same run: (a) the floor, the engine alone on the move's pose
(``viewer.deformers.vertices(engine, pose)``: ``engine.deform(pose)`` as float32, or the baked
basis for tissue), interleaved with the moves; (b) the naive update, re-adding every part as a
new mesh (``scene.add_mesh_simple`` with the new vertices and the part's faces, after the same
pose and deformation): interleaved and hidden without a client, shown in place of the parts with
the browser.

Tables per head: case | median | p90 | ÷ floor | ÷ naive (ratios of medians; ÷ naive against the
naive update's time of the same kind: callback, frame sent or in the browser). Then the goals:
slider move → updated mesh ≤ 50 ms for the default head and ≤ 100 ms for ICT, server side,
judged on the median callback without a client and on the median "frame sent" with the browser
(p90 beside them). The load average, and the share of the cores this process, the browser and
other processes used while a head was measured, are printed: the machine is shared.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import itertools
import os
import shutil
import statistics
import tempfile
import time
import warnings
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import websockets.asyncio.connection

import report
from bench_basis import table
from bench_capture import Contention
from mimetic.engines import ENGINES
from mimetic.head.model import make_head
from mimetic.rig.format import save_rig
from mimetic.rig.recipe import build_rig
from mimetic.testing import CHROMIUM, CHROMIUM_ARGS, ict_folder, ict_landmarks, load_ict
from mimetic.view.session import BAKED_ENGINES, Deformers
from mimetic.view.web import Viewer, start

TABLES: list[str] = []
"""The per-head tables written to ``out/view.md`` (``report.save``, after the goals), in order."""
DEFAULT = "default head"
ICT = "ICT-FaceKit"
GOAL_MS = {DEFAULT: 50.0, ICT: 100.0}
"""The issue's goals: slider move → updated mesh, server side."""
MOVES, QUICK_MOVES = 50, 15
"""Moves per case without a client (each round: a move, the floor, the naive update)."""
BROWSER_MOVES, QUICK_BROWSER_MOVES = 30, 10
"""Moves per case with the browser (each waits for delivery and ``GAP_S``)."""
WARMUP, BROWSER_WARMUP = 5, 3
CHANNELS = ("zygomatic_major_L", "jaw_open")
FRACTIONS = (0.3, 0.6, 0.45, 0.75)
"""Slider positions, as fractions of the channel's range; a channel never gets the same value twice
in a row."""
GAP_S = 0.12
"""Least time between moves with the browser: each frame travels alone, and viser's producer is idle
(waiting for a message) when a move comes, as when a user drags a slider after a pause."""
CALIBRATIONS = 15
"""Round trips to the client worker that map its clock to ``perf_counter`` (the fastest is used)."""
VIEWPORT = {"width": 400, "height": 300}
"""Small: the page renders with SwiftShader (no GPU) on the same two cores as the server."""
INIT_SCRIPT = """
(() => {
  const prelude = `
    self.benchFrames = [];  // [clock ms, bytes] of each websocket message, as the worker gets it
    const BenchSocket = self.WebSocket;
    self.WebSocket = class extends BenchSocket {
      constructor(...args) {
        super(...args);
        this.addEventListener("message", (event) => {
          const bytes = event.data.byteLength ?? event.data.size ?? event.data.length;
          self.benchFrames.push([performance.timeOrigin + performance.now(), bytes]);
        });
      }
    };
  `;
  const Base = window.Worker;
  window.Worker = class extends Base {
    constructor(url, options) {
      // viser's client worker is an inline module (a blob URL): read it, put the prelude first.
      const request = new XMLHttpRequest();
      request.open("GET", String(url), false);
      request.send();
      const code = new Blob([prelude + request.responseText], {type: "text/javascript"});
      super(URL.createObjectURL(code), options);
    }
  };
})();
"""
"""Log in viser's client worker (which holds the websocket) when it gets each message, on its clock
(``performance.timeOrigin + now()``): the worker's code is read and given a prelude that wraps its
``WebSocket``. The log is read from the worker itself, so the page's main thread (busy drawing in
software) is never waited on."""
NEXT_FRAME = """
([threshold, seen]) => new Promise((resolve) => {
  const check = () => {
    const big = self.benchFrames.filter((f) => f[1] > threshold);
    if (big.length > seen) resolve([big[seen][0], big.length]);
    else setTimeout(check, 1);
  };
  check();
})
"""
"""Wait in the worker for its big frame number ``seen``: (its time, the big frames so far)."""


# --------------------------------------------------------------------------- timing


SENT: list[tuple[float, int]] = []
"""(perf_counter, bytes) of every binary websocket frame the server sends, when it calls ``send``
(serialised; the write follows at once, but ``send`` may return only after the browser has it)."""


def log_sends() -> None:
    """Wrap ``websockets``' ``Connection.send`` (viser's producer awaits it per frame) to fill SENT."""
    send = websockets.asyncio.connection.Connection.send
    if getattr(send, "logged", False):
        return

    async def logged(self, message, text=None):
        if isinstance(message, bytes | bytearray | memoryview):
            SENT.append((time.perf_counter(), len(message)))
        await send(self, message, text)

    logged.logged = True
    websockets.asyncio.connection.Connection.send = logged


def _cpu_seconds(pid: str) -> tuple[int, float] | None:
    """(parent pid, user + system CPU seconds) of process ``pid`` from /proc; None when it is gone."""
    try:
        with open(f"/proc/{pid}/stat") as file:
            fields = file.read().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return int(fields[1]), (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def descendants_cpu() -> float:
    """CPU seconds used so far by the processes this one started (playwright's driver, chromium)."""
    stats = {int(p): s for p in os.listdir("/proc") if p.isdigit() and (s := _cpu_seconds(p)) is not None}
    children: dict[int, list[int]] = {}
    for pid, (parent, _) in stats.items():
        children.setdefault(parent, []).append(pid)
    total, stack = 0.0, list(children.get(os.getpid(), []))
    while stack:
        pid = stack.pop()
        total += stats[pid][1]
        stack += children.get(pid, [])
    return total


class Load(Contention):
    """How busy the cores were since ``start``: this process, the processes it started (the browser)
    and the others (bench_capture's ``Contention`` with the browser told apart)."""

    @staticmethod
    def _sample() -> tuple[float, ...] | None:
        base = Contention._sample()
        return None if base is None else (*base, descendants_cpu())

    def note(self) -> str:
        end = self._sample()
        if self.start is None or end is None:
            return "load unknown"
        total, idle, ours, started = (b - a for a, b in zip(self.start, end, strict=True))
        total = max(total, 1e-9)
        others = max(0.0, total - idle - ours - started) / total
        text = f"this process kept {ours / total:.0%} of the cores busy, other processes {others:.0%}"
        return text.replace(", other", f", the browser {started / total:.0%}, other") if started > 0 else text


def summary(samples: list[float]) -> tuple[float, float]:
    """Median and 90th percentile (s)."""
    return statistics.median(samples), float(np.percentile(samples, 90))


def ms(seconds: float) -> str:
    return f"{seconds * 1e3:,.2f} ms" if seconds < 0.1 else f"{seconds * 1e3:,.0f} ms"


@contextlib.contextmanager
def quiet() -> Iterator[None]:
    """Hide viser's banner and "Server stopped" (printed whatever ``verbose`` says)."""
    with contextlib.redirect_stdout(io.StringIO()):
        yield


# --------------------------------------------------------------------------- cases


MOVE_COUNT = itertools.count()
"""Moves so far: the sequence runs on across cases."""


def moves(viewer: Viewer, n: int) -> Iterator[tuple[str, object, float]]:
    """(channel, slider, value) of ``n`` moves, alternating CHANNELS over FRACTIONS of their ranges;
    never to the value the slider has (viser skips the callback of an unchanged value)."""
    made = 0
    for k in MOVE_COUNT:
        if made == n:
            return
        name = CHANNELS[k % len(CHANNELS)]
        channel = viewer.rig.channel(name)
        slider = viewer.sliders[("channels", name)]
        fraction = FRACTIONS[(k // len(CHANNELS)) % len(FRACTIONS)]
        value = float(channel.minimum + fraction * (channel.maximum - channel.minimum))
        if value != slider.value:
            made += 1
            yield name, slider, value


class Naive:
    """The naive update: pose, deform, and re-add every part as a new mesh under ``/naive``."""

    def __init__(self, viewer: Viewer) -> None:
        self.viewer = viewer
        self.parts = [
            (used, handle.name.rsplit("/", 1)[-1], np.asarray(handle.faces), handle.color)
            for used, handle in viewer.parts
        ]
        self.handles: list = []

    def __call__(self, visible: bool = False) -> None:
        viewer = self.viewer
        vertices = viewer.deformers.vertices(viewer.engine, viewer.session.pose())
        scene = viewer.server.scene
        with viewer.server.atomic():
            self.handles = [
                scene.add_mesh_simple(
                    f"/naive/{name}", vertices[used], faces, color=color, side="double", visible=visible
                )
                for used, name, faces, color in self.parts
            ]

    def remove(self) -> None:
        for handle in self.handles:
            handle.remove()
        self.handles = []


def without_client(viewer: Viewer, n: int) -> dict[str, list[float]]:
    """Per round: a move (callback time, ``last_update_ms``), the floor on its pose, the naive update."""
    naive = Naive(viewer)
    samples: dict[str, list[float]] = {"callback": [], "last_update": [], "floor": [], "naive": []}
    for k, (_, slider, value) in enumerate(moves(viewer, WARMUP + n)):
        start = time.perf_counter()
        slider.value = value
        callback = time.perf_counter() - start
        pose = viewer.session.pose()
        start = time.perf_counter()
        viewer.deformers.vertices(viewer.engine, pose)
        floor = time.perf_counter() - start
        start = time.perf_counter()
        naive()
        naive_s = time.perf_counter() - start
        if k >= WARMUP:
            samples["callback"].append(callback)
            samples["last_update"].append(viewer.last_update_ms / 1e3)
            samples["floor"].append(floor)
            samples["naive"].append(naive_s)
    naive.remove()
    return samples


class Browser:
    """A headless chromium on the viewer's page, counting the big frames its client worker has got."""

    def __init__(self, playwright, port: int, threshold: int) -> None:
        self.threshold = threshold
        self.browser = playwright.chromium.launch(executable_path=CHROMIUM, args=list(CHROMIUM_ARGS))
        self.page = self.browser.new_page(viewport=VIEWPORT)
        self.page.add_init_script(INIT_SCRIPT)
        self.page.goto(f"http://127.0.0.1:{port}/")
        deadline = time.perf_counter() + 60
        while not (
            workers := [w for w in self.page.workers if w.evaluate("Array.isArray(self.benchFrames)")]
        ):
            if time.perf_counter() > deadline:
                raise RuntimeError("viser's client worker did not start")
            self.page.wait_for_timeout(100)
        self.worker = workers[0]
        self.seen = 0
        self._wait()  # the scene's replay
        self.settle()
        self.offset_ms, self.uncertainty_ms = self.calibrate()

    def calibrate(self) -> tuple[float, float]:
        """The client worker's clock (ms) − 1000 · perf_counter, from the fastest of CALIBRATIONS round
        trips to the worker; and half that round trip (ms), the offset's uncertainty."""
        trips = []
        for _ in range(CALIBRATIONS):
            before = time.perf_counter()
            worker_ms = self.worker.evaluate("performance.timeOrigin + performance.now()")
            after = time.perf_counter()
            trips.append((after - before, worker_ms - 500 * (before + after)))
        trip, offset = min(trips)
        return offset, 500 * trip

    def settle(self) -> None:
        """Let pending frames arrive (an update of unchanged vertices sends nothing), then count them."""
        time.sleep(0.5)
        self.seen = self.worker.evaluate(f"self.benchFrames.filter((f) => f[1] > {self.threshold}).length")

    def _wait(self) -> float:
        """The worker's clock (ms) when it got the next big frame."""
        worker_ms, self.seen = self.worker.evaluate(NEXT_FRAME, [self.threshold, self.seen])
        return worker_ms

    def next_frame(self) -> float:
        """perf_counter time (s) at which the client worker got the next big frame."""
        return (self._wait() - self.offset_ms) / 1e3

    def close(self) -> None:
        self.browser.close()


def sent_after(start: float, n_sent: int, threshold: int) -> tuple[float, int]:
    """perf_counter time and size of the first big frame sent after SENT[n_sent] (waits up to 5 s for
    the log)."""
    deadline = time.perf_counter() + 5
    while time.perf_counter() < deadline:
        big = [(t, size) for t, size in SENT[n_sent:] if size > threshold]
        if big:
            return big[0]
        time.sleep(0.001)
    raise RuntimeError(f"no frame over {threshold:,} bytes was sent after the move at {start:.3f}")


def with_browser(viewer: Viewer, browser: Browser, n: int, kind: str) -> dict[str, list[float]]:
    """Moves of ``kind`` ("move", "flush" or "naive") one at a time with the browser connected:
    times (s from just before the assignment) until the callback returned, the frame was sent and
    the client worker had it; and the frame's size (bytes)."""
    threshold = browser.threshold
    naive = Naive(viewer) if kind == "naive" else None
    if naive is not None:
        for _, handle in viewer.parts:
            handle.visible = False
        browser.settle()
    browser.offset_ms, browser.uncertainty_ms = browser.calibrate()
    samples: dict[str, list[float]] = {"callback": [], "sent": [], "worker": [], "bytes": []}
    for k, (name, slider, value) in enumerate(moves(viewer, BROWSER_WARMUP + n)):
        n_sent = len(SENT)
        start = time.perf_counter()
        if naive is not None:
            viewer.session.set_channel(name, value)
            naive(visible=True)
        else:
            slider.value = value
        callback = time.perf_counter() - start
        if kind == "flush":
            viewer.server.flush()
        worker = browser.next_frame()
        sent, size = sent_after(start, n_sent, threshold)
        if k >= BROWSER_WARMUP:
            samples["callback"].append(callback)
            samples["sent"].append(sent - start)
            samples["bytes"].append(size)
            samples["worker"].append(worker - start)
        time.sleep(max(0.0, start + GAP_S - time.perf_counter()))
    if naive is not None:
        naive.remove()
        for _, handle in viewer.parts:
            handle.visible = True
        viewer.session.reset()
        viewer._refresh()
        browser.settle()
    return samples


# --------------------------------------------------------------------------- heads


def heads(quick: bool) -> Iterator[tuple[str, object, float]]:
    """(label, rig, seconds to build it)."""
    start = time.perf_counter()
    rig = build_rig(make_head())
    yield DEFAULT, rig, time.perf_counter() - start
    if quick:
        return
    folder = ict_folder()
    if folder is None:
        print("\nICT-FaceKit not in the shared data (../shared/data/ict-facekit): ICT skipped")
        return
    from mimetic.fit.pipeline import rig_head

    start = time.perf_counter()
    neutral, meta = load_ict(folder)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rig = rig_head(neutral, ict_landmarks(neutral, meta)).rig
    yield ICT, rig, time.perf_counter() - start


def browser_available() -> str | None:
    """None when playwright and chromium are there, else why not."""
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "playwright is not installed"
    if not Path(CHROMIUM).exists():
        return f"{CHROMIUM} is missing"
    return None


def bench_head(
    label: str, rig, build_s: float, engines: tuple[str, ...], n: int, n_browser: int, browser_ok: bool
) -> list[tuple[str, ...]]:
    """Print the head's table; return its goal rows."""
    busy = Load()
    load = os.getloadavg()[0]
    folder = Path(tempfile.mkdtemp(prefix="bench_view_"))
    try:
        path = save_rig(rig, folder / "head.mrig")
        start_s = time.perf_counter()
        with quiet():
            viewer = start(path, port=0)
        start_s = time.perf_counter() - start_s
        try:
            return run_head(
                label, rig, viewer, path, build_s, start_s, load, busy, engines, n, n_browser, browser_ok
            )
        finally:
            with quiet():
                viewer.server.stop()
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def run_head(
    label, rig, viewer, path, build_s, start_s, load, busy, engines, n, n_browser, browser_ok
) -> list[tuple[str, ...]]:
    prepare: dict[str, float] = {}
    fresh = Deformers(rig, engines=("wire",))
    began = time.perf_counter()
    fresh.prepare("wire")
    prepare["wire"] = time.perf_counter() - began
    quiet_samples: dict[str, dict[str, list[float]]] = {}
    caught: dict[str, list[warnings.WarningMessage]] = {}
    for engine in engines:
        if engine != "wire":
            began = time.perf_counter()
            with warnings.catch_warnings(record=True) as caught[engine]:
                warnings.simplefilter("always")
                viewer.deformers.prepare(engine)
            prepare[engine] = time.perf_counter() - began
        viewer.engine = engine
        viewer._refresh()
        quiet_samples[engine] = without_client(viewer, n)
    quiet_note = busy.note()

    browser_samples: dict[str, dict[str, dict[str, list[float]]]] = {}
    browser_note = ""
    if browser_ok:
        from playwright.sync_api import sync_playwright

        threshold = 6 * rig.n_vertices  # half the vertex array in float32; GUI-only frames are < 2 kB
        busy = Load()
        with sync_playwright() as playwright:
            browser = Browser(playwright, viewer.server.get_port(), threshold)
            try:
                browser_busy = ""
                for engine in engines:
                    viewer.engine = engine
                    viewer._refresh()
                    browser.settle()
                    browser_samples[engine] = {
                        kind: with_browser(viewer, browser, n_browser, kind)
                        for kind in ("move", "flush", "naive")
                    }
                uncertainty = browser.uncertainty_ms
                browser_busy = busy.note()  # before the browser's processes end
            finally:
                browser.close()
        browser_note = f"; with the browser {browser_busy} (worker clock mapped within ±{uncertainty:.1f} ms)"

    n_parts = len(viewer.parts)
    print(
        f"\n{label}: {rig.n_vertices:,} vertices in {n_parts} parts, {len(rig.channels)} channels; rig "
        f"built in {build_s:.1f} s, .mrig {path.stat().st_size / 1e6:.1f} MB; viewer started in "
        f"{start_s:.2f} s (load the .mrig, prepare wire, build the page); load average {load:.2f}"
    )
    print(
        "engine preparation, once: "
        + ", ".join(
            f"{engine} {prepare[engine]:.2f} s" + (" (engine + bake)" if engine in BAKED_ENGINES else "")
            for engine in engines
        )
    )
    for engine, found in caught.items():
        if found:
            first = found[0]
            print(
                f"   {engine}: {len(found)} warning(s) while preparing, the first: "
                f"{first.category.__name__}: {first.message}"
            )
    if browser_samples:
        sizes = {
            kind: statistics.median(browser_samples[engines[0]][kind]["bytes"]) / 1e3
            for kind in ("move", "naive")
        }
        print(
            f"frames ({engines[0]}): a move sends {sizes['move']:,.0f} kB, the naive update "
            f"{sizes['naive']:,.0f} kB"
        )
    print(
        f"{n} moves per case without a client, {n_browser} per case with the browser (after warm-up); "
        f"without a client {quiet_note}{browser_note}"
    )
    rows, goals = [], []
    goal = GOAL_MS[label] / 1e3
    for engine in engines:
        rows += engine_rows(engine, quiet_samples[engine], browser_samples.get(engine))
        callback = summary(quiet_samples[engine]["callback"])
        sent = summary(browser_samples[engine]["move"]["sent"]) if engine in browser_samples else None
        received = summary(browser_samples[engine]["move"]["worker"]) if engine in browser_samples else None
        goals.append(
            (
                label,
                engine,
                f"≤ {goal * 1e3:.0f} ms",
                f"{ms(callback[0])} (p90 {ms(callback[1])})",
                "met" if callback[0] <= goal else "NOT met",
                f"{ms(sent[0])} (p90 {ms(sent[1])})" if sent else "no browser",
                ("met" if sent[0] <= goal else "NOT met") if sent else "",
                f"{ms(received[0])} (p90 {ms(received[1])})" if received else "",
            )
        )
    moves = table(("case", "median", "p90", "÷ floor", "÷ naive"), rows, f"{label}: slider moves")
    TABLES.append(f"{label[0].upper()}{label[1:]}, slider moves:\n\n{moves}")  # two heads in a full run
    return goals


def engine_rows(
    engine: str, quiet: dict[str, list[float]], browser: dict[str, dict[str, list[float]]] | None
) -> list[tuple[str, ...]]:
    """Table rows of one engine: case | median | p90 | ÷ floor | ÷ naive (ratios of medians)."""
    q = {case: summary(s) for case, s in quiet.items()}
    floor = q["floor"][0]
    cases = [
        ("slider → callback returned (no client)", q["callback"], q["naive"][0]),
        ("viewer.last_update_ms (no client)", q["last_update"], None),
        ("baseline (a): deform alone (floor)", q["floor"], None),
        ("baseline (b): naive re-add, call (no client)", q["naive"], None),
    ]
    if browser is not None:
        b = {kind: {what: summary(s) for what, s in times.items()} for kind, times in browser.items()}
        move, flush, naive = b["move"], b["flush"], b["naive"]
        cases += [
            ("slider → callback returned (browser on)", move["callback"], naive["callback"][0]),
            ("slider → frame sent", move["sent"], naive["sent"][0]),
            ("slider → frame in the browser", move["worker"], naive["worker"][0]),
            ("slider + server.flush() → frame sent", flush["sent"], None),
            ("slider + server.flush() → frame in the browser", flush["worker"], None),
            ("baseline (b): naive re-add → frame sent", naive["sent"], None),
            ("baseline (b): naive re-add → frame in the browser", naive["worker"], None),
        ]
    return [
        (
            f"{engine}: {case}",
            ms(median),
            ms(p90),
            f"{median / floor:.2f}",
            f"{median / naive:.2f}" if naive else "",
        )
        for case, (median, p90), naive in cases
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="the default head, wire only, fewer moves")
    parser.add_argument("--no-browser", action="store_true", help="skip the headless-browser cases")
    args = parser.parse_args()
    begin = time.perf_counter()
    engines = ("wire",) if args.quick else ENGINES
    n, n_browser = (QUICK_MOVES, QUICK_BROWSER_MOVES) if args.quick else (MOVES, BROWSER_MOVES)
    why_not = "--no-browser" if args.no_browser else browser_available()
    if why_not:
        print(f"browser cases skipped: {why_not}")
    log_sends()
    print(f"load average at the start {os.getloadavg()[0]:.2f} ({os.cpu_count()} cores)")
    goals = []
    for label, rig, build_s in heads(args.quick):
        goals += bench_head(label, rig, build_s, engines, n, n_browser, why_not is None)
    print(
        "\ngoals: slider move → updated mesh, server side (median; p90 beside it; the browser's time for "
        "reference)"
    )
    goals_table = table(
        (
            "head",
            "engine",
            "goal",
            "callback, no client",
            "met",
            "frame sent (browser on)",
            "met",
            "in the browser",
        ),
        goals,
        "Goals",
    )
    print(f"\nbenchmark wall time {time.perf_counter() - begin:.0f} s")
    report.save("view", [goals_table, *TABLES])  # the goals first, as the document shows them


if __name__ == "__main__":
    main()
