"""Tests for mimetic.tasks.parsing: the text forms of structured options, read or refused with the form."""

from __future__ import annotations

import math

import pytest

from mimetic.animate.keyframes import from_poses
from mimetic.tasks.parsing import channel_values, key_spec, name_value, pose_spec, proxy_spec, weights


@pytest.mark.parametrize(
    ("spec", "expected"),
    [
        ("jaw_open@1.25=0.3", ("jaw_open", 1.25, 0.3)),
        (" zygomatic_major_L @ 2s = -0.5 ", ("zygomatic_major_L", 2.0, -0.5)),
        ("a@0=1e-3", ("a", 0.0, 0.001)),
    ],
)
def test_key_spec_reads_channel_time_value(spec, expected):
    assert key_spec(spec) == expected


@pytest.mark.parametrize(
    ("spec", "match"),
    [
        ("jaw_open=0.3", "must look like CHANNEL@TIME_S=VALUE"),
        ("jaw_open@1.25", "must look like CHANNEL@TIME_S=VALUE"),
        ("jaw_open=0.3@1", "must look like CHANNEL@TIME_S=VALUE"),
        ("@1=0.3", "'' is not a channel name"),
        ("jaw_open@soon=0.3", "the time 'soon' is not a finite number"),
        ("jaw_open@1=nan", "the value 'nan' is not a finite number"),
    ],
)
def test_key_spec_rejects_malformed_specs(spec, match):
    with pytest.raises(ValueError, match=match):
        key_spec(spec)


def test_key_spec_feeds_edit():
    clip = from_poses([(0.0, {"b": 0.0}), (3.0, {"b": 1.0})], ["a", "b"])
    channel, time_s, value = key_spec("b@2.5=0.42")
    edited = clip.edit(channel, {time_s: value})
    assert edited.channel_values("b", time_s) == pytest.approx(0.42, abs=1e-12)
    assert math.isfinite(edited.duration_s)


def test_pose_spec_reads_rest_and_blends_and_refuses_bad_weights():
    assert pose_spec("0:rest") == (0.0, None)
    assert pose_spec("1.5s:surprise=0.8+joy") == (1.5, (("surprise", 0.8), ("joy", 1.0)))
    with pytest.raises(ValueError, match=r"weight 'x' of 'joy' is not a number"):
        pose_spec("1:joy=x")
    with pytest.raises(ValueError, match=r"expected TIME:EXPRESSION"):
        pose_spec("joy")


def test_weights_and_values_read_names_and_numbers():
    assert weights(["joy", "surprise=0.3"]) == (("joy", 1.0), ("surprise", 0.3))
    assert channel_values(["jaw_open=0.2"]) == (("jaw_open", 0.2),)
    with pytest.raises(ValueError, match=r"expected CHANNEL=VALUE, e.g. jaw_open=0.2"):
        channel_values(["jaw_open"])
    with pytest.raises(ValueError, match="expected NAME=VALUE"):
        name_value("nose_length=inf")


def test_proxy_spec_reads_auto_off_and_counts():
    assert proxy_spec("auto") == "auto" and proxy_spec(" OFF ") == "off"
    assert proxy_spec("20000") == 20_000 and proxy_spec("20_000") == 20_000
    assert isinstance(proxy_spec("5000"), int)
    for bad in ("fast", "-3", "2.5", ""):
        with pytest.raises(ValueError, match="auto, off or a skin vertex count"):
            proxy_spec(bad)
