"""Trajectory files: exact CSV/TRC round trips, C3D from the c3d package's writer, OpenFace's real
sample (mm, turned into +Y up / +Z toward the camera), the frame-rate and units rules, and bad input."""

from __future__ import annotations

import csv
import dataclasses
import io
import warnings
from pathlib import Path

import c3d
import numpy as np
import pytest

from mimetic.capture.formats import read_trajectories, write_trajectories
from mimetic.capture.trajectories import CaptureError, Trajectories
from mimetic.errors import MimeticWarning
from mimetic.testing import require_shared_data

OPENFACE = "landmarks/OpenFace_Test.csv"


def random_trajectories(
    rng: np.random.Generator, frames: int = 30, points: int = 5, dims: int = 3, units: str | None = "mm"
) -> Trajectories:
    """Gaussian positions (about ±100) with 20 % of the points missing (NaN) and random confidence;
    every point is seen in frame 0, so none is missing throughout."""
    positions = rng.normal(scale=100.0, size=(frames, points, dims))
    missing = rng.random((frames, points)) < 0.2
    missing[0] = False
    positions[missing] = np.nan
    names = (*(f"marker_{j}" for j in range(points - 1)), "L.ear_x")  # a name that ends in an axis
    return Trajectories(names, positions, 59.94, units, rng.random(frames), "synthetic")


def assert_same(read: Trajectories, written: Trajectories, *, confidence: bool = True) -> None:
    assert read.positions.shape == written.positions.shape and read.positions.dtype == np.float64
    assert read.names == written.names
    np.testing.assert_array_equal(read.positions, written.positions)  # exact; NaN where NaN
    assert read.fps == written.fps
    assert read.units == written.units
    if confidence:
        np.testing.assert_array_equal(read.confidence, written.confidence)


def openface_copy(tmp_path: Path, drop=lambda name: False, edit=None) -> Path:
    """The OpenFace sample rewritten to tmp_path without the columns ``drop`` selects (by stripped
    name); ``edit(header, rows)`` may change the rows in place."""
    with open(require_shared_data(OPENFACE), newline="") as handle:
        rows = list(csv.reader(handle))
    keep = [j for j, name in enumerate(rows[0]) if not drop(name.strip())]
    rows = [[row[j] for j in keep] for row in rows]
    if edit is not None:
        edit([c.strip() for c in rows[0]], rows[1:])
    path = tmp_path / "openface.csv"
    with open(path, "w", newline="") as handle:
        csv.writer(handle).writerows(rows)
    return path


def write_c3d(path: Path, points: np.ndarray, labels, rate: float = 120.0, units: str = "m   ") -> None:
    """``points`` (f, m, 4): x, y, z, residual (−1 for a missing point), written by c3d.Writer."""
    writer = c3d.Writer(point_rate=rate, point_units=units)
    writer.set_point_labels(labels)
    for frame in points:
        block = np.zeros((len(frame), 5), np.float32)
        block[:, :4] = frame
        writer.add_frames((block, np.zeros((0, 0))))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # "No analog data found in file."
        with open(path, "wb") as handle:
            writer.write(handle)


# ---------------------------------------------------------------------------------------------
# round trips


@pytest.mark.parametrize(("dims", "units"), [(3, "mm"), (2, "px"), (3, None)])
def test_csv_round_trip_is_exact(tmp_path: Path, dims: int, units: str | None) -> None:
    written = random_trajectories(np.random.default_rng(dims), dims=dims, units=units)
    before = written.positions.copy()
    path = write_trajectories(written, tmp_path / "t.csv")
    assert path == tmp_path / "t.csv"
    assert_same(read_trajectories(path), written)
    np.testing.assert_array_equal(written.positions, before)
    assert not list(tmp_path.glob(".t.csv.*"))  # no temporary file left


def test_trc_round_trip_is_exact(tmp_path: Path) -> None:
    written = dataclasses.replace(random_trajectories(np.random.default_rng(7), units="m"), confidence=None)
    path = write_trajectories(written, tmp_path / "t.trc")
    assert path.read_text().startswith("PathFileType\t4\t(X/Y/Z)\tt.trc\n")
    read = read_trajectories(path)
    assert_same(read, written)
    np.testing.assert_array_equal(read.confidence, np.ones(written.n_frames))


