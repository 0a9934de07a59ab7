"""The built-in reference head: parametric conformation, parts, landmarks and regions by construction.

``make_head(HeadParams.random(seed=7))`` gives a ``Head`` (a mesh in cm, +Y up, +Z forward, with
eyeballs, teeth, tongue, mouth cavity and ears as parts, its 82 landmarks, 19 regions and an exact
mirror map). ``IBUG68`` and ``MEDIAPIPE`` map the iBUG 68-point and MediaPipe FaceMesh orders to
the landmark names.
"""

from mimetic.head.landmarks import IBUG68, MEDIAPIPE
from mimetic.head.model import DEFAULT_RESOLUTION, Head, make_head
from mimetic.head.params import PARAM_RANGES, HeadParams

__all__ = ["DEFAULT_RESOLUTION", "IBUG68", "MEDIAPIPE", "PARAM_RANGES", "Head", "HeadParams", "make_head"]
