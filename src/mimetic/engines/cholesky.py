"""Sparse factorisations of the physically based engines' symmetric positive definite systems.

Two, for two uses (measured on 2 cores, ``benchmarks/bench_physics.py``):

* ``cholesky``: CHOLMOD's simplicial factor through ``cholespy``. Its solves are the fastest: on the
  tissue engine's 10k-node system one 3-column solve takes 1.3 ms against 4.7 ms for scipy's
  ``splu``, and the tissue engine solves every iteration.
* ``nested_lu``: scipy's SuperLU (supernodal) in symmetric mode, without pivoting, on the matrix
  permuted by a nested dissection of its *node* graph (METIS through ``pymetis``). The fem system of
  the default head (60,852 unknowns) factorises in about 1.9 s against 4.2 s for CHOLMOD's
  simplicial factor, solving 40 columns costs about the same, and the fem engine factorises once.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pymetis
import scipy.sparse as sp
from cholespy import CholeskySolverD, MatrixType
from scipy.sparse.linalg import SuperLU, splu


@dataclass(frozen=True, eq=False)
class Cholesky:
    """The factor of a symmetric positive definite ``n``×``n`` matrix: ``solve(b)`` for b (n,) or (n, k)."""

    n: int
    _solver: CholeskySolverD

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = _rhs(b, self.n)
        x = np.empty_like(b)
        self._solver.solve(b, x)
        return x


def cholesky(matrix: sp.spmatrix) -> Cholesky:
    """Factorise ``matrix`` (n, n), symmetric positive definite (both triangles stored)."""
    coo = sp.coo_matrix(matrix)
    solver = CholeskySolverD(
        coo.shape[0],
        coo.row.astype(np.int32),
        coo.col.astype(np.int32),
        coo.data.astype(np.float64),
        MatrixType.COO,
    )
    return Cholesky(coo.shape[0], solver)


@dataclass(frozen=True, eq=False)
class NestedLU:
    """The LU factor of a symmetric positive definite ``n``×``n`` matrix permuted by ``order`` (n,):
    ``solve(b)`` for b (n,) or (n, k)."""

    n: int
    order: np.ndarray
    _lu: SuperLU

    def solve(self, b: np.ndarray) -> np.ndarray:
        b = _rhs(b, self.n)
        x = np.empty_like(b)
        x[self.order] = self._lu.solve(b[self.order])
        return x


def node_dissection(matrix: sp.spmatrix, block: int) -> np.ndarray:
    """A fill-reducing order (n,) of the rows of ``matrix`` (n, n), whose rows come in consecutive
    groups of ``block`` per node (``block * node + axis``): METIS's nested dissection of the graph of
    nodes that share a non-zero, each node's rows kept together."""
    n = matrix.shape[0]
    if n % block:
        raise ValueError(f"a {n}×{n} matrix does not split into nodes of {block} rows")
    coo = sp.coo_matrix(matrix)
    nodes = n // block
    keep = coo.row // block != coo.col // block
    graph = sp.csr_matrix(
        (np.ones(int(keep.sum()), dtype=np.int8), (coo.row[keep] // block, coo.col[keep] // block)),
        shape=(nodes, nodes),
    )
    graph.sum_duplicates()
    if graph.nnz == 0:
        return np.arange(n)
    order, _ = pymetis.nested_dissection(adjacency=pymetis.CSRAdjacency(graph.indptr, graph.indices))
    return (block * np.asarray(order, dtype=np.int64)[:, None] + np.arange(block)).ravel()


def nested_lu(matrix: sp.spmatrix, block: int = 3) -> NestedLU:
    """Factorise ``matrix`` (n, n), symmetric positive definite (not checked), whose rows come in groups
    of ``block`` per node, in the order of ``node_dissection``."""
    order = node_dissection(matrix, block)
    permuted = sp.csr_matrix(matrix)[order][:, order].tocsc()
    lu = splu(permuted, permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    return NestedLU(matrix.shape[0], order, lu)


def _rhs(b: np.ndarray, n: int) -> np.ndarray:
    b = np.ascontiguousarray(b, dtype=np.float64)
    if b.shape[0] != n:
        raise ValueError(f"right-hand side has {b.shape[0]} rows, the matrix {n}")
    return b
