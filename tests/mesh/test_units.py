"""Tests for mimetic.mesh.units: unit checks, head-size unit detection, conversion."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mimetic.errors import MeshError
from mimetic.mesh.units import (
    PLAUSIBLE_EXTENT_M,
    UNIT_SCALE,
    check_units,
    convert_units,
    detect_units,
    largest_extent,
    units_for_extent,
)


def box(height: float, rng: np.random.Generator | None = None) -> np.ndarray:
    """Vertices (50, 3) filling a box of the given height (Y) that is narrower in X and Z."""
    rng = rng or np.random.default_rng(0)
    points = rng.random((50, 3)) * np.array([0.7, 1.0, 0.8]) * height
    points[0], points[1] = 0.0, [0.7 * height, height, 0.8 * height]  # pin the extremes
    return points


@pytest.mark.parametrize(
    ("height", "expected"),
    [(23.0, "cm"), (230.0, "mm"), (0.23, "m"), (2.3, "dm"), (150.0, "mm"), (0.15, "m"), (29.0, "cm")],
)
def test_detect_units_head_sized_box_gives_expected_unit(height, expected):
    vertices = box(height)
    before = vertices.copy()
    assert detect_units(vertices) == expected
    np.testing.assert_array_equal(vertices, before)


@pytest.mark.parametrize("height", [1e6, 1e-6, 5000.0, 0.01])
def test_detect_units_absurd_size_raises_with_extent_and_hint(height):
    with pytest.raises(MeshError, match=r'units="cm"') as info:
        detect_units(box(height))
    assert f"{height:.3g}" in str(info.value)
    assert "--units" in str(info.value)


def test_detect_units_ignores_nonfinite_rows():
    vertices = box(23.0)
    vertices[5] = [np.nan, 0.0, 0.0]
    vertices[6] = [np.inf, 1e9, 0.0]
    assert detect_units(vertices) == "cm"


def test_detect_units_no_finite_vertex_raises():
    with pytest.raises(MeshError, match="finite"):
        detect_units(np.full((4, 3), np.nan))


def test_detect_units_wrong_shape_raises_value_error():
    with pytest.raises(ValueError, match=r"\(n, 3\)"):
        detect_units(np.zeros((4, 2)))


@given(
    extent_m=st.floats(PLAUSIBLE_EXTENT_M[0] * (1 + 1e-9), PLAUSIBLE_EXTENT_M[1] * (1 - 1e-9)),
    unit=st.sampled_from(["mm", "cm", "dm", "m"]),  # inches are never guessed (see the next test)
)
def test_units_for_extent_plausible_head_recovers_its_unit(extent_m, unit):
    assert units_for_extent(extent_m / UNIT_SCALE[unit]) == unit


def test_units_for_extent_never_guesses_inches():
    """A head 9.2 units tall: a 23 cm head in inches, or a 9.2 cm face mask; detection says cm."""
    assert units_for_extent(9.2) == "cm"


def test_convert_units_inches_to_millimetres_and_back():
    inch = np.ones((1, 3))
    np.testing.assert_allclose(convert_units(inch, "in", "mm"), np.full((1, 3), 25.4), rtol=1e-15)
    np.testing.assert_allclose(
        convert_units(np.full((1, 3), 254.0), "mm", "in"), np.full((1, 3), 10.0), rtol=1e-15
    )


@given(extent=st.floats(1e-12, 1e12))
def test_units_for_extent_result_is_always_head_sized(extent):
    unit = units_for_extent(extent)
    if unit is not None:
        assert PLAUSIBLE_EXTENT_M[0] <= extent * UNIT_SCALE[unit] < PLAUSIBLE_EXTENT_M[1]


def test_units_for_extent_nonpositive_or_nan_is_none():
    assert units_for_extent(0.0) is None
    assert units_for_extent(-3.0) is None
    assert units_for_extent(float("nan")) is None


def test_largest_extent_all_nan_is_nan():
    assert np.isnan(largest_extent(np.full((3, 3), np.nan)))
    assert largest_extent(np.array([[0.0, 0.0, 0.0], [1.0, 5.0, -2.0]])) == 5.0


def test_convert_units_cm_to_mm_scales_by_ten_exactly():
    vertices = np.array([[1.0, 2.5, -3.0], [0.1, 0.0, 7.0]])
    before = vertices.copy()
    out = convert_units(vertices, "cm", "mm")
    assert out.shape == (2, 3)
    assert out.dtype == np.float64
    np.testing.assert_array_equal(out, vertices * 10.0)
    np.testing.assert_array_equal(vertices, before)
    assert out is not vertices


@pytest.mark.parametrize(("a", "b"), [("mm", "m"), ("m", "mm"), ("dm", "cm"), ("cm", "m"), ("m", "m")])
def test_convert_units_round_trip_restores_vertices(a, b):
    vertices = np.random.default_rng(3).normal(size=(20, 3))
    there = convert_units(vertices, a, b)
    np.testing.assert_allclose(there, vertices * UNIT_SCALE[a] / UNIT_SCALE[b], rtol=1e-15)
    np.testing.assert_allclose(convert_units(there, b, a), vertices, rtol=1e-15)


def test_convert_units_dm_to_mm_is_exact_hundred():
    np.testing.assert_array_equal(convert_units(np.ones((1, 3)), "dm", "mm"), np.full((1, 3), 100.0))


@pytest.mark.parametrize("bad", ["inches", "CM", "", "meters"])
def test_convert_units_unknown_unit_raises_listing_allowed(bad):
    with pytest.raises(MeshError, match="'mm', 'cm', 'dm', 'm'"):
        convert_units(np.zeros((1, 3)), bad, "m")


def test_check_units_known_unit_is_returned():
    for unit in UNIT_SCALE:
        assert check_units(unit) == unit
    with pytest.raises(MeshError, match="unknown units"):
        check_units(None)  # type: ignore[arg-type]
