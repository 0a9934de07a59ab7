"""Rig any head: landmarks (file or MediaPipe), conformation and similarity, non-rigid
registration of the reference, rig transfer to the user's vertices, and the fit report.

``rig_head(mesh, landmarks)`` runs it all; see ``mimetic.fit.pipeline``.
"""

from mimetic.fit.autolandmarks import auto_landmarks
from mimetic.fit.landmarks import Landmarks, read_landmarks, write_landmarks
from mimetic.fit.pipeline import RigResult, rig_head
from mimetic.fit.report import FitReport
from mimetic.fit.similarity import Similarity, fit_similarity

__all__ = [
    "FitReport",
    "Landmarks",
    "RigResult",
    "Similarity",
    "auto_landmarks",
    "fit_similarity",
    "read_landmarks",
    "rig_head",
    "write_landmarks",
]
