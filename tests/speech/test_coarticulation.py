"""Coarticulation: timed phones → a Clip. Lip closure is measured on the wire engine's geometry;
the rest against the viseme targets, the linear baseline, and the rig's ranges."""

from __future__ import annotations

import numpy as np
import pytest

from mimetic.errors import SpeechError
from mimetic.quality import lip_gap
from mimetic.rig.activations import Clip
from mimetic.speech.coarticulation import (
    BLINK_S,
    EYE_CHANNELS,
    add_eye_motion,
    coarticulate,
    linear_clip,
)
from mimetic.speech.phones import SILENCE, Phone, PhoneTimings
from mimetic.speech.visemes import channel_group, load_viseme_map, phone_targets, viseme_map

BILABIAL = ("P", "B", "M")
SENTENCE = (  # "my mom bought a map by the pub", durations in ms, a pause after "map"
    "M:70 AY:160 M:60 AA:130 M:70 B:60 AO:140 T:60 AH:50 M:70 AE:150 P:80 SIL:250 "
    "B:60 AY:150 DH:40 AH:60 P:70 AH:110 B:80"
)


def _timings(spec: str, language: str = "en", start_s: float = 0.3, tail_s: float = 0.3) -> PhoneTimings:
    """Phones from "LABEL:ms LABEL:ms ...", back to back from ``start_s``, then a pause of ``tail_s``."""
    phones, t = [], start_s
    for item in spec.split():
        label, ms = item.split(":")
        phones.append(Phone(label, t, t + float(ms) / 1000))
        t += float(ms) / 1000
    phones.append(Phone(SILENCE, t, t + tail_s))
    return PhoneTimings(tuple(phones), language)


def _frame(phone: Phone, fps: float) -> int:
    """The frame nearest the phone's centre (its dominance peak)."""
    return round((phone.start_s + phone.end_s) / 2 * fps)


def _closure_frame(phone: Phone, fps: float) -> int:
    """The frame nearest the middle of a bilabial's closure (the start of a stop's span, ``closure``
    of it; a nasal's whole span)."""
    share = viseme_map("en").phone(phone.label).closure
    return round((phone.start_s + share * phone.duration_s / 2) * fps)


def _lip_gap(rig, engine, values) -> float:
    """The inner lips' gap of a pose on the engine (rig units)."""
    return lip_gap(rig, engine.deform(values))


def _column(rig, name):
    return rig.channel_names.index(name)


def test_coarticulate_returns_a_clip_of_the_rigs_channels(rig):
    timings = _timings("HH:60 AH:100 L:60 OW:180")
    clip = coarticulate(timings, rig, fps=30.0)
    assert isinstance(clip, Clip) and clip.channels == rig.channel_names and clip.fps == 30.0
    assert clip.values.shape == (int(timings.end_s * 30) + 1, len(rig.channels))
    assert clip.values.dtype == np.float64 and np.isfinite(clip.values).all()
    assert clip.values.flags.c_contiguous
    assert timings == _timings("HH:60 AH:100 L:60 OW:180")  # the input is unchanged
    # before the first phone and after a long pause: rest
    np.testing.assert_allclose(clip.values[0], [c.default for c in rig.channels], atol=1e-9)
    np.testing.assert_allclose(clip.values[-1], [c.default for c in rig.channels], atol=0.01)


@pytest.mark.parametrize(
    "spec",
    [
        "B:70 AA:160 B:80",  # bob
        "P:80 AA:140 P:70 AH:120",  # papa
        "M:70 AA:150 M:70 AH:120",  # mama
        SENTENCE,
    ],
)
def test_lips_close_at_every_bilabial_and_open_at_open_vowels(rig, engine, spec):
    timings = _timings(spec)
    clip = coarticulate(timings, rig, fps=60.0)
    closed = [
        _lip_gap(rig, engine, clip.values[_closure_frame(p, 60)])
        for p in timings.phones
        if p.label in BILABIAL
    ]
    opened = [
        _lip_gap(rig, engine, clip.values[_frame(p, 60)]) for p in timings.phones if p.label in ("AA", "AE")
    ]
    assert max(closed) < 0.005 * rig.scale  # measured 0.37 % of the head height (lips pressed)
    assert min(opened) > 0.06 * rig.scale  # measured 8.8-10.3 %
    assert min(opened) > 20 * max(closed)


