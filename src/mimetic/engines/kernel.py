"""The compiled single-frame kernel of ``CompactBasis`` (numba; imported by ``basis`` on first use).

``evaluate_runs`` writes ``out = neutral + Σ_j α_j D_j``, walking only the stored runs of the
terms whose α_j is non-zero: one call per frame, whatever the number of runs. float32 runs are
read as they are; float16 runs are stored as their bits (int16) and unpacked run by run into a
small scratch with two integer operations (see ``basis._unpack_f16``), numba having no float16.

The machine code is cached on disk beside this module (``cache=True``): the first process on a
machine compiles it for ~2 s, later ones load it in ~0.1 s.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import types
from numba.extending import overload

from mimetic.engines.basis import _F16_UNPACK_MASK, ALPHA_LIMIT

OK, BAD_SHAPE, NOT_FINITE, TOO_LARGE = 0, 1, 2, 3
"""What ``evaluate_runs`` returns: done; an input of the wrong size; an activation not finite; an
activation times its term's scale not representable in float32. On anything but OK, ``out`` is
untouched."""


def _add_run(y, x, alpha, bits, values):  # pragma: no cover - replaced by its overload in compiled code
    """y += alpha · x, for x float32 values or float16 bits (int16); see ``_add_run_overload``."""
    raise NotImplementedError


@overload(_add_run, inline="always")
def _add_run_overload(y, x, alpha, bits, values):
    if x.dtype == types.float32:

        def add(y, x, alpha, bits, values):
            for i in range(len(y)):  # views indexed from 0: LLVM vectorises the loop
                y[i] += alpha * x[i]

        return add

    def add_f16(y, x, alpha, bits, values):  # values is a float32 view of bits
        m = len(y)
        for i in range(m):  # float16 bits into float32 ones: the value · 2^-112 (alpha holds 2^112)
            bits[i] = (np.int32(x[i]) << 13) & _F16_UNPACK_MASK
        for i in range(m):
            y[i] += alpha * values[i]

    return add_f16


def _evaluate_runs(out, a, neutral, scale, pairs, index, runs, data, longest):
    """out = neutral + Σ_j α_j D_j over the stored runs of the terms with α_j ≠ 0.

    Parameters
    ----------
    out : (n, 3) float32
        Written.
    a : (c,) float64
        Channel activations. Term j's activation is t_j = a_j for j < c and
        t_(c+k) = a_(pairs[k, 0]) · a_(pairs[k, 1]); its multiplier α_j = float32(t_j · scale_j).
    neutral : (n, 3) float32
    scale : (T,) float64
        1 for float32 storage; for float16, the term's storage scale times 2^112.
    pairs : (T - c, 2) int32
    index : (T + 1,) int32
        Term j's runs are ``runs[index[j] : index[j + 1]]``.
    runs : (R, 3) int32
        (first element in ``out`` flattened, length, first element in ``data``) of each run.
    data : (Σ length,) float32, or int16 holding float16 bits
    longest : int
        The longest run (sizes the float16 scratch).

    Returns
    -------
    status : int
        OK, BAD_SHAPE, NOT_FINITE or TOO_LARGE.
    """
    c, terms = len(a), len(index) - 1
    if c + len(pairs) != terms or len(scale) != terms or out.shape != neutral.shape:
        return BAD_SHAPE
    for i in range(c):
        if not math.isfinite(a[i]):
            return NOT_FINITE
    alphas = np.empty(terms, np.float32)
    for j in range(terms):
        t = a[j] if j < c else a[pairs[j - c, 0]] * a[pairs[j - c, 1]]
        alpha = t * scale[j]
        if not abs(alpha) < ALPHA_LIMIT:
            return TOO_LARGE
        alphas[j] = np.float32(alpha)  # as BLAS rounds its alpha
    bits = np.empty(longest if data.itemsize == 2 else 0, np.int32)
    values = bits.view(np.float32)
    out, neutral = out.reshape(-1), neutral.reshape(-1)  # (3n,) views
    for i in range(len(out)):  # faster than out[:] = neutral in numba 0.68
        out[i] = neutral[i]
    for j in range(terms):
        alpha = alphas[j]
        if alpha == 0.0:  # skipped: exact, its products are zero
            continue
        for r in range(index[j], index[j + 1]):
            start, m, offset = runs[r, 0], runs[r, 1], runs[r, 2]
            _add_run(out[start : start + m], data[offset : offset + m], alpha, bits, values)
    return OK


def _signature(data: types.Type) -> types.Type:
    def array(dtype: types.Type, ndim: int = 1, readonly: bool = True) -> types.Array:
        return types.Array(dtype, ndim, "C", readonly=readonly)

    return types.int64(
        array(types.float32, 2, readonly=False),
        array(types.float64),
        array(types.float32, 2),
        array(types.float64),
        array(types.int32, 2),
        array(types.int32),
        array(types.int32, 2),
        array(data),
        types.int64,
    )


evaluate_runs = numba.njit(
    [_signature(types.float32), _signature(types.int16)], cache=True, nogil=True, fastmath={"contract"}
)(_evaluate_runs)
"""``_evaluate_runs`` compiled for float32 and float16-bits data. Inputs are declared read-only,
which takes writeable arrays too; a type matching neither signature raises TypeError. Only FMA
contraction is allowed (``fastmath={"contract"}``): the full set would assume finite values and
drop the check of the activations."""