def test_write_trc_warns_that_confidence_is_dropped(tmp_path: Path) -> None:
    written = random_trajectories(np.random.default_rng(8))
    with pytest.warns(MimeticWarning, match="confidence"):
        write_trajectories(written, tmp_path / "t.trc")
    assert_same(read_trajectories(tmp_path / "t.trc"), written, confidence=False)


@pytest.mark.parametrize(
    ("change", "match"), [({"units": None}, "length unit"), ({"units": "px"}, "length unit")]
)
def test_write_trc_rejects_trajectories_without_a_length_unit(tmp_path: Path, change, match) -> None:
    trajectories = dataclasses.replace(random_trajectories(np.random.default_rng(9)), **change)
    with pytest.raises(CaptureError, match=match):
        write_trajectories(trajectories, tmp_path / "t.trc")
    assert not (tmp_path / "t.trc").exists()


def test_write_trc_rejects_2d_points(tmp_path: Path) -> None:
    trajectories = random_trajectories(np.random.default_rng(10), dims=2, units="px")
    with pytest.raises(CaptureError, match="3D"):
        write_trajectories(trajectories, tmp_path / "t.trc")


def test_write_rejects_an_unknown_suffix_and_keeps_the_old_file(tmp_path: Path) -> None:
    path = tmp_path / "t.json"
    path.write_text("old")
    with pytest.raises(CaptureError, match=r"\.csv, \.trc"):
        write_trajectories(random_trajectories(np.random.default_rng(11)), path)
    assert path.read_text() == "old"


# ---------------------------------------------------------------------------------------------
# C3D


def test_c3d_reads_labels_rate_units_and_missing_points(tmp_path: Path) -> None:
    rng = np.random.default_rng(12)
    points = np.zeros((6, 3, 4), np.float32)
    points[..., :3] = rng.normal(size=(6, 3, 3))
    points[2, 1, 3] = -1.0  # RHEAD not seen in frame 2
    path = tmp_path / "capture.c3d"
    write_c3d(path, points, ["LHEAD", "RHEAD", "CHIN"], rate=120.0, units="m   ")
    t = read_trajectories(path)
    assert t.positions.shape == (6, 3, 3) and t.positions.dtype == np.float64
    assert t.names == ("LHEAD", "RHEAD", "CHIN")  # "CHIN " padded in the file
    assert t.fps == 120.0 and t.units == "m"
    assert np.isnan(t.positions[2, 1]).all()
    assert t.seen.sum() == 6 * 3 - 1
    expected = points[..., :3].astype(np.float64)
    expected[2, 1] = np.nan
    np.testing.assert_array_equal(t.positions, expected)  # float32 in the file, exact in float64


def test_c3d_detected_by_content_without_the_suffix(tmp_path: Path) -> None:
    points = np.ones((2, 1, 4), np.float32)
    points[..., 3] = 0.0
    write_c3d(tmp_path / "capture.c3d", points, ["A"])
    renamed = (tmp_path / "capture.c3d").rename(tmp_path / "capture.dat")
    assert read_trajectories(renamed).names == ("A",)


@pytest.mark.parametrize("keep", [100, 700, -1024], ids=["header", "parameters", "data"])
def test_c3d_truncated_raises_capture_error(tmp_path: Path, keep: int) -> None:
    points = np.zeros((40, 4, 4), np.float32)
    points[..., :3] = 1.0
    full = tmp_path / "full.c3d"
    write_c3d(full, points, ["A", "B", "C", "D"])
    data = full.read_bytes()
    assert len(data) == 4608  # 4 blocks of header and parameters, 5 of data (40 × 4 × 16 bytes)
    cut = tmp_path / "cut.c3d"
    cut.write_bytes(data[:keep])
    with pytest.raises(CaptureError, match=r"cut\.c3d: .*(truncated|corrupt)"):
        read_trajectories(cut)


# ---------------------------------------------------------------------------------------------
# OpenFace


