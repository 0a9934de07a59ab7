"""The compiled chain kernels against the numpy code they replace (``mimetic.engines.kernels``)."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from mimetic.engines import kernels
from mimetic.engines.chain import (
    LID_MAX_OPENING_RAD,
    LID_SOLVE_STEPS,
    _clearance,
    _least_opening,
    _lower_line,
    _median,
    _turn_parts,
)
from mimetic.engines.skinning import linear_blend_skinning
from mimetic.rig.anatomy.lids import lower_line


def numpy_bridged_margin(u: np.ndarray, v: np.ndarray, span: float, column: float) -> np.ndarray:
    """The (j, j, j) formula of ``chain._lower_line``: chords up to ``span`` over dips, up to ``column``
    over anything."""
    j = len(u)
    k = np.arange(j)
    between = (k[:, None, None] < k[None, None, :]) & (k[None, None, :] < k[None, :, None])
    width = u[None, :] - u[:, None]
    slope = (v[None, :] - v[:, None]) / np.maximum(width, 1e-300)
    chord = v[:, None, None] + (u[None, None, :] - u[:, None, None]) * slope[:, :, None]
    dip = (v[None, None, :] <= v[:, None, None]) & (v[None, None, :] <= v[None, :, None])
    usable = between & ((width <= column)[:, :, None] | ((width <= span)[:, :, None] & dip))
    return np.maximum(v, np.where(usable, chord, -np.inf).max(axis=(0, 1)))


@pytest.mark.parametrize("seed", range(5))
def test_bridged_margin_gives_the_bits_of_the_numpy_formula(seed):
    rng = np.random.default_rng(seed)
    u = np.sort(rng.uniform(-1, 1, 20))
    v = rng.normal(0, 0.1, 20)
    u_before, v_before = u.copy(), v.copy()
    got = kernels.bridged_margin(u, v, 0.4, 0.15)
    assert got.shape == (20,) and got.dtype == np.float64
    np.testing.assert_array_equal(got, numpy_bridged_margin(u, v, 0.4, 0.15))
    np.testing.assert_array_equal(u, u_before)
    np.testing.assert_array_equal(v, v_before)


def test_lower_line_follows_a_rise_into_the_corner_and_bridges_dips():
    """The contact line (``chain._lower_line``) keeps a convex rise into a corner (bridging it lifted
    the line 0.27 cm over ICT identity s2 σ 2's canthus), bridges a dip up to ``span`` wide, and any
    turn within ``column``."""
    u = np.array([0.0, 0.01, 0.1, 0.2, 0.3, 0.4, 0.5])
    v = np.array([0.3, 0.0, -0.1, -0.15, -0.3, -0.15, -0.15])  # a wall, a slope, a dip at 0.3
    u_before, v_before = u.copy(), v.copy()
    line_u, line_v, step = _lower_line(np.column_stack([u, v, np.zeros(7)]), 0.25, 0.0)
    assert line_u.shape == line_v.shape == (7,) and line_v.dtype == np.float64
    np.testing.assert_array_equal(line_v[:4], v[:4])  # the rise stays where it is
    assert line_v[4] == pytest.approx(-0.15)  # the dip is bridged
    _, cut, _ = _lower_line(np.column_stack([u, v, np.zeros(7)]), 0.25, 0.15)
    assert cut[1] == pytest.approx(0.3 - 0.4 * 0.01 / 0.1)  # the wall's foot: under the column's chord
    assert step == pytest.approx(0.1)
    wall = np.column_stack([[0.0, 0.001, 0.002, 0.1], [0.1, 0.3, 0.0, -0.1], np.zeros(4)])
    assert _lower_line(wall, 0.25, 0.05)[1][0] == pytest.approx(0.3)  # the end stands at the wall's top
    np.testing.assert_array_equal(u, u_before)
    np.testing.assert_array_equal(v, v_before)


@pytest.mark.parametrize("seed", range(3))
def test_lower_line_is_the_rigs_line_compiled(seed):
    """The chain's per-frame line (compiled) is the one the closing weights aim at (numpy)."""
    rng = np.random.default_rng(seed)
    points = np.column_stack([rng.uniform(0, 3, 25), rng.normal(0, 0.2, 25), rng.normal(0, 0.1, 25)])
    before = points.copy()
    u, v, _ = _lower_line(points, 0.3, 0.1)
    want_u, want_v = lower_line(points, 0.3, 0.1)
    assert v.shape == want_v.shape == (25,)
    np.testing.assert_array_equal(u, want_u)
    np.testing.assert_array_equal(v, want_v)
    np.testing.assert_array_equal(points, before)


def test_median_is_numpys():
    rng = np.random.default_rng(3)
    for n in (1, 2, 7, 16):
        x = rng.normal(size=n)
        assert _median(x) == float(np.median(x))


def test_least_opening_matches_the_numpy_search():
    rng = np.random.default_rng(4)
    k = 12
    axis = np.array([1.0, 0.0, 0.0])
    along, across, cross = _turn_parts(rng.normal(0, 0.3, (k, 3)) + np.array([0, 0, 1.0]), axis)
    start, scale = rng.normal(0, 0.05, (k, 3)) + np.array([0, 1.0, 0]), rng.uniform(0.5, 1, k)
    origin, axes = np.zeros(3), np.eye(3)
    line_u = np.sort(rng.uniform(-2, 2, 15))
    line = (line_u, rng.normal(0.8, 0.02, 15), float(np.median(np.diff(line_u))))
    floor = rng.uniform(-0.01, 0.01, k)

    def above(delta: np.ndarray) -> np.ndarray:
        turned = along + across * np.cos(-delta)[:, None] + cross * np.sin(-delta)[:, None]
        return _clearance(start + scale[:, None] * turned, line, beyond=True) - floor

    expected = _least_opening(above, k)
    got = kernels.least_opening(
        start, scale, along, across, cross, origin, axes, line[0], line[1], line[2], floor,
        LID_MAX_OPENING_RAD, LID_SOLVE_STEPS,
    )  # fmt: skip
    assert got.shape == (k,)
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9)


