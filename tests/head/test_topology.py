"""Tests for mimetic.head.topology: the skin's connectivity, its openings and its mirror map."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse import csgraph

from mimetic.head.model import make_head
from mimetic.head.topology import build_topology, eye_ring_params, mouth_ring_params
from mimetic.mesh.geometry import boundary_loops

FLIP_X = np.array([-1.0, 1.0, 1.0])


def canonical_faces(faces: np.ndarray) -> np.ndarray:
    """Faces (m, 3) rotated so each starts at its smallest index (orientation kept), rows sorted."""
    first = np.argmin(faces, axis=1)  # (m,)
    cols = (first[:, None] + np.arange(3)) % 3  # (m, 3)
    rolled = np.take_along_axis(faces, cols, axis=1)
    return rolled[np.lexsort(rolled.T[::-1])]


def fans_per_vertex(faces: np.ndarray, n: int) -> np.ndarray:
    """Number of separate triangle fans (n,) around each vertex: 1 everywhere on a manifold.

    The corners of the faces at one vertex are joined when their faces share an edge through
    that vertex; the connected components of that corner graph are the fans.
    """
    m = len(faces)
    corner_vertex = faces.ravel()  # corner c = 3 f + k
    a = faces.ravel()
    b = np.roll(faces, -1, axis=1).ravel()  # half-edge a -> b at corner of a
    next_corner = (np.arange(3 * m) // 3) * 3 + (np.arange(3 * m) + 1) % 3  # the corner of b in the face
    key = a * n + b
    twin_key = b * n + a
    order = np.argsort(key)
    pos = np.searchsorted(key[order], twin_key)
    pos = np.minimum(pos, len(key) - 1)
    found = key[order][pos] == twin_key
    twin = order[pos][found]  # half-edge b -> a in another face
    here = np.arange(3 * m)[found]
    # half-edge a->b (corner of a = here) and its twin b->a (corner of a = the twin's next corner)
    rows = np.concatenate([here, next_corner[here]])
    cols = np.concatenate([next_corner[twin], twin])
    graph = sp.coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(3 * m, 3 * m))
    _, label = csgraph.connected_components(graph, directed=False)
    fans = np.zeros(n, np.int64)
    pairs = np.unique(np.column_stack([corner_vertex, label]), axis=0)
    np.add.at(fans, pairs[:, 0], 1)
    return fans


def test_build_topology_arrays_have_documented_shapes_and_dtypes(topology):
    n = topology.n_vertices
    assert topology.directions.shape == (n, 3) and topology.directions.dtype == np.float64
    assert topology.faces.ndim == 2 and topology.faces.shape[1] == 3 and topology.faces.dtype == np.int64
    assert topology.ring_uv.shape == (n, 2) and topology.ring_uv.dtype == np.float64
    assert topology.mirror.shape == (n,) and topology.mirror.dtype == np.int64
    for rings in (topology.eye_L, topology.eye_R, topology.mouth):
        assert rings.index.ndim == 2 and rings.index.dtype == np.int64
        assert rings.u.shape == (rings.index.shape[0],)
    for array in (topology.directions, topology.faces, topology.ring_uv, topology.mirror):
        assert not array.flags.writeable
    np.testing.assert_allclose(np.linalg.norm(topology.directions, axis=1), 1.0, atol=1e-12)
    assert topology.faces.min() >= 0 and topology.faces.max() < n


def test_build_topology_is_deterministic(topology):
    fresh = build_topology.__wrapped__(2_500)  # bypass the cache
    assert fresh is not topology
    assert np.array_equal(fresh.faces, topology.faces)
    assert np.array_equal(fresh.directions, topology.directions)
    assert np.array_equal(fresh.mirror, topology.mirror)


@pytest.mark.parametrize("resolution", [2_500, 10_000])
def test_build_topology_skin_is_an_oriented_manifold_sphere_with_three_holes(resolution):
    topo = build_topology(resolution)
    f, n = topo.faces, topo.n_vertices
    assert f.dtype == np.int64 and f.shape[1] == 3
    assert np.all((f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])), "degenerate faces"
    assert np.array_equal(np.unique(f), np.arange(n)), "every vertex is used by a face"
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])  # (3m, 2)
    _, directed_counts = np.unique(directed, axis=0, return_counts=True)
    assert directed_counts.max() == 1, "two faces walk an edge the same way: inconsistent winding"
    undirected, counts = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    assert set(np.unique(counts)) <= {1, 2}, "an edge is used by more than two faces"
    assert np.all(fans_per_vertex(f, n) == 1), "a vertex joins two separate fans (pinch)"
    graph = sp.coo_matrix((np.ones(len(undirected)), (undirected[:, 0], undirected[:, 1])), shape=(n, n))
    assert csgraph.connected_components(graph, directed=False)[0] == 1
    euler = n - len(undirected) + len(f)
    assert euler == -1, f"Euler characteristic {euler}; a sphere minus three holes has -1"


@pytest.mark.parametrize("resolution", [2_500, 10_000])
def test_build_topology_openings_are_the_eye_and_mouth_rings(resolution):
    topo = build_topology(resolution)
    per_eye, u_eye = eye_ring_params(resolution)
    per_mouth, u_mouth = mouth_ring_params(resolution)
    assert topo.eye_L.index.shape == topo.eye_R.index.shape == (len(u_eye), per_eye)
    assert topo.mouth.index.shape == (len(u_mouth), per_mouth)
    loops = boundary_loops(topo.faces)
    assert sorted(len(loop) for loop in loops) == sorted([per_eye, per_eye, per_mouth])
    assert sorted(map(frozenset, (loop.tolist() for loop in loops)), key=min) == sorted(
        (frozenset(r.index[0].tolist()) for r in (topo.eye_L, topo.eye_R, topo.mouth)), key=min
    )
    # the innermost rings are the holes' edges: the conjunctiva skirt (u < 0) and the inner lip
    assert topo.eye_L.u[0] < 0 and topo.mouth.u[0] == -1.0
    rings = np.concatenate([r.index.ravel() for r in (topo.eye_L, topo.eye_R, topo.mouth)])
    assert len(np.unique(rings)) == len(rings), "the ring sets overlap"
    is_ring = np.zeros(topo.n_vertices, bool)
    is_ring[rings] = True
    assert np.array_equal(~np.isnan(topo.ring_uv[:, 0]), is_ring)


@pytest.mark.parametrize("resolution", [2_500, 10_000])
def test_build_topology_mirror_is_an_involution_over_mirrored_directions(resolution):
    topo = build_topology(resolution)
    mirror, n = topo.mirror, topo.n_vertices
    assert mirror.shape == (n,) and mirror.dtype == np.int64
    assert np.array_equal(np.sort(mirror), np.arange(n)), "the mirror map is a permutation"
    assert np.array_equal(mirror[mirror], np.arange(n))
    assert np.array_equal(mirror[topo.eye_L.index], topo.eye_R.index)
    assert set(mirror[topo.mouth.index.ravel()].tolist()) == set(topo.mouth.index.ravel().tolist())
    fill = np.isnan(topo.ring_uv[:, 0])
    np.testing.assert_array_equal(topo.directions[mirror][fill], (topo.directions * FLIP_X)[fill])
    centre = mirror == np.arange(n)
    assert np.all(topo.directions[centre & fill, 0] == 0.0), "self-mirror vertices lie on x = 0"


@pytest.mark.parametrize("resolution", [2_500, 10_000])
def test_build_topology_mirror_maps_faces_to_faces(resolution):
    topo = build_topology(resolution)
    mirrored = topo.mirror[topo.faces][:, ::-1]  # reversed: mirroring flips winding
    assert mirrored.shape == topo.faces.shape and mirrored.dtype == np.int64
    faces = {tuple(f) for f in canonical_faces(topo.faces).tolist()}
    missing = np.array([tuple(f) not in faces for f in canonical_faces(mirrored).tolist()])
    # canonical_faces sorts rows, so report by vertex membership rather than by face index
    lips = np.isin(canonical_faces(mirrored), topo.mouth.index).all(axis=1)
    assert not missing.any(), (
        f"{missing.sum()} of {len(missing)} mirrored faces are not faces "
        f"({(missing & lips).sum()} of them in the mouth rings)"
    )


@pytest.mark.parametrize("resolution", [2_000, 10_000, 100_000])
def test_build_topology_vertex_count_is_near_the_requested_resolution(resolution):
    n = build_topology(resolution).n_vertices
    assert abs(n - resolution) <= 0.15 * resolution, f"{n} skin vertices for resolution={resolution}"


@pytest.mark.parametrize("resolution", [0, -5, 1_000, 1_499, 250_001, 1_000_000])
def test_build_topology_resolution_out_of_range_raises(resolution):
    with pytest.raises(ValueError, match="resolution"):
        build_topology(resolution)


def test_make_head_resolution_out_of_range_raises():
    with pytest.raises(ValueError, match="resolution"):
        make_head(resolution=1_000)