def test_openface_sample_reads_68_points_in_mm_turned_to_y_up_z_toward_the_camera() -> None:
    path = require_shared_data(OPENFACE)
    with pytest.warns(MimeticWarning, match=r"fps=30 .* 1000 fps"):
        t = read_trajectories(path, fps=30)
    assert t.positions.shape == (100, 68, 3) and t.positions.dtype == np.float64
    assert t.names[0] == "ibug68_01" and t.names[30] == "ibug68_31" and t.names[-1] == "ibug68_68"
    assert t.units == "mm" and t.fps == 30.0
    assert t.confidence.shape == (100,) and t.confidence.min() >= 0.88
    assert t.seen.all()
    p = {n: t.positions[:, t.names.index(n)] for n in ("ibug68_31", "ibug68_37", "ibug68_46")}
    p |= {n: t.positions[:, t.names.index(n)] for n in ("ibug68_49", "ibug68_55")}
    eyes, mouth = (p["ibug68_37"] + p["ibug68_46"]) / 2, (p["ibug68_49"] + p["ibug68_55"]) / 2
    assert (p["ibug68_31"][:, 2] > p["ibug68_37"][:, 2] + 10).all()  # nose tip in front (mm)
    assert (p["ibug68_31"][:, 2] > p["ibug68_46"][:, 2] + 10).all()
    assert (eyes[:, 1] > mouth[:, 1] + 30).all()  # eyes above the mouth
    assert (p["ibug68_46"][:, 0] > p["ibug68_37"][:, 0]).all()  # the face's left (45) at +X
    assert (t.positions[..., 2] < 0).all()  # in front of the camera at z = 0, seen down -Z


def test_openface_without_fps_asks_for_it() -> None:
    with pytest.raises(CaptureError, match=r"1000 fps.*fps="):
        read_trajectories(require_shared_data(OPENFACE))


