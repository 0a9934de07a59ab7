"""Live lip sync (``speech.stream``): agreement with the offline lip sync on a real utterance, and
the look-ahead bound: no frame depends on audio more than ``lookahead_s`` after it."""

from __future__ import annotations

import numpy as np
import pytest

from mimetic.errors import SpeechError
from mimetic.speech.align import read_wav
from mimetic.speech.lipsync import lip_sync
from mimetic.testing import require_extra, require_shared_data

LIBRIVOX = "speech/librivox/sense_and_sensibility_01_austen_64kb-0880"
FPS = 30.0
MIN_JAW_R = 0.7
"""Correlation of the streamed jaw_open with the offline (forced-aligned) one on LIBRIVOX: 0.84
measured on the default head (benchmarks/bench_live.py: 0.70-0.84 over the five utterances)."""


@pytest.fixture(scope="module")
def pocketsphinx():
    return require_extra("pocketsphinx", "speech")


@pytest.fixture(scope="module")
def utterance(pocketsphinx):
    wav = require_shared_data(f"{LIBRIVOX}.wav")
    samples, rate = read_wav(wav)
    return wav, samples, rate


def stream(rig, samples, rate, chunks, **options):
    """All frames of ``samples`` pushed in pieces of the sizes ``chunks`` cycles through, then flushed:
    (the values (f, c), [(frames returned by each push, the sample count pushed so far)])."""
    from mimetic.speech.stream import LiveLipSync

    live = LiveLipSync(rig, fps=FPS, rate=rate, **options)
    parts, i, k = [], 0, 0
    while i < len(samples):
        n = chunks[k % len(chunks)]
        out = live.push(samples[i : i + n])
        i, k = i + n, k + 1
        assert out.start == sum(len(p[0].values) for p in parts)
        parts.append((out, i))
    parts.append((live.flush(), i))
    return np.concatenate([p.values for p, _ in parts]), parts


def test_live_lip_sync_agrees_with_the_offline_lip_sync(rig, utterance):
    wav, samples, rate = utterance
    copy = samples.copy()
    values, parts = stream(rig, samples, rate, [rate // 50])
    offline = lip_sync(rig, audio=wav, text=require_shared_data(f"{LIBRIVOX}.txt").read_text(), fps=FPS)
    assert values.shape == offline.clip.values.shape and values.dtype == np.float64
    assert np.isfinite(values).all()
    np.testing.assert_array_equal(samples, copy)  # the input is not modified
    j = rig.channel_index("jaw_open")
    r = np.corrcoef(values[:, j], offline.clip.values[:, j])[0, 1]
    assert r > MIN_JAW_R, r
    # a frame comes out once the audio reaches 0.1 s past it, not before, not much later
    for out, pushed in parts[:-1]:
        if len(out.values):
            assert out.times_s[-1] + 0.1 <= pushed / rate + 1e-9
            assert out.times_s[-1] + 0.1 + 1 / FPS > pushed / rate - 0.02


def test_no_frame_depends_on_audio_beyond_the_look_ahead(rig, utterance):
    """Frames whose look-ahead ends before a cut are the same whatever comes after the cut, and
    whatever the chunk sizes: pushing other audio from the cut on changes none of them."""
    _, samples, rate = utterance
    rng = np.random.default_rng(0)
    cut = int(1.2 * rate)
    other = samples.copy()
    other[cut:] = rng.normal(0, 0.1, len(samples) - cut)  # different audio after the cut
    a, _ = stream(rig, samples, rate, [rate // 50])
    b, _ = stream(rig, other, rate, list(rng.integers(1, rate // 5, 40)))
    final = int(np.floor((cut / rate - 0.1) * FPS + 1e-9))  # last frame heard in full before the cut
    np.testing.assert_array_equal(a[: final + 1], b[: final + 1])
    assert np.abs(a[final + 6 :] - b[final + 6 :]).max() > 0.01  # later frames do hear the change


def test_live_lip_sync_takes_int16_and_rejects_bad_input(rig, utterance):
    from mimetic.speech.stream import LiveLipSync

    _, samples, rate = utterance
    short = samples[: rate // 2]
    pcm = np.round(short * 32767).astype(np.int16)
    a, _ = stream(rig, short, rate, [rate // 10])
    b, _ = stream(rig, pcm, rate, [rate // 10])
    np.testing.assert_allclose(a, b, atol=0.05)
    live = LiveLipSync(rig, rate=rate)
    with pytest.raises(SpeechError, match="mono"):
        live.push(np.zeros((10, 2)))
    with pytest.raises(SpeechError, match="lookahead_s"):
        LiveLipSync(rig, lookahead_s=1.0)
    with pytest.raises(SpeechError, match="English"):
        LiveLipSync(rig, visemes="nso")
