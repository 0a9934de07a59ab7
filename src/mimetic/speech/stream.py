"""Live lip sync: audio pushed in chunks → activation frames as soon as they are final.

``LiveLipSync(rig).push(samples)`` takes mono audio of any chunk size and returns the frames (at
``fps``) that the audio so far makes final; ``flush()`` returns the rest when the audio ends.
Nothing needs a transcript: the phones come from pocketsphinx's phone recogniser (``allphone``
search with the bundled English phone language model, extra ``[speech]``), run incrementally.

1. **Audio.** Samples (float in [-1, 1] or int16) at ``rate`` Hz are resampled causally to the
   recogniser's 16 kHz (``_Resampler``: a windowed-sinc low-pass carried across chunks, then linear
   interpolation; its group delay is taken off, so its times match the input's to a sample).
2. **Phones so far.** Frame k (time t = k / fps) is final once the audio reaches t + ``lookahead_s``
   (at most ``MAX_LOOKAHEAD_S``, 0.1 s, by default). The recogniser is fed exactly up to that
   sample, whatever the chunks were, and its *partial* segmentation then (``Decoder.seg()`` within
   the utterance: the best path to the last frame searched) gives the phones, the last one still
   in progress and ending at the last frame searched.
3. **Causal coarticulation.** The frame is ``coarticulation.coarticulate`` of those phones alone
   (the ones that end within ``HISTORY_S`` before t: older ones no longer reach it), so it depends on
   no audio later than t + ``lookahead_s``. Frames are returned once and never revised.

**The trade-off of the look-ahead.** Cohen–Massaro dominance anticipates: a phone's shape appears
up to ``WINDOW_S`` (0.3 s; 0.45 s for rounding) before its centre. With 0.1 s of look-ahead a frame
sees the phones starting up to 0.1 s after it (less the recogniser's few frames of feature delay),
so anticipation beyond that is lost: the mouth starts rounding for /uw/ later than offline, and the
phone under a frame is known from less of its sound (a recogniser's guess at a phone's first
frames is often revised). The centre of a phone still in progress is not known, so the closure
guarantee of a bilabial applies once its end has been heard: a /p/ shorter than about twice the
look-ahead still closes on its centre frame. More look-ahead agrees better with the offline lip
sync and costs latency one for one (``benchmarks/bench_live.py`` measures both).

The latency from a sound to its frame is then ``lookahead_s`` plus the chunk's length (a frame
waits for the chunk holding its look-ahead) plus the compute of ``push`` (a few ms per frame).
One utterance is decoded for the whole stream, so a stream of many minutes grows the
recogniser's memory; ``flush()`` ends it and the next ``push`` starts a new one at t = 0.
"""

from __future__ import annotations

import logging
import math
import os
import time
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from mimetic.errors import MissingExtraError, SpeechError, install_hint
from mimetic.rig.model import Channel, Rig
from mimetic.speech.align import SAMPLE_RATE, read_wav
from mimetic.speech.coarticulation import ROUNDING_WINDOW_S, coarticulate
from mimetic.speech.phones import SILENCE, Phone, PhoneTimings
from mimetic.speech.visemes import VisemeMap, viseme_map

log = logging.getLogger(__name__)

MAX_LOOKAHEAD_S = 0.1
"""The default look-ahead (seconds): no frame depends on audio more than this after it (up to
0.5 s may be asked for, at that much more latency)."""
HISTORY_S = ROUNDING_WINDOW_S + 0.05
"""Phones that ended this long before a frame cannot reach it (the widest dominance window, 0.45 s)."""
FRAME_S = 0.01
"""pocketsphinx's frame: segment times are multiples of it."""
RESAMPLE_TAPS = 63
"""Length of the anti-aliasing low-pass before resampling to 16 kHz (odd: an integer delay)."""


@dataclass(frozen=True)
class SpeechFrames:
    """The frames one ``push`` (or ``flush``) made final.

    Attributes
    ----------
    start : int
        Index of the first frame (frame k is at k / fps seconds of the audio's clock).
    values : (k, c) float64
        Activations of frames ``start`` … ``start + k - 1`` over the rig's channels; k may be 0.
    fps : float
    seconds : float
        Compute time of the call.
    """

    start: int
    values: np.ndarray
    fps: float
    seconds: float

    @property
    def times_s(self) -> np.ndarray:
        """(k,) float64, each frame's time in the audio, seconds."""
        return (self.start + np.arange(len(self.values))) / self.fps


