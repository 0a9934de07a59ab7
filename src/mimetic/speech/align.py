"""Audio + transcript → phone timings, offline, by pocketsphinx forced alignment; and speech audio for
text from the ``espeak-ng`` program.

``align_audio`` reads a PCM WAV (any rate, any channels), converts it to what pocketsphinx's
bundled English model needs (16 kHz mono 16-bit), and runs pocketsphinx's two-pass alignment: a
word alignment of the transcript (optional pauses between words), then a phone alignment inside
it, on a 10 ms frame grid (at least 30 ms a phone). The settings are those of pocketsphinx's own
``align`` command (no language model, no best-path rescoring), which made the shared data's
LibriVox reference alignments. Words missing from pocketsphinx's dictionary are added with the
phones of ``mimetic.speech.english``; stress digits are taken from the CMU dictionary
pronunciation that matches the aligned phones.

Northern Sotho: no acoustic model exists, so each phone is aligned as its nearest English phones
(``nso.TO_ARPABET``: KG as K HH, TLH as T L, …) by the English model, and the English segments are
joined back into the Sepedi phone. This is an approximation: expect boundaries to be rougher than
in English, especially for phones English lacks (HL, KG, G, BJ).

**A transcript that does not match the audio is refused** (English; ``force=True`` aligns it
anyway). pocketsphinx scores each aligned frame against the best-scoring model state of that frame
(its senone scores are normalised so the best is 0), so an aligned word's score per frame is a
goodness of fit next to an unconstrained choice of sound: near 0 where the audio says the word, far
below where it says something else. ``transcript_mismatch`` averages it over stretches of at least
``CHECK_WINDOW_S`` of consecutive aligned words and pauses and refuses the transcript when a stretch
falls below ``MISMATCH_SCORE``; the pauses at the padded ends (``PAD_S``) are passed over. Measured
(``benchmarks/bench_speech.py``, table 1c) on the 5 LibriVox utterances and praatIO's "bobby" with
their own transcripts, and with wrong ones (the next utterance's text, the words shuffled, the
second half replaced, seeded): worst stretch of a correct transcript -27.0 (5 espeak-ng sentences
measured once by hand: -44.3); of the 18 wrong ones 5 do not align at all and the others score
-49.2 or lower. The margin is thin on the wrong side, and a wrong transcript that keeps much of
the audio's words and rhythm can pass (the second half of 0920 replaced by the next text's second
half scored -15.9).
espeak-ng's voice is not reliably above it (the demo's sentence, ``tasks.demo.TALK``, has a stretch below), so
``lipsync.lip_sync`` does not check the speech it synthesizes. Comparing with a free phone
decoding of the same stretch (its phones force-aligned, so the scores share units) separated the
recordings as well but not the espeak-ng sentences, so the plain score is used. Wrong transcripts
that pruned every path fail to align at all (a ``SpeechError`` whatever ``force`` says).

pocketsphinx is in the extra ``[speech]``; espeak-ng (GPL) is only ever run as a separate program.
"""

from __future__ import annotations

import logging
import shutil
import subprocess
import wave
from math import gcd
from pathlib import Path

import numpy as np

from mimetic.atomic import atomic_path
from mimetic.errors import MissingExtraError, SpeechError, install_hint
from mimetic.speech import nso
from mimetic.speech.english import cmu_pronunciations, text_to_phonemes
from mimetic.speech.phones import LANGUAGES, PhoneTimings, WordPhones
from mimetic.speech.timings import timings_from_words

log = logging.getLogger(__name__)

