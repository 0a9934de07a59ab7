"""Tests for mimetic.speech.align: WAV reading, pocketsphinx alignment accuracy, espeak-ng speech.

Accuracy is measured as boundary error: the spoken phones of the alignment and of the reference are
matched in order (``timings.boundary_errors``: ``difflib`` on their labels), and each matched phone's
start and end are compared with the reference's. The LibriVox references are pocketsphinx's own
forced alignments (made by its ``align`` command with the same bundled model), so they check that
``align_audio`` reproduces pocketsphinx; praatIO's "bobby" TextGrid is hand-labelled, an independent check.
"""

from __future__ import annotations

import shutil
import sys
import wave

import numpy as np
import pytest

from mimetic.errors import MissingExtraError, SpeechError
from mimetic.speech import nso
from mimetic.speech.align import FRAME_S, align_audio, pcm16, read_wav, synthesize
from mimetic.speech.english import ARPABET, text_to_phonemes
from mimetic.speech.phones import SILENCE
from mimetic.speech.timings import boundary_errors, load_timings
from mimetic.testing import require_extra, require_shared_data

LIBRIVOX = "speech/librivox/sense_and_sensibility_01_austen_64kb-"
UTTERANCES = ("0870", "0880", "0890", "0920", "0930")
MEDIAN_GOAL_S = 0.025
WITHIN_S = 0.05
WITHIN_GOAL = 0.9


@pytest.fixture(scope="module")
def pocketsphinx():
    """pocketsphinx (extra [speech]); skips when missing, except on CI, where it fails."""
    return require_extra("pocketsphinx", "speech")


@pytest.fixture(scope="module")
def espeak():
    if shutil.which("espeak-ng") is None:
        pytest.skip("the espeak-ng program is not installed (apt-get install espeak-ng)")


def write_wav(path, samples: np.ndarray, rate: int, width: int = 2) -> None:
    """Integer samples (n,) or (n, channels) into a PCM WAV of ``width`` bytes a sample."""
    frames = np.atleast_2d(samples.T).T
    if width == 1:
        data = (frames + 128).astype(np.uint8).tobytes()
    elif width == 3:
        data = frames.astype("<i4").view(np.uint8).reshape(-1, 4)[:, :3].tobytes()
    else:
        data = frames.astype({2: "<i2", 4: "<i4"}[width]).tobytes()
    with wave.open(str(path), "wb") as wav:
        wav.setnchannels(frames.shape[1])
        wav.setsampwidth(width)
        wav.setframerate(rate)
        wav.writeframes(data)


# --------------------------------------------------------------------------- audio


