"""Read and write meshes (.obj, .ply, .stl, .glb, .gltf; read .fbx) without changing their vertex order.

Every rig element refers to vertices by index, so a mesh must come back from disk with exactly
the vertices, in exactly the order, it was written with. What each format keeps:

========  =============  ==========  ===========================  ====================================
format    vertex order   precision   parts                        colours / units
========  =============  ==========  ===========================  ====================================
.obj      exact          float64     ``g`` groups (``o`` too),    ``v x y z r g b``, ``.mtl`` ``Kd`` /
                                     ``usemtl`` materials         ``# units: cm``
.ply      exact          float64     not stored (merged)          uchar RGB / ``comment units cm``
.glb      exact          float32     one node per part            COLOR_0, ``baseColorFactor`` /
                                                                  mesh ``extras.units``
.gltf     exact          float32     one node per part            as .glb
.stl      first use      float32     not stored (merged)          none / none
.fbx      exact          float32     mesh objects (or materials)  none / ``UnitScaleFactor``
========  =============  ==========  ===========================  ====================================

FBX is read only, and through Blender's own importer (``mimetic.blender``, bpy installed on first
use): binary FBX only, turned from the file's declared axes into +Y up, +Z forward.

OBJ is read and written by mimetic itself: trimesh 5.2 splits OBJ vertices by their ``vt``/``vn``
indices (or, with ``maintain_order=True``, drops unused trailing vertices), and returns groups in
reverse order, merged by name. OBJ polygons are fan-triangulated in place, so face order follows
the file. PLY is read by trimesh and written by mimetic (trimesh writes float32); a PLY mixing
triangles and quads comes back with the triangles first (trimesh's order, deterministic). glTF is
read and written by trimesh with processing off; node order comes from the file's own JSON,
because trimesh's scene graph lists nodes in reverse. STL has no vertex indices at all: loading
merges equal corners in order of first use.

Materials are read, not written: an OBJ's ``usemtl`` materials (with their ``.mtl`` colour and
opacity) and a multi-part glTF's primitive materials become ``Mesh.materials`` of the parts named
after them, and their flat colours become ``Mesh.colors`` when they colour every face. Saving
keeps those colours (as vertex colours) and parts, not the materials themselves.

Modules: ``common`` (what the readers share), ``obj``, ``ply``, ``stl``, ``gltf``, ``fbx`` (one per
format: ``read_*`` bytes to arrays, ``encode_*`` a mesh to bytes).
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

import numpy as np

from mimetic.atomic import atomic_write_bytes
from mimetic.errors import MeshError, MimeticWarning
from mimetic.inputs import read_input
from mimetic.mesh.io.common import check_loaded, file_units, log
from mimetic.mesh.io.fbx import read_fbx
from mimetic.mesh.io.gltf import encode_glb, encode_gltf, part_blocks, read_glb, read_gltf
from mimetic.mesh.io.obj import encode_obj, read_obj
from mimetic.mesh.io.ply import encode_ply, read_ply
from mimetic.mesh.io.stl import encode_stl, read_stl
from mimetic.mesh.model import Mesh
from mimetic.mesh.units import check_units, detect_units, largest_extent, units_for_extent

__all__ = [
    "READ_FORMATS",
    "SUPPORTED_FORMATS",
    "encode_obj",
    "load_mesh",
    "part_blocks",
    "read_input",
    "save_mesh",
]

SUPPORTED_FORMATS = (".obj", ".ply", ".stl", ".glb", ".gltf")
"""File extensions :func:`load_mesh` and :func:`save_mesh` accept (case-insensitive)."""

READ_FORMATS = (*SUPPORTED_FORMATS, ".fbx")
"""File extensions :func:`load_mesh` accepts: the written ones and FBX (through Blender)."""

READERS = {
    ".obj": read_obj,
    ".ply": read_ply,
    ".stl": read_stl,
    ".glb": read_glb,
    ".gltf": read_gltf,
    ".fbx": read_fbx,
}
"""Each format's reader: (bytes, file name for messages, path) → arrays in file order."""

ENCODERS = {
    ".obj": encode_obj,
    ".ply": encode_ply,
    ".stl": encode_stl,
    ".glb": encode_glb,
    ".gltf": encode_gltf,
}
"""Each format's writer: (mesh, file name for messages) → the file's bytes."""


