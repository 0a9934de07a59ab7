"""Timed phones: what text, timing files and alignment produce, and what visemes consume."""

from __future__ import annotations

import difflib
import math
from collections.abc import Sequence
from dataclasses import dataclass

from mimetic.errors import SpeechError

SILENCE = "SIL"
"""The label of a pause (TextGrid's empty intervals, ``sil``, ``sp``, ``<sil>`` are read as this)."""
LANGUAGES = ("en", "nso")
"""English (ARPAbet labels) and Northern Sotho (``mimetic.speech.nso`` labels)."""
OVERLAP_TOLERANCE_S = 1e-6
"""Boundaries closer than this count as touching (TextGrids round their times)."""


@dataclass(frozen=True)
class Phone:
    """One phone: ``label`` (English: ARPAbet in capitals without stress digits, e.g. "AA", "P";
    Northern Sotho: ``nso.PHONES``; ``SILENCE`` for a pause) from ``start_s`` to ``end_s`` seconds;
    ``stress`` the ARPAbet stress digit of a vowel (0, 1, 2) or None; ``word`` the index of its word in
    the utterance (None for a pause)."""

    label: str
    start_s: float
    end_s: float
    stress: int | None = None
    word: int | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.start_s) and math.isfinite(self.end_s)):
            raise SpeechError(f"phone {self.label!r}: times must be finite; got {self.start_s}..{self.end_s}")
        if self.end_s <= self.start_s:
            raise SpeechError(
                f"phone {self.label!r} at {self.start_s:.3f} s: it must end after it starts (ends at "
                f"{self.end_s:.3f} s)"
            )

    @property
    def duration_s(self) -> float:
        return self.end_s - self.start_s


@dataclass(frozen=True)
class PhoneTimings:
    """The phones of an utterance in time order, not overlapping (gaps are allowed and mean
    silence), in ``language`` (``LANGUAGES``); ``words`` the utterance's words (``Phone.word`` indexes
    them), empty when unknown."""

    phones: tuple[Phone, ...]
    language: str = "en"
    words: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "phones", tuple(self.phones))
        object.__setattr__(self, "words", tuple(self.words))
        if self.language not in LANGUAGES:
            raise SpeechError(f"unknown language {self.language!r}; mimetic speaks {', '.join(LANGUAGES)}")
        for before, after in zip(self.phones, self.phones[1:], strict=False):
            if after.start_s < before.end_s - OVERLAP_TOLERANCE_S:
                raise SpeechError(
                    f"phones overlap: {before.label!r} ends at {before.end_s:.3f} s but {after.label!r} "
                    f"starts at {after.start_s:.3f} s; phones must be in time order"
                )

    @property
    def start_s(self) -> float:
        return self.phones[0].start_s if self.phones else 0.0

    @property
    def end_s(self) -> float:
        return self.phones[-1].end_s if self.phones else 0.0

    def spoken(self) -> tuple[Phone, ...]:
        """The phones that are not pauses."""
        return tuple(p for p in self.phones if p.label != SILENCE)


PAUSE_MARKS = ".!?…,;:—–()"
"""Punctuation read as a pause between words (``mimetic.speech.english``, ``mimetic.speech.nso``)."""
SENTENCE_MARKS = ".!?…"
"""The pause marks that end a sentence (a longer pause in naive timing)."""


@dataclass(frozen=True)
class WordPhones:
    """A word of a text and its phones in order, before any timing: ``text`` as spoken (lower case,
    numbers spelled out, e.g. "twenty"), ``phones`` its (label, stress) pairs (see ``Phone``). A
    pause between words is ``text`` its punctuation (e.g. "," or "?!") with the single phone
    ``(SILENCE, None)``."""

    text: str
    phones: tuple[tuple[str, int | None], ...]

    @property
    def is_pause(self) -> bool:
        return self.phones == ((SILENCE, None),)

    @staticmethod
    def pause(marks: str) -> WordPhones:
        """The pause for the punctuation ``marks``."""
        return WordPhones(marks, ((SILENCE, None),))


def unknown_phone_error(label: str, valid: Sequence[str], language: str) -> SpeechError:
    """The error for a phone ``label`` outside ``valid`` (the labels of ``language``): it names the
    closest valid labels and lists all of them."""
    close = difflib.get_close_matches(label.upper().rstrip("012"), valid, n=3, cutoff=0.4)
    hint = f"did you mean {' or '.join(close)}? " if close else ""
    return SpeechError(f"unknown {language} phone {label!r}; {hint}valid phones: {', '.join(valid)}")
