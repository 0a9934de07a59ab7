"""Phone timings from files (Praat / Montreal Forced Aligner TextGrids, CSV, JSON, pocketsphinx
alignment JSON) or from text alone (naive timing), and back to files.

Every reader turns a label into (label, stress) the same way (``parse_label``): pause labels
(``SILENCE_LABELS``, pocketsphinx fillers such as ``+NSN+``) become ``SILENCE``, a trailing stress
digit goes to ``Phone.stress``, and a label that is several phones run together (praatIO's "PT")
is split into equal parts when every part is a known phone. Touching pauses are merged into one.

Formats (``load_timings`` picks one by suffix, else by content; ``save_timings`` by suffix):

* ``.TextGrid``: Praat long or short text format. The phone tier is the one named "phone(s)"
  (any case, or MFA's "<speaker> - phones"), else the only interval tier; a tier named "word(s)"
  fills ``PhoneTimings.words`` and ``Phone.word`` (the word whose interval holds the phone's
  middle). Written with tiers "phones" and "words" as MFA does, pauses as empty intervals. A
  TextGrid tiles its tiers, so gaps (and the time before the first phone) read back as pauses.
* ``.csv``: header ``phoneme,start,end`` (seconds), optionally a ``word`` column holding each phone's
  word (consecutive phones with the same word text make one word).
* ``.json``: ``[{"phoneme", "start", "end"}, …]`` or ``{"language", "words", "phones": [...]}`` with
  an optional integer ``"word"`` per phone indexing ``"words"``; or pocketsphinx's alignment JSON
  (``{"b", "d", "t", "w": [words]}``, each word with ``"w": [phones]``, as ``-phone_align yes``
  writes it: the shared data's ``.phone.json``).
"""

from __future__ import annotations

import csv
import difflib
import io
import json
import logging
import math
import re
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from mimetic.atomic import atomic_path, atomic_write
from mimetic.errors import SpeechError
from mimetic.inputs import read_text
from mimetic.speech import nso
from mimetic.speech.english import ARPABET, ARPABET_VOWELS, parse_arpabet, text_to_phonemes
from mimetic.speech.phones import (
    LANGUAGES,
    OVERLAP_TOLERANCE_S,
    SENTENCE_MARKS,
    SILENCE,
    Phone,
    PhoneTimings,
    WordPhones,
    unknown_phone_error,
)

log = logging.getLogger(__name__)

SILENCE_LABELS = frozenset({"", "sil", "sp", "spn", "<sil>", "<s>", "</s>", "pau"})
"""Labels read as a pause (any case). ``spn`` is MFA's "spoken noise" for a word it could not
pronounce: there is speech there, but no phone to show."""
PHONE_TIERS = ("phone", "phones")
WORD_TIERS = ("word", "words")

KLATT_MS = {
    **{"AA": (240, 100), "AE": (230, 80), "AH": (140, 60), "AO": (240, 100), "AW": (260, 100)},
    **{"AY": (250, 150), "EH": (150, 70), "ER": (180, 80), "EY": (190, 100), "IH": (135, 40)},
    **{"IY": (155, 55), "OW": (220, 80), "OY": (280, 150), "UH": (160, 60), "UW": (210, 70)},
    **{"B": (85, 60), "CH": (70, 50), "D": (75, 50), "DH": (50, 30), "F": (100, 80), "G": (80, 60)},
    **{"HH": (80, 20), "JH": (70, 50), "K": (80, 60), "L": (80, 40), "M": (70, 60), "N": (60, 50)},
    **{"NG": (95, 60), "P": (90, 50), "R": (80, 30), "S": (105, 60), "SH": (105, 80), "T": (75, 50)},
    **{"TH": (90, 60), "V": (60, 40), "W": (80, 60), "Y": (80, 40), "Z": (75, 40), "ZH": (70, 40)},
}
"""ARPAbet phone → (inherent, minimum) duration in ms: Klatt (1979), "Synthesis by rule of
segmental durations in English sentences", as tabulated in Festival's ``klatt_durs.scm``; an
unstressed AH is the schwa (120, 60)."""
KLATT_SCHWA_MS = (120, 60)
CONNECTED_SPEECH = 0.6
"""Klatt's rules scale the inherent-minus-minimum part of a duration by a product of percentages
(phrase position, word length, stress, context). Naive timing uses this one factor instead, chosen
so that the 5 LibriVox transcripts of the shared data come out at 0.93–1.04 of their spoken length
(a careful audiobook reading; everyday speech is faster: raise ``rate``)."""
UNSTRESSED = 0.7
"""Klatt's rule 7: an unstressed vowel's percentage ×0.7 and its minimum halved."""
PAUSE_S = 0.15
SENTENCE_PAUSE_S = 0.35
"""Naive pauses after a comma-like mark and after a sentence (approximate, at rate 1)."""

