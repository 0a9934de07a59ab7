"""Tests for mimetic.speech.english: English text → ARPAbet (CMU dictionary, numbers, gruut)."""

from __future__ import annotations

import sys
from types import SimpleNamespace

import pytest

from mimetic.errors import SpeechError
from mimetic.speech.english import (
    ARPABET,
    ARPABET_VOWELS,
    IPA_TO_ARPABET,
    cmu_pronunciations,
    ipa_to_arpabet,
    parse_arpabet,
    text_to_phonemes,
)
from mimetic.speech.phones import SILENCE
from mimetic.testing import require_extra


@pytest.fixture(scope="module")
def gruut():
    """gruut (extra [speech]); skips when missing, except on CI, where it fails."""
    return require_extra("gruut", "speech")


def labels(text: str) -> list[list[str]]:
    return [[label for label, _ in w.phones] for w in text_to_phonemes(text)]


def test_arpabet_inventory_has_39_phones_15_vowels():
    assert len(ARPABET) == len(set(ARPABET)) == 39
    assert len(ARPABET_VOWELS) == 15
    assert set(IPA_TO_ARPABET.values()) == set(ARPABET)


@pytest.mark.parametrize(
    ("word", "expected"),
    [
        ("boot", (("B", None), ("UW", 1), ("T", None))),
        ("beet", (("B", None), ("IY", 1), ("T", None))),
        ("Ledger", (("L", None), ("EH", 1), ("JH", None), ("ER", 0))),
    ],
)
def test_text_to_phonemes_known_words_give_cmu_pronunciation(word, expected):
    (result,) = text_to_phonemes(word)
    assert result.text == word.lower()
    assert result.phones == expected
    assert result.phones == cmu_pronunciations(word)[0]


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("23", ["twenty", "three"]),
        ("1,000", ["one", "thousand"]),
        ("21st", ["twenty", "first"]),
        ("3.5", ["three", "point", "five"]),
        ("50%", ["fifty", "percent"]),
        ("1999", ["one", "thousand", "nine", "hundred", "and", "ninety", "nine"]),
    ],
)
def test_text_to_phonemes_spells_out_numbers(text, words):
    result = text_to_phonemes(text)
    assert [w.text for w in result] == words
    assert all(w.phones == cmu_pronunciations(w.text)[0] for w in result)


def test_text_to_phonemes_punctuation_gives_one_pause_between_words_only():
    result = text_to_phonemes('("Hello", she said... Bye!)')
    assert [w.text for w in result] == ["hello", ",", "she", "said", "...", "bye"]
    assert [w.is_pause for w in result] == [False, True, False, False, True, False]
    assert result[1].phones == ((SILENCE, None),)


def test_text_to_phonemes_keeps_apostrophes_and_reads_unknown_hyphenated_words_as_parts():
    assert [w.text for w in text_to_phonemes("Don't, well-known ‘dog’s’ sea-dog")] == [
        "don't",
        ",",
        "well-known",
        "dog's",
        "sea",
        "dog",
    ]
    assert labels("sea-dog") == [["S", "IY"], ["D", "AO", "G"]]


def test_text_to_phonemes_without_words_is_empty():
    assert text_to_phonemes("  ... ?! ") == ()


def test_text_to_phonemes_unknown_word_uses_plausible_letter_to_sound(gruut):
    (zorblax,) = text_to_phonemes("Zorblax")
    phones = [label for label, _ in zorblax.phones]
    assert phones[0] == "Z" and phones[-2:] == ["K", "S"]
    assert {"R", "B", "L"} <= set(phones)
    assert all(label in ARPABET for label in phones)
    stresses = [s for label, s in zorblax.phones if label in ARPABET_VOWELS]
    assert len(stresses) == 2 and 1 in stresses
    assert all(s is None for label, s in zorblax.phones if label not in ARPABET_VOWELS)


def test_text_to_phonemes_unknown_word_without_gruut_names_word_and_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "gruut", None)  # import gruut raises ImportError
    with pytest.raises(SpeechError, match=r"'qwzzk'.*\[speech\].*pip install"):
        text_to_phonemes("the qwzzk sat")
    assert text_to_phonemes("the cat")[1].text == "cat"  # known words need no gruut


def test_text_to_phonemes_gruut_without_english_data_says_what_to_install(gruut, monkeypatch):
    def no_english(text, lang):  # what gruut gives when gruut-lang-en is missing
        return [[SimpleNamespace(text=text, is_spoken=True, phonemes=None)]]

    monkeypatch.setattr(gruut, "sentences", no_english)
    with pytest.raises(SpeechError, match=r"'plinketh'.*gruut-lang-en.*\[speech\]"):
        text_to_phonemes("plinketh")


def test_ipa_to_arpabet_maps_stress_and_moves_it_from_consonant_to_vowel():
    assert ipa_to_arpabet(["ˈb", "ʌ", "t͡ʃ", "ə", "ˌɹ", "ɪ", "ŋ"]) == (
        ("B", None),
        ("AH", 1),
        ("CH", None),
        ("AH", 0),
        ("R", None),
        ("IH", 2),
        ("NG", None),
    )
    with pytest.raises(SpeechError, match=r"'ʀ'.*IPA_TO_ARPABET"):
        ipa_to_arpabet(["ʀ", "a"])


@pytest.mark.parametrize(
    ("label", "expected"), [("AA1", ("AA", 1)), ("t", ("T", None)), (" ER0 ", ("ER", 0))]
)
def test_parse_arpabet_reads_label_and_stress(label, expected):
    assert parse_arpabet(label) == expected


def test_parse_arpabet_unknown_label_suggests_close_match_and_lists_valid():
    with pytest.raises(SpeechError) as error:
        parse_arpabet("KK")
    message = str(error.value)
    assert "'KK'" in message and "did you mean K" in message
    assert "valid phones: AA, AE" in message and "ZH" in message


def test_parse_arpabet_rejects_stress_on_consonant():
    with pytest.raises(SpeechError, match="only vowels carry a stress digit"):
        parse_arpabet("T1")


def test_text_to_phonemes_labels_are_arpabet_with_stress_on_vowels_only():
    result = text_to_phonemes("Mister John Dashwood had then leisure to consider, 42 times.")
    for word in result:
        assert word.phones, word
        for label, stress in word.phones:
            assert label in (*ARPABET, SILENCE)
            assert (stress is not None) == (label in ARPABET_VOWELS)
