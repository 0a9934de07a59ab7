"""FBX (.fbx, binary): read through Blender's own FBX importer (``mimetic.blender``), never written here.

Blender imports the file in a separate process and hands back its meshes' arrays: vertices in the
file's order and unit (``GlobalSettings`` ``UnitScaleFactor``: mm, cm, dm, m or in), turned from the
file's declared axes into +Y up, +Z forward; polygons fan-triangulated in place; one part per mesh
object, or per material of a single object (none for a single object of one material). Writing
FBX is ``mimetic.export.fbx`` (a rig, not a mesh).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np

from mimetic.blender import run_script
from mimetic.errors import MeshError
from mimetic.mesh.io.common import Loaded

BINARY_MAGIC = b"Kaydara FBX Binary  \x00"


def check_fbx_bytes(data: bytes, src: str) -> None:
    """Reject what Blender's importer cannot read before starting it: ASCII FBX, other files.

    Raises
    ------
    MeshError
        One line naming the file and what to do.
    """
    if data.startswith(BINARY_MAGIC):
        return
    head = data[:4096].lstrip()
    if head.startswith(b";") or b"FBXHeaderExtension" in head:
        raise MeshError(f"{src}: ASCII FBX is not supported by Blender's importer; save as binary")
    raise MeshError(
        f"{src}: not a binary FBX file (it does not start with 'Kaydara FBX Binary'); the file is corrupt "
        "or not FBX. Re-export it as binary FBX."
    )


def read_fbx(data: bytes, src: str, path: Path) -> Loaded:
    check_fbx_bytes(data, src)
    with tempfile.TemporaryDirectory(prefix="mimetic-fbx-") as folder:
        out = Path(folder) / "mesh.npz"
        try:
            report = run_script("fbx_read.py", [str(Path(path).resolve()), str(out)], error=MeshError)
        except MeshError as error:
            raise MeshError(f"{src}: {error}") from None
        with np.load(out) as arrays:
            vertices, faces, labels = arrays["vertices"], arrays["faces"], arrays["labels"]
    found = {name: np.flatnonzero(labels == k) for k, name in enumerate(report["parts"])}
    parts = {name: ids for name, ids in found.items() if len(ids)} if len(found) > 1 else {}
    return Loaded(vertices, faces, parts, units=report["units"])
