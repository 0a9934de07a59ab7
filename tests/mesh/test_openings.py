"""The openings of a head seen from the front (``mimetic.mesh.openings``): synthetic openings with
known margins, and ICT-FaceKit's eyes and mouth checked against its own captured shapes (the
margins found must be the ones its blink closes and its jaw drop parts)."""

from __future__ import annotations

import numpy as np
import pytest

from mimetic.mesh.openings import (
    eye_opening,
    margin_seeds,
    mouth_opening,
    opening_sides,
    skin_faces,
    without_pits,
)
from mimetic.testing import ict_expressions, load_ict, require_shared_data

A, B = 1.5, 0.5  # the synthetic eye hole's half width and half height


def holed_plane(hole) -> tuple[np.ndarray, np.ndarray]:
    """A 6 × 4 plane at z = 0 (+Z toward the viewer), 0.05 grid, without the faces whose centre is
    inside ``hole(x, y) -> bool``."""
    x, y = np.meshgrid(np.linspace(-3, 3, 121), np.linspace(-2, 2, 81))
    vertices = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    i = np.arange(80)[:, None] * 121 + np.arange(120)[None]
    quads = np.stack([i, i + 1, i + 122, i + 121], axis=-1).reshape(-1, 4)
    faces = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    centre = vertices[faces].mean(axis=1)
    return vertices, faces[~hole(centre[:, 0], centre[:, 1])]


def ellipse(x, y):
    return (x / A) ** 2 + (y / B) ** 2 < 1


def test_an_elliptic_hole_is_an_eye_opening_with_its_margins_at_top_and_bottom():
    vertices, faces = holed_plane(ellipse)
    opening = eye_opening(vertices, faces, np.array([[-A, 0, 0], [A, 0, 0]]))
    assert opening is not None
    middle = np.argmin(np.abs(opening.upper[:, 0]))
    assert opening.upper[middle, 1] == pytest.approx(B, abs=0.1)
    assert opening.lower[middle, 1] == pytest.approx(-B, abs=0.1)
    assert opening.width == pytest.approx(2 * A, rel=0.1)
    # the margin vertices are the hole's rim, split by the nearer margin
    upper, lower = margin_seeds(vertices, faces, opening, 0.1)
    assert len(upper) > 10 and len(lower) > 10
    assert (vertices[upper, 1] > -0.05).all() and (vertices[lower, 1] < 0.05).all()


def test_a_ray_lost_between_two_triangles_is_filled_but_a_hole_is_not():
    z = np.full((6, 7), 2.0)
    z[2, 3] = np.nan  # one ray that missed: every neighbour was hit
    z[0, 6] = -5.0  # one ray that saw far behind, on the map's corner
    z[4, 1:3] = np.nan  # a hole two rays across
    filled = without_pits(z)
    assert filled[2, 3] == 2.0 and filled[0, 6] == 2.0
    assert np.isnan(filled[4, 1:3]).all()
    assert np.isnan(filled).sum() == 2 and (filled[~np.isnan(filled)] == 2.0).all()


def test_a_plane_without_a_hole_has_no_eye_opening():
    vertices, faces = holed_plane(lambda x, y: np.zeros_like(x, dtype=bool))
    assert eye_opening(vertices, faces, np.array([[-A, 0, 0], [A, 0, 0]])) is None


def test_opening_sides_split_the_surface_by_the_nearer_margin():
    vertices, faces = holed_plane(ellipse)
    opening = eye_opening(vertices, faces, np.array([[-A, 0, 0], [A, 0, 0]]))
    upper, lower = margin_seeds(vertices, faces, opening, 0.1)
    side = opening_sides(vertices, faces, upper, lower, reach=0.8)
    near = np.linalg.norm(vertices[:, :2], axis=1) < 1.0  # around the middle, within reach
    above = near & (vertices[:, 1] > B + 0.05)
    below = near & (vertices[:, 1] < -B - 0.05)
    assert above.any() and below.any()
    assert (side[above] == 1).all() and (side[below] == -1).all()
    assert (side[np.abs(vertices[:, 0]) > 2.8] == 0).all()  # beyond reach of both


def closed_lips() -> tuple[np.ndarray, np.ndarray]:
    """Two lips bulging toward the viewer, meeting along y = 0 between the corners x = ±2: a 6 × 3
    sheet, 0.05 grid."""
    x, y = np.meshgrid(np.linspace(-3, 3, 121), np.linspace(-1.5, 1.5, 61))
    lip = np.clip(1 - (x / 2) ** 2, 0, None) * 0.3 * np.exp(-((np.abs(y) - 0.4) ** 2) / 0.05)
    vertices = np.column_stack([x.ravel(), y.ravel(), lip.ravel()])
    i = np.arange(60)[:, None] * 121 + np.arange(120)[None]
    quads = np.stack([i, i + 1, i + 122, i + 121], axis=-1).reshape(-1, 4)
    return vertices, np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])


