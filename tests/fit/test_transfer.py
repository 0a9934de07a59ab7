"""The weight repairs of rig transfer, on synthetic cases with known answers: jumps of the jaw weight
across a face, and soft mouth parts (gums joined to the tongue) by their nearer tooth row."""

from __future__ import annotations

import numpy as np

from mimetic.fit.transfer import _smooth_jaw_jumps, _soft_mouth_jaw


def grid(size: int, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """A flat (size × size) grid in the z = 0 plane centred on the origin: vertices (n, 3), faces (m, 3)."""
    x, y = np.meshgrid(np.arange(size) - (size - 1) / 2, np.arange(size) - (size - 1) / 2, indexing="ij")
    vertices = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1) * spacing
    k = np.arange(size * size).reshape(size, size)
    a, b, c, d = k[:-1, :-1].ravel(), k[1:, :-1].ravel(), k[1:, 1:].ravel(), k[:-1, 1:].ravel()
    return vertices, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def test_a_jaw_weight_step_becomes_a_slope_near_it_and_nothing_else_changes():
    """The left half of the lower rows on the jaw, the rest on the head (a commissure fold cut one row
    deep, ending at x = 0): near the step it becomes a slope; beyond the radius nothing changes."""
    vertices, faces = grid(61, 0.05)  # 3 × 3 cm at 0.5 mm
    weights = np.zeros((len(vertices), 3))  # head, jaw, a third bone
    lower = (vertices[:, 1] < 0) & (vertices[:, 0] < 0)
    weights[lower, 1] = 1.0
    weights[~lower, 0] = 1.0
    radius = 0.4
    out = _smooth_jaw_jumps(weights, vertices, faces, radius, jaw=1)
    np.testing.assert_allclose(out.sum(axis=1), 1.0)
    assert np.all(out >= 0) and np.all(out[:, 2] == 0)
    # only vertices within the radius of the step's faces changed
    on_step = (np.abs(vertices[:, 1]) < 0.06) & (vertices[:, 0] < 0.06)
    on_step |= (np.abs(vertices[:, 0]) < 0.06) & (vertices[:, 1] < 0.06)
    changed = np.any(out != weights, axis=1)
    reach = np.min(np.linalg.norm(vertices[changed][:, None] - vertices[on_step][None], axis=2), axis=1)
    assert changed.any() and reach.max() < radius + 1e-9
    # across the step, away from its ends, neighbours now differ by far less than 1, in the same order
    column = np.flatnonzero((np.abs(vertices[:, 0] + 0.75) < 1e-9) & (np.abs(vertices[:, 1]) < 0.3))
    jaw = out[column[np.argsort(vertices[column, 1])], 1]
    assert np.all(np.diff(jaw) <= 1e-12)
    assert np.abs(np.diff(jaw)).max() < 0.35


def test_a_gentle_jaw_weight_ramp_is_left_alone():
    vertices, faces = grid(21, 0.1)
    weights = np.zeros((len(vertices), 2))
    weights[:, 1] = np.clip(0.5 - vertices[:, 1] / 2.0, 0.0, 1.0)  # 0.05 per row of faces
    weights[:, 0] = 1.0 - weights[:, 1]
    np.testing.assert_array_equal(_smooth_jaw_jumps(weights, vertices, faces, 0.4, jaw=1), weights)


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