def test_openface_fps_that_agrees_with_timestamps_gives_no_warning(tmp_path: Path) -> None:
    def at_25_fps(header, rows):
        for i, row in enumerate(rows):
            row[header.index("timestamp")] = f"{i / 25:.3f}"

    path = openface_copy(tmp_path, edit=at_25_fps)
    assert read_trajectories(path).fps == pytest.approx(25.0, rel=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert read_trajectories(path, fps=25.1).fps == 25.1  # within 1 %


def test_openface_2d_landmarks_are_pixels_with_y_down(tmp_path: Path) -> None:
    path = openface_copy(tmp_path, drop=lambda name: name[:2] in ("X_", "Y_", "Z_"))
    with pytest.warns(MimeticWarning):
        t = read_trajectories(path, fps=30)
    assert t.positions.shape == (100, 68, 2) and t.units == "px"
    eyes = t.positions[:, [36, 45], 1].mean(axis=1)
    mouth = t.positions[:, [48, 54], 1].mean(axis=1)
    assert (eyes < mouth).all()  # image rows grow downwards
    assert (t.positions > 0).all()


def test_openface_failed_frames_are_missing_with_zero_confidence(tmp_path: Path) -> None:
    def fail_frame_3(header, rows):
        rows[3][header.index("success")] = " 0"

    with pytest.warns(MimeticWarning):
        t = read_trajectories(openface_copy(tmp_path, edit=fail_frame_3), fps=30)
    assert np.isnan(t.positions[3]).all() and t.confidence[3] == 0.0
    assert t.seen[[2, 4]].all() and t.confidence[4] >= 0.88


def test_openface_units_argument_must_agree(tmp_path: Path) -> None:
    with pytest.raises(CaptureError, match=r"units 'mm' but units='cm'"), pytest.warns(MimeticWarning):
        read_trajectories(require_shared_data(OPENFACE), fps=30, units="cm")


def test_openface_without_landmark_columns_says_how_to_get_them(tmp_path: Path) -> None:
    path = openface_copy(tmp_path, drop=lambda name: name[:2].lower() in ("x_", "y_", "z_"))
    with pytest.raises(CaptureError, match="-3Dfp"):
        read_trajectories(path, fps=30)


# ---------------------------------------------------------------------------------------------
# the CSV format: frame rate and units


def write_text(tmp_path: Path, text: str, name: str = "t.csv") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_csv_rate_comes_from_time_s_without_an_fps_line(tmp_path: Path) -> None:
    path = write_text(tmp_path, "frame,time_s,a_x,a_y\n10,1.0,1,2\n11,1.04,3,\n12,1.08,nan,4\n")
    t = read_trajectories(path, units="px")
    assert t.fps == pytest.approx(25.0, rel=1e-12) and t.units == "px"
    assert t.positions.shape == (3, 1, 2)
    np.testing.assert_array_equal(t.positions[:, 0], [[1, 2], [3, np.nan], [np.nan, 4]])
    np.testing.assert_array_equal(t.confidence, np.ones(3))


def test_csv_without_any_rate_asks_for_fps(tmp_path: Path) -> None:
    path = write_text(tmp_path, "frame,a_x,a_y,a_z\n0,1,2,3\n1,1,2,3\n")
    with pytest.raises(CaptureError, match=r"fps="):
        read_trajectories(path)
    assert read_trajectories(path, fps=50).fps == 50.0


def test_csv_fps_argument_overrides_the_file_with_a_warning(tmp_path: Path) -> None:
    path = write_text(tmp_path, "# fps: 60\nframe,a_x,a_y,a_z\n0,1,2,3\n")
    with pytest.warns(MimeticWarning, match=r"fps=30 .* 60 fps"):
        assert read_trajectories(path, fps=30).fps == 30.0


def test_csv_units_argument_fills_in_but_must_not_contradict(tmp_path: Path) -> None:
    bare = write_text(tmp_path, "# fps: 60\nframe,a_x,a_y,a_z\n0,1,2,3\n", "bare.csv")
    assert read_trajectories(bare).units is None
    assert read_trajectories(bare, units="cm").units == "cm"
    said = write_text(tmp_path, "# units: mm\n# fps: 60\nframe,a_x,a_y,a_z\n0,1,2,3\n", "said.csv")
    assert read_trajectories(said, units="mm").units == "mm"
    with pytest.raises(CaptureError, match=r"units 'mm' but units='m'.*Drop the argument"):
        read_trajectories(said, units="m")


# ---------------------------------------------------------------------------------------------
# bad input


def test_read_missing_file_raises(tmp_path: Path) -> None:
    with pytest.raises(CaptureError, match=r"nope\.csv: no such file"):
        read_trajectories(tmp_path / "nope.csv")


def test_read_empty_file_raises(tmp_path: Path) -> None:
    with pytest.raises(CaptureError, match=r"empty\.csv: the file is empty"):
        read_trajectories(write_text(tmp_path, "\n  \n", "empty.csv"))


@pytest.mark.parametrize(
    "content", [b"name,x,y,z\nnose,1,2,3\n", b"\xff\xfe\x00\x01binary"], ids=["csv", "binary"]
)
def test_read_unknown_format_lists_the_known_ones(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / "t.txt"
    path.write_bytes(content)
    with pytest.raises(CaptureError, match=r"t\.txt: .*Known formats: .*CSV.*TRC.*C3D.*OpenFace"):
        read_trajectories(path)


def test_csv_column_count_mismatch_names_the_line(tmp_path: Path) -> None:
    path = write_text(tmp_path, "# fps: 60\nframe,a_x,a_y,a_z\n0,1,2,3\n1,1,2\n")
    with pytest.raises(CaptureError, match=r"t\.csv: line 4 has 3 cells but the header has 4"):
        read_trajectories(path)


def test_csv_non_numeric_cell_names_line_and_column(tmp_path: Path) -> None:
    path = write_text(tmp_path, "# fps: 60\nframe,a_x,a_y,a_z\n0,1,2,3\n1,1,two,3\n")
    with pytest.raises(CaptureError, match=r"line 4, column 'a_y': 'two' is not a number"):
        read_trajectories(path)


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("frame,a_x,a_y,a_z,b_x,b_y\n0,1,2,3,4,5\n", r"'b'.*b_x, b_y, b_z"),
        ("frame,a_x,a_y,a_w\n0,1,2,3\n", r"'a_w' is not <name>_x"),
        ("frame,a_x,a_y,a_z\n0,1,2,3\n2,1,2,3\n", r"line 3: frame 2 after 0"),
        ("frame,a_x,a_y,a_z,confidence\n0,1,2,3,1.5\n", r"line 2: confidence 1.5"),
        ("frame,a_x,a_y,a_z\n", r"no frames"),
        ("# fps: sixty\nframe,a_x,a_y,a_z\n0,1,2,3\n", r"line 1: '# fps: sixty' is not a number"),
        ("# units: inch\nframe,a_x,a_y,a_z\n0,1,2,3\n", r"units 'inch' unknown"),
    ],
    ids=["mixed-dims", "bad-axis", "frame-gap", "confidence", "no-rows", "bad-fps", "bad-units"],
)
def test_csv_malformed_raises(tmp_path: Path, text: str, match: str) -> None:
    with pytest.raises(CaptureError, match=match):
        read_trajectories(write_text(tmp_path, text), fps=60)