FORMATS = (".TextGrid", ".csv", ".json")


def english_duration_s(label: str, stress: int | None) -> float:
    """A typical duration (s) of an ARPAbet phone in connected speech at a normal rate:
    ``minimum + CONNECTED_SPEECH · (inherent − minimum)`` from ``KLATT_MS``, unstressed vowels
    shortened by Klatt's rule 7. Approximate: context, position and emphasis are ignored."""
    inherent, minimum = KLATT_SCHWA_MS if (label, stress) == ("AH", 0) else KLATT_MS[label]
    factor = CONNECTED_SPEECH
    if stress == 0:
        minimum, factor = minimum / 2, factor * UNSTRESSED
    return (minimum + factor * (inherent - minimum)) / 1000


def _inventory(language: str) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """(phone labels, labels that take a stress digit) of ``language``."""
    return (ARPABET, ARPABET_VOWELS) if language == "en" else (tuple(nso.PHONES), ())


def _split(label: str, language: str) -> list[str] | None:
    """``label`` as the fewest known phones (each with an optional stress digit when it is a vowel)
    run together, e.g. "PT" → ["P", "T"], "AA1B" → ["AA1", "B"]; None when there is no such split."""
    phones, stressed = _inventory(language)
    text = label.upper()
    best: dict[int, list[str]] = {0: []}
    for i in range(len(text)):
        if i not in best:
            continue
        for phone in phones:
            if not text.startswith(phone, i):
                continue
            j = i + len(phone)
            if phone in stressed and j < len(text) and text[j] in "012":
                j += 1
            if j not in best or len(best[i]) + 1 < len(best[j]):
                best[j] = [*best[i], text[i:j]]
    return best.get(len(text))


def _is_pause(label: str) -> bool:
    """A pause label (``SILENCE_LABELS``) or an aligner's filler ("+NSN+", "[NOISE]")."""
    return label.lower() in SILENCE_LABELS or re.fullmatch(r"\+\w+\+|\[\w+\]", label) is not None


def parse_label(raw: str, language: str = "en") -> list[tuple[str, int | None]]:
    """A timing file's phone label as one or more (label, stress) pairs (see the module docstring):
    "AA1" → [("AA", 1)], "sp" → [(SILENCE, None)], "PT" → [("P", None), ("T", None)], "P T" too.

    Raises
    ------
    SpeechError
        The label is not a phone of ``language`` (ARPAbet for "en", ``nso.PHONES`` for "nso"), nor
        phones run together.
    """
    text = raw.strip()
    if _is_pause(text):
        return [(SILENCE, None)]
    phones, _ = _inventory(language)
    parts = text.split()
    if len(parts) == 1 and text.upper().rstrip("012") not in phones:
        parts = _split(text, language) or parts
    if language == "en":
        return [parse_arpabet(part) for part in parts]
    if any(part.upper() not in phones for part in parts):
        raise unknown_phone_error(text, phones, "Northern Sotho")
    return [(part.upper(), None) for part in parts]


Row = tuple[str, str, float, float, int | None]
"""A phone as a file gives it: (where it is, for errors; raw label; start_s; end_s; word index)."""


