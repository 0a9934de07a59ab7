"""Keyframe clips: interpolation, layers, B-spline displacement edits, JSON and CSV files."""

from __future__ import annotations

import json
import re
import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import mimetic.animate.clipfiles as clip_module
from mimetic.animate.clipfiles import load_clip, load_csv, save_clip, save_csv
from mimetic.animate.curves import BSplineEdit, ClipError, Curve, Key, fit_displacement, key_tangents
from mimetic.animate.expressions import expression_pose
from mimetic.animate.keyframes import KeyframeClip, Layer, from_clip, from_expressions, from_poses
from mimetic.errors import MimeticError, MimeticWarning
from mimetic.rig.activations import Clip, pose
from mimetic.rig.model import Channel

MODES = ("step", "linear", "cubic", "tcb")
FD_STEP_S = 1e-6  # finite-difference step for slopes; slope error ~ 1e-6 for these curves
SLOPE_TOL = 1e-4


def wavy_curve(interpolation="cubic", seed=0, n=7):
    """Keys at uneven times in [0, ~6] s with random values in [0, 1]."""
    rng = np.random.default_rng(seed)
    times = np.cumsum(rng.uniform(0.3, 1.5, n)) - 0.3
    return Curve.from_arrays(times, rng.uniform(0, 1, n), interpolation)


def two_channel_clip():
    base = Layer("base", {"a": wavy_curve(seed=1), "b": wavy_curve("linear", seed=2)})
    return KeyframeClip(("a", "b"), (base,))


def slope(curve, t, side):
    """One-sided finite-difference slope of ``curve`` at ``t`` (side -1 = left, +1 = right)."""
    if side > 0:
        return (curve.evaluate(t + FD_STEP_S) - curve.evaluate(t)) / FD_STEP_S
    return (curve.evaluate(t) - curve.evaluate(t - FD_STEP_S)) / FD_STEP_S


