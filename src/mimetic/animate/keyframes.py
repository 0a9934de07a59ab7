"""Keyframe clips: layers of per-channel curves, edits that keep the detail under them, and the
builders that make clips from poses, expressions and baked clips.

A ``KeyframeClip`` is the editable form of an animation; ``KeyframeClip.sample(fps)`` bakes it
into the activation pivot (``mimetic.rig.activations.Clip``, (frames, c) float64). Times are in
seconds everywhere, so one clip samples at any frame rate (24, 30, 59.94 fps …).

Layers
------
A clip holds ``layers`` applied in order to every channel, starting from 0:

- "absolute": ``value = (1 - weight) * value + weight * curve(t)``;
- "additive": ``value = value + weight * curve(t)``.

A layer changes only the channels it has curves for. ``layers[0]`` is the *base* and is absolute;
``with_base`` swaps it (e.g. after the base is regenerated from speech or re-solved from capture)
and keeps every other layer.

Edits (``KeyframeClip.edit``) add a smooth B-spline displacement in an additive layer
(``mimetic.animate.curves``). Files: ``mimetic.animate.clipfiles``.
"""

from __future__ import annotations

import difflib
import logging
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, replace
from types import MappingProxyType
from typing import Any, Literal, get_args

import numpy as np

from mimetic.animate.curves import (
    DEFAULT_KNOT_SPACING_S,
    BSplineEdit,
    ClipError,
    Curve,
    Interpolation,
    _fmt,
    _number,
    _positive,
    _times,
    _unknown_channel,
    fit_displacement,
)
from mimetic.animate.expressions import Expression, ExpressionLibrary, compose_pose
from mimetic.rig.activations import Clip, check_shape
from mimetic.rig.model import Channel, Rig

log = logging.getLogger(__name__)

LayerMode = Literal["absolute", "additive"]
LAYER_MODES: tuple[str, ...] = get_args(LayerMode)

# --------------------------------------------------------------------------- layers and clips


@dataclass(frozen=True)
class Layer:
    """A named set of curves applied on top of the layers before it (see the module docstring).

    Attributes
    ----------
    name : str
        Unique within a clip, e.g. "base", "edit".
    curves : Mapping[str, Curve | BSplineEdit]
        Channel name → curve (keyframes) or displacement (edit layers).
    mode : "absolute" | "additive"
        Absolute layers blend toward their curves by ``weight``; additive layers add
        ``weight * curve``.
    weight : float
        Finite; 1 applies the layer fully, 0 mutes it.
    """

    name: str
    curves: Mapping[str, Curve | BSplineEdit]
    mode: LayerMode = "absolute"
    weight: float = 1.0

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ClipError(f"layer name {self.name!r} must be a non-empty string")
        if self.mode not in LAYER_MODES:
            raise ClipError(f"layer {self.name!r}: unknown mode {self.mode!r}; use 'absolute' or 'additive'")
        object.__setattr__(self, "weight", _number(self.weight, f"layer {self.name!r}: weight"))
        if not isinstance(self.curves, Mapping):
            raise TypeError(f"layer {self.name!r}: curves must be a mapping channel → Curve")
        for channel, curve in self.curves.items():
            if not isinstance(channel, str) or not channel:
                raise ClipError(f"layer {self.name!r}: channel name {channel!r} must be a non-empty string")
            if not isinstance(curve, (Curve, BSplineEdit)):
                raise TypeError(
                    f"layer {self.name!r}: curve of {channel!r} is a {type(curve).__name__}; "
                    "use a Curve or a BSplineEdit"
                )
        object.__setattr__(self, "curves", MappingProxyType(dict(self.curves)))


