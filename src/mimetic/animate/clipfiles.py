"""Clip files: JSON keyframe clips and CSV sampled curves, for keyframe and baked clips alike.

``save_clip(clip, path)`` writes a ``KeyframeClip`` or a baked ``Clip`` (the activation pivot), in
the format ``path``'s suffix names: ``.json`` (a keyframe clip; a baked one gets a linear key per
frame, ``from_clip``) or ``.csv`` (sampled curves; a keyframe clip is sampled at ``fps``).
``load_clip(path)`` reads either back as a ``KeyframeClip``.

Files
-----
``save_clip``/``load_clip`` read and write JSON (``FORMAT``, ``VERSION``)::

    {"format": "mimetic-clip", "version": 1, "duration_s": 2.0, "channels": ["jaw_open"],
     "layers": [{"name": "base", "mode": "absolute", "weight": 1.0, "curves": {
         "jaw_open": {"keys": [[0.0, 0.0, "cubic", 0.0, 0.0, 0.0], [1.0, 0.3, "tcb", 0.5, 0.0, 0.0]]}}},
                {"name": "edit", "mode": "additive", "weight": 1.0, "curves": {
         "jaw_open": {"bspline": {"start_s": 0.25, "spacing_s": 0.25, "coefficients": [0.01, 0.02]}}}}]}

A key may also be written ``[t, v]`` (cubic) or ``[t, v, interpolation]``. ``save_csv``/``load_csv``
write and read sampled curves as ``time_s,channel,...`` rows. Every writer is atomic
(``mimetic.atomic.atomic_write``); every reader names the file, the line or the JSON path, and the
fix.
"""

from __future__ import annotations

import csv
import io
import json
import logging
import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from mimetic.animate.curves import BSplineEdit, ClipError, Curve, Key
from mimetic.animate.keyframes import KeyframeClip, Layer, from_clip, from_samples
from mimetic.atomic import atomic_write
from mimetic.inputs import read_text
from mimetic.rig.activations import Clip, check_shape

log = logging.getLogger(__name__)

FORMAT = "mimetic-clip"
VERSION = 1
SUFFIXES = (".json", ".csv")
"""The clip files ``save_clip`` writes and ``load_clip`` reads."""

_TOP_KEYS = frozenset({"format", "version", "duration_s", "channels", "layers"})
_LAYER_KEYS = frozenset({"name", "mode", "weight", "curves"})
_BSPLINE_KEYS = frozenset({"start_s", "spacing_s", "coefficients"})


# --------------------------------------------------------------------------- JSON files


def _curve_document(curve: Curve | BSplineEdit) -> dict[str, Any]:
    if isinstance(curve, BSplineEdit):
        return {
            "bspline": {
                "start_s": curve.start_s,
                "spacing_s": curve.spacing_s,
                "coefficients": list(curve.coefficients),
            }
        }
    return {
        "keys": [[k.time_s, k.value, k.interpolation, k.tension, k.continuity, k.bias] for k in curve.keys]
    }


def _document(clip: KeyframeClip) -> dict[str, Any]:
    """The JSON document of ``clip`` (plain dicts, lists, floats and strings)."""
    return {
        "format": FORMAT,
        "version": VERSION,
        "duration_s": clip.duration_s,
        "channels": list(clip.channels),
        "layers": [
            {
                "name": layer.name,
                "mode": layer.mode,
                "weight": layer.weight,
                "curves": {channel: _curve_document(curve) for channel, curve in layer.curves.items()},
            }
            for layer in clip.layers
        ],
    }


def _dumps(document: dict[str, Any]) -> str:
    """Indented JSON with every innermost list (a key, the coefficients, the channels) on one line."""
    text = json.dumps(document, indent=1, allow_nan=False, ensure_ascii=False)

    def one_line(match: re.Match[str]) -> str:
        # a raw newline never occurs inside a JSON string, so these only touch whitespace between tokens
        flat = re.sub(r",\n\s*", ", ", match.group(0))
        return re.sub(r"\n\s*", "", flat)

    return re.sub(r"\[[^\[\]{}]*\]", one_line, text) + "\n"


