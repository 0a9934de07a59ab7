"""Tests for mimetic.mesh.weld: unwelded seams found and merged, and nothing else merged."""

from __future__ import annotations

import numpy as np

from mimetic.mesh.model import Mesh
from mimetic.mesh.weld import coincident_groups, find_weld
from mimetic.testing import cheek_centre, small_head, triangle_soup, unwelded_patch


def _same_surface(a: Mesh, b: Mesh) -> bool:
    """Whether two meshes have the same triangles (as sets of corner positions), whatever the numbering."""

    def keys(mesh: Mesh) -> np.ndarray:
        corners = np.round(mesh.vertices[mesh.faces], 9)  # (m, 3, 3)
        order = np.lexsort(corners.transpose(2, 0, 1)[::-1], axis=1)
        return np.sort(
            np.take_along_axis(corners, order[..., None], axis=1).reshape(len(corners), -1), axis=0
        )

    return a.n_faces == b.n_faces and np.array_equal(keys(a), keys(b))


def test_find_weld_of_a_clean_skin_merges_nothing():
    skin, _ = small_head().mesh.submesh("skin")
    weld = find_weld(skin)
    assert weld.n_merged == 0 and weld.mesh is skin and weld.groups() == []
    np.testing.assert_array_equal(weld.index, np.arange(skin.n_vertices))


def test_find_weld_closes_an_unwelded_patch_back_into_the_original_mesh():
    head = small_head()
    skin, _ = head.mesh.submesh("skin")
    cut = unwelded_patch(skin, cheek_centre(head))
    copies = cut.n_vertices - skin.n_vertices
    assert copies > 10
    weld = find_weld(cut)
    assert weld.n_merged == copies and len(weld.groups()) == copies
    assert weld.mesh.n_vertices == skin.n_vertices
    np.testing.assert_array_equal(weld.mesh.vertices, skin.vertices)  # the first copy of each is kept
    np.testing.assert_array_equal(weld.mesh.faces, skin.faces)  # the patch's faces use the originals again
    np.testing.assert_array_equal(cut.vertices[weld.first], weld.mesh.vertices)
    np.testing.assert_array_equal(weld.mesh.vertices[weld.index], cut.vertices)  # every copy maps home


def test_find_weld_rebuilds_a_triangle_soup(sphere, torus):
    """(A soup of a head with closed lips welds the lips too: a soup keeps no trace of two sheets.)"""
    for mesh in (sphere, torus):
        weld = find_weld(triangle_soup(mesh))
        assert weld.mesh.n_vertices == mesh.n_vertices and weld.mesh.n_faces == mesh.n_faces
        assert _same_surface(weld.mesh, mesh)
        np.testing.assert_array_equal(weld.faces, np.arange(mesh.n_faces))


def test_find_weld_keeps_closed_lips_apart():
    """The generated lips touch along a line of interior vertices (two sheets that must part): not a seam."""
    head = small_head()
    weld = find_weld(head.mesh)
    upper, lower = head.regions["upper_lip"], head.regions["lower_lip"]
    touching = (
        np.linalg.norm(head.mesh.vertices[upper][:, None] - head.mesh.vertices[lower][None], axis=2) < 1e-9
    )
    assert touching.sum() >= 5  # the lips do touch at rest
    assert not np.intersect1d(weld.index[upper], weld.index[lower]).size  # and stay separate vertices


def test_find_weld_drops_collapsed_faces_and_maps_faces_both_ways():
    vertices = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 0, 0], [1, 1, 0], [1, 1e-12, 0]])
    faces = np.array([[0, 1, 2], [3, 4, 2], [1, 5, 4]])  # the last face collapses once 1, 3, 5 merge
    weld = find_weld(Mesh(vertices, faces, {"a": [0, 2], "b": [1]}))
    np.testing.assert_array_equal(weld.index, [0, 1, 2, 1, 3, 1])
    np.testing.assert_array_equal(weld.faces, [0, 1])
    np.testing.assert_array_equal(weld.face_of([0, 1, 2]), [0, 1, -1])
    assert {k: v.tolist() for k, v in weld.mesh.parts.items()} == {"a": [0], "b": [1]}


def test_coincident_groups_of_many_copies_of_one_point_stay_linear():
    """A soup of a scan repeats a collapsed corner (a fan of degenerate faces, a film's pole) many
    times over: 20,000 copies of one point would be 2·10⁸ pairs; grouped exactly first they are one."""
    rng = np.random.default_rng(0)
    pole = np.zeros((20_000, 3))
    others = rng.uniform(1.0, 2.0, (100, 3))
    near = others[:10] + 1e-7  # within tol of the first ten: merged with them
    vertices = np.concatenate([others, pole, near])
    label = coincident_groups(vertices, np.arange(len(vertices)), 1e-6)
    assert (label[100:20_100] == 100).all()  # the pole's copies: the lowest index among them
    np.testing.assert_array_equal(label[20_100:], np.arange(10))
    np.testing.assert_array_equal(label[:100], np.arange(100))
