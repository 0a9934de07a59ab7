"""Expressions held under the lip sync (``lipsync.under_expression``, ``mimetic speak --expr``): the
smile stays, the bilabials still close the lips (measured on the wire engine's geometry)."""

from __future__ import annotations

import numpy as np
import pytest

from mimetic import quality
from mimetic.animate.expressions import blend
from mimetic.speech.lipsync import lip_sync, under_expression
from mimetic.speech.visemes import viseme_map
from mimetic.tasks.speak import SpeakOptions, held_expressions

SENTENCE = "my mom bought a map by the pub"
FPS = 30.0
CLOSED_REL = 0.005
"""Inner-lip gap at a closure, fraction of head size (0.33 % measured on the default head with joy:0.4)."""


def lip_gap(rig, engine, values) -> float:
    """The inner lips' gap of a pose on the engine (rig units)."""
    return quality.lip_gap(rig, engine.deform(values))


def test_bilabials_close_the_lips_under_joy(rig, engine):
    speech = lip_sync(rig, text=SENTENCE, fps=FPS, eyes=False)
    pose = blend(rig, [("joy", 0.4)])
    copy = speech.clip.values.copy()
    joy = under_expression(speech.clip, speech.timings, rig, pose)
    assert joy.channels == speech.clip.channels and joy.values.shape == speech.clip.values.shape
    assert joy.values.dtype == np.float64
    np.testing.assert_array_equal(speech.clip.values, copy)
    closures = [p for p in speech.timings.phones if p.label in ("P", "B", "M")]
    share = {label: viseme_map("en").phone(label).closure for label in ("P", "B", "M")}
    frames = [round((p.start_s + share[p.label] * p.duration_s / 2) * FPS) for p in closures]  # mid-closure
    assert len(frames) == 9
    for k in frames:
        assert lip_gap(rig, engine, joy.values[k]) < CLOSED_REL * rig.scale, k
    assert lip_gap(rig, engine, pose) > 2 * CLOSED_REL * rig.scale  # joy alone parts the lips
    # the smile is held through the closures and between them
    smile = rig.channel_index("zygomatic_major_L")
    assert (joy.values[:, smile] >= pose[smile] - 1e-9).all()


def test_speak_takes_expressions_as_name_colon_weight():
    assert held_expressions(["joy:0.4", "surprise=0.2", "anger"]) == (
        ("joy", 0.4),
        ("surprise", 0.2),
        ("anger", 1.0),
    )
    with pytest.raises(ValueError):
        held_expressions(["joy:lots"])
    assert SpeakOptions(text="hi", expressions=(("joy", 0.4),)).expressions == (("joy", 0.4),)


def test_speak_command_holds_the_expression_under_the_clip(tmp_path):
    """``mimetic speak --expr joy:0.4``: the written clip keeps joy's smile on every frame, and the
    same command without it has none."""
    from mimetic.animate.clipfiles import load_clip
    from mimetic.rig.format import save_rig
    from mimetic.testing import run_cli, small_rig

    rig = small_rig()
    path = tmp_path / "small.mrig"
    save_rig(rig, path)
    smile = blend(rig, [("joy", 0.4)])[rig.channel_index("zygomatic_major_L")]
    assert smile > 0.1
    values = {}
    for name, extra in (("joy", ("--expr", "joy:0.4")), ("plain", ())):
        out = tmp_path / f"{name}.json"
        result = run_cli("speak", path, "--text", SENTENCE, *extra, "-o", out, "--no-eyes")
        assert result.exit_code == 0, result.output
        clip = load_clip(out).sample(FPS, channels=rig)
        values[name] = clip.values[:, rig.channel_index("zygomatic_major_L")]
    assert values["joy"].min() >= smile - 1e-6
    assert values["plain"].max() < 0.05