def save_clip(clip: KeyframeClip | Clip, path: str | Path, *, fps: float | None = None) -> Path:
    """Write ``clip`` atomically in the format ``path``'s suffix names; returns the path.

    Parameters
    ----------
    clip : KeyframeClip or Clip
        A keyframe clip, or a baked one (the activation pivot, (frames, c) at its fps).
    path : path-like
        ``.json``: the clip file (``FORMAT`` version ``VERSION``; a baked clip gets a linear key per
        frame, ``from_clip``), written with full precision so ``load_clip`` gives back an equal
        clip. ``.csv``: sampled curves (``save_csv``).
    fps : float, optional
        For a keyframe clip written as CSV: the rate it is sampled at (required there).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        raise ClipError(f"{path.name}: a clip file is {' or '.join(SUFFIXES)}; got {suffix or 'no suffix'!r}")
    if suffix == ".csv":
        return save_csv(clip, path, fps=fps)
    if isinstance(clip, Clip):
        clip = from_clip(clip)
    if not isinstance(clip, KeyframeClip):
        raise TypeError(f"save_clip writes a KeyframeClip or a Clip; got {type(clip).__name__}")
    with atomic_write(path, "w") as handle:
        handle.write(_dumps(_document(clip)))
    log.info("wrote clip %s (%d layers, %d channels)", path, len(clip.layers), len(clip.channels))
    return path


def _check_keys(data: Mapping[str, Any], allowed: frozenset[str], where: str) -> None:
    extra = sorted(set(data) - allowed)
    if extra:
        raise ClipError(
            f"{where}: unknown field {extra[0]!r}; allowed fields are {', '.join(sorted(allowed))}"
        )


def _parse_curve(data: Any, where: str) -> Curve | BSplineEdit:
    if not isinstance(data, dict) or len(data) != 1 or next(iter(data)) not in ("keys", "bspline"):
        raise ClipError(f'{where}: a curve must be {{"keys": [[t, v, ...], ...]}} or {{"bspline": {{...}}}}')
    if "bspline" in data:
        spline = data["bspline"]
        if not isinstance(spline, dict):
            raise ClipError(f"{where}.bspline must be an object with start_s, spacing_s, coefficients")
        _check_keys(spline, _BSPLINE_KEYS, f"{where}.bspline")
        missing = sorted(_BSPLINE_KEYS - set(spline))
        if missing:
            raise ClipError(f"{where}.bspline: missing field {missing[0]!r}")
        if not isinstance(spline["coefficients"], list):
            raise ClipError(f"{where}.bspline.coefficients must be a list of numbers")
        try:
            return BSplineEdit(spline["start_s"], spline["spacing_s"], tuple(spline["coefficients"]))
        except ClipError as error:
            raise ClipError(f"{where}.bspline: {error}") from None
    rows = data["keys"]
    if not isinstance(rows, list) or not rows:
        raise ClipError(f"{where}.keys must be a non-empty list of [time_s, value, interpolation, T, C, B]")
    keys = []
    for i, row in enumerate(rows):
        if not isinstance(row, list) or len(row) not in (2, 3, 6):
            raise ClipError(
                f"{where}.keys[{i}] = {row!r}: a key is [time_s, value], [time_s, value, interpolation] or "
                "[time_s, value, interpolation, tension, continuity, bias]"
            )
        try:
            keys.append(Key(*row))
        except ClipError as error:
            raise ClipError(f"{where}.keys[{i}]: {error}") from None
    try:
        return Curve(tuple(keys))
    except ClipError as error:
        raise ClipError(f"{where}.keys: {error}") from None


def _parse_clip(data: Any, source: str) -> KeyframeClip:
    if not isinstance(data, dict):
        raise ClipError(f"{source}: a clip file holds a JSON object; got {type(data).__name__}")
    if data.get("format") != FORMAT:
        raise ClipError(f"{source}: not a mimetic clip (format={data.get('format')!r}; expected {FORMAT!r})")
    version = data.get("version")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise ClipError(f"{source}: version={version!r} must be a positive integer")
    if version > VERSION:
        raise ClipError(
            f"{source}: written by a newer mimetic (clip version {version}; this one reads up to {VERSION}). "
            "Upgrade mimetic."
        )
    _check_keys(data, _TOP_KEYS, source)
    layers_data = data.get("layers")
    if not isinstance(layers_data, list) or not layers_data:
        raise ClipError(f"{source}: 'layers' must be a non-empty list of layers")
    layers = []
    order: list[str] = []
    for i, item in enumerate(layers_data):
        where = f"{source}: layers[{i}]"
        if not isinstance(item, dict):
            raise ClipError(f"{where} must be an object with name, mode, weight, curves")
        _check_keys(item, _LAYER_KEYS, where)
        curves_data = item.get("curves", {})
        if not isinstance(curves_data, dict):
            raise ClipError(f"{where}.curves must be an object channel → curve")
        curves = {}
        for channel, curve in curves_data.items():
            curves[channel] = _parse_curve(curve, f"{where}.curves[{channel!r}]")
            if channel not in order:
                order.append(channel)
        try:
            layers.append(
                Layer(item.get("name"), curves, item.get("mode", "absolute"), item.get("weight", 1.0))
            )
        except ClipError as error:
            raise ClipError(f"{where}: {error}") from None
    channels = data.get("channels", order)
    if not isinstance(channels, list):
        raise ClipError(f"{source}: 'channels' must be a list of channel names")
    try:
        return KeyframeClip(tuple(channels), tuple(layers), data.get("duration_s"))
    except ClipError as error:
        raise ClipError(f"{source}: {error}") from None


def load_clip(path: str | Path) -> KeyframeClip:
    """Read a clip file written by ``save_clip`` (or by hand; see the module docstring): a ``.json``
    clip, or ``.csv`` sampled curves (``load_csv``).

    Raises ``ClipError`` naming the file and the line (syntax) or JSON path (content) of a problem:
    invalid JSON, NaN/Infinity, unsorted or repeated key times, unknown interpolation, unknown
    fields, or a newer format version.
    """
    path = Path(path)
    if path.suffix.lower() == ".csv":
        return load_csv(path)
    text = read_text(path, ClipError, "clip")

    def reject_constant(name: str) -> float:
        at = re.search(rf"(?<![\w\"]){re.escape(name)}(?![\w\"])", text)
        line = text.count("\n", 0, at.start()) + 1 if at else "?"
        raise ClipError(f"{path.name} line {line}: {name} is not allowed; every number must be finite")

    try:
        data = json.loads(text, parse_constant=reject_constant)
    except json.JSONDecodeError as error:
        raise ClipError(
            f"{path.name} line {error.lineno} column {error.colno}: not valid JSON ({error.msg})"
        ) from None
    return _parse_clip(data, path.name)


# --------------------------------------------------------------------------- CSV files


def save_csv(
    clip: KeyframeClip | Clip,
    path: str | Path,
    *,
    fps: float | None = None,
    digits: int | None = None,
) -> Path:
    """Write sampled curves as CSV, atomically: a ``time_s,<channel>,...`` header, one row per frame.

    Parameters
    ----------
    clip : KeyframeClip or Clip
        A keyframe clip is sampled at ``fps`` (required); a baked ``Clip`` is written at its own fps.
    path : path-like
    fps : float or None
        Frame rate for a keyframe clip; frame times are ``i / fps`` seconds.
    digits : int or None
        Significant digits of the values (1–17); None writes each value exactly (shortest repr).
        Times are always written exactly.
    """
    if isinstance(clip, KeyframeClip):
        if fps is None:
            raise ClipError("save_csv needs fps= to sample a keyframe clip, e.g. fps=30")
        sampled = clip.sample(fps)
    elif isinstance(clip, Clip):
        if fps is not None and fps != clip.fps:
            raise ClipError(f"the clip is already sampled at {clip.fps:g} fps; leave fps out or resample it")
        sampled = clip
    else:
        raise TypeError(f"save_csv writes a KeyframeClip or Clip; got {type(clip).__name__}")
    if digits is not None and (
        isinstance(digits, bool) or not isinstance(digits, int) or not 1 <= digits <= 17
    ):
        raise ClipError(f"digits={digits!r} must be an integer in 1…17, or None for exact values")
    values = check_shape(sampled.channels, sampled.values, ndim=2)  # names frame and channel of a NaN
    times = (np.arange(len(values)) / sampled.fps).tolist()

    def text(value: float) -> str:
        return repr(value) if digits is None else f"{value:.{digits}g}"

    path = Path(path)
    with atomic_write(path, "w") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(["time_s", *sampled.channels])
        for time_s, row in zip(times, values.tolist(), strict=True):
            writer.writerow([repr(time_s), *(text(v) for v in row)])
    log.info("wrote %s (%d frames at %g fps)", path, len(values), sampled.fps)
    return path


def load_csv(path: str | Path, *, tolerance: float | None = None, name: str = "base") -> KeyframeClip:
    """Read sampled curves (``time_s,<channel>,...``) as a clip of linear keys, one per row.

    Rows may be at any times (any fps, even uneven), strictly increasing. ``tolerance`` drops keys
    as in ``from_clip``. ``duration_s`` is the last row's time. Raises ``ClipError`` naming the file,
    line and column of a bad header, a short row, a non-number, NaN, or a time out of order.
    """
    path = Path(path)
    reader = csv.reader(io.StringIO(read_text(path, ClipError, "clip")))
    header: list[str] | None = None
    times: list[float] = []
    rows: list[list[float]] = []
    for fields in reader:
        line = reader.line_num
        if not any(f.strip() for f in fields):
            continue
        if header is None:
            header = [f.strip() for f in fields]
            if header[0] != "time_s":
                raise ClipError(
                    f"{path.name} line {line}: the first column must be 'time_s'; got {header[0]!r}. "
                    "The header is time_s,<channel>,<channel>,…"
                )
            if len(header) < 2 or not all(header[1:]):
                raise ClipError(
                    f"{path.name} line {line}: the header needs at least one non-empty channel name"
                )
            repeated = [c for c in header[1:] if header[1:].count(c) > 1]
            if repeated:
                raise ClipError(
                    f"{path.name} line {line}: channel {repeated[0]!r} appears twice in the header"
                )
            continue
        if len(fields) != len(header):
            raise ClipError(
                f"{path.name} line {line}: expected {len(header)} values ({', '.join(header[:3])}, …); "
                f"got {len(fields)}"
            )
        numbers = []
        for column, field in zip(header, fields, strict=True):
            try:
                number = float(field)
            except ValueError:
                raise ClipError(
                    f"{path.name} line {line}, column {column!r}: {field!r} is not a number"
                ) from None
            if not math.isfinite(number):
                raise ClipError(f"{path.name} line {line}, column {column!r}: {field.strip()} must be finite")
            numbers.append(number)
        if times and numbers[0] <= times[-1]:
            raise ClipError(
                f"{path.name} line {line}: time_s {numbers[0]:g} is not after the previous row's "
                f"{times[-1]:g}; rows must be in increasing time with no repeats"
            )
        times.append(numbers[0])
        rows.append(numbers[1:])
    if header is None:
        raise ClipError(f"{path.name}: empty file; expected a time_s,<channel>,… header and rows")
    if not rows:
        raise ClipError(f"{path.name}: no rows after the header")
    return from_samples(header[1:], np.array(times), np.array(rows), tolerance, name)