def _timings(rows: Sequence[Row], words: Sequence[str], language: str, source: str) -> PhoneTimings:
    """Timings from ``rows`` in file order: labels parsed (merged labels split evenly over their
    interval), touching pauses merged; errors name ``source`` and the row."""
    phones: list[Phone] = []
    for where, raw, start, end, word in rows:
        try:
            parts = parse_label(raw, language)
            step = (end - start) / len(parts)
            for k, (label, stress) in enumerate(parts):
                stop = end if k == len(parts) - 1 else start + (k + 1) * step
                phone = Phone(label, start + k * step, stop, stress, None if label == SILENCE else word)
                last = phones[-1] if phones else None
                touching = last is not None and abs(last.end_s - phone.start_s) <= OVERLAP_TOLERANCE_S
                if label == SILENCE and touching and last.label == SILENCE:
                    phones[-1] = Phone(SILENCE, last.start_s, phone.end_s)
                else:
                    phones.append(phone)
        except SpeechError as error:
            raise SpeechError(f"{source}: {where}: {error}") from None
    try:
        return PhoneTimings(tuple(phones), language, tuple(words))
    except SpeechError as error:
        raise SpeechError(f"{source}: {error}") from None


def _word_label(word: str) -> str | None:
    """A word as aligners write it without its variant suffix ("and(2)" → "and"); None for a pause
    or filler ("<sil>", "[NOISE]", "+breath+", "")."""
    word = re.sub(r"\(\d+\)$", "", word.strip())
    return None if _is_pause(word) or word.startswith("<") else word


def timings_from_words(
    words: Sequence[tuple[str, Sequence[tuple[str, float, float]]]], *, language: str = "en", source: str = ""
) -> PhoneTimings:
    """Timings from an aligner's words in order, each (word label, [(phone label, start_s, end_s),
    …]): pauses and fillers ("<sil>", "[NOISE]") give pauses, variant suffixes ("and(2)") are dropped,
    phone labels are read by ``parse_label``; ``source`` prefixes error messages."""
    rows: list[Row] = []
    spoken: list[str] = []
    for i, (word, phones) in enumerate(words):
        text = _word_label(word)
        if text is not None:
            spoken.append(text)
        index = None if text is None else len(spoken) - 1
        rows += [(f"word {i + 1} ({word!r})", p, s, e, index) for p, s, e in phones]
    return _timings(rows, spoken, language, source)


# --------------------------------------------------------------------------- readers


def _read_textgrid(path: Path, language: str) -> PhoneTimings:
    from praatio import textgrid
    from praatio.utilities.errors import PraatioException

    text = read_text(path, SpeechError, "TextGrid")
    try:
        with tempfile.TemporaryDirectory(prefix="mimetic-textgrid-") as folder:
            # praatio reads UTF-16 or else UTF-8 only: hand it the text in the encoding it tries first
            copy = Path(folder) / "grid.TextGrid"
            copy.write_text(text, encoding="utf-16")
            grid = textgrid.openTextgrid(str(copy), includeEmptyIntervals=True, reportingMode="silence")
    except (PraatioException, ValueError, IndexError, KeyError, UnicodeError) as error:
        reason = str(error) or type(error).__name__
        raise SpeechError(
            f"{path}: not a readable Praat TextGrid (long or short text format): {reason}"
        ) from None
    intervals = [name for name in grid.tierNames if isinstance(grid.getTier(name), textgrid.IntervalTier)]

    def named(names: tuple[str, ...]) -> str | None:
        return next((t for t in intervals if t.lower().split(" - ")[-1] in names), None)

    tier = named(PHONE_TIERS) or (intervals[0] if len(intervals) == 1 else None)
    if tier is None:
        raise SpeechError(
            f"{path}: no phone tier among the interval tiers {intervals}; name it 'phones' (or keep only one "
            "interval tier)"
        )
    word_tier = named(WORD_TIERS) if tier != named(WORD_TIERS) else None
    spans = [] if word_tier is None else [e for e in grid.getTier(word_tier).entries if _word_label(e.label)]
    rows = []
    for i, entry in enumerate(grid.getTier(tier).entries):
        middle = (entry.start + entry.end) / 2
        word = next((k for k, w in enumerate(spans) if w.start <= middle < w.end), None)
        rows.append((f"tier {tier!r} interval {i + 1}", entry.label, entry.start, entry.end, word))
    return _timings(rows, [_word_label(w.label) for w in spans], language, str(path))