def test_a_10_ms_p_at_24_fps_still_closes_the_lips(rig, engine):
    timings = _timings("AA:150 P:10 AA:150", start_s=0.2)
    p = timings.phones[1]
    fps = 24.0
    assert np.floor(p.end_s * fps) < p.start_s * fps  # no frame falls inside the phone
    clip, linear = coarticulate(timings, rig, fps), linear_clip(timings, rig, fps)
    target = phone_targets(viseme_map("en"), ["P"], rig)[0]
    k = _closure_frame(p, fps)
    held = [j for j, n in enumerate(rig.channel_names) if channel_group(n) != "tongue"]
    np.testing.assert_allclose(clip.values[k, held], target[held], atol=1e-12)
    assert _lip_gap(rig, engine, clip.values[k]) < 0.005 * rig.scale
    assert _lip_gap(rig, engine, linear.values[k]) > 0.02 * rig.scale  # the baseline misses it: 2.8 %


def test_stops_close_the_lips_at_their_closure_and_release_before_the_vowel(rig, engine):
    """An aligned P spans its closure (the first 60 %) and its release: the lips are shut at the
    closure's midpoint and parting by the release's end; an M (no release) is shut at its middle.
    Centred on the whole phone, the lips were still 1.7 % of the head apart 15 ms into the closure
    and 1.0 % at the release's end."""
    timings = _timings("AA:150 P:150 AA:150 M:150 AA:150", start_s=0.2)
    p, m = timings.phones[1], timings.phones[3]
    clip = coarticulate(timings, rig, 60.0)

    def gap(share):  # the lips' gap at this share of the P, % of the head
        return (
            100
            * _lip_gap(rig, engine, clip.values[round((p.start_s + share * p.duration_s) * 60)])
            / rig.scale
        )

    assert gap(0.1) < 0.6 and gap(0.3) < 0.5  # measured 0.47 and 0.37: shut from early in the closure
    assert gap(0.93) > 3.0  # measured 4.7: the release opens toward the vowel
    assert _lip_gap(rig, engine, clip.values[_frame(m, 60)]) < 0.005 * rig.scale


def test_t_is_rounder_beside_u_than_beside_i(rig):
    oo, risorius = _column(rig, "orbicularis_oris"), _column(rig, "risorius_L")
    at_t = {}
    for word, spec in (("boot", "B:70 UW:150 T:70"), ("beet", "B:70 IY:150 T:70")):
        timings = _timings(spec)
        at_t[word] = coarticulate(timings, rig).values[_frame(timings.phones[2], 60)]
    t_alone = phone_targets(viseme_map("en"), ["T"], rig)[0]
    assert t_alone[oo] == 0 and t_alone[risorius] == 0  # T has no lip shape of its own
    assert at_t["boot"][oo] > 0.2 > at_t["beet"][oo]  # measured 0.39 against 0
    assert at_t["beet"][risorius] > 0.1 > at_t["boot"][risorius]  # measured 0.19 against 0


@pytest.mark.parametrize("vowel", ["AA", "EH", "IY", "UW", "OW", "AE"])
def test_long_vowels_reach_their_target_within_5_percent(rig, vowel):
    timings = _timings(f"B:80 {vowel}:400 D:80")
    value = coarticulate(timings, rig).values[_frame(timings.phones[1], 60)]
    target = phone_targets(viseme_map("en"), [vowel], rig)[0]
    rest = np.array([c.default for c in rig.channels])
    assert np.abs(value - target).max() <= 0.05 * np.abs(target - rest).max()  # measured < 0.5 %


