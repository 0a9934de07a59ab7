"""Coarticulation: timed phones + a viseme map → a ``Clip`` of channel activations.

**Cohen–Massaro dominance** (Cohen & Massaro 1993; Massaro 1998). Each phone i has a target T_i
per channel (``visemes.phone_targets``) and, per articulator group g (``visemes.GROUPS``: lips,
jaw, tongue), a dominance that falls off with the time τ = t − c_i from the phone's centre c_i::

    D_ig(τ) = α_ig · exp(−θ_ig · |τ|^c),   θ_ig = s_ig^−c,  c = POWER

with its own scale s for τ < 0 (anticipatory: the phone's shape appears before it) and τ > 0
(carry-over), ``SCALE_S``. Each channel's value is the dominance-weighted mean of the targets::

    F(t) = Σ_i D_ig(t) T_i / Σ_i D_ig(t)

The magnitude follows the phone's deformability d_ig (``visemes.CLASSES``, per phone in the map):
α = ``ALPHA_RANGE`` ^ (1 − d), 1 for a fully deformable phone, 20 for a rigid one. So the lips of
P B M and F V win over their neighbours', while the lips of T D N take the rounding of a
neighbouring /u/ ("boot" against "beet"). Rounded phones (class "rounded") reach further ahead
with their lips: anticipatory scale ``ROUNDING_SCALE_S`` and window ``ROUNDING_WINDOW_S``.

**Influence window.** A phone influences the frames within ``WINDOW_S`` (0.3 s) of its centre
only; its dominance is tapered to reach 0 exactly there, ``(e(τ) − e(W)) / (1 − e(W))`` with
e = exp(−θ|τ|^c), so the curve has no step at the cut. 0.3 s spans 3-7 phones at ordinary
rates (Albrecht et al. limit the influence to 7 segments either side).

**Pauses** (``SILENCE`` phones, gaps between phones, the time before the first) are rest
segments of at most ``REST_PIECE_S`` each, with the rest pose as target and the "silence"
class's dominance scaled by the segment's share of ``REST_PIECE_S``, so the face relaxes to
neutral in a pause but hardly in a short gap between words. A small constant rest dominance
(``REST_FLOOR``) fills frames that no phone reaches.

**Speech rate** comes from the timings themselves: the dominance scales are in seconds (the
articulators' speed), so in fast speech the phones' dominances overlap more and short vowels
undershoot their targets, as they do in real speech (Pelachaud: deformability grows with rate).

**Closure guarantee** (Albrecht, Haber & Seidel 2002). At every bilabial and labiodental phone
the frame nearest its closure's centre takes the phone's lips and jaw targets exactly, so a 10 ms
/p/ at 24 fps still closes the lips on one frame. The closure's other frames are eased toward the
same targets by a raised cosine, 1 at that frame, so a closure is a short hold and not a
one-frame spike. The tongue keeps its blend.

**Closure phase.** An aligned stop spans its closure and then its release (the burst and the
aspiration before the vowel); the lips are shut only in the first part. The viseme map gives each
phone's closed share (``PhoneVisemes.closure``: English P 0.6, B 0.8, nasals and fricatives 1),
and the lips' and jaw's dominance and the guarantee are centred on that part, so the lips are shut
at the closure's midpoint, not after it (the built-in shares follow stop closure and voice-onset
times in read English: Crystal & House 1988, Lisker & Abramson 1964).

**JALI-style dials** (Edwards et al. 2016): ``jaw`` and ``lips`` (0..2) scale the jaw and the lip
channels around the rest pose, ``rest + k (F − rest)``; 0 keeps them at rest, 2 exaggerates.
Every channel is finally clipped into its range.

``linear_clip`` is the baseline of Radovan's experiment (3ds Max keys with linear
interpolation): the targets at the phones' centres joined by straight lines, no coarticulation.
``add_eye_motion`` adds stochastic blinks and small gaze saccades to any clip.
"""

from __future__ import annotations

import itertools
import logging
import math
import numbers
from collections.abc import Sequence
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np
import scipy.sparse as sp

from mimetic.errors import SpeechError
from mimetic.rig.activations import Clip, check_activations
from mimetic.rig.model import Channel, Rig
from mimetic.speech.phones import SILENCE, PhoneTimings
from mimetic.speech.visemes import GROUPS, VisemeMap, channel_group, phone_targets, viseme_map

log = logging.getLogger(__name__)

