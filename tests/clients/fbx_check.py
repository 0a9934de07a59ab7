"""Import an .fbx with Blender's own FBX importer (bpy) and report what Blender made of it.

Runs inside the bpy venv, not mimetic's: ``python fbx_check.py FILE.fbx OUT_DIR SECONDS,SECONDS,…``.
Prints one JSON line (prefixed ``BLENDER_JSON``): the file's own header (``UnitScaleFactor``, axes,
frame rate, takes, read with Blender's FBX parser) and the imported scene (mesh, materials, shape
keys, bones, vertex groups, actions). Writes OUT_DIR/arrays.npz, in glTF axes (+Y up; Blender's
Z-up import undone) and metres, in Blender's vertex order:

* ``rest`` (n, 3): the mesh without shape keys or armature;
* ``keys`` (k, n, 3): each shape key's displacement from the basis;
* ``posed`` (t, n, 3): the evaluated mesh (shape keys and armature) at each of SECONDS, with the
  animation imported at its own frames (``anim_offset=0``: FBX time 0 is Blender frame 0).
"""

import json
import sys
from pathlib import Path

import bpy
import numpy as np
from io_scene_fbx import parse_fbx


def to_gltf_axes(co: np.ndarray) -> np.ndarray:
    """Blender's Z-up (x, y, z) is glTF's (x, z, -y)."""
    return np.column_stack([co[:, 0], co[:, 2], -co[:, 1]])


def coordinates(items) -> np.ndarray:
    co = np.empty(len(items) * 3)
    items.foreach_get("co", co)
    return co.reshape(-1, 3)


def header(path: str) -> dict:
    root, version = parse_fbx.parse(path)
    settings, stacks = {}, []
    for elem in root.elems:
        if elem.id == b"GlobalSettings":
            for props in elem.elems:
                for p in props.elems:
                    if p.props and p.props[0] in (b"UnitScaleFactor", b"UpAxis", b"UpAxisSign", b"FrontAxis",
                                                  b"FrontAxisSign", b"CoordAxis", b"CoordAxisSign",
                                                  b"CustomFrameRate"):  # fmt: skip
                        settings[p.props[0].decode()] = p.props[4]
        if elem.id == b"Objects":
            stacks = [e.props[1].split(b"\x00")[0].decode() for e in elem.elems if e.id == b"AnimationStack"]
    return {"version": version, **settings, "takes": stacks}


def main() -> None:
    fbx, out, seconds = sys.argv[1], Path(sys.argv[2]), [float(s) for s in sys.argv[3].split(",")]
    raw = header(fbx)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    result = bpy.ops.import_scene.fbx(filepath=fbx, anim_offset=0.0)
    scene = bpy.context.scene
    meshes = [o for o in scene.objects if o.type == "MESH"]
    armatures = [o for o in scene.objects if o.type == "ARMATURE"]
    obj = max(meshes, key=lambda o: len(o.data.vertices))
    rotation = np.array(obj.matrix_world)[:3, :3]
    world = np.array(obj.matrix_world)
    rest = to_gltf_axes(coordinates(obj.data.vertices) @ world[:3, :3].T + world[:3, 3])
    blocks = obj.data.shape_keys.key_blocks if obj.data.shape_keys else []
    basis = coordinates(blocks[0].data) if blocks else None
    keys = np.array([to_gltf_axes((coordinates(k.data) - basis) @ rotation.T) for k in list(blocks)[1:]])
    fps = scene.render.fps / scene.render.fps_base
    posed = []
    for t in seconds:
        frame = t * fps
        scene.frame_set(int(np.floor(frame)), subframe=float(frame - np.floor(frame)))
        evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
        mesh = evaluated.to_mesh()
        matrix = np.array(evaluated.matrix_world)
        posed.append(to_gltf_axes(coordinates(mesh.vertices) @ matrix[:3, :3].T + matrix[:3, 3]))
        evaluated.to_mesh_clear()
    np.savez(out / "arrays.npz", rest=rest, keys=keys.reshape(-1, len(rest), 3), posed=np.array(posed))
    report = {
        "result": sorted(result),
        "blender": bpy.app.version_string,
        "header": raw,
        "meshes": [o.name for o in meshes],
        "mesh_object": obj.name,
        "vertices": len(obj.data.vertices),
        "faces": len(obj.data.polygons),
        "materials": [m.name for m in obj.data.materials if m is not None],
        "shape_keys": [k.name for k in blocks],
        "vertex_groups": [g.name for g in obj.vertex_groups],
        "armatures": [a.name for a in armatures],
        "bones": [b.name for b in armatures[0].data.bones] if armatures else [],
        "actions": [{"name": a.name, "frame_range": list(a.frame_range)} for a in bpy.data.actions],
        "fps": fps,
    }
    print("BLENDER_JSON " + json.dumps(report))


main()