def test_jaw_opening_follows_vowel_openness_in_running_speech(rig):
    jaw = {}
    for vowel in ("AA", "EH", "IY", "UW"):
        timings = _timings(f"HH:60 {vowel}:120 D:60")
        jaw[vowel] = coarticulate(timings, rig).values[
            _frame(timings.phones[1], 60), _column(rig, "jaw_open")
        ]
    assert jaw["AA"] > jaw["EH"] > jaw["IY"] > 0 and jaw["UW"] < jaw["EH"]


def test_fast_speech_undershoots_through_overlap(rig):
    def aa_jaw(scale):
        timings = _timings(" ".join(f"{p}:{ms * scale:g}" for p, ms in (("B", 70), ("AA", 120), ("D", 70))))
        return coarticulate(timings, rig).values[_frame(timings.phones[1], 60), _column(rig, "jaw_open")]

    target = phone_targets(viseme_map("en"), ["AA"], rig)[0, _column(rig, "jaw_open")]
    slow, normal, fast = aa_jaw(2.0), aa_jaw(1.0), aa_jaw(0.5)
    assert target >= slow > normal > fast and fast < 0.9 * target


def test_rounding_is_anticipated_earlier_than_spreading(rig):
    # two consonants without lip shapes before the vowel: how much of the vowel's lips show at the first
    reach = {}
    for vowel, channel in (("UW", "orbicularis_oris"), ("IY", "risorius_L")):
        timings = _timings(f"K:70 T:70 {vowel}:150")
        value = coarticulate(timings, rig).values[_frame(timings.phones[0], 60), _column(rig, channel)]
        reach[vowel] = value / phone_targets(viseme_map("en"), [vowel], rig)[0, _column(rig, channel)]
    assert reach["UW"] > 1.5 * reach["IY"] and reach["UW"] > 0.1


def test_a_pause_relaxes_to_rest(rig):
    timings = _timings("M:70 AA:150 SIL:1000 AA:150 M:70")
    clip = coarticulate(timings, rig)
    pause = timings.phones[2]
    np.testing.assert_allclose(clip.values[_frame(pause, 60)], [c.default for c in rig.channels], atol=1e-3)
    gap = _timings("M:70 AA:150 SIL:40 AA:150 M:70")  # a short gap between words does not close the jaw
    values = coarticulate(gap, rig).values[:, _column(rig, "jaw_open")]
    assert values[_frame(gap.phones[2], 60)] > 0.5 * values[_frame(gap.phones[1], 60)]


@pytest.mark.parametrize("seed", range(8))
def test_no_channel_leaves_its_range_for_random_timings(rig, seed):
    rng = np.random.default_rng(seed)
    labels = [p for p in viseme_map("en").phones]
    phones, t = [], rng.uniform(0, 0.5)
    for _ in range(60):
        d = rng.choice([rng.uniform(0.002, 0.02), rng.uniform(0.02, 0.6)])
        phones.append(Phone(str(rng.choice(labels)), t, t + d))
        t += d + rng.choice([0.0, rng.uniform(0, 0.4)])
    timings = PhoneTimings(tuple(phones), "en")
    fps = float(rng.choice([24.0, 25.0, 30.0, 60.0, 100.0]))
    lo, hi = np.array([[c.minimum, c.maximum] for c in rig.channels]).T
    for clip in (
        coarticulate(timings, rig, fps, jaw=rng.uniform(0, 2), lips=rng.uniform(0, 2)),
        linear_clip(timings, rig, fps),
        add_eye_motion(coarticulate(timings, rig, fps), rig, seed=seed),
    ):
        assert np.isfinite(clip.values).all()
        assert (clip.values >= lo).all() and (clip.values <= hi).all()


