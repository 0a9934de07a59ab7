"""Length units of a mesh: check them, guess them from the size of a head, convert between them.

A human head is about 20–26 cm from chin to crown (up to ~30 cm with some neck), and a face-only
mask 12–20 cm. :func:`detect_units` picks the metric unit that puts the mesh's largest bounding-box
extent closest to a typical head size (22 cm, on a log scale) and accepts it when the result lies
in ``PLAUSIBLE_EXTENT_M``. That window is one decade wide and centred on 22 cm, so exactly one
metric unit can ever match: there are no ties and no gaps between units. Inches ("in") are
accepted when a user or a file says so, never guessed: a head 9 units tall would be a 9 cm face
mask or a 23 cm head in inches, and the size cannot tell which.
"""

from __future__ import annotations

import math

import numpy as np

from mimetic.errors import MeshError

UNIT_SCALE: dict[str, float] = {"mm": 1e-3, "cm": 1e-2, "dm": 1e-1, "m": 1.0, "in": 0.0254}
"""Metres per unit."""

_DECADE = {"mm": -3, "cm": -2, "dm": -1, "m": 0}  # log10 of UNIT_SCALE for the metric units, exact

TYPICAL_HEAD_EXTENT_M = 0.22
"""Largest bounding-box extent of a typical head mesh, in metres."""

PLAUSIBLE_EXTENT_M = (TYPICAL_HEAD_EXTENT_M / math.sqrt(10.0), TYPICAL_HEAD_EXTENT_M * math.sqrt(10.0))
"""(low, high) largest extent, in metres, accepted as a head or face: about 7 cm to 70 cm."""


def check_units(units: str) -> str:
    """Return ``units`` if it is one of ``UNIT_SCALE`` ("mm", "cm", "dm", "m", "in"); else raise MeshError."""
    if not isinstance(units, str) or units not in UNIT_SCALE:
        raise MeshError(f"unknown units {units!r}; use one of {', '.join(map(repr, UNIT_SCALE))}.")
    return units


def largest_extent(vertices: np.ndarray) -> float:
    """Largest side of the axis-aligned bounding box of the finite rows of ``vertices`` (n, 3).

    Rows with a NaN or infinite coordinate are ignored. Returns NaN when no row is finite, and
    inf when the extent overflows float64.
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    finite = vertices[np.isfinite(vertices).all(axis=1)]  # (k, 3)
    if len(finite) == 0:
        return math.nan
    with np.errstate(over="ignore"):  # e.g. -1e308 .. 1e308 gives inf, which is fine
        return float(np.max(finite.max(axis=0) - finite.min(axis=0)))


def units_for_extent(extent: float) -> str | None:
    """The metric unit in which a largest extent ``extent`` (in unknown units) is a plausible head size.

    Returns None when no metric unit gives an extent inside ``PLAUSIBLE_EXTENT_M``.
    """
    if not math.isfinite(extent) or extent <= 0.0:
        return None
    log_typical = math.log(TYPICAL_HEAD_EXTENT_M)
    unit = min(_DECADE, key=lambda u: abs(math.log(extent * UNIT_SCALE[u]) - log_typical))
    low, high = PLAUSIBLE_EXTENT_M
    return unit if low <= extent * UNIT_SCALE[unit] < high else None


def detect_units(vertices: np.ndarray) -> str:
    """Guess the units of a head or face mesh from its size.

    Parameters
    ----------
    vertices : (n, 3) float64
        Vertex positions; rows with non-finite coordinates are ignored.

    Returns
    -------
    units : str
        "mm", "cm", "dm" or "m": the unit in which the largest bounding-box extent is closest to
        a typical head (22 cm) and within ``PLAUSIBLE_EXTENT_M`` (about 7–70 cm).

    Raises
    ------
    MeshError
        No vertex is finite, or no unit makes the mesh head-sized (e.g. an extent of 1e6 or 1e-6).
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise ValueError(f"vertices must have shape (n, 3); got {vertices.shape}")
    extent = largest_extent(vertices)
    if math.isnan(extent):
        raise MeshError(
            f"cannot tell the units: none of the {len(vertices)} vertices has finite coordinates. "
            'Fix the mesh, or pass units="cm" (CLI --units cm) with its real unit.'
        )
    unit = units_for_extent(extent)
    if unit is None:
        low, high = PLAUSIBLE_EXTENT_M
        raise MeshError(
            f"cannot tell the units: the largest extent is {extent:.3g}, which is not a head size "
            f"({low * 100:.0f}–{high * 100:.0f} cm) in any of {', '.join(UNIT_SCALE)}. Check that the file "
            'is a head or face, then pass units="cm" (CLI --units cm) with its real unit.'
        )
    return unit


def convert_units(vertices: np.ndarray, from_units: str, to_units: str) -> np.ndarray:
    """Rescale positions ``vertices`` (n, 3) from ``from_units`` to ``to_units``.

    Returns a new (n, 3) float64 array (a copy even when the units are equal).

    Raises
    ------
    MeshError
        A unit is not one of ``UNIT_SCALE``.
    """
    check_units(from_units), check_units(to_units)
    if from_units in _DECADE and to_units in _DECADE:
        # 10 ** integer is exact for the ratios >= 1, and the nearest double otherwise
        # (0.1 / 0.001 would give 100.00000000000001).
        scale = 10.0 ** (_DECADE[from_units] - _DECADE[to_units])
    else:
        scale = UNIT_SCALE[from_units] / UNIT_SCALE[to_units]
    vertices = np.asarray(vertices, dtype=np.float64)
    if vertices.ndim != 2 or vertices.shape[1] != 3:
        raise ValueError(f"vertices must have shape (n, 3); got {vertices.shape}")
    return vertices * scale
