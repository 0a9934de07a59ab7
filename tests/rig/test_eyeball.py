"""An eyeball's own surface, read off its mesh, for the lids' sculptor (``mimetic.rig.anatomy.eyeball``)."""

import numpy as np
import trimesh
from scipy.spatial.transform import Rotation

from mimetic.head.parts import eyeball_profile
from mimetic.rig.anatomy.eyeball import REACH_RAD, Eyeball

BULGE, REACH = 0.1, 0.5  # a cornea rising 10 % out of the sphere, 0.5 rad wide
AXIS = Rotation.from_euler("xy", [-0.12, 0.15]).apply([0.0, 0.0, 1.0])  # the cornea's axis, off the gaze


def cornea(directions: np.ndarray) -> np.ndarray:
    """The test eye's radius (k,) along unit ``directions`` (k, 3)."""
    angle = np.arccos(np.clip(directions @ AXIS, -1.0, 1.0))
    return 1.0 + BULGE * np.cos(np.minimum(angle / REACH, 1.0) * np.pi / 2) ** 2


def expected(directions: np.ndarray) -> np.ndarray:
    """What the sculptor takes for the test eye's radius (k,) along unit ``directions`` (k, 3) (at rest,
    gaze +Z): the eye's own within ``REACH_RAD`` of the gaze, never below the generic profile."""
    theta = np.arccos(directions[:, 2])
    return np.where(theta <= REACH_RAD, np.maximum(cornea(directions), eyeball_profile(theta)), 1.0)


def eye_mesh() -> trimesh.Trimesh:
    ball = trimesh.creation.icosphere(subdivisions=5)
    v = ball.vertices / np.linalg.norm(ball.vertices, axis=1, keepdims=True)
    return trimesh.Trimesh(v * cornea(v)[:, None], ball.faces, process=False)


def directions(count: int, within: float, seed: int = 0) -> np.ndarray:
    """``count`` unit directions (k, 3) within ``within`` rad of +Z."""
    rng = np.random.default_rng(seed)
    theta, phi = within * np.sqrt(rng.random(count)), rng.uniform(-np.pi, np.pi, count)
    return np.column_stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)])


def test_the_surface_is_the_eyes_own_where_its_cornea_bulges_off_the_gaze():
    mesh = eye_mesh()
    eye = Eyeball.of(np.zeros(3), np.array([0.0, 0.0, 1.0]), 1.0, mesh.vertices, mesh.faces)
    d = directions(2000, 1.2)
    dist, surface = eye.surface(2.0 * d)
    np.testing.assert_allclose(dist, 2.0)
    assert np.abs(surface - expected(d)).max() < 0.006  # the grid's 2.5° and the mesh's facets
    # one profile about the gaze misses the tilt: up to 0.05 of the radius too low on one side
    generic = eyeball_profile(np.arccos(d[:, 2]))
    assert (cornea(d) - generic).max() > 0.04


def test_without_an_eye_mesh_the_surface_is_the_generic_profile():
    eye = Eyeball.of(np.array([1.0, 2.0, 3.0]), np.array([0.0, 0.0, 2.0]), 1.5)
    d = directions(500, 1.5, seed=1)
    dist, surface = eye.surface(np.array([1.0, 2.0, 3.0]) + 0.7 * d)
    np.testing.assert_allclose(dist, 0.7)
    np.testing.assert_allclose(surface, 1.5 * eyeball_profile(np.arccos(d[:, 2])), atol=2e-3)


def test_a_turned_eye_carries_its_surface_and_the_sculptor_pushes_lids_out_of_it():
    mesh = eye_mesh()
    centre = np.array([0.3, -0.2, 0.5])
    eye = Eyeball.of(centre, np.array([0.0, 0.0, 1.0]), 1.0, mesh.vertices + centre, mesh.faces)
    turn = np.eye(4)
    turn[:3, :3] = Rotation.from_euler("xy", [0.3, -0.2]).as_matrix()
    turn[:3, 3] = [0.1, 0.0, -0.05]
    moved_centre = turn[:3, :3] @ centre + turn[:3, 3]
    d = directions(300, 1.0, seed=2)
    lids = moved_centre + (0.98 * d) @ turn[:3, :3].T  # inside the turned eye, everywhere
    _, surface = eye.surface(lids, turn)
    np.testing.assert_allclose(surface, expected(d), atol=0.006)
    out = eye.sculpt(lids, 0.01, turn)
    dist, surface = eye.surface(out, turn)
    np.testing.assert_allclose(dist, surface + 0.01, atol=1e-3)  # clear of the eye's own surface (3 steps)
    # out of the generic eyeball radially, then out of the cornea forward: across the gaze each point
    # lies where the radial push alone put it
    generic = eyeball_profile(np.arccos(d[:, 2]))
    radial = (generic + 0.01)[:, None] * d
    across = (out - moved_centre) @ turn[:3, :3]  # in the eye's rest frame
    np.testing.assert_allclose(across[:, :2], radial[:, :2], atol=1e-9)
    assert (across[:, 2] >= radial[:, 2] - 1e-12).all()
    # a point already outside, or told to be left alone (-inf), does not move
    far = moved_centre + 1.3 * (d @ turn[:3, :3].T)
    np.testing.assert_array_equal(eye.sculpt(far, 0.01, turn), far)
    np.testing.assert_array_equal(eye.sculpt(lids, -np.inf, turn), lids)


def test_each_lid_vertex_keeps_its_rest_height_over_the_eye_and_a_tucked_skirt_is_left_alone():
    mesh = eye_mesh()
    eye = Eyeball.of(np.zeros(3), np.array([0.0, 0.0, 1.0]), 1.0, mesh.vertices, mesh.faces)
    up = np.array([[0.0, np.sin(0.3), np.cos(0.3)]])  # over the cornea, 0.3 rad above the gaze
    own = float(cornea(up)[0])
    assert own > eyeball_profile(np.array([0.3]))[0] + 0.02  # this eye's cornea stands out of the generic one
    clearance, thickness = 0.001, 0.02
    points = np.concatenate(
        [
            (own + 0.1) * up,  # high over it: keeps the thickness
            (own + 0.01) * up,  # low over it: its own height
            (own - 0.01) * up,  # in the bulge's facets, outside the generic eyeball: as deep as at rest
            0.85 * up,  # a skirt tucked inside the sphere: left alone
            0.5 * up,  # deep inside: left alone
        ]
    )
    keep = eye.rest_clearance(points, clearance, thickness)
    # over its own surface: the thickness, its own height, as deep as at rest; over the generic
    # eyeball, which the cornea stands out of, higher than that
    np.testing.assert_allclose(keep[:3, 1], [clearance + thickness, 0.01, -0.01], atol=1e-3)
    assert (keep[:3, 0] >= keep[:3, 1] - 1e-12).all() and (keep[:3, 0] <= clearance + thickness + 1e-12).all()
    assert np.isneginf(keep[3:]).all()
    np.testing.assert_allclose(eye.sculpt(points, keep), points, atol=1e-12)  # at rest nothing moves
    # the same vertices swung down into the cornea's peak come out with those heights over it
    out = eye.sculpt(np.repeat(1.05 * AXIS[None, :], 3, axis=0), keep[:3])
    dist, surface = eye.surface(out)
    np.testing.assert_allclose(dist - surface, keep[:3, 1], atol=1e-3)  # three steps of the forward push
    # beyond the reach of the eye's own surface, the generic sphere
    side = np.array([[np.sin(1.2), 0.0, np.cos(1.2)]])
    np.testing.assert_allclose(eye.surface(side)[1], 1.0)