def _number(value: object, where: str) -> float:
    """``value`` (a number or its text) as finite seconds; errors start with ``where``."""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise SpeechError(f"{where}: {value!r} is not a time in seconds") from None
    if not math.isfinite(number):
        raise SpeechError(f"{where}: time {value!r} is not finite")
    return number


def _read_csv(path: Path, text: str, language: str) -> PhoneTimings:
    reader = csv.reader(io.StringIO(text))
    header = [h.strip().lower() for h in next(reader, [])]
    if not {"phoneme", "start", "end"} <= set(header):
        raise SpeechError(
            f"{path}: line 1 must be the header 'phoneme,start,end' (optionally ',word'); got {header}"
        )
    column = {name: header.index(name) for name in ("phoneme", "start", "end", "word") if name in header}
    rows: list[Row] = []
    words: list[str] = []
    previous = ""
    for line, record in enumerate(reader, start=2):
        if not any(cell.strip() for cell in record):
            continue
        if len(record) < len(header):
            raise SpeechError(f"{path}: line {line} has {len(record)} fields, the header {len(header)}")
        where = f"line {line}"
        label = record[column["phoneme"]]
        word_text = record[column["word"]].strip() if "word" in column else ""
        if word_text and word_text != previous:
            words.append(word_text)
        previous = word_text
        start, end = (_number(record[column[k]], f"{path}: {where}") for k in ("start", "end"))
        rows.append((where, label, start, end, len(words) - 1 if word_text else None))
    return _timings(rows, words, language, str(path))


def _read_json(path: Path, text: str, language: str) -> PhoneTimings:
    try:
        data = json.loads(text)
    except json.JSONDecodeError as error:
        raise SpeechError(f"{path}: not valid JSON: {error.msg} at line {error.lineno}") from None
    if isinstance(data, dict) and "w" in data:
        return _read_pocketsphinx(path, data, language)
    if isinstance(data, dict) and isinstance(data.get("phones"), list):
        language = data.get("language", language)
        words, phones = data.get("words", []), data["phones"]
    elif isinstance(data, list):
        words, phones = [], data
    else:
        raise SpeechError(
            f"{path}: expected a list of {{'phoneme', 'start', 'end'}} objects, {{'phones': [...]}} or "
            "pocketsphinx's alignment JSON"
        )
    if language not in LANGUAGES:
        raise SpeechError(f"{path}: unknown language {language!r}; mimetic speaks {', '.join(LANGUAGES)}")
    rows: list[Row] = []
    for i, entry in enumerate(phones):
        where = f"phones[{i}]"
        if not isinstance(entry, dict) or not {"phoneme", "start", "end"} <= entry.keys():
            raise SpeechError(
                f"{path}: {where} must be an object with 'phoneme', 'start' and 'end'; got {entry!r}"
            )
        word = entry.get("word")
        if word is not None and not (isinstance(word, int) and 0 <= word < len(words)):
            raise SpeechError(f"{path}: {where}: 'word' {word!r} is not an index into 'words' ({len(words)})")
        start, end = (_number(entry[k], f"{path}: {where}") for k in ("start", "end"))
        rows.append((where, str(entry["phoneme"]), start, end, word))
    return _timings(rows, [str(w) for w in words], language, str(path))


