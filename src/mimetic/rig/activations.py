"""The activation pivot: named channel values for one pose or a clip of frames.

Every driver (expressions, keyframes, speech, capture) produces activations and every engine
consumes them. A pose is a (c,) float64 vector in the rig's channel order; a clip is
(frames, c) at a frame rate. Muscle channels are in [0, 1]; jaw, eyelid, gaze and head
channels are in radians or fractions of the head height (see ``Channel.unit``).
"""

from __future__ import annotations

import difflib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from mimetic.errors import ActivationError
from mimetic.rig.model import Channel, Rig


def _channels(source: Rig | Sequence[Channel]) -> tuple[Channel, ...]:
    return tuple(source.channels) if isinstance(source, Rig) else tuple(source)


def _unknown(name: str, names: Sequence[str]) -> ActivationError:
    close = difflib.get_close_matches(name, names, n=3)
    hint = f"; did you mean {', '.join(close)}?" if close else f"; channels are {', '.join(names[:6])}, …"
    return ActivationError(f"unknown channel {name!r}{hint}")


def pose(
    source: Rig | Sequence[Channel], values: Mapping[str, float] | None = None, *, clip: bool = False
) -> np.ndarray:
    """A pose vector (c,) float64: channel defaults, with the named ``values`` set.

    Raises ``ActivationError`` for an unknown channel name, a non-finite value, or a value
    outside the channel's range (unless ``clip`` is True, which clips it into range).
    """
    channels = _channels(source)
    names = [c.name for c in channels]
    index = {n: i for i, n in enumerate(names)}
    out = np.array([c.default for c in channels], dtype=np.float64)
    for name, value in (values or {}).items():
        if name not in index:
            raise _unknown(name, names)
        out[index[name]] = float(value)
    return check_activations(channels, out, clip=clip)


def check_shape(
    names: Sequence[str], activations: object, *, ndim: int | None = None, owner: str = "rig"
) -> np.ndarray:
    """Activations as float64 (c,) or (f, c) for channels ``names``; ``ActivationError`` names what is wrong.

    ``ndim`` (1 or 2) demands one frame or a batch; None accepts either. ``owner`` ("rig" or
    "basis") is what the message says the channels belong to.
    """
    try:
        a = np.asarray(activations, dtype=np.float64)
    except (TypeError, ValueError) as error:
        raise ActivationError(f"activations cannot be read as float64 numbers: {error}") from None
    c = len(names)
    if a.ndim not in ((1, 2) if ndim is None else (ndim,)):
        wanted = {1: f"({c},)", 2: f"(frames, {c})", None: f"({c},) or (frames, {c})"}[ndim]
        raise ActivationError(f"activations must have shape {wanted}; got {a.shape}")
    if a.shape[-1] != c:
        wanted = {1: f"({c},)", 2: f"(frames, {c})", None: f"({c},) or (frames, {c})"}[ndim]
        attribute = "channels" if owner == "basis" else "channel_names"
        raise ActivationError(
            f"activations must have shape {wanted}: got {a.shape[-1]} channels; this {owner} has {c} "
            f"({', '.join(names[:3])}, …). "
            f"Reorder with clip.select({owner}.{attribute})."
        )
    if not np.isfinite(a).all():
        bad = np.argwhere(~np.isfinite(a))[0]
        frame = f" in frame {bad[0]}" if a.ndim == 2 else ""
        raise ActivationError(
            f"activation of channel {names[bad[-1]]!r}{frame} is not finite ({a[tuple(bad)]}); "
            "fill or drop the missing values first"
        )
    return a


def check_activations(
    source: Rig | Sequence[Channel], values: np.ndarray, *, clip: bool = False
) -> np.ndarray:
    """Validate activations (c,) or (f, c) against the channels and their ranges; returns float64.

    Shape and finiteness as ``check_shape``; values outside a channel's range raise, or are clipped
    into it when ``clip`` is True.
    """
    channels = _channels(source)
    a = check_shape([c.name for c in channels], values)
    lo = np.array([c.minimum for c in channels])
    hi = np.array([c.maximum for c in channels])
    if clip:
        return np.clip(a, lo, hi)
    outside = (a < lo - 1e-9) | (a > hi + 1e-9)
    if outside.any():
        j = int(np.argwhere(outside)[0][-1])
        c = channels[j]
        value = a[..., j].ravel()[np.argmax(outside[..., j].ravel())]
        raise ActivationError(
            f"channel {c.name!r} = {value:.4g} is outside its range [{c.minimum:g}, {c.maximum:g}] {c.unit}; "
            "clip it or change the channel's range"
        )
    return a


@dataclass(frozen=True, eq=False)
class Clip:
    """Activations over time: ``values`` (frames, c) float64 for ``channels`` at ``fps``."""

    channels: tuple[str, ...]
    values: np.ndarray
    fps: float

    def __post_init__(self) -> None:
        values = np.array(self.values, dtype=np.float64, ndmin=2)
        if values.ndim != 2 or values.shape[1] != len(self.channels):
            raise ActivationError(f"clip values must be (frames, {len(self.channels)}); got {values.shape}")
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise ActivationError(f"clip fps must be positive; got {self.fps}")
        values.setflags(write=False)
        object.__setattr__(self, "channels", tuple(self.channels))
        object.__setattr__(self, "values", values)

    @property
    def n_frames(self) -> int:
        return len(self.values)

    @property
    def duration_s(self) -> float:
        return self.n_frames / self.fps

    def select(self, channels: Sequence[str], defaults: Mapping[str, float] | None = None) -> Clip:
        """The clip with columns in the order of ``channels``; missing ones take ``defaults`` (or 0)."""
        index = {n: i for i, n in enumerate(self.channels)}
        defaults = defaults or {}
        out = np.empty((self.n_frames, len(channels)))
        for j, name in enumerate(channels):
            out[:, j] = self.values[:, index[name]] if name in index else defaults.get(name, 0.0)
        return Clip(tuple(channels), out, self.fps)
