"""Where the shared real test data lives (ICT-FaceKit, MediaPipe, speech, landmarks).

Not shipped with the package: tests, benchmarks and the demo use it when it is beside the
repository (``../shared/data``, the layout on CI and in development) or named by
``$MIMETIC_SHARED_DATA``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from mimetic.mesh.model import Mesh

if TYPE_CHECKING:
    from mimetic.fit.landmarks import Landmarks

SHARED_DATA_ENV = "MIMETIC_SHARED_DATA"
ICT_IBUG_USED = tuple(i for i in range(17, 68) if i not in (60, 64))
"""The iBUG-68 landmarks of ICT-FaceKit's file that fits use: no jaw contour (0-16, which a mesh
shows only in profile), and not the inner mouth corners 60/64, which name the same project
landmarks as the outer 48/54."""


def shared_data_dir() -> Path | None:
    """The shared data folder (it holds a ``README.md``), or None when absent."""
    env = os.environ.get(SHARED_DATA_ENV)
    candidates = [Path(env)] if env else []
    candidates.append(Path(__file__).resolve().parents[3] / "shared" / "data")
    return next((c for c in candidates if (c / "README.md").is_file()), None)


def load_ict(folder: Path) -> tuple[Mesh, dict]:
    """ICT-FaceKit's neutral head (cm, all its parts) and its ``meta.json``, from ``folder`` (the
    shared data's ``ict-facekit``)."""
    data = np.load(folder / "neutral.npz")
    meta = json.loads((folder / "meta.json").read_text())
    mesh = Mesh(data["vertices"].astype(np.float64), data["faces"].astype(np.int64), units="cm")
    return mesh, meta


def ict_landmarks(mesh: Mesh, meta: dict) -> Landmarks:
    """The 49 landmarks of ``ICT_IBUG_USED`` at ICT's own landmark vertices of ``mesh`` (the neutral,
    or any mesh that keeps its first vertices, as without the eye shells), under project names."""
    from mimetic.fit.landmarks import Landmarks
    from mimetic.head.landmarks import IBUG68

    ids = np.asarray(meta["landmarks_68"]["vertex_indices"])[list(ICT_IBUG_USED)]
    names = tuple(IBUG68[i] for i in ICT_IBUG_USED)
    return Landmarks(names, mesh.vertices[ids], np.ones(len(ids)), "cm", "ict-facekit landmarks_68")
