"""Tests for mimetic.head.params: the conformation parameters, their ranges and random draws."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from mimetic.errors import MimeticError
from mimetic.head.params import PARAM_RANGES, HeadParamError, HeadParams
from mimetic.testing import RANDOM_SEEDS

NAMES = tuple(PARAM_RANGES)


def half_range(name: str) -> float:
    low, high, _ = PARAM_RANGES[name]
    return (high - low) / 2


def test_head_params_fields_match_ranges_and_number_at_least_12():
    fields = [f.name for f in dataclasses.fields(HeadParams)]
    assert fields == list(PARAM_RANGES)
    assert len(fields) >= 12
    for name, (low, high, meaning) in PARAM_RANGES.items():
        assert isinstance(low, float) and isinstance(high, float), name
        assert low < 1.0 < high, f"{name}: the default 1.0 must lie strictly inside [{low}, {high}]"
        assert isinstance(meaning, str) and meaning, name


def test_head_params_defaults_are_valid_and_equal_one():
    params = HeadParams()
    values = params.as_dict()
    assert list(values) == list(NAMES)
    assert all(type(v) is float for v in values.values())
    assert values == dict.fromkeys(NAMES, 1.0)
    for name, value in values.items():
        low, high, _ = PARAM_RANGES[name]
        assert low <= value <= high


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("end", ["below", "above"])
def test_head_params_out_of_range_value_raises_naming_the_parameter(name, end):
    low, high, _ = PARAM_RANGES[name]
    value = low - 0.01 if end == "below" else high + 0.01
    with pytest.raises(HeadParamError, match=name):
        HeadParams(**{name: value})
    with pytest.raises(HeadParamError, match=name):
        HeadParams().with_values(**{name: value})


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf])
def test_head_params_non_finite_value_raises(value):
    with pytest.raises(HeadParamError, match="nose_length"):
        HeadParams(nose_length=value)


@pytest.mark.parametrize("name", NAMES)
def test_head_params_range_ends_are_accepted(name):
    low, high, _ = PARAM_RANGES[name]
    assert getattr(HeadParams(**{name: low}), name) == low
    assert getattr(HeadParams(**{name: high}), name) == high


@given(name=st.sampled_from(NAMES), fraction=st.floats(-0.5, 1.5, allow_nan=False))
def test_head_params_accepts_exactly_the_values_in_range(name, fraction):
    low, high, _ = PARAM_RANGES[name]
    value = low + fraction * (high - low)
    if low <= value <= high:
        assert HeadParams().with_values(**{name: value}).as_dict()[name] == value
    elif value < low - 1e-6 or value > high + 1e-6:
        with pytest.raises(HeadParamError, match=name):
            HeadParams().with_values(**{name: value})


def test_head_params_with_values_unknown_name_raises_naming_it():
    with pytest.raises(HeadParamError, match="nose_size") as info:
        HeadParams().with_values(nose_length=1.1, nose_size=1.0)
    assert isinstance(info.value, MimeticError) and isinstance(info.value, ValueError)


def test_head_params_with_values_returns_a_copy_and_leaves_the_original():
    params = HeadParams()
    changed = params.with_values(nose_length=1.1, jaw_width=0.9)
    assert changed.nose_length == 1.1 and changed.jaw_width == 0.9
    assert params == HeadParams()
    assert {k for k, v in changed.as_dict().items() if v != 1.0} == {"nose_length", "jaw_width"}
    with pytest.raises(dataclasses.FrozenInstanceError):
        params.nose_length = 1.1  # type: ignore[misc]


@pytest.mark.parametrize("seed", [0, 1, 7, 12345])
def test_head_params_random_is_deterministic_per_seed(seed):
    assert HeadParams.random(seed) == HeadParams.random(seed)
    assert HeadParams.random(seed) != HeadParams.random(seed + 1)


def test_head_params_random_stays_within_ranges():
    draws = [HeadParams.random(seed) for seed in RANDOM_SEEDS]
    draws += [HeadParams.random(seed, spread=4.0) for seed in RANDOM_SEEDS]  # mostly clipped
    for params in draws:
        for name, value in params.as_dict().items():
            low, high, _ = PARAM_RANGES[name]
            assert low <= value <= high, f"{name}={value} outside [{low}, {high}]"


def test_head_params_random_with_zero_spread_is_the_default():
    assert HeadParams.random(3, spread=0.0) == HeadParams()


def test_head_params_random_gives_clearly_different_faces():
    # (seeds, params) offsets from the default in units of each parameter's half-range
    offsets = np.array(
        [
            [abs(v - 1.0) / half_range(n) for n, v in HeadParams.random(s).as_dict().items()]
            for s in RANDOM_SEEDS
        ]
    )
    assert offsets.shape == (len(RANDOM_SEEDS), len(NAMES)) and offsets.dtype == np.float64
    # most draws have some parameter more than 60 % of its half-range away from the default ...
    assert np.mean(offsets.max(axis=1) > 0.6) >= 0.75, offsets.max(axis=1)
    # ... and every parameter varies between draws
    values = np.array([list(HeadParams.random(s).as_dict().values()) for s in RANDOM_SEEDS])
    assert np.all(values.std(axis=0) > 0.1 * np.array([half_range(n) for n in NAMES]))
