"""Northern Sotho (Sesotho sa Leboa, Sepedi, ISO 639 ``nso``): letters → phones by rule.

The orthography is close to phonemic, so each word is read left to right taking the longest
grapheme of ``GRAPHEMES`` that matches ("tšhwene" → tšh·w·e·n·e → CHH W E N E). ``TABLE`` is the
whole model, one row per phone: its grapheme, label, IPA, duration and nearest English phones.

Sources and honest limits:

* Phone values follow the usual descriptions of Sepedi (and, for ``d``, ``b``, ``g``, ``hl``,
  ``tl``, ``kg``, ``bj``, A.E. Kotzé's notes in Radovan 2008, ch. 10, summarised in
  ``research/seed-004-survey-lipsync.md`` §3.3). Textbooks call ``p t k ts tš tl`` ejective; many
  speakers (Radovan's informant too) do not eject. Not checked against a speaker or a dictionary.
* ``e`` and ``o`` are read as close-mid [e] [o]; the open [ɛ] [ɔ] only when written ``ê`` ``ô``
  (the spelling usually leaves them unmarked, so unmarked text gets the close vowels). Tone is not
  written and not modelled.
* ``v`` and ``z`` occur in loanwords only; ``c``, ``q``, ``x`` and digits are not read (spell
  numbers out in words).
* Durations are approximations, not measurements (no published Sepedi duration table was at
  hand): English-like segment durations (Klatt 1979) with the orderings the sources give — low
  vowels longer than high ones, stops < affricates < fricatives (Kent & Read 2002), aspiration
  adding about 20–30 ms, and the double articulations ``bj pš fs fš`` longest, being phonetic
  sequences (Ladefoged & Maddieson 1996, via Kotzé). Penultimate lengthening is not modelled.
* ``TO_ARPABET`` maps each phone to its nearest English phones, only so that the English acoustic
  model of ``mimetic.speech.align`` can place it; it is a rough approximation.
"""

from __future__ import annotations

import re
import unicodedata

from mimetic.errors import SpeechError
from mimetic.speech.phones import PAUSE_MARKS, WordPhones

# grapheme, label, IPA, duration (s), nearest ARPAbet phones
TABLE = (
    ("a", "A", "a", 0.11, ("AA",)),
    ("e", "E", "e", 0.10, ("EY",)),
    ("ê", "E_OPEN", "ɛ", 0.11, ("EH",)),
    ("i", "I", "i", 0.09, ("IY",)),
    ("o", "O", "o", 0.10, ("OW",)),
    ("ô", "O_OPEN", "ɔ", 0.11, ("AO",)),
    ("u", "U", "u", 0.09, ("UW",)),
    ("p", "P", "pʼ", 0.07, ("P",)),
    ("ph", "PH", "pʰ", 0.09, ("P",)),
    ("b", "B", "β", 0.07, ("B",)),
    ("bj", "BJ", "β͡ʒ", 0.13, ("B", "ZH")),
    ("pš", "PSH", "pʃʼ", 0.13, ("P", "SH")),
    ("f", "F", "f", 0.09, ("F",)),
    ("fs", "FS", "fs", 0.13, ("F", "S")),
    ("fš", "FSH", "fʃ", 0.13, ("F", "SH")),
    ("v", "V", "v", 0.07, ("V",)),
    ("m", "M", "m", 0.07, ("M",)),
    ("t", "T", "tʼ", 0.07, ("T",)),
    ("th", "TH", "tʰ", 0.09, ("T",)),
    ("d", "D", "ɽ", 0.06, ("D",)),
    ("n", "N", "n", 0.07, ("N",)),
    ("l", "L", "l", 0.06, ("L",)),
    ("r", "R", "r", 0.06, ("R",)),
    ("s", "S", "s", 0.09, ("S",)),
    ("š", "SH", "ʃ", 0.09, ("SH",)),
    ("z", "Z", "z", 0.07, ("Z",)),
    ("ts", "TS", "tsʼ", 0.10, ("T", "S")),
    ("tsh", "TSH", "tsʰ", 0.12, ("T", "S")),
    ("tš", "CH", "tʃʼ", 0.10, ("CH",)),
    ("tšh", "CHH", "tʃʰ", 0.12, ("CH",)),
    ("tl", "TL", "tɬʼ", 0.10, ("T", "L")),
    ("tlh", "TLH", "tɬʰ", 0.12, ("T", "L")),
    ("hl", "HL", "ɬ", 0.09, ("SH",)),
    ("j", "J", "d͡ʒ", 0.09, ("JH",)),
    ("y", "Y", "j", 0.06, ("Y",)),
    ("ny", "NY", "ɲ", 0.07, ("N", "Y")),
    ("k", "K", "kʼ", 0.07, ("K",)),
    ("kh", "KH", "kʰ", 0.09, ("K",)),
    ("kg", "KG", "kxʰ", 0.12, ("K", "HH")),
    ("g", "G", "ɣ", 0.07, ("G",)),
    ("ng", "NG", "ŋ", 0.07, ("NG",)),
    ("w", "W", "w", 0.06, ("W",)),
    ("h", "H", "ɦ", 0.06, ("HH",)),
)
PHONES = {label: ipa for _, label, ipa, _, _ in TABLE}
"""Phone label → IPA, for the 43 phones (7 vowels first)."""
VOWELS = ("A", "E", "E_OPEN", "I", "O", "O_OPEN", "U")
GRAPHEMES = {grapheme: label for grapheme, label, _, _, _ in TABLE}
"""Grapheme (lower case) → phone label."""
DURATIONS_S = {label: duration for _, label, _, duration, _ in TABLE}
"""Phone label → typical duration in seconds at a normal speaking rate (approximate, see above)."""
TO_ARPABET = {label: arpabet for _, label, _, _, arpabet in TABLE}
"""Phone label → the nearest English (ARPAbet) phones, for the English acoustic model."""

