"""STL: bare triangles, so loading merges equal corners in order of first use.

STL has no vertex indices: a mesh read back has its distinct corners in the order the triangles
first use them, which ``encode_stl`` warns about when that is not the mesh's own order.
"""

from __future__ import annotations

import struct
import warnings
from pathlib import Path

import numpy as np

from mimetic.errors import MeshError, MimeticWarning
from mimetic.mesh.io.common import Loaded, trimesh_scene, warn_parts_dropped
from mimetic.mesh.model import Mesh


def read_stl(data: bytes, src: str, path: Path) -> Loaded:
    binary = len(data) >= 84 and len(data) == 84 + 50 * struct.unpack_from("<I", data, 80)[0]
    if not binary:
        head = data.lstrip()[:5].lower()
        if head != b"solid" or b"\x00" in data[:4096]:
            raise MeshError(
                f"{src}: not an STL file (neither a binary STL of the size its header gives, nor text "
                "starting with 'solid'). The file is truncated or in another format."
            )
    scene = trimesh_scene(data, "stl", src, path)
    import trimesh

    geometries = [g for g in scene.geometry.values() if isinstance(g, trimesh.Trimesh)]
    if not geometries:
        return Loaded(np.zeros((0, 3)), np.zeros((0, 3), np.int64))
    corners = np.concatenate([np.asarray(g.vertices)[np.asarray(g.faces)].reshape(-1, 3) for g in geometries])
    vertices, faces = _merge_corners(corners)
    parts: dict[str, np.ndarray] = {}
    if len(geometries) > 1:
        offsets = np.cumsum([0] + [len(g.faces) for g in geometries])
        parts = {
            str(name): np.arange(lo, hi)
            for name, lo, hi in zip(scene.geometry, offsets, offsets[1:], strict=False)
        }
    return Loaded(vertices, faces, parts)


def _merge_corners(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indexed mesh from triangle corners (3m, 3): equal corners merged, in order of first use.

    Returns vertices (n, 3) float64 and faces (m, 3) int64. Sorts rows with ``np.lexsort``
    (``np.unique(axis=0)`` is several times slower).
    """
    c = np.asarray(corners, dtype=np.float64)
    order = np.lexsort((c[:, 2], c[:, 1], c[:, 0]))  # stable: equal rows keep file order
    sc = c[order]
    new = np.r_[True, (sc[1:] != sc[:-1]).any(axis=1)]  # (3m,) starts a new distinct row
    group = np.cumsum(new) - 1  # distinct-row id of each sorted corner
    first = order[new]  # first use of each distinct row
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    inverse = np.empty(len(c), dtype=np.int64)
    inverse[order] = rank[group]
    return c[np.sort(first)], inverse.reshape(-1, 3)


def encode_stl(mesh: Mesh, src: str) -> bytes:
    import trimesh

    warn_parts_dropped(mesh, src, "STL")
    stored = mesh.vertices.astype(np.float32)[mesh.faces].reshape(-1, 3)
    vertices, faces = _merge_corners(stored)
    if len(vertices) != mesh.n_vertices or not np.array_equal(faces, mesh.faces):
        warnings.warn(
            f"{src}: STL stores bare triangles, so this mesh will read back with {len(vertices)} vertices in "
            f"order of first use, not its {mesh.n_vertices} in their own order. Save as .ply or .obj to keep "
            "vertex order.",
            MimeticWarning,
            stacklevel=3,
        )
    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False, validate=False)
    return tm.export(file_type="stl")