SAMPLE_RATE = 16000
"""Hz: the rate of pocketsphinx's English acoustic model."""
FRAME_S = 0.01
"""pocketsphinx's frame: alignment times are multiples of it."""
MISMATCH_SCORE = -48.0
"""Mean aligned score per frame (pocketsphinx's log units, 0 = the frame's best state) below which a
stretch of the alignment does not say its words (see the module docstring for the measurement)."""
CHECK_WINDOW_S = 0.5
"""The shortest stretch ``transcript_mismatch`` judges: a short word alone scores too noisily."""
ESPEAK_TIMEOUT_S = 60.0
PAD_S = 0.3
"""Silence added before and after the audio for the alignment (seconds, then taken off): without it
a recording that starts or ends on speech gives its leading silence to the first phone, or runs the
last past the speech (the onset was more than 100 ms early in about a quarter of such recordings)."""
NOISE_FRAME_S = 0.02
"""Frames whose RMS gives the recording's background level."""
WIDE_BEAMS = {"beam": 1e-80, "wbeam": 1e-60, "pbeam": 1e-80}
"""The second try's search beams (pocketsphinx's defaults are 1e-48, 7e-29, 1e-48): a long
synthesized sentence (6.5 s) pruned every path with the defaults and aligned with these."""


def read_wav(path: str | Path) -> tuple[np.ndarray, int]:
    """The samples of a PCM WAV file, channels averaged.

    Returns
    -------
    samples : (n,) float64 in [-1, 1]
    rate : int, Hz

    Raises
    ------
    SpeechError
        The file is missing, not a WAV file, not PCM (e.g. float or compressed WAV), or holds no
        samples.
    """
    path = Path(path)
    convert = f"convert it, e.g. ffmpeg -i {path.name} -ac 1 -ar {SAMPLE_RATE} -sample_fmt s16 out.wav"
    try:
        with wave.open(str(path), "rb") as wav:
            channels, width, rate = wav.getnchannels(), wav.getsampwidth(), wav.getframerate()
            data = wav.readframes(wav.getnframes())
    except FileNotFoundError:
        raise SpeechError(f"{path}: no such audio file") from None
    except (wave.Error, EOFError) as error:
        raise SpeechError(f"{path}: not a PCM WAV file ({error}); {convert}") from None
    n = len(data) // (width * channels)
    if n == 0:
        raise SpeechError(f"{path}: the WAV file holds no samples")
    if width == 3:  # 24-bit little-endian: assemble, then sign-extend
        raw = np.frombuffer(data[: n * channels * 3], np.uint8).reshape(-1, 3).astype(np.int64)
        ints = raw[:, 0] | (raw[:, 1] << 8) | (raw[:, 2] << 16)
        ints, scale = np.where(ints >= 1 << 23, ints - (1 << 24), ints), 2.0**23
    else:
        dtype = {1: np.uint8, 2: np.dtype("<i2"), 4: np.dtype("<i4")}[width]
        ints = np.frombuffer(data[: n * channels * width], dtype).astype(np.int64)
        ints, scale = (ints - 128, 128.0) if width == 1 else (ints, 2.0 ** (8 * width - 1))
    samples = ints.reshape(n, channels).mean(axis=1) / scale
    return samples, rate


