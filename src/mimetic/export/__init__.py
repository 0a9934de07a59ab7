"""Files for other tools: an animatable glTF (.glb), FBX (through Blender's own exporter), USD
(UsdSkel, with the ``[usd]`` extra) and per-frame OBJ sequences.

Nothing else in mimetic imports this package.
"""

from mimetic.export.fbx import export_fbx
from mimetic.export.gltf import (
    ExportError,
    bone_channels,
    export_glb,
    gltf_vertices,
    morph_targets,
    morph_targets_from_basis,
    read_accessor,
    read_glb_summary,
)
from mimetic.export.obj_sequence import export_obj_sequence, frame_name
from mimetic.export.usd import check_usd, export_usd, usd_names

__all__ = [
    "ExportError",
    "bone_channels",
    "check_usd",
    "export_fbx",
    "export_glb",
    "export_obj_sequence",
    "export_usd",
    "frame_name",
    "gltf_vertices",
    "morph_targets",
    "morph_targets_from_basis",
    "read_accessor",
    "read_glb_summary",
    "usd_names",
]