@pytest.mark.parametrize("width", [1, 2, 3, 4])
def test_read_wav_decodes_every_pcm_width_and_averages_channels(tmp_path, width):
    full = 2 ** (8 * width - 1)
    left = np.array([0, full // 2, -full // 2, full - 1, -full])
    right = np.array([0, 0, -full // 2, -(full // 4), 0])
    write_wav(tmp_path / "s.wav", np.stack([left, right], axis=1), 8000, width)
    samples, rate = read_wav(tmp_path / "s.wav")
    assert rate == 8000 and samples.shape == (5,) and samples.dtype == np.float64
    np.testing.assert_allclose(samples, (left + right) / 2 / full)


def test_read_wav_rejects_non_wav_empty_and_float_files(tmp_path):
    (tmp_path / "a.wav").write_bytes(b"ID3\x03\x00 this is an mp3")
    with pytest.raises(SpeechError, match=r"a.wav: not a PCM WAV file .*ffmpeg -i a.wav"):
        read_wav(tmp_path / "a.wav")
    write_wav(tmp_path / "empty.wav", np.zeros(0, int), 16000)
    with pytest.raises(SpeechError, match="holds no samples"):
        read_wav(tmp_path / "empty.wav")
    write_wav(tmp_path / "float.wav", np.zeros(100, int), 16000, width=4)
    data = bytearray((tmp_path / "float.wav").read_bytes())
    data[20:22] = (3).to_bytes(2, "little")  # WAVE_FORMAT_IEEE_FLOAT
    (tmp_path / "float.wav").write_bytes(bytes(data))
    with pytest.raises(SpeechError, match=r"float\.wav: not a PCM WAV file"):
        read_wav(tmp_path / "float.wav")
    with pytest.raises(SpeechError, match="no such audio file"):
        read_wav(tmp_path / "missing.wav")


def test_pcm16_resamples_48k_to_16k_keeping_the_tone():
    rate, seconds = 48000, 0.5
    t = np.arange(int(rate * seconds)) / rate
    tone = 0.5 * np.sin(2 * np.pi * 440.0 * t)
    out = np.frombuffer(pcm16(tone, rate), "<i2")
    assert out.shape == (8000,)
    spectrum = np.abs(np.fft.rfft(out))
    assert np.argmax(spectrum) * 16000 / len(out) == pytest.approx(440.0, abs=2.0)
    assert np.abs(out[1000:-1000]).max() / 32768 == pytest.approx(0.5, abs=0.01)


def test_pcm16_clips_instead_of_wrapping():
    out = np.frombuffer(pcm16(np.array([1.5, -1.5, 0.25]), 16000), "<i2")
    assert out.tolist() == [32767, -32768, 8192]


# --------------------------------------------------------------------------- alignment accuracy


@pytest.mark.parametrize("utterance", UTTERANCES)
def test_align_audio_librivox_matches_reference_boundaries(pocketsphinx, utterance):
    wav = require_shared_data(f"{LIBRIVOX}{utterance}.wav")
    transcript = require_shared_data(f"{LIBRIVOX}{utterance}.txt").read_text()
    reference = load_timings(require_shared_data(f"{LIBRIVOX}{utterance}.phone.json"))
    result = align_audio(wav, transcript)
    errors, count = boundary_errors(result, reference)
    matched = count / len(reference.spoken())
    median, within = float(np.median(errors)), float(np.mean(errors <= WITHIN_S))
    print(
        f"{utterance}: median {median * 1000:.1f} ms, {within:.1%} within 50 ms, {matched:.1%} phones matched"
    )
    assert result.words == tuple(transcript.split())
    assert matched >= 0.95
    assert median <= MEDIAN_GOAL_S, f"median boundary error {median * 1000:.1f} ms"
    assert within >= WITHIN_GOAL, f"{within:.1%} of boundaries within 50 ms"
    samples, rate = read_wav(wav)
    assert result.end_s == pytest.approx(len(samples) / rate, abs=2 * FRAME_S)


@pytest.mark.parametrize("utterance", UTTERANCES)
def test_align_audio_edges_on_time_when_speech_starts_and_ends_the_recording(
    pocketsphinx, utterance, tmp_path
):
    """The recording cut 50 ms before the reference's first phone and after its last: without the
    padding (``PAD_S``) the first phone took the lead-in in every utterance (onset 50 ms early) and
    the last ran 40 ms past the speech."""
    wav = require_shared_data(f"{LIBRIVOX}{utterance}.wav")
    transcript = require_shared_data(f"{LIBRIVOX}{utterance}.txt").read_text()
    spoken = load_timings(require_shared_data(f"{LIBRIVOX}{utterance}.phone.json")).spoken()
    samples, rate = read_wav(wav)
    lead = 0.05
    a, b = spoken[0].start_s - lead, spoken[-1].end_s + lead
    cut = tmp_path / "cut.wav"
    write_wav(cut, np.round(samples[round(a * rate) : round(b * rate)] * 32767).astype(np.int16), rate)
    result = align_audio(cut, transcript).spoken()
    onset, offset = result[0].start_s - lead, result[-1].end_s - (b - a - lead)
    assert abs(onset) <= 0.02, f"onset {onset * 1000:+.0f} ms"
    assert abs(offset) <= 0.06, f"offset {offset * 1000:+.0f} ms"


def test_align_audio_bobby_48k_is_close_to_hand_labels(pocketsphinx):
    wav = require_shared_data("speech/praatio/bobby.wav")
    with wave.open(str(wav)) as w:
        assert w.getframerate() == 48000  # resampled to 16 kHz by align_audio
    reference = load_timings(require_shared_data("speech/praatio/bobby_phones.TextGrid"))
    result = align_audio(wav, "Bobby ripped the ledger.")
    errors, count = boundary_errors(result, reference)
    matched = count / len(reference.spoken())
    median, within = float(np.median(errors)), float(np.mean(errors <= WITHIN_S))
    print(
        f"bobby: median {median * 1000:.1f} ms, {within:.1%} within 50 ms, max {errors.max() * 1000:.0f} ms"
    )
    assert matched == 1.0  # every hand-labelled phone (PT split in two) found in order
    assert median <= MEDIAN_GOAL_S and within >= WITHIN_GOAL and errors.max() <= 0.1
    assert result.words == ("bobby", "ripped", "the", "ledger")
    assert [(p.label, p.stress) for p in result.phones[:4]] == [
        ("B", None),
        ("AA", 1),
        ("B", None),
        ("IY", 0),
    ]


# --------------------------------------------------------------------------- alignment behaviour


def test_align_audio_northern_sotho_joins_english_phones_back(pocketsphinx):
    """Plumbing only (there is no Sepedi recording here): a Sepedi transcript aligned to bobby's audio
    comes back as Sepedi phones tiling the audio, KG and TS each one phone."""
    wav = require_shared_data("speech/praatio/bobby.wav")
    words = ["bobi", "kgoripitse", "lêtšha"]
    result = align_audio(wav, " ".join(words), language="nso")
    assert result.language == "nso" and result.words == tuple(words)
    for k, word in enumerate(words):
        assert tuple(p.label for p in result.spoken() if p.word == k) == nso.word_to_phones(word)
    assert all(p.duration_s >= 3 * FRAME_S - 1e-9 for p in result.spoken())
    for before, after in zip(result.phones, result.phones[1:], strict=False):
        assert after.start_s == pytest.approx(before.end_s)


def test_align_audio_too_short_audio_raises(pocketsphinx, tmp_path):
    write_wav(tmp_path / "short.wav", np.zeros(800, int), 16000)  # 50 ms
    with pytest.raises(SpeechError, match="could not align the transcript"):
        align_audio(tmp_path / "short.wav", "the quick brown fox jumps over the lazy dog")


def test_align_audio_rejects_empty_transcript_and_bad_language(tmp_path):
    with pytest.raises(SpeechError, match="no words to align"):
        align_audio(tmp_path / "any.wav", " ... ")
    with pytest.raises(SpeechError, match="unknown language 'fr'"):
        align_audio(tmp_path / "any.wav", "bonjour", language="fr")


def test_align_audio_without_pocketsphinx_names_the_extra(monkeypatch, tmp_path):
    write_wav(tmp_path / "a.wav", np.zeros(1600, int), 16000)
    monkeypatch.setitem(sys.modules, "pocketsphinx", None)
    with pytest.raises(MissingExtraError, match=r"\[speech\].*pip install"):
        align_audio(tmp_path / "a.wav", "hello")


# --------------------------------------------------------------------------- espeak-ng


def test_synthesize_without_espeak_says_what_to_install(monkeypatch, tmp_path):
    monkeypatch.setattr(shutil, "which", lambda name: None)
    with pytest.raises(SpeechError, match="needs the espeak-ng program"):
        synthesize("hello", tmp_path / "a.wav")
    assert not (tmp_path / "a.wav").exists()


def test_synthesize_then_align_gives_timings_of_the_sound(espeak, pocketsphinx, tmp_path):
    text = "The mimetic zorblax jumped over 23 lazy dogs."
    wav = synthesize(text, tmp_path / "speech.wav")
    samples, rate = read_wav(wav)
    result = align_audio(wav, text)
    spoken = [w for w in text_to_phonemes(text) if not w.is_pause]
    assert result.words == tuple(w.text for w in spoken)
    assert result.end_s == pytest.approx(len(samples) / rate, abs=2 * FRAME_S)
    zorblax = [p.label for p in result.spoken() if result.words[p.word] == "zorblax"]
    assert zorblax == [label for label, _ in spoken[2].phones]  # out of vocabulary: added from gruut
    assert all(p.label in (*ARPABET, SILENCE) for p in result.phones)
    loud = np.abs(samples) > 0.02
    first_sound = np.argmax(loud) / rate
    assert abs(result.spoken()[0].start_s - first_sound) <= 0.05


def test_synthesize_unknown_voice_fails_cleanly(espeak, tmp_path):
    (tmp_path / "keep.wav").write_bytes(b"old")
    with pytest.raises(SpeechError, match="espeak-ng -v nso failed"):
        synthesize("Dumela", tmp_path / "keep.wav", voice="nso")
    assert (tmp_path / "keep.wav").read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.wav"]


# --------------------------------------------------------------------------- wrong transcripts


def test_align_audio_passes_every_correct_librivox_transcript(pocketsphinx):
    folder = require_shared_data("speech/librivox")
    for u in UTTERANCES:
        wav = folder / f"sense_and_sensibility_01_austen_64kb-{u}.wav"
        assert align_audio(wav, wav.with_suffix(".txt").read_text()).spoken()


def test_align_audio_refuses_a_wrong_transcript_naming_the_stretch_unless_forced(pocketsphinx):
    """The second half of 0930 replaced by the start of 0880's text: refused, naming where it
    first goes wrong; with force the same text is aligned over the recording."""
    folder = require_shared_data("speech/librivox")
    wav = folder / "sense_and_sensibility_01_austen_64kb-0930.wav"
    words = wav.with_suffix(".txt").read_text().split()  # he might even have been made amiable himself
    wrong = " ".join([*words[:4], "he", "was", "not", "an"])
    with pytest.raises(
        SpeechError, match=r"does not say the transcript from \d+\.\d\d s to \d+\.\d\d s \(\"have he"
    ) as error:
        align_audio(wav, wrong)
    assert "force=True" in str(error.value) and "\n" not in str(error.value)
    forced = align_audio(wav, wrong, force=True)
    assert [w for w in forced.words] == ["he", "might", "even", "have", "he", "was", "not", "an"]