def leftovers(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


# --------------------------------------------------------------------------- interpolation


@pytest.mark.parametrize("interpolation", MODES)
def test_curve_each_mode_passes_through_its_keys(interpolation):
    curve = wavy_curve(interpolation, seed=3)
    times = curve.times_s.copy()
    values = curve.evaluate(times)
    assert values.shape == times.shape and values.dtype == np.float64
    np.testing.assert_array_equal(values, curve.values)
    np.testing.assert_array_equal(times, curve.times_s)  # input untouched


@settings(max_examples=60, deadline=None)
@given(
    gaps=st.lists(st.floats(0.01, 3.0), min_size=1, max_size=8),
    values=st.lists(st.floats(-10, 10), min_size=9, max_size=9),
    interpolation=st.sampled_from(MODES),
)
def test_curve_any_keys_are_interpolated_exactly(gaps, values, interpolation):
    times = np.cumsum(gaps) - 1.0
    if len(np.unique(times)) != len(times):
        return
    curve = Curve.from_arrays(times, values[: len(times)], interpolation)
    np.testing.assert_array_equal(curve.evaluate(times), values[: len(times)])


def test_curve_linear_is_piecewise_linear():
    curve = wavy_curve("linear", seed=4)
    t, p = curve.times_s, curve.values
    for i in range(len(t) - 1):
        u = np.linspace(0, 1, 11)[:-1]
        inside = curve.evaluate(t[i] + u * (t[i + 1] - t[i]))
        np.testing.assert_allclose(inside, p[i] + u * (p[i + 1] - p[i]), rtol=0, atol=1e-14)


def test_curve_step_holds_each_value_until_the_next_key():
    curve = Curve((Key(0.0, 0.2, "step"), Key(1.0, 0.7, "step"), Key(2.5, 0.1, "step")))
    times = np.array([0.0, 0.5, 0.999999, 1.0, 2.0, 2.499999, 2.5, 9.0])
    np.testing.assert_array_equal(curve.evaluate(times), [0.2, 0.2, 0.2, 0.7, 0.7, 0.7, 0.1, 0.1])


def test_curve_is_constant_outside_its_keys_and_with_one_key():
    curve = wavy_curve(seed=5)
    assert curve.evaluate(-100.0) == curve.values[0]
    np.testing.assert_array_equal(curve.evaluate([curve.times_s[-1] + 1, 1e6]), curve.values[-1])
    single = Curve((Key(2.0, 0.4),))
    out = single.evaluate(np.zeros((2, 3)))
    assert out.shape == (2, 3)
    np.testing.assert_array_equal(out, 0.4)


def test_curve_cubic_is_c1_at_interior_keys_with_uneven_spacing():
    curve = wavy_curve("cubic", seed=6, n=8)
    m_in, m_out = curve.tangents
    t, p = curve.times_s, curve.values
    for i in range(1, len(t) - 1):
        left, right = slope(curve, t[i], -1), slope(curve, t[i], +1)
        assert left == pytest.approx(right, abs=SLOPE_TOL)
        catmull_rom = (p[i + 1] - p[i - 1]) / (t[i + 1] - t[i - 1])
        assert right == pytest.approx(catmull_rom, abs=SLOPE_TOL)
        assert m_in[i] == pytest.approx(catmull_rom, rel=1e-12) and m_out[i] == m_in[i]
    # end keys: the one-sided chord slope
    assert slope(curve, t[0], +1) == pytest.approx((p[1] - p[0]) / (t[1] - t[0]), abs=SLOPE_TOL)


@settings(max_examples=60, deadline=None)
@given(
    gaps=st.lists(st.floats(0.05, 2.0), min_size=1, max_size=7),
    rate=st.floats(-5, 5),
    offset=st.floats(-3, 3),
)
def test_curve_cubic_reproduces_a_linear_ramp(gaps, rate, offset):
    times = np.cumsum(gaps)
    curve = Curve.from_arrays(times, offset + rate * times, "cubic")
    query = np.linspace(times[0], times[-1], 97)
    np.testing.assert_allclose(
        curve.evaluate(query), offset + rate * query, rtol=0, atol=1e-12 * (1 + 20 * abs(rate))
    )


def test_curve_tcb_with_zero_parameters_equals_catmull_rom():
    cubic = wavy_curve("cubic", seed=7, n=9)
    tcb = Curve.from_arrays(cubic.times_s, cubic.values, "tcb")
    query = np.linspace(-1, 12, 1001)
    np.testing.assert_array_equal(tcb.evaluate(query), cubic.evaluate(query))


def test_curve_tcb_tension_one_gives_zero_tangents():
    base = wavy_curve("cubic", seed=8)
    keys = tuple(Key(k.time_s, k.value, "tcb", tension=1.0) for k in base.keys)
    curve = Curve(keys)
    m_in, m_out = curve.tangents
    np.testing.assert_array_equal(m_in, 0.0)
    np.testing.assert_array_equal(m_out, 0.0)
    for t in curve.times_s[1:-1]:
        assert abs(slope(curve, t, +1)) < SLOPE_TOL and abs(slope(curve, t, -1)) < SLOPE_TOL


def test_curve_tcb_continuity_makes_a_corner():
    # uniform keys, chords +1 then -1: m_out = (1+C)/2 - (1-C)/2 = C, m_in = -C
    curve = Curve((Key(0, 0.0, "tcb"), Key(1, 1.0, "tcb", continuity=0.5), Key(2, 0.0, "tcb")))
    m_in, m_out = curve.tangents
    assert (m_in[1], m_out[1]) == pytest.approx((-0.5, 0.5), abs=1e-15)
    assert slope(curve, 1.0, -1) == pytest.approx(-0.5, abs=SLOPE_TOL)
    assert slope(curve, 1.0, +1) == pytest.approx(0.5, abs=SLOPE_TOL)
    smooth = Curve((Key(0, 0.0), Key(1, 1.0), Key(2, 0.0)))
    assert slope(smooth, 1.0, -1) == pytest.approx(slope(smooth, 1.0, +1), abs=SLOPE_TOL)


@pytest.mark.parametrize(("bias", "expected"), [(1.0, 1.0), (-1.0, 0.0), (0.0, 0.5)])
def test_curve_tcb_bias_tilts_the_tangent_toward_one_chord(bias, expected):
    # chord before key 1 has slope 1, after it 0: bias 1 takes the incoming chord, -1 the outgoing
    curve = Curve((Key(0, 0.0, "tcb"), Key(1, 1.0, "tcb", bias=bias), Key(2, 1.0, "tcb")))
    m_in, m_out = curve.tangents
    assert m_in[1] == pytest.approx(expected) and m_out[1] == pytest.approx(expected)
    assert slope(curve, 1.0, +1) == pytest.approx(expected, abs=SLOPE_TOL)


def test_key_tangents_match_kochanek_bartels_for_uniform_keys():
    # textbook KB source tangent (per unit parameter, spacing 1): (1-T)(1+C)(1+B)/2 Δ- + (1-T)(1-C)(1-B)/2 Δ+
    T, C, B = 0.2, -0.3, 0.4
    p = np.array([0.0, 0.5, 2.0])
    m_in, m_out = key_tangents(np.array([0.0, 1.0, 2.0]), p, np.array([[0, 0, 0], [T, C, B], [0, 0, 0]]))
    d_minus, d_plus = p[1] - p[0], p[2] - p[1]
    source = (1 - T) * ((1 + C) * (1 + B) * d_minus + (1 - C) * (1 - B) * d_plus) / 2
    destination = (1 - T) * ((1 - C) * (1 + B) * d_minus + (1 + C) * (1 - B) * d_plus) / 2
    assert m_out[1] == pytest.approx(source, rel=1e-14) and m_in[1] == pytest.approx(destination, rel=1e-14)


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: Key(float("nan"), 0.0), "time_s=nan must be finite"),
        (lambda: Key(0.0, float("inf")), "value=inf must be finite"),
        (lambda: Key(0.0, 1.0, "bezier"), "unknown interpolation 'bezier'; use one of step, linear"),
        (lambda: Key(0.0, 1.0, "cubic", tension=0.5), "only applies to 'tcb' keys"),
        (lambda: Key(0.0, 1.0, "tcb", bias=1.5), r"bias=1.5 must be in \[-1, 1\]"),
        (lambda: Key("0", 1.0), "must be a number"),
        (lambda: Curve(()), "at least one key"),
        (lambda: Curve((Key(1, 0), Key(0, 1))), r"comes before key 0 .* sort keys by time"),
        (lambda: Curve((Key(1, 0), Key(1, 1))), "keys 0 and 1 are both at t=1 s; keep one"),
        (lambda: wavy_curve().evaluate([0.0, float("nan")]), "times_s must be finite"),
    ],
)
def test_keys_and_curves_reject_bad_input_with_a_fix(make, match):
    with pytest.raises(ClipError, match=match) as info:
        make()
    assert isinstance(info.value, MimeticError) and isinstance(info.value, ValueError)


