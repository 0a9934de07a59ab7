"""rig_head on messy exports of a known head: unwelded seams, a triangle soup, a reversed patch.

Each case is a generated head made messy the way real exports are (``mimetic.testing``), rigged
from its own landmarks, and compared with the clean head's rig: the user's vertex order and count
come back, coincident copies move together in every library expression, and the fix is said.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from mimetic.animate.expressions import expression_pose, load_library
from mimetic.engines import make_engine
from mimetic.errors import MimeticWarning
from mimetic.fit.pipeline import rig_head
from mimetic.mesh.weld import find_weld
from mimetic.mesh.winding import winding_flips
from mimetic.testing import (
    cheek_centre,
    head_landmarks,
    patch_faces,
    small_head,
    triangle_soup,
    unwelded_patch,
)

EXPRESSIONS = ("joy", "surprise", "anger", "pucker", "jaw_drop")


@pytest.fixture(scope="module")
def head():
    return small_head(2)


@pytest.fixture(scope="module")
def clean(head):
    return rig_head(head.mesh, head_landmarks(head))


def _edge_stretch(faces: np.ndarray, rest: np.ndarray, posed: np.ndarray) -> np.ndarray:
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    before = np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)
    after = np.linalg.norm(posed[edges[:, 0]] - posed[edges[:, 1]], axis=1)
    return after / np.maximum(before, 1e-12)


@pytest.mark.parametrize("engine_name", ["wire", "vector"])
def test_an_unwelded_cheek_patch_moves_as_one_surface(head, clean, engine_name):
    mesh = unwelded_patch(head.mesh, cheek_centre(head))
    with pytest.warns(MimeticWarning, match="unwelded seams"):
        result = rig_head(mesh, head_landmarks(head))
    rig = result.rig
    assert rig.n_vertices == mesh.n_vertices
    assert result.welded == clean.welded + mesh.n_vertices - head.mesh.n_vertices  # the rim merges in both
    np.testing.assert_array_equal(rig.mesh.vertices, mesh.vertices)
    np.testing.assert_array_equal(rig.mesh.faces, mesh.faces)
    groups = find_weld(mesh).groups()
    for group in groups:  # copies carry the same skin weights, so a skinned export moves them together
        rows = rig.skin_weights[group].toarray()
        np.testing.assert_array_equal(rows, np.broadcast_to(rows[0], rows.shape))
    engine, reference = make_engine(rig, engine_name), make_engine(clean.rig, engine_name)
    patch = patch_faces(mesh, cheek_centre(head), 2.0)
    for name in EXPRESSIONS:
        values = expression_pose(rig, name)
        posed = engine.deform(values)
        gap = max(np.linalg.norm(posed[g] - posed[g[0]], axis=1).max() for g in groups)
        assert gap < 1e-12 * rig.scale, f"{name}: copies of one vertex part by {gap:.3g} cm"
        # and the patch deforms as the clean head's cheek does there
        clean_pose = reference.deform(values)
        np.testing.assert_allclose(posed[: head.mesh.n_vertices], clean_pose, atol=1e-3 * rig.scale)
        stretch = _edge_stretch(mesh.faces[patch], mesh.vertices, posed)
        clean_stretch = _edge_stretch(head.mesh.faces[patch], head.mesh.vertices, clean_pose)
        assert stretch.max() < clean_stretch.max() + 0.01, f"{name}: the patch stretches {stretch.max():.2f}x"


def test_a_triangle_soup_rigs_and_keeps_every_vertex(head):
    soup = triangle_soup(head.mesh)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", MimeticWarning)
        result = rig_head(soup, head_landmarks(head))
    rig = result.rig
    assert result.report.accepted and rig.n_vertices == soup.n_vertices
    np.testing.assert_array_equal(rig.mesh.faces, soup.faces)
    posed = make_engine(rig, "wire").deform(expression_pose(rig, "joy"))
    welded = find_weld(soup)
    # each welded vertex's copies all sit at one place: the soup still closes after the pose
    spread = np.linalg.norm(posed - posed[welded.first][welded.index], axis=1)
    assert np.isfinite(posed).all() and spread.max() < 1e-12 * rig.scale  # (float rounding only)
    assert np.linalg.norm(posed - soup.vertices, axis=1).max() > 0.005 * rig.scale  # and it does smile


def test_a_reversed_patch_is_turned_back_with_a_warning(head, clean):
    patch = patch_faces(head.mesh, cheek_centre(head), 2.0)
    faces = head.mesh.faces.copy()
    faces[patch] = faces[patch, ::-1]
    mesh = type(head.mesh)(head.mesh.vertices, faces, head.mesh.parts, head.mesh.colors, head.mesh.units)
    with pytest.warns(MimeticWarning, match=f"{len(patch)} faces wind against their neighbours"):
        result = rig_head(mesh, head_landmarks(head))
    assert result.reversed_faces == len(patch)
    np.testing.assert_array_equal(result.rig.mesh.faces, head.mesh.faces)
    assert not winding_flips(result.rig.mesh.vertices, result.rig.mesh.faces).any()


def test_library_expressions_all_run_on_the_welded_rig(head):
    result = rig_head(unwelded_patch(head.mesh, cheek_centre(head)), head_landmarks(head))
    engine = make_engine(result.rig, "wire")
    for name in load_library().names:
        assert np.isfinite(engine.deform(expression_pose(result.rig, name))).all()
