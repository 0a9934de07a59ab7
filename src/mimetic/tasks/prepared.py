"""A rig loaded once per process, with the engines and bases tasks make for it, each made once.

Tasks load rigs through ``prepared_rig(path)``: within one process (a batch worker running many
items, the web viewer exporting what it shows) the rig file is read once while it is unchanged (its
size and modification time key it), and each engine and each bake of it is made once. A command run
once pays for what it uses, as before.
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from mimetic.rig.model import Rig

if TYPE_CHECKING:
    from mimetic.capture.markers import MarkerSet
    from mimetic.engines import Basis, Engine

CAPTURE_BAKE = {"correctives": 0, "samples": 2}
"""How a capture solve bakes its rig: linear (the solve is linear least squares), checked on 2 poses."""

PHYSICAL = ("fem", "tissue")
"""The engines that take a ``proxy`` option (the others work on the rig's vertices directly)."""
RIGS_KEPT = 2
"""Rig files kept prepared per process (a batch worker alternates between few rigs)."""


class Prepared:
    """A rig and what tasks made for it: engines, bases, morph targets, marker sets (thread-safe)."""

    def __init__(self, rig: Rig) -> None:
        self.rig = rig
        self._made: dict[tuple, object] = {}
        self._lock = threading.RLock()

    def _once(self, key: tuple, make: Callable[[], object]):
        with self._lock:
            if key not in self._made:
                self._made[key] = make()
            return self._made[key]

    def engine(
        self, name: str, progress: Callable[[int, int], None] | None = None, *, proxy: str | int = "auto"
    ) -> Engine:
        """The engine ``name`` of this rig (``make_engine``); ``progress(done, total)`` while it is made;
        ``proxy`` the physical engines' (fem, tissue: ``engines.volume.proxy_size``)."""
        from mimetic.engines import make_engine

        if name not in PHYSICAL:
            return self._once(("engine", name), lambda: make_engine(self.rig, name, progress=progress))
        return self._once(
            ("engine", name, proxy), lambda: make_engine(self.rig, name, progress=progress, proxy=proxy)
        )

    def basis(
        self,
        name: str,
        progress: Callable[[int, int], None] | None = None,
        *,
        correctives: int | None = None,
        samples: int | None = None,
    ) -> Basis:
        """The engine ``name`` baked (``engines.bake.bake`` with these settings), once per setting."""
        from mimetic.engines.bake import bake

        def make() -> Basis:
            return bake(self.engine(name), correctives=correctives, samples=samples, progress=progress).basis

        return self._once(("basis", name, correctives, samples), make)

    def morph_targets(
        self, name: str, progress: Callable[[int, int], None] | None = None
    ) -> dict[str, np.ndarray]:
        """One morph target per muscle channel (``export.gltf.morph_targets``), from ``basis(name)``."""
        from mimetic.export.gltf import morph_targets_from_basis

        return self._once(
            ("targets", name), lambda: morph_targets_from_basis(self.basis(name, progress), self.rig)
        )

    def markers(self, layout: str) -> MarkerSet:
        """The marker layout ``layout`` (a built-in name or a marker file) placed on this rig."""
        from mimetic.capture.markers import marker_set

        return self._once(("markers", layout), lambda: marker_set(self.rig, layout))


_KEPT: dict[tuple[str, int, int], Prepared] = {}
_KEPT_LOCK = threading.Lock()


def prepared_rig(path: str | os.PathLike[str]) -> Prepared:
    """The rig file ``path`` loaded (``load_rig``) and kept for this process while it is unchanged
    (the last ``RIGS_KEPT`` files)."""
    from mimetic.rig.format import load_rig

    try:
        stat = Path(path).stat()
    except OSError:  # load_rig says what is wrong with the file, in its words
        return Prepared(load_rig(path))
    key = (str(Path(path).resolve()), stat.st_size, stat.st_mtime_ns)
    with _KEPT_LOCK:
        found = _KEPT.pop(key, None)
    found = found or Prepared(load_rig(path))
    with _KEPT_LOCK:
        _KEPT[key] = found  # the most recent last
        while len(_KEPT) > RIGS_KEPT:
            _KEPT.pop(next(iter(_KEPT)))
    return found