# --------------------------------------------------------------------------- sampling


def test_sample_includes_both_ends_of_the_duration():
    clip = KeyframeClip(("a",), (Layer("base", {"a": Curve((Key(0, 0.0, "linear"), Key(2, 1.0)))}),))
    assert clip.duration_s == 2.0
    baked = clip.sample(24)
    assert isinstance(baked, Clip) and baked.fps == 24 and baked.channels == ("a",)
    assert baked.values.shape == (49, 1) and baked.values.dtype == np.float64
    assert baked.values[0, 0] == 0.0 and baked.values[-1, 0] == 1.0
    assert baked.values[12, 0] == pytest.approx(0.25, abs=1e-15)


def test_sample_frame_rates_agree_at_shared_times():
    clip = two_channel_clip()
    at_24 = clip.sample(24).values
    at_60 = clip.sample(60).values
    # 24 and 60 fps share every 1/12 s: frames 2k and 5k
    k = np.arange(min(len(at_24[::2]), len(at_60[::5])))
    np.testing.assert_array_equal(at_24[2 * k], at_60[5 * k])
    ntsc = clip.sample(60000 / 1001)
    times = np.arange(ntsc.n_frames) * 1001 / 60000
    np.testing.assert_allclose(ntsc.values, clip.evaluate(times), rtol=0, atol=1e-12)
    assert times[-1] <= clip.duration_s < times[-1] + 1001 / 60000


def test_sample_with_names_reorders_and_fills_missing_channels():
    clip = two_channel_clip()
    full = clip.sample(30).values
    picked = clip.sample(30, channels=["b", "extra", "a"], defaults={"extra": 0.25})
    assert picked.channels == ("b", "extra", "a") and picked.values.shape == (len(full), 3)
    np.testing.assert_array_equal(picked.values[:, 0], full[:, 1])
    np.testing.assert_array_equal(picked.values[:, 1], 0.25)
    np.testing.assert_array_equal(picked.values[:, 2], full[:, 0])


def test_sample_with_channels_clips_into_ranges_and_uses_their_defaults():
    curve = Curve((Key(0, 0.0), Key(0.5, 1.0), Key(1.0, 1.0), Key(1.5, 0.0)))  # Catmull-Rom overshoots 1
    clip = KeyframeClip(("m",), (Layer("base", {"m": curve}),))
    assert clip.evaluate(np.linspace(0, 1.5, 151)).max() > 1.0
    channels = (Channel("m", 0.0, 1.0), Channel("jaw", -0.1, 0.5, default=0.2, unit="rad"))
    baked = clip.sample(100, channels=channels)
    assert baked.channels == ("m", "jaw") and baked.values.shape == (151, 2)
    assert baked.values[:, 0].max() == 1.0 and baked.values[:, 0].min() == 0.0
    np.testing.assert_array_equal(baked.values[:, 1], 0.2)
    with pytest.raises(ClipError, match="'m' is not a channel of the rig"):
        clip.sample(30, channels=[Channel("n", 0.0, 1.0)])


# --------------------------------------------------------------------------- layers


def test_additive_layer_weight_scales_its_offset():
    clip = two_channel_clip()
    offset = Curve.from_arrays([0.0, 1.0, 3.0], [0.1, -0.2, 0.3], "cubic")
    times = np.linspace(0, clip.duration_s, 200)
    base = clip.evaluate(times)
    for weight in (0.0, 0.5, 1.0, 2.0):
        layered = clip.with_layer(Layer("offset", {"a": offset}, "additive", weight))
        values = layered.evaluate(times)
        assert values.shape == (200, 2)
        np.testing.assert_allclose(values[:, 0] - base[:, 0], weight * offset.evaluate(times), atol=1e-15)
        np.testing.assert_array_equal(values[:, 1], base[:, 1])