def pcm16(samples: np.ndarray, rate: int) -> bytes:
    """Mono samples (n,) float64 in [-1, 1] at ``rate`` Hz → 16 kHz 16-bit little-endian PCM bytes
    (polyphase resampling, ``scipy.signal.resample_poly``)."""
    if rate != SAMPLE_RATE:
        from scipy.signal import resample_poly  # a slow import (seconds): only when needed

        g = gcd(SAMPLE_RATE, rate)
        samples = resample_poly(samples, SAMPLE_RATE // g, rate // g)
    return np.clip(np.round(samples * 32768.0), -32768, 32767).astype("<i2").tobytes()


def _decoder(wide: bool = False):
    try:
        from pocketsphinx import Decoder
    except ImportError as error:
        raise MissingExtraError(
            f"aligning audio needs pocketsphinx, in the optional extra [speech]: {install_hint('speech')}; "
            f"importing it failed: {error}"
        ) from error
    # As pocketsphinx's `align` command: no language model, no best-path pass. Dither (seeded, so
    # results repeat) because digital silence, as in synthesized speech, makes the search fail.
    beams = WIDE_BEAMS if wide else {}
    return Decoder(
        samprate=SAMPLE_RATE, lm=None, bestpath=False, loglevel="FATAL", dither=True, seed=1, **beams
    )


def _align(decoder, audio: bytes, words: list[str]) -> list[tuple[str, list[tuple[str, float, float]], int]]:
    """Two-pass alignment of ``words`` (all in the decoder's dictionary) to 16 kHz PCM ``audio``:
    [(word, [(phone, start_s, end_s), …], score), …] with pocketsphinx's pauses as words "<sil>";
    ``score`` is the word's acoustic score summed over its frames (log units, ≤ 0)."""
    failed = (
        "pocketsphinx could not align the transcript to the audio ({}): check that the audio says "
        "exactly the transcript and is not silent or too short"
    )
    try:
        decoder.set_align_text(" ".join(words))
        for second in (False, True):
            if second:
                decoder.set_alignment()
            decoder.start_utt()
            decoder.process_raw(audio, full_utt=True)
            decoder.end_utt()
        alignment = decoder.get_alignment()
    except RuntimeError as error:
        raise SpeechError(failed.format(error)) from None
    if alignment is None:
        raise SpeechError(failed.format("no alignment"))
    return [
        (w.name, [(p.name, p.start * FRAME_S, (p.start + p.duration) * FRAME_S) for p in w], w.score)
        for w in alignment
    ]


def stretch_scores(aligned: list[tuple[str, list, int]], edge_s: float = 0.0) -> list[tuple[int, int, float]]:
    """Mean score per frame of each stretch of ``aligned`` (``_align``'s words): [(i, j, score)]
    for the runs ``aligned[i:j]`` of consecutive words (pauses included) starting at each word and
    just reaching ``CHECK_WINDOW_S`` (the whole alignment when it is shorter). Pauses within
    ``edge_s`` of either end are passed over: they score the padding (``PAD_S``), not the transcript."""
    end_s = aligned[-1][1][-1][2] if aligned else 0.0

    def counted(name: str, phones: list) -> bool:
        edge = phones[0][1] < edge_s - 1e-9 or phones[-1][2] > end_s - edge_s + 1e-9
        return not (edge and name.startswith(("<", "[")))

    frames = [round((p[-1][2] - p[0][1]) / FRAME_S) if counted(name, p) else 0 for name, p, _ in aligned]
    window = round(CHECK_WINDOW_S / FRAME_S)
    stretches = []
    for i in range(len(aligned)):
        j, n = i, 0
        while j < len(aligned) and n < window:
            n, j = n + frames[j], j + 1
        if n < window and i > 0:
            break  # the tail is inside an earlier stretch
        score = sum(aligned[k][2] for k in range(i, j) if frames[k])
        stretches.append((i, j, score / max(n, 1)))
    return stretches


def transcript_mismatch(aligned: list[tuple[str, list, int]], offset_s: float = 0.0) -> str | None:
    """The first stretch of ``aligned`` (``stretch_scores``) below ``MISMATCH_SCORE``, as "from A s
    to B s ("words")" on a clock ``offset_s`` behind the alignment's, or None when every stretch
    matches; overlapping bad stretches are one."""
    bad: tuple[int, int] | None = None
    for i, j, score in stretch_scores(aligned, offset_s):
        if score < MISMATCH_SCORE:
            bad = (i, j) if bad is None else (bad[0], j)
            log.debug("stretch %d..%d scores %.1f a frame", i, j, score)
        elif bad is not None and i >= bad[1]:
            break
    if bad is None:
        return None
    stretch = aligned[bad[0] : bad[1]]
    words = " ".join(name.split("(")[0] for name, _, _ in stretch if not name.startswith("<")) or "a pause"
    start, end = stretch[0][1][0][1] - offset_s, stretch[-1][1][-1][2] - offset_s
    return f'from {max(start, 0.0):.2f} s to {end:.2f} s ("{words}")'


def _stressed(word: str, phones: list[tuple[str, float, float]], guess: WordPhones | None) -> list:
    """``phones`` of an aligned English word with stress digits from the CMU dictionary (or the
    letter-to-sound ``guess``) pronunciation that has the same phones; unchanged without one."""
    labels = [p[0] for p in phones]
    candidates = [*cmu_pronunciations(word.split("(")[0]), *([guess.phones] if guess else [])]
    match = next((pron for pron in candidates if [label for label, _ in pron] == labels), None)
    if match is None:
        return phones
    return [
        (label + ("" if s is None else str(s)), a, b)
        for (label, a, b), (_, s) in zip(phones, match, strict=True)
    ]


def _align_words(decoder, audio: bytes, spoken: list[WordPhones], language: str) -> tuple[list[str], list]:
    """``_align`` of the words ``spoken`` (added to the decoder's dictionary where missing): the
    dictionary keys used and the alignment."""
    if language == "en":
        for w in spoken:
            if decoder.lookup_word(w.text) is None:
                decoder.add_word(w.text, " ".join(label for label, _ in w.phones))
        keys = [w.text for w in spoken]
    else:  # each Sepedi word as a made-up English word of its nearest English phones
        keys = [f"nso{i}" for i in range(len(spoken))]
        for key, w in zip(keys, spoken, strict=True):
            decoder.add_word(key, " ".join(a for label, _ in w.phones for a in nso.TO_ARPABET[label]))
    return keys, _align(decoder, audio, keys)


def align_audio(
    wav_path: str | Path, transcript: str, *, language: str = "en", force: bool = False
) -> PhoneTimings:
    """Phone timings of a recording of ``transcript`` (see the module docstring).

    Parameters
    ----------
    wav_path : path-like
        A PCM WAV file (8/16/24/32-bit, any rate and channel count; channels are averaged).
    transcript : str
        Exactly what is said; numbers and punctuation are fine (English is read by
        ``text_to_phonemes``, Northern Sotho by ``nso.nso_to_phonemes``).
    language : {"en", "nso"}
    force : bool
        Align an English transcript even where the audio does not say it (see the module docstring);
        Northern Sotho is never checked (English scores of Sepedi sounds say little).

    Returns
    -------
    PhoneTimings
        From 0 s at the start of the audio to its end, on a 10 ms grid: pauses as ``SILENCE``,
        ``words`` the transcript's spoken words (English numbers spelled out).

    Raises
    ------
    MissingExtraError
        pocketsphinx (extra ``[speech]``) is not installed.
    SpeechError
        The audio cannot be read (see ``read_wav``), the transcript has no words or cannot be read,
        the alignment fails, or (English, without ``force``) the audio does not say the transcript.
    """
    if language not in LANGUAGES:
        raise SpeechError(f"unknown language {language!r}; mimetic speaks {', '.join(LANGUAGES)}")
    spoken = [
        w
        for w in (text_to_phonemes if language == "en" else nso.nso_to_phonemes)(transcript)
        if not w.is_pause
    ]
    if not spoken:
        raise SpeechError(f"the transcript {transcript!r} has no words to align")
    samples, rate = read_wav(wav_path)
    audio = pcm16(padded(samples, rate), rate)
    try:
        keys, aligned = _align_words(_decoder(), audio, spoken, language)
    except SpeechError:  # the first pass pruned every path: search again with wide beams
        keys, aligned = _align_words(_decoder(wide=True), audio, spoken, language)
    log.debug("aligned %d words to %s", len(spoken), wav_path)
    if language == "en" and not force and (stretch := transcript_mismatch(aligned, PAD_S)) is not None:
        raise SpeechError(
            f"{Path(wav_path).name}: the audio does not say the transcript {stretch}; check the text, "
            "or pass force=True to align it anyway"
        )
    if language == "en":
        guesses = {w.text: w for w in spoken}
        words = [
            (name, _stressed(name, phones, guesses.get(name.split("(")[0]))) for name, phones, _ in aligned
        ]
    else:
        words = [_join_nso(name, phones, spoken, keys) for name, phones, _ in aligned]
    return timings_from_words(_unpadded(words, len(samples) / rate), language=language, source=str(wav_path))


def padded(samples: np.ndarray, rate: int) -> np.ndarray:
    """``samples`` (n,) with ``PAD_S`` of the recording's own background before and after: seeded
    noise at the 20th percentile of its ``NOISE_FRAME_S`` frames' RMS, so the aligner's silence model
    takes the padding and any lead-in alike."""
    frame = max(1, round(NOISE_FRAME_S * rate))
    frames = samples[: len(samples) // frame * frame].reshape(-1, frame)
    level = float(np.percentile(np.sqrt((frames**2).mean(axis=1)), 20)) if len(frames) else 0.0
    noise = np.random.default_rng(0).normal(0.0, level, (2, round(PAD_S * rate)))
    return np.concatenate([noise[0], samples, noise[1]])


def _unpadded(words: list, duration_s: float) -> list:
    """Aligned words [(name, [(phone, start_s, end_s), …]), …] of the padded audio back on the
    recording's clock: shifted by ``PAD_S`` and cut to [0, ``duration_s``] (phones wholly in the
    padding dropped, and words left without phones)."""
    out = []
    for name, phones in words:
        kept = [
            (label, max(a - PAD_S, 0.0), min(b - PAD_S, duration_s))
            for label, a, b in phones
            if min(b - PAD_S, duration_s) - max(a - PAD_S, 0.0) > 1e-9
        ]
        if kept:
            out.append((name, kept))
    return out


def _join_nso(name: str, phones: list, spoken: list[WordPhones], keys: list[str]) -> tuple[str, list]:
    """An aligned made-up word back as its Sepedi word and phones: each phone spans the English
    phones it was aligned as."""
    if name not in keys:
        return name, phones  # a pause
    word = spoken[keys.index(name)]
    joined, k = [], 0
    for label, _ in word.phones:
        n = len(nso.TO_ARPABET[label])
        joined.append((label, phones[k][1], phones[k + n - 1][2]))
        k += n
    return word.text, joined


def synthesize(text: str, wav_path: str | Path, *, voice: str = "en-us") -> Path:
    """Speak ``text`` into a WAV file with the ``espeak-ng`` program (run as a separate process);
    ``align_audio(wav_path, text)`` then gives timings that match the sound.

    Parameters
    ----------
    text : str
    wav_path : path-like
        The WAV file to write (22,050 Hz mono 16-bit); written atomically.
    voice : str
        An espeak-ng voice (``espeak-ng --voices``). espeak-ng has no Northern Sotho voice;
        "tn" (Setswana, a close relative) is a rough stand-in that misreads some Sepedi spellings.

    Raises
    ------
    SpeechError
        espeak-ng is not installed, or fails (e.g. an unknown voice).
    """
    program = shutil.which("espeak-ng")
    if program is None:
        raise SpeechError(
            "synthesize needs the espeak-ng program (e.g. apt-get install espeak-ng, or brew install "
            "espeak-ng); without it, use naive_timings for timings from text"
        )
    with atomic_path(wav_path, keep_suffix=True) as tmp:
        result = subprocess.run(
            [program, "-v", voice, "-w", str(tmp), "--stdin"],
            input=text,
            capture_output=True,
            text=True,
            timeout=ESPEAK_TIMEOUT_S,
            check=False,
        )
        if result.returncode != 0:
            raise SpeechError(
                f"espeak-ng -v {voice} failed (exit {result.returncode}): {result.stderr.strip()}"
            )
    return Path(wav_path)
