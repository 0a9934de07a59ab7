"""mimetic: turn any 3D head mesh into a muscle-driven, animatable face.

Coordinates are right-handed, +Y up, +Z forward (the face looks down +Z), as in glTF.
Lengths keep the source mesh's units; the rig records them.
"""

from mimetic.errors import (
    ActivationError,
    LandmarkError,
    MeshError,
    MimeticError,
    MimeticWarning,
    MissingExtraError,
    RenderError,
    RigError,
    RigFormatError,
)

__version__ = "0.1.0"

__all__ = [
    "ActivationError",
    "LandmarkError",
    "MeshError",
    "MimeticError",
    "MimeticWarning",
    "MissingExtraError",
    "RenderError",
    "RigError",
    "RigFormatError",
    "__version__",
]