def test_absolute_layer_weight_blends_toward_its_curve():
    clip = two_channel_clip()
    over = Curve((Key(0.0, 0.9),))
    times = np.linspace(0, 5, 50)
    base = clip.channel_values("a", times)
    blended = clip.with_layer(Layer("over", {"a": over}, "absolute", 0.25)).channel_values("a", times)
    np.testing.assert_allclose(blended, 0.75 * base + 0.25 * 0.9, atol=1e-15)


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (lambda: KeyframeClip(("a",), ()), "at least one layer"),
        (lambda: KeyframeClip(("a",), (Layer("e", {}, "additive"),)), "base and must be 'absolute'"),
        (lambda: KeyframeClip(("a", "a"), (Layer("b", {}),)), "'a' appears twice"),
        (lambda: KeyframeClip(("a",), (Layer("b", {}), Layer("b", {}))), "two layers are named 'b'"),
        (lambda: KeyframeClip(("jaw_open",), (Layer("b", {"jaw_opne": Curve((Key(0, 0),))}),)), "jaw_open"),
        (lambda: Layer("b", {}, "multiply"), "unknown mode 'multiply'"),
        (lambda: KeyframeClip(("a",), (Layer("b", {}),), -1.0), "duration_s=-1 must be >= 0"),
    ],
)
def test_clip_rejects_bad_layers_with_a_fix(make, match):
    with pytest.raises(ClipError, match=match):
        make()


# --------------------------------------------------------------------------- B-spline edits


@pytest.mark.parametrize(
    ("time_s", "first_knot", "last_knot"),
    [(1.3, 2, 9), (1.25, 2, 8)],  # inside interval j=5 reaches knots j-3…j+4; on knot 5 only 2…8
)
def test_fit_displacement_reaches_exactly_its_knot_span(time_s, first_knot, last_knot):
    h = 0.25
    edit = fit_displacement([time_s], [0.3], h)
    assert edit.support_s == pytest.approx((first_knot * h, last_knot * h), abs=1e-12)
    assert edit.evaluate(time_s) == pytest.approx(0.3, abs=1e-12)
    outside = np.concatenate([np.linspace(-5, first_knot * h, 200), np.linspace(last_knot * h, 9, 200)])
    assert np.all(edit.evaluate(outside) == 0.0)  # exactly zero, not just small
    just_inside = np.array([first_knot * h + 0.01 * h, last_knot * h - 0.01 * h])
    assert np.all(edit.evaluate(just_inside) != 0.0)
    inside = np.linspace(first_knot * h, last_knot * h, 101)[1:-1]
    assert np.all(np.abs(edit.evaluate(inside)) > 0)


def test_fit_displacement_is_zero_between_far_apart_constraints():
    edit = fit_displacement([1.0, 6.0], [0.2, -0.1], 0.25)
    gap = np.linspace(2.0 + 1e-9, 5.25 - 1e-9, 300)  # 1.0 is knot 4 → up to 7 h = 1.75 s; 6.0 from 5.25 s
    assert np.all(edit.evaluate(gap) == 0.0)
    np.testing.assert_allclose(edit.evaluate([1.0, 6.0]), [0.2, -0.1], rtol=0, atol=1e-12)


def test_fit_displacement_wider_knots_reach_further():
    times = np.linspace(0, 4, 401)
    narrow = np.flatnonzero(fit_displacement([2.0], [1.0], 0.1).evaluate(times))
    wide = np.flatnonzero(fit_displacement([2.0], [1.0], 0.4).evaluate(times))
    assert times[narrow].max() - times[narrow].min() == pytest.approx(0.6 - 0.02, abs=1e-9)
    assert times[wide].max() - times[wide].min() == pytest.approx(2.4 - 0.02, abs=1e-9)


@settings(max_examples=40, deadline=None)
@given(
    h=st.sampled_from([0.1, 0.25, 0.5]),
    start=st.floats(0, 3),
    gaps=st.lists(st.floats(1.0, 6.0), min_size=0, max_size=5),
    targets=st.lists(st.floats(-1, 1), min_size=6, max_size=6),
)
def test_edit_hits_feasible_constraints_within_1e9(h, start, gaps, targets):
    # constraints at least one knot apart can always be met exactly (Schoenberg–Whitney)
    times = start + h * np.concatenate([[0.0], np.cumsum(gaps)])
    constraints = dict(zip(times.tolist(), targets, strict=False))
    clip = two_channel_clip()
    with warnings.catch_warnings():
        warnings.simplefilter("error", MimeticWarning)
        edited = clip.edit("a", constraints, knot_spacing_s=h)
    got = edited.channel_values("a", list(constraints))
    np.testing.assert_allclose(got, list(constraints.values()), rtol=0, atol=1e-9)


