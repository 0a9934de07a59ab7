"""Performance capture: tracked markers, landmarks or video → the rig's channel activations.

* ``read_trajectories`` (CSV, TRC, C3D, OpenFace) and ``track_video`` (MediaPipe FaceMesh, extra
  ``[track]``) give ``Trajectories``: named points over frames, NaN where missing.
* ``marker_set(rig, layout)`` places the matching virtual markers on a rig (the paper's 24,
  iBUG-68, MediaPipe-468 or a JSON file); ``save_marker_set`` keeps the markers as placed on one
  performer, for their next takes.
* ``solve_performance(rig, trajectories, basis=...)`` calibrates (the markers moved to where the
  performer's are), removes the head's motion, smooths and solves each frame: 3D markers by bounded
  least squares on the basis, image landmarks on their reprojection through a perspective camera.
  The ``Performance``'s ``clip`` plays on any rig (``retarget``) and edits with clip layers
  (``keep_edits``).
* ``LiveSolver`` / ``LiveCapture`` / ``live_frames`` solve a stream frame by frame, as it arrives.
* ``solve_activations`` fits activations to whole-mesh vertex targets (the vertex-level solver,
  with correctives).

Each name is imported from its module on first use, so that the task layer and the command line can
read this package's constants (layouts, units, the cutoff) without loading the solvers and numba.
"""

from __future__ import annotations

import importlib
from typing import Any

# eager: the function shares its module's name, which importing the module would otherwise bind here
from mimetic.capture.retarget import keep_edits as keep_edits
from mimetic.capture.retarget import retarget as retarget

_API = {
    "read_trajectories": "formats",
    "write_trajectories": "formats",
    "MarkerSet": "markers",
    "load_marker_set": "markers",
    "marker_set": "markers",
    "save_marker_set": "markers",
    "Performance": "performance",
    "solve_performance": "performance",
    "ActivationSolver": "solve",
    "SolveResult": "solve",
    "prepare_solver": "solve",
    "solve_activations": "solve",
    "LiveCapture": "stream",
    "LiveFrame": "stream",
    "LiveSolver": "stream",
    "live_frames": "stream",
    "CaptureError": "trajectories",
    "Trajectories": "trajectories",
}

__all__ = sorted([*_API, "keep_edits", "retarget"])


def __getattr__(name: str) -> Any:
    """This package's names, each imported from its module on first use."""
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module 'mimetic.capture' has no attribute {name!r}")
    value = getattr(importlib.import_module(f"mimetic.capture.{module}"), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_API))