POWER = 1.5
"""Cohen–Massaro's exponent c: 1 gives a cusp at the centre, 2 a Gaussian; 1.5 holds a long
vowel's target near its centre yet lets short phones overlap."""
ALPHA_RANGE = 20.0
"""Dominance magnitude of a rigid phone (deformability 0) over a fully deformable one (1)."""
SCALE_S = MappingProxyType({"lips": (0.07, 0.06), "jaw": (0.06, 0.06), "tongue": (0.05, 0.05)})
"""(anticipatory, carry-over) dominance scale s per group, seconds: D falls to α/e at τ = ±s."""
ROUNDING_SCALE_S = 0.12
"""Anticipatory scale of the lips of rounded phones: rounding starts earlier than spreading."""
WINDOW_S = 0.3
"""A phone influences no frame farther than this from its centre (seconds)."""
ROUNDING_WINDOW_S = 0.45
"""The anticipatory window of the lips of rounded phones (seconds)."""
REST_PIECE_S = 0.15
"""Pauses are cut into rest segments of at most this length (seconds)."""
REST_FLOOR = 1e-3
"""Constant dominance of the rest pose, so frames beyond every window rest."""
CLOSURE_CLASSES = ("bilabial", "labiodental")
"""Classes whose lips and jaw targets are reached exactly on the frame nearest their centre."""
MAX_DIAL = 2.0
"""The largest ``jaw`` and ``lips`` dial."""


@dataclass(frozen=True)
class _Segments:
    """Phones and rest pieces in time order, p of them."""

    labels: tuple[str, ...]
    centres_s: np.ndarray  # (p, g) each group's centre: a closure phone's lips and jaw at its closure's
    durations_s: np.ndarray  # (p, g) the span around that centre
    targets: np.ndarray  # (p, c)
    alpha: np.ndarray  # (p, g) dominance magnitude per group
    scale_s: np.ndarray  # (2, p, g) anticipatory, carry-over scale
    window_s: np.ndarray  # (2, p, g) anticipatory, carry-over window
    closure: np.ndarray  # (p,) bool


def _channels(rig: Rig | Sequence[Channel]) -> tuple[Channel, ...]:
    return tuple(rig.channels if isinstance(rig, Rig) else rig)


def _check(timings: PhoneTimings, vmap: VisemeMap | str | None, fps: float) -> VisemeMap:
    if not isinstance(timings, PhoneTimings):
        raise TypeError(f"timings must be PhoneTimings; got {type(timings).__name__}")
    if not timings.phones:
        raise SpeechError("the timings hold no phones; there is nothing to animate")
    if not (isinstance(fps, numbers.Real) and math.isfinite(fps) and fps > 0):
        raise SpeechError(f"fps must be a positive number; got {fps!r}")
    vmap = viseme_map(timings.language) if vmap is None else vmap
    vmap = viseme_map(vmap) if isinstance(vmap, str) else vmap
    if vmap.language and vmap.language != timings.language:
        raise SpeechError(
            f"the timings are in {timings.language!r} but viseme map {vmap.name!r} is for "
            f"{vmap.language!r}; pass a map for {timings.language!r}"
        )
    return vmap


def _segments(timings: PhoneTimings, vmap: VisemeMap, channels: tuple[Channel, ...]) -> _Segments:
    """The timings' phones plus rest pieces covering every pause from t = 0 (pauses split at
    ``REST_PIECE_S``), with their targets and dominance parameters."""
    pieces: list[tuple[str, float, float]] = []  # (label, start_s, end_s)
    clock = 0.0
    for phone in timings.phones:
        pause_end_s = phone.end_s if phone.label == SILENCE else phone.start_s
        if pause_end_s - clock > 1e-6:
            edges = np.linspace(
                clock, pause_end_s, math.ceil((pause_end_s - clock) / REST_PIECE_S - 1e-9) + 1
            )
            pieces += [(SILENCE, a, b) for a, b in itertools.pairwise(edges)]
        if phone.label != SILENCE:
            pieces.append((phone.label, phone.start_s, phone.end_s))
        clock = max(clock, phone.end_s)
    labels = tuple(p[0] for p in pieces)
    entries = [vmap.phone(label) for label in labels]
    closes = np.array([e.kind in CLOSURE_CLASSES for e in entries], dtype=bool)
    start = np.array([a for _, a, _ in pieces])
    share = np.ones((len(pieces), len(GROUPS)))  # of the phone, from its start: each group's span
    share[:, [GROUPS.index("lips"), GROUPS.index("jaw")]] = np.where(
        closes, [e.closure for e in entries], 1.0
    )[:, None]
    durations_s = np.array([b - a for _, a, b in pieces])[:, None] * share
    centres = start[:, None] + durations_s / 2
    deform = np.array([[e.deformability[g] for g in GROUPS] for e in entries]).reshape(-1, len(GROUPS))
    alpha = ALPHA_RANGE ** (1.0 - deform)  # (p, g)
    silent = np.array([label == SILENCE for label in labels], dtype=bool)
    alpha[silent] *= np.minimum(durations_s[silent] / REST_PIECE_S, 1.0)  # short gaps rest little
    scale = np.array([[SCALE_S[g] for g in GROUPS]], dtype=np.float64).transpose(2, 0, 1)  # (2, 1, g)
    scale = np.repeat(scale, len(pieces), axis=1)  # (2, p, g)
    window = np.full_like(scale, WINDOW_S)
    rounded = np.array([e.kind == "rounded" for e in entries], dtype=bool)
    lips = GROUPS.index("lips")
    scale[0, rounded, lips] = ROUNDING_SCALE_S
    window[0, rounded, lips] = ROUNDING_WINDOW_S
    return _Segments(
        labels,
        centres,
        durations_s,
        phone_targets(vmap, labels, channels),
        alpha,
        scale,
        window,
        closes,
    )


