"""Files for other tools: an animatable glTF (.glb) and per-frame OBJ sequences with channel curves.

Nothing else in mimetic imports this package.
"""

from mimetic.export.gltf import (
    ExportError,
    bone_channels,
    export_glb,
    gltf_vertices,
    morph_targets_from_basis,
    read_accessor,
    read_glb_summary,
)
from mimetic.export.obj_sequence import export_obj_sequence, frame_name

__all__ = [
    "ExportError",
    "bone_channels",
    "export_glb",
    "export_obj_sequence",
    "frame_name",
    "gltf_vertices",
    "morph_targets_from_basis",
    "read_accessor",
    "read_glb_summary",
]
