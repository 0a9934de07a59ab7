"""Deformation engines: activations in, vertex positions out.

``make_engine(rig, "wire" | "vector" | "fem" | "tissue")`` prepares an engine;
``engine.deform(pose) -> (n, 3)``.
Every engine runs the thesis's chain after its muscle stage (skull, creases, skinning, lid
sculptors) and can be baked to a linear ``Basis`` with ``bake(engine).basis``;
``evaluate_basis(basis, activations)`` then gives the vertices of any number of frames fast.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from mimetic.engines.bake import bake
from mimetic.engines.basis import Basis, evaluate_basis
from mimetic.rig.model import Rig

__all__ = ["ENGINES", "Basis", "Engine", "bake", "evaluate_basis", "make_engine"]

ENGINES = ("wire", "vector", "fem", "tissue")


class Engine(Protocol):
    name: str
    rig: Rig
    channels: tuple[str, ...]

    def deform(self, values: np.ndarray) -> np.ndarray: ...


def make_engine(rig: Rig, name: str = "wire", *, progress=None, **options) -> Engine:
    """Prepare the named engine for a rig (option ``skull``: False leaves out the skull push).

    Engines work from vertex positions and the rig's precomputed anatomy (``Rig.anatomy``), which
    is derived across unwelded seams, so coincident copies of a vertex (a UV seam, an unwelded
    patch) move together in every pose. ``progress(done, total)`` hears the preparation's stages of
    the engines that take seconds to prepare (fem, tissue); wire and vector are ready at once.
    """
    if name == "wire":
        from mimetic.engines.wire import WireEngine

        return WireEngine(rig, **options)
    if name == "vector":
        from mimetic.engines.vector import VectorEngine

        return VectorEngine(rig, **options)
    if name == "fem":
        from mimetic.engines.fem import FemEngine

        return FemEngine(rig, progress=progress, **options)
    if name == "tissue":
        from mimetic.engines.tissue import TissueEngine

        return TissueEngine(rig, progress=progress, **options)
    from mimetic.errors import MimeticError

    raise MimeticError(f"unknown engine {name!r}; choose one of {', '.join(ENGINES)}")