def _n_frames(timings: PhoneTimings, fps: float) -> int:
    return math.floor(timings.end_s * fps + 1e-9) + 1


def _dominance(seg: _Segments, group: int, fps: float, n_frames: int) -> sp.csr_matrix:
    """Dominance (f, p) of every segment on group ``group`` at frame times k / fps, sparse: each
    segment reaches only the frames within its windows."""
    before, after = seg.window_s[0, :, group], seg.window_s[1, :, group]  # (p,)
    centres = seg.centres_s[:, group]
    first = np.clip(np.ceil((centres - before) * fps), 0, n_frames - 1).astype(np.int64)
    last = np.clip(np.floor((centres + after) * fps), -1, n_frames - 1).astype(np.int64)
    span = int(max(1, (last - first).max() + 1))
    frames = first[:, None] + np.arange(span)  # (p, k)
    valid = frames <= last[:, None]
    tau = frames / fps - centres[:, None]  # (p, k) seconds from the centre
    ahead = tau < 0
    s = np.where(ahead, seg.scale_s[0, :, group, None], seg.scale_s[1, :, group, None])
    w = np.where(ahead, before[:, None], after[:, None])
    edge = np.exp(-((w / s) ** POWER))
    d = (np.exp(-((np.abs(tau) / s) ** POWER)) - edge) / (1.0 - edge)
    d = seg.alpha[:, group, None] * np.clip(d, 0.0, None)  # (p, k)
    rows = np.broadcast_to(np.arange(len(seg.labels))[:, None], frames.shape)
    return sp.csr_matrix((d[valid], (frames[valid], rows[valid])), shape=(n_frames, len(seg.labels)))


def _close(values: np.ndarray, seg: _Segments, held: np.ndarray, fps: float) -> None:
    """The closure guarantee, in place on ``values`` (f, c): each closure phone's frames eased toward
    its targets on the ``held`` columns (raised cosine, 1 at the frame nearest its centre), then
    those peak frames set to the targets exactly (so a neighbour's easing cannot undo them)."""
    n = len(values)
    closures = np.flatnonzero(seg.closure)
    lips = GROUPS.index("lips")
    peaks = np.minimum(np.round(seg.centres_s[closures, lips] * fps).astype(np.int64), n - 1)
    for i, k in zip(closures, peaks, strict=True):
        h = round(seg.durations_s[i, lips] * fps / 2)  # frames from the peak to the closure's edges
        frames = np.arange(max(k - h, 0), min(k + h, n - 1) + 1)
        w = np.cos(0.5 * np.pi * (frames - k) / (h + 1))[:, None] ** 2  # 1 at k, 0 beyond h
        block = np.ix_(frames, held)
        values[block] += w * (seg.targets[i, held] - values[block])
    values[np.ix_(peaks, held)] = seg.targets[np.ix_(closures, held)]


def _dials(values: np.ndarray, channels: tuple[Channel, ...], jaw: float, lips: float) -> np.ndarray:
    rest = np.array([c.default for c in channels])
    gain = np.array([{"jaw": jaw, "lips": lips}.get(channel_group(c.name), 1.0) for c in channels])
    return rest + gain * (values - rest)


