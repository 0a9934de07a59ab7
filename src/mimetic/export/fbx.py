"""Write a rig as FBX through Blender's own FBX exporter: what Unity, Unreal and Maya import.

mimetic writes its GLB (``export_glb``: mesh in parts, skin, skeleton, morph targets, clip) to a
temporary folder, then Blender (``mimetic.blender``, bpy in its own venv) imports it with its glTF
importer and exports FBX 7.4 binary with its FBX exporter. No FBX bytes are written by mimetic.

What the file holds
-------------------
* the skinned mesh, named ``<name>_mesh``, one material per part, vertices in rig order;
* the armature ``<name>`` (``<name>_rig`` if a bone has that name): one bone per rig joint (head,
  jaw, eyelids, eyes), no leaf bones;
* one shape key (FBX blend shape channel) per morph target, under its name (the muscle channels, or
  the 52 ARKit names);
* with a clip, one take named ``clip_name`` (FBX "animation stack") sampled at every clip frame at
  the clip's rate: bone rotations and translations, and shape-key values (FBX ``DeformPercent``);
* centimetres (``UnitScaleFactor`` 1, vertex data × 100 from metres), axes +Y up, -Z forward (the
  file's ``GlobalSettings``, Unity's and Unreal's defaults); the face looks down +Z as in glTF.

Blender's FBX importer reads it back within 1e-7 m of ``gltf_vertices`` at rest and posed
(tests/clients/test_fbx.py).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Mapping
from pathlib import Path

import numpy as np

from mimetic.atomic import atomic_path
from mimetic.blender import Progress, run_script
from mimetic.export.gltf import ExportError, export_glb
from mimetic.rig.activations import Clip
from mimetic.rig.model import Rig

SUFFIX = ".fbx"


def export_fbx(
    rig: Rig,
    path: str | os.PathLike[str],
    *,
    morph_targets: Mapping[str, np.ndarray] | None = None,
    clip: Clip | None = None,
    clip_name: str = "clip",
    name: str | None = None,
    progress: Progress | None = None,
) -> Path:
    """Write ``rig`` (and optionally morph targets and one clip) to an FBX file, atomically.

    Parameters
    ----------
    rig : Rig
        Its mesh, bones and skin weights; vertices are written in rig order.
    path : path-like
        The .fbx to create or replace; its folder must exist.
    morph_targets : Mapping[str, (n, 3) float], optional
        Displacements in rig units and rig vertex order, as for ``export_glb``: one shape key each.
    clip : Clip, optional
        Channel values over time at ``clip.fps``: drives shape keys of the same names and the bones.
    clip_name : str
        The take's name.
    name : str, optional
        The armature's name (the mesh is ``<name>_mesh``); defaults to the file's stem. A bone's name
        gets ``_rig`` appended (``head.fbx`` has the armature ``head_rig``).
    progress : callable(step, done, total), optional
        Told about installing Blender's bpy on first use (a minute or two).

    Returns
    -------
    path : Path
        The file written.

    Raises
    ------
    ExportError
        A bad morph target or clip (as ``export_glb``), or a path that does not end in .fbx.
    BlenderError
        bpy is missing and cannot be installed (no Python 3.11), or Blender failed.
    WriteError
        The folder is missing or not writable; an existing file is left as it was.
    """
    path = Path(path)
    if path.suffix.lower() != SUFFIX:
        raise ExportError(
            f"{path.name}: an FBX file must end in {SUFFIX} (got {path.suffix or 'no suffix'!r})"
        )
    name = name or path.stem
    if name in rig.bone_names:  # head.fbx: an armature "head" over a bone "head" confuses importers
        name = f"{name}_rig"
    with tempfile.TemporaryDirectory(prefix="mimetic-fbx-") as folder:
        glb = export_glb(rig, Path(folder) / f"{name}.glb", morph_targets=morph_targets, clip=clip,
                         clip_name=clip_name, target_normals=False, name=name)  # fmt: skip
        with atomic_path(path, keep_suffix=True) as tmp:
            fps, frames = (clip.fps, clip.n_frames) if clip is not None else (30.0, 0)
            run_script(
                "fbx_write.py",
                [str(glb), str(tmp), name, repr(float(fps)), str(frames), clip_name],
                error=ExportError,
                progress=progress,
            )
    return path