@dataclass(frozen=True)
class KeyframeClip:
    """An editable animation: layers of per-channel curves over ``duration_s`` seconds.

    Attributes
    ----------
    channels : tuple of str
        The channels the clip animates, in output order. Every curve's channel is one of them; a
        channel with no curve stays 0.
    layers : tuple of Layer
        Applied in order; ``layers[0]`` is the base and must be absolute.
    duration_s : float or None
        Length in seconds (>= 0); None takes the time of the last key of any layer (at least 0).
    """

    channels: tuple[str, ...]
    layers: tuple[Layer, ...]
    duration_s: float | None = None

    def __post_init__(self) -> None:
        if isinstance(self.channels, str):
            raise TypeError("channels must be a sequence of names, not one string")
        channels = tuple(self.channels)
        seen: set[str] = set()
        for name in channels:
            if not isinstance(name, str) or not name:
                raise ClipError(f"channel name {name!r} must be a non-empty string")
            if name in seen:
                raise ClipError(f"channel {name!r} appears twice in the clip's channels; list it once")
            seen.add(name)
        layers = tuple(self.layers)
        if not layers:
            raise ClipError("a clip needs at least one layer (the base)")
        for layer in layers:
            if not isinstance(layer, Layer):
                raise TypeError(f"clip layers must be Layer objects; got {type(layer).__name__}")
        names = [layer.name for layer in layers]
        for layer in layers:
            if names.count(layer.name) > 1:
                raise ClipError(f"two layers are named {layer.name!r}; give each layer its own name")
            for channel in layer.curves:
                if channel not in seen:
                    error = _unknown_channel(channel, channels, "the clip")
                    raise ClipError(f"layer {layer.name!r}: {error} Add it to the clip's channels.")
        if layers[0].mode != "absolute":
            raise ClipError(
                f"layers[0] ({layers[0].name!r}) is the base and must be 'absolute'; "
                "put an absolute layer first"
            )
        if self.duration_s is None:
            ends = [
                c.keys[-1].time_s for layer in layers for c in layer.curves.values() if isinstance(c, Curve)
            ]
            duration = max([0.0, *ends])
        else:
            duration = _number(self.duration_s, "clip duration_s")
            if duration < 0:
                raise ClipError(f"clip duration_s={duration:g} must be >= 0")
        object.__setattr__(self, "channels", channels)
        object.__setattr__(self, "layers", layers)
        object.__setattr__(self, "duration_s", duration)

    @property
    def base(self) -> Layer:
        """The first layer, which ``with_base`` replaces."""
        return self.layers[0]

    def layer(self, name: str) -> Layer:
        """The layer called ``name``."""
        for layer in self.layers:
            if layer.name == name:
                return layer
        raise ClipError(f"no layer {name!r}; the clip has {', '.join(x.name for x in self.layers)}")

    def channel_values(self, channel: str, times_s: Any) -> np.ndarray:
        """Composed value of one channel at ``times_s`` (any shape, seconds), all layers, unclipped."""
        if channel not in self.channels:
            raise _unknown_channel(channel, self.channels, "the clip")
        t = _times(times_s)
        value = np.zeros(t.shape)
        for layer in self.layers:
            curve = layer.curves.get(channel)
            if curve is None:
                continue
            v = curve.evaluate(t)
            if layer.mode == "additive":
                value = value + layer.weight * v
            else:
                value = (1.0 - layer.weight) * value + layer.weight * v
        return value

    def evaluate(self, times_s: Any) -> np.ndarray:
        """Composed values (t, c) float64 at times (t,) seconds, columns in ``channels`` order, unclipped."""
        t = _times(times_s).ravel()
        out = np.zeros((len(t), len(self.channels)))
        for j, channel in enumerate(self.channels):
            out[:, j] = self.channel_values(channel, t)
        return out

    def frame_times(self, fps: float) -> np.ndarray:
        """Frame times (frames,) float64 in seconds: ``i / fps`` for ``0 <= i / fps <= duration_s``."""
        fps = _positive(fps, "fps")
        n = math.floor(self.duration_s * fps + 1e-9) + 1
        return np.arange(n) / fps

    def sample(
        self,
        fps: float,
        *,
        channels: Rig | Sequence[Channel] | Sequence[str] | None = None,
        defaults: Mapping[str, float] | None = None,
    ) -> Clip:
        """Bake the clip into the activation pivot at ``fps``.

        Frames are at ``i / fps`` for ``0 <= i / fps <= duration_s``: a 2 s clip at 24 fps has 49
        frames, the last at exactly 2 s. Times never accumulate, so any two frame rates agree at the
        times they share.

        Parameters
        ----------
        fps : float
            Frames per second, > 0 (e.g. 24, 30, 60000 / 1001).
        channels : Rig, sequence of Channel, sequence of str, or None
            None: the clip's channels, values as composed. Names: those columns in that order;
            names the clip lacks take ``defaults`` (or 0); clip channels not named are dropped.
            A rig or Channel objects: the rig's channel order; channels the clip lacks take their
            ``default``; every value is clipped into its channel's [minimum, maximum]; a clip
            channel the rig does not have raises ``ClipError``.
        defaults : Mapping[str, float] or None
            Values for requested names the clip lacks (names only; overrides ``Channel.default``).

        Returns
        -------
        Clip with values (frames, len(channels)) float64.
        """
        times = self.frame_times(fps)
        values = self.evaluate(times)  # (frames, c)
        if channels is None:
            return Clip(self.channels, values, float(fps))
        if isinstance(channels, Rig):
            channels = channels.channels
        if isinstance(channels, str):
            raise TypeError("channels must be a sequence of names or Channel objects, not one string")
        channels = tuple(channels)
        defaults = dict(defaults or {})
        index = {name: j for j, name in enumerate(self.channels)}
        if all(isinstance(c, Channel) for c in channels):
            names = tuple(c.name for c in channels)
            for name in self.channels:
                if name not in names:
                    close = difflib.get_close_matches(name, names, n=3)
                    hint = f" (did you mean {', '.join(close)}?)" if close else ""
                    raise ClipError(
                        f"clip channel {name!r} is not a channel of the rig{hint}; rename it or drop it "
                        "from the clip, or sample with channel names instead of the rig"
                    )
            lo = np.array([c.minimum for c in channels])
            hi = np.array([c.maximum for c in channels])
            fill = [defaults.get(c.name, c.default) for c in channels]
        elif all(isinstance(c, str) for c in channels):
            names, lo, hi = channels, None, None
            fill = [defaults.get(name, 0.0) for name in names]
        else:
            raise TypeError("channels must be all names or all Channel objects")
        out = np.empty((len(times), len(names)))
        for j, name in enumerate(names):
            out[:, j] = values[:, index[name]] if name in index else _number(fill[j], f"default of {name!r}")
        if lo is not None:
            clipped = np.clip(out, lo, hi)
            log.debug(
                "sample: clipped %d of %d values into channel ranges", int((clipped != out).sum()), out.size
            )
            out = clipped
        return Clip(names, out, float(fps))

    def edit(
        self,
        channel: str,
        constraints: Mapping[float, float] | Iterable[tuple[float, float]],
        *,
        knot_spacing_s: float = DEFAULT_KNOT_SPACING_S,
        layer: str = "edit",
        regularization: float = 0.0,
    ) -> KeyframeClip:
        """A new clip whose ``channel`` passes through ``constraints`` ({time_s: value}).

        The change is a B-spline displacement (``fit_displacement``) stored in the additive layer
        ``layer``: created at the end if missing, otherwise added to the displacement it already
        holds for ``channel`` (same ``knot_spacing_s`` required). Every other layer is unchanged.
        Each edit is fitted to the curve as it is now, earlier edits included; where the new edit
        reaches an earlier constraint it moves it, so repeat earlier constraints to keep them.

        Parameters
        ----------
        channel : str
            One of ``channels``.
        constraints : Mapping[float, float] or iterable of (time_s, value)
            Wanted values at distinct times, in the channel's unit.
        knot_spacing_s : float
            Knot spacing h > 0, seconds: each constraint changes the curve only within 3–4 h of it.
        layer : str
            Name of the edit layer (additive, with a weight that does not mute it).
        regularization : float
            See ``fit_displacement``.
        """
        if channel not in self.channels:
            raise _unknown_channel(channel, self.channels, "the clip")
        pairs = list(constraints.items() if isinstance(constraints, Mapping) else constraints)
        if not pairs:
            raise ClipError(f"edit of {channel!r} has no constraints; give {{time_s: value}}")
        times = np.array([_number(t, f"edit of {channel!r}: constraint time") for t, _ in pairs])
        wanted = np.array([_number(v, f"edit of {channel!r}: value at t={_fmt(t)} s") for t, v in pairs])
        position = next((i for i, x in enumerate(self.layers) if x.name == layer), None)
        if position is None:
            target = Layer(layer, {}, "additive", 1.0)
            layers = (*self.layers, target)
            position = len(layers) - 1
        else:
            target = self.layers[position]
            layers = self.layers
            if target.mode != "additive":
                raise ClipError(
                    f"layer {layer!r} is absolute; edits go in an additive layer, e.g. layer='edit'"
                )
        # the final value moves by gain * d: the edit layer's weight, times (1 - w) of later absolute layers
        gain = target.weight
        for later in layers[position + 1 :]:
            if later.mode == "absolute" and channel in later.curves:
                gain *= 1.0 - later.weight
        if gain == 0.0:
            raise ClipError(
                f"layer {layer!r} cannot change {channel!r}: its weight is 0 or a later absolute layer "
                "overrides it; edit in another layer or change the weights"
            )
        current = self.channel_values(channel, times)
        displacement = fit_displacement(
            times, (wanted - current) / gain, knot_spacing_s, regularization=regularization
        )
        existing = target.curves.get(channel)
        if isinstance(existing, Curve):
            raise ClipError(
                f"layer {layer!r} holds keyframes for {channel!r}; "
                "put the edit in another layer (e.g. layer='edit')"
            )
        if existing is not None:
            displacement = existing + displacement
        curves = {**target.curves, channel: displacement}
        new_layers = list(layers)
        new_layers[position] = replace(target, curves=curves)
        log.info("edited %r in layer %r with %d constraints", channel, layer, len(pairs))
        return replace(self, layers=tuple(new_layers))

    def with_base(self, base: Layer, *, duration_s: float | None = None) -> KeyframeClip:
        """This clip with ``base`` in place of ``layers[0]``; every other layer (the edits) is kept.

        Channels of ``base`` the clip lacks are appended to ``channels``. ``duration_s`` None keeps
        the current duration.
        """
        extra = tuple(c for c in base.curves if c not in self.channels)
        return KeyframeClip(
            (*self.channels, *extra),
            (base, *self.layers[1:]),
            self.duration_s if duration_s is None else duration_s,
        )

    def with_layer(self, layer: Layer) -> KeyframeClip:
        """This clip with ``layer`` replacing the layer of the same name, or appended if there is none."""
        layers = list(self.layers)
        names = [x.name for x in layers]
        if layer.name in names:
            layers[names.index(layer.name)] = layer
        else:
            layers.append(layer)
        return replace(self, layers=tuple(layers))