def coarticulate(
    timings: PhoneTimings,
    rig: Rig | Sequence[Channel],
    fps: float = 60.0,
    *,
    viseme_map: VisemeMap | str | None = None,
    jaw: float = 1.0,
    lips: float = 1.0,
) -> Clip:
    """Activations of timed phones, coarticulated by Cohen–Massaro dominance (module docstring).

    Parameters
    ----------
    timings : PhoneTimings
        The phones; the clip's frame k is at k / fps seconds of the timings' clock.
    rig : Rig or sequence of Channel
        Channel order, rest values and ranges (c channels).
    fps : float
        Frame rate of the clip.
    viseme_map : VisemeMap or built-in name, optional
        Default: the built-in map of ``timings.language``.
    jaw, lips : float in [0, 2]
        JALI-style dials: the jaw's and the lips' excursion from rest (1 as mapped).

    Returns
    -------
    clip : Clip, values (floor(end_s · fps) + 1, c) float64, every channel within its range.
    """
    vmap = _check(timings, viseme_map, fps)
    for name, dial in (("jaw", jaw), ("lips", lips)):
        if not (isinstance(dial, numbers.Real) and 0.0 <= dial <= MAX_DIAL):
            raise SpeechError(f"the {name} dial is {dial!r}; it must be a number in [0, {MAX_DIAL:g}]")
    channels = _channels(rig)
    seg = _segments(timings, vmap, channels)
    n = _n_frames(timings, fps)
    rest = np.array([c.default for c in channels])
    group_of = np.array([GROUPS.index(channel_group(c.name)) for c in channels])
    values = np.empty((n, len(channels)))
    for g in range(len(GROUPS)):
        cols = np.flatnonzero(group_of == g)
        d = _dominance(seg, g, fps, n)
        weight = np.asarray(d.sum(axis=1)).ravel() + REST_FLOOR  # (f,)
        values[:, cols] = (d @ seg.targets[:, cols] + REST_FLOOR * rest[cols]) / weight[:, None]
    _close(values, seg, np.flatnonzero(group_of != GROUPS.index("tongue")), fps)
    log.debug("coarticulated %d segments over %d frames at %g fps", len(seg.labels), n, fps)
    return Clip(
        tuple(c.name for c in channels),
        check_activations(channels, _dials(values, channels, jaw, lips), clip=True),
        fps,
    )


def linear_clip(
    timings: PhoneTimings,
    rig: Rig | Sequence[Channel],
    fps: float = 60.0,
    *,
    viseme_map: VisemeMap | str | None = None,
) -> Clip:
    """The baseline: each phone's (and rest piece's) target keyed at its centre, straight lines
    between keys, held before the first and after the last. Same arguments and shape as
    ``coarticulate``; no dominance, closure guarantee or dials."""
    vmap = _check(timings, viseme_map, fps)
    channels = _channels(rig)
    seg = _segments(timings, vmap, channels)
    t = np.arange(_n_frames(timings, fps)) / fps  # (f,)
    # the first and last targets once more, 1 s beyond the clip at either end: held there
    centres = seg.centres_s[:, GROUPS.index("tongue")]  # the phones' own centres
    keys_s = np.concatenate([[-1.0], centres, [max(t[-1], centres[-1]) + 1.0]])
    keys = np.concatenate([seg.targets[:1], seg.targets, seg.targets[-1:]])
    right = np.searchsorted(keys_s, t, side="right")  # keys_s[right - 1] <= t < keys_s[right]
    u = ((t - keys_s[right - 1]) / (keys_s[right] - keys_s[right - 1]))[:, None]
    values = (1 - u) * keys[right - 1] + u * keys[right]
    return Clip(tuple(c.name for c in channels), check_activations(channels, values, clip=True), fps)


# ---- eyes


BLINK_S = (0.10, 0.15)
"""A blink lasts between these (seconds, uniform)."""
BLINK_CLOSING = 0.35
"""Share of a blink spent closing: the lid drops fast and rises slower."""
BLINK_GAP_S = 0.5
"""The shortest time between two blinks' starts (seconds)."""
SACCADE_S = 0.04
"""A saccade's duration (seconds): the eyes jump to a new fixation and hold it."""
SACCADE_GAP_S = 0.25
"""The shortest fixation between two saccades (seconds)."""
EYE_CHANNELS = ("eyelid_upper_L", "eyelid_upper_R", "gaze_yaw", "gaze_pitch")


def _onsets_s(rng: np.random.Generator, per_min: float, gap_s: float, duration_s: float) -> np.ndarray:
    """Event times in [0, duration_s): gaps of ``gap_s`` plus an exponential wait, ``per_min`` a minute
    on average (``gap_s`` < 60 / ``per_min``)."""
    if per_min <= 0:
        return np.zeros(0)
    mean_s = 60.0 / per_min
    wait_s = max(mean_s - gap_s, 1e-3)
    n = math.ceil(duration_s / mean_s * 2) + 10
    times = rng.uniform(0, mean_s) + np.cumsum(gap_s + rng.exponential(wait_s, n)) - gap_s
    return times[times < duration_s]