def test_edit_leaves_the_base_and_other_channels_untouched():
    clip = two_channel_clip()
    edited = clip.edit("a", {2.0: 0.9}, knot_spacing_s=0.25)
    assert [layer.name for layer in edited.layers] == ["base", "edit"]
    assert edited.layers[0] is clip.layers[0]
    assert edited.layers[1].mode == "additive" and set(edited.layers[1].curves) == {"a"}
    assert len(clip.layers) == 1  # the original clip is not changed
    times = np.linspace(0, clip.duration_s, 300)
    before, after = clip.evaluate(times), edited.evaluate(times)
    np.testing.assert_array_equal(after[:, 1], before[:, 1])
    far = np.abs(times - 2.0) >= 4 * 0.25
    np.testing.assert_array_equal(after[far, 0], before[far, 0])
    assert edited.channel_values("a", 2.0) == pytest.approx(0.9, abs=1e-12)


def test_edit_survives_a_new_base():
    clip = two_channel_clip()
    edited = clip.edit("a", {1.0: 0.8, 3.0: 0.1}, knot_spacing_s=0.5)
    displacement = edited.layer("edit").curves["a"]
    new_base = Layer("base", {"a": wavy_curve(seed=11), "b": wavy_curve(seed=12), "c": wavy_curve(seed=13)})
    rebased = edited.with_base(new_base)
    assert rebased.layers[1] is edited.layers[1]
    assert rebased.channels == ("a", "b", "c") and rebased.duration_s == edited.duration_s
    times = np.linspace(0, 5, 200)
    np.testing.assert_allclose(
        rebased.channel_values("a", times),
        new_base.curves["a"].evaluate(times) + displacement.evaluate(times),
        rtol=0,
        atol=1e-15,
    )


def test_edit_twice_in_one_layer_merges_displacements():
    clip = two_channel_clip()
    once = clip.edit("a", {1.0: 0.8})
    twice = once.edit("a", {4.0: 0.2})
    assert len(twice.layers) == 2 and isinstance(twice.layer("edit").curves["a"], BSplineEdit)
    np.testing.assert_allclose(twice.channel_values("a", [1.0, 4.0]), [0.8, 0.2], rtol=0, atol=1e-12)
    with pytest.raises(
        ClipError, match=re.escape("knot spacings 0.25 s and 0.5 s; edit with the same knot_spacing_s")
    ):
        once.edit("a", {3.0: 0.5}, knot_spacing_s=0.5)
    separate = once.edit("a", {3.0: 0.5}, knot_spacing_s=0.5, layer="edit2")
    assert [x.name for x in separate.layers] == ["base", "edit", "edit2"]


def test_edit_in_a_weighted_layer_still_hits_the_constraint():
    clip = two_channel_clip().with_layer(Layer("edit", {}, "additive", 0.5))
    edited = clip.edit("b", {2.2: 0.6})
    assert edited.channel_values("b", 2.2) == pytest.approx(0.6, abs=1e-12)
    muted = two_channel_clip().with_layer(Layer("edit", {}, "additive", 0.0))
    with pytest.raises(ClipError, match="cannot change 'b'"):
        muted.edit("b", {2.2: 0.6})
    with pytest.raises(ClipError, match="layer 'base' is absolute"):
        two_channel_clip().edit("b", {2.2: 0.6}, layer="base")


def test_edit_with_too_many_constraints_in_one_knot_warns():
    clip = two_channel_clip()
    wiggle = {1.0 + 0.04 * i: (-1.0) ** i for i in range(6)}  # 6 values in one 0.25 s knot interval
    with pytest.warns(MimeticWarning, match="use a smaller knot_spacing_s"):
        clip.edit("a", wiggle, knot_spacing_s=0.25)
    with warnings.catch_warnings():
        warnings.simplefilter("error", MimeticWarning)
        fine = clip.edit("a", wiggle, knot_spacing_s=0.04)
    np.testing.assert_allclose(fine.channel_values("a", list(wiggle)), list(wiggle.values()), atol=1e-9)


def test_edit_regularization_shrinks_the_displacement():
    exact = fit_displacement([1.0, 1.05], [0.5, -0.5], 0.25)
    ridge = fit_displacement([1.0, 1.05], [0.5, -0.5], 0.25, regularization=1e-3)
    assert np.linalg.norm(ridge.coefficients) < np.linalg.norm(exact.coefficients)
    np.testing.assert_allclose(exact.evaluate([1.0, 1.05]), [0.5, -0.5], atol=1e-9)


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda c: c.edit("z", {1.0: 0.5}), "unknown channel 'z'"),
        (lambda c: c.edit("a", {}), "has no constraints"),
        (lambda c: c.edit("a", {1.0: float("nan")}), "value at t=1 s=nan must be finite"),
        (lambda c: c.edit("a", {1.0: 0.5}, knot_spacing_s=0), "knot_spacing_s=0 must be > 0"),
        (lambda c: c.edit("a", [(1.0, 0.5), (1.0, 0.6)]), "constraint times must be distinct"),
    ],
)
def test_edit_rejects_bad_input(call, match):
    with pytest.raises(ClipError, match=match):
        call(two_channel_clip())


