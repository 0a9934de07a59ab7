"""Deformation engines: activations in, vertex positions out.

``make_engine(rig, "wire" | "vector")`` prepares an engine; ``engine.deform(pose) -> (n, 3)``.
Every engine runs the thesis's chain after its muscle stage (skull, creases, skinning, lid
sculptors) and can be baked to a linear ``Basis`` with ``mimetic.engines.bake.bake``.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from mimetic.rig.model import Rig

ENGINES = ("wire", "vector")


class Engine(Protocol):
    name: str
    rig: Rig
    channels: tuple[str, ...]

    def deform(self, values: np.ndarray) -> np.ndarray: ...


def make_engine(rig: Rig, name: str = "wire", **options) -> Engine:
    """Prepare the named engine for a rig (options: ``skull``, ``creases``)."""
    if name == "wire":
        from mimetic.engines.wire import WireEngine

        return WireEngine(rig, **options)
    if name == "vector":
        from mimetic.engines.vector import VectorEngine

        return VectorEngine(rig, **options)
    from mimetic.errors import MimeticError

    raise MimeticError(f"unknown engine {name!r}; choose one of {', '.join(ENGINES)}")
