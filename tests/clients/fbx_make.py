"""Write the FBX files the reading tests need with Blender itself (no binaries in the repository).

Runs inside the bpy venv: ``python fbx_make.py KIND OUT.fbx [HEAD.glb]``, KIND one of

* ``no_mesh``: an armature and an empty, no mesh;
* ``body``: seven boxes making a 1.8 m figure (a whole body: head, torso, arms, legs);
* ``head_mm_z_up``: the head GLB (its armature and skinned mesh), saved in millimetres
  (``UnitScaleFactor`` 0.1) with the file's axes +Z up, -Y forward (as 3ds Max writes them).
"""

import sys

import bpy


def main() -> None:
    kind, out = sys.argv[1], sys.argv[2]
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    options = {"axis_forward": "-Z", "axis_up": "Y"}
    if kind == "no_mesh":
        bpy.ops.object.armature_add()
        bpy.ops.object.empty_add()
    elif kind == "body":
        for x, z, sx, sz in ((0, 1.65, 0.1, 0.12), (0, 1.2, 0.2, 0.35), (-0.35, 1.2, 0.05, 0.35),
                             (0.35, 1.2, 0.05, 0.35), (-0.1, 0.45, 0.07, 0.45), (0.1, 0.45, 0.07, 0.45),
                             (0, 1.45, 0.04, 0.05)):  # fmt: skip
            bpy.ops.mesh.primitive_cube_add(location=(x, 0, z), scale=(sx, 0.1, sz))
    elif kind == "head_mm_z_up":
        scene.unit_settings.scale_length = 0.001  # one Blender unit is a millimetre
        bpy.ops.import_scene.gltf(filepath=sys.argv[3])
        for obj in list(scene.objects):  # the importer's bone shape and the skinned mesh node's empty
            if obj.type == "EMPTY" or (obj.type == "MESH" and obj.parent is None):
                bpy.data.objects.remove(obj)
        options = {"axis_forward": "-Y", "axis_up": "Z", "apply_scale_options": "FBX_SCALE_UNITS"}
    else:
        raise SystemExit(f"unknown kind {kind!r}")
    bpy.ops.export_scene.fbx(filepath=out, apply_unit_scale=True, add_leaf_bones=False, **options)


main()