def test_bspline_edit_sum_needs_aligned_knots():
    a = BSplineEdit(0.5, 0.25, (1.0, 2.0))
    b = BSplineEdit(1.0, 0.25, (3.0,))
    total = a + b
    assert total == BSplineEdit(0.5, 0.25, (1.0, 2.0, 3.0))
    times = np.linspace(0, 3, 61)
    np.testing.assert_allclose(total.evaluate(times), a.evaluate(times) + b.evaluate(times), atol=1e-15)
    with pytest.raises(ClipError, match="not aligned"):
        a + BSplineEdit(0.6, 0.25, (1.0,))


# --------------------------------------------------------------------------- building clips


def test_from_poses_expression_sequence_passes_through_each_pose(rig):
    rest = pose(rig)
    joy, surprise = expression_pose(rig, "joy"), expression_pose(rig, "surprise")
    clip = from_poses([(0.0, rest), (0.5, joy), (1.0, surprise), (1.5, rest)], rig)
    assert clip.channels == rig.channel_names and clip.duration_s == 1.5
    baked = clip.sample(30, channels=rig)
    assert baked.values.shape == (46, len(rig.channels)) and baked.values.dtype == np.float64
    for frame, expected in ((0, rest), (15, joy), (30, surprise), (45, rest)):
        np.testing.assert_allclose(baked.values[frame], expected, rtol=0, atol=1e-12)
    lo = np.array([c.minimum for c in rig.channels])
    hi = np.array([c.maximum for c in rig.channels])
    assert np.all(baked.values >= lo) and np.all(baked.values <= hi)
    same = from_expressions(rig, [(0.0, None), (0.5, "joy"), (1.0, "surprise"), (1.5, "rest")])
    assert same == clip


def test_from_poses_mappings_fill_defaults_and_reject_unknown_channels():
    channels = (Channel("a", 0, 1), Channel("jaw", -0.1, 0.5, default=0.1, unit="rad"))
    clip = from_poses([(0.0, {"a": 0.5}), (1.0, {"jaw": 0.3})], channels, interpolation="linear")
    np.testing.assert_allclose(clip.evaluate([0.0, 0.5, 1.0]), [[0.5, 0.1], [0.25, 0.2], [0.0, 0.3]])
    with pytest.raises(ClipError, match="pose 0: unknown channel 'jow'; did you mean jaw"):
        from_poses([(0.0, {"jow": 0.1})], channels)
    with pytest.raises(ClipError, match=r"pose 1 has shape \(3,\); expected \(2,\)"):
        from_poses([(0.0, [0, 0]), (1.0, [0, 0, 0])], ["a", "b"])
    with pytest.raises(ClipError, match=re.escape("pose 1 at t=0.5 s is not after pose 0 at t=1 s")):
        from_poses([(1.0, [0, 0]), (0.5, [0, 0])], ["a", "b"])


def test_from_clip_reproduces_every_frame():
    rng = np.random.default_rng(3)
    values = rng.uniform(0, 1, (40, 3))
    baked = Clip(("x", "y", "z"), values, 25.0)
    clip = from_clip(baked)
    assert clip.duration_s == pytest.approx(39 / 25)
    again = clip.sample(25.0)
    assert again.values.shape == (40, 3)
    np.testing.assert_array_equal(again.values, values)
    np.testing.assert_array_equal(baked.values, values)  # input untouched


def test_from_clip_tolerance_drops_keys_within_tolerance():
    times = np.arange(200) / 50
    rng = np.random.default_rng(4)
    values = np.stack([np.sin(times), np.full(200, 0.3), rng.normal(0, 1e-3, 200)], axis=1)
    clip = from_clip(Clip(("s", "flat", "noise"), values, 50.0), tolerance=1e-3)
    counts = {c: len(curve.keys) for c, curve in clip.base.curves.items()}
    assert counts["flat"] == 2 and 2 < counts["s"] < 60
    assert np.abs(clip.sample(50.0).values - values).max() <= 1e-3 + 1e-15


def test_from_clip_rejects_nan_frames():
    values = np.zeros((5, 2))
    values[3, 1] = np.nan
    with pytest.raises(MimeticError, match="'b' in frame 3 is not finite"):
        from_clip(Clip(("a", "b"), values, 30.0))


# --------------------------------------------------------------------------- JSON files


