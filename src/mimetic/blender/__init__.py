"""Blender as a tool: scripts run by Blender's own Python module (``bpy``) in a separate process.

mimetic reads and writes FBX through Blender's own FBX importer and exporter, never a hand-written
binary reader or writer. ``bpy`` pins Python 3.11 and numpy < 2 (mimetic pins numpy 2), so it lives
in its own venv, created once and cached under ``~/.cache/mimetic/bpy-<BPY_VERSION>`` (about 1 GB;
the first install downloads a 374 MB wheel and takes a minute or two). ``mimetic setup fbx`` makes
it ahead of time; otherwise the first FBX read or write does.

``MIMETIC_BLENDER`` overrides the venv: the path of a ``blender`` binary (run as ``blender
--background --factory-startup --python SCRIPT -- ARGS``) or of a Python that imports ``bpy``.

The scripts beside this module (``fbx_write.py``, ``fbx_read.py``) run inside Blender, import
nothing from mimetic, and talk back through one ``MIMETIC_JSON {...}`` line on stdout; a problem
with the user's file is one ``MIMETIC_ERROR <message>`` line and exit code 3.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mimetic.errors import MimeticError

log = logging.getLogger(__name__)

BPY_VERSION = "5.0.1"
"""The bpy release mimetic's FBX scripts are written and tested against."""

ENV_VAR = "MIMETIC_BLENDER"
SCRIPTS = Path(__file__).parent
USER_ERROR_EXIT = 3
"""Exit code of a script that found a problem with the user's file (its message is on stdout)."""

Progress = Callable[[str, int, int], None]
"""``progress(step, done, total)``, as the tasks report their steps."""


class BlenderError(MimeticError, RuntimeError):
    """Blender (bpy) is missing and cannot be installed here, or it failed on a file."""


@dataclass(frozen=True)
class Blender:
    """A Blender to run scripts in: a Python that imports bpy, or a ``blender`` executable."""

    program: Path
    is_binary: bool  # a ``blender`` executable rather than a Python that imports bpy

    def command(self, script: Path, args: list[str]) -> list[str]:
        if self.is_binary:
            return [
                str(self.program),
                "--background",
                "--factory-startup",
                "--python",
                str(script),
                "--",
                *args,
            ]
        return [str(self.program), str(script), "--", *args]


def cache_dir() -> Path:
    """mimetic's cache folder: ``$XDG_CACHE_HOME/mimetic``, else ``~/.cache/mimetic``."""
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "mimetic"


def venv_dir() -> Path:
    return cache_dir() / f"bpy-{BPY_VERSION}"


def python311() -> str | None:
    """A Python 3.11 to build the venv from: this one if it is 3.11, else ``python3.11`` on PATH."""
    if sys.version_info[:2] == (3, 11):
        return sys.executable
    return shutil.which("python3.11")


def find_blender() -> Blender | None:
    """The Blender to use without installing anything: ``$MIMETIC_BLENDER``, else the cached venv."""
    override = os.environ.get(ENV_VAR)
    if override:
        program = Path(override).expanduser()
        if not program.is_file():
            raise BlenderError(
                f"{ENV_VAR}={override}: no such file; give a blender binary or a Python with bpy"
            )
        return Blender(program, is_binary=program.name.lower().startswith("blender"))
    python = venv_dir() / "bin" / "python"
    if (venv_dir() / ".installed").is_file() and python.exists():
        return Blender(python, is_binary=False)
    return None


def _run(command: list[str], timeout: float) -> subprocess.CompletedProcess:
    try:
        return subprocess.run(command, capture_output=True, text=True, timeout=timeout, check=False)
    except (OSError, subprocess.TimeoutExpired) as error:
        return subprocess.CompletedProcess(command, 127, "", str(error))


def _tail(text: str, lines: int = 8) -> str:
    return " | ".join(text.strip().splitlines()[-lines:])