# --------------------------------------------------------------------------- building clips


def _channel_source(
    channels: Rig | Sequence[Channel] | Sequence[str],
) -> tuple[tuple[str, ...], np.ndarray]:
    """(names, defaults (c,)) from a rig, Channel objects or plain names (default 0)."""
    if isinstance(channels, Rig):
        channels = channels.channels
    if isinstance(channels, str):
        raise TypeError("channels must be a sequence of names or Channel objects, not one string")
    channels = tuple(channels)
    if all(isinstance(c, Channel) for c in channels):
        return tuple(c.name for c in channels), np.array([c.default for c in channels], dtype=np.float64)
    if all(isinstance(c, str) for c in channels):
        return channels, np.zeros(len(channels))
    raise TypeError("channels must be a Rig, or all names, or all Channel objects")


def from_poses(
    poses: Sequence[tuple[float, Any]],
    channels: Rig | Sequence[Channel] | Sequence[str],
    *,
    interpolation: Interpolation = "cubic",
    name: str = "base",
    duration_s: float | None = None,
) -> KeyframeClip:
    """A clip that passes through whole poses at given times: one key per pose in every channel.

    Parameters
    ----------
    poses : sequence of (time_s, pose)
        Strictly increasing times in seconds. A pose is a (c,) vector in ``channels`` order or a
        mapping {channel: value}; channels a mapping leaves out take their default (0 for names).
    channels : Rig, sequence of Channel, or sequence of str
        The clip's channels. Values are not range-checked here; ``sample(fps, channels=rig)``
        clips them (cubic interpolation may overshoot between poses).
    interpolation : "step" | "linear" | "cubic" | "tcb"
        Of every key.
    name : str
        Name of the single (base) layer.
    duration_s : float or None
        None: the last pose's time.

    Example: ``from_poses([(0, rest), (0.5, expression_pose(rig, "joy")), (1.0, rest)], rig)``.
    """
    names, defaults = _channel_source(channels)
    index = {n: j for j, n in enumerate(names)}
    times: list[float] = []
    rows: list[np.ndarray] = []
    for i, item in enumerate(poses):
        if not isinstance(item, (tuple, list)) or len(item) != 2:
            raise ClipError(f"pose {i} must be a (time_s, pose) pair; got {item!r}")
        time_s = _number(item[0], f"pose {i}: time_s")
        if times and time_s <= times[-1]:
            raise ClipError(
                f"pose {i} at t={_fmt(time_s)} s is not after pose {i - 1} at t={_fmt(times[-1])} s; "
                "give poses in increasing time order with no repeated times"
            )
        if isinstance(item[1], Mapping):
            row = defaults.copy()
            for channel, value in item[1].items():
                if channel not in index:
                    raise ClipError(f"pose {i}: {_unknown_channel(channel, names, 'the clip')}")
                row[index[channel]] = _number(value, f"pose {i}: {channel}")
        else:
            try:
                row = np.array(item[1], dtype=np.float64)
            except (TypeError, ValueError) as error:
                raise ClipError(f"pose {i} cannot be read as float64 numbers: {error}") from None
            if row.shape != (len(names),):
                raise ClipError(
                    f"pose {i} has shape {row.shape}; expected ({len(names)},) in the clip's channel order"
                )
            if not np.isfinite(row).all():
                bad = int(np.flatnonzero(~np.isfinite(row))[0])
                raise ClipError(f"pose {i}: channel {names[bad]!r} is not finite ({row[bad]})")
        times.append(time_s)
        rows.append(row)
    if not rows:
        raise ClipError("from_poses needs at least one (time_s, pose)")
    values = np.stack(rows)  # (poses, c)
    curves = {n: Curve.from_arrays(times, values[:, j], interpolation) for j, n in enumerate(names)}
    return KeyframeClip(names, (Layer(name, curves, "absolute"),), duration_s)