def test_closed_lips_are_found_as_a_valley_between_two_bulges():
    vertices, faces = closed_lips()
    opening = mouth_opening(vertices, faces, np.array([[-2.0, 0, 0], [2.0, 0, 0]]))
    assert opening is not None
    assert np.abs(opening.upper[:, 1]).max() <= 0.1
    assert opening.upper[0, 0] < -1.0 and opening.upper[-1, 0] > 1.0


def test_lips_parted_over_a_cavity_have_their_margins_on_the_lips_not_on_the_cavity():
    # the lips above, parted by a slit over the left half of the mouth that shows a wall 8 units
    # behind them (a mouth's cavity): the margins there are the slit's edges, on the lips
    vertices, grid = closed_lips()
    centre = vertices[grid].mean(axis=1)
    lips = grid[~((np.abs(centre[:, 1]) < 0.1) & (centre[:, 0] < 0.0))]
    wall = vertices.copy()
    wall[:, 2] = -8.0
    vertices = np.concatenate([vertices, wall])
    faces = np.concatenate([lips, grid + len(wall)])
    opening = mouth_opening(vertices, faces, np.array([[-2.0, 0, 0], [2.0, 0, 0]]))
    assert opening is not None
    assert opening.width == pytest.approx(4.0, rel=0.1)
    assert (opening.upper[:, 2] > -0.5).all() and (opening.lower[:, 2] > -0.5).all()
    slit = opening.upper[:, 0] < -0.5
    assert (opening.upper[slit, 1] > 0.05).all() and (opening.lower[slit, 1] < -0.05).all()
    assert np.abs(opening.upper[~slit & (opening.upper[:, 0] > 0.5), 1]).max() <= 0.1


# --------------------------------------------------------------------------- ICT-FaceKit

IBUG_EYES = {"L": (42, 45), "R": (39, 36)}  # (inner, outer) corners; the subject's left is +x
IBUG_MOUTH = (48, 54)


@pytest.fixture(scope="module")
def ict():
    folder = require_shared_data("ict-facekit")
    mesh, meta = load_ict(folder)
    names, deltas = ict_expressions(folder)
    ids = np.asarray(meta["landmarks_68"]["vertex_indices"])
    skin = skin_faces(mesh.vertices, mesh.faces)
    return mesh, dict(zip(names, deltas, strict=True)), ids, skin


def column_gap(upper: np.ndarray, lower: np.ndarray) -> float:
    """Median vertical gap between two point sets (k, 3) over their common x range."""
    x = np.linspace(max(upper[:, 0].min(), lower[:, 0].min()), min(upper[:, 0].max(), lower[:, 0].max()), 9)
    up = upper[np.argsort(upper[:, 0])]
    lo = lower[np.argsort(lower[:, 0])]
    return float(np.median(np.interp(x[2:-2], up[:, 0], up[:, 1]) - np.interp(x[2:-2], lo[:, 0], lo[:, 1])))


@pytest.mark.parametrize("side", ["L", "R"])
def test_ict_eye_margins_are_the_ones_its_captured_blink_closes(ict, side):
    mesh, shapes, ids, skin = ict
    V = mesh.vertices
    corners = V[ids[list(IBUG_EYES[side])]]
    opening = eye_opening(V, skin, corners)
    assert opening is not None
    upper, lower = margin_seeds(V, skin, opening, 0.03 * opening.width)
    assert len(upper) >= 5 and len(lower) >= 5
    rest = column_gap(V[upper], V[lower])
    assert 0.5 < rest < 1.5  # cm: an open human eye
    blink = V + shapes[f"eyeBlink_{side}"]
    assert abs(column_gap(blink[upper], blink[lower])) < 0.2 * rest


def test_ict_lip_margins_are_the_ones_its_captured_jaw_drop_parts(ict):
    mesh, shapes, ids, skin = ict
    V = mesh.vertices
    opening = mouth_opening(V, skin, V[ids[list(IBUG_MOUTH)]])
    assert opening is not None
    assert opening.width == pytest.approx(np.linalg.norm(np.subtract(*V[ids[list(IBUG_MOUTH)]])), rel=0.25)
    upper, lower = margin_seeds(V, skin, opening, 0.03 * opening.width)
    assert len(upper) >= 5 and len(lower) >= 5
    jaw = shapes["jawOpen"]
    up_moves = np.linalg.norm(jaw[upper], axis=1)
    low_moves = np.linalg.norm(jaw[lower], axis=1)
    assert np.median(low_moves) > 3 * np.median(up_moves)
    assert column_gap(V[upper] + jaw[upper], V[lower] + jaw[lower]) > 1.0  # cm: the lips part
