"""Results of pure functions of a mesh's arrays, kept while those arrays live.

Rigging one head asks for the same mesh's edges, boundary, pieces and skin dozens of times, from
functions far apart (the fit, the transfer, the lids, the anatomy) that each take plain
``(vertices, faces)`` arrays. ``per_arrays`` remembers such a function's result for the very array
objects it was given, when they cannot change: read-only arrays whose memory no writeable array
shares (a ``Mesh``'s arrays are). The entry goes when any of those arrays is garbage collected, so
nothing outlives the mesh it describes, and writeable arrays (which could change under the cache)
are never remembered. Results are handed out read-only: a caller that wants to change one copies it.
"""

from __future__ import annotations

import functools
import weakref
from collections.abc import Callable
from typing import TypeVar

import numpy as np

F = TypeVar("F", bound=Callable)

_results: dict[tuple, object] = {}


def frozen(array: object) -> bool:
    """True when ``array`` is an ndarray that cannot change: it, and every array it is a view of,
    is read-only (and the memory at the bottom is an array's own, not a writeable buffer's)."""
    if not isinstance(array, np.ndarray):
        return False
    while isinstance(array, np.ndarray):
        if array.flags.writeable:
            return False
        array = array.base
    return array is None or isinstance(array, bytes)


def _readonly(value: object) -> object:
    if isinstance(value, np.ndarray):
        value.setflags(write=False)
    elif isinstance(value, tuple):
        for item in value:
            _readonly(item)
    return value


def per_arrays(arrays: int, *, copies: bool = False) -> Callable[[F], F]:
    """Remember ``function(*args, **kwargs)`` per identity of its first ``arrays`` arguments (when
    all are ``frozen``) and the values of the others (when all are hashable). Returned arrays (alone
    or in a tuple) are read-only, or with ``copies`` a fresh copy of a remembered array (for a
    function whose callers may change what it returns)."""

    def wrap(function: F) -> F:
        @functools.wraps(function)
        def remembered(*args, **kwargs):
            key_arrays = args[:arrays]
            if len(key_arrays) < arrays or not all(frozen(a) for a in key_arrays):
                return function(*args, **kwargs)
            key = (function, *map(id, key_arrays), *args[arrays:], *sorted(kwargs.items()))
            try:
                hash(key)
            except TypeError:  # an argument that is not a value (an array passed as an option)
                return function(*args, **kwargs)
            hit = _results.get(key)
            if hit is not None and all(ref() is a for ref, a in zip(hit[0], key_arrays, strict=True)):
                value = hit[1]
            else:
                value = _readonly(function(*args, **kwargs))
                forget = functools.partial(_forget, key)
                _results[key] = ([weakref.ref(a, forget) for a in key_arrays], value)
            return value.copy() if copies else value

        return remembered  # type: ignore[return-value]

    return wrap


def _forget(key: tuple, _ref: weakref.ref) -> None:
    _results.pop(key, None)
