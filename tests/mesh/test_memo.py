"""``mesh.memo``: results kept for read-only arrays while they live, never for writeable ones."""

from __future__ import annotations

import gc

import numpy as np
import pytest

from mimetic.mesh import memo
from mimetic.mesh.geometry import edges_with_counts, face_normals
from mimetic.mesh.model import Mesh
from mimetic.testing import tetrahedron


def _counted():
    calls = []

    @memo.per_arrays(1)
    def double(array: np.ndarray, factor: int = 2) -> np.ndarray:
        calls.append(1)
        return array * factor

    return double, calls


def test_per_arrays_remembers_a_read_only_array_and_hands_out_read_only_results():
    double, calls = _counted()
    array = np.arange(4.0)
    array.setflags(write=False)
    first, second = double(array), double(array)
    assert first is second and len(calls) == 1
    assert not first.flags.writeable
    np.testing.assert_array_equal(first, [0.0, 2.0, 4.0, 6.0])
    double(array, 3)  # another value of the other arguments: computed again
    assert len(calls) == 2


def test_per_arrays_never_remembers_a_writeable_array_or_a_view_of_one():
    double, calls = _counted()
    array = np.arange(4.0)
    double(array)
    array[0] = 10.0
    np.testing.assert_array_equal(double(array), [20.0, 2.0, 4.0, 6.0])
    view = array[:2]
    view.setflags(write=False)  # read-only, but its memory can still change through ``array``
    assert not memo.frozen(view)
    double(view)
    double(view)
    assert len(calls) == 4


def test_per_arrays_forgets_an_array_that_is_gone():
    double, _ = _counted()
    array = np.arange(4.0)
    array.setflags(write=False)
    double(array)
    key = (double.__wrapped__, id(array))
    assert key in memo._results
    del array
    gc.collect()
    assert key not in memo._results


def test_a_mesh_s_edges_are_found_once_and_cannot_be_changed():
    mesh = tetrahedron()
    edges, counts = edges_with_counts(mesh.faces)
    again = edges_with_counts(mesh.faces)
    assert again[0] is edges and again[1] is counts
    with pytest.raises(ValueError, match="read-only"):
        edges[0, 0] = 7
    fresh = edges_with_counts(np.array(mesh.faces))  # a writeable copy: computed, equal
    np.testing.assert_array_equal(fresh[0], edges)


def test_remembered_normals_are_fresh_copies():
    mesh = Mesh(tetrahedron().vertices, tetrahedron().faces)
    a, b = face_normals(mesh.vertices, mesh.faces), face_normals(mesh.vertices, mesh.faces)
    assert a is not b and a.flags.writeable
    a[:] = 0.0  # the caller's own array
    np.testing.assert_array_equal(face_normals(mesh.vertices, mesh.faces), b)
    np.testing.assert_array_equal(b, face_normals(np.array(mesh.vertices), np.array(mesh.faces)))


def test_per_arrays_computes_anew_when_an_option_is_not_a_value():
    """An array passed as an option (``skin_faces(..., labels=labels)``) is not a key: no error, no entry."""
    from mimetic.mesh.geometry import connected_components
    from mimetic.mesh.openings import skin_faces

    mesh = Mesh(np.array(tetrahedron().vertices), np.array(tetrahedron().faces))  # arrays of its own
    _, labels = connected_components(np.array(mesh.faces), mesh.n_vertices)
    np.testing.assert_array_equal(skin_faces(mesh.vertices, mesh.faces, labels=labels), mesh.faces)
    mine = (skin_faces.__wrapped__, id(mesh.vertices), id(mesh.faces))
    assert not any(key[:3] == mine for key in memo._results)
