"""Inside Blender: a mimetic .glb in, an FBX out (Blender's own glTF importer and FBX exporter).

``fbx_write.py -- GLB FBX NAME FPS FRAMES TAKE``: FPS the clip's rate (frames per second), FRAMES its
number of frames (0: no animation), TAKE the animation's name. The FBX holds the skinned mesh
(one material per part), the armature (one bone per joint, no leaf bones) and one shape key per
morph target; with FRAMES > 0 one take sampled at every frame of the clip (bones and shape-key
values, unsimplified). Units: centimetres (``UnitScaleFactor`` 1), vertex data scaled by 100 from
the glTF's metres. Axes: the file declares +Y up and -Z forward, Unity's and Unreal's defaults;
Blender's Z-up scene is turned into them by a -90° rotation on the root objects (Blender's
default), which both importers undo. Prints ``MIMETIC_JSON {...}`` (what was written).
"""

import json
import sys

import bpy


def main() -> None:
    glb, fbx, name, fps, frames, take = sys.argv[sys.argv.index("--") + 1 :]
    fps, frames = float(fps), int(frames)
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.fps = max(1, round(fps))
    # Blender 5.0's glTF importer turns seconds into frames at fps * fps_base, the FBX exporter (and the
    # rest of Blender) at fps / fps_base: set each so that frame i of the clip is Blender's frame i.
    scene.render.fps_base = fps / scene.render.fps
    scene.unit_settings.scale_length = (
        0.01  # one Blender unit is a centimetre: the glTF importer scales by 100
    )
    bpy.ops.import_scene.gltf(filepath=glb)
    scene.render.fps_base = scene.render.fps / fps
    armatures = [o for o in scene.objects if o.type == "ARMATURE"]
    meshes = [o for o in scene.objects if o.type == "MESH" and (o.parent in armatures or not armatures)]
    for obj in list(scene.objects):  # the skinned mesh node's empty, the importer's bone shapes
        if obj not in armatures and obj not in meshes:
            bpy.data.objects.remove(obj)
    for obj in armatures:
        obj.name = name
    for obj in meshes:
        obj.name = obj.data.name = f"{name}_mesh"
    scene.name = take
    if frames > 0:
        scene.frame_start, scene.frame_end = 0, frames - 1
    bpy.ops.export_scene.fbx(
        filepath=fbx,
        object_types={"ARMATURE", "MESH"},
        apply_unit_scale=True,
        apply_scale_options="FBX_SCALE_NONE",
        axis_forward="-Z",
        axis_up="Y",
        bake_space_transform=False,
        use_mesh_modifiers=False,
        mesh_smooth_type="OFF",
        add_leaf_bones=False,
        use_armature_deform_only=False,
        primary_bone_axis="Y",
        secondary_bone_axis="X",
        bake_anim=frames > 0,
        bake_anim_use_all_bones=True,
        bake_anim_use_nla_strips=False,
        bake_anim_use_all_actions=False,
        bake_anim_force_startend_keying=True,
        bake_anim_step=1.0,
        bake_anim_simplify_factor=0.0,
    )
    mesh = meshes[0].data if meshes else None
    report = {
        "blender": bpy.app.version_string,
        "fps": scene.render.fps / scene.render.fps_base,
        "meshes": [o.name for o in meshes],
        "vertices": sum(len(o.data.vertices) for o in meshes),
        "bones": [b.name for a in armatures for b in a.data.bones],
        "shape_keys": [k.name for k in mesh.shape_keys.key_blocks[1:]] if mesh and mesh.shape_keys else [],
        "frames": frames,
    }
    print("MIMETIC_JSON " + json.dumps(report))


main()
