"""Tests for mimetic.mesh.winding: a reversed patch is found exactly, consistent meshes are left alone."""

from __future__ import annotations

import numpy as np

from mimetic.mesh.winding import winding_flips
from mimetic.testing import cheek_centre, patch_faces, small_head, tetrahedron, triangle_soup


def test_winding_flips_of_consistent_meshes_are_empty():
    for mesh in (tetrahedron(), small_head().mesh, triangle_soup(tetrahedron())):
        flips = winding_flips(mesh.vertices, mesh.faces)
        assert flips.shape == (mesh.n_faces,) and flips.dtype == bool and not flips.any()


def test_winding_flips_find_exactly_a_reversed_patch():
    head = small_head()
    patch = patch_faces(head.mesh, cheek_centre(head), 2.0)
    faces = head.mesh.faces.copy()
    faces[patch] = faces[patch, ::-1]
    before = faces.copy()
    flips = winding_flips(head.mesh.vertices, faces)
    np.testing.assert_array_equal(np.flatnonzero(flips), patch)
    np.testing.assert_array_equal(faces, before)  # the input is not modified


def test_winding_flips_turn_the_smaller_side_of_each_piece():
    mesh = tetrahedron()
    faces = mesh.faces.copy()
    faces[:3] = faces[:3, ::-1]  # three of four reversed: turning the fourth is the smaller change
    flips = winding_flips(mesh.vertices, faces)
    assert flips.sum() == 1
    fixed = np.where(flips[:, None], faces[:, ::-1], faces)
    assert not winding_flips(mesh.vertices, fixed).any()
