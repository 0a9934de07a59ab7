"""Fitting activations to target vertices: known answers on a tiny basis, recovery on a baked small rig."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
from scipy.optimize import lsq_linear

from mimetic.capture import SolveResult, prepare_solver, solve_activations
from mimetic.capture.solve import box_qp
from mimetic.engines import make_engine
from mimetic.engines.bake import bake
from mimetic.engines.basis import Basis, Corrective, evaluate_basis
from mimetic.errors import ActivationError, MimeticWarning
from mimetic.rig.model import Channel
from mimetic.testing import small_rig

RECOVERY_TOL = 1e-8  # rig units (the small head is ~23 cm tall): float64 normal equations, unregularized


@cache
def baked():
    """The small rig and its wire-engine basis with 6 correctives (built once; ~3 s)."""
    rig = small_rig()
    return rig, bake(make_engine(rig, "wire"), correctives=6, samples=2).basis


def tiny_basis(correctives: bool = False) -> Basis:
    """Two vertices, three channels: "a" moves vertex 0 along x, "b" vertex 1 along y, "c" both along z
    (one unit each). With ``correctives``, a·b adds (0, 0, 1) to vertex 0."""
    deltas = np.zeros((3, 2, 3))
    deltas[0, 0, 0] = 1.0
    deltas[1, 1, 1] = 1.0
    deltas[2, :, 2] = 1.0
    extra = (Corrective(("a", "b"), [[0.0, 0.0, 1.0], [0.0, 0.0, 0.0]]),) if correctives else ()
    return Basis(("a", "b", "c"), np.zeros((2, 3)), deltas, extra)


TINY_CHANNELS = (Channel("a", 0.0, 1.0), Channel("b", -0.5, 1.0), Channel("c", 0.0, 2.0))


def random_pose(rig, rng: np.random.Generator, density: float = 0.4) -> np.ndarray:
    """(c,) activations inside the channel ranges, the head rotation (which a basis cannot show) at 0."""
    lo = np.array([c.minimum for c in rig.channels])
    hi = np.array([c.maximum for c in rig.channels])
    a = rng.uniform(0.1 * lo, 0.9 * hi) * (rng.random(len(lo)) < density)
    a[[rig.channel_index(n) for n in ("head_yaw", "head_pitch", "head_roll")]] = 0.0
    return a


def check_result(result: SolveResult, frames: int, channels: int) -> None:
    assert isinstance(result, SolveResult)
    assert result.activations.shape == (frames, channels) and result.activations.dtype == np.float64
    for name in ("relative_residual", "rms_error", "max_error"):
        array = getattr(result, name)
        assert array.shape == (frames,) and array.dtype == np.float64, name
    assert result.iterations.shape == (frames,) and result.iterations.dtype == np.int64


# --------------------------------------------------------------------------- known answers


def test_solve_activations_tiny_basis_outside_span_gives_known_residual():
    basis = tiny_basis()
    target = np.array([[0.5, 0.0, 1.0], [0.0, 0.0, -1.0]])  # z: +1 and -1, which "c" cannot split
    result = solve_activations(basis, target, channels=TINY_CHANNELS, regularization=0.0)
    check_result(result, 1, 3)
    np.testing.assert_allclose(result.activations[0], [0.5, 0.0, 0.0], atol=1e-9)
    np.testing.assert_allclose(result.relative_residual, [np.sqrt(2.0) / np.sqrt(2.25)], rtol=1e-9)
    np.testing.assert_allclose(result.rms_error, [1.0], rtol=1e-9)  # both vertices off by 1
    np.testing.assert_allclose(result.max_error, [1.0], rtol=1e-9)
    assert result.success and result.held == ()


def test_solve_activations_respects_bounds_and_reports_the_clipped_residual():
    basis = tiny_basis()
    target = np.array([[2.0, 0.0, 0.0], [0.0, -2.0, 0.0]])  # a = 2 > 1, b = -2 < -0.5
    result = solve_activations(basis, target, channels=TINY_CHANNELS, regularization=0.0)
    np.testing.assert_allclose(result.activations[0], [1.0, -0.5, 0.0], atol=1e-12)
    np.testing.assert_allclose(result.max_error, [1.5], rtol=1e-9)  # vertex 1: -2 against -0.5
    np.testing.assert_allclose(result.rms_error, [np.sqrt((1.0 + 2.25) / 2)], rtol=1e-9)
    unbounded = solve_activations(basis, target, regularization=0.0)  # channels=None: no bounds
    np.testing.assert_allclose(unbounded.activations[0], [2.0, -2.0, 0.0], atol=1e-9)


def test_solve_activations_regularization_shrinks_by_the_known_factor():
    # one channel alone: min (a - 1)² ‖d‖² + λ ‖d‖² a²  →  a = 1 / (1 + λ)
    basis = tiny_basis()
    target = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]])
    result = solve_activations(basis, target, active=["a"], regularization=0.25)
    np.testing.assert_allclose(result.activations[0], [0.8, 0.0, 0.0], rtol=1e-12)
    assert result.held == ("b", "c")


def test_solve_activations_recovers_a_corrective_product_by_gauss_newton():
    basis = tiny_basis(correctives=True)
    truth = np.array([[0.6, 0.7, 0.2], [0.9, -0.4, 1.5], [0.0, 0.0, 0.0]])
    targets = evaluate_basis(basis, truth)  # (3, 2, 3)
    result = solve_activations(basis, targets, channels=TINY_CHANNELS, regularization=0.0, tolerance=0.0)
    check_result(result, 3, 3)
    np.testing.assert_allclose(result.activations, truth, atol=1e-7)
    assert result.max_error.max() < 1e-7 and result.success
    assert result.iterations[0] > 1  # the product needed Gauss-Newton steps beyond the linear solve
    assert np.isnan(result.relative_residual[2])  # the target is the neutral: no relative residual


def test_solve_activations_neutral_target_gives_zero_activations_exactly():
    basis = tiny_basis(correctives=True)
    result = solve_activations(basis, np.zeros((2, 3)), channels=TINY_CHANNELS)
    np.testing.assert_array_equal(result.activations, np.zeros((1, 3)))
    assert result.rms_error[0] == 0.0 and result.max_error[0] == 0.0
    assert np.isnan(result.relative_residual[0])
    assert not result.activations.flags.writeable  # results are read-only


def test_solve_activations_single_frame_equals_the_batch_row():
    basis = tiny_basis(correctives=True)
    targets = evaluate_basis(basis, np.array([[0.3, 0.2, 0.1], [0.8, 0.9, 0.0]]))
    batch = solve_activations(basis, targets, channels=TINY_CHANNELS)
    one = solve_activations(basis, targets[1], channels=TINY_CHANNELS)
    np.testing.assert_array_equal(one.activations[0], batch.activations[1])


# --------------------------------------------------------------------------- the bounded kernel


def test_box_qp_matches_scipy_bvls_on_random_problems():
    rng = np.random.default_rng(7)
    for _ in range(200):
        m = int(rng.integers(1, 30))
        A = rng.normal(size=(m + 5, m)) * rng.uniform(0.1, 5.0, m)
        H = A.T @ A + 1e-6 * np.eye(m)
        g = A.T @ (3.0 * rng.normal(size=m + 5))
        lower = np.where(rng.random(m) < 0.5, -rng.uniform(0, 1, m), 0.0)
        upper = np.where(rng.random(m) < 0.1, np.inf, rng.uniform(0.1, 1.0, m))
        x, solved = box_qp(H, g, lower, upper, np.zeros(m))
        L = np.linalg.cholesky(H)
        reference = lsq_linear(L.T, np.linalg.solve(L, g), bounds=(lower, upper), method="bvls", tol=1e-14).x
        assert solved and np.all(x >= lower) and np.all(x <= upper)

        def objective(v, H=H, g=g):
            return 0.5 * v @ H @ v - g @ v

        assert objective(x) <= objective(reference) + 1e-9 * (1 + abs(objective(reference)))


# --------------------------------------------------------------------------- a baked rig


def test_solve_activations_recovers_generated_poses_on_a_baked_rig():
    rig, basis = baked()
    rng = np.random.default_rng(3)
    truth = np.stack([random_pose(rig, rng) for _ in range(4)])  # (4, c), inside the ranges
    targets = evaluate_basis(basis, truth)  # (4, n, 3), correctives included
    before = targets.copy()
    result = solve_activations(basis, targets, channels=rig, regularization=0.0, tolerance=0.0, iterations=30)
    check_result(result, 4, basis.n_channels)
    np.testing.assert_array_equal(targets, before)  # the input is untouched
    assert result.success, result.message
    assert result.max_error.max() < RECOVERY_TOL
    assert result.relative_residual.max() < 1e-8  # measured 1.6e-9 with 64 channels
    assert set(result.held) == {"head_yaw", "head_pitch", "head_roll"}  # a basis cannot rotate the head
    fitted = evaluate_basis(basis, result.activations)
    np.testing.assert_allclose(fitted, targets, atol=RECOVERY_TOL)
    # the channels that move the skin are determined: recovered themselves
    np.testing.assert_allclose(result.activations, truth, atol=1e-5)


def test_solve_activations_default_regularization_stays_close_on_a_baked_rig():
    rig, basis = baked()
    truth = random_pose(rig, np.random.default_rng(4))
    result = solve_activations(basis, evaluate_basis(basis, truth), channels=rig)
    assert result.relative_residual[0] < 0.02  # λ = 1e-3 per channel costs about 0.1 % per channel
    assert np.abs(result.activations[0] - truth).max() < 0.05


def test_solve_activations_respects_the_rig_ranges_on_overdriven_targets():
    rig, basis = baked()
    lo = np.array([c.minimum for c in rig.channels])
    hi = np.array([c.maximum for c in rig.channels])
    over = np.zeros(basis.n_channels)
    for name in ("zygomatic_major_L", "zygomatic_major_R", "frontalis_inner_L"):
        over[rig.channel_index(name)] = 1.6  # beyond the maximum 1
    result = solve_activations(basis, evaluate_basis(basis, over), channels=rig, regularization=0.0)
    a = result.activations[0]
    assert np.all(a >= lo - 1e-12) and np.all(a <= hi + 1e-12)
    assert a[rig.channel_index("zygomatic_major_L")] == pytest.approx(1.0, abs=1e-3)
    assert result.max_error[0] > 0  # 0.6 of each muscle is out of reach


def test_solve_activations_fits_only_the_chosen_vertices():
    rig, basis = baked()
    truth = random_pose(rig, np.random.default_rng(5))
    targets = evaluate_basis(basis, truth).copy()
    targets[-10:] = np.nan  # untracked vertices outside the subset
    targets[0] += 5.0  # an outlier outside the subset does not matter either
    subset = np.arange(1, basis.n_vertices - 10)
    result = solve_activations(basis, targets, vertices=subset, channels=rig, regularization=0.0)
    np.testing.assert_array_equal(result.vertices, subset)
    assert result.max_error[0] < 1e-6


def test_prepare_solver_is_reusable_across_clips():
    rig, basis = baked()
    solver = prepare_solver(basis, channels=rig, regularization=0.0)
    rng = np.random.default_rng(6)
    for _ in range(2):
        truth = random_pose(rig, rng)
        done: list[tuple[int, int]] = []
        result = solver.solve(
            evaluate_basis(basis, truth), progress=lambda k, n, done=done: done.append((k, n))
        )
        assert done == [(1, 1)] and result.max_error[0] < 1e-6


# --------------------------------------------------------------------------- bad input


def test_solve_activations_rejects_nan_targets_naming_frame_and_vertex():
    basis = tiny_basis()
    targets = np.zeros((3, 2, 3))
    targets[2, 1, 0] = np.nan
    with pytest.raises(ActivationError, match=r"frame 2, vertex 1"):
        solve_activations(basis, targets)


@pytest.mark.parametrize(
    "shape",
    [(2,), (3, 3), (2, 2), (4, 2, 3, 1), (0, 2, 3)],
)
def test_solve_activations_rejects_wrong_target_shapes(shape):
    with pytest.raises(ActivationError, match=r"targets"):
        solve_activations(tiny_basis(), np.zeros(shape))


def test_solve_activations_rejects_bad_arguments():
    basis = tiny_basis()
    target = np.zeros((2, 3))
    with pytest.raises(ActivationError, match="out of range"):
        solve_activations(basis, target, vertices=[0, 2])
    with pytest.raises(ActivationError, match="repeated"):
        solve_activations(basis, target, vertices=[1, 1])
    with pytest.raises(ActivationError, match=r"shape \(2,\)"):
        solve_activations(basis, target, vertices=np.ones(3, bool))
    with pytest.raises(ActivationError, match="no vertex"):
        solve_activations(basis, target, vertices=np.zeros(2, bool))
    with pytest.raises(ActivationError, match="did you mean a"):
        solve_activations(basis, target, active=["aa"])
    with pytest.raises(ActivationError, match="no range for basis channel"):
        solve_activations(basis, target, channels=TINY_CHANNELS[:2])
    with pytest.raises(ActivationError, match="leaves out 0"):
        solve_activations(basis, target, channels=(Channel("a", 0.2, 1.0, default=0.5), *TINY_CHANNELS[1:]))
    with pytest.raises(ActivationError, match="regularization"):
        solve_activations(basis, target, regularization=-1.0)


def test_solve_activations_warns_when_a_frame_does_not_converge():
    basis = tiny_basis(correctives=True)
    target = evaluate_basis(basis, np.array([0.9, 0.8, 0.3]))
    with pytest.warns(MimeticWarning, match="Gauss-Newton"):
        result = solve_activations(basis, target, regularization=0.0, iterations=1, tolerance=0.0)
    assert not result.success and "iterations" in result.message
