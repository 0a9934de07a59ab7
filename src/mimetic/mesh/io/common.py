"""What the format readers share: the loaded arrays before checks, units and colours, trimesh.

Each format module (``obj``, ``ply``, ``stl``, ``gltf``) reads bytes into a ``Loaded`` and encodes a
``Mesh`` into bytes; ``mimetic.mesh.io`` checks what was loaded and writes atomically.
"""

from __future__ import annotations

import io
import logging
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mimetic.errors import MeshError
from mimetic.mesh.model import Material, Mesh
from mimetic.mesh.units import largest_extent, units_for_extent
from mimetic.mesh.validate import MIN_FACES

log = logging.getLogger("mimetic.mesh.io")

DEFAULT_COLOR = 0.6
"""Grey given to vertices of glTF nodes without COLOR_0 when other nodes have it."""

UNIT_ALIASES = {
    **{u: u for u in ("mm", "cm", "dm", "m", "in")},
    **{
        f"{p}{s}": u
        for p, u in (("millimet", "mm"), ("centimet", "cm"), ("decimet", "dm"), ("met", "m"))
        for s in ("er", "ers", "re", "res")
    },
    "inch": "in",
    "inches": "in",
}


@dataclass
class Loaded:
    """What a format reader found, before checks: arrays in file order."""

    vertices: np.ndarray  # (n, 3) float64
    faces: np.ndarray  # (m, 3) int64
    parts: dict[str, np.ndarray] = field(default_factory=dict)
    colors: np.ndarray | None = None  # (n, 3) float32 in [0, 1]
    units: str | None = None  # as written in the file, not yet checked
    materials: dict[str, Material] = field(default_factory=dict)  # part name -> its material


PLACEHOLDER_MATERIAL = re.compile(
    r"^(default[\w ]*|material|none|lambert1|initialshadinggroup)([._]\d+)?$", re.IGNORECASE
)
"""Names modelling tools give the material of an untouched mesh (Blender "Material", Maya
"lambert1", "default"): their placeholder grey or white says nothing about the surface."""


def check_loaded(vertices: np.ndarray, n_faces: int, src: str) -> None:
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any():
        raise MeshError(
            f"{src}: {int(bad.sum())} of {len(vertices)} vertices have NaN or infinite coordinates "
            f"(first: vertex {int(np.argmax(bad))}). Fix or delete them in your modelling tool, or load "
            "with check=False and inspect the mesh with validate_mesh."
        )
    if n_faces < MIN_FACES:
        raise MeshError(
            f"{src}: only {n_faces} face{'s' * (n_faces != 1)}; a head mesh needs at least {MIN_FACES}. "
            "Check that this is the right file, or load with check=False."
        )


def file_units(raw: str | None, vertices: np.ndarray, src: str) -> str | None:
    """The units written in a file, normalised; None (and a log line) when absent or unknown."""
    if raw is None:
        return None
    units = UNIT_ALIASES.get(raw.strip().lower())
    if units is None:
        log.warning("%s: ignoring units %r recorded in the file (not one of mm, cm, dm, m)", src, raw)
        return None
    detected = units_for_extent(largest_extent(vertices))
    if detected is not None and detected != units:
        log.warning(
            "%s: the file says units %s but its size suggests %s; using %s", src, units, detected, units
        )
    return units


def colors_from_u8(rgba: np.ndarray) -> np.ndarray:
    """(n, 3 or 4) uint8 → (n, 3) float32 in [0, 1]."""
    return (np.asarray(rgba)[:, :3].astype(np.float32) / np.float32(255.0)).astype(np.float32)


def colors_to_u8(colors: np.ndarray) -> np.ndarray:
    """(n, 3) float in [0, 1] → (n, 3) uint8; NaN becomes 0."""
    c = np.nan_to_num(np.asarray(colors, dtype=np.float64), nan=0.0)
    return np.round(np.clip(c, 0.0, 1.0) * 255.0).astype(np.uint8)


def trimesh_scene(data: bytes, file_type: str, src: str, path: Path, **kwargs):
    """Parse ``data`` with trimesh (processing off); any failure becomes a MeshError."""
    import trimesh

    resolver = trimesh.resolvers.FilePathResolver(str(path.absolute()))
    try:
        return trimesh.load_scene(
            io.BytesIO(data), file_type=file_type, resolver=resolver, process=False, **kwargs
        )
    except Exception as error:  # trimesh raises ValueError, KeyError, IndexError, struct.error, ...
        raise MeshError(
            f"{src}: not a readable {file_type.upper()} file ({type(error).__name__}: {error}). "
            "Check that it is complete and really in this format; re-export it if it was truncated."
        ) from error


def trimesh_colors(geometry) -> np.ndarray | None:
    """Per-vertex colours (n, 3) float32 of a trimesh geometry, or None when it has none."""
    visual = geometry.visual
    if visual is None:
        return None
    if visual.kind == "vertex":
        return colors_from_u8(visual.vertex_colors)
    color = getattr(visual, "vertex_attributes", {}).get("color")
    if color is not None and len(color) == len(geometry.vertices):
        color = np.asarray(color)
        return (
            colors_from_u8(color)
            if color.dtype == np.uint8
            else np.clip(color[:, :3], 0, 1).astype(np.float32)
        )
    return None


def warn_parts_dropped(mesh: Mesh, src: str, fmt: str) -> None:
    """Log that ``fmt`` (PLY, STL) cannot store ``mesh``'s parts."""
    if mesh.parts:
        log.warning(
            "%s: %s cannot store parts; writing one merged surface (parts %s dropped)",
            src,
            fmt,
            list(mesh.parts),
        )