def load_mesh(path: str | os.PathLike[str], *, units: str | None = None, check: bool = True) -> Mesh:
    """Read a triangle mesh, keeping its vertices exactly as stored (no merging or reordering).

    Parameters
    ----------
    path : path-like
        A .obj, .ply, .stl, .glb, .gltf (it may refer to .bin files beside it) or binary .fbx file
        (read by Blender's importer in a separate process; see the module table).
    units : {"mm", "cm", "dm", "m", "in"}, optional
        The unit the coordinates are in. It wins over anything else; the coordinates are never
        rescaled (use :func:`~mimetic.mesh.units.convert_units` for that). When omitted, the units
        written in the file are used (see the module table), else :func:`detect_units` guesses
        them from the head's size, with a ``MimeticWarning`` that says the guess.
    check : bool
        When True (default), reject meshes every later step would fail on: non-finite
        coordinates, fewer than ``MIN_FACES`` faces, or units that are neither given, stored nor
        detectable. When False, such meshes load (``units`` may be None) so that
        :func:`~mimetic.mesh.validate.validate_mesh` can report on them.

    Returns
    -------
    mesh : Mesh
        ``vertices`` (n, 3) float64 in file order, ``faces`` (m, 3) int64 in file order (OBJ
        polygons are fan-triangulated in place), ``parts`` from OBJ groups or glTF nodes
        (``{}`` for a single geometry), per-vertex ``colors`` when stored, and ``units``.

    Raises
    ------
    MeshError
        Naming the file: it is missing, has an unsupported extension, is not a mesh of its
        format, is truncated or corrupt, has no faces or face indices out of range, or (with
        ``check``) fails the checks above.
    """
    src = str(path)
    path = Path(path)
    ext = _extension(path, src, READ_FORMATS)
    if units is not None:
        units = check_units(units)
    data = read_input(path, src, MeshError, "mesh")
    loaded = READERS[ext](data, src, path)

    vertices = np.ascontiguousarray(loaded.vertices, dtype=np.float64)
    faces = np.ascontiguousarray(loaded.faces, dtype=np.int64).reshape(-1, 3)
    n, m = len(vertices), len(faces)
    if m == 0:
        raise MeshError(
            f"{src}: contains no faces ({n} vertices): it is empty or a point cloud. mimetic needs a "
            "triangle surface; export the mesh with its faces."
        )
    if faces.min() < 0 or faces.max() >= n:
        bad = int(np.flatnonzero((faces < 0).any(axis=1) | (faces >= n).any(axis=1))[0])
        raise MeshError(
            f"{src}: face {bad} refers to vertex {faces[bad].tolist()} but the file has {n} vertices "
            "(indices 0..n-1). The file is corrupt; re-export it."
        )
    if check:
        check_loaded(vertices, m, src)
    units = units or file_units(loaded.units, vertices, src)
    if units is None:
        extent = largest_extent(vertices)
        units = units_for_extent(extent)
        if units is None and check:  # re-run to raise detect_units' own message
            try:
                detect_units(vertices)
            except MeshError as error:
                raise MeshError(f"{src}: {error}") from None
        if units is not None:
            warnings.warn(
                f"{src} does not say its units; its size ({extent:.4g} across) suggests {units}. If that "
                f'is wrong, give them: units="cm" (CLI --units cm; mm, cm, dm, m or in)',
                MimeticWarning,
                stacklevel=2,
            )
    mesh = Mesh(vertices, faces, loaded.parts, loaded.colors, units, loaded.materials)
    log.info("loaded %s: %d vertices, %d faces, %d parts, units %s", src, n, m, len(mesh.parts), units)
    return mesh


def save_mesh(mesh: Mesh, path: str | os.PathLike[str]) -> Path:
    """Write ``mesh`` to ``path`` atomically, in the format its extension names.

    Parameters
    ----------
    mesh : Mesh
        Written in its own vertex and face order.
    path : path-like
        .obj (parts become ``g`` groups; a face in several parts gets ``g a b``), .ply or .stl
        (one merged surface, parts dropped with a log warning), .glb or .gltf (one named node per
        part; the .gltf embeds its buffer). ``mesh.units`` is recorded where the format allows.

    Returns
    -------
    path : Path
        The file written.

    Raises
    ------
    MeshError
        Unsupported extension; a part name an OBJ group cannot hold (empty or with spaces); for
        glTF, parts that are not consecutive blocks of faces and vertices.
    WriteError
        The folder does not exist or is not writable. The target is never left half-written.

    Warns
    -----
    MimeticWarning
        For .stl when the mesh read back would not have the same vertices in the same order.
    """
    src = str(path)
    path = Path(path)
    ext = _extension(path, src, SUPPORTED_FORMATS)
    data = ENCODERS[ext](mesh, src)
    atomic_write_bytes(path, data)
    log.info("wrote %s: %d vertices, %d faces", src, mesh.n_vertices, mesh.n_faces)
    return path


# --- shared helpers -------------------------------------------------------------------------------


def _extension(path: Path, src: str, formats: tuple[str, ...]) -> str:
    ext = path.suffix.lower()
    if ext not in formats:
        shown = f"'{path.suffix}'" if path.suffix else "no extension"
        raise MeshError(
            f"{src}: unsupported mesh format ({shown}); supported: {', '.join(formats)}. "
            "Convert the file (e.g. in Blender) or fix its extension."
        )
    return ext
