"""Tests for mimetic.speech.recognize: phone timings from audio alone, against the LibriVox
references (pocketsphinx's own alignments of the true transcripts)."""

from __future__ import annotations

import pytest

from mimetic.errors import SpeechError
from mimetic.speech.phones import SILENCE
from mimetic.speech.recognize import recognize_phones, recognize_timings
from mimetic.speech.timings import load_timings
from mimetic.testing import require_extra, require_shared_data

LIBRIVOX = "speech/librivox/sense_and_sensibility_01_austen_64kb-"
BILABIALS = ("P", "B", "M")
VOWELS = frozenset("AA AE AH AO AW AY EH ER EY IH IY OW OY UH UW".split())
BILABIAL_HITS = 0.8
"""Measured with "words": 17 of 18 reference bilabials (0870 and 0920); free phone decoding 12 of 18."""
VOWEL_HITS = 0.85
"""Measured with "words": 54 of 57 reference vowel centres; free phone decoding 45 of 57."""


def label_at(timings, t: float) -> str | None:
    return next((p.label for p in timings.phones if p.start_s <= t < p.end_s), None)


def test_recognize_timings_without_a_transcript_recovers_bilabials_and_vowels():
    """At the centre of each reference bilabial (P B M) the recognised timings have a bilabial too,
    and at each reference vowel centre a vowel: what the mouth shows."""
    require_extra("pocketsphinx", "speech")
    folder = require_shared_data("speech/librivox")
    bilabials = vowels = n_bilabials = n_vowels = 0
    for u in ("0870", "0920"):
        wav = folder / f"sense_and_sensibility_01_austen_64kb-{u}.wav"
        reference = load_timings(wav.with_suffix(".phone.json"))
        heard = recognize_timings(wav)
        assert heard.language == "en" and heard.words and heard.end_s <= 8.0
        for p in reference.spoken():
            centre = (p.start_s + p.end_s) / 2
            if p.label in BILABIALS:
                n_bilabials += 1
                bilabials += label_at(heard, centre) in BILABIALS
            elif p.label in VOWELS:
                n_vowels += 1
                vowels += label_at(heard, centre) in VOWELS
    assert bilabials >= BILABIAL_HITS * n_bilabials, f"{bilabials}/{n_bilabials} bilabials"
    assert vowels >= VOWEL_HITS * n_vowels, f"{vowels}/{n_vowels} vowels"


def test_recognize_phones_gives_arpabet_phones_on_the_frame_grid():
    require_extra("pocketsphinx", "speech")
    wav = require_shared_data(f"{LIBRIVOX}0880.wav")
    phones = recognize_phones(wav)
    assert len(phones.spoken()) > 10 and phones.words == ()
    assert all(p.label == SILENCE or (p.label.isalpha() and p.label.isupper()) for p in phones.phones)
    assert all(round(p.start_s * 100, 6).is_integer() for p in phones.phones)


def test_recognize_timings_refuses_northern_sotho_and_unknown_methods():
    with pytest.raises(SpeechError, match=r"English only; for language 'nso' pass the transcript"):
        recognize_timings("any.wav", language="nso")
    with pytest.raises(SpeechError, match="unknown recognition method 'vowels'"):
        recognize_timings("any.wav", method="vowels")
