"""Tests for mimetic.fit.landmarks: the Landmarks type and landmark files.

JSON and CSV round trips, iBUG-68 names, unit conversion, and one clear LandmarkError per
kind of bad input. (Automatic landmarks: tests/fit/test_autolandmarks.py.)

"""

from __future__ import annotations

import json
import os

import numpy as np
import pytest

from mimetic.errors import LandmarkError
from mimetic.fit.landmarks import (
    MIN_LANDMARKS,
    PROJECT_LANDMARKS,
    Landmarks,
    read_landmarks,
    write_landmarks,
)
from mimetic.head.landmarks import IBUG68
from mimetic.mesh.units import convert_units
from mimetic.testing import small_head

# ---------------------------------------------------------------------------------------------
# the name tables


def test_project_landmarks_are_the_generated_head_landmarks():
    assert PROJECT_LANDMARKS == tuple(small_head().landmarks)
    assert len(set(PROJECT_LANDMARKS)) == len(PROJECT_LANDMARKS) == 82


# ---------------------------------------------------------------------------------------------
# the Landmarks type


def _landmarks(names=("nose_tip", "menton"), units="cm") -> Landmarks:
    positions = np.arange(3.0 * len(names)).reshape(-1, 3)
    return Landmarks(tuple(names), positions, np.full(len(names), 0.5), units, "test")


def test_landmarks_arrays_are_read_only_float64_copies():
    positions = np.array([[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]])
    before = positions.copy()
    landmarks = Landmarks(("nose_tip", "menton"), positions, [1.0, 0.5], "cm", "test")
    assert landmarks.positions.shape == (2, 3) and landmarks.positions.dtype == np.float64
    assert landmarks.confidence.shape == (2,) and landmarks.confidence.dtype == np.float64
    assert not landmarks.positions.flags.writeable and not landmarks.confidence.flags.writeable
    positions[0, 0] = 99.0
    np.testing.assert_array_equal(landmarks.positions, before)


def test_landmarks_position_subset_as_dict():
    landmarks = _landmarks(("nose_tip", "menton", "nasion"))
    np.testing.assert_array_equal(landmarks.position("menton"), [3.0, 4.0, 5.0])
    sub = landmarks.subset(["nasion", "nose_tip"])
    assert sub.names == ("nasion", "nose_tip")
    np.testing.assert_array_equal(sub.positions, [[6.0, 7.0, 8.0], [0.0, 1.0, 2.0]])
    assert (sub.units, sub.source) == ("cm", "test")
    assert landmarks.as_dict() == {
        "nose_tip": [0.0, 1.0, 2.0],
        "menton": [3.0, 4.0, 5.0],
        "nasion": [6.0, 7.0, 8.0],
    }
    assert all(type(c) is float for p in landmarks.as_dict().values() for c in p)
    with pytest.raises(LandmarkError, match="'pogonion' not among these 3 landmarks"):
        landmarks.position("pogonion")


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"names": ("nose_tip", "nose_tip")}, LandmarkError, "more than once"),
        ({"names": ("nose_tipp", "menton")}, LandmarkError, "Did you mean 'nose_tipp' → 'nose_tip'"),
        ({"positions": np.zeros((2, 2))}, ValueError, r"shape \(2, 3\)"),
        ({"positions": [[np.nan, 0, 0], [0, 0, 0]]}, LandmarkError, "'nose_tip' has a NaN"),
        ({"confidence": [0.5, 1.5]}, ValueError, r"in \[0, 1\]"),
        ({"units": "inch"}, LandmarkError, "unknown units 'inch'"),
        ({"orientation": np.diag([1.0, 1.0, -1.0])}, ValueError, "rotation"),
    ],
    ids=["duplicate", "unknown", "shape", "nan", "confidence", "units", "reflection"],
)
def test_landmarks_rejects_bad_fields(kwargs, error, match):
    fields = {
        "names": ("nose_tip", "menton"),
        "positions": np.zeros((2, 3)),
        "confidence": [1.0, 1.0],
        "units": "cm",
        "source": "test",
    }
    fields.update(kwargs)
    with pytest.raises(error, match=match):
        Landmarks(**fields)