def edited_clip():
    tcb = Curve((Key(0.0, 0.1, "tcb", 0.3, -0.2, 0.5), Key(1.1, 0.7, "step"), Key(2.0, 1 / 3, "linear")))
    base = Layer("base", {"a": wavy_curve(seed=21), "b": tcb})
    clip = KeyframeClip(("a", "b", "c"), (base, Layer("breath", {"c": wavy_curve(seed=22)}, "additive", 0.3)))
    return clip.edit("a", {1.7: 0.123456789012345, 3.3: 0.9}, knot_spacing_s=0.3)


def test_save_load_clip_round_trip_is_exact(tmp_path):
    clip = edited_clip()
    path = save_clip(clip, tmp_path / "clip.json")
    assert path == tmp_path / "clip.json" and leftovers(tmp_path) == []
    loaded = load_clip(path)
    assert loaded == clip
    times = np.linspace(-1, 7, 333)
    np.testing.assert_array_equal(loaded.evaluate(times), clip.evaluate(times))
    document = json.loads(path.read_text())
    assert document["format"] == "mimetic-clip" and document["version"] == 1
    assert document["layers"][0]["curves"]["b"]["keys"][0] == [0.0, 0.1, "tcb", 0.3, -0.2, 0.5]
    assert set(document["layers"][2]["curves"]["a"]["bspline"]) == {"start_s", "spacing_s", "coefficients"}


@settings(max_examples=30, deadline=None)
@given(
    values=st.lists(st.floats(-1e6, 1e6, allow_subnormal=True), min_size=1, max_size=6),
    gaps=st.lists(st.floats(1e-6, 1e3), min_size=6, max_size=6),
    weight=st.floats(-2, 2),
    modes=st.lists(st.sampled_from(MODES), min_size=6, max_size=6),
)
def test_save_load_clip_round_trip_for_any_floats(tmp_path_factory, values, gaps, weight, modes):
    times = np.cumsum(gaps[: len(values)]).tolist()
    keys = tuple(Key(t, v, m) for t, v, m in zip(times, values, modes, strict=False))
    clip = KeyframeClip(
        ("a",),
        (
            Layer("base", {"a": Curve(keys)}),
            Layer("e", {"a": BSplineEdit(-0.7, 0.3, values)}, "additive", weight),
        ),
    )
    path = save_clip(clip, tmp_path_factory.mktemp("rt") / "c.json")
    assert load_clip(path) == clip


def test_load_clip_accepts_short_keys(tmp_path):
    path = tmp_path / "hand.json"
    path.write_text(
        json.dumps(
            {
                "format": "mimetic-clip",
                "version": 1,
                "layers": [{"name": "base", "curves": {"jaw_open": {"keys": [[0, 0], [1, 0.3, "linear"]]}}}],
            }
        )
    )
    clip = load_clip(path)
    assert clip.channels == ("jaw_open",) and clip.duration_s == 1.0
    assert clip.base.curves["jaw_open"].keys[0] == Key(0.0, 0.0, "cubic")


def good_document():
    return {
        "format": "mimetic-clip",
        "version": 1,
        "duration_s": 2.0,
        "channels": ["a"],
        "layers": [
            {"name": "base", "mode": "absolute", "weight": 1.0, "curves": {"a": {"keys": [[0, 0], [1, 1]]}}}
        ],
    }


def _with(path, value):
    document = good_document()
    target = document
    for step in path[:-1]:
        target = target[step]
    target[path[-1]] = value
    return document


@pytest.mark.parametrize(
    ("document", "match"),
    [
        (_with(["format"], "mimetic-rig"), "not a mimetic clip"),
        (_with(["version"], 2), "newer mimetic .* Upgrade mimetic"),
        (
            _with(["layers", 0, "curves", "a", "keys"], [[1, 0], [0, 1]]),
            r"layers\[0\]\.curves\['a'\]\.keys: key 1",
        ),
        (_with(["layers", 0, "curves", "a", "keys"], [[0, 0], [0, 1]]), "both at t=0 s"),
        (
            _with(["layers", 0, "curves", "a", "keys"], [[0, 0], [1, 1, "smooth"]]),
            r"keys\[1\]: key at t=1 s: unknown interpolation 'smooth'",
        ),
        (
            _with(["layers", 0, "curves", "a", "keys"], [[0, "x"]]),
            r"keys\[0\]: key at t=0 s: value='x' must be",
        ),
        (_with(["layers", 0, "curves", "a", "keys"], [[0]]), r"keys\[0\] = \[0\]: a key is"),
        (_with(["layers", 0, "curves", "a"], {"bspline": {"start_s": 0}}), "missing field 'coefficients'"),
        (_with(["layers", 0, "mode"], "over"), r"layers\[0\]: layer 'base': unknown mode 'over'"),
        (_with(["layers", 0, "colour"], "red"), "unknown field 'colour'"),
        (_with(["channels"], ["b"]), "unknown channel 'a'"),
        (_with(["layers"], []), "'layers' must be a non-empty list"),
    ],
)
def test_load_clip_names_file_and_key_of_a_problem(tmp_path, document, match):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(document, indent=1))
    with pytest.raises(ClipError, match=match) as info:
        load_clip(path)
    assert str(info.value).startswith("bad.json")


