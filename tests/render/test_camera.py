"""Tests for mimetic.render.camera: matrices, framing, named views and ``project``."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mimetic.render.camera import VIEWS, Camera, clip_planes, frame_camera, project

BOX_MIN = np.array([-0.8, -1.1, -0.9])
BOX_MAX = np.array([0.8, 1.2, 1.0])


def box_corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


def test_camera_view_matrix_puts_eye_at_origin_looking_down_negative_z():
    camera = Camera(eye=(1.0, 2.0, 5.0), target=(0.0, 0.5, 0.0))
    view = camera.view_matrix()
    assert view.shape == (4, 4) and view.dtype == np.float64
    np.testing.assert_allclose(view @ [1.0, 2.0, 5.0, 1.0], [0, 0, 0, 1], atol=1e-12)
    target_view = view @ [0.0, 0.5, 0.0, 1.0]
    np.testing.assert_allclose(target_view[:2], 0, atol=1e-12)
    assert target_view[2] < 0
    np.testing.assert_allclose(view[:3, :3] @ view[:3, :3].T, np.eye(3), atol=1e-12)


def test_camera_rejects_up_parallel_to_view_and_eye_at_target():
    with pytest.raises(ValueError, match="parallel"):
        Camera(eye=(0, 5, 0), target=(0, 0, 0), up=(0, 1, 0))
    with pytest.raises(ValueError, match="same point"):
        Camera(eye=(1, 1, 1), target=(1, 1, 1))


def test_camera_arrays_are_read_only():
    camera = Camera(eye=[0, 0, 3], target=[0, 0, 0])
    assert camera.eye.dtype == np.float64 and camera.eye.shape == (3,)
    with pytest.raises(ValueError):
        camera.eye[0] = 1.0


def test_project_matches_projection_and_view_matrices():
    rng = np.random.default_rng(0)
    camera = Camera(eye=(0.4, 0.3, 4.0), target=(0.1, 0.0, 0.0), fov_y_deg=35.0)
    points = rng.uniform(-1, 1, (20, 3))
    w, h = 320, 200
    world_to_clip = camera.projection_matrix(w / h, 0.5, 10.0) @ camera.view_matrix()
    clip = np.c_[points, np.ones(20)] @ world_to_clip.T
    ndc = clip[:, :3] / clip[:, 3:]
    expected = np.stack([(ndc[:, 0] + 1) * w / 2, (1 - ndc[:, 1]) * h / 2], axis=1)
    pixels, depth = project(points, camera, (w, h))
    assert pixels.shape == (20, 2) and depth.shape == (20,)
    np.testing.assert_allclose(pixels, expected, atol=1e-9)
    np.testing.assert_allclose(depth, clip[:, 3], atol=1e-12)


def test_project_target_lands_on_image_centre_and_behind_camera_is_nan():
    camera = Camera(eye=(0, 0, 3), target=(0, 0, 0))
    pixels, depth = project(np.array([[0.0, 0, 0], [0.0, 0, 5]]), camera, (64, 48))
    np.testing.assert_allclose(pixels[0], [32, 24])
    assert depth[0] == pytest.approx(3.0)
    assert np.isnan(pixels[1]).all() and depth[1] < 0


def test_frame_camera_front_fits_box_inside_fill_and_touches_it():
    for fill in (0.5, 0.8):
        camera = frame_camera(BOX_MIN, BOX_MAX, fill=fill)
        pixels, depth = project(box_corners(BOX_MIN, BOX_MAX), camera, 100)
        assert (depth > 0).all()
        offset = np.abs(pixels - 50) / 50  # fraction of the half-frame
        assert offset.max() == pytest.approx(fill, abs=1e-9)
        np.testing.assert_allclose(camera.target, (BOX_MIN + BOX_MAX) / 2)
        assert camera.eye[2] > BOX_MAX[2]  # looks from the +Z side


def test_frame_camera_aspect_uses_wider_frame():
    camera = frame_camera(BOX_MIN, BOX_MAX, fill=0.8, aspect=2.0)
    pixels, _ = project(box_corners(BOX_MIN, BOX_MAX), camera, (200, 100))
    assert np.abs(pixels[:, 0] - 100).max() <= 0.8 * 100 + 1e-9
    assert np.abs(pixels[:, 1] - 50).max() <= 0.8 * 50 + 1e-9


def test_frame_camera_positive_yaw_turns_face_to_image_right():
    nose = np.array([0.0, 0.0, 1.0])  # the face looks down +Z
    for name, expected in (("front", 0.0), ("three_quarter", 1.0), ("profile", 1.0)):
        camera = frame_camera(BOX_MIN, BOX_MAX, yaw_deg=VIEWS[name])
        pixels, _ = project(nose, camera, 200)
        centre = project(camera.target, camera, 200).pixels
        assert np.sign(round(pixels[0] - centre[0], 6)) == expected, name
    profile = frame_camera(BOX_MIN, BOX_MAX, yaw_deg=90)
    assert profile.eye[0] < -1 and abs(profile.eye[2] - profile.target[2]) < 1e-9  # seen from -X


def test_frame_camera_positive_pitch_tilts_face_up():
    camera = frame_camera(BOX_MIN, BOX_MAX, pitch_deg=30)
    assert camera.eye[1] < camera.target[1]  # camera below, looking up
    nose = project(np.array([0.0, 0.0, 1.0]), camera, 200).pixels
    centre = project(camera.target, camera, 200).pixels
    assert nose[1] < centre[1]  # the nose moves up the image
    right, up, forward = camera.basis()
    assert abs(right @ up) < 1e-12 and abs(up @ forward) < 1e-12


def test_frame_camera_rejects_empty_box():
    with pytest.raises(ValueError, match="single point"):
        frame_camera(np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="below"):
        frame_camera(np.ones(3), np.zeros(3))


def test_clip_planes_enclose_vertices():
    camera = frame_camera(BOX_MIN, BOX_MAX, yaw_deg=35)
    corners = box_corners(BOX_MIN, BOX_MAX)
    near, far = clip_planes(camera, corners)
    depth = project(corners, camera, 64).depth
    assert 0 < near < depth.min() and depth.max() < far
    assert math.isfinite(far)