# ---------------------------------------------------------------------------------------------
# files

# Ten well-spread landmarks of the default head (cm), from make_head() at the default resolution.
SPREAD = ["eye_outer_corner_L", "eye_outer_corner_R", "eye_inner_corner_L", "eye_inner_corner_R"]
SPREAD += ["nose_tip", "mouth_corner_L", "mouth_corner_R", "menton", "nasion", "brow_mid_L"]


@pytest.fixture(scope="module")
def spread() -> dict[str, np.ndarray]:
    head = small_head()
    return dict(zip(SPREAD, head.landmark_positions(SPREAD), strict=True))


def _write_json(path, points: dict, units="cm") -> None:
    path.write_text(
        json.dumps({"units": units, "landmarks": {n: list(map(float, p)) for n, p in points.items()}})
    )


def test_read_landmarks_json_gives_positions_in_file_order_with_confidence_one(tmp_path, spread):
    path = tmp_path / "lm.json"
    _write_json(path, spread)
    landmarks = read_landmarks(path)
    assert landmarks.names == tuple(SPREAD)
    assert landmarks.positions.shape == (len(SPREAD), 3) and landmarks.positions.dtype == np.float64
    np.testing.assert_array_equal(landmarks.positions, np.array(list(spread.values())))
    np.testing.assert_array_equal(landmarks.confidence, np.ones(len(SPREAD)))
    assert (landmarks.units, landmarks.source, landmarks.orientation) == ("cm", "file:lm.json", None)


@pytest.mark.parametrize("suffix", [".json", ".csv"])
@pytest.mark.parametrize("units", ["mm", None])
def test_write_then_read_landmarks_round_trips_exactly(tmp_path, spread, suffix, units):
    rng = np.random.default_rng(7)
    positions = np.array(list(spread.values())) + rng.normal(
        0.0, 1e-3, (len(spread), 3)
    )  # full-precision floats
    original = Landmarks(tuple(spread), positions, np.full(len(spread), 0.3), units, "auto:test")
    path = write_landmarks(original, tmp_path / f"lm{suffix}")
    assert path == tmp_path / f"lm{suffix}"
    back = read_landmarks(path)
    assert back.names == original.names
    np.testing.assert_array_equal(back.positions, original.positions)  # bit for bit
    assert back.units == units
    assert [p.name for p in tmp_path.iterdir()] == [path.name]  # no temporary file left behind


def test_read_landmarks_csv_with_header_and_units_comment(tmp_path, spread):
    lines = ["# exported by a test", "# units: mm", "name, x, y, z"]
    lines += [f"{n}, {x}, {y}, {z}" for n, (x, y, z) in spread.items()]
    path = tmp_path / "lm.csv"
    path.write_text("\n".join(lines) + "\n\n")
    landmarks = read_landmarks(path)
    assert landmarks.units == "mm"
    np.testing.assert_array_equal(landmarks.positions, np.array(list(spread.values())))
    # without header and units line, units come from the argument
    path.write_text("\n".join(f"{n},{x},{y},{z}" for n, (x, y, z) in spread.items()))
    assert read_landmarks(path, units="m").units == "m"
    assert read_landmarks(path).units is None


def test_read_landmarks_converts_mm_to_mesh_cm_exactly(tmp_path, spread):
    in_mm = {n: p * 10.0 for n, p in spread.items()}
    path = tmp_path / "lm.json"
    _write_json(path, in_mm, units="mm")
    landmarks = read_landmarks(path, mesh_units="cm")
    assert landmarks.units == "cm"
    mm = np.array(list(in_mm.values()))
    np.testing.assert_array_equal(
        landmarks.positions, convert_units(mm, "mm", "cm")
    )  # the project's conversion
    np.testing.assert_allclose(landmarks.positions, mm / 10.0, rtol=2.3e-16, atol=0)  # within 1 ulp of exact
    same = read_landmarks(path, mesh_units="mm")
    np.testing.assert_array_equal(same.positions, np.array(list(in_mm.values())))
    path.write_text(path.read_text().replace('"mm"', "null"))  # unknown file units: no conversion
    unknown = read_landmarks(path, mesh_units="cm")
    assert unknown.units is None
    np.testing.assert_array_equal(unknown.positions, np.array(list(in_mm.values())))


