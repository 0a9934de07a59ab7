"""Performance capture: tracked markers, landmarks or video → the rig's channel activations.

* ``read_trajectories`` (CSV, TRC, C3D, OpenFace) and ``track_video`` (MediaPipe FaceMesh, extra
  ``[track]``) give ``Trajectories``: named points over frames, NaN where missing.
* ``marker_set(rig, layout)`` places the matching virtual markers on a rig (the paper's 24,
  iBUG-68, MediaPipe-468 or a JSON file).
* ``solve_performance(rig, trajectories, basis=...)`` calibrates, removes the head's motion,
  smooths, and solves bounded least squares per frame (``capture.qp``): a ``Performance`` whose
  ``clip`` plays on any rig (``retarget``) and edits with clip layers (``keep_edits``).
* ``solve_activations`` fits activations to whole-mesh vertex targets (the older, vertex-level
  solver, with correctives).
"""

from mimetic.capture.formats import read_trajectories, write_trajectories
from mimetic.capture.markers import MarkerSet, marker_set
from mimetic.capture.performance import Performance, solve_performance
from mimetic.capture.retarget import keep_edits, retarget
from mimetic.capture.solve import ActivationSolver, SolveResult, prepare_solver, solve_activations
from mimetic.capture.trajectories import CaptureError, Trajectories

__all__ = [
    "ActivationSolver",
    "CaptureError",
    "MarkerSet",
    "Performance",
    "SolveResult",
    "Trajectories",
    "keep_edits",
    "marker_set",
    "prepare_solver",
    "read_trajectories",
    "retarget",
    "solve_activations",
    "solve_performance",
    "write_trajectories",
]
