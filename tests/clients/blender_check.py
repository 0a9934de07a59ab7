"""Import a .glb with Blender's own glTF importer (bpy) and report what Blender made of it.

Runs inside the bpy venv (Python 3.11, numpy < 2), not mimetic's: ``python blender_check.py FILE.glb
OUT_DIR SECONDS``. Prints one JSON line (prefixed ``BLENDER_JSON``) and writes two arrays to
OUT_DIR, (n, 3) float64:

* ``rest.npy``: the mesh's vertices in Blender's vertex order, without shape keys or armature, in
  glTF axes (+Y up; Blender's Z-up import is undone);
* ``posed.npy``: the evaluated mesh (shape keys and armature) at time SECONDS of the first action,
  in glTF axes;
* ``posed_blender.npy``: the same evaluated mesh in Blender's own world axes (+Z up, front -Y), as
  Blender draws it.
"""

import json
import math
import sys
from pathlib import Path

import bpy
import numpy as np


def to_gltf_axes(co: np.ndarray) -> np.ndarray:
    """Blender's importer maps glTF (x, y, z) to (x, -z, y); undo it."""
    return np.column_stack([co[:, 0], co[:, 2], -co[:, 1]])


def coordinates(mesh) -> np.ndarray:
    co = np.empty(len(mesh.vertices) * 3)
    mesh.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def main() -> None:
    glb, out, seconds = Path(sys.argv[1]), Path(sys.argv[2]), float(sys.argv[3])
    bpy.ops.wm.read_factory_settings(use_empty=True)
    result = bpy.ops.import_scene.gltf(filepath=str(glb))
    scene = bpy.context.scene
    meshes = [o for o in scene.objects if o.type == "MESH" and o.data.shape_keys is not None]
    if not meshes:  # a file without morph targets: the largest mesh (not a bone shape)
        meshes = sorted((o for o in scene.objects if o.type == "MESH"), key=lambda o: -len(o.data.vertices))
    armatures = [o for o in scene.objects if o.type == "ARMATURE"]
    obj = meshes[0]
    keys = [k.name for k in obj.data.shape_keys.key_blocks] if obj.data.shape_keys else []
    world = np.array(obj.matrix_world)
    rest = coordinates(obj.data) @ world[:3, :3].T + world[:3, 3]
    np.save(out / "rest.npy", to_gltf_axes(rest))

    actions = []
    for action in bpy.data.actions:
        slots = {}
        for layer in action.layers:
            for strip in layer.strips:
                for slot in action.slots:
                    bag = strip.channelbag(slot)
                    if bag is not None:
                        slots[slot.identifier] = len(bag.fcurves)
        actions.append(
            {
                "name": action.name,
                "frame_range": list(action.frame_range),
                "fcurves": sum(slots.values()),
                "slots": slots,
            }
        )
    frame = seconds * scene.render.fps / scene.render.fps_base
    scene.frame_set(math.floor(frame), subframe=frame - math.floor(frame))
    depsgraph = bpy.context.evaluated_depsgraph_get()
    evaluated = obj.evaluated_get(depsgraph)
    posed_mesh = evaluated.to_mesh()
    world = np.array(evaluated.matrix_world)
    posed = coordinates(posed_mesh) @ world[:3, :3].T + world[:3, 3]
    evaluated.to_mesh_clear()
    np.save(out / "posed.npy", to_gltf_axes(posed))
    np.save(out / "posed_blender.npy", posed)

    report = {
        "result": sorted(result),
        "blender": bpy.app.version_string,
        "mesh_object": obj.name,
        "vertices": len(obj.data.vertices),
        "faces": len(obj.data.polygons),
        "materials": [m.name for m in obj.data.materials if m is not None],
        "shape_keys": keys,
        "vertex_groups": [g.name for g in obj.vertex_groups],
        "armatures": [a.name for a in armatures],
        "bones": [b.name for b in armatures[0].data.bones] if armatures else [],
        "actions": actions,
        "fps": scene.render.fps / scene.render.fps_base,
        "frame": frame,
    }
    print("BLENDER_JSON " + json.dumps(report))


main()
