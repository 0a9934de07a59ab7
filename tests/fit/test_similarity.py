"""Tests for mimetic.fit.similarity (Umeyama) and mimetic.fit.conform (HeadParams from landmarks)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mimetic.errors import LandmarkError
from mimetic.fit.conform import fit_conformation, landmark_model
from mimetic.fit.similarity import Similarity, axis_rotations, fit_similarity, nearest_axis_rotation
from mimetic.head.model import make_head
from mimetic.head.params import PARAM_RANGES, HeadParams


def _random_similarity(seed: int) -> Similarity:
    rng = np.random.default_rng(seed)
    return Similarity(
        float(rng.uniform(0.1, 20.0)), Rotation.random(random_state=seed).as_matrix(), rng.normal(0, 5, 3)
    )


@pytest.mark.parametrize("seed", range(5))
def test_fit_similarity_recovers_a_known_transform(seed: int) -> None:
    truth = _random_similarity(seed)
    src = np.random.default_rng(100 + seed).normal(size=(12, 3))
    fit = fit_similarity(src, truth.apply(src))
    assert fit.scale == pytest.approx(truth.scale, rel=1e-10)
    np.testing.assert_allclose(fit.rotation, truth.rotation, atol=1e-10)
    np.testing.assert_allclose(fit.translation, truth.translation, atol=1e-8)
    assert np.linalg.det(fit.rotation) == pytest.approx(1.0)


def test_fit_similarity_weights_ignore_an_outlier_with_zero_weight() -> None:
    truth = _random_similarity(7)
    src = np.random.default_rng(0).normal(size=(10, 3))
    dst = truth.apply(src)
    dst[3] += 50.0
    weights = np.ones(10)
    weights[3] = 0.0
    fit = fit_similarity(src, dst, weights=weights)
    np.testing.assert_allclose(fit.apply(src[:3]), dst[:3], atol=1e-8)
    unweighted = fit_similarity(src, dst)
    assert np.abs(unweighted.apply(src[:3]) - dst[:3]).max() > 1.0


def test_fit_similarity_never_reflects() -> None:
    src = np.random.default_rng(1).normal(size=(8, 3))
    fit = fit_similarity(src, src * np.array([-1.0, 1.0, 1.0]))  # a mirror image: no rotation fits
    assert np.linalg.det(fit.rotation) == pytest.approx(1.0)


def test_fit_similarity_rigid_keeps_scale_one() -> None:
    truth = _random_similarity(3)
    src = np.random.default_rng(2).normal(size=(6, 3))
    assert fit_similarity(src, truth.apply(src), scale=False).scale == 1.0


def test_collinear_points_raise_a_landmark_error() -> None:
    src = np.outer(np.arange(5.0), [1.0, 2.0, 3.0])
    with pytest.raises(LandmarkError, match="collinear"):
        fit_similarity(src, src + 1.0)
    with pytest.raises(LandmarkError, match="at least 3"):
        fit_similarity(src[:2], src[:2])


def test_inverse_composition_and_matrix_agree() -> None:
    a, b = _random_similarity(1), _random_similarity(2)
    pts = np.random.default_rng(3).normal(size=(5, 3))
    np.testing.assert_allclose(a.inverse().apply(a.apply(pts)), pts, atol=1e-9)
    np.testing.assert_allclose(a.then(b).apply(pts), b.apply(a.apply(pts)), atol=1e-8)
    homogeneous = np.column_stack([pts, np.ones(5)]) @ a.matrix().T
    np.testing.assert_allclose(homogeneous[:, :3], a.apply(pts), atol=1e-9)


def test_axis_rotations_are_the_24_proper_signed_permutations() -> None:
    rots = axis_rotations()
    assert rots.shape == (24, 3, 3)
    assert len({r.tobytes() for r in rots}) == 24
    np.testing.assert_allclose(np.linalg.det(rots), 1.0)
    for r in rots:
        noisy = Rotation.from_rotvec([0.2, -0.1, 0.15]).as_matrix() @ r
        np.testing.assert_array_equal(nearest_axis_rotation(noisy), r)


# ------------------------------------------------------------------------------ conformation


def test_shipped_landmark_model_matches_the_generator() -> None:
    """The shipped JSON is the finite-difference model of make_head (checked on 2 parameters)."""
    shipped = landmark_model()
    base = make_head(HeadParams(), shipped.resolution)
    np.testing.assert_allclose(shipped.base, base.landmark_positions(list(shipped.names)), atol=1e-8)
    for k, name in [(0, "head_width"), (5, "nose_length")]:
        assert list(PARAM_RANGES)[k] == name
        value = HeadParams().as_dict()[name] + 0.02
        moved = make_head(HeadParams().with_values(**{name: value}), shipped.resolution)
        column = (
            moved.landmark_positions(list(shipped.names)) - base.landmark_positions(list(shipped.names))
        ) / 0.02
        np.testing.assert_allclose(shipped.jacobian[..., k], column, atol=1e-6)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_fit_conformation_recovers_size_and_pose(seed: int) -> None:
    params = HeadParams.random(seed)
    head = make_head(params, 10_000)
    names = [n for n in head.landmarks if not n.startswith(("pupil", "jaw_")) and n != "menton"]
    to_target = Similarity(
        10.0, Rotation.from_euler("y", 180, degrees=True).as_matrix(), np.array([3.0, -2, 40])
    )
    result = fit_conformation(names, to_target.apply(head.landmark_positions(names)))
    # the similarity undoes the mm scale and the turn; the landmarks fit to about a millimetre
    assert result.to_model.scale == pytest.approx(0.1, rel=0.05)
    np.testing.assert_allclose(result.to_model.rotation, to_target.rotation.T, atol=0.03)
    assert np.sqrt(np.mean(result.residual**2)) < 0.12  # cm
    # the conformation explains more than the similarity alone: defaults leave larger residuals
    model = landmark_model()
    default_lm = model.positions(model.defaults, np.array([model.names.index(n) for n in names]))
    seen = to_target.apply(head.landmark_positions(names))
    moved = fit_similarity(seen, default_lm).apply(seen)
    assert np.sqrt(np.mean(np.sum((moved - default_lm) ** 2, axis=1))) > 1.5 * np.sqrt(
        np.mean(result.residual**2)
    )
    # the parameters stay in range
    for name, (low, high, _) in PARAM_RANGES.items():
        assert low <= getattr(result.params, name) <= high