def test_read_landmarks_maps_ibug68_names(tmp_path):
    head = small_head()
    points = {f"ibug68_{k + 1:02d}": head.landmark_positions([name])[0] for k, name in enumerate(IBUG68)}
    points["ibug68_61"] = points["ibug68_61"] + 0.2  # iBUG's inner mouth corner differs from the outer one
    path = tmp_path / "ibug.json"
    _write_json(path, points)
    landmarks = read_landmarks(path)
    assert len(landmarks.names) == len(set(IBUG68)) == 66  # 49/61 and 55/65 are both mouth corners
    assert landmarks.names[:3] == ("jaw_R1", "jaw_R2", "jaw_R3")
    for name in ("menton", "nose_tip", "eye_outer_corner_R", "eye_outer_corner_L", "mouth_corner_R"):
        np.testing.assert_array_equal(landmarks.position(name), head.landmark_positions([name])[0])
    assert IBUG68[36] == "eye_outer_corner_R" and IBUG68[45] == "eye_outer_corner_L"
    # unpadded numbers are accepted too: the jaw (1-17) and the nose tip (31)
    numbers = [*range(1, 18), 31]
    unpadded = {f"ibug68_{k}": head.landmark_positions([IBUG68[k - 1]])[0] for k in numbers}
    path.write_text(_json_text(unpadded))
    assert read_landmarks(path).names[-2:] == ("jaw_L1", "nose_tip")


def _expect_error(tmp_path, text: str, *patterns: str, name="lm.json", **kwargs) -> str:
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(LandmarkError) as info:
        read_landmarks(path, **kwargs)
    message = str(info.value)
    assert message.startswith(name), message  # says which file
    for pattern in patterns:
        assert pattern in message, message
    return message


def _json_text(points: dict, units="cm") -> str:
    return json.dumps({"units": units, "landmarks": {n: list(map(float, p)) for n, p in points.items()}})


def test_read_landmarks_rejects_fewer_than_eight(tmp_path, spread):
    few = dict(list(spread.items())[: MIN_LANDMARKS - 1])
    _expect_error(tmp_path, _json_text(few), "only 7 landmarks", "at least 8", "auto_landmarks")


def test_read_landmarks_rejects_collinear_points(tmp_path):
    line = {name: np.array([k, 2.0 * k, 0.5 * k]) + 1e-4 * (k % 2) for k, name in enumerate(SPREAD)}
    _expect_error(tmp_path, _json_text(line), "nearly on one line", "spread over the face")


def test_read_landmarks_rejects_coplanar_2d_points(tmp_path, spread):
    flat = {n: np.array([p[0], p[1], 0.0]) for n, p in spread.items()}
    _expect_error(tmp_path, _json_text(flat), "lie in one plane", "2D image landmarks")


def test_read_landmarks_rejects_unknown_names_with_suggestions(tmp_path, spread):
    points = dict(spread)
    points["nose_tipp"] = points.pop("nose_tip")
    points["ibug68_69"] = points["menton"]
    message = _expect_error(tmp_path, _json_text(points), "'nose_tipp'", "'ibug68_69'", "ibug68_01")
    assert "'nose_tip'?" in message and "eye_outer_corner_L" in message


@pytest.mark.parametrize("value", [np.nan, np.inf])
def test_read_landmarks_rejects_non_finite_coordinates(tmp_path, spread, value):
    points = dict(spread)
    points["menton"] = np.array([0.0, value, 5.0])
    _expect_error(tmp_path, _json_text(points), "'menton'", "NaN or infinite")  # JSON NaN / Infinity tokens
    points = dict(spread)
    points["nasion"] = np.array([0.0, 1.0, value])
    csv_text = "\n".join(f"{n},{x},{y},{z}" for n, (x, y, z) in points.items())
    _expect_error(tmp_path, csv_text, "'nasion' (line 9)", "NaN or infinite", name="lm.csv")