def test_coarticulation_is_smoother_than_linear_yet_closer_at_bilabials(rig):
    timings = _timings(SENTENCE)
    clip, linear = coarticulate(timings, rig), linear_clip(timings, rig)
    mouth = [j for j, n in enumerate(rig.channel_names) if channel_group(n) in ("lips", "jaw")]

    def roughness(values):  # summed squared second difference of the mouth channels
        return float((np.diff(values[:, mouth], n=2, axis=0) ** 2).sum())

    assert roughness(clip.values) < 0.7 * roughness(linear.values)
    vmap = viseme_map("en")
    bilabials = [p for p in timings.phones if p.label in BILABIAL]
    targets = phone_targets(vmap, [p.label for p in bilabials], rig)[:, mouth]
    frames = [_closure_frame(p, 60) for p in bilabials]
    error = np.abs(clip.values[frames][:, mouth] - targets).max()
    assert error < 1e-12 < np.abs(linear.values[frames][:, mouth] - targets).max()


def test_jaw_and_lips_dials_scale_around_rest(rig):
    timings = _timings(SENTENCE)
    normal = coarticulate(timings, rig)
    jaw = [j for j, n in enumerate(rig.channel_names) if channel_group(n) == "jaw"]
    lips = [j for j, n in enumerate(rig.channel_names) if channel_group(n) == "lips"]
    tongue = [j for j, n in enumerate(rig.channel_names) if channel_group(n) == "tongue"]
    still = coarticulate(timings, rig, jaw=0.0)
    np.testing.assert_array_equal(still.values[:, jaw], 0.0)
    np.testing.assert_array_equal(still.values[:, lips + tongue], normal.values[:, lips + tongue])
    quiet = coarticulate(timings, rig, lips=0.0)
    np.testing.assert_array_equal(quiet.values[:, lips], 0.0)
    np.testing.assert_array_equal(quiet.values[:, jaw], normal.values[:, jaw])
    loud = coarticulate(timings, rig, jaw=1.5)
    j = _column(rig, "jaw_open")
    np.testing.assert_allclose(loud.values[:, j], np.minimum(1.5 * normal.values[:, j], 0.45), atol=1e-12)


def test_northern_sotho_p_closes_the_lips_with_the_surveys_blend(rig, engine):
    # Diphahla (heard as D IY P AH S AA), at the thesis's 25 fps
    timings = _timings("D:80 I:120 PH:90 A:120 HL:100 A:160", language="nso")
    clip = coarticulate(timings, rig, fps=25.0)
    p, a = timings.phones[2], timings.phones[5]
    assert _lip_gap(rig, engine, clip.values[_frame(p, 25)]) < 0.005 * rig.scale
    assert _lip_gap(rig, engine, clip.values[_frame(a, 25)]) > 0.06 * rig.scale
    with pytest.raises(SpeechError, match="is for 'en'"):
        coarticulate(timings, rig, viseme_map="en")


def test_a_users_map_changes_the_mouth(rig):
    timings = _timings("D:80 I:120 PH:90 A:120 HL:100 A:160", language="nso")
    kiss = load_viseme_map(
        {"base": "nso", "phones": {"A": {"blend": {"O": 1, "Closed": 1, "TH": 1, "W": 1}}}}
    )
    k = _frame(timings.phones[5], 60)
    oo = _column(rig, "orbicularis_oris")
    assert (
        coarticulate(timings, rig, viseme_map=kiss).values[k, oo]
        > 0.9
        > coarticulate(timings, rig).values[k, oo]
    )


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"fps": 0.0}, "fps must be a positive number"),
        ({"fps": float("nan")}, "fps must be a positive number"),
        ({"jaw": 2.5}, r"the jaw dial is 2.5; it must be a number in \[0, 2\]"),
        ({"lips": -0.1}, "the lips dial"),
        ({"viseme_map": "fr"}, "unknown viseme map 'fr'"),
    ],
)
def test_coarticulate_rejects_bad_arguments(rig, kwargs, message):
    with pytest.raises(SpeechError, match=message):
        coarticulate(_timings("AA:100"), rig, **kwargs)


