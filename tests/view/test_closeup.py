"""Close-ups of the eyes and mouth corners: camera framing and the close-up sheet."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mimetic.animate.expressions import ExpressionLibrary, load_library
from mimetic.engines import make_engine
from mimetic.render import raster
from mimetic.render.camera import project
from mimetic.rig.activations import pose
from mimetic.testing import small_rig
from mimetic.view.sheets import CLOSEUP_HALF_REL, CLOSEUPS, closeup_camera, closeup_sheet

SIZE = 64
LABEL = 24  # contact_sheet's label strip
BACKGROUND = np.array(raster.to_uint8(np.asarray(raster.BACKGROUND, dtype=np.float64)), dtype=np.uint8)
CORNER = ("mouth_corner_L",)
EYE_L = ("eye_outer_corner_L", "eye_inner_corner_L")


@pytest.fixture(scope="module")
def rig():
    return small_rig()


def _jaw_open(rig) -> np.ndarray:
    """Posed vertices (n, 3) of ``rig`` with the jaw fully open."""
    values = pose(rig, {"jaw_open": rig.channel("jaw_open").maximum})
    return make_engine(rig, "vector").deform(values)


@pytest.mark.parametrize("seed", [None, 3])
@pytest.mark.parametrize("names", [CORNER, EYE_L, ("mouth_corner_R",)])
@pytest.mark.parametrize("yaw", [0.0, 20.0, -20.0])
def test_closeup_camera_puts_its_landmarks_at_the_image_centre(seed, names, yaw):
    rig = small_rig(seed)
    camera = closeup_camera(rig, names, yaw_deg=yaw)
    target = rig.landmark_positions(list(names)).mean(axis=0)  # (3,)
    pixels, depth = project(target, camera, 256)
    assert pixels.shape == (2,) and depth > 0
    np.testing.assert_allclose(pixels, [128.0, 128.0], atol=0.5)


def test_closeup_camera_shows_half_rel_of_the_head_height_around_its_target(rig):
    half_rel = CLOSEUP_HALF_REL["eye"]
    camera = closeup_camera(rig, EYE_L, half_rel=half_rel)
    target = rig.landmark_positions(list(EYE_L)).mean(axis=0)
    _, up, _ = camera.basis()
    edges = target + np.outer([1.0, -1.0], half_rel * rig.scale * up)  # (2, 3) top and bottom of the view
    pixels = project(edges, camera, 256).pixels
    np.testing.assert_allclose(pixels[:, 1], [0.0, 256.0], atol=0.5)
    eye_width = np.linalg.norm(np.subtract(*rig.landmark_positions(list(EYE_L))))
    assert 2 * half_rel * rig.scale > 1.2 * eye_width  # the whole eye fits, with a margin


def test_closeup_camera_follows_the_landmark_on_a_posed_mesh(rig):
    posed = _jaw_open(rig)
    camera = closeup_camera(rig, CORNER, vertices=posed)
    face, bary = rig.landmarks[CORNER[0]].face, np.array(rig.landmarks[CORNER[0]].bary)
    moved = bary @ posed[rig.mesh.faces[face]]  # (3,) the corner on the posed mesh
    rest = rig.landmark_positions(list(CORNER))[0]
    assert np.linalg.norm(moved - rest) > 0.01 * rig.scale  # the jaw does move the corner
    np.testing.assert_allclose(project(moved, camera, 256).pixels, [128.0, 128.0], atol=0.5)
    assert np.abs(project(rest, camera, 256).pixels - 128.0).max() > 5.0


def test_closeup_camera_frames_the_same_view_in_any_units(rig):
    """The rig in mm (mesh and scale × 10) sees exactly what the rig in cm sees."""
    mesh_mm = dataclasses.replace(rig.mesh, vertices=10.0 * rig.mesh.vertices, units="mm")
    rig_mm = dataclasses.replace(rig, mesh=mesh_mm, units="mm", scale=10.0 * rig.scale, anatomy=None)
    near = rig.mesh.vertices[
        np.linalg.norm(rig.mesh.vertices - rig.landmark_positions(list(CORNER)), axis=1) < 2
    ]
    assert len(near) > 10
    cm = project(near, closeup_camera(rig, CORNER, yaw_deg=20.0), 256).pixels
    mm = project(10.0 * near, closeup_camera(rig_mm, CORNER, yaw_deg=20.0), 256).pixels
    np.testing.assert_allclose(mm, cm, atol=1e-6)


def test_closeup_camera_names_a_missing_landmark(rig):
    with pytest.raises(KeyError, match="mouth_corner_X"):
        closeup_camera(rig, ("mouth_corner_X",))


def test_closeup_sheet_has_the_face_and_four_closeups_per_pose(rig, gl_renderer):
    full = load_library()
    library = ExpressionLibrary({n: full[n] for n in ("joy", "jaw_drop")})
    before = rig.mesh.vertices.copy()
    sheet = closeup_sheet(rig, "wire", library, size=SIZE, renderer=gl_renderer)
    columns, rows = 1 + len(CLOSEUPS), 1 + len(library)
    assert columns == 5
    assert sheet.dtype == np.uint8 and sheet.shape == (rows * (SIZE + LABEL), columns * SIZE, 3)
    np.testing.assert_array_equal(rig.mesh.vertices, before)
    cells = [
        sheet[r * (SIZE + LABEL) : r * (SIZE + LABEL) + SIZE, c * SIZE : (c + 1) * SIZE]
        for r in range(rows)
        for c in range(columns)
    ]
    skin = [float(np.mean(np.any(cell != BACKGROUND, axis=-1))) for cell in cells]
    assert all(s > 0.4 for s in skin), skin  # every tile shows the head
    assert all(s > max(0.8, skin[0]) for k, s in enumerate(skin) if k % columns), (
        skin
    )  # close-ups: mostly face
    rest, jaw_drop = cells[:columns], cells[2 * columns :]
    for k in range(1, columns):
        assert not np.array_equal(rest[k], rest[0])  # a close-up is not the face tile
    assert not np.array_equal(rest[3], jaw_drop[3])  # the mouth corner moves with the jaw
