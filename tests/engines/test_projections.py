"""The tissue engine's compiled local step (``engines.projections``) and the sparse factorisations
(``engines.cholesky``) against reference computations."""

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.linalg import polar

from mimetic.engines.cholesky import cholesky, nested_lu, node_dissection
from mimetic.engines.projections import prism_targets, spring_targets


def column_major(m: np.ndarray) -> np.ndarray:
    """(P, 3, 3) matrices as (P, 9) rows with entry ``3 j + i`` = ``F[i, j]``."""
    return np.ascontiguousarray(np.transpose(m, (0, 2, 1)).reshape(-1, 9))


def random_gradients(n: int, spread: float, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.eye(3) + spread * rng.normal(size=(n, 3, 3))


def test_prism_rotations_are_the_polar_factor_and_survive_inversion():
    """Shape term alone: the target is the nearest proper rotation, scipy's polar factor for an
    upright matrix (Newton or SVD: large strains too) and ``U diag(1, 1, -1) Vᵀ``-corrected for an
    inverted one; the energy is Σ ws/2 |F - R|²."""
    f = random_gradients(400, 0.4)
    f[:50, :, 2] *= -1  # inverted prisms
    ws = np.linspace(0.5, 2.0, len(f))
    target = np.empty((len(f), 9))
    energy = prism_targets(column_major(f), ws, np.zeros(len(f)), target)
    expected = np.empty_like(f)
    for k, m in enumerate(f):
        u, _, vt = np.linalg.svd(m)
        u[:, 2] *= np.sign(np.linalg.det(u @ vt))
        expected[k] = u @ vt
        if np.linalg.det(m) > 0:
            np.testing.assert_allclose(expected[k], polar(m)[0], atol=1e-10)
    np.testing.assert_allclose(target, column_major(expected), atol=1e-6)
    assert np.allclose(np.linalg.det(expected), 1.0)
    assert energy == pytest.approx(0.5 * np.sum(ws * np.sum((f - expected) ** 2, axis=(1, 2))), rel=1e-6)


def test_volume_targets_have_unit_determinant_and_mix_by_weight():
    """Three Newton steps reach determinant 1 for a few per cent of volume change; an inverted prism's
    target is on the upright side (det > 0), so the volume term pushes it back out."""
    f = random_gradients(300, 0.05, seed=1)
    f[:20, :, 0] *= -1
    ws, wv = np.full(len(f), 1.0), np.full(len(f), 3.0)
    rotations, mixed = np.empty((len(f), 9)), np.empty((len(f), 9))
    prism_targets(column_major(f), ws, np.zeros(len(f)), rotations)
    prism_targets(column_major(f), ws, wv, mixed)
    unit = (mixed - 0.25 * rotations) / 0.75  # target = R + wv/(ws+wv) (V - R)
    det = np.linalg.det(unit.reshape(-1, 3, 3).transpose(0, 2, 1))
    upright = np.linalg.det(f) > 0
    assert upright.sum() == len(f) - 20
    np.testing.assert_allclose(det[upright], 1.0, atol=1e-8)
    assert np.all(det[~upright] > 0)


def test_springs_go_to_their_rest_length_within_the_strain_limit():
    rng = np.random.default_rng(2)
    d = rng.normal(size=(500, 3))
    rest = np.abs(rng.normal(1.0, 0.3, 500))
    soft, stiff = np.full(500, 2.0), np.where(np.arange(500) % 2 == 0, 8.0, 0.0)
    target = np.empty_like(d)
    energy = spring_targets(d, rest, soft, stiff, 0.2, target)
    length = np.linalg.norm(d, axis=1)
    limited = np.clip(length, 0.8 * rest, 1.2 * rest)
    expected = (soft * rest + stiff * limited) / (soft + stiff)
    np.testing.assert_allclose(np.linalg.norm(target, axis=1), expected, rtol=1e-12)
    np.testing.assert_allclose(np.cross(target, d), 0.0, atol=1e-12)  # along the edge
    expected_energy = 0.5 * np.sum(soft * (length - rest) ** 2 + stiff * (length - limited) ** 2)
    assert energy == pytest.approx(expected_energy)


def test_the_factorisation_matches_scipy():
    rng = np.random.default_rng(3)
    a = sp.random(300, 200, density=0.03, random_state=4, format="csr")
    spd = (a.T @ a + sp.identity(200)).tocsr()
    b = rng.normal(size=(200, 4))
    np.testing.assert_allclose(spd @ cholesky(spd).solve(b), b, atol=1e-10)
    with pytest.raises(ValueError, match="not positive definite"):
        cholesky(sp.csr_matrix(np.array([[1.0, 2.0], [2.0, 1.0]])))


def grid_system(side: int) -> sp.csr_matrix:
    """An elasticity-like SPD matrix on a ``side``×``side`` grid of nodes, 3 rows per node."""
    path = sp.diags([-np.ones(side - 1), 2 * np.ones(side), -np.ones(side - 1)], [-1, 0, 1])
    laplacian = sp.kronsum(path, path)
    coupling = np.array([[2.0, 0.5, 0.1], [0.5, 1.5, 0.2], [0.1, 0.2, 1.0]])
    return (sp.kron(laplacian, coupling) + 1e-3 * sp.identity(3 * side * side)).tocsr()


def test_nested_dissection_lu_solves_and_keeps_each_nodes_rows_together():
    system = grid_system(30)
    b = np.random.default_rng(5).normal(size=(system.shape[0], 3))
    np.testing.assert_allclose(system @ nested_lu(system).solve(b), b, atol=1e-9)
    np.testing.assert_allclose(nested_lu(system).solve(b[:, 0]), nested_lu(system).solve(b)[:, 0], atol=1e-12)
    order = node_dissection(system, 3)
    assert np.array_equal(np.sort(order), np.arange(system.shape[0]))
    assert np.array_equal(order.reshape(-1, 3) % 3, np.tile(np.arange(3), (len(order) // 3, 1)))
    assert np.all(np.diff(order.reshape(-1, 3) // 3, axis=1) == 0)
    with pytest.raises(ValueError, match="nodes of 7 rows"):
        node_dissection(system, 7)
    with pytest.raises(ValueError, match="right-hand side has 5 rows"):
        nested_lu(system).solve(np.ones(5))


def test_nested_dissection_fills_less_than_the_grids_own_order():
    from scipy.sparse.linalg import splu

    system = grid_system(40)
    lu = nested_lu(system)._lu
    natural = splu(
        system.tocsc(), permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True}
    )
    assert lu.L.nnz < 0.6 * natural.L.nnz
