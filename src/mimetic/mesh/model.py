"""The ``Mesh``, ``Material`` and ``SurfacePoint`` data types.

A ``Mesh`` is a triangle soup with a fixed vertex order: nothing in mimetic reorders, merges
or drops vertices, because every rig element refers to them by index.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np


def _frozen(array: np.ndarray) -> np.ndarray:
    array = np.ascontiguousarray(array)
    array.setflags(write=False)
    return array


TRANSPARENT_BELOW = 0.5
"""A material with opacity below this is a see-through layer (a tear film, an eye occlusion shell)."""


@dataclass(frozen=True)
class Material:
    """How a part's surface looks, as its file states it (an OBJ ``.mtl`` entry, a glTF material).

    Attributes
    ----------
    name : str, optional
        The material's name in the file (e.g. "M_EyeLashes"), which often says what a part is.
    color : (r, g, b) floats in [0, 1], optional
        The flat diffuse colour (``Kd``, ``baseColorFactor``); None when the file gives none, or
        only a texture, which mimetic does not read.
    opacity : float in [0, 1]
        1 is opaque (``d``, ``1 - Tr``, glTF alpha).
    """

    name: str | None = None
    color: tuple[float, float, float] | None = None
    opacity: float = 1.0

    def __post_init__(self) -> None:
        if self.color is not None:
            rgb = tuple(float(c) for c in np.asarray(self.color, dtype=np.float64).reshape(-1))
            if len(rgb) != 3 or not all(0.0 <= c <= 1.0 for c in rgb):
                raise ValueError(
                    f"material {self.name!r}: color must be 3 numbers in [0, 1]; got {self.color!r}"
                )
            object.__setattr__(self, "color", rgb)
        opacity = float(self.opacity)
        if not 0.0 <= opacity <= 1.0:
            raise ValueError(f"material {self.name!r}: opacity={self.opacity} must be in [0, 1]")
        object.__setattr__(self, "opacity", opacity)

    @property
    def transparent(self) -> bool:
        """Whether the surface is mostly see-through (opacity below ``TRANSPARENT_BELOW``)."""
        return self.opacity < TRANSPARENT_BELOW


@dataclass(frozen=True, eq=False)
class Mesh:
    """A triangle mesh with named parts.

    Attributes
    ----------
    vertices : (n, 3) float64
        Positions in ``units`` (or unknown units when ``units`` is None).
    faces : (m, 3) int64
        Counter-clockwise triangles seen from outside, 0-based vertex indices.
    parts : Mapping[str, (k,) int64]
        Part name → sorted face indices, e.g. ``{"skin": ..., "eye_L": ...}``. Empty when the
        source had no parts. Parts need not cover every face.
    colors : (n, 3) float32 in [0, 1], optional
        Per-vertex albedo (e.g. the iris and pupil of an eyeball).
    units : str, optional
        "mm", "cm", "dm" or "m" when known.
    materials : Mapping[str, Material]
        Part name → the material its faces use in the source file (colour, opacity, name), for
        the parts a file names after its materials; empty when the file has none. Every key is a
        part. ``colors`` already holds the materials' colours when the file coloured every face.
    """

    vertices: np.ndarray
    faces: np.ndarray
    parts: Mapping[str, np.ndarray] = field(default_factory=dict)
    colors: np.ndarray | None = None
    units: str | None = None
    materials: Mapping[str, Material] = field(default_factory=dict)

    def __post_init__(self) -> None:
        vertices = np.asarray(self.vertices, dtype=np.float64)
        faces = np.asarray(self.faces, dtype=np.int64)
        if vertices.ndim != 2 or vertices.shape[1] != 3:
            raise ValueError(f"vertices must have shape (n, 3); got {vertices.shape}")
        if faces.size == 0:
            faces = faces.reshape(0, 3)
        if faces.ndim != 2 or faces.shape[1] != 3:
            raise ValueError(f"faces must have shape (m, 3); got {faces.shape}")
        object.__setattr__(self, "vertices", _frozen(vertices))
        object.__setattr__(self, "faces", _frozen(faces))
        parts = {str(k): _frozen(np.asarray(v, dtype=np.int64)) for k, v in self.parts.items()}
        object.__setattr__(self, "parts", MappingProxyType(parts))
        if self.colors is not None:
            colors = np.asarray(self.colors, dtype=np.float32)
            if colors.shape != vertices.shape:
                raise ValueError(f"colors must have shape {vertices.shape}; got {colors.shape}")
            object.__setattr__(self, "colors", _frozen(colors))
        materials = dict(self.materials)
        for name, material in materials.items():
            if name not in parts:
                raise ValueError(f"material of part {name!r}, which is not a part; parts are {sorted(parts)}")
            if not isinstance(material, Material):
                raise ValueError(f"materials[{name!r}] must be a Material; got {type(material).__name__}")
        object.__setattr__(self, "materials", MappingProxyType(materials))

    @property
    def n_vertices(self) -> int:
        return len(self.vertices)

    @property
    def n_faces(self) -> int:
        return len(self.faces)

    def with_vertices(self, vertices: np.ndarray) -> Mesh:
        """The same mesh (faces, parts, colours, units, materials) with new vertex positions (n, 3)."""
        vertices = np.asarray(vertices, dtype=np.float64)
        if vertices.shape != self.vertices.shape:
            raise ValueError(f"expected vertices of shape {self.vertices.shape}; got {vertices.shape}")
        return Mesh(vertices, self.faces, self.parts, self.colors, self.units, self.materials)

    def part_vertices(self, name: str) -> np.ndarray:
        """Sorted indices (k,) int64 of the vertices used by the faces of part ``name``."""
        if name not in self.parts:
            raise KeyError(f"no part {name!r}; parts are {sorted(self.parts)}")
        return np.unique(self.faces[self.parts[name]])

    def submesh(self, names: str | list[str]) -> tuple[Mesh, np.ndarray]:
        """The faces of one or more parts as a compact mesh.

        Returns the sub-mesh and ``index`` (k,) int64, the original index of each of its vertices,
        so ``sub.vertices == mesh.vertices[index]``.
        """
        names = [names] if isinstance(names, str) else list(names)
        face_ids = np.unique(np.concatenate([self.parts[n] for n in names])) if names else np.zeros(0, int)
        faces = self.faces[face_ids]
        index, inverse = np.unique(faces, return_inverse=True)
        colors = None if self.colors is None else self.colors[index]
        sub = Mesh(self.vertices[index], inverse.reshape(-1, 3), {}, colors, self.units)
        return sub, index

    @staticmethod
    def concatenate(pieces: Mapping[str, Mesh], units: str | None = None) -> Mesh:
        """Join named meshes into one, in the given order; each becomes a part.

        Vertices keep their order within each piece; piece k's indices are offset by the vertex
        count of the pieces before it. Missing colours default to mid grey.
        """
        vertices, faces, parts, colors = [], [], {}, []
        v_off = f_off = 0
        any_color = any(p.colors is not None for p in pieces.values())
        for name, piece in pieces.items():
            vertices.append(piece.vertices)
            faces.append(piece.faces + v_off)
            parts[name] = np.arange(f_off, f_off + piece.n_faces)
            if any_color:
                c = piece.colors if piece.colors is not None else np.full((piece.n_vertices, 3), 0.6)
                colors.append(c)
            v_off += piece.n_vertices
            f_off += piece.n_faces
        return Mesh(
            np.concatenate(vertices) if vertices else np.zeros((0, 3)),
            np.concatenate(faces) if faces else np.zeros((0, 3), np.int64),
            parts,
            np.concatenate(colors) if any_color else None,
            units,
        )


@dataclass(frozen=True)
class SurfacePoint:
    """A point on a mesh surface: a triangle and barycentric weights.

    ``face`` indexes ``mesh.faces``; ``bary`` (3,) sums to 1 and weights that face's three
    vertices. A point exactly on a vertex has one weight equal to 1.
    """

    face: int
    bary: tuple[float, float, float]

    def position(self, vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
        """Position (3,) on the mesh with these ``vertices`` (n, 3) and ``faces`` (m, 3)."""
        return np.asarray(self.bary) @ vertices[faces[self.face]]

    @staticmethod
    def at_vertex(vertex: int, faces: np.ndarray) -> SurfacePoint:
        """The surface point at vertex ``vertex``, on the first face that uses it."""
        rows, cols = np.nonzero(faces == vertex)
        if len(rows) == 0:
            raise ValueError(f"vertex {vertex} is used by no face")
        bary = [0.0, 0.0, 0.0]
        bary[int(cols[0])] = 1.0
        return SurfacePoint(int(rows[0]), (bary[0], bary[1], bary[2]))


def surface_positions(points: list[SurfacePoint], vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Positions (k, 3) of several surface points on ``vertices`` (n, 3) / ``faces`` (m, 3)."""
    if not points:
        return np.zeros((0, 3))
    face_ids = np.array([p.face for p in points])
    bary = np.array([p.bary for p in points])  # (k, 3)
    return np.einsum("kj,kjd->kd", bary, vertices[faces[face_ids]])  # (k, 3)
