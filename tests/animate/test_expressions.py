"""The expression library: loading and validation, blending, intensity, and lips that never cross."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from mimetic.animate.expressions import (
    Expression,
    ExpressionError,
    ExpressionLibrary,
    blend,
    check_library,
    compose_pose,
    expression_pose,
    load_library,
)
from mimetic.engines import ENGINES, make_engine
from mimetic.errors import ActivationError, MimeticError
from mimetic.head.topology import build_topology
from mimetic.rig.activations import pose
from mimetic.testing import small_rig

REQUIRED = (
    "joy", "sadness", "anger", "fear", "surprise", "disgust",
    "smile", "fake_smile", "quizzical", "joyous_surprise", "weeping", "wink", "pucker", "jaw_drop",
)  # fmt: skip
UNIVERSAL = ("joy", "sadness", "anger", "fear", "surprise", "disgust")
LIP_TOLERANCE_CM = 0.02


@pytest.fixture(scope="module")
def library():
    return load_library()


def _mirror(channel: str) -> str:
    if channel.endswith("_L"):
        return channel[:-2] + "_R"
    if channel.endswith("_R"):
        return channel[:-2] + "_L"
    return channel


def _values(rig, pose_vector):
    return dict(zip(rig.channel_names, pose_vector, strict=True))


# ---- the built-in library


def test_load_library_has_the_thesis_expressions(library):
    assert set(REQUIRED) <= set(library.names)
    assert library.names[:6] == UNIVERSAL
    for name in library.names:
        expression = library[name]
        assert expression.name == name and expression.description and expression.values


@pytest.mark.parametrize("seed", [None, 3])
def test_builtin_expressions_name_valid_channels_within_range(library, seed):
    rig = small_rig(seed)
    check_library(library, rig)  # raises on an unknown channel or a value out of range
    for name in library.names:
        for channel, value in library[name].values.items():
            c = rig.channel(channel)
            assert c.minimum <= value <= c.maximum, (name, channel, value)


def test_library_and_expressions_are_frozen(library):
    with pytest.raises(dataclasses.FrozenInstanceError):
        library.source = "x"  # type: ignore[misc]
    with pytest.raises(TypeError):
        library["joy"].values["jaw_open"] = 0.3  # type: ignore[index]
    with pytest.raises(TypeError):
        library.expressions["new"] = library["joy"]  # type: ignore[index]
    assert load_library() is library  # built once


def test_universal_expressions_are_mirror_symmetric(library):
    for name in UNIVERSAL:
        values = library[name].values
        for channel, value in values.items():
            assert values.get(_mirror(channel), 0.0) == value, (name, channel)


def test_asymmetric_expressions_favour_the_left_side(library, rig):
    quizzical = _values(rig, expression_pose(rig, "quizzical"))
    assert quizzical["frontalis_outer_L"] > quizzical["frontalis_outer_R"]
    wink = _values(rig, expression_pose(rig, "wink"))
    assert wink["eyelid_upper_L"] > 0.5 and wink["eyelid_upper_R"] == 0.0


def test_fake_smile_has_no_eye_involvement(library):
    values = library["fake_smile"].values
    assert values["zygomatic_major_L"] > 0 and values["zygomatic_major_R"] > 0
    assert not any("oculi" in c or c.startswith("eyelid") for c in values)


def test_unknown_expression_suggests_a_name(library, rig):
    with pytest.raises(ExpressionError, match="did you mean joy") as info:
        library["jyo"]
    assert isinstance(info.value, MimeticError) and isinstance(info.value, ValueError)
    with pytest.raises(ExpressionError, match="jyo"):
        blend(rig, [("jyo", 1.0)])


# ---- blending


def test_blend_is_linear_before_clipping(rig):
    joy, surprise = expression_pose(rig, "joy"), expression_pose(rig, "surprise")
    result = blend(rig, [("joy", 0.4), ("surprise", 0.3)])
    assert result.shape == (len(rig.channels),) and result.dtype == np.float64
    np.testing.assert_allclose(result, 0.4 * joy + 0.3 * surprise, atol=1e-12)  # defaults are 0
    mapping = blend(rig, {"joy": 0.4, "surprise": 0.3})
    np.testing.assert_array_equal(mapping, result)


def test_blend_clips_the_weighted_sum_into_channel_ranges(rig):
    lo = np.array([c.minimum for c in rig.channels])
    hi = np.array([c.maximum for c in rig.channels])
    raw = 2.0 * expression_pose(rig, "surprise") + 1.5 * expression_pose(rig, "fear")  # before clipping
    result = blend(rig, [("surprise", 2.0), ("fear", 1.5)])
    assert np.all(result >= lo) and np.all(result <= hi)
    np.testing.assert_allclose(result, np.clip(raw, lo, hi), atol=1e-12)
    values = _values(rig, result)
    assert values["frontalis_inner_L"] == 1.0  # 2·1 + 1.5·1 clipped to the muscle maximum
    assert values["jaw_open"] == pytest.approx(min(2 * 0.25 + 1.5 * 0.12, rig.channel("jaw_open").maximum))


def test_blend_intensity_scales_the_whole_blend(rig):
    full = blend(rig, [("sadness", 0.6), ("anger", 0.3)])
    half = blend(rig, [("sadness", 0.6), ("anger", 0.3)], intensity=0.5)
    np.testing.assert_allclose(half, 0.5 * full, atol=1e-12)
    np.testing.assert_array_equal(blend(rig, [("joy", 1.0)], intensity=0.0), pose(rig))


def test_blend_of_nothing_is_the_rest_pose(rig):
    np.testing.assert_array_equal(blend(rig, []), pose(rig))


@pytest.mark.parametrize("weight", [-0.5, float("nan"), float("inf")])
def test_blend_rejects_bad_weights(rig, weight):
    with pytest.raises(ExpressionError, match="weight"):
        blend(rig, [("joy", weight)])


def test_blend_rejects_bad_intensity(rig):
    with pytest.raises(ExpressionError, match="intensity"):
        blend(rig, [("joy", 1.0)], intensity=-1.0)


def test_expression_pose_is_a_single_blend(rig):
    np.testing.assert_array_equal(expression_pose(rig, "fear", 0.7), blend(rig, [("fear", 0.7)]))


def test_blend_accepts_expression_objects(rig):
    custom = Expression("smirk", "one-sided smile", {"zygomatic_major_L": 0.8})
    values = _values(rig, blend(rig, [(custom, 0.5)]))
    assert values["zygomatic_major_L"] == pytest.approx(0.4) and values["zygomatic_major_R"] == 0.0


def test_blend_names_the_expression_when_the_rig_lacks_a_channel(rig):
    alien = Expression("alien", "", {"antenna_L": 1.0})
    with pytest.raises(ExpressionError, match=r"'alien'.*'antenna_L'"):
        blend(rig, [(alien, 1.0)])


def test_compose_pose_sets_values_after_the_blend(rig):
    result = _values(rig, compose_pose(rig, [("surprise", 1.0)], {"jaw_open": 0.05}))
    assert result["jaw_open"] == 0.05 and result["frontalis_inner_L"] == 1.0
    with pytest.raises(ActivationError, match="range"):
        compose_pose(rig, [], {"jaw_open": 2.0})
    with pytest.raises(ActivationError, match="jaw_open"):
        compose_pose(rig, [], {"jaw_opn": 0.1})


def test_blend_leaves_its_inputs_alone(rig, library):
    before = dict(library["joy"].values)
    weights = [("joy", 0.5)]
    blend(rig, weights, intensity=2.0)
    assert weights == [("joy", 0.5)] and dict(library["joy"].values) == before


# ---- user library files


def _write(tmp_path, data, name="mine.json"):
    path = tmp_path / name
    path.write_text(json.dumps(data) if not isinstance(data, str) else data)
    return path


def test_load_library_reads_a_user_file(tmp_path, rig):
    path = _write(
        tmp_path,
        {
            "format": "mimetic-expressions",
            "version": 1,
            "expressions": {"smirk": {"description": "one-sided", "values": {"zygomatic_major_L": 0.8}}},
        },
    )
    library = load_library(path)
    assert isinstance(library, ExpressionLibrary) and library.names == ("smirk",)
    assert library.source == "mine.json"
    values = _values(rig, expression_pose(rig, "smirk", library=library))
    assert values["zygomatic_major_L"] == 0.8


@pytest.mark.parametrize(
    ("entry", "words"),
    [
        (
            {"values": {"zygomatic_majr_L": 0.5}},
            ["'grin'", "unknown channel 'zygomatic_majr_L'", "zygomatic_major_L"],
        ),
        ({"values": {"jaw_open": 0.9}}, ["'grin'", "'jaw_open'", "outside its range"]),
        ({"values": {"jaw_open": "wide"}}, ["'grin'", "'jaw_open'", "not a finite number"]),
        ({"values": {"jaw_open": True}}, ["'grin'", "'jaw_open'", "not a finite number"]),
        ({"valeus": {"jaw_open": 0.1}}, ["'grin'", "unknown key", "'valeus'"]),
        ({"description": 3, "values": {}}, ["'grin'", "'description'"]),
        ([1, 2], ["'grin'", "expected an object"]),
    ],
)
def test_load_library_names_expression_and_channel_of_a_problem(tmp_path, entry, words):
    path = _write(tmp_path, {"expressions": {"grin": entry}})
    with pytest.raises(ExpressionError) as info:
        load_library(path)
    message = str(info.value)
    assert message.startswith("mine.json: ")
    for word in words:
        assert word in message, message


@pytest.mark.parametrize(
    ("content", "words"),
    [
        ("{not json", ["not valid JSON"]),
        ({"expressions": {}}, ["non-empty"]),
        ({"format": "other", "expressions": {"a": {"values": {}}}}, ["'format'"]),
        ({"version": 99, "expressions": {"a": {"values": {}}}}, ["newer", "upgrade"]),
        ({"expressions": {"big smile": {"values": {}}}}, ["'big smile'", "names use letters"]),
        ([], ["top level"]),
    ],
)
def test_load_library_rejects_malformed_files(tmp_path, content, words):
    with pytest.raises(ExpressionError) as info:
        load_library(_write(tmp_path, content))
    for word in words:
        assert word in str(info.value)


def test_load_library_missing_file(tmp_path):
    with pytest.raises(ExpressionError, match="does not exist"):
        load_library(tmp_path / "nope.json")


# ---- lips never cross


# The wire engine lets the lower lip's contact line rise above the upper one for closed-mouth
# poses (mentalis pushes the lower lip up; zygomatic major lifts the lower corner past the upper;
# orbicularis oris); the vector engine keeps the lips apart. Reported to the engine owners.
def _lip_pairs(rig):
    """(upper, lower) vertex ids (k,) of the lip contact ring, each pair at the same x."""
    ring = build_topology(rig.metadata["resolution"]).mouth.index[1]  # the contact line
    n = len(ring)
    j = np.arange(1, n // 2)  # upper columns, without the corners
    upper, lower = ring[j], ring[(n - j) % n]
    assert np.isin(upper, rig.regions["upper_lip"]).all() and np.isin(lower, rig.regions["lower_lip"]).all()
    np.testing.assert_allclose(rig.mesh.vertices[upper, 0], rig.mesh.vertices[lower, 0], atol=1e-9)
    return upper, lower


@pytest.fixture(scope="module")
def engines(rig):
    return {name: make_engine(rig, name) for name in ENGINES}


@pytest.mark.parametrize("engine_name", ENGINES)
@pytest.mark.parametrize("name", REQUIRED)
def test_expression_keeps_the_upper_lip_above_the_lower(rig, engines, name, engine_name):
    upper, lower = _lip_pairs(rig)
    vertices = engines[engine_name].deform(expression_pose(rig, name))
    assert vertices.shape == rig.mesh.vertices.shape
    gap = vertices[upper, 1] - vertices[lower, 1]  # (k,) cm, >= 0 when the lips do not cross
    assert gap.min() >= -LIP_TOLERANCE_CM, (
        f"{name} on {engine_name}: upper lip {-gap.min():.3f} cm below the lower"
    )


# ---- anger: the brow lowerer (AU4)


@pytest.mark.parametrize("engine_name", ENGINES)
def test_anger_brings_the_inner_brows_together_and_down(rig, engines, engine_name):
    """Corrugator, depressor supercilii and procerus: the brows' heads closer together and lower than
    at rest, and lower than the corrugator and procerus alone brought them."""
    engine = engines[engine_name]
    f = rig.mesh.faces

    def heads(values):
        v = engine.deform(values)
        return np.stack([rig.landmarks[f"brow_inner_{s}"].position(v, f) for s in "LR"])  # (2, 3)

    rest, anger = heads(pose(rig)), heads(expression_pose(rig, "anger"))
    without = _values(rig, expression_pose(rig, "anger"))
    without.update(depressor_supercilii_L=0.0, depressor_supercilii_R=0.0)
    no_depressor = heads(pose(rig, without))
    eye = np.linalg.norm(
        np.subtract(
            *(rig.landmarks[f"eye_{c}_corner_L"].position(rig.mesh.vertices, f) for c in ("outer", "inner"))
        )
    )
    assert anger[0, 0] - anger[1, 0] < rest[0, 0] - rest[1, 0] - 0.05 * eye  # closer across
    assert (anger[:, 1] < rest[:, 1] - 0.1 * eye).all()
    assert (anger[:, 1] < no_depressor[:, 1] - 0.05 * eye).all()