def from_expressions(
    rig: Rig,
    sequence: Sequence[tuple[float, str | Expression | Mapping[str, float] | None]],
    *,
    interpolation: Interpolation = "cubic",
    library: ExpressionLibrary | None = None,
) -> KeyframeClip:
    """A clip through named expressions, e.g. ``[(0, None), (0.5, "joy"), (1, "surprise"), (1.5, None)]``.

    Each entry is ``(time_s, expression)`` where expression is None or "rest" (the rig's defaults),
    an expression name or ``Expression`` (its pose at weight 1), or a mapping {name: weight} blended
    by ``compose_pose``. See ``from_poses`` for the rest.
    """
    poses = []
    for time_s, item in sequence:
        if item is None or (item == "rest" and (library is None or "rest" not in library)):
            weights: Any = ()
        elif isinstance(item, Mapping):
            weights = item
        else:
            weights = [(item, 1.0)]
        poses.append((time_s, compose_pose(rig, weights, library=library)))
    return from_poses(poses, rig, interpolation=interpolation)


def _simplify(times: np.ndarray, values: np.ndarray, tolerance: float | None) -> np.ndarray:
    """Indices of samples to keep so linear interpolation between them is within ``tolerance`` of all.

    Ramer–Douglas–Peucker with vertical error; None keeps every sample.
    """
    n = len(times)
    if tolerance is None or n <= 2:
        return np.arange(n)
    keep = np.zeros(n, dtype=bool)
    keep[0] = keep[-1] = True
    stack = [(0, n - 1)]
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        u = (times[a + 1 : b] - times[a]) / (times[b] - times[a])
        error = np.abs(values[a + 1 : b] - (values[a] + u * (values[b] - values[a])))
        k = int(np.argmax(error))
        if error[k] > tolerance:
            m = a + 1 + k
            keep[m] = True
            stack += [(a, m), (m, b)]
    return np.flatnonzero(keep)


