"""A decimated proxy keeps the surface, and the embedding carries values and poses back exactly."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from mimetic.mesh.decimate import decimate, embed


@pytest.fixture(scope="module")
def sphere():
    mesh = trimesh.creation.icosphere(subdivisions=5, radius=10.0)  # 10,242 vertices
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)


def test_decimate_reaches_the_target_and_keeps_the_surface(sphere):
    vertices, faces = sphere
    proxy_v, proxy_f = decimate(vertices, faces, 1_000)
    assert 800 <= len(proxy_v) <= 1_200
    assert proxy_f.max() < len(proxy_v)
    radius = np.linalg.norm(proxy_v, axis=1)
    assert np.abs(radius - 10.0).max() < 0.05  # the proxy's vertices stay on the sphere


def test_a_small_surface_comes_back_unchanged(sphere):
    vertices, faces = sphere
    same_v, same_f = decimate(vertices, faces, 20_000)
    assert same_v is vertices or np.array_equal(same_v, vertices)
    assert np.array_equal(same_f, faces)


def test_embedding_restores_the_dense_points_and_follows_the_proxy(sphere):
    vertices, faces = sphere
    proxy_v, proxy_f = decimate(vertices, faces, 600)
    tied = embed(vertices, proxy_v, proxy_f)
    assert np.allclose(tied.bary.sum(axis=1), 1.0)
    assert np.abs(tied.place(proxy_v) - vertices).max() < 1e-9  # exact at the proxy's rest
    # a rigid motion of the proxy moves every dense point rigidly with it
    angle = 0.4
    rot = np.array([[np.cos(angle), 0, np.sin(angle)], [0, 1, 0], [-np.sin(angle), 0, np.cos(angle)]])
    shift = np.array([1.0, -2.0, 3.0])
    moved = tied.place(proxy_v @ rot.T + shift)
    assert np.abs(moved - (vertices @ rot.T + shift)).max() < 1e-9
    # the curvature between proxy vertices is kept: every dense point stays on the sphere
    assert np.abs(np.linalg.norm(tied.place(proxy_v), axis=1) - 10.0).max() < 1e-9


def test_carry_interpolates_linear_fields_exactly(sphere):
    vertices, faces = sphere
    proxy_v, proxy_f = decimate(vertices, faces, 600)
    tied = embed(vertices, proxy_v, proxy_f)
    field = proxy_v @ np.array([0.3, -0.2, 0.5]) + 1.0  # linear: barycentric interpolation is exact
    carried = tied.carry(field)
    barycentric = np.einsum("nk,nkd->nd", tied.bary, proxy_v[tied.triangles])
    assert np.allclose(carried, barycentric @ np.array([0.3, -0.2, 0.5]) + 1.0)
    assert np.allclose(tied.matrix() @ field, carried)
    weights = np.stack([field, 2 * field], axis=1)  # (k, 2) values carry column by column
    assert np.allclose(tied.carry(weights)[:, 1], 2 * carried)


def test_embed_with_normals_takes_the_triangle_facing_its_way():
    # two touching sheets as lips are: the upper faces down at z = 0, the lower up at z = -0.001
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    upper = np.column_stack([square, np.zeros(4)])
    lower = np.column_stack([square, np.full(4, -0.001)])
    vertices = np.concatenate([upper, lower])
    faces = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7]])  # upper: normal -z; lower: +z
    point = np.array([[0.4, 0.3, -0.0004]])  # nearer the upper sheet, on the lower lip's side
    plain = embed(point, vertices, faces)
    facing = embed(point, vertices, faces, normals=np.array([[0.0, 0.0, 1.0]]))
    assert set(plain.triangles[0]) <= {0, 1, 2, 3}
    assert set(facing.triangles[0]) <= {4, 5, 6, 7}
    np.testing.assert_allclose(facing.carry(vertices)[0, :2], point[0, :2], atol=1e-12)
    # no triangle facing its way among the candidates: the closest of any
    away = embed(point, vertices, faces[:2], normals=np.array([[0.0, 0.0, 1.0]]))
    assert set(away.triangles[0]) <= {0, 1, 2, 3}
