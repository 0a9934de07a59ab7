"""Head-motion removal with known answers: the weighted rigid fit, its outliers, contour markers."""

from __future__ import annotations

import numpy as np

from mimetic.capture.head import MODEL_ERROR, HeadMotion, head_motion, head_weights, nearest_true
from mimetic.engines.skinning import rotation_x, rotation_y, rotation_z
from mimetic.fit.similarity import Similarity


def face_points(rng: np.random.Generator, k: int = 12) -> np.ndarray:
    """Points spread like markers on a 20 cm head (cm)."""
    return rng.normal(scale=[6.0, 8.0, 4.0], size=(k, 3))


def test_head_motion_is_recovered_and_an_outlier_ignored():
    rng = np.random.default_rng(3)
    rest = face_points(rng, 10)
    pivot = np.array([0.0, 2.0, -3.0])
    f = 20
    angles = rng.uniform(-0.3, 0.3, (f, 3))  # yaw, pitch, roll
    angles[0] = 0.0
    shift = rng.normal(scale=2.0, size=(f, 3))
    shift[0] = 0.0
    frames = np.empty((f, 10, 3))
    for t in range(f):
        R = rotation_y(angles[t, 0]) @ rotation_x(angles[t, 1]) @ rotation_z(-angles[t, 2])
        frames[t] = (rest - pivot) @ R.T + pivot + shift[t]
    frames[5, 3] += 4.0  # a loose marker
    frames[7, 1] = np.nan  # a missing one
    motion = head_motion(
        frames, rest, np.ones(10), Similarity.identity(), pivot=pivot, size=20.0, fixed_scale=True
    )
    assert isinstance(motion, HeadMotion)
    np.testing.assert_allclose(motion.angles(), angles, atol=1e-9)
    np.testing.assert_allclose(motion.translation, shift, atol=1e-8)
    assert not motion.inliers[5, 3] and motion.inliers[5].sum() == 9
    assert not motion.inliers[7, 1]
    assert motion.fitted.all()
    err = np.linalg.norm(motion.stabilise(frames) - rest, axis=2)
    err[5, 3] = err[7, 1] = 0.0
    assert err.max() < 1e-9


def test_frames_without_enough_points_take_their_neighbours_motion():
    rng = np.random.default_rng(4)
    rest = face_points(rng, 5)
    frames = np.repeat(rest[None], 6, axis=0)
    frames[2:4, :3] = np.nan  # two points left: no fit
    motion = head_motion(
        frames, rest, np.ones(5), Similarity.identity(), pivot=np.zeros(3), size=20.0, fixed_scale=True
    )
    assert motion.fitted.tolist() == [True, True, False, False, True, True]
    assert np.isnan(motion.residual[2]) and motion.residual[0] < 1e-9
    np.testing.assert_allclose(motion.rotation[2], np.eye(3), atol=1e-12)


def test_nearest_true():
    mask = np.array([False, True, False, False, False, False, True, False])
    assert nearest_true(mask).tolist() == [1, 1, 1, 1, 6, 6, 6, 6]


def test_head_weights_trust_the_markers_the_expression_moves_least():
    usable = np.array([[True, True, True, False]])
    motion = np.array([[0.0, 0.1, 1.0, 0.0]])  # cm: still, a little, much, unseen
    w = head_weights(usable, motion, noise=0.03)
    assert w[0, 0] > w[0, 1] > w[0, 2] > 0 and w[0, 3] == 0
    np.testing.assert_allclose(w[0, 0] / w[0, 2], (0.03**2 + MODEL_ERROR**2) / 0.03**2)


def test_contour_markers_constrain_the_head_only_across_their_contour():
    """Contour points that slide along their contour (a tracker's jaw line) must not drag the head:
    with the projectors the motion is exact, without them it is not."""
    rng = np.random.default_rng(5)
    rest = face_points(rng, 12)
    contour = np.arange(6)  # the first six slide along x
    projectors = np.repeat(np.eye(3)[None], 12, axis=0)
    projectors[contour] -= np.outer([1.0, 0.0, 0.0], [1.0, 0.0, 0.0])
    R = rotation_y(0.2) @ rotation_x(-0.1)
    slide = np.zeros_like(rest)
    slide[contour, 0] = rng.normal(scale=1.5, size=6)  # each contour point slid along x in the rig frame
    frames = ((rest + slide) @ R.T + np.array([1.0, -0.5, 2.0]))[None].repeat(3, axis=0)
    args = dict(pivot=np.zeros(3), size=20.0, fixed_scale=True)
    with_projectors = head_motion(
        frames, rest, np.ones(12), Similarity.identity(), projectors=projectors, **args
    )
    np.testing.assert_allclose(with_projectors.rotation[0], R, atol=1e-8)  # the head's turn
    plain = head_motion(frames, rest, np.ones(12), Similarity.identity(), **args)
    assert np.abs(plain.rotation[0] - R).max() > 1e-3


def test_a_frame_with_a_free_scale_follows_a_face_nearing_the_camera():
    rng = np.random.default_rng(6)
    rest = face_points(rng, 10)
    frames = np.stack([rest, 1.25 * rest @ rotation_z(0.1).T + 3.0])  # pixels: nearer, turned
    calibration = Similarity(1.0, np.eye(3), np.zeros(3))
    motion = head_motion(
        frames, rest, np.ones(10), calibration, pivot=np.zeros(3), size=20.0, fixed_scale=False
    )
    np.testing.assert_allclose(motion.stabilise(frames), np.stack([rest, rest]), atol=1e-8)
    np.testing.assert_allclose(motion.angles()[1], [0.0, 0.0, -0.1], atol=1e-9)
