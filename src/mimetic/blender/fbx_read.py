"""Inside Blender: an FBX head in (Blender's own FBX importer), its meshes out as arrays.

``fbx_read.py -- FBX OUT.npz``. Writes ``vertices`` (n, 3) float64 in the file's own unit, turned
into +Y up, +Z forward (glTF's axes: Blender's importer turns the file's declared axes into its
Z-up, which is undone here), at rest (no shape keys, no armature pose); ``faces`` (m, 3) int64,
each polygon fan-triangulated in place; ``labels`` (m,) int64, each face's part: its mesh object
when the file has several, else its material (``parts`` in the JSON names them). Vertex order is
the file's, object after object.
Prints ``MIMETIC_JSON {...}`` (units, part names, counts), or ``MIMETIC_ERROR <message>`` and exits
with code 3 when the file holds no mesh or a whole body.
"""

import json
import sys

import bpy
import numpy as np
from io_scene_fbx import parse_fbx

UNITS = {0.1: "mm", 1.0: "cm", 10.0: "dm", 100.0: "m", 2.54: "in"}
"""FBX ``UnitScaleFactor`` (centimetres per file unit) → mimetic's unit name."""

BODY_HEIGHT_M = 0.8
"""Meshes taller than this (in metres, by the file's units) are a body or a scene, not a head."""


def fail(message: str) -> None:
    print("MIMETIC_ERROR " + message)
    sys.exit(3)


def unit_scale(path: str) -> float:
    """The file's ``GlobalSettings`` ``UnitScaleFactor``: centimetres per file unit (1 when absent)."""
    root, _ = parse_fbx.parse(path)
    for elem in root.elems:
        if elem.id == b"GlobalSettings":
            for props in elem.elems:
                for p in props.elems:
                    if p.props and p.props[0] == b"UnitScaleFactor":
                        return float(p.props[4])
    return 1.0


def main() -> None:
    fbx, out = sys.argv[sys.argv.index("--") + 1 :]
    try:
        cm_per_unit = unit_scale(fbx)
    except Exception as error:  # Blender's parser raises plain exceptions on a damaged file
        fail(f"not a readable binary FBX ({error}); the file is corrupt or truncated. Re-export it.")
    known = next((name for factor, name in UNITS.items() if abs(cm_per_unit / factor - 1) < 1e-6), None)
    units = known or "cm"  # an unusual unit is read in centimetres
    cm_per_value = cm_per_unit if known else 1.0
    # The importer scales by global_scale * UnitScaleFactor / 100 (to metres): keep the file's numbers.
    keep = 100.0 / cm_per_value
    bpy.ops.wm.read_factory_settings(use_empty=True)
    try:
        bpy.ops.import_scene.fbx(filepath=fbx, global_scale=keep, use_anim=False, use_custom_props=False)
    except RuntimeError as error:
        fail(f"Blender's FBX importer failed ({' '.join(str(error).split())[:200]}). Re-export it.")
    scene = bpy.context.scene
    meshes = [o for o in scene.objects if o.type == "MESH" and len(o.data.polygons) > 0]
    if not meshes:
        kinds = sorted({o.type.lower() for o in scene.objects}) or ["nothing"]
        fail(f"holds no mesh (only {', '.join(kinds)}); export the head's mesh with it.")
    vertices, faces, labels, parts = [], [], [], []
    offset = 0
    for obj in meshes:
        mesh = obj.data
        co = np.empty(len(mesh.vertices) * 3)
        mesh.vertices.foreach_get("co", co)
        world = np.array(obj.matrix_world)
        co = co.reshape(-1, 3) @ world[:3, :3].T + world[:3, 3]
        vertices.append(np.column_stack([co[:, 0], co[:, 2], -co[:, 1]]))  # Blender Z-up → +Y up, +Z forward
        loops = np.empty(len(mesh.loops), dtype=np.int64)
        mesh.loops.foreach_get("vertex_index", loops)
        starts = np.empty(len(mesh.polygons), dtype=np.int64)
        totals = np.empty(len(mesh.polygons), dtype=np.int64)
        mesh.polygons.foreach_get("loop_start", starts)
        mesh.polygons.foreach_get("loop_total", totals)
        materials = np.empty(len(mesh.polygons), dtype=np.int64)
        mesh.polygons.foreach_get("material_index", materials)
        fans = [
            np.column_stack([np.full(t - 2, loops[s]), loops[s + 1 : s + t - 1], loops[s + 2 : s + t]])
            for s, t in zip(starts, totals, strict=True)
        ]
        faces.append(np.concatenate(fans) + offset)
        if len(meshes) > 1:
            labels.append(np.full(sum(len(f) for f in fans), len(parts)))
            parts.append(obj.name)
        else:
            parts = [
                s.material.name if s.material else f"material_{i}" for i, s in enumerate(obj.material_slots)
            ]
            labels.append(np.repeat(materials, totals - 2))
        offset += len(mesh.vertices)
    vertices = np.concatenate(vertices)
    height_m = float(np.ptp(vertices, axis=0).max()) * cm_per_value / 100.0
    if height_m > BODY_HEIGHT_M:
        fail(
            f"holds {len(meshes)} mesh{'es' * (len(meshes) > 1)} {height_m:.2f} m across by its units: "
            "a whole body or a scene, not a head. Export the head's meshes alone (Blender: select them, "
            "File > Export > FBX, Limit to Selected Objects) and rig that file."
        )
    np.savez(out, vertices=vertices, faces=np.concatenate(faces), labels=np.concatenate(labels))
    report = {"units": units, "unit_scale_cm": cm_per_unit, "parts": parts, "vertices": offset}
    print("MIMETIC_JSON " + json.dumps(report))


main()
