"""Compiled loops (numba) for ``fit.register``: its conjugate gradients and their sparse products.

Profiling ``rig_head`` on ICT's head, the registration's 13 solves (39 conjugate-gradient runs, one
per coordinate, some 170 steps each) were a fifth of the rig, two thirds of it in scipy's CSR
product. Here one pass over the matrix serves the three coordinates, each summed as scipy's
``csr_matvec`` sums it (row by row, entry by entry in stored order, from 0), so the products are the
same bits; unsigned indices spare the loop numba's negative-index test. The iteration around them
(``cg3``) is compiled too: in Python its vector updates cost a third as much again.
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


@numba.njit(cache=True, error_model="numpy")
def cg3(
    indptr: np.ndarray,
    indices: np.ndarray,
    data: np.ndarray,
    inverse_diagonal: np.ndarray,
    b: np.ndarray,
    x: np.ndarray,
    atol: np.ndarray,
    maxiter: int,
) -> bool:
    """Jacobi-preconditioned conjugate gradients for ``A x[d] = b[d]``, d = 0, 1, 2, side by side:
    ``A`` (n, n) SPD in CSR (as ``csr_matvec3`` takes it), ``inverse_diagonal`` (n,), ``b`` (3, n),
    ``x`` (3, n) the start, overwritten with the solution; a coordinate stops once its residual's norm
    is below ``atol[d]`` (0: ``x[d] = b[d]``, as scipy returns b = 0). Each coordinate takes the steps
    of ``scipy.sparse.linalg.cg`` with ``M = diags(inverse_diagonal)`` with the same arithmetic (BLAS
    dot products, element-wise updates), so the same bits. False when ``maxiter`` steps did not do."""
    n = len(inverse_diagonal)
    ax = csr_matvec3(indptr, indices, data, x)
    r = np.zeros((3, n))  # the residuals (0 in a column that is done from the start)
    live = np.zeros(3, dtype=np.bool_)
    for d in range(3):
        if atol[d] == 0.0:
            x[d] = b[d]
        else:
            if np.any(x[d] != 0.0):
                r[d] = b[d] - ax[d]
            else:
                r[d] = b[d]
            live[d] = True
    p = np.zeros((3, n))
    z = np.empty((3, n))
    rho_prev = np.ones(3)
    for iteration in range(maxiter):
        for d in range(3):
            if live[d] and np.sqrt(np.dot(r[d], r[d])) < atol[d]:
                live[d] = False
        if not live.any():
            return True
        for d in range(3):
            for i in range(n):
                z[d, i] = inverse_diagonal[i] * r[d, i]
        for d in range(3):
            if live[d]:
                rho = np.dot(r[d], z[d])
                if iteration > 0:
                    scale = rho / rho_prev[d]
                    for i in range(n):
                        p[d, i] *= scale
                        p[d, i] += z[d, i]
                else:
                    p[d] = z[d]
                rho_prev[d] = rho
        q = csr_matvec3(indptr, indices, data, p)
        for d in range(3):
            if live[d]:
                alpha = rho_prev[d] / np.dot(p[d], q[d])
                for i in range(n):
                    x[d, i] += alpha * p[d, i]
                    r[d, i] -= alpha * q[d, i]
    return False
