"""ARKit-52 as a control layer (mimetic.animate.arkit): the table, names and sides, and the pose map.
(The bake and the reverse map: tests/export/test_arkit.py.)"""

from __future__ import annotations

import json

import numpy as np
import pytest

from mimetic.animate.arkit import (
    APPROXIMATE,
    ARKIT_NAMES,
    SPLIT,
    STATUS,
    UNSUPPORTED,
    ArkitError,
    arkit_pose,
    arkit_table,
    arkit_values,
    ict_name,
    resolve_name,
)
from mimetic.testing import require_shared_data

# Apple's ARFaceAnchor.BlendShapeLocation, in the order of its documentation
APPLE = (
    "eyeBlinkLeft", "eyeLookDownLeft", "eyeLookInLeft", "eyeLookOutLeft", "eyeLookUpLeft", "eyeSquintLeft",
    "eyeWideLeft", "eyeBlinkRight", "eyeLookDownRight", "eyeLookInRight", "eyeLookOutRight", "eyeLookUpRight",
    "eyeSquintRight", "eyeWideRight", "jawForward", "jawLeft", "jawRight", "jawOpen", "mouthClose",
    "mouthFunnel", "mouthPucker", "mouthLeft", "mouthRight", "mouthSmileLeft", "mouthSmileRight",
    "mouthFrownLeft", "mouthFrownRight", "mouthDimpleLeft", "mouthDimpleRight", "mouthStretchLeft",
    "mouthStretchRight", "mouthRollLower", "mouthRollUpper", "mouthShrugLower", "mouthShrugUpper",
    "mouthPressLeft", "mouthPressRight", "mouthLowerDownLeft", "mouthLowerDownRight", "mouthUpperUpLeft",
    "mouthUpperUpRight", "browDownLeft", "browDownRight", "browInnerUp", "browOuterUpLeft",
    "browOuterUpRight", "cheekPuff", "cheekSquintLeft", "cheekSquintRight", "noseSneerLeft", "noseSneerRight",
    "tongueOut",
)  # fmt: skip


# ---- the table and its names


def test_table_holds_apples_52_names_in_order():
    assert ARKIT_NAMES == APPLE
    assert len(set(ARKIT_NAMES)) == 52


def test_status_tables_give_reasons():
    assert set(UNSUPPORTED) == set()  # the tongue and the cheek puff have their own channels
    assert set(APPROXIMATE) == {"mouthClose", "mouthShrugUpper"}
    assert set(STATUS) == set(APPLE)
    for table in (SPLIT, APPROXIMATE, UNSUPPORTED):
        assert all(reason for reason in table.values())
    for name in SPLIT:
        shape = arkit_table()[name]
        assert shape.side and arkit_table()[shape.pair].side != shape.side


def test_table_values_name_channels_in_range(rig):
    for shape in arkit_table().values():
        values = dict(shape.values)
        if shape.status == "split":  # alone it may leave a range (divergence); with its pair it may not
            for channel, value in arkit_table()[shape.pair].values.items():
                values[channel] = values.get(channel, 0.0) + value
        for channel, value in values.items():
            c = rig.channel(channel)
            assert c.minimum - 1e-9 <= value <= c.maximum + 1e-9, (shape.name, channel, value)


def test_ict_names_resolve_to_apple_names():
    ict = [
        "browDown_L", "browDown_R", "browInnerUp_L", "browInnerUp_R", "browOuterUp_L", "browOuterUp_R",
        "cheekPuff_L", "cheekPuff_R", "cheekSquint_L", "cheekSquint_R", "eyeBlink_L", "eyeBlink_R",
        "eyeLookDown_L", "eyeLookDown_R", "eyeLookIn_L", "eyeLookIn_R", "eyeLookOut_L", "eyeLookOut_R",
        "eyeLookUp_L", "eyeLookUp_R", "eyeSquint_L", "eyeSquint_R", "eyeWide_L", "eyeWide_R", "jawForward",
        "jawLeft", "jawOpen", "jawRight", "mouthClose", "mouthDimple_L", "mouthDimple_R", "mouthFrown_L",
        "mouthFrown_R", "mouthFunnel", "mouthLeft", "mouthLowerDown_L", "mouthLowerDown_R", "mouthPress_L",
        "mouthPress_R", "mouthPucker", "mouthRight", "mouthRollLower", "mouthRollUpper", "mouthShrugLower",
        "mouthShrugUpper", "mouthSmile_L", "mouthSmile_R", "mouthStretch_L", "mouthStretch_R",
        "mouthUpperUp_L", "mouthUpperUp_R", "noseSneer_L", "noseSneer_R",
    ]  # fmt: skip
    assert len(ict) == 53
    for name in ict:
        apple, half = resolve_name(name)
        assert apple in APPLE
        assert half == (name[-1] if apple in ("browInnerUp", "cheekPuff") else "")
    assert resolve_name("eyeBlink_L") == ("eyeBlinkLeft", "")
    assert resolve_name("jawLeft") == ("jawLeft", "")  # a direction, not a side
    assert resolve_name("EYEBLINKLEFT") == ("eyeBlinkLeft", "")
    assert ict_name("mouthSmileRight") == "mouthSmile_R" and ict_name("mouthLeft") == "mouthLeft"
    with pytest.raises(ArkitError, match="eyeBlinkLeft"):
        resolve_name("eyeBlinkLft")
    with pytest.raises(ArkitError):
        resolve_name("jaw_L")


