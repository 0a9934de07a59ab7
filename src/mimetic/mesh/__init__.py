"""Meshes: the ``Mesh`` data type, file I/O, units and validation."""

from mimetic.mesh.io import SUPPORTED_FORMATS, load_mesh, save_mesh
from mimetic.mesh.model import Mesh, SurfacePoint
from mimetic.mesh.units import UNIT_SCALE, check_units, convert_units, detect_units
from mimetic.mesh.validate import MeshReport, validate_mesh

__all__ = [
    "SUPPORTED_FORMATS",
    "UNIT_SCALE",
    "Mesh",
    "MeshReport",
    "SurfacePoint",
    "check_units",
    "convert_units",
    "detect_units",
    "load_mesh",
    "save_mesh",
    "validate_mesh",
]
