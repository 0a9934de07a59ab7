"""Shared set-up of the client tests: the exported file, and the tools that open it.

Each client test opens the same .glb (the small rig as if fitted to a Z-up scan, its baked muscle
targets and a 1 s clip at 60 fps) in a real client and compares what the client shows with
``gltf_vertices``. The clients install themselves on first use and are cached:

* node packages (``three``, ``gltf-validator``, pinned in package.json / package-lock.json) in
  ``tests/clients/node_modules`` by ``npm ci``;
* Blender as a Python module (``bpy``) in its own venv under ``~/.cache/mimetic/bpy-<version>``
  (bpy pins numpy < 2 and Python 3.11), made by ``mimetic.blender`` as for users (``mimetic setup
  fbx``), or ``$MIMETIC_BLENDER``;
* assimp (``assimp-utils``, a second FBX reader) is a system package: ``.ci/run`` installs it;
* Chromium is a system package: ``.ci/run`` installs it (``apt-get install chromium``).

A client that cannot be installed skips its test with the reason, except on CI (``CI=true``),
where it fails.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

HERE = Path(__file__).parent
SECONDS = 0.5  # the time the clients pose: frame 30 at 60 fps, frame 12 at Blender's 24 fps
FPS = 60.0
FRAMES = 61


def unavailable(reason: str) -> None:
    """Skip the test locally; fail it on CI, where every client must run."""
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(f"{reason} (CI=true requires this client)")
    pytest.skip(reason)


def run(command: list[str], *, timeout: float, cwd: Path | None = None) -> subprocess.CompletedProcess:
    """Run a command, capturing its output; a missing program or a timeout is a failed process."""
    try:
        return subprocess.run(command, capture_output=True, text=True, timeout=timeout, cwd=cwd, check=False)
    except (OSError, subprocess.TimeoutExpired) as error:
        return subprocess.CompletedProcess(command, 127, "", str(error))


def tail(text: str, lines: int = 15) -> str:
    return "\n".join(text.strip().splitlines()[-lines:])


@dataclass(frozen=True)
class Exported:
    seconds: float  # the time the clients pose
    path: Path
    rig: object
    targets: dict
    clip: object
    turn: np.ndarray  # (3, 3) the rig's source rotation (its mesh came from a Z-up scan)
    rest: np.ndarray  # (n, 3) metres, glTF world frame
    posed: np.ndarray  # (n, 3) metres at SECONDS
    summary: dict  # read_glb_summary of the file

    def landmark(self, vertices: np.ndarray, name: str) -> np.ndarray:
        """The position (3,) of a rig landmark on ``vertices`` (n, 3) in rig order."""
        point = self.rig.landmarks[name]
        return np.asarray(point.bary) @ vertices[self.rig.mesh.faces[point.face]]


@pytest.fixture(scope="session")
def exported(tmp_path_factory) -> Exported:
    import dataclasses

    from mimetic.engines import make_engine
    from mimetic.engines.bake import bake
    from mimetic.export import export_glb, gltf_vertices, morph_targets_from_basis, read_glb_summary
    from mimetic.rig.activations import Clip
    from mimetic.rig.model import thaw_json
    from mimetic.testing import small_rig

    turn = Rotation.from_euler("x", -90, degrees=True).as_matrix()  # the user's mesh was Z-up
    base = small_rig()
    rig = dataclasses.replace(base, metadata={**thaw_json(base.metadata), "source_rotation": turn.tolist()})
    targets = morph_targets_from_basis(bake(make_engine(rig, "wire"), correctives=0, samples=1).basis, rig)
    t = np.arange(FRAMES) / FPS
    values = np.zeros((FRAMES, len(rig.channels)))
    curves = {
        "jaw_open": 0.35 * np.sin(3 * t) ** 2,
        "jaw_protrude": 0.03 * np.sin(2 * t) ** 2,
        "gaze_yaw": 0.4 * np.sin(4 * t),
        "head_pitch": 0.3 * np.sin(2 * t),
        "zygomatic_major_L": np.sin(2 * t) ** 2,
        "orbicularis_oculi_R": np.sin(5 * t) ** 2,
    }
    for name, curve in curves.items():
        values[:, rig.channel_index(name)] = curve
    clip = Clip(rig.channel_names, values, FPS)
    path = tmp_path_factory.mktemp("clients") / "face.glb"
    export_glb(rig, path, morph_targets=targets, clip=clip)
    frame = round(SECONDS * FPS)
    return Exported(
        seconds=SECONDS,
        path=path,
        rig=rig,
        targets=targets,
        clip=clip,
        turn=turn,
        rest=gltf_vertices(rig, targets, {}),
        posed=gltf_vertices(rig, targets, dict(zip(clip.channels, clip.values[frame], strict=True))),
        summary=read_glb_summary(path),
    )


@pytest.fixture(scope="session")
def node_modules() -> Path:
    """tests/clients/node_modules as package-lock.json pins it (``npm ci`` when the lock changed)."""
    folder = HERE / "node_modules"
    lock = (HERE / "package-lock.json").read_bytes()
    stamp = folder / ".mimetic-lock-sha256"
    digest = hashlib.sha256(lock).hexdigest()
    if stamp.exists() and stamp.read_text() == digest:
        return folder
    npm = shutil.which("npm")
    if npm is None:
        unavailable("npm is not installed (apt-get install nodejs npm)")
    done = run([npm, "ci", "--no-audit", "--no-fund"], timeout=600, cwd=HERE)
    if done.returncode != 0:
        unavailable(f"npm ci in {HERE} failed:\n{tail(done.stdout + done.stderr)}")
    stamp.write_text(digest)
    return folder


@pytest.fixture(scope="session")
def node() -> str:
    path = shutil.which("node")
    if path is None:
        unavailable("node is not installed (apt-get install nodejs)")
    return path


@pytest.fixture(scope="session")
def blender_tool():
    """The Blender (``mimetic.blender.Blender``) the package uses: found, or installed on first use."""
    from mimetic.blender import BlenderError, blender

    start = time.monotonic()
    try:
        tool = blender()
    except BlenderError as error:
        unavailable(str(error))
    print(f"blender: {tool.program} ({time.monotonic() - start:.1f} s to find or install)")
    return tool


@pytest.fixture(scope="session")
def bpy_python(blender_tool) -> Path:
    """The python of the venv with bpy (the test scripts run as ``python SCRIPT ARGS``)."""
    if blender_tool.is_binary:
        unavailable(f"the client checks run bpy as a Python module; MIMETIC_BLENDER={blender_tool.program}")
    return blender_tool.program


@pytest.fixture(scope="session")
def assimp() -> str:
    """Debian's assimp command (``apt-get install assimp-utils``; .ci/run installs it)."""
    path = shutil.which("assimp")
    if path is None:
        unavailable("assimp is not installed (apt-get install assimp-utils)")
    return path


@pytest.fixture(scope="session")
def chromium() -> str:
    """Debian's chromium (``apt-get install chromium``; .ci/run installs it)."""
    path = shutil.which("chromium") or ("/usr/bin/chromium" if Path("/usr/bin/chromium").exists() else None)
    if path is None:
        unavailable("chromium is not installed (apt-get install chromium)")
    return path