@pytest.mark.parametrize(
    ("text", "match"),
    [
        (
            '{\n "format": "mimetic-clip",\n "version": 1,\n "layers": [NaN]\n}',
            "bad.json line 4: NaN is not allowed",
        ),
        ('{\n "format": "mimetic-clip",\n "version": 1,,\n}', "bad.json line 3 column 15: not valid JSON"),
        ("[1, 2]", "holds a JSON object; got list"),
    ],
)
def test_load_clip_reports_the_line_of_bad_json(tmp_path, text, match):
    path = tmp_path / "bad.json"
    path.write_text(text)
    with pytest.raises(ClipError, match=match):
        load_clip(path)


def test_load_clip_missing_file_says_so(tmp_path):
    with pytest.raises(ClipError, match="no such file"):
        load_clip(tmp_path / "nothing.json")


def test_save_clip_failure_keeps_the_old_file(tmp_path, monkeypatch):
    path = tmp_path / "clip.json"
    save_clip(edited_clip(), path)
    good = path.read_bytes()

    original = clip_module._document
    # a document that fails only after the good part has been serialised
    monkeypatch.setattr(clip_module, "_document", lambda clip: {"ok": original(clip), "bad": object()})
    with pytest.raises(TypeError, match="not JSON serializable"):
        save_clip(two_channel_clip(), path)
    assert path.read_bytes() == good
    assert leftovers(tmp_path) == []
    assert load_clip(path) == edited_clip()


# --------------------------------------------------------------------------- CSV files


def test_save_load_csv_round_trip_within_written_precision(tmp_path):
    clip = edited_clip()
    for fps, digits, tol in ((24, 6, 5e-6), (59.94, None, 0.0)):
        path = save_csv(clip, tmp_path / "curves.csv", fps=fps, digits=digits)
        header = path.read_text().splitlines()[0]
        assert header == "time_s,a,b,c"
        loaded = load_csv(path)
        assert loaded.channels == clip.channels
        original, again = clip.sample(fps).values, loaded.sample(fps).values
        assert again.shape == original.shape
        np.testing.assert_allclose(again, original, rtol=tol, atol=tol * 1e-3)


def test_save_csv_writes_a_baked_clip_at_its_own_rate(tmp_path):
    baked = Clip(("a",), np.array([[0.1], [0.2], [0.3]]), 2.0)
    path = save_csv(baked, tmp_path / "b.csv")
    assert path.read_text() == "time_s,a\n0.0,0.1\n0.5,0.2\n1.0,0.3\n"
    with pytest.raises(ClipError, match="already sampled at 2 fps"):
        save_csv(baked, tmp_path / "b.csv", fps=30)
    with pytest.raises(ClipError, match="needs fps="):
        save_csv(two_channel_clip(), tmp_path / "k.csv")


def test_save_csv_nan_keeps_the_old_file(tmp_path):
    path = tmp_path / "b.csv"
    path.write_text("time_s,a\n0.0,1.0\n")
    values = np.array([[0.1], [np.nan]])
    with pytest.raises(MimeticError, match="frame 1 is not finite"):
        save_csv(Clip(("a",), values, 30.0), path)
    assert path.read_text() == "time_s,a\n0.0,1.0\n" and leftovers(tmp_path) == []


@pytest.mark.parametrize(
    ("text", "match"),
    [
        ("time,a\n0,1\n", "line 1: the first column must be 'time_s'; got 'time'"),
        ("time_s,a,a\n0,1,2\n", "channel 'a' appears twice"),
        ("time_s,a,b\n0,1,2\n0.1,1\n", r"line 3: expected 3 values \(time_s, a, b, …\); got 2"),
        ("time_s,a\n0,1\n0.1,abc\n", "line 3, column 'a': 'abc' is not a number"),
        ("time_s,a\n0,nan\n", "line 2, column 'a': nan must be finite"),
        ("time_s,a\n0,1\n0.2,1\n0.1,1\n", "line 4: time_s 0.1 is not after the previous row's 0.2"),
        ("", "empty file"),
        ("time_s,a\n", "no rows after the header"),
    ],
)
def test_load_csv_names_file_and_line_of_a_problem(tmp_path, text, match):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(ClipError, match=match) as info:
        load_csv(path)
    assert str(info.value).startswith("bad.csv")


def test_load_csv_accepts_uneven_times_and_blank_lines(tmp_path):
    path = tmp_path / "uneven.csv"
    path.write_text("time_s, a\n0.0,0\n\n0.3,0.6\n1.0,0.2\n")
    clip = load_csv(path)
    assert clip.duration_s == 1.0
    np.testing.assert_allclose(clip.channel_values("a", [0.15, 0.3, 0.65]), [0.3, 0.6, 0.4], atol=1e-15)