_LONGEST = max(map(len, GRAPHEMES))
_TOKEN = re.compile(rf"(?P<word>[^\W\d_]+)|(?P<pause>[{re.escape(PAUSE_MARKS)}]+)|(?P<digits>\d+)")


def word_to_phones(word: str) -> tuple[str, ...]:
    """The phone labels of one word (any case), by longest grapheme match.

    Raises
    ------
    SpeechError
        A letter of ``word`` is not part of any grapheme of ``GRAPHEMES``.
    """
    word = unicodedata.normalize("NFC", word).lower()
    phones, unknown, i = [], [], 0
    while i < len(word):
        length = next((n for n in range(_LONGEST, 0, -1) if word[i : i + n] in GRAPHEMES), 0)
        if length:
            phones.append(GRAPHEMES[word[i : i + length]])
        else:
            unknown.append(word[i])
        i += length or 1
    if unknown:
        letters = " ".join(sorted(g for g in GRAPHEMES if len(g) == 1))
        raise SpeechError(
            f"Northern Sotho word {word!r}: {', '.join(repr(c) for c in dict.fromkeys(unknown))} is not "
            f"a Sepedi letter; use {letters} (respell loanwords)"
        )
    return tuple(phones)


def nso_to_phonemes(text: str) -> tuple[WordPhones, ...]:
    """Northern Sotho text as spoken words and pauses with their phones.

    Words are runs of letters (hyphens, apostrophes and quotes separate them); runs of
    ``PAUSE_MARKS`` are one pause each, none at the start or end.

    Parameters
    ----------
    text : str
        Sepedi in its standard spelling, e.g. "Ke a leboga, tšhwene."

    Returns
    -------
    words : tuple of WordPhones
        ``text`` lower case; ``phones`` (label of ``PHONES``, None) pairs (no stress); pauses as
        ``WordPhones.pause``; empty when the text has no words.

    Raises
    ------
    SpeechError
        A letter outside the Sepedi alphabet, or a number written in digits.
    """
    words: list[WordPhones] = []
    for match in _TOKEN.finditer(unicodedata.normalize("NFC", text)):
        if match["digits"]:
            raise SpeechError(
                f"Northern Sotho text has the number {match['digits']!r}: write numbers in words "
                "(mimetic does not spell out Sepedi numbers)"
            )
        if match["word"]:
            word = match["word"].lower()
            words.append(WordPhones(word, tuple((p, None) for p in word_to_phones(word))))
        elif words and words[-1].is_pause:
            words[-1] = WordPhones.pause(words[-1].text + match["pause"])
        elif words:
            words.append(WordPhones.pause(match["pause"]))
    if words and words[-1].is_pause:
        words.pop()
    return tuple(words)