@pytest.mark.parametrize(
    ("text", "pattern"),
    [
        ('{"units": "cm", "landmarks": {"nose_tip": [1, 2, 3],', "not valid JSON"),
        ("[1, 2, 3]", "not an object"),
        ('{"units": "cm"}', 'no "landmarks" key'),
        ('{"landmarks": [[1, 2, 3]]}', '"landmarks" must be an object'),
        ('{"landmarks": {"nose_tip": [1, 2]}}', "must be a list of 3 numbers"),
        ('{"landmarks": {"nose_tip": [1, 2, "3"]}}', "must be a list of 3 numbers"),
        ('{"units": 10, "landmarks": {}}', '"units" must be a string'),
    ],
    ids=["truncated", "array", "no-landmarks", "list", "two-coords", "string-coord", "units-number"],
)
def test_read_landmarks_rejects_corrupt_json(tmp_path, text, pattern):
    message = _expect_error(tmp_path, text, pattern)
    assert "expected" in message or "got" in message or "must" in message


def test_read_landmarks_rejects_bad_units_and_bad_csv_rows(tmp_path, spread):
    _expect_error(tmp_path, _json_text(spread, units="inch"), "unknown units in the file 'inch'", "'mm'")
    _expect_error(tmp_path, _json_text(spread, units="mm"), "says units 'mm'", "units='cm'", units="cm")
    rows = [f"{n},{x},{y},{z}" for n, (x, y, z) in spread.items()]
    _expect_error(
        tmp_path, "\n".join([*rows[:3], "menton,1,2", *rows[3:]]), "line 4", "expected 4 values", name="a.csv"
    )
    _expect_error(
        tmp_path, "\n".join([*rows[:3], "menton,1,2,z", *rows[3:]]), "line 4", "must be numbers", name="b.csv"
    )
    _expect_error(tmp_path, "", "only 0 landmarks", name="empty.csv")


def test_read_landmarks_rejects_missing_file_and_binary_data(tmp_path):
    with pytest.raises(LandmarkError, match="no such file"):
        read_landmarks(tmp_path / "missing.json")
    (tmp_path / "lm.json").write_bytes(b"\xff\xfe\x00\x81")
    with pytest.raises(LandmarkError, match="not UTF-8"):
        read_landmarks(tmp_path / "lm.json")


def test_read_landmarks_rejects_a_name_given_twice(tmp_path, spread):
    rows = [f"{n},{x},{y},{z}" for n, (x, y, z) in spread.items()]
    _expect_error(
        tmp_path, "\n".join([*rows, rows[4]]), "'nose_tip' is given twice (lines 5 and 11)", name="lm.csv"
    )
    text = _json_text(spread)[:-2] + ', "menton": [0.0, 0.0, 0.0]}}'  # repeated JSON key
    _expect_error(tmp_path, text, "'menton' is given twice")


def test_read_landmarks_rejects_alias_conflict_and_accepts_alias_agreement(tmp_path, spread):
    menton = IBUG68.index("menton") + 1
    points = dict(spread)
    points[f"ibug68_{menton:02d}"] = spread["menton"] + np.array([0.0, -0.5, 0.0])
    _expect_error(
        tmp_path, _json_text(points), "'menton' is given twice with different positions", "ibug68_09"
    )
    points[f"ibug68_{menton:02d}"] = spread["menton"]  # the same point under both names is fine
    path = tmp_path / "ok.json"
    path.write_text(_json_text(points))
    landmarks = read_landmarks(path)
    assert landmarks.names.count("menton") == 1 and len(landmarks.names) == len(spread)
    points["ibug68_9"] = spread["menton"]  # but the same iBUG number twice is not
    _expect_error(tmp_path, _json_text(points), "'ibug68_09' is given twice")


def test_write_landmarks_failure_leaves_the_old_file_untouched(tmp_path, spread, monkeypatch):
    path = tmp_path / "lm.json"
    _write_json(path, spread)
    before = path.read_bytes()
    landmarks = Landmarks(tuple(spread), np.zeros((len(spread), 3)) + 1.0, np.ones(len(spread)), "cm", "test")

    def fail(fd):
        raise OSError("disk full")

    monkeypatch.setattr(os, "fsync", fail)  # atomic_write fsyncs the finished temporary file
    with pytest.raises(OSError, match="disk full"):
        write_landmarks(landmarks, path)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lm.json"]