def trc_text(num_markers: int = 2, rows: str = "1\t0\t1\t2\t3\t4\t5\t6\n2\t0.01\t\t\t\t4\t5\t6\n") -> str:
    return (
        "PathFileType\t4\t(X/Y/Z)\tt.trc\n"
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames\n"
        f"100\t100\t2\t{num_markers}\tmm\t100\t1\t2\n"
        "Frame#\tTime\tA\t\t\tB\n"
        "\t\tX1\tY1\tZ1\tX2\tY2\tZ2\n"
        "\n" + rows
    )


def test_trc_written_by_hand_reads_with_missing_markers(tmp_path: Path) -> None:
    t = read_trajectories(write_text(tmp_path, trc_text(), "t.trc"))
    assert t.names == ("A", "B") and t.fps == 100.0 and t.units == "mm"
    assert t.positions.shape == (2, 2, 3)
    assert np.isnan(t.positions[1, 0]).all()
    np.testing.assert_array_equal(t.positions[1, 1], [4, 5, 6])


def test_trc_num_markers_disagreeing_with_the_name_row_raises(tmp_path: Path) -> None:
    with pytest.raises(CaptureError, match=r"NumMarkers is 3 but the marker-name row names 2 markers"):
        read_trajectories(write_text(tmp_path, trc_text(num_markers=3), "t.trc"))


@pytest.mark.parametrize(
    ("rows", "match"),
    [
        ("1\t0\t1\t2\t3\t4\t5\t6\n", r"NumFrames is 2 but the file has 1 frame rows"),
        ("1\t0\t1\t2\t3\t4\t5\t6\n2\t0.01\t1\t2\t3\n", r"line 8 has 5 cells"),
        ("1\t0\t1\t2\t3\t4\t5\t6\n2\t0.01\t1\tx\t3\t4\t5\t6\n", r"line 8, column 'A Y': 'x'"),
    ],
    ids=["truncated", "short-row", "non-numeric"],
)
def test_trc_malformed_rows_raise(tmp_path: Path, rows: str, match: str) -> None:
    with pytest.raises(CaptureError, match=match):
        read_trajectories(write_text(tmp_path, trc_text(rows=rows), "t.trc"))


def test_all_frames_missing_raises(tmp_path: Path) -> None:
    path = write_text(tmp_path, "# fps: 60\nframe,a_x,a_y,a_z,b_x,b_y,b_z\n0,,,,,,\n1,nan,nan,nan,,,\n")
    with pytest.raises(CaptureError, match=r"no point is seen in any of its 2 frames"):
        read_trajectories(path)


def test_point_missing_in_every_frame_is_kept_with_a_warning(tmp_path: Path) -> None:
    path = write_text(tmp_path, "# fps: 60\nframe,a_x,a_y,a_z,b_x,b_y,b_z\n0,1,2,3,,,\n1,1,2,3,,,\n")
    with pytest.warns(MimeticWarning, match=r"point\(s\) b missing in every frame"):
        t = read_trajectories(path)
    assert t.names == ("a", "b") and np.isnan(t.positions[:, 1]).all()


def test_c3d_reader_warnings_do_not_leak(tmp_path: Path) -> None:
    points = np.ones((2, 1, 4), np.float32)
    write_c3d(tmp_path / "t.c3d", points, ["A"])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        t = read_trajectories(tmp_path / "t.c3d")
    assert t.n_frames == 2


def test_csv_header_quoting_survives_names_with_commas(tmp_path: Path) -> None:
    written = Trajectories(("a,b", "c"), np.arange(12.0).reshape(2, 2, 3), 24.0, "cm")
    path = write_trajectories(written, tmp_path / "t.csv")
    assert next(csv.reader(io.StringIO(path.read_text().splitlines()[2])))[2] == "a,b_x"
    assert_same(read_trajectories(path), written)