# ---- weights → activations


def test_arkit_pose_is_linear_then_clipped(rig):
    one = arkit_pose(rig, {"mouthSmileLeft": 0.5, "jawOpen": 0.5})
    two = arkit_pose(rig, {"mouthSmileLeft": 1.0, "jawOpen": 1.0})
    assert one.shape == (len(rig.channels),) and one.dtype == np.float64
    np.testing.assert_allclose(2 * one, two)
    stacked = arkit_pose(rig, {"mouthStretchLeft": 1.0, "mouthLeft": 1.0})  # risorius 1.0 + 0.6
    assert stacked[rig.channel_index("risorius_L")] == 1.0
    array = np.zeros(52)
    array[ARKIT_NAMES.index("jawOpen")] = 0.5
    np.testing.assert_array_equal(arkit_pose(rig, array), arkit_pose(rig, {"jawOpen": 0.5}))


def test_arkit_pose_accepts_ict_names_and_halves(rig):
    np.testing.assert_array_equal(
        arkit_pose(rig, {"eyeBlink_L": 1.0}), arkit_pose(rig, {"eyeBlinkLeft": 1.0})
    )
    halves = arkit_pose(rig, {"browInnerUp_L": 1.0, "browInnerUp_R": 1.0})
    np.testing.assert_allclose(halves, arkit_pose(rig, {"browInnerUp": 1.0}))
    assert arkit_values({"cheekPuff_L": 1.0}) == {"cheek_puff_L": 1.0}  # a half drives its side
    left = arkit_values({"browInnerUp_L": 1.0})
    assert left == pytest.approx({"frontalis_inner_L": 1.0})
    down = arkit_values({"browDown_L": 1.0})  # the brow lowerer: corrugator, depressor supercilii, procerus
    assert down == pytest.approx({"corrugator_L": 1.0, "depressor_supercilii_L": 1.0, "procerus": 0.5})


def test_arkit_pose_refuses_bad_weights(rig):
    weights = {"jawOpen": 0.3}
    arkit_pose(rig, weights)
    assert weights == {"jawOpen": 0.3}
    with pytest.raises(ArkitError, match=r"\[0, 1\]"):
        arkit_pose(rig, {"jawOpen": 1.5})
    with pytest.raises(ArkitError, match="twice"):
        arkit_pose(rig, {"eyeBlinkLeft": 1.0, "eyeBlink_L": 1.0})
    with pytest.raises(ArkitError, match="shape"):
        arkit_pose(rig, np.zeros(51))
    with pytest.raises(ArkitError):
        arkit_pose(rig, {"jawOpen": "wide"})


def test_mediapipe_scores_drive_the_rig(rig):
    folder = require_shared_data("mediapipe")
    data = json.loads((folder / "fixtures" / "portrait_expected_blendshapes.json").read_text())
    scores = dict(zip(data["labels"], data["scores"], strict=True))
    assert "_neutral" in scores and len(scores) == 52  # _neutral + 51 names (no tongueOut)
    pose = arkit_pose(rig, scores)
    # loose sanity only (model output, not ground truth): browDownLeft 0.79, mouthUpperUpLeft 0.82
    assert pose[rig.channel_index("corrugator_L")] > 0.5
    assert pose[rig.channel_index("levator_labii_mid_L")] > 0.5
