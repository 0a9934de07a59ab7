"""The skull under the forehead: a surface the skin slides over and never enters.

Raising the brows drags the skin over the brow ridge; without a skull the wires pull it straight
through the bone and the forehead looks stretched (the automated-rigging thesis, §4.3). As in the
thesis the skull is lofted through the forehead's own rest vertices, ``SKULL_CLEARANCE_REL``
under them, and the engines push forehead skin that moved behind it forward (+Z) onto it.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

SKULL_CLEARANCE_REL = 0.0
"""Depth of the skull surface under the rest forehead, × the head height (the thesis lofts it on it)."""
MIN_SKULL_VERTICES = 10
"""A forehead region with fewer vertices gets no skull."""


@dataclass(frozen=True, eq=False)
class Skull:
    """The forehead's skull surface.

    Attributes
    ----------
    vertices : (k,) int64
        The skin vertices the skull pushes (the forehead region).
    surface : (k, 3) float64
        The skull's sample points under them (rig units): a height field over (x, y).
    """

    vertices: np.ndarray
    surface: np.ndarray

    def __post_init__(self) -> None:
        for name, dtype in (("vertices", np.int64), ("surface", np.float64)):
            array = np.array(getattr(self, name), dtype=dtype, copy=True)
            array.setflags(write=False)
            object.__setattr__(self, name, array)

    def __len__(self) -> int:
        return len(self.vertices)


def forehead_skull(vertices: np.ndarray, regions: Mapping[str, np.ndarray], scale: float) -> Skull:
    """The skull under the ``forehead`` region of a rest mesh ``vertices`` (n, 3), rig units; empty
    when the region is missing or smaller than ``MIN_SKULL_VERTICES``."""
    ids = np.asarray(regions.get("forehead", np.zeros(0, np.int64)), dtype=np.int64)
    if len(ids) < MIN_SKULL_VERTICES:
        return Skull(np.zeros(0, np.int64), np.zeros((0, 3)))
    surface = vertices[ids] - np.array([0.0, 0.0, SKULL_CLEARANCE_REL * scale])
    return Skull(ids, surface)