def add_eye_motion(
    clip: Clip,
    rig: Rig | Sequence[Channel],
    *,
    seed: int | np.random.Generator = 0,
    blinks_per_min: float = 15.0,
    saccades_per_min: float = 30.0,
    saccade_rad: float = 0.05,
) -> Clip:
    """The clip with stochastic blinks and small gaze saccades added (a seeded, repeatable layer).

    Blinks come about ``blinks_per_min`` a minute (at least ``BLINK_GAP_S`` apart, else
    exponentially spaced), each ``BLINK_S`` long: both upper lids close to the channel's maximum
    (closed) and reopen. Saccades come ``saccades_per_min`` a minute: the gaze jumps within
    ``SACCADE_S`` to a new fixation, yaw and pitch uniform in ±``saccade_rad`` (pitch half that)
    around the clip's own gaze, and holds it. Values add to the clip's, then are clipped.

    Parameters
    ----------
    clip : Clip
        Must have the channels ``EYE_CHANNELS``; ``rig`` gives their ranges.
    seed : int or numpy Generator
        The same seed gives the same motion.

    Returns
    -------
    clip : Clip, same channels, frames and fps.
    """
    for name, per_min, gap_s in (
        ("blinks_per_min", blinks_per_min, BLINK_GAP_S),
        ("saccades_per_min", saccades_per_min, SACCADE_GAP_S),
    ):
        if not (math.isfinite(per_min) and 0 <= per_min < 60.0 / gap_s):
            raise SpeechError(f"{name} is {per_min!r}; it must be in [0, {60.0 / gap_s:g})")
    if not (math.isfinite(saccade_rad) and saccade_rad >= 0):
        raise SpeechError(f"saccade_rad is {saccade_rad!r}; it must be ≥ 0")
    ranges = {c.name: c for c in _channels(rig)}
    missing = [c for c in EYE_CHANNELS if c not in clip.channels or c not in ranges]
    if missing:
        raise SpeechError(
            f"the clip or the rig has no channel(s) {', '.join(missing)}; eye motion needs "
            f"{', '.join(EYE_CHANNELS)}"
        )
    rng = np.random.default_rng(seed)
    t = np.arange(clip.n_frames) / clip.fps  # (f,)
    values = np.array(clip.values)
    col = {name: clip.channels.index(name) for name in EYE_CHANNELS}

    # events never overlap (the gaps exceed their durations): each frame is in the latest one's
    # course or after it; a start at -inf stands for "none yet"
    start_s = np.concatenate([[-np.inf], _onsets_s(rng, blinks_per_min, BLINK_GAP_S, clip.duration_s)])
    length_s = np.concatenate([[1.0], rng.uniform(*BLINK_S, len(start_s) - 1)])
    j = np.searchsorted(start_s, t, side="right") - 1  # (f,) the latest blink
    u = (t - start_s[j]) / length_s[j]  # 0..1 during the blink
    closing = np.sin(0.5 * np.pi * np.clip(u / BLINK_CLOSING, 0, 1)) ** 2
    opening = np.cos(0.5 * np.pi * np.clip((u - BLINK_CLOSING) / (1 - BLINK_CLOSING), 0, 1)) ** 2
    lid = np.where(u < BLINK_CLOSING, closing, opening) * (u <= 1)  # (f,)
    for name in EYE_CHANNELS[:2]:
        values[:, col[name]] += lid * (ranges[name].maximum - ranges[name].default)

    start_s = np.concatenate([[-np.inf], _onsets_s(rng, saccades_per_min, SACCADE_GAP_S, clip.duration_s)])
    fixations = rng.uniform(-1, 1, (len(start_s), 2)) * saccade_rad * np.array([1.0, 0.5])  # (s, 2)
    fixations[0] = 0.0  # before the first saccade: the clip's own gaze
    j = np.searchsorted(start_s, t, side="right") - 1  # (f,) the latest saccade
    x = np.clip((t - start_s[j]) / SACCADE_S, 0, 1)[:, None]
    step = x * x * (3 - 2 * x)  # smoothstep from the previous fixation to this one
    previous = fixations[np.maximum(j - 1, 0)]
    values[:, [col["gaze_yaw"], col["gaze_pitch"]]] += previous + step * (fixations[j] - previous)
    for name in EYE_CHANNELS:
        c = ranges[name]
        values[:, col[name]] = np.clip(values[:, col[name]], c.minimum, c.maximum)
    return Clip(clip.channels, values, clip.fps)
