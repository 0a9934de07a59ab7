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
"""

from mimetic.capture.formats import read_trajectories, write_trajectories
from mimetic.capture.markers import MarkerSet, load_marker_set, marker_set, save_marker_set
from mimetic.capture.performance import Performance, solve_performance
from mimetic.capture.retarget import keep_edits, retarget
from mimetic.capture.solve import ActivationSolver, SolveResult, prepare_solver, solve_activations
from mimetic.capture.stream import LiveCapture, LiveFrame, LiveSolver, live_frames
from mimetic.capture.trajectories import CaptureError, Trajectories

__all__ = [
    "ActivationSolver",
    "CaptureError",
    "LiveCapture",
    "LiveFrame",
    "LiveSolver",
    "MarkerSet",
    "Performance",
    "SolveResult",
    "Trajectories",
    "keep_edits",
    "live_frames",
    "load_marker_set",
    "marker_set",
    "prepare_solver",
    "read_trajectories",
    "retarget",
    "save_marker_set",
    "solve_activations",
    "solve_performance",
    "write_trajectories",
]
