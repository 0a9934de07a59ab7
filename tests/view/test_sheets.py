"""Muscle and expression sheets: face framing, tile counts, and tiles that show a face."""

from __future__ import annotations

import numpy as np
import pytest

from mimetic.animate.expressions import load_library
from mimetic.engines import make_engine
from mimetic.render import raster
from mimetic.render.camera import VIEWS, project
from mimetic.rig.activations import pose
from mimetic.testing import small_rig
from mimetic.view.sheets import (
    expression_sheet,
    face_camera,
    face_points,
    muscle_actions,
    muscle_sheet,
    render_pose,
)

SIZE = 64
LABEL = 24  # contact_sheet's label strip
BACKGROUND = tuple(raster.to_uint8(np.asarray(raster.BACKGROUND, dtype=np.float64)))


@pytest.fixture(scope="module")
def rig():
    return small_rig()


def _cells(sheet: np.ndarray, n: int, columns: int, size: int) -> list[np.ndarray]:
    """The n tiles (size, size, 3) of a contact sheet laid out by ``contact_sheet``."""
    cells = []
    for k in range(n):
        r, c = divmod(k, columns)
        top = r * (size + LABEL)
        cells.append(sheet[top : top + size, c * size : (c + 1) * size])
    return cells


def _face_fraction(tile: np.ndarray) -> float:
    """Fraction of a tile's pixels that are not the render background."""
    return float(np.mean(np.any(tile != np.array(BACKGROUND, dtype=np.uint8), axis=-1)))


@pytest.mark.parametrize("seed", [None, 3])
@pytest.mark.parametrize("yaw", [0.0, VIEWS["three_quarter"], -VIEWS["three_quarter"], VIEWS["profile"]])
def test_face_camera_frames_the_face_close_up(seed, yaw):
    rig = small_rig(seed)
    camera = face_camera(rig, yaw_deg=yaw)
    pixels = project(face_points(rig), camera, 512).pixels  # (k, 2)
    assert np.isfinite(pixels).all()
    assert pixels.min() >= 0 and pixels.max() <= 512  # every face point in the image
    landmarks = project(rig.landmark_positions(["menton", "brow_mid_L", "brow_mid_R"]), camera, 512).pixels
    assert np.all((landmarks > 10) & (landmarks < 502))  # with a margin
    height = pixels[:, 1].max() - pixels[:, 1].min()
    assert height > 0.6 * 512  # a close-up: chin to brows fills most of the frame


def test_muscle_actions_cover_every_muscle_and_the_bones(rig):
    actions = muscle_actions(rig)
    assert actions[0].label == "rest" and not actions[0].values
    labels = [a.label for a in actions]
    assert set(rig.muscle_names) <= set(labels)
    assert {"cheek_puff_L", "orbicularis_oris_marginalis_upper", "tongue_out"} <= set(labels)
    tongue = next(a for a in actions if a.label == "tongue_out")
    assert tongue.values["jaw_open"] > 0  # the tongue shows between open teeth
    assert {"jaw_open", "eyelids closed", "gaze left", "gaze up"} <= set(labels)
    for action in actions:
        pose(rig, action.values)  # every value is a valid channel value
    sides = {a.label: a.side for a in actions}
    assert sides["zygomatic_major_L"] == "L" and sides["corrugator_R"] == "R" and sides["procerus"] is None


@pytest.mark.parametrize("engine_name", ["wire", "vector"])
def test_muscle_sheet_has_a_face_tile_per_action_and_view(rig, gl_renderer, engine_name):
    actions = muscle_actions(rig)
    columns = 8
    sheet = muscle_sheet(rig, engine_name, size=SIZE, columns=columns, renderer=gl_renderer)
    n = 2 * len(actions)
    rows = -(-n // columns)
    assert sheet.dtype == np.uint8 and sheet.shape == (rows * (SIZE + LABEL), columns * SIZE, 3)
    cells = _cells(sheet, n, columns, SIZE)
    for k, cell in enumerate(cells):
        assert _face_fraction(cell) > 0.4, f"tile {k} ({actions[k // 2].label}) is nearly blank"
    rest_front = cells[0]
    moved = [not np.array_equal(cells[2 * k], rest_front) for k in range(1, len(actions))]
    assert sum(moved) >= 0.9 * len(moved)  # (nearly) every action changes the picture


def test_expression_sheet_has_rest_and_every_expression(rig, gl_renderer):
    library = load_library()
    engine = make_engine(rig, "vector")
    views = ("front", "three_quarter")
    sheet = expression_sheet(rig, engine, library, size=SIZE, views=views, renderer=gl_renderer)
    n = (1 + len(library)) * len(views)
    columns = 4 * len(views)
    assert sheet.shape == (-(-n // columns) * (SIZE + LABEL), columns * SIZE, 3)
    cells = _cells(sheet, n, columns, SIZE)
    assert all(_face_fraction(c) > 0.4 for c in cells)
    assert not any(np.array_equal(cells[0], cells[2 * (k + 1)]) for k in range(len(library)))


def test_render_pose_single_view_and_all_views(rig, gl_renderer):
    values = pose(rig, {"jaw_open": 0.3})
    one = render_pose(rig, "wire", values, view="front", size=SIZE, renderer=gl_renderer)
    assert one.shape == (SIZE, SIZE, 3) and one.dtype == np.uint8
    every = render_pose(rig, "wire", values, view="all", size=SIZE, renderer=gl_renderer)
    assert every.shape == (SIZE + LABEL, 3 * SIZE, 3)
    with pytest.raises(ValueError, match="unknown view"):
        render_pose(rig, "wire", values, view="top", size=SIZE, renderer=gl_renderer)