def install_bpy(progress: Progress | None = None) -> Blender:
    """Create the bpy venv (``python3.11 -m venv``, ``pip install bpy==BPY_VERSION``) and return it;
    ``progress`` hears of each step (without it, one log warning says what is being installed).

    The venv is built in a temporary folder beside its place and renamed into place when complete,
    so an interrupted install leaves nothing half-made, and two processes installing at once end
    with one venv.

    Raises
    ------
    BlenderError
        No Python 3.11 on this machine, or venv / pip failed (the message quotes pip's last lines).
    """
    base = python311()
    if base is None:
        raise BlenderError(
            f"FBX needs Blender's Python module (bpy {BPY_VERSION}), which runs only on Python 3.11, and "
            f"no python3.11 is on PATH: install Python 3.11 (e.g. apt-get install python3.11, or pyenv), "
            f"or set {ENV_VAR} to a blender binary"
        )
    target = venv_dir()
    # a command without a progress display (mimetic rig head.fbx) still says why it waits
    if progress is None:
        log.warning("installing Blender's bpy %s for FBX into %s (once: about 1 GB, a minute or two)",
                    BPY_VERSION, target)  # fmt: skip
    target.parent.mkdir(parents=True, exist_ok=True)
    building = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
    python = building / "bin" / "python"
    steps = (
        ("create a Python 3.11 venv", [base, "-m", "venv", "--clear", str(building)], 300),
        (f"pip install bpy=={BPY_VERSION} (374 MB)", [str(python), "-m", "pip", "install", "--quiet",
                                                     f"bpy=={BPY_VERSION}"], 3600),
    )  # fmt: skip
    start = time.monotonic()
    try:
        for done, (step, command, timeout) in enumerate(steps):
            if progress is not None:
                progress(f"set up FBX: {step}", done, len(steps))
            result = _run(command, timeout)
            if result.returncode != 0:
                output = _tail(result.stderr or result.stdout)
                raise BlenderError(f"setting up FBX support failed at '{step}' in {target}: {output}")
        (building / ".installed").write_text(f"bpy=={BPY_VERSION}\n")
        if target.exists() and not (target / ".installed").is_file():  # an install cut short by older code
            shutil.rmtree(target)
        try:
            building.rename(target)
        except OSError:  # another process finished first: use its venv
            shutil.rmtree(building, ignore_errors=True)
    except BaseException:
        shutil.rmtree(building, ignore_errors=True)
        raise
    if progress is not None:
        progress(f"set up FBX: done in {time.monotonic() - start:.0f} s", len(steps), len(steps))
    found = find_blender()
    assert found is not None
    return found


def blender(progress: Progress | None = None) -> Blender:
    """The Blender to run scripts in: ``$MIMETIC_BLENDER``, the cached venv, or a new venv."""
    return find_blender() or install_bpy(progress)


def run_script(
    name: str,
    args: list[str],
    *,
    error: type[MimeticError],
    timeout: float = 900.0,
    progress: Progress | None = None,
) -> dict[str, Any]:
    """Run the script ``name`` (beside this module) in Blender with ``args``; its JSON report.

    Raises
    ------
    error
        The script found a problem with the user's file (its one-line message).
    BlenderError
        Blender itself failed (crashed, timed out); the message quotes its last output lines.
    """
    tool = blender(progress)
    done = _run(tool.command(SCRIPTS / name, args), timeout)
    lines = done.stdout.splitlines()
    if done.returncode == USER_ERROR_EXIT:
        messages = [
            line.removeprefix("MIMETIC_ERROR ") for line in lines if line.startswith("MIMETIC_ERROR ")
        ]
        raise error(messages[-1] if messages else _tail(done.stderr))
    reports = [line.removeprefix("MIMETIC_JSON ") for line in lines if line.startswith("MIMETIC_JSON ")]
    if done.returncode != 0 or not reports:
        raise BlenderError(
            f"Blender ({tool.program}) failed running {name} (exit {done.returncode}): "
            f"{_tail(done.stderr + done.stdout)}"
        )
    return json.loads(reports[-1])
