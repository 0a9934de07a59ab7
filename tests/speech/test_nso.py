"""Tests for mimetic.speech.nso: Northern Sotho letters → phones by longest grapheme match."""

from __future__ import annotations

import re
import unicodedata

import pytest

from mimetic.errors import SpeechError
from mimetic.speech import nso
from mimetic.speech.english import ARPABET
from mimetic.speech.phones import SILENCE


@pytest.mark.parametrize(
    ("word", "phones"),
    [
        ("tšhwene", ("CHH", "W", "E", "N", "E")),  # baboon: tšh, not tš + h
        ("tshwene", ("TSH", "W", "E", "N", "E")),
        ("kgomo", ("KG", "O", "M", "O")),  # cow
        ("hlogo", ("HL", "O", "G", "O")),  # head
        ("ngwana", ("NG", "W", "A", "N", "A")),  # child
        ("šela", ("SH", "E", "L", "A")),
        ("bêilê", ("B", "E_OPEN", "I", "L", "E_OPEN")),
        ("bôna", ("B", "O_OPEN", "N", "A")),
        ("tlhapa", ("TLH", "A", "P", "A")),
        ("tlase", ("TL", "A", "S", "E")),
        ("mokgalabje", ("M", "O", "KG", "A", "L", "A", "BJ", "E")),
        ("Diphahla", ("D", "I", "PH", "A", "HL", "A")),
        ("nyaka", ("NY", "A", "K", "A")),
        ("hlapša", ("HL", "A", "PSH", "A")),
        ("lefsifsi", ("L", "E", "FS", "I", "FS", "I")),
        ("utswitšwêgo", ("U", "TS", "W", "I", "CH", "W", "E_OPEN", "G", "O")),
    ],
)
def test_word_to_phones_takes_longest_grapheme(word, phones):
    assert nso.word_to_phones(word) == phones


def test_word_to_phones_reads_decomposed_and_upper_case_letters():
    decomposed = unicodedata.normalize("NFD", "TŠHWENE BÊILÊ")
    assert len(decomposed) > len("TŠHWENE BÊILÊ")
    assert nso.word_to_phones(decomposed.split()[0]) == nso.word_to_phones("tšhwene")
    assert nso.word_to_phones(decomposed.split()[1]) == nso.word_to_phones("bêilê")


def test_nso_to_phonemes_gives_words_and_pauses():
    result = nso.nso_to_phonemes("Diphahla tšê mokgalabje a di utswitšwêgo, o di bêilê ka tlase ga tafola.")
    texts = [w.text for w in result]
    assert texts[:3] == ["diphahla", "tšê", "mokgalabje"]
    assert texts[6] == "," and result[6].phones == ((SILENCE, None),)
    assert texts[-1] == "tafola"  # no pause at the end
    assert len(result) == 14
    assert all(stress is None for w in result for _, stress in w.phones)


def test_nso_to_phonemes_unknown_letters_are_named():
    with pytest.raises(SpeechError, match=r"'xhosa'.*'x' is not a Sepedi letter"):
        nso.nso_to_phonemes("ke a xhosa")
    with pytest.raises(SpeechError, match=r"'c', 'q'"):
        nso.word_to_phones("cqa")


def test_nso_to_phonemes_rejects_digits():
    with pytest.raises(SpeechError, match=r"'23'.*write numbers in words"):
        nso.nso_to_phonemes("dikgomo tše 23")


def test_phone_table_is_consistent_and_ascii():
    assert len(nso.PHONES) == len(nso.TABLE) == len(nso.GRAPHEMES) == 43
    for label, ipa in nso.PHONES.items():
        assert re.fullmatch(r"[A-Z][A-Z_]*", label), label
        assert ipa and not any(c.isupper() or c.isdigit() for c in ipa), ipa
        assert all(a in ARPABET for a in nso.TO_ARPABET[label]), label
        assert 0.03 < nso.DURATIONS_S[label] < 0.2
    assert set(nso.VOWELS) <= set(nso.PHONES)
    assert {"tšh", "tš", "tlh", "tl", "hl", "kg", "kh", "ph", "th", "bj", "ny", "ng", "š", "ê", "ô"} <= set(
        nso.GRAPHEMES
    )


def test_durations_vowels_outlast_simple_consonants_and_double_articulations_are_longest():
    d = nso.DURATIONS_S
    simple = ["P", "T", "K", "B", "D", "M", "N", "L", "R", "W", "Y", "H", "G"]
    assert min(d[v] for v in nso.VOWELS) > max(d[c] for c in simple)
    assert d["BJ"] > d["B"] and d["PSH"] > d["P"] and d["FS"] > d["F"]
    assert d["TSH"] > d["TS"] > d["T"] and d["KG"] > d["K"]
    assert d["A"] > d["I"] and d["A"] > d["U"]  # low vowels outlast high ones
