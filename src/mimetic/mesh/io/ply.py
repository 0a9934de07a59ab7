"""PLY: read by trimesh, written by mimetic (binary, float64 positions; trimesh writes float32).

A PLY mixing triangles and quads comes back with the triangles first (trimesh's order,
deterministic). Parts are not stored; ``comment units cm`` records the units.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from mimetic.errors import MeshError
from mimetic.mesh.io.common import Loaded, colors_to_u8, trimesh_colors, trimesh_scene, warn_parts_dropped
from mimetic.mesh.model import Mesh

_PLY_UNITS = re.compile(rb"^comment\s+units\s+(\S+)\s*$", re.MULTILINE)


def read_ply(data: bytes, src: str, path: Path) -> Loaded:
    if not data.startswith(b"ply"):
        raise MeshError(f"{src}: not a PLY file (it does not start with 'ply'). Check the file's format.")
    end = data.find(b"end_header")
    if end < 0:
        raise MeshError(f"{src}: the PLY header has no 'end_header'; the file is truncated or corrupt.")
    match = _PLY_UNITS.search(data[:end])
    scene = trimesh_scene(data, "ply", src, path)
    loaded = _single_geometry(scene, src, "PLY")
    loaded.units = match.group(1).decode("ascii", "replace") if match else None
    return loaded


def _single_geometry(scene, src: str, fmt: str) -> Loaded:
    import trimesh

    geometries = [g for g in scene.geometry.values()]
    if not geometries:
        raise MeshError(f"{src}: the {fmt} file contains no geometry (empty mesh).")
    if len(geometries) > 1 or not isinstance(geometries[0], trimesh.Trimesh):
        g = geometries[0]
        if len(geometries) == 1 and isinstance(g, trimesh.PointCloud):
            return Loaded(np.asarray(g.vertices, dtype=np.float64), np.zeros((0, 3), np.int64))
        raise MeshError(
            f"{src}: expected one triangle mesh in the {fmt} file; found {len(geometries)} geometries."
        )
    g = geometries[0]
    return Loaded(np.asarray(g.vertices, np.float64), np.asarray(g.faces, np.int64), {}, trimesh_colors(g))


def encode_ply(mesh: Mesh, src: str) -> bytes:
    """Binary little-endian PLY with float64 positions (trimesh's own writer uses float32)."""
    warn_parts_dropped(mesh, src, "PLY")
    vertex_dtype = [("x", "<f8"), ("y", "<f8"), ("z", "<f8")]
    if mesh.colors is not None:
        vertex_dtype += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    vertex = np.zeros(mesh.n_vertices, dtype=vertex_dtype)
    for d, axis in enumerate("xyz"):
        vertex[axis] = mesh.vertices[:, d]
    if mesh.colors is not None:
        rgb = colors_to_u8(mesh.colors)
        for d, channel in enumerate(("red", "green", "blue")):
            vertex[channel] = rgb[:, d]
    face = np.zeros(mesh.n_faces, dtype=[("count", "u1"), ("index", "<i4", (3,))])
    face["count"] = 3
    face["index"] = mesh.faces
    header = ["ply", "format binary_little_endian 1.0", "comment written by mimetic"]
    if mesh.units:
        header.append(f"comment units {mesh.units}")
    header.append(f"element vertex {mesh.n_vertices}")
    header += [f"property {'double' if t == '<f8' else 'uchar'} {name}" for name, t in vertex_dtype]
    header += [f"element face {mesh.n_faces}", "property list uchar int vertex_indices", "end_header", ""]
    return "\n".join(header).encode("ascii") + vertex.tobytes() + face.tobytes()
