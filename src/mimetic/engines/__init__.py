"""Deformation engines: activations in, vertex positions out.

``make_engine(rig, "wire" | "vector")`` prepares an engine; ``engine.deform(pose) -> (n, 3)``.
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

ENGINES = ("wire", "vector")


class Engine(Protocol):
    name: str
    rig: Rig
    channels: tuple[str, ...]

    def deform(self, values: np.ndarray) -> np.ndarray: ...


def make_engine(rig: Rig, name: str = "wire", **options) -> Engine:
    """Prepare the named engine for a rig (options: ``skull``, ``creases``).

    An engine runs on the rig with its unwelded seams merged (``mimetic.rig.weld.weld_rig``: UV
    seams, an unwelded patch), so what it computes from the topology sees one surface, and
    ``deform`` gives every copy of a merged vertex the same position: (n, 3) in the rig's own
    vertex order and count either way.
    """
    from mimetic.rig.weld import weld_rig

    welded, weld = weld_rig(rig)
    if name == "wire":
        from mimetic.engines.wire import WireEngine

        engine: Engine = WireEngine(welded, **options)
    elif name == "vector":
        from mimetic.engines.vector import VectorEngine

        engine = VectorEngine(welded, **options)
    else:
        from mimetic.errors import MimeticError

        raise MimeticError(f"unknown engine {name!r}; choose one of {', '.join(ENGINES)}")
    return engine if weld.n_merged == 0 else WeldedEngine(engine, rig, weld.index)


class WeldedEngine:
    """An engine prepared on a rig's welded copy, answering for the rig itself.

    ``deform(values)`` is the inner engine's (k, 3) result spread to the rig's n vertices through
    ``index`` (n,), the welded vertex of each rig vertex.
    """

    def __init__(self, inner: Engine, rig: Rig, index: np.ndarray) -> None:
        self.inner = inner
        self.name = inner.name
        self.rig = rig
        self.channels = inner.channels
        self.index = index

    def deform(self, values: np.ndarray) -> np.ndarray:
        return self.inner.deform(values)[self.index]
