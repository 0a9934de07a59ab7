"""The compiled loops of ``mesh.kernels`` against the library arithmetic they replace, bit for bit."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from mimetic.mesh.geometry import closest_on_polyline
from mimetic.mesh.openings import front_depth


def _trimesh_depth(mesh: trimesh.Trimesh, x: np.ndarray, y: np.ndarray, step: float) -> np.ndarray:
    """The first hit's z of rays going down −Z from above ``mesh`` over the grid, NaN where a ray
    misses, by brute force: trimesh's plane hit and barycentric test (the narrow phase of its ray
    query) on every (ray, triangle) pair; per ray the hit nearest its origin, as trimesh picks it (the
    first triangle on a tie: next to an edge two triangles' hits can differ by an ulp)."""
    top = mesh.triangles[:, :, 2].max() + step  # where front_depth starts its rays
    gx, gy = np.meshgrid(x, y)
    rays = np.repeat(np.arange(gx.size), len(mesh.faces))
    tri = np.tile(np.arange(len(mesh.faces)), gx.size)
    origins = np.column_stack([gx.ravel()[rays], gy.ravel()[rays], np.full(len(rays), top)])
    location, valid = trimesh.intersections.planes_lines(
        mesh.triangles[tri, 0], mesh.face_normals[tri], origins, np.tile([0.0, 0.0, -1.0], (len(rays), 1))
    )
    barycentric = trimesh.triangles.points_to_barycentric(mesh.triangles[tri[valid]], location)
    hit = ((barycentric > -trimesh.tol.zero) & (barycentric < 1 + trimesh.tol.zero)).all(axis=1)
    ray, z, face = rays[valid][hit], location[hit, 2], tri[valid][hit]
    order = np.lexsort((face, top - z, ray))
    first = order[np.r_[True, ray[order][1:] != ray[order][:-1]]]
    depth = np.full(gx.size, np.nan)
    depth[ray[first]] = z[first]
    return depth.reshape(gx.shape)


def test_front_depth_gives_trimesh_s_ray_hits_bit_for_bit():
    """A lumpy sphere with a hole (the rays through it reach the far side), seen on a grid finer than
    its triangles and one coarser: every depth as trimesh's ray query finds it, misses where it misses."""
    mesh = trimesh.creation.icosphere(subdivisions=2, radius=2.0)
    rng = np.random.default_rng(4)
    mesh.vertices *= 1.0 + 0.05 * rng.normal(size=(len(mesh.vertices), 1))
    hole = mesh.triangles_center[:, 2] > 1.6
    mesh = trimesh.Trimesh(mesh.vertices, mesh.faces[~hole], process=False)
    for step in (0.09, 0.31):
        depth = front_depth(mesh.vertices, mesh.faces, np.array([-2.5, -2.2]), np.array([2.4, 2.5]), step)
        expected = _trimesh_depth(mesh, depth.x, depth.y, step)
        np.testing.assert_array_equal(depth.z, expected)
        assert np.isnan(depth.z).any() and np.isfinite(depth.z).sum() > 10
        through = np.isfinite(depth.z) & (depth.z < 0)  # seen through the hole: the far side
        assert through.any()


def _numpy_closest_on_polyline(points: np.ndarray, polyline: np.ndarray):
    """The formula ``closest_on_polyline`` had in numpy: (m, s) arrays of parameters and distances."""
    a, b = polyline[:-1], polyline[1:]
    ab = b - a
    t = np.einsum("msd,sd->ms", points[:, None] - a[None], ab) / np.maximum(
        np.einsum("sd,sd->s", ab, ab), 1e-30
    )
    t = np.clip(t, 0.0, 1.0)
    dist = np.linalg.norm(points[:, None] - (a[None] + t[..., None] * ab[None]), axis=2)
    seg = np.argmin(dist, axis=1)
    rows = np.arange(len(points))
    return seg, t[rows, seg], dist[rows, seg]


def test_closest_on_polyline_is_the_numpy_formula_bit_for_bit():
    rng = np.random.default_rng(5)
    for trial in range(60):
        m, k = int(rng.integers(1, 800)), int(rng.integers(2, 40))
        points = rng.normal(size=(m, 3)) * rng.uniform(0.1, 10.0)
        polyline = np.cumsum(rng.normal(size=(k, 3)), axis=0)
        if trial % 3 == 0:  # flat, as the openings' margins are
            points[:, 2] = polyline[:, 2] = 0.0
        if trial % 5 == 0:  # a zero-length segment
            polyline[min(3, k - 1)] = polyline[min(2, k - 1)]
        found = closest_on_polyline(points, polyline)
        for got, expected in zip(found, _numpy_closest_on_polyline(points, polyline), strict=True):
            np.testing.assert_array_equal(got, expected)
    seg, t, dist = closest_on_polyline(
        np.array([[0.5, 1.0, 0.0]]), np.array([[0.0, 0, 0], [1, 0, 0], [2, 0, 0]])
    )
    assert seg[0] == 0 and t[0] == 0.5 and dist[0] == 1.0
    with pytest.raises(ValueError, match="at least 2 points"):
        closest_on_polyline(np.zeros((3, 3)), np.zeros((1, 3)))
