"""Tests for mimetic.view.drawing: 2D drawing, 3D segment overlays, contact sheets, PNG saving."""

from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from mimetic.view import Camera, contact_sheet, draw_lines, draw_points, overlay_segments, project, save_png

GREY = 40


def blank(h: int = 40, w: int = 60) -> np.ndarray:
    return np.full((h, w, 3), GREY, np.uint8)


def test_draw_lines_colours_the_pixels_along_the_segment_and_keeps_input():
    image = blank()
    out = draw_lines(image, np.array([[[10.5, 20.5], [50.5, 20.5]]]), (1.0, 0.0, 0.0), width=1)
    assert out.shape == image.shape and out.dtype == np.uint8
    assert (image == GREY).all()  # input untouched
    np.testing.assert_array_equal(out[20, 10:51], np.tile([255, 0, 0], (41, 1)))
    assert (out[19] == GREY).all() and (out[21] == GREY).all() and (out[20, :10] == GREY).all()


def test_draw_lines_and_points_skip_nan():
    image = blank()
    out = draw_lines(image, np.array([[[np.nan, 1.0], [5.0, 5.0]]]), width=3)
    out = draw_points(out, np.array([[np.nan, 3.0]]))
    np.testing.assert_array_equal(out, image)


def test_draw_points_fills_discs_with_per_point_colours():
    out = draw_points(blank(), np.array([[10.5, 10.5], [40.5, 30.5]]), [[0, 1, 0], [0, 0, 1]], radius=2)
    np.testing.assert_array_equal(out[10, 10], [0, 255, 0])
    np.testing.assert_array_equal(out[30, 40], [0, 0, 255])
    assert (out[20, 25] == GREY).all()
    with pytest.raises(ValueError, match="colors"):
        draw_points(blank(), np.zeros((2, 2)), [[0, 1, 0]] * 3)


def test_overlay_segments_draws_projected_segments_and_skips_behind_camera():
    camera = Camera(eye=(0, 0, 3), target=(0, 0, 0))
    segments = np.array([[[-0.5, 0.2, 0.0], [0.5, 0.2, 0.0]], [[0.0, 0.0, 0.0], [0.0, 0.0, 4.0]]])
    out = overlay_segments(blank(80, 100), camera, segments, (0.0, 1.0, 1.0), labels=["a", "behind"], width=1)
    ends = project(segments[0], camera, (100, 80)).pixels
    y = int(ends[0, 1])
    assert (out[y, int(ends[0, 0]) + 3 : int(ends[1, 0]) - 3] == [0, 255, 255]).all()
    changed = np.flatnonzero((out != GREY).any(axis=2).any(axis=1))
    assert changed.min() >= y - 6 and changed.max() <= y + 6  # nothing from the 2nd segment
    with pytest.raises(ValueError, match="labels"):
        overlay_segments(blank(), camera, segments, labels=["one"])


def test_contact_sheet_lays_out_tiles_and_labels_in_a_grid():
    tiles = [(f"tile {k}", np.full((30, 40, 3), 60 * (k + 1), np.uint8)) for k in range(3)]
    sheet = contact_sheet(tiles, columns=2, label_height=20, background=(0, 0, 0))
    assert sheet.shape == (2 * (30 + 20), 2 * 40, 3) and sheet.dtype == np.uint8
    for k in range(3):
        r, c = divmod(k, 2)
        tile = sheet[r * 50 : r * 50 + 30, c * 40 : (c + 1) * 40]
        assert (tile == 60 * (k + 1)).all()
        strip = sheet[r * 50 + 30 : r * 50 + 50, c * 40 : (c + 1) * 40]
        assert (strip > 128).any(), f"no label text under tile {k}"
    assert (sheet[50:, 40:] == 0).all()  # the 4th cell is empty


def test_contact_sheet_centres_smaller_tiles_and_rejects_empty():
    big, small = np.full((20, 20, 3), 200, np.uint8), np.full((10, 10), 100, np.uint8)
    sheet = contact_sheet([("big", big), ("", small)], 5)
    assert sheet.shape == (20 + 24, 40, 3)
    assert (sheet[5:15, 25:35] == 100).all() and (sheet[0:5, 20:40] != 100).all()
    with pytest.raises(ValueError, match="at least one"):
        contact_sheet([], 2)


def test_save_png_round_trips_and_replaces_atomically(tmp_path):
    rng = np.random.default_rng(3)
    image = rng.integers(0, 256, (17, 23, 3), dtype=np.uint8)
    path = save_png(image, tmp_path / "out.png")
    assert path == tmp_path / "out.png"
    np.testing.assert_array_equal(np.asarray(Image.open(path)), image)
    save_png(image[::-1], path)  # overwrite in place
    np.testing.assert_array_equal(np.asarray(Image.open(path)), image[::-1])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.png"]  # no temp files left
    with pytest.raises(ValueError, match="uint8"):
        save_png(image.astype(np.float32), tmp_path / "bad.png")
    assert not (tmp_path / "bad.png").exists()


def test_draw_lines_clips_far_off_screen_endpoints():
    # Points just in front of the camera project to huge coordinates; the visible part must stay right.
    out = draw_lines(blank(), np.array([[[10.5, 10.5], [1e12, 0.3e12]]]), (1.0, 0.0, 0.0), width=1)
    ys, xs = np.nonzero((out != GREY).any(axis=2))
    assert xs.min() == 10 and xs.max() == 59
    np.testing.assert_allclose(ys + 0.5, 10.5 + 0.3 * (xs + 0.5 - 10.5), atol=1.0)


def test_save_png_failure_keeps_the_previous_file(tmp_path, monkeypatch):
    path = save_png(np.zeros((4, 4, 3), np.uint8), tmp_path / "keep.png")
    before = path.read_bytes()

    def broken_save(self, fp, *args, **kwargs):
        fp.write(b"half a png")
        raise OSError("disk full")

    monkeypatch.setattr(Image.Image, "save", broken_save)
    with pytest.raises(OSError, match="disk full"):
        save_png(np.ones((4, 4, 3), np.uint8), path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.png"]