class _Resampler:
    """Streaming resampling of mono float samples at ``rate`` to ``SAMPLE_RATE``: a windowed-sinc
    low-pass (state kept across chunks), then linear interpolation at the output instants shifted by
    the filter's delay. ``push(x)`` returns the output samples that the input so far determines."""

    def __init__(self, rate: int) -> None:
        self.rate = rate
        self.step = rate / SAMPLE_RATE  # input samples per output sample
        if rate != SAMPLE_RATE:
            from scipy.signal import firwin

            self.taps = firwin(RESAMPLE_TAPS, 0.45 * min(rate, SAMPLE_RATE), fs=rate)
            self.zi = np.zeros(RESAMPLE_TAPS - 1)
        self.delay = (RESAMPLE_TAPS - 1) / 2 if rate != SAMPLE_RATE else 0.0
        self.filtered = np.zeros(0)  # filtered input from index ``base`` on
        self.base = 0
        self.produced = 0  # output samples returned so far

    def push(self, x: np.ndarray) -> np.ndarray:
        if self.rate == SAMPLE_RATE:
            self.produced += len(x)
            return x
        from scipy.signal import lfilter

        y, self.zi = lfilter(self.taps, 1.0, x, zi=self.zi)
        self.filtered = np.concatenate([self.filtered, y])
        end = self.base + len(self.filtered)  # filtered samples 0 … end - 1 exist
        # output m sits at input position m · step + delay; it needs floor(position) + 1 < end
        last = math.floor((end - 2 - self.delay) / self.step)
        m = np.arange(self.produced, max(last + 1, self.produced))
        position = m * self.step + self.delay - self.base
        left = np.floor(position).astype(np.int64)
        u = position - left
        out = (1 - u) * self.filtered[left] + u * self.filtered[np.minimum(left + 1, len(self.filtered) - 1)]
        self.produced += len(m)
        keep = math.floor(self.produced * self.step + self.delay) - self.base  # next output's left sample
        if keep > 0:
            self.filtered, self.base = self.filtered[keep:], self.base + keep
        return out


def phone_decoder():
    """A pocketsphinx decoder of English phones (allphone search), 16 kHz; MissingExtraError without it."""
    try:
        from pocketsphinx import Decoder, get_model_path
    except ImportError as error:
        raise MissingExtraError(
            f"live lip sync recognises phones with pocketsphinx, in the optional extra [speech]: "
            f"{install_hint('speech')}; importing it failed: {error}"
        ) from error
    phone_lm = os.path.join(get_model_path(), "en-us", "en-us-phone.lm.bin")
    # dither (seeded, so runs repeat): digital silence, as in synthesized speech, stalls the search
    return Decoder(
        allphone=phone_lm,
        lm=None,
        samprate=SAMPLE_RATE,
        loglevel="FATAL",
        dither=True,
        seed=1,
        bestpath=False,
    )


