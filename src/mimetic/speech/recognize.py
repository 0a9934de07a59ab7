"""Audio alone → phone timings, offline, with pocketsphinx's bundled English models.

Two ways, both giving the ``PhoneTimings`` that alignment gives (so the same coarticulation follows):

* ``"words"`` (the default): recognise the words with the bundled English language model
  (``en-us.lm.bin``), then force-align them (``align.align_audio``, unchecked: the recognised words
  are what the recogniser heard). Phones come from the dictionary, so they are whole, plausible
  words even where a word is misrecognised ("dashwood had then" → "guess would have been").
* ``"phones"``: free phone recognition with the bundled phone language model
  (``en-us-phone.lm.bin``), each recognised phone as it is timed. Faster, but noisy.

Why words: measured (``benchmarks/bench_speech.py``, table 1b) against the reference phones of the 5
LibriVox utterances and the hand-labelled praatIO "bobby", words then alignment matched 221 of 251
reference phones, 98 % of their boundaries within 50 ms, the reference's mouth shape (Rhubarb's
A-H, X) at 94 % of 10 ms frames and 24 of 29 lip closures (text and audio: 26); phone decoding
115 of 251, 87 %, 74 % and 17 of 29. On bobby (1.2 s) the two are close: 11 vs 10 of 14 phones,
91 vs 85 % within 50 ms, 73 vs 71 % of frames, 1 vs 2 of 3 closures. The LibriVox references were
made by pocketsphinx's own aligner, which favours the words route there; bobby is the independent
check. The price is time: about 0.5-0.8 s of computing per second of audio on the shared 2-core
machine, against 0.1 s.

English only: the models are English. Northern Sotho audio needs its transcript.
"""

from __future__ import annotations

import logging
import re
from pathlib import Path

from mimetic.errors import MissingExtraError, SpeechError, install_hint
from mimetic.speech.align import FRAME_S, SAMPLE_RATE, align_audio, pcm16, read_wav
from mimetic.speech.phones import SILENCE, Phone, PhoneTimings

log = logging.getLogger(__name__)

METHODS = ("words", "phones")
"""``recognize_timings``' ways: word recognition then alignment (the default), free phone decoding."""
_PHONE = re.compile(r"[A-Z]{1,2}")
"""An ARPAbet phone as pocketsphinx's phone decoder names it (fillers are "+NSN+", "SIL", …)."""


def _pocketsphinx():
    try:
        import pocketsphinx
    except ImportError as error:
        raise MissingExtraError(
            "recognising speech needs pocketsphinx, in the optional extra [speech]: "
            f"{install_hint('speech')}; importing it failed: {error}"
        ) from error
    return pocketsphinx


def _decode(audio: bytes, **search) -> list:
    """pocketsphinx's segments of 16 kHz PCM ``audio`` with the search ``search`` (its keywords)."""
    pocketsphinx = _pocketsphinx()
    decoder = pocketsphinx.Decoder(samprate=SAMPLE_RATE, loglevel="FATAL", dither=True, seed=1, **search)
    decoder.start_utt()
    decoder.process_raw(audio, full_utt=True)
    decoder.end_utt()
    return list(decoder.seg())


def recognize_words(wav_path: str | Path) -> list[str]:
    """The words pocketsphinx hears in a PCM WAV file (bundled English language model), in order,
    lower case, without pauses, fillers or pronunciation variants ("to(2)" → "to")."""
    segments = _decode(pcm16(*read_wav(wav_path)))
    words = [s.word.split("(")[0] for s in segments]
    return [w for w in words if w and w[0] not in "<[+"]


def recognize_phones(wav_path: str | Path) -> PhoneTimings:
    """Phone timings of a PCM WAV file by free phone recognition (bundled phone language model):
    each recognised ARPAbet phone (no stress, no words) on pocketsphinx's 10 ms grid, pauses and
    fillers as ``SILENCE``."""
    model = Path(_pocketsphinx().get_model_path()) / "en-us" / "en-us-phone.lm.bin"
    segments = _decode(pcm16(*read_wav(wav_path)), allphone=str(model), lm=None, bestpath=False)
    phones: list[Phone] = []
    for s in segments:
        label = s.word if _PHONE.fullmatch(s.word) else SILENCE
        start, end = s.start_frame * FRAME_S, (s.end_frame + 1) * FRAME_S
        if phones and phones[-1].label == SILENCE and label == SILENCE:
            phones[-1] = Phone(SILENCE, phones[-1].start_s, end)
        else:
            phones.append(Phone(label, start, end))
    return PhoneTimings(tuple(phones), "en")


def recognize_timings(wav_path: str | Path, *, method: str = "words", language: str = "en") -> PhoneTimings:
    """Phone timings of a recording without its transcript (see the module docstring).

    Parameters
    ----------
    wav_path : path-like
        A PCM WAV file (any rate and channel count, as ``align.read_wav``).
    method : {"words", "phones"}
    language : str
        Only "en": other languages need their transcript.

    Returns
    -------
    PhoneTimings
        From 0 s at the start of the audio; all silence when nothing is heard.

    Raises
    ------
    MissingExtraError
        pocketsphinx (extra ``[speech]``) is not installed.
    SpeechError
        Not English, an unknown ``method``, or the audio cannot be read.
    """
    if language != "en":
        raise SpeechError(
            f"audio alone is recognised in English only; for language {language!r} pass the transcript "
            "too (--text or --text-file)"
        )
    if method not in METHODS:
        raise SpeechError(f"unknown recognition method {method!r}; use one of {', '.join(METHODS)}")
    if method == "phones":
        return recognize_phones(wav_path)
    words = recognize_words(wav_path)
    log.info("heard %d words in %s: %s", len(words), wav_path, " ".join(words))
    if not words:
        samples, rate = read_wav(wav_path)
        return PhoneTimings((Phone(SILENCE, 0.0, max(len(samples) / rate, FRAME_S)),), "en")
    return align_audio(wav_path, " ".join(words), force=True)
