"""mimetic: turn any 3D head mesh into a muscle-driven, animatable face.

The front door, one name per job (each is imported on first use, so ``import mimetic`` stays fast)::

    import mimetic

    mesh = mimetic.load_mesh("my_head.obj")                 # any units, any axis-aligned frame
    result = mimetic.rig_mesh(mesh, "landmarks.csv")        # or None: MediaPipe finds them
    rig = result.rig                                        # on your vertices, in your units
    mimetic.save_rig(rig, "my_head.mrig")

    engine = mimetic.make_engine(rig, "wire")
    joy = engine.deform(mimetic.expression_pose(rig, "joy"))        # (n, 3) vertex positions
    smile = mimetic.pose(rig, {"zygomatic_major_L": 1.0, "jaw_open": 0.2})

    clip = mimetic.from_expressions(rig, [(0, "rest"), (1, "joy"), (2, "rest")]).sample(30, channels=rig)
    mimetic.export_glb(rig, "joy.glb", morph_targets=mimetic.morph_targets(rig), clip=clip)
    mimetic.save_image(mimetic.render_pose(rig, "wire", clip.values[30]), "joy.png")

Meshes: ``load_mesh``, ``save_mesh``, ``Mesh``. The built-in head: ``make_head``, ``HeadParams``,
``build_rig``. Rigging any head: ``rig_mesh`` (one call), ``rig_head``, ``read_landmarks``,
``auto_landmarks``. Rigs: ``Rig``, ``load_rig``, ``save_rig``. Deforming: ``make_engine``,
``bake``, ``evaluate_basis``, ``pose``. Driving: ``expression_pose``, ``blend``,
``load_library``, ``arkit_pose``, ``facs_pose``, ``Clip``, ``from_expressions``, ``load_clip``,
``save_clip``. Delivering: ``export_glb``, ``export_fbx``, ``export_usd``, ``export_obj_sequence``,
``morph_targets``, ``arkit_shapes``, ``render_mesh``, ``render_pose``, ``render_clip``, ``save_image``.
Speech: ``lip_sync``, ``load_timings``, ``LiveLipSync``. Capture: ``Trajectories``, ``read_trajectories``,
``track_video``, ``marker_set``, ``solve_performance``, ``retarget``. Many at once: ``run_batch``,
``rig_many``, ``animate_many``, ``render_many``, ``speak_many``, ``capture_many``. Every command as a
task: ``TASKS`` (``mimetic.tasks``).

Coordinates are right-handed, +Y up, +Z forward (the face looks down +Z), as in glTF.
Lengths keep the source mesh's units; the rig records them.
"""

from __future__ import annotations

import importlib
from typing import Any

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

_API = {
    "Mesh": "mimetic.mesh.model",
    "load_mesh": "mimetic.mesh.io",
    "save_mesh": "mimetic.mesh.io",
    "Head": "mimetic.head.model",
    "make_head": "mimetic.head.model",
    "HeadParams": "mimetic.head.params",
    "build_rig": "mimetic.rig.recipe",
    "rig_mesh": "mimetic.fit.pipeline",
    "rig_head": "mimetic.fit.pipeline",
    "RigResult": "mimetic.fit.pipeline",
    "Landmarks": "mimetic.fit.landmarks",
    "read_landmarks": "mimetic.fit.landmarks",
    "write_landmarks": "mimetic.fit.landmarks",
    "auto_landmarks": "mimetic.fit.autolandmarks",
    "Rig": "mimetic.rig.model",
    "load_rig": "mimetic.rig.format",
    "save_rig": "mimetic.rig.format",
    "make_engine": "mimetic.engines",
    "Basis": "mimetic.engines.basis",
    "bake": "mimetic.engines.bake",
    "evaluate_basis": "mimetic.engines.basis",
    "pose": "mimetic.rig.activations",
    "Clip": "mimetic.rig.activations",
    "expression_pose": "mimetic.animate.expressions",
    "blend": "mimetic.animate.expressions",
    "load_library": "mimetic.animate.expressions",
    "arkit_pose": "mimetic.animate.arkit",
    "facs_pose": "mimetic.animate.facs",
    "from_expressions": "mimetic.animate.keyframes",
    "load_clip": "mimetic.animate.clipfiles",
    "save_clip": "mimetic.animate.clipfiles",
    "export_glb": "mimetic.export.gltf",
    "morph_targets": "mimetic.export.gltf",
    "export_fbx": "mimetic.export.fbx",
    "export_usd": "mimetic.export.usd",
    "export_obj_sequence": "mimetic.export.obj_sequence",
    "arkit_shapes": "mimetic.export.arkit",
    "render_mesh": ("mimetic.render", "render"),
    "render_pose": "mimetic.view.sheets",
    "render_clip": "mimetic.view.video",
    "save_image": "mimetic.view.drawing",
    "lip_sync": "mimetic.speech.lipsync",
    "LiveLipSync": "mimetic.speech.stream",
    "load_timings": "mimetic.speech.timings",
    "Trajectories": "mimetic.capture.trajectories",
    "read_trajectories": "mimetic.capture.formats",
    "track_video": "mimetic.capture.video",
    "marker_set": "mimetic.capture.markers",
    "solve_performance": "mimetic.capture.performance",
    "retarget": "mimetic.capture.retarget",
    "run_batch": "mimetic.batch.run",
    "rig_many": "mimetic.batch.run",
    "animate_many": "mimetic.batch.run",
    "render_many": "mimetic.batch.run",
    "speak_many": "mimetic.batch.run",
    "capture_many": "mimetic.batch.run",
    "TASKS": "mimetic.tasks",
}

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
    *sorted(_API),
]


def __getattr__(name: str) -> Any:
    """The front door's names, each imported from its module on first use."""
    where = _API.get(name)
    if where is None:
        raise AttributeError(f"module 'mimetic' has no attribute {name!r}")
    module, attribute = where if isinstance(where, tuple) else (where, name)
    value = getattr(importlib.import_module(module), attribute)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_API))
