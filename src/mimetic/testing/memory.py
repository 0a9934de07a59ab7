"""Peak memory of a piece of work, measured in a fresh process (tests and ``bench_memory``).

``peak_rss(code)`` runs ``code`` with ``python -c`` in a new interpreter and returns what it printed
and its peak resident set size, read by the child itself as its last act: on Linux its memory's
high-water mark (``VmHWM`` in ``/proc/self/status``; ``ru_maxrss`` keeps the caller's size from
before the exec, so a large test process would count), elsewhere ``ru_maxrss``. A fresh process
is the only honest measure: the caller's own caches, imports and freed-but-kept arenas would
otherwise be counted.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

_TRAILER = """
import resource as _resource, sys as _sys
_sys.stdout.flush()
try:  # Linux: this process's own high-water mark, fresh at exec
    _peak = next(int(l.split()[1]) for l in open("/proc/self/status") if l.startswith("VmHWM:"))
except (OSError, StopIteration):
    _peak = _resource.getrusage(_resource.RUSAGE_SELF).ru_maxrss
print("\\nPEAK_RSS_KB", _peak, file=_sys.stderr)
"""


@dataclass(frozen=True)
class Measured:
    """What ``peak_rss`` saw: ``peak_bytes`` the child's peak resident set size, ``stdout`` and
    ``stderr`` its output (the measurement line removed), ``returncode`` its exit status."""

    peak_bytes: int
    stdout: str
    stderr: str
    returncode: int

    @property
    def peak_gib(self) -> float:
        return self.peak_bytes / 2**30


def _address_space_cap(max_bytes: int) -> Callable[[], None]:
    """A ``preexec_fn`` that limits the child's virtual address space to ``max_bytes`` (POSIX)."""

    def cap() -> None:
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (max_bytes, max_bytes))

    return cap


def peak_rss(
    code: str,
    *,
    cwd: str | os.PathLike[str] | None = None,
    timeout_s: float = 1800,
    max_address_space: int | None = None,
) -> Measured:
    """Run ``code`` (Python source) in a new interpreter and measure its peak memory.

    ``max_address_space`` (bytes, POSIX) caps the child's virtual memory (``RLIMIT_AS``): work that
    would need more fails in the child (a ``MemoryError`` in its stderr) instead of exhausting the
    machine. Raises ``RuntimeError`` with the child's stderr when it fails.
    """
    run = subprocess.run(
        [sys.executable, "-c", code + "\n" + _TRAILER],
        cwd=None if cwd is None else Path(cwd),
        capture_output=True,
        text=True,
        timeout=timeout_s,
        check=False,
        preexec_fn=None if max_address_space is None else _address_space_cap(max_address_space),
    )
    lines = run.stderr.splitlines()
    peak = [line for line in lines if line.startswith("PEAK_RSS_KB ")]
    if run.returncode != 0 or not peak:
        raise RuntimeError(f"the measured code failed (exit {run.returncode}):\n{run.stderr[-3000:]}")
    stderr = "\n".join(line for line in lines if not line.startswith("PEAK_RSS_KB ")).rstrip()
    return Measured(int(peak[-1].split()[1]) * 1024, run.stdout, stderr, run.returncode)
