"""Tests for mimetic.render.raster, the CPU rasterizer (no GL needed)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from mimetic.errors import MeshError
from mimetic.mesh.model import Mesh
from mimetic.render.raster import (
    AMBIENT,
    BACKGROUND,
    DETECTION,
    DIFFUSE,
    DISPLAY,
    FILL,
    FILL_DIR_VIEW,
    Lighting,
    shade,
    to_uint8,
)
from mimetic.view import Camera, frame_camera, project, rasterize


def test_rasterize_small_sphere_centroid_matches_project():
    point = np.array([-0.3, 0.2, 0.1])
    tm = trimesh.creation.icosphere(subdivisions=4, radius=0.1)
    mesh = Mesh(tm.vertices + point, tm.faces)
    camera = Camera(eye=(0.3, 0.2, 3.0), target=(0.0, 0.0, 0.0), fov_y_deg=30)
    image = rasterize(mesh, camera, size=(150, 100), albedo=(1, 1, 1), background=(0, 0, 0))
    assert image.shape == (100, 150, 3) and image.dtype == np.uint8
    weight = (image.sum(axis=2) > 0).astype(np.float64)  # coverage, not brightness
    ys, xs = np.mgrid[0:100, 0:150]
    centroid = np.array([(weight * (xs + 0.5)).sum(), (weight * (ys + 0.5)).sum()]) / weight.sum()
    np.testing.assert_allclose(centroid, project(point, camera, (150, 100)).pixels, atol=0.2)


def test_rasterize_empty_mesh_gives_background():
    camera = Camera(eye=(0, 0, 3), target=(0, 0, 0))
    image = rasterize(Mesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64)), camera, size=(8, 4))
    assert image.shape == (4, 8, 3)
    assert (image == to_uint8(np.array(BACKGROUND))).all()


def test_rasterize_rejects_nan_vertices():
    tm = trimesh.creation.icosphere(subdivisions=1)
    vertices = tm.vertices.copy()
    vertices[3] = np.nan
    with pytest.raises(MeshError, match="NaN"):
        rasterize(Mesh(vertices, tm.faces), Camera(eye=(0, 0, 3), target=(0, 0, 0)), size=16)


def test_rasterize_large_triangles_crossing_the_frame_edge_cover_the_screen():
    # Two triangles far larger than the image: exercises the chunked path and screen clipping.
    corners = np.array([[-50, -50, 0], [50, -50, 0], [50, 50, 0], [-50, 50, 0]], float)
    quad = Mesh(corners, [[0, 1, 2], [0, 2, 3]])
    image = rasterize(quad, Camera(eye=(0, 0, 3), target=(0, 0, 0)), size=(300, 200), background=(0, 0, 0))
    assert (image.sum(axis=2) > 0).all()


def test_rasterize_nearer_surface_wins():
    near = trimesh.creation.box(extents=(1, 1, 0.1))
    far = trimesh.creation.box(extents=(2, 2, 0.1))
    pieces = {
        "near": Mesh(near.vertices + np.array([0, 0, 0.5]), near.faces, colors=np.tile([[1, 0, 0]], (8, 1))),
        "far": Mesh(far.vertices, far.faces, colors=np.tile([[0, 0, 1]], (8, 1))),
    }
    mesh = Mesh.concatenate(pieces)
    image = rasterize(mesh, frame_camera(mesh.vertices.min(0), mesh.vertices.max(0)), size=64).astype(int)
    centre, corner = image[32, 32], image[32, 8]
    assert centre[0] > centre[2] and corner[2] > corner[0]


def test_shade_lights_front_facing_normal_toward_light_brightest():
    light = np.array([0.3, 0.6, 1.0]) / np.linalg.norm([0.3, 0.6, 1.0])
    normals = np.array([light, [-1.0, 0, 0], -light, [0, -1.0, 0]])  # key, fill only, neither, below
    positions = np.tile([[0, 0, -3.0]], (4, 1))
    colors = np.full((4, 3), 0.5)
    front = np.ones(4, bool)
    c = shade(normals, positions, colors, front)
    assert c.shape == (4, 3)
    assert c[0, 0] > c[1, 0] > c[2, 0]
    np.testing.assert_allclose(c[2], 0.5 * AMBIENT)  # facing away from both lights: ambient only
    # facing down, away from the key light: ambient and the fill from below (no smudge under a nose)
    np.testing.assert_allclose(c[3], 0.5 * (AMBIENT + FILL * -FILL_DIR_VIEW[1]))
    assert c[3, 0] > 1.5 * c[2, 0]
    back = shade(normals, positions, colors, ~front)  # flipped, darkened
    assert (back[2] > back[0]).all()


def test_a_face_detector_sees_its_own_light_not_the_pictures():
    """``raster.DETECTION`` (``fit.autolandmarks``' renders) has no fill light and its own levels, so
    restyling the pictures (``DISPLAY``) never moves a fitted rig's automatic landmarks."""
    normals = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, 1.0]])  # facing down (fill only), facing the viewer
    positions = np.tile([[0, 0, -3.0]], (2, 1))
    colors = np.full((2, 3), 0.5)
    front = np.ones(2, bool)
    seen = shade(normals, positions, colors, front, DETECTION)
    np.testing.assert_allclose(seen[0], 0.5 * DETECTION.ambient)  # no fill for the detector
    shown = shade(normals, positions, colors, front, DISPLAY)
    assert shown[0, 0] > seen[0, 0]  # the pictures' fill lights skin facing down
    assert DISPLAY == Lighting(AMBIENT, DIFFUSE, FILL) and DETECTION != DISPLAY
