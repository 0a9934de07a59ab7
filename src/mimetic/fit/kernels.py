"""Compiled loops (numba) for ``fit.register``: the sparse products of its conjugate gradients.

Profiling ``rig_head`` on ICT's head, the registration's 13 solves (39 conjugate-gradient runs, one
per coordinate, some 170 steps each) were a fifth of the rig, two thirds of it in scipy's CSR
product. Here one pass over the matrix serves the three coordinates, each summed as scipy's
``csr_matvec`` sums it (row by row, entry by entry in stored order, from 0), so the products are the
same bits; unsigned indices spare the loop numba's negative-index test.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, error_model="numpy")
def csr_matvec3(indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``A @ x[d]`` for d = 0, 1, 2: ``A`` (n, n) in CSR (``indptr`` (n + 1,) and ``indices`` (nnz,)
    uint64, ``data`` (nnz,) float64), ``x`` (3, n) float64; returns (3, n)."""
    n = len(indptr) - 1
    y = np.empty((3, n))
    for i in range(n):
        s0 = 0.0
        s1 = 0.0
        s2 = 0.0
        for e in range(indptr[i], indptr[i + 1]):
            a = data[e]
            j = indices[e]
            s0 += a * x[0, j]
            s1 += a * x[1, j]
            s2 += a * x[2, j]
        y[0, i] = s0
        y[1, i] = s1
        y[2, i] = s2
    return y