def _read_pocketsphinx(path: Path, data: dict, language: str) -> PhoneTimings:
    if not isinstance(data["w"], list):
        raise SpeechError(f"{path}: pocketsphinx JSON: 'w' must be the list of words")
    words = []
    for i, word in enumerate(data["w"]):
        if not isinstance(word, dict) or "w" not in word:
            raise SpeechError(
                f"{path}: word {i + 1} has no phones: this is a word alignment; align with "
                "'-phone_align yes' (pocketsphinx writes .phone.json) or use mimetic.speech.align"
            )
        try:
            phones = [
                (str(p["t"]), float(p["b"]), round(float(p["b"]) + float(p["d"]), 9)) for p in word["w"]
            ]
        except (KeyError, TypeError, ValueError):
            raise SpeechError(f"{path}: word {i + 1}: each phone needs 'b', 'd' (seconds) and 't'") from None
        words.append((str(word.get("t", "")), phones))
    return timings_from_words(words, language=language, source=str(path))


def load_timings(path: str | Path, *, language: str = "en") -> PhoneTimings:
    """Phone timings from a TextGrid, CSV or JSON file (see the module docstring).

    Parameters
    ----------
    path : path-like
        ``.TextGrid``, ``.csv`` or ``.json`` (any case); another suffix is read by its content.
    language : {"en", "nso"}
        How to read the labels: ARPAbet (with stress digits) or ``nso.PHONES``. A JSON file's own
        ``"language"`` wins.

    Raises
    ------
    SpeechError
        The file is missing, of an unknown format or corrupt (the message names the line, interval
        or entry), or has an unknown label, or phones that overlap.
    """
    path = Path(path)
    if language not in LANGUAGES:
        raise SpeechError(f"unknown language {language!r}; mimetic speaks {', '.join(LANGUAGES)}")
    if not path.is_file():
        raise SpeechError(f"{path}: no such timing file")
    suffix = path.suffix.lower()
    if suffix == ".textgrid":
        return _read_textgrid(path, language)
    text = read_text(path, SpeechError, "timing")
    head = text.lstrip()
    if suffix == ".json" or (suffix != ".csv" and head[:1] in ("[", "{")):
        return _read_json(path, text, language)
    if suffix == ".csv" or head.lower().startswith("phoneme"):
        return _read_csv(path, text, language)
    if head.startswith('File type = "ooTextFile"'):
        return _read_textgrid(path, language)
    raise SpeechError(
        f"{path}: unknown timing format; use one of {', '.join(FORMATS)} (see mimetic.speech.timings)"
    )


# --------------------------------------------------------------------------- writers


def _label(phone: Phone) -> str:
    return phone.label + ("" if phone.stress is None else str(phone.stress))


