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


def test_closest_on_triangles_gives_trimesh_s_points_bit_for_bit():
    """The compiled pass (``mesh.kernels``) against ``trimesh.triangles.closest_point``, on a sphere and
    on degenerate triangles (coincident corners, a point, collinear corners)."""
    from mimetic.mesh.closest import _kernels

    rng = np.random.default_rng(3)
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=2.0)
    degenerate = np.array(
        [[[0, 0, 0], [0, 0, 0], [1, 0, 0]], [[1, 1, 1]] * 3, [[0, 0, 0], [1, 0, 0], [2, 0, 0]]], dtype=float
    )
    for vertices, faces in (
        (sphere.vertices, sphere.faces),
        (degenerate.reshape(-1, 3), np.arange(9).reshape(3, 3)),
    ):
        queries = rng.normal(size=(300, 3)) * 2.5
        near = rng.integers(0, len(faces), size=(300, 4))
        points, distance = _kernels().closest_on_triangles(vertices, faces, near, queries, trimesh.tol.zero)
        with np.errstate(all="ignore"):
            expected = trimesh.triangles.closest_point(
                vertices[faces][near.ravel()], np.repeat(queries, 4, axis=0)
            ).reshape(300, 4, 3)
        assert points.shape == (300, 4, 3) and distance.shape == (300, 4)
        np.testing.assert_array_equal(points, expected)
        np.testing.assert_array_equal(distance, np.linalg.norm(expected - queries[:, None], axis=2))