def test_blend_skinning_and_channel_offsets_match_scipy():
    rng = np.random.default_rng(5)
    n, b, c = 50, 4, 6
    vertices = rng.normal(size=(n, 3))
    weights = sp.random(n, b, density=0.5, random_state=1, format="csc")
    transforms = np.tile(np.eye(4), (b, 1, 1))
    transforms[1:, :3, :] += rng.normal(0, 0.1, (b - 1, 3, 4))
    got = kernels.blend_skinning(
        vertices, weights.indptr, weights.indices, weights.data, transforms, np.arange(1, b)
    )
    np.testing.assert_allclose(got, linear_blend_skinning(vertices, weights, transforms), rtol=0, atol=1e-14)
    creases = sp.random(c, 3 * n, density=0.3, random_state=2, format="csr")
    values = np.array([0.0, 0.5, 0.0, 1.0, 0.25, 0.0])
    offsets = kernels.channel_offsets(creases.indptr, creases.indices, creases.data, values, 3 * n)
    np.testing.assert_array_equal(offsets, creases.T @ values)


@pytest.mark.parametrize("own", [True, False])
def test_sculpt_lids_is_the_eyeballs_sculptor_compiled(own):
    """The chain's compiled sculptor moves lid points as ``Eyeball.sculpt`` does, on an eye with a
    cornea of its own (tilted off the gaze, 10 % proud) and on the generic one, turned as a gaze turns."""
    import trimesh
    from scipy.spatial.transform import Rotation

    from mimetic.head.parts import CORNEA_BULGE, IRIS_ANGLE
    from mimetic.rig.anatomy.eyeball import FORWARD_STEPS, FORWARD_TOL_REL, GRID_STEP_RAD, REACH_RAD, Eyeball

    rng = np.random.default_rng(3)
    centre, radius = np.array([3.1, 3.4, 8.2]), 1.4
    ball = trimesh.creation.icosphere(subdivisions=5)
    unit = ball.vertices / np.linalg.norm(ball.vertices, axis=1, keepdims=True)
    axis = Rotation.from_euler("xy", [-0.1, 0.12]).apply([0.0, 0.0, 1.0])
    angle = np.arccos(np.clip(unit @ axis, -1.0, 1.0))
    bulge = 1.0 + 0.1 * np.cos(np.minimum(angle / 0.5, 1.0) * np.pi / 2) ** 2
    gaze = np.array([0.0, -0.1, 1.0])
    faces = ball.faces if own else None
    eye = Eyeball.of(centre, gaze, radius, centre + radius * unit * bulge[:, None], faces)
    assert (eye.radii is not None) == own
    transform = np.eye(4)
    transform[:3, :3] = Rotation.from_euler("xy", [0.2, -0.15]).as_matrix()
    transform[:3, 3] = transform[:3, :3] @ -centre + centre  # turned about its centre
    # lid points over the front of the eye, some inside it, with clearances from rest heights
    directions = rng.normal(size=(400, 3)) * [0.5, 0.5, 0.0] + [0.0, 0.0, 1.0]
    directions /= np.linalg.norm(directions, axis=1, keepdims=True)
    points = centre + radius * rng.uniform(0.95, 1.3, size=(400, 1)) * directions
    keep = np.ascontiguousarray(eye.rest_clearance(points, 0.005, 0.2))
    keep[np.isneginf(keep)] = 0.005
    moved = centre + (points - centre) @ transform[:3, :3].T * 0.97  # closing in on the eye
    expected = eye.sculpt(moved, keep, transform)
    assert np.abs(expected - moved).max() > 0.01  # the sculptor pushed points out
    v = np.concatenate([moved, [[0.0, 0.0, 0.0]]])  # a row it is not asked to move
    kernels.sculpt_lids(
        v, np.arange(400), centre, np.ascontiguousarray(transform[:3, :3]), eye.axes, radius, keep,
        np.zeros((0, 0)) if eye.radii is None else eye.radii, eye.grid[0], GRID_STEP_RAD, REACH_RAD,
        eye.excess, IRIS_ANGLE, CORNEA_BULGE, FORWARD_STEPS, FORWARD_TOL_REL,
    )  # fmt: skip
    np.testing.assert_allclose(v[:400], expected, rtol=0, atol=1e-9 * radius)
    np.testing.assert_array_equal(v[400], 0.0)