def save_timings(timings: PhoneTimings, path: str | Path) -> Path:
    """Write ``timings`` to ``path`` as a TextGrid, CSV or JSON file, by its suffix (see the module
    docstring); stress digits are appended to labels ("AA1"). The file is written beside ``path``
    and moved over it, so a failure leaves an existing file untouched. Returns the path.

    Raises
    ------
    SpeechError
        Another suffix.
    WriteError
        The folder is missing or not writable.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in {f.lower() for f in FORMATS}:
        raise SpeechError(
            f"{path}: cannot write timings as {suffix or 'no suffix'}; use {', '.join(FORMATS)}"
        )
    {".textgrid": _write_textgrid, ".csv": _write_csv, ".json": _write_json}[suffix](timings, path)
    log.debug("wrote %d phones to %s", len(timings.phones), path)
    return path


def _write_csv(timings: PhoneTimings, path: Path) -> None:
    with atomic_write(path, "w") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(["phoneme", "start", "end", *(["word"] if timings.words else [])])
        for p in timings.phones:
            word = [] if not timings.words else [timings.words[p.word] if p.word is not None else ""]
            writer.writerow([_label(p), repr(p.start_s), repr(p.end_s), *word])


def _write_json(timings: PhoneTimings, path: Path) -> None:
    phones = [
        {
            "phoneme": _label(p),
            "start": p.start_s,
            "end": p.end_s,
            **({} if p.word is None else {"word": p.word}),
        }
        for p in timings.phones
    ]
    data = {"language": timings.language, "words": list(timings.words), "phones": phones}
    with atomic_write(path, "w") as handle:
        handle.write(json.dumps(data, ensure_ascii=False, indent=1) + "\n")


def _write_textgrid(timings: PhoneTimings, path: Path) -> None:
    from praatio import textgrid

    start, end = min(0.0, timings.start_s), max(timings.end_s, OVERLAP_TOLERANCE_S)
    grid = textgrid.Textgrid()
    phones = [(p.start_s, p.end_s, _label(p)) for p in timings.spoken()]
    grid.addTier(textgrid.IntervalTier("phones", phones, start, end))
    if timings.words:
        spans: dict[int, list[float]] = {}
        for p in timings.spoken():
            if p.word is not None:
                spans.setdefault(p.word, [p.start_s, p.end_s])[1] = p.end_s
        words = [(s, e, timings.words[k]) for k, (s, e) in sorted(spans.items())]
        grid.addTier(textgrid.IntervalTier("words", words, start, end))
    with atomic_path(path, keep_suffix=True) as tmp:
        grid.save(str(tmp), format="long_textgrid", includeBlankSpaces=True, reportingMode="silence")


# --------------------------------------------------------------------------- naive timing


def naive_timings(text: str, *, language: str = "en", rate: float = 1.0) -> PhoneTimings:
    """Phone timings from text alone: phones from ``text_to_phonemes`` (English) or
    ``nso.nso_to_phonemes``, each lasting its typical duration (``english_duration_s``,
    ``nso.DURATIONS_S``), pauses at punctuation (``PAUSE_S``, ``SENTENCE_PAUSE_S`` after . ! ? …),
    from 0 s with no gaps.

    Parameters
    ----------
    text : str
        What is said.
    language : {"en", "nso"}
    rate : float
        Speaking speed relative to normal: 2.0 speaks twice as fast (every duration halved).

    Raises
    ------
    SpeechError
        ``rate`` is not a positive number, the text has no words, or a word cannot be read (see
        ``text_to_phonemes``, ``nso.nso_to_phonemes``).
    """
    if not (math.isfinite(rate) and rate > 0):
        raise SpeechError(f"rate must be a positive number (1.0 is normal, 2.0 twice as fast); got {rate}")
    if language not in LANGUAGES:
        raise SpeechError(f"unknown language {language!r}; mimetic speaks {', '.join(LANGUAGES)}")
    words: tuple[WordPhones, ...] = text_to_phonemes(text) if language == "en" else nso.nso_to_phonemes(text)
    if not words:
        raise SpeechError(f"no words to time in {text!r}")
    phones: list[Phone] = []
    spoken: list[str] = []
    t = 0.0
    for word in words:
        if not word.is_pause:
            spoken.append(word.text)
        for label, stress in word.phones:
            if label == SILENCE:
                duration = SENTENCE_PAUSE_S if set(word.text) & set(SENTENCE_MARKS) else PAUSE_S
            else:
                duration = english_duration_s(label, stress) if language == "en" else nso.DURATIONS_S[label]
            index = None if word.is_pause else len(spoken) - 1
            phones.append(Phone(label, t, t + duration / rate, stress, index))
            t += duration / rate
    return PhoneTimings(tuple(phones), language, tuple(spoken))


def boundary_errors(timings: PhoneTimings, reference: PhoneTimings) -> tuple[np.ndarray, int]:
    """How far the phone boundaries of ``timings`` lie from those of ``reference`` (an alignment's
    accuracy): the spoken phones are matched in order by their labels (``difflib``, so a phone one
    side has and the other lacks is skipped), and each matched pair gives its start and end errors.

    Returns
    -------
    errors : (2 m,) float64
        Absolute boundary errors, seconds, for the ``m`` matched phones.
    matched : int
        ``m``; ``len(reference.spoken())`` is the most there can be.
    """
    ours, theirs = timings.spoken(), reference.spoken()
    matcher = difflib.SequenceMatcher(
        None, [p.label for p in ours], [p.label for p in theirs], autojunk=False
    )
    errors = [
        abs(getattr(ours[block.a + i], end) - getattr(theirs[block.b + i], end))
        for block in matcher.get_matching_blocks()
        for i in range(block.size)
        for end in ("start_s", "end_s")
    ]
    return np.array(errors), len(errors) // 2
