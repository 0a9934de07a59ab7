"""One call from what a user has (text, a timing file, or audio with its transcript) to a clip.

``lip_sync`` picks the timing source, coarticulates (``coarticulation``), optionally adds blinks and
saccades, and makes the clip last as long as the audio, so a video never cuts the sound.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mimetic.errors import SpeechError
from mimetic.rig.activations import Clip
from mimetic.rig.model import Rig
from mimetic.speech import nso
from mimetic.speech.align import align_audio, read_wav, synthesize
from mimetic.speech.coarticulation import add_eye_motion, coarticulate, linear_clip
from mimetic.speech.phones import SILENCE, Phone, PhoneTimings
from mimetic.speech.recognize import recognize_timings
from mimetic.speech.timings import load_timings, naive_timings
from mimetic.speech.visemes import VisemeMap

PathLike = str | os.PathLike[str]
TAIL_S = 0.4
"""Silence added after the last phone when the timings end on a sound: the face relaxes to rest."""


ENGLISH_VOICE = "en-us"
"""The espeak-ng voice that speaks English text (Northern Sotho: ``nso.SYNTHESIS_VOICE``)."""


@dataclass(frozen=True)
class Speech:
    """A lip-synced performance: its phone ``timings``, the ``clip`` of activations and the ``audio``
    it plays with (None for none); ``source`` says where the timings came from; ``notes`` what the
    user should be told (Sepedi spoken by the Setswana voice)."""

    timings: PhoneTimings
    clip: Clip
    audio: Path | None
    source: str
    notes: tuple[str, ...] = ()


def _timings(
    text: str | None,
    timings: PathLike | None,
    audio: PathLike | None,
    synthesize_to: PathLike | None,
    language: str,
    rate: float,
    force: bool = False,
) -> tuple[PhoneTimings, Path | None, str]:
    if timings is not None:
        if synthesize_to is not None:
            raise SpeechError("synthesized audio needs text, not a timing file; give one or the other")
        return load_timings(timings, language=language), _path(audio), f"timings {timings}"
    if (not text or not text.strip()) and audio is not None and synthesize_to is None:
        return recognize_timings(_path(audio), language=language), Path(audio), f"recognised from {audio}"
    if not text or not text.strip():
        raise SpeechError("nothing to say: give text (--text), a timing file (--timings) or audio (--audio)")
    if audio is not None and synthesize_to is not None:
        raise SpeechError("give either recorded audio (--audio) or --synthesize, not both")
    if synthesize_to is not None:
        voice = nso.SYNTHESIS_VOICE if language == "nso" else ENGLISH_VOICE
        spoken = nso.for_synthesis(text) if language == "nso" else text
        sound = synthesize(spoken, synthesize_to, voice=voice)
        source = f"aligned to speech synthesized by espeak-ng -v {voice}"
        # synthesized speech says its text by construction, and espeak-ng's voice scores below
        # recordings (the demo sentence fell under align.MISMATCH_SCORE): never checked
        return align_audio(sound, text, language=language, force=True), sound, source
    if audio is not None:
        return align_audio(audio, text, language=language, force=force), Path(audio), f"aligned to {audio}"
    return naive_timings(text, language=language, rate=rate), None, f"text at rate {rate:g}"


def _path(audio: PathLike | None) -> Path | None:
    if audio is None:
        return None
    path = Path(audio)
    if not path.is_file():
        raise SpeechError(f"audio {path} not found")
    return path


def _with_tail(timings: PhoneTimings) -> PhoneTimings:
    """``timings`` ending in a pause of ``TAIL_S`` (unless they already end in one)."""
    if not timings.phones or timings.phones[-1].label == SILENCE:
        return timings
    tail = Phone(SILENCE, timings.end_s, timings.end_s + TAIL_S)
    return PhoneTimings((*timings.phones, tail), timings.language, timings.words)


def _hold(clip: Clip, rig: Rig, seconds: float) -> Clip:
    """``clip`` extended with the rest pose to cover ``seconds`` (at least one frame past its end)."""
    frames = math.floor(seconds * clip.fps + 1e-9) + 1
    if frames <= clip.n_frames:
        return clip
    rest = np.array([rig.channels[rig.channel_index(name)].default for name in clip.channels])
    tail = np.tile(rest, (frames - clip.n_frames, 1))
    return Clip(clip.channels, np.concatenate([clip.values, tail]), clip.fps)


def lip_sync(
    rig: Rig,
    *,
    text: str | None = None,
    timings: PathLike | None = None,
    audio: PathLike | None = None,
    synthesize_to: PathLike | None = None,
    language: str = "en",
    fps: float = 30.0,
    visemes: VisemeMap | str | None = None,
    jaw: float = 1.0,
    lips: float = 1.0,
    rate: float = 1.0,
    eyes: bool = False,
    seed: int = 0,
    baseline: bool = False,
    force: bool = False,
) -> Speech:
    """Lip sync for ``rig`` from one source:

    * ``timings``: a phone timing file (TextGrid, CSV, JSON, pocketsphinx alignment JSON);
    * ``audio`` (WAV) with its transcript ``text``: forced alignment (pocketsphinx, extra ``[speech]``),
      refused where the audio does not say the text unless ``force`` (``align.align_audio``);
    * ``audio`` alone: English speech recognised offline, then aligned (``recognize.recognize_timings``);
    * ``text`` and ``synthesize_to`` (a WAV path): speech synthesized by the ``espeak-ng`` program,
      then aligned, so the mouth matches the sound; Northern Sotho with the nearest voice espeak-ng
      has (``nso.SYNTHESIS_VOICE``, Setswana), which ``Speech.notes`` says;
    * ``text`` alone: naive timing at ``rate`` (2 = twice as fast).

    ``visemes`` is a map name ("en", "nso", "mpeg4"), a ``VisemeMap`` or None (the language's own);
    ``jaw`` and ``lips`` (0..2) are the JALI-style intensity dials; ``eyes`` adds blinks and saccades
    (seeded by ``seed``); ``baseline`` gives the linear-interpolation baseline instead of the
    coarticulated curves. The clip is at ``fps``, ends at rest (timings that end on a sound get a
    pause of ``TAIL_S``) and lasts at least as long as the audio.
    """
    phones, sound, source = _timings(text, timings, audio, synthesize_to, language, rate, force)
    phones = _with_tail(phones)
    if baseline:
        clip = linear_clip(phones, rig, fps, viseme_map=visemes)
    else:
        clip = coarticulate(phones, rig, fps, viseme_map=visemes, jaw=jaw, lips=lips)
    if sound is not None:
        samples, sample_rate = read_wav(sound)
        clip = _hold(clip, rig, len(samples) / sample_rate)
    if eyes:
        clip = add_eye_motion(clip, rig, seed=seed)
    notes = (nso.SYNTHESIS_NOTE,) if synthesize_to is not None and language == "nso" else ()
    return Speech(phones, clip, sound, source, notes)


CLOSURE_EASE_S = 0.06
"""Around a bilabial or labiodental phone, a held expression's mouth comes back over this long."""


def under_expression(
    clip: Clip, timings: PhoneTimings, rig: Rig, pose: np.ndarray, *, visemes: VisemeMap | str | None = None
) -> Clip:
    """``clip`` played over a held expression ``pose`` (c,) in ``rig.channel_names`` order (e.g.
    ``animate.expressions.blend(rig, [("joy", 0.4)])``), with the closures kept.

    The expression's offset from rest, ``pose - rest``, is added to every frame. On the channels a
    closure sets (those the map's bilabial and labiodental targets move from rest: the jaw, the
    orbicularis oris, the mentalis …) it is faded out by a closure weight w(t): 1 during each
    bilabial and labiodental phone of ``timings``, easing back to 0 over ``CLOSURE_EASE_S`` on either
    side (raised cosine), so P B M F V close the lips as they do without the expression. The other
    channels (a smile's zygomatics, the brows, the lids) keep it throughout: a smile does not flicker
    at each /m/. On the default head with the wire engine, joy:0.4 alone parts the lips by 1.5 % of
    the head's size; at the bilabials of "my mom bought a map by the pub" the gap is 0.33 % with it
    and 0.38 % without. Values
    are clipped into their ranges; the clip keeps its channels, frames and fps.
    """
    from mimetic.rig.activations import check_activations
    from mimetic.speech.coarticulation import CLOSURE_CLASSES
    from mimetic.speech.visemes import phone_targets, viseme_map

    vmap = viseme_map(timings.language) if visemes is None else visemes
    vmap = viseme_map(vmap) if isinstance(vmap, str) else vmap
    channels = [rig.channels[rig.channel_index(name)] for name in clip.channels]
    rest = np.array([c.default for c in channels])
    order = [rig.channel_index(name) for name in clip.channels]
    offset = np.asarray(pose, dtype=np.float64)[order] - rest  # (c,)
    closing = tuple(label for label, entry in vmap.phones.items() if entry.kind in CLOSURE_CLASSES)
    targets = phone_targets(vmap, closing, channels)  # (p, c)
    driven = (np.abs(targets - rest) > 1e-9).any(axis=0)  # (c,) the channels a closure sets
    t = np.arange(clip.n_frames) / clip.fps  # (f,)
    w = np.zeros(clip.n_frames)
    for phone in timings.phones:
        if phone.label in vmap.phones and vmap.phone(phone.label).kind in CLOSURE_CLASSES:
            outside = np.maximum(np.maximum(phone.start_s - t, t - phone.end_s), 0.0)  # s beyond the phone
            w = np.maximum(w, np.cos(0.5 * np.pi * np.clip(outside / CLOSURE_EASE_S, 0.0, 1.0)) ** 2)
    values = clip.values + offset * np.where(driven, 1.0 - w[:, None], 1.0)
    return Clip(clip.channels, check_activations(channels, values, clip=True), clip.fps)