def from_samples(
    names: Sequence[str], times: np.ndarray, values: np.ndarray, tolerance: float | None, name: str
) -> KeyframeClip:
    if tolerance is not None:
        tolerance = _number(tolerance, "tolerance")
        if tolerance < 0:
            raise ClipError(f"tolerance={tolerance:g} must be >= 0 (or None to keep every sample)")
    curves = {}
    for j, channel in enumerate(names):
        keep = _simplify(times, values[:, j], tolerance)
        curves[channel] = Curve.from_arrays(times[keep], values[keep, j], "linear")
    return KeyframeClip(tuple(names), (Layer(name, curves, "absolute"),), max(0.0, float(times[-1])))


def from_clip(clip: Clip, *, tolerance: float | None = None, name: str = "base") -> KeyframeClip:
    """A keyframe clip from a baked one: a linear key at every frame ``i / clip.fps``.

    With ``tolerance`` (>= 0, the channel's unit) keys are dropped while linear interpolation of the
    rest stays within ``tolerance`` of every frame (Ramer–Douglas–Peucker). ``duration_s`` is the
    time of the last frame, ``(frames - 1) / fps``, so ``sample(clip.fps)`` gives back the same frames
    (``Clip.duration_s`` counts one frame more: ``frames / fps``).
    """
    values = check_shape(clip.channels, clip.values, ndim=2)  # names the frame of a NaN
    if len(values) == 0:
        raise ClipError("the clip has no frames")
    times = np.arange(len(values)) / clip.fps
    return from_samples(clip.channels, times, values, tolerance, name)
