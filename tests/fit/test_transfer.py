"""The weight repairs of rig transfer, on synthetic cases with known answers: the jaw weight around
the mouth corners, and soft mouth parts (gums joined to the tongue) by their nearer tooth row."""

from __future__ import annotations

import numpy as np

from mimetic.fit.transfer import _smooth_mouth_corners, _soft_mouth_jaw


def grid(size: int, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """A flat (size × size) grid in the z = 0 plane centred on the origin: vertices (n, 3), faces (m, 3)."""
    x, y = np.meshgrid(np.arange(size) - (size - 1) / 2, np.arange(size) - (size - 1) / 2, indexing="ij")
    vertices = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1) * spacing
    k = np.arange(size * size).reshape(size, size)
    a, b, c, d = k[:-1, :-1].ravel(), k[1:, :-1].ravel(), k[1:, 1:].ravel(), k[:-1, 1:].ravel()
    return vertices, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def test_corner_smoothing_turns_a_step_into_a_slope_inside_the_radius_only():
    """Upper half on the head, lower half on the jaw, split along y = 0 (a commissure cut one row
    deep): near the corner the step becomes a slope; beyond the radius nothing changes."""
    vertices, faces = grid(41, 0.05)  # 2 × 2 cm at 0.5 mm
    weights = np.zeros((len(vertices), 3))  # head, jaw, a third bone
    lower = vertices[:, 1] < 0
    weights[lower, 1] = 1.0
    weights[~lower, 0] = 1.0
    corner = np.zeros((2, 3))  # both corners at the origin
    radius = 0.6
    out = _smooth_mouth_corners(weights, vertices, faces, corner, radius, jaw=1)
    np.testing.assert_allclose(out.sum(axis=1), 1.0)
    assert np.all(out >= 0) and np.all(out[:, 2] == 0)
    distance = np.linalg.norm(vertices, axis=1)
    np.testing.assert_array_equal(out[distance >= radius], weights[distance >= radius])
    # across the split, next to the corner, neighbours now differ by far less than the step of 1
    column = np.flatnonzero((np.abs(vertices[:, 0]) < 1e-9) & (np.abs(vertices[:, 1]) < 0.2))
    column = column[np.argsort(vertices[column, 1])]
    jaw = out[column, 1]
    assert np.all(np.diff(jaw) <= 1e-12)  # still falls from the lower side to the upper
    assert np.abs(np.diff(jaw)).max() < 0.35
    assert 0.3 < out[column[np.argmin(np.abs(vertices[column, 1]))], 1] < 0.7  # the corner shares


def test_soft_mouth_vertices_follow_their_nearer_tooth_row():
    upper = np.array([[x, 1.0, 0.0] for x in np.linspace(-2, 2, 9)])  # a tooth row at y = 1
    lower = upper - np.array([0.0, 2.0, 0.0])  # and one at y = -1
    points = np.array(
        [
            [0.0, 1.6, 0.0],  # upper gum: head
            [0.25, 0.6, 0.0],  # a papilla between upper teeth, reaching down: still head
            [0.0, -1.5, -0.5],  # lower gum: jaw
            [0.0, -0.8, -0.6],  # the tongue's side, inside the lower arch: jaw
            [0.0, 0.0, 0.0],  # halfway: shared
        ]
    )
    jaw = _soft_mouth_jaw(points, upper, lower)
    np.testing.assert_allclose(jaw[:2], 0.0, atol=1e-12)
    np.testing.assert_allclose(jaw[2:4], 1.0, atol=1e-12)
    assert abs(jaw[4] - 0.5) < 1e-12