class LiveLipSync:
    """Lip sync of a live voice (see the module docstring).

    Parameters
    ----------
    rig : Rig or sequence of Channel
        The channels (their order, rest values and ranges) of the frames.
    fps : float
        Frame rate of the frames returned.
    rate : int
        Sample rate of the audio pushed, Hz.
    visemes : VisemeMap or built-in name, optional
        An English (ARPAbet) map; default "en".
    lookahead_s : float
        How far past a frame the audio must reach before the frame is final, seconds (0 … 0.5;
        ``MAX_LOOKAHEAD_S`` by default).
    jaw, lips : float in [0, 2]
        The JALI-style dials of ``coarticulate``.
    """

    def __init__(
        self,
        rig: Rig | Sequence[Channel],
        *,
        fps: float = 30.0,
        rate: int = SAMPLE_RATE,
        visemes: VisemeMap | str | None = None,
        lookahead_s: float = MAX_LOOKAHEAD_S,
        jaw: float = 1.0,
        lips: float = 1.0,
    ) -> None:
        if not (isinstance(fps, int | float) and math.isfinite(fps) and fps > 0):
            raise SpeechError(f"fps must be a positive number; got {fps!r}")
        if not (isinstance(rate, int) and rate >= 8000):
            raise SpeechError(f"rate must be an integer sample rate of at least 8000 Hz; got {rate!r}")
        if not (math.isfinite(lookahead_s) and 0.0 <= lookahead_s <= 0.5):
            raise SpeechError(f"lookahead_s is {lookahead_s!r}; it must be in [0, 0.5] seconds")
        vmap = viseme_map("en") if visemes is None else visemes
        vmap = viseme_map(vmap) if isinstance(vmap, str) else vmap
        if vmap.language not in (None, "", "en"):
            raise SpeechError(
                f"live lip sync recognises English (ARPAbet) phones; viseme map {vmap.name!r} is for "
                f"{vmap.language!r}: pass an English map"
            )
        self.channels = tuple(rig.channels if isinstance(rig, Rig) else rig)
        self.vmap, self.fps, self.rate, self.lookahead_s = vmap, float(fps), rate, float(lookahead_s)
        self.jaw, self.lips = jaw, lips
        self.rest = np.array([c.default for c in self.channels])
        self._decoder = phone_decoder()
        self._reset()

    def _reset(self) -> None:
        self._resampler = _Resampler(self.rate)
        self._audio = np.zeros(0, np.int16)  # 16 kHz samples received but not yet fed
        self._fed = 0  # 16 kHz samples fed to the recogniser
        self._next = 0  # the next frame to make final
        self._started = False
        self.phones: tuple[Phone, ...] = ()
        """The latest partial phones (the one still heard last), on the audio's clock."""

    @property
    def heard_s(self) -> float:
        """Seconds of audio received since the stream (re)started."""
        return (self._fed + len(self._audio)) / SAMPLE_RATE

    # ---- input

    def _samples(self, samples) -> np.ndarray:
        x = np.asarray(samples)
        if x.ndim != 1:
            raise SpeechError(f"push takes mono samples (n,); got shape {x.shape}")
        if x.dtype == np.int16:
            return x.astype(np.float64) / 32768.0
        if not np.issubdtype(x.dtype, np.floating):
            raise SpeechError(f"push takes float samples in [-1, 1] or int16; got {x.dtype}")
        return x.astype(np.float64)

    def _feed(self, upto: int) -> None:
        """Feed the recogniser the 16 kHz samples up to index ``upto`` and read its phones so far."""
        if not self._started:
            self._decoder.start_utt()
            self._started = True
        n = upto - self._fed
        if n > 0:
            self._decoder.process_raw(self._audio[:n].tobytes(), False, False)
            self._audio, self._fed = self._audio[n:], upto
        self._read(self._decoder.seg())

    def _read(self, segments) -> None:
        phones = []
        for s in segments or ():  # None before the first frame is searched
            label = s.word if s.word in self.vmap.phones else SILENCE  # fillers (+NSN+ …) are pauses
            start_s, end_s = s.start_frame * FRAME_S, (s.end_frame + 1) * FRAME_S
            if end_s > start_s:
                phones.append(Phone(label, start_s, end_s))
        self.phones = tuple(phones)

    # ---- output

    def _frame(self, k: int) -> np.ndarray:
        """Frame k (c,) from ``self.phones``: the phones that can reach it, coarticulated."""
        t = k / self.fps
        near = [p for p in self.phones if p.end_s > t - HISTORY_S]
        if not near:
            return self.rest.copy()
        k0 = math.floor(near[0].start_s * self.fps + 1e-9)  # clip frame 0 is frame k0
        offset_s = k0 / self.fps
        last = near[-1]  # still in progress: it lasts at least until t
        near[-1] = Phone(last.label, last.start_s, max(last.end_s, t + 0.5 / self.fps))
        shifted = tuple(Phone(p.label, p.start_s - offset_s, p.end_s - offset_s) for p in near)
        clip = coarticulate(
            PhoneTimings(shifted, "en"),
            self.channels,
            self.fps,
            viseme_map=self.vmap,
            jaw=self.jaw,
            lips=self.lips,
        )
        return np.array(clip.values[min(k - k0, clip.n_frames - 1)])

    def push(self, samples) -> SpeechFrames:
        """Take the next chunk of audio (n,) (float in [-1, 1] or int16, mono, at ``rate``); return
        the frames it made final (none when the look-ahead is not yet heard)."""
        begin = time.perf_counter()
        x = self._resampler.push(self._samples(samples))
        pcm = np.clip(np.round(x * 32768.0), -32768, 32767).astype(np.int16)
        self._audio = np.concatenate([self._audio, pcm])
        heard = self._fed + len(self._audio)
        start, frames = self._next, []
        while True:
            upto = round((self._next / self.fps + self.lookahead_s) * SAMPLE_RATE)
            if upto > heard:
                break
            self._feed(upto)
            frames.append(self._frame(self._next))
            self._next += 1
        return self._result(start, frames, begin)

    def flush(self) -> SpeechFrames:
        """End the audio: the frames up to its end, from the recogniser's final phones. The next
        ``push`` starts a new stream at t = 0."""
        begin = time.perf_counter()
        start, frames = self._next, []
        if self.heard_s > 0:
            self._feed(self._fed + len(self._audio))
            self._decoder.end_utt()
            self._read(self._decoder.seg())
            self._started = False
            end = math.floor(self._fed / SAMPLE_RATE * self.fps + 1e-9)
            frames = [self._frame(k) for k in range(self._next, end + 1)]
        result = self._result(start, frames, begin)
        self._reset()
        return result

    def _result(self, start: int, frames: list[np.ndarray], begin: float) -> SpeechFrames:
        values = np.array(frames).reshape(len(frames), len(self.channels))
        return SpeechFrames(start, values, self.fps, time.perf_counter() - begin)


def live_lip_sync(
    rig: Rig,
    source: str | os.PathLike[str],
    *,
    chunk_s: float = 0.02,
    realtime: bool = False,
    **options,
) -> Iterator[tuple[SpeechFrames, float]]:
    """A WAV file played through ``LiveLipSync`` as a microphone would deliver it: chunks of
    ``chunk_s`` (paced in real time when ``realtime``), then the flush. Yields (the frames of each
    chunk, the audio's time at the chunk's end, seconds). ``options`` go to ``LiveLipSync``."""
    samples, rate = read_wav(source)
    stream = LiveLipSync(rig, rate=rate, **options)
    n = max(1, round(chunk_s * rate))
    begin = time.perf_counter()
    for i in range(0, len(samples), n):
        end = min(i + n, len(samples))
        if realtime:
            wait = end / rate - (time.perf_counter() - begin)
            if wait > 0:
                time.sleep(wait)
        yield stream.push(samples[i:end]), end / rate
    yield stream.flush(), len(samples) / rate
