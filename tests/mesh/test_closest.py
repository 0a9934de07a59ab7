"""Closest points on a mesh, including the degenerate triangles real scans and decimations contain."""

from __future__ import annotations

import numpy as np
import trimesh

from mimetic.mesh.closest import closest_points


def test_closest_points_match_trimesh_on_a_sphere():
    mesh = trimesh.creation.icosphere(subdivisions=3, radius=5.0)
    queries = np.random.default_rng(0).normal(size=(200, 3)) * 6.0
    found = closest_points(mesh.vertices, mesh.faces, queries)
    expected, distance, _ = trimesh.proximity.closest_point(mesh, queries)
    np.testing.assert_allclose(found.distance, distance, atol=1e-9)
    np.testing.assert_allclose(found.points, expected, atol=1e-9)
    on = np.einsum("qk,qkd->qd", found.bary, mesh.vertices[mesh.faces[found.faces]])
    np.testing.assert_allclose(on, found.points, atol=1e-9)


def test_a_degenerate_triangle_gives_finite_barycentric_coordinates():
    # a unit square of two triangles, and a third with no area lying on its diagonal's end
    vertices = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 2, 0], [3, 3, 0]], dtype=float)
    faces = np.array([[0, 1, 2], [0, 2, 3], [2, 4, 5]])  # the last: three collinear points
    queries = np.array([[2.9, 3.0, 0.5], [0.2, 0.7, 1.0], [2.05, 2.0, 0.0]])
    found = closest_points(vertices, faces, queries)
    assert np.isfinite(found.bary).all() and np.isfinite(found.points).all()
    np.testing.assert_allclose(found.bary.sum(axis=1), 1.0)
    assert found.faces[1] in (0, 1)  # over the square: the square's own triangle
    assert found.faces[0] == 2 and found.bary[0, 2] == 1.0  # nearest the collinear corner at (3, 3)
