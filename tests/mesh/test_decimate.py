"""A decimated proxy keeps the surface, and the embedding carries values and poses back exactly."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from mimetic.mesh.decimate import decimate, decimate_mapped, embed


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


def test_read_only_arrays_as_a_mesh_holds_them(sphere):
    vertices, faces = (np.array(a) for a in sphere)
    for a in (vertices, faces):
        a.setflags(write=False)
    proxy_v, _ = decimate(vertices, faces, 1_000)
    assert 800 <= len(proxy_v) <= 1_200


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


def test_embed_with_normals_keeps_points_on_their_own_sheet():
    # two sheets 0.1 apart, like lips at rest: the upper faces +z, the lower -z (a closed slit's sides)
    grid = np.stack(np.meshgrid(np.linspace(0, 1, 6), np.linspace(0, 1, 6)), -1).reshape(-1, 2)
    quads = [
        (i * 6 + j, i * 6 + j + 1, (i + 1) * 6 + j + 1, (i + 1) * 6 + j) for i in range(5) for j in range(5)
    ]
    up = np.array([(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads])
    upper = np.column_stack([grid, np.full(36, 0.05)])
    lower = np.column_stack([grid, np.full(36, -0.05)])
    vertices = np.concatenate([upper, lower])
    faces = np.concatenate([up, up[:, ::-1] + 36])  # the lower sheet wound the other way: faces -z
    rng = np.random.default_rng(0)
    points = np.column_stack([rng.uniform(0.1, 0.9, (200, 2)), np.full(200, -0.01)])  # nearer the lower
    normals = np.tile([0.0, 0.0, 1.0], (200, 1))  # but on the upper sheet's side
    before = points.copy()
    plain = embed(points, vertices, faces)
    facing = embed(points, vertices, faces, normals=normals)
    assert facing.triangles.shape == (200, 3) and facing.triangles.dtype == np.int64
    assert np.all(plain.triangles >= 36)  # the closest triangles are the lower sheet's
    assert np.all(facing.triangles < 36)  # the ones facing the points' way: the upper sheet's
    assert np.abs(facing.place(vertices) - points).max() < 1e-9  # still exact at rest
    assert np.array_equal(points, before)
    # a point no triangle faces (the upper sheet alone, seen from below) takes the closest of all
    away = embed(points[:3], upper, up, normals=-normals[:3])
    assert np.array_equal(away.triangles, embed(points[:3], upper, up).triangles)


def test_decimate_mapped_sends_each_vertex_to_its_own_piece(sphere):
    vertices, faces = sphere
    far = vertices * 0.5 + [30.0, 0.0, 0.0]
    both_v = np.concatenate([vertices, far])
    both_f = np.concatenate([faces, faces + len(vertices)])
    v, f, source = decimate_mapped(both_v, both_f, 2_000)
    assert source.shape == (len(both_v),) and source.dtype == np.int64
    np.testing.assert_array_equal(v, decimate(both_v, both_f, 2_000)[0])
    assert source.min() >= 0 and source.max() < len(v)
    # collapses run along edges: each sphere's vertices land on that sphere's copy, nearby
    np.testing.assert_array_equal(v[source, 0] > 15.0, both_v[:, 0] > 15.0)
    edge = np.median(np.linalg.norm(v[f[:, 0]] - v[f[:, 1]], axis=1))
    assert np.median(np.linalg.norm(v[source] - both_v, axis=1)) < edge


def test_embed_around_keeps_a_point_on_its_own_sheet_where_the_copies_cross():
    """A decimated lip: the upper lip's underside (faces -y) copied as two large triangles (their
    centroids far off) a little too high, the lower lip's top (faces +y) finely and just below the
    points. The points' nearest triangles by centroid are all the lower lip's and face away, so the
    closest of all (the lower lip's) took them; with the vertex their sheet collapsed into they keep
    to the upper lip."""
    grid = np.stack(np.meshgrid(np.linspace(0, 1, 11), np.linspace(0, 1, 11)), -1).reshape(-1, 2)
    quads = [
        (i * 11 + j, i * 11 + j + 1, (i + 1) * 11 + j + 1, (i + 1) * 11 + j)
        for i in range(10)
        for j in range(10)
    ]
    fine = np.array([(a, b, c) for a, b, c, d in quads] + [(a, c, d) for a, b, c, d in quads])
    lower = np.column_stack([grid[:, 0], np.full(121, -0.01), grid[:, 1]])  # x, y, z
    if np.cross(*(lower[fine[0, 1:]] - lower[fine[0, 0]]))[1] < 0:
        fine = fine[:, ::-1]  # the lower lip's top faces +y
    upper = np.array([[-5.0, 0.03, -5.0], [6.0, 0.03, -5.0], [6.0, 0.03, 6.0], [-5.0, 0.03, 6.0]])
    coarse = np.array([[0, 1, 2], [0, 2, 3]]) + 121
    if np.cross(*(upper[coarse[0, 1:] - 121] - upper[coarse[0, 0] - 121]))[1] > 0:
        coarse = coarse[:, ::-1]  # the upper lip's underside faces -y
    vertices = np.concatenate([lower, upper])
    faces = np.concatenate([fine, coarse])
    rng = np.random.default_rng(1)
    points = np.column_stack([rng.uniform(0.3, 0.7, 50), np.zeros(50), rng.uniform(0.3, 0.7, 50)])
    normals = np.tile([0.0, -1.0, 0.0], (50, 1))
    around = np.full(50, 121)  # a corner of the upper lip's copy
    before = points.copy()
    old = embed(points, vertices, faces, normals=normals, candidates=6)
    assert np.all(old.triangles < 121)  # the lower lip's: what strung the inner lips at 1.68M
    kept = embed(points, vertices, faces, normals=normals, candidates=6, around=around)
    assert kept.triangles.shape == (50, 3) and kept.bary.dtype == np.float64
    assert np.all(kept.triangles >= 121)
    np.testing.assert_allclose(kept.place(vertices), points, atol=1e-9)
    np.testing.assert_array_equal(points, before)
    # a point with no sheet vertex (-1) keeps the first answer
    lone = embed(points, vertices, faces, normals=normals, candidates=6, around=np.full(50, -1))
    np.testing.assert_array_equal(lone.triangles, old.triangles)
