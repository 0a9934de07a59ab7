"""The compiled per-frame bounded solve against scipy's BVLS on the same problems."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from mimetic.capture.qp import box_qp_frames


def problem(rng: np.random.Generator, rows: int = 60, c: int = 12, f: int = 40):
    """A least-squares problem per frame with correlated columns, smooth targets, and its bounds."""
    D = rng.normal(size=(rows, c))
    D[:, 1:] += 0.7 * D[:, :-1]  # neighbouring columns alike, as overlapping muscles are
    truth = np.clip(np.cumsum(rng.normal(scale=0.15, size=(f, c)), axis=0), -0.3, 1.2)
    Y = truth @ D.T + rng.normal(scale=0.1, size=(f, rows))
    lower = np.where(np.arange(c) % 3 == 0, -0.5, 0.0)
    upper = np.where(np.arange(c) % 4 == 0, np.inf, 1.0)
    return D, Y, lower, upper


def reference(D: np.ndarray, y: np.ndarray, lower: np.ndarray, upper: np.ndarray) -> np.ndarray:
    return lsq_linear(D, y, bounds=(lower, upper), method="bvls", tol=1e-14).x


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_shared_normal_matrix_matches_bvls(seed):
    rng = np.random.default_rng(seed)
    D, Y, lower, upper = problem(rng)
    x, solved = box_qp_frames(D.T @ D, Y @ D, lower, upper)
    assert solved.all()
    expected = np.array([reference(D, y, lower, upper) for y in Y])
    np.testing.assert_allclose(x, expected, atol=1e-8)
    assert np.all(x >= lower - 1e-12) and np.all(x <= upper + 1e-12)
    assert ((x == lower) | (x == upper)).mean() > 0.1  # bounds are active: the test tests them


def test_per_frame_normal_matrices_match_bvls():
    """Each frame with its own rows weighted (missing markers have weight 0)."""
    rng = np.random.default_rng(5)
    D, Y, lower, upper = problem(rng, f=25)
    weights = (rng.random((25, len(D))) > 0.2).astype(float)
    H = np.einsum("fr,ri,rj->fij", weights, D, D)
    g = np.einsum("fr,fr,ri->fi", weights, Y, D)
    x, solved = box_qp_frames(H, g, lower, upper)
    assert solved.all()
    for t in range(25):
        keep = weights[t] > 0
        np.testing.assert_allclose(x[t], reference(D[keep], Y[t, keep], lower, upper), atol=1e-8)


def test_the_answer_does_not_depend_on_the_start():
    rng = np.random.default_rng(7)
    D, Y, lower, upper = problem(rng)
    H, g = D.T @ D, Y @ D
    x0, _ = box_qp_frames(H, g, lower, upper)
    start = np.where(rng.random(g.shape) < 0.5, lower, np.minimum(upper, 2.0))
    x1, solved = box_qp_frames(H, g, lower, upper, start)
    assert solved.all()
    np.testing.assert_allclose(x1, x0, atol=1e-9)


def test_an_interior_optimum_is_the_unconstrained_solution():
    rng = np.random.default_rng(3)
    H = np.diag(rng.uniform(1, 2, 6))
    x_star = rng.uniform(0.2, 0.8, (10, 6))
    x, solved = box_qp_frames(H, x_star @ H, np.zeros(6), np.ones(6))
    assert solved.all()
    np.testing.assert_allclose(x, x_star, atol=1e-12)


def test_a_variable_freed_at_its_bound_stays_there_when_the_step_is_blocked_at_once():
    """Found by a random search: the variable freed at its lower bound (wanting to rise) while another
    variable blocked the step at zero length was sent to its upper bound, here infinity, and the
    frame came back 'solved' with inf in it."""
    H = np.array([
        [5.497653173027783, -2.030457075134373, -1.2103281004190198, 3.0639365634951012, 0.03985136823584233],
        [-2.030457075134373, 2.992529973853138, 4.006640769101604, -2.8755810577903276, -1.8653553486826564],
        [-1.2103281004190198, 4.006640769101604, 9.28032631598238, -4.210999925295763, -2.957341716207161],
        [3.0639365634951012, -2.8755810577903276, -4.210999925295763, 3.3712826562395097, 1.8890025503706822],
        [0.03985136823584233, -1.8653553486826564, -2.957341716207161, 1.8890025503706822, 6.57521236472973],
    ])  # fmt: skip
    g = np.array([[1.7826881874513507, -0.9400366509852818, 5.105079502936946, -2.663631305229626,
                   -3.7143266765691134]])  # fmt: skip
    lower = np.array([0.0, -1.0, -1.0, -1.0, 0.0])
    upper = np.array([np.inf, np.inf, np.inf, np.inf, 1.0])
    x, solved = box_qp_frames(H, g, lower, upper, np.zeros((1, 5)))
    assert solved.all() and np.isfinite(x).all()
    L = np.linalg.cholesky(H).T  # H = Lᵀ L: ½xᵀHx − gᵀx = ½‖L x − L⁻ᵀ g‖² + const
    np.testing.assert_allclose(x[0], reference(L, np.linalg.solve(L.T, g[0]), lower, upper), atol=1e-8)
