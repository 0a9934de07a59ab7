"""Tests for the topology helpers in mimetic.mesh.geometry."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from mimetic.mesh.geometry import (
    boundary_counts,
    boundary_edges,
    boundary_loops,
    boundary_paths,
    connected_components,
    edges_unique,
    edges_with_counts,
    smooth_field,
    vertex_adjacency,
    vertex_areas,
)

FIN = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]])  # three triangles on edge (0, 1)
BOWTIE = np.array([[0, 1, 2], [0, 3, 4]])  # two triangles touching at vertex 0


def two_tetrahedra(tetrahedron):
    return np.concatenate([tetrahedron.faces, tetrahedron.faces + 4])


def test_edges_unique_tetrahedron_has_six_sorted_edges(tetrahedron):
    faces = tetrahedron.faces
    edges = edges_unique(faces)
    assert edges.shape == (6, 2)
    assert edges.dtype == np.int64
    np.testing.assert_array_equal(edges, [[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])


def test_edges_with_counts_unit_square_diagonal_is_shared(unit_square):
    edges, counts = edges_with_counts(unit_square.faces)
    assert edges.shape == (5, 2)
    assert counts.shape == (5,)
    assert counts.dtype == np.int64
    np.testing.assert_array_equal(edges, [[0, 1], [0, 2], [0, 3], [1, 2], [2, 3]])
    np.testing.assert_array_equal(counts, [1, 2, 1, 1, 1])


def test_edges_with_counts_fin_edge_counts_three():
    edges, counts = edges_with_counts(FIN)
    assert counts[(edges == [0, 1]).all(axis=1)].tolist() == [3]


def test_edges_with_counts_degenerate_face_drops_self_edge():
    edges, counts = edges_with_counts(np.array([[4, 4, 7]]))
    np.testing.assert_array_equal(edges, [[4, 7]])
    np.testing.assert_array_equal(counts, [2])


def test_edges_with_counts_empty_faces_give_empty_arrays():
    edges, counts = edges_with_counts(np.zeros((0, 3), np.int64))
    assert edges.shape == (0, 2)
    assert counts.shape == (0,)


def test_edges_unique_float_faces_raise_type_error():
    with pytest.raises(TypeError, match="integer"):
        edges_unique(np.zeros((2, 3)))


def test_vertex_adjacency_square_is_symmetric_with_expected_degrees(unit_square):
    adjacency = vertex_adjacency(unit_square.faces, 5)
    assert adjacency.shape == (5, 5)
    assert adjacency.dtype == np.float64
    assert (adjacency != adjacency.T).nnz == 0
    assert adjacency.diagonal().sum() == 0
    np.testing.assert_array_equal(np.asarray(adjacency.sum(axis=1)).ravel(), [3, 2, 3, 2, 0])
    np.testing.assert_array_equal(np.sort(adjacency[0].indices), [1, 2, 3])


def test_vertex_adjacency_n_too_small_raises(unit_square):
    with pytest.raises(ValueError, match="n=3"):
        vertex_adjacency(unit_square.faces, 3)


def test_connected_components_two_tetrahedra_give_two(tetrahedron):
    faces = two_tetrahedra(tetrahedron)
    before = faces.copy()
    count, labels = connected_components(faces, 9)
    assert labels.shape == (9,)
    assert labels.dtype == np.int64
    assert count == 3  # two tetrahedra and the unused vertex 8
    assert len(set(labels[:4])) == 1
    assert len(set(labels[4:8])) == 1
    assert len({labels[0], labels[4], labels[8]}) == 3
    np.testing.assert_array_equal(faces, before)


def test_connected_components_bowtie_is_one_component():
    count, labels = connected_components(BOWTIE, 5)
    assert count == 1
    np.testing.assert_array_equal(labels, np.zeros(5))


def test_boundary_loops_closed_tetrahedron_has_none(tetrahedron):
    assert boundary_loops(tetrahedron.faces) == []
    assert boundary_edges(tetrahedron.faces).shape == (0, 2)
    assert boundary_counts(tetrahedron.faces) == (0, 0)


def test_boundary_loops_unit_square_is_one_loop_in_face_winding(unit_square):
    loops = boundary_loops(unit_square.faces)
    assert len(loops) == 1
    assert loops[0].dtype == np.int64
    np.testing.assert_array_equal(loops[0], [0, 1, 2, 3])


def test_boundary_loops_reversed_faces_reverse_the_loop(unit_square):
    (loop,) = boundary_loops(unit_square.faces[:, ::-1])
    np.testing.assert_array_equal(loop, [0, 3, 2, 1])


def test_boundary_edges_follow_face_winding(unit_square):
    edges = boundary_edges(unit_square.faces)
    assert edges.shape == (4, 2)
    assert {tuple(e) for e in edges.tolist()} == {(0, 1), (1, 2), (2, 3), (3, 0)}


def test_boundary_loops_bowtie_pinch_splits_into_two_triangles():
    loops = boundary_loops(BOWTIE)
    assert [loop.tolist() for loop in loops] == [[0, 1, 2], [0, 3, 4]]
    assert boundary_counts(BOWTIE) == (2, 0)


def test_boundary_paths_fin_gives_open_chain():
    paths = boundary_paths(FIN)
    assert len(paths.chains) == 1
    assert len(paths.loops) == 1
    assert boundary_counts(FIN) == (1, 1)
    used = np.concatenate([*paths.loops, *paths.chains])
    assert set(used.tolist()) == {0, 1, 2, 3, 4}


def test_boundary_loops_open_hemisphere_loop_is_ordered_rim():
    sphere = trimesh.creation.icosphere(subdivisions=2)
    faces = sphere.faces[sphere.vertices[sphere.faces].mean(axis=1)[:, 1] > 0]  # upper half, open rim
    (loop,) = boundary_loops(faces)
    edges = {tuple(e) for e in boundary_edges(faces).tolist()}
    assert len(loop) == len(edges)
    steps = set(zip(loop.tolist(), np.roll(loop, -1).tolist(), strict=True))
    assert steps == edges  # every step is a boundary edge, walked in face winding
    assert loop[0] == loop.min()


def test_boundary_counts_random_soups_match_boundary_paths():
    rng = np.random.default_rng(11)
    for _ in range(200):
        n = int(rng.integers(3, 9))
        faces = rng.integers(0, n, size=(int(rng.integers(1, 10)), 3))
        paths = boundary_paths(faces)
        assert boundary_counts(faces) == (len(paths.loops), len(paths.chains))
        walked = sum(len(p) for p in paths.loops) + sum(len(p) - 1 for p in paths.chains)
        assert walked == len(boundary_edges(faces))  # every boundary edge walked exactly once


def _plane(size: int, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    x, y = np.meshgrid(np.arange(size) - (size - 1) / 2, np.arange(size) - (size - 1) / 2, indexing="ij")
    vertices = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1) * spacing
    k = np.arange(size * size).reshape(size, size)
    a, b, c, d = k[:-1, :-1].ravel(), k[1:, :-1].ravel(), k[1:, 1:].ravel(), k[:-1, 1:].ravel()
    return vertices, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def test_smooth_field_turns_a_step_into_a_ramp_of_the_given_length():
    """Screened Poisson in 1D across a step: 1/2 · exp(−|x|/ℓ) either side, slope 1/(2ℓ) at the step."""
    vertices, faces = _plane(81, 0.02)  # 1.6 × 1.6 at 0.2 mm spacing
    step = (vertices[:, 0] > 0).astype(float)
    for length in (0.05, 0.1):
        out = smooth_field(step, vertices, faces, length)
        row = np.flatnonzero(np.abs(vertices[:, 1]) < 1e-9)
        row = row[np.argsort(vertices[row, 0])]
        x, y = vertices[row, 0], out[row]
        inside = (np.abs(x) > 2 * length) & (np.abs(x) < 0.6)
        expected = np.where(x > 0, 1 - 0.5 * np.exp(-x / length), 0.5 * np.exp(x / length))
        np.testing.assert_allclose(y[inside], expected[inside], atol=0.03)


def test_smooth_field_keeps_constants_and_fixed_vertices_and_the_input():
    vertices, faces = _plane(11, 0.1)
    values = np.column_stack([np.full(len(vertices), 2.5), vertices[:, 0] ** 2])
    before = values.copy()
    free = vertices[:, 0] > 0
    out = smooth_field(values, vertices, faces, 0.2, free=free)
    np.testing.assert_array_equal(values, before)
    np.testing.assert_allclose(out[:, 0], 2.5)
    np.testing.assert_array_equal(out[~free], values[~free])
    assert out.shape == values.shape and not np.allclose(out[free, 1], values[free, 1])
    np.testing.assert_array_equal(smooth_field(values, vertices, faces, 0.0), values)


def test_vertex_areas_average_like_the_surface_however_it_is_sampled():
    """Shares sum to the area, and weighting by them gives the area centroid: a hemisphere with its
    top half subdivided twice has the same weighted mean height, while its vertex mean rises."""
    sphere = trimesh.creation.icosphere(2)
    keep = sphere.triangles_center[:, 1] > -0.1
    vertices, faces = sphere.vertices, sphere.faces[keep]
    before = vertices.copy()
    shares = vertex_areas(vertices, faces)
    assert shares.shape == (len(vertices),) and shares.dtype == np.float64
    np.testing.assert_allclose(shares.sum(), trimesh.Trimesh(vertices, faces, process=False).area, rtol=1e-12)
    assert shares[np.setdiff1d(np.arange(len(vertices)), faces)].max(initial=0.0) == 0.0  # unused
    top = np.flatnonzero(vertices[faces, 1].mean(axis=1) > 0.5)
    fine_v, fine_f = vertices, faces
    for _ in range(2):
        fine_v, fine_f = trimesh.remesh.subdivide(fine_v, fine_f, face_index=top)
        top = np.arange(len(fine_f) - 4 * len(top), len(fine_f))
    used, fine_used = np.unique(faces), np.unique(fine_f)
    centroid = np.average(vertices[:, 1], weights=shares)
    fine = np.average(fine_v[:, 1], weights=vertex_areas(fine_v, fine_f))
    assert abs(fine - centroid) < 1e-12
    assert fine_v[fine_used, 1].mean() > vertices[used, 1].mean() + 0.1
    np.testing.assert_array_equal(vertices, before)
