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
        ("tšhwene", ("CHH", "W", "E_OPEN", "N", "E_OPEN")),  # baboon: tšh, not tš + h
        ("tshwene", ("TSH", "W", "E_OPEN", "N", "E_OPEN")),
        ("kgomo", ("KG", "O_OPEN", "M", "O_OPEN")),  # cow
        ("hlogo", ("HL", "O_OPEN", "G", "O_OPEN")),  # head
        ("ngwana", ("NG", "W", "A", "N", "A")),  # child
        ("šela", ("SH", "E_OPEN", "L", "A")),
        ("bêilê", ("B", "E", "I", "L", "E")),  # the circumflex marks the close-mid vowels
        ("bôna", ("B", "O", "N", "A")),
        ("tlhapa", ("TLH", "A", "P", "A")),
        ("tlase", ("TL", "A", "S", "E_OPEN")),
        ("mokgalabje", ("M", "O_OPEN", "KG", "A", "L", "A", "BJ", "E_OPEN")),
        ("Diphahla", ("D", "I", "PH", "A", "HL", "A")),
        ("nyaka", ("NY", "A", "K", "A")),
        ("hlapša", ("HL", "A", "PSH", "A")),
        ("lefsifsi", ("L", "E_OPEN", "FS", "I", "FS", "I")),
        ("utswitšwêgo", ("U", "TS", "W", "I", "CH", "W", "E", "G", "O_OPEN")),
        ("psha", ("PS_H", "A")),  # one aspirated affricate, once p + s + h
        ("pšhatla", ("PSH_H", "A", "TL", "A")),
    ],
)
def test_word_to_phones_takes_longest_grapheme(word, phones):
    assert nso.word_to_phones(word) == phones


def test_word_to_phones_reads_decomposed_and_upper_case_letters():
    decomposed = unicodedata.normalize("NFD", "TŠHWENE BÊILÊ")
    assert len(decomposed) > len("TŠHWENE BÊILÊ")
    assert nso.word_to_phones(decomposed.split()[0]) == nso.word_to_phones("tšhwene")
    assert nso.word_to_phones(decomposed.split()[1]) == nso.word_to_phones("bêilê")


@pytest.mark.parametrize(
    ("word", "ipa", "was"),
    [
        ("dumela", "ɭumɛla", "ɽumela"),  # d retroflex lateral; unmarked e open-mid
        ("kgomo", "kxɔmɔ", "kxʰomo"),  # kg unaspirated; unmarked o open-mid
        ("lefsifsi", "lɛɸsiɸsi", "lefsifsi"),  # fs bilabial
        ("lefšega", "lɛɸʃɛɣa", "lefʃeɣa"),
        ("psha", "psʰa", "pʼsɦa"),  # psh one sound, not three
        ("bôna", "βona", "βɔna"),  # the circumflex: close-mid
    ],
)
def test_word_to_phones_reads_the_lwazi_values_not_the_old_ones(word, ipa, was):
    got = "".join(nso.PHONES[p] for p in nso.word_to_phones(word))
    assert got == ipa and got != was


def test_for_synthesis_respells_what_the_setswana_voice_misreads():
    assert nso.for_synthesis("Šela tšhwene, pšha bêilê ôna") == "Shela tšhwene, psha beile ona"
    assert nso.SYNTHESIS_VOICE == "tn" and "Setswana" in nso.SYNTHESIS_NOTE


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
    assert len(nso.PHONES) == len(nso.TABLE) == len(nso.GRAPHEMES) == 46
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
    assert d["BJ"] > d["B"] and d["PSH"] > d["P"] and d["FS"] > d["F"] and d["PS_H"] > d["PS"] > d["P"]
    assert d["TSH"] > d["TS"] > d["T"] and d["KG"] > d["K"]
    assert d["A"] > d["I"] and d["A"] > d["U"]  # low vowels outlast high ones