def test_coarticulate_rejects_empty_timings_and_unknown_phones(rig):
    with pytest.raises(SpeechError, match="no phones"):
        coarticulate(PhoneTimings((), "en"), rig)
    with pytest.raises(SpeechError, match=r"phone 'AX' is not in viseme map 'en'; did you mean"):
        coarticulate(_timings("AX:100"), rig)
    with pytest.raises(SpeechError, match="no phones"):
        linear_clip(PhoneTimings((), "en"), rig)


def test_linear_baseline_passes_through_the_targets_at_phone_centres(rig):
    timings = _timings("M:100 AA:200 S:100", start_s=0.25)  # centres 0.3, 0.45, 0.6 s: frames at 60 fps
    clip = linear_clip(timings, rig)
    targets = phone_targets(viseme_map("en"), ["M", "AA", "S"], rig)
    np.testing.assert_allclose(clip.values[[18, 27, 36]], targets, atol=1e-12)
    np.testing.assert_allclose(
        clip.values[22], targets[0] + (22 - 18) / 9 * (targets[1] - targets[0]), atol=1e-12
    )


# ---- eyes


def test_blinks_come_about_15_a_minute_and_last_100_to_150_ms(rig):
    fps = 60.0
    base = Clip(rig.channel_names, np.zeros((int(120 * fps), len(rig.channels))), fps)
    clip = add_eye_motion(base, rig, seed=7)
    assert clip.values.shape == base.values.shape and clip.channels == base.channels
    np.testing.assert_array_equal(base.values, 0.0)  # the input is unchanged
    left, right = (clip.values[:, _column(rig, n)] for n in ("eyelid_upper_L", "eyelid_upper_R"))
    np.testing.assert_array_equal(left, right)
    closed = rig.channel("eyelid_upper_L").maximum
    shut = left > 0.5 * closed
    starts = np.flatnonzero(shut[1:] & ~shut[:-1]) + 1
    ends = np.flatnonzero(~shut[1:] & shut[:-1]) + 1
    assert 22 <= len(starts) <= 38  # 30 expected in 2 minutes
    assert left.max() > 0.95 * closed
    assert ((ends - starts) / fps).max() <= BLINK_S[1]  # half-closed for less than the whole blink
    others = [j for j, n in enumerate(rig.channel_names) if n not in EYE_CHANNELS]
    np.testing.assert_array_equal(clip.values[:, others], 0.0)


def test_saccades_are_small_seeded_jumps(rig):
    base = Clip(rig.channel_names, np.zeros((600, len(rig.channels))), 60.0)
    a, b = add_eye_motion(base, rig, seed=1), add_eye_motion(base, rig, seed=1)
    np.testing.assert_array_equal(a.values, b.values)
    assert not np.array_equal(a.values, add_eye_motion(base, rig, seed=2).values)
    yaw = a.values[:, _column(rig, "gaze_yaw")]
    assert 0 < np.abs(yaw).max() <= 0.05 and np.abs(a.values[:, _column(rig, "gaze_pitch")]).max() <= 0.025
    assert (np.abs(np.diff(yaw)) < 1e-12).mean() > 0.8  # mostly fixations
    quiet = add_eye_motion(base, rig, blinks_per_min=0, saccades_per_min=0)
    np.testing.assert_array_equal(quiet.values, base.values)


def test_add_eye_motion_rejects_bad_arguments(rig):
    base = Clip(rig.channel_names, np.zeros((10, len(rig.channels))), 60.0)
    with pytest.raises(SpeechError, match="blinks_per_min"):
        add_eye_motion(base, rig, blinks_per_min=-1)
    with pytest.raises(SpeechError, match="saccade_rad"):
        add_eye_motion(base, rig, saccade_rad=float("inf"))
    mouth = base.select(["jaw_open", "mentalis"])
    with pytest.raises(SpeechError, match=r"no channel.*eyelid_upper_L"):
        add_eye_motion(mouth, rig)
