"""Northern Sotho (Sesotho sa Leboa, Sepedi, ISO 639 ``nso``): letters → phones by rule.

The orthography is close to phonemic, so each word is read left to right taking the longest
grapheme of ``GRAPHEMES`` that matches ("tšhwene" → tšh·w·e·n·e → CHH W E N E). ``TABLE`` is the
whole model, one row per phone: its grapheme, label, IPA, duration and nearest English phones.

Sources and honest limits:

* Phone values follow the Lwazi Pedi phone set (D.R. van Niekerk, Lwazi project, CSIR Meraka
  Institute; the ``LwaziPediPhoneset`` of the ttslab Pedi voice, ``ttslab/voices/pedi_default.py``)
  where it settles a question, and otherwise the usual descriptions of Sepedi (and, for ``b``, ``g``,
  ``hl``, ``tl``, ``bj``, A.E. Kotzé's notes in Radovan 2008, ch. 10, summarised in
  ``research/seed-004-survey-lipsync.md`` §3.3). Textbooks call ``p t k ts tš tl`` ejective (so
  does Lwazi); many speakers (Radovan's informant too) do not eject. Not checked against a speaker
  or a dictionary.
* Choices where the sources differ, each a row of ``TABLE`` to change if a speaker disagrees:

  - ``e`` and ``o`` unmarked are the open-mid [ɛ] [ɔ] (labels ``E_OPEN``, ``O_OPEN``): the Lwazi Pedi
    phone set has only these two mid vowels, so the voices and recognisers built on it read every
    unmarked e/o this way. Written ``ê`` ``ô`` they are the close-mid [e] [o] (``E``, ``O``); that is
    how a user marks, word by word, the raised vowels that descriptions of Sepedi phonology give
    (e.g. Poulos & Louwrens 1994, *A Linguistic Analysis of Northern Sotho*; not checked here
    word by word), since the standard spelling leaves them unmarked. Tone is not written and not modelled.
  - ``d`` is the retroflex lateral [ɭ] (Lwazi ``l_``), not Kotzé's retroflex flap [ɽ]: both put the
    tongue tip up and back, which is what the viseme shows, so the choice changes the IPA only.
  - ``kg`` is the velar affricate [kx] (Lwazi), not Kotzé's aspirated [kxʰ].
  - ``fs`` ``fš`` are bilabial, [ɸs] [ɸʃ] (Lwazi ``_s`` ``_S``), not labiodental [fs] [fʃ]: the
    lips come together and the lower lip does not touch the teeth, which the viseme shows.
  - ``ps`` ``psh`` are one affricate each, [psʼ] [psʰ] (Lwazi ``ps_e`` ``ps_h``), like ``ts`` ``tsh``;
    ``pš`` stays [pʃʼ] and ``pšh`` is [pʃʰ] (Lwazi ``pS_h``). Before, ``psh`` was read p·s·h.
* ``v`` and ``z`` occur in loanwords only; ``c``, ``q``, ``x`` and digits are not read (spell
  numbers out in words).
* Durations are approximations, not measurements (no published Sepedi duration table was at
  hand): English-like segment durations (Klatt 1979) with the orderings the sources give — low
  vowels longer than high ones, stops < affricates < fricatives (Kent & Read 2002), aspiration
  adding about 20–30 ms, and the double articulations ``bj pš fs fš`` longest, being phonetic
  sequences (Ladefoged & Maddieson 1996, via Kotzé). Penultimate lengthening is not modelled.
* ``TO_ARPABET`` maps each phone to its nearest English phones, only so that the English acoustic
  model of ``mimetic.speech.align`` can place it; it is a rough approximation.
* espeak-ng has no Sepedi voice; ``SYNTHESIS_VOICE`` is the nearest one it has (Setswana, of the
  same Sotho–Tswana group), fed ``for_synthesis(text)``, and ``SYNTHESIS_NOTE`` tells the user so.
"""

from __future__ import annotations

import re
import unicodedata

from mimetic.errors import SpeechError
from mimetic.speech.phones import PAUSE_MARKS, WordPhones

# grapheme, label, IPA, duration (s), nearest ARPAbet phones
TABLE = (
    ("a", "A", "a", 0.11, ("AA",)),
    ("ê", "E", "e", 0.10, ("EY",)),
    ("e", "E_OPEN", "ɛ", 0.11, ("EH",)),
    ("i", "I", "i", 0.09, ("IY",)),
    ("ô", "O", "o", 0.10, ("OW",)),
    ("o", "O_OPEN", "ɔ", 0.11, ("AO",)),
    ("u", "U", "u", 0.09, ("UW",)),
    ("p", "P", "pʼ", 0.07, ("P",)),
    ("ph", "PH", "pʰ", 0.09, ("P",)),
    ("b", "B", "β", 0.07, ("B",)),
    ("bj", "BJ", "β͡ʒ", 0.13, ("B", "ZH")),
    ("ps", "PS", "psʼ", 0.12, ("P", "S")),
    ("psh", "PS_H", "psʰ", 0.14, ("P", "S")),
    ("pš", "PSH", "pʃʼ", 0.13, ("P", "SH")),
    ("pšh", "PSH_H", "pʃʰ", 0.15, ("P", "SH")),
    ("f", "F", "f", 0.09, ("F",)),
    ("fs", "FS", "ɸs", 0.13, ("F", "S")),
    ("fš", "FSH", "ɸʃ", 0.13, ("F", "SH")),
    ("v", "V", "v", 0.07, ("V",)),
    ("m", "M", "m", 0.07, ("M",)),
    ("t", "T", "tʼ", 0.07, ("T",)),
    ("th", "TH", "tʰ", 0.09, ("T",)),
    ("d", "D", "ɭ", 0.06, ("D",)),
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
    ("kg", "KG", "kx", 0.11, ("K", "HH")),
    ("g", "G", "ɣ", 0.07, ("G",)),
    ("ng", "NG", "ŋ", 0.07, ("NG",)),
    ("w", "W", "w", 0.06, ("W",)),
    ("h", "H", "ɦ", 0.06, ("HH",)),
)
PHONES = {label: ipa for _, label, ipa, _, _ in TABLE}
"""Phone label → IPA, for the 46 phones (7 vowels first)."""
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


SYNTHESIS_VOICE = "tn"
"""The espeak-ng voice that speaks Sepedi text: Setswana, the nearest voice espeak-ng has (it has
none for Sepedi or Sesotho)."""
SYNTHESIS_NOTE = (
    "espeak-ng has no Northern Sotho voice; the speech is synthesized with its Setswana voice (tn), "
    "the nearest it has, so some sounds are Setswana ones"
)
"""What a front end tells the user when Sepedi is synthesized with ``SYNTHESIS_VOICE``."""


def for_synthesis(text: str) -> str:
    """``text`` respelled for the Setswana voice: ``š`` as ``sh`` (the voice garbles ``š`` unless it
    follows ``t``: "šela" → [s-ila], "shela" → [ʃela]) and ``ê ô`` as plain ``e o``."""
    text = unicodedata.normalize("NFC", text)
    text = re.sub(r"(?<![tT])šh?", "sh", re.sub(r"(?<![tT])Šh?", "Sh", text))
    return text.translate(str.maketrans("êôÊÔ", "eoEO"))
