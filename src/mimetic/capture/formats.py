"""Trajectory files: read marker and landmark tracks, write them back.

``read_trajectories(path)`` reads four formats, told apart by their content (C3D also by the
``.c3d`` suffix); ``write_trajectories(trajectories, path)`` writes the first two:

* **CSV** (mimetic's own, ``.csv``)::

      # units: mm
      # fps: 60.0
      frame,time_s,nose_tip_x,nose_tip_y,nose_tip_z,chin_x,chin_y,chin_z,confidence
      0,0.0,1.5,20.25,88.0,,,,1.0
      1,0.016666666666666666,1.5,20.5,88.0,0.0,-40.0,80.5,0.75

  The header names a ``frame`` column first, then an optional ``time_s`` column, then for each
  point ``<name>_x``, ``<name>_y`` and (for 3D points) ``<name>_z``, and an optional
  ``confidence`` column in [0, 1] (1 where absent). Every point has the same axes: all 3D or all
  2D (image pixels, +y down). One row per frame; ``frame`` counts up by 1 from any start. An empty
  cell or ``nan`` is a missing coordinate. Lines starting with ``#`` are comments; before the
  header, ``# units: <mm|cm|m|px>`` gives the length unit and ``# fps: <rate>`` the frame rate.
  Without ``# fps``, the rate comes from ``frame`` and ``time_s`` (frames per second between the
  first and the last row). The writer writes every line above, numbers with ``repr`` (the
  shortest text that reads back to the same float), so a written file reads back exactly.
* **TRC** (OpenSim / Motion Analysis, ``.trc``): tab-separated; a ``PathFileType`` line, a line
  of header keys (``DataRate``, ``NumFrames``, ``NumMarkers``, ``Units``, …) and one of their
  values, the marker-name row (``Frame#``, ``Time``, one name per marker), the ``X1 Y1 Z1 …``
  row, then one row per frame; an empty cell is a missing coordinate. 3D only; the frame rate is
  ``DataRate``. Confidence is not stored.
* **C3D** (binary, read with the ``c3d`` package): labels from ``POINT:LABELS`` (and
  ``LABELS2`` …), the rate from ``POINT:RATE``, units from ``POINT:UNITS``; a point whose
  residual is negative is missing.
* **OpenFace 2.x** ``FeatureExtraction`` CSV (header `` frame, timestamp, confidence, success,
  …``): the 68 iBUG points, named ``ibug68_01`` … ``ibug68_68``
  (1-based, as iBUG and ``mimetic.fit.landmarks`` number them: OpenFace's column k is point
  k + 1). With its 3D columns ``X_k, Y_k, Z_k`` (mm, camera frame: +X right, +Y down, +Z away
  from the camera) the points are turned 180° about X (Y and Z negated) into mimetic's frame:
  right-handed, +Y up, +Z toward the camera, so the face looks down +Z. Without them the 2D
  columns ``x_k, y_k`` are read as they are: image pixels, +y down, units "px". A frame with
  ``success`` 0 has every point missing and confidence 0; other frames take the ``confidence``
  column. The rate comes from ``frame`` and ``timestamp``; a rate of ``MAX_TIMESTAMP_FPS`` or
  more (OpenFace writes 0.001 s steps when it is run on images) is refused unless ``fps`` is
  given.

Frame rate: the file's, unless ``fps`` is passed; when both are known and differ by more than
1 %, ``fps`` is used and a ``MimeticWarning`` names both. Units: the file's; ``units`` gives them
for a file that does not say, and must agree with a file that does.

Over 600 lines because its four readers share one check of names, units, frame rates and gaps.
"""

from __future__ import annotations

import csv
import io
import itertools
import logging
import math
import os
import re
import struct
import warnings
from collections.abc import Sequence
from pathlib import Path

import c3d
import numpy as np

from mimetic.atomic import atomic_write
from mimetic.capture.trajectories import LENGTH_UNITS, CaptureError, Trajectories
from mimetic.errors import MimeticWarning
from mimetic.inputs import decode_text, read_input

log = logging.getLogger(__name__)

__all__ = ["FPS_TOLERANCE", "MAX_TIMESTAMP_FPS", "read_trajectories", "write_trajectories"]

MAX_TIMESTAMP_FPS = 1000.0
"""A frame rate derived from a file's timestamps at or above this is implausible; pass ``fps=``."""

FPS_TOLERANCE = 0.01
"""Relative difference between a passed ``fps`` and the file's own rate above which a warning is given."""

_KNOWN_FORMATS = (
    "mimetic CSV (header 'frame,time_s,<name>_x,<name>_y,<name>_z,…'), TRC (first line 'PathFileType …'), "
    "C3D (.c3d), OpenFace 2.x FeatureExtraction CSV (header 'frame, timestamp, confidence, success, …')"
)
_WRITE_SUFFIXES = (".csv", ".trc")
_AXES = ("x", "y", "z")
_COMMENT_RE = re.compile(r"#\s*(units|fps)\s*[:=]\s*(.*?)\s*$", re.IGNORECASE)
_OPENFACE_COLUMNS = ("frame", "timestamp", "confidence", "success")
_OPENFACE_POINTS = 68
# What the c3d package raises on a truncated or corrupt file.
_C3D_ERRORS = (struct.error, AssertionError, ValueError, IndexError, KeyError, AttributeError, TypeError)


# ---------------------------------------------------------------------------------------------
# reading


def read_trajectories(
    path: str | os.PathLike[str], *, fps: float | None = None, units: str | None = None
) -> Trajectories:
    """Read tracked points from a mimetic CSV, TRC, C3D or OpenFace 2.x CSV file.

    See the module docstring for the formats and the coordinate conventions.

    Parameters
    ----------
    path : path-like
        The file; its format is told from its content (C3D also from a ``.c3d`` suffix).
    fps : float, optional
        Frames per second. Needed when the file gives no rate, or an implausible one (timestamps
        of ``MAX_TIMESTAMP_FPS`` or more); overrides the file's rate otherwise, with a
        ``MimeticWarning`` when the two differ by more than 1 %.
    units : {"mm", "cm", "m", "px"}, optional
        The length unit of a file that does not say; must agree with a file that does.

    Returns
    -------
    Trajectories
        ``positions`` (f, m, 3) or (f, m, 2) float64 in the file's units, NaN where a point is
        missing; ``confidence`` (f,) in [0, 1]; ``source`` the path. A point missing in every
        frame is kept, with a ``MimeticWarning`` naming it.

    Raises
    ------
    CaptureError
        A missing, empty, unknown, truncated or malformed file (the message names the line and
        column where it can); no frame rate; units that contradict the file; no point seen in
        any frame.
    """
    path = Path(path)
    src = str(path)
    data = _read_bytes(path, src)
    kind = "markers"
    if path.suffix.lower() == ".c3d" or (data[1:2] == b"P" and b"\0" in data[:512]):
        names, positions, confidence, file_fps, file_units = _parse_c3d(data, src)
        rate = _resolve_fps(file_fps, fps, src, origin="POINT:RATE", derived=False)
    else:
        text = _decode(data, src)
        first = next((line.strip() for line in text.splitlines() if line.strip()), "")
        if first.startswith("PathFileType"):
            names, positions, confidence, file_fps, file_units = _parse_trc(text, src)
            rate = _resolve_fps(file_fps, fps, src, origin="DataRate", derived=False)
        else:
            kind, header, values, lines, comments = _parse_csv(text, src)
            if kind == "openface":
                names, positions, confidence, file_fps, file_units = _openface(header, values, lines, src)
                rate = _resolve_fps(file_fps, fps, src, origin="timestamps", derived=True)
            else:
                names, positions, confidence, file_fps, derived, file_units = _mimetic_csv(
                    header, values, lines, comments, src
                )
                origin = "time_s column" if derived else "'# fps' line"
                rate = _resolve_fps(file_fps, fps, src, origin=origin, derived=derived)
    trajectories = Trajectories(
        names,
        positions,
        rate,
        _resolve_units(file_units, units, src),
        confidence,
        src,
        tracked=kind == "openface",
    )
    _check_seen(trajectories)
    log.debug(
        "%s: %d frames of %d points (d=%d) at %g fps",
        src,
        trajectories.n_frames,
        trajectories.n_points,
        trajectories.dims,
        rate,
    )
    return trajectories


def _read_bytes(path: Path, src: str) -> bytes:
    data = read_input(path, src, CaptureError, "trajectory")
    if not data.strip():
        raise CaptureError(f"{src}: the file is empty. Expected one of: {_KNOWN_FORMATS}.")
    return data


def _decode(data: bytes, src: str) -> str:
    """The file's text in any encoding ``mimetic.inputs.decode_text`` reads."""
    try:
        return decode_text(data, src, CaptureError)
    except CaptureError as error:
        raise CaptureError(f"{error}; and it is not C3D. Known formats: {_KNOWN_FORMATS}.") from None


def _unknown_format(src: str, what: str = "not a known trajectory format") -> CaptureError:
    return CaptureError(f"{src}: {what}. Known formats: {_KNOWN_FORMATS}.")


def _numbers(cells: Sequence[str], line: int, header: Sequence[str], src: str) -> list[float]:
    """The cells of one row as floats; an empty cell is NaN."""
    try:
        return [float(c) if c else math.nan for c in cells]
    except ValueError:
        column, cell = next((h, c) for h, c in zip(header, cells, strict=True) if not _is_number(c))
        raise CaptureError(
            f"{src}: line {line}, column {column!r}: {cell!r} is not a number. "
            "Write numbers, or leave the cell empty (or nan) for a missing coordinate."
        ) from None


def _is_number(cell: str) -> bool:
    try:
        float(cell or "nan")
    except ValueError:
        return False
    return True


def _check_frames(frames: np.ndarray, lines: Sequence[int], src: str, column: str) -> None:
    """Frame numbers (f,) must be integers counting up by 1."""
    bad = ~((frames == np.round(frames)) & np.isfinite(frames))
    bad[1:] |= np.diff(frames) != 1
    if bad.any():
        i = int(np.argmax(bad))
        after = f" after {frames[i - 1]:g}" if i else ""
        raise CaptureError(
            f"{src}: line {lines[i]}: {column} {frames[i]:g}{after}; frame numbers must be integers counting "
            "up by 1, one row per frame (one face per file for OpenFace)."
        )


def _check_confidence(confidence: np.ndarray, lines: Sequence[int], src: str) -> None:
    bad = ~((confidence >= 0) & (confidence <= 1))
    if bad.any():
        i = int(np.argmax(bad))
        raise CaptureError(
            f"{src}: line {lines[i]}: confidence {confidence[i]:g} must be a number in [0, 1]."
        )


def _timestamp_rate(frames: np.ndarray, times: np.ndarray) -> float | None:
    """Frames per second between the first and last row; None for a single frame."""
    if len(frames) < 2:
        return None
    span = float(times[-1] - times[0])
    return float(frames[-1] - frames[0]) / span if span else math.inf


def _csv_kind(header: list[str], src: str) -> str:
    """ "openface" or "mimetic", from a CSV file's header row; raise for any other header."""
    if set(_OPENFACE_COLUMNS) <= set(header):
        return "openface"
    if header[0] == "frame":
        return "mimetic"
    raise _unknown_format(src)


def _parse_csv(
    text: str, src: str
) -> tuple[str, list[str], np.ndarray, list[int], dict[str, tuple[str, int]]]:
    """The kind of CSV (see ``_csv_kind``), its header (stripped cells), values (rows, columns)
    float64, each row's line number, and the ``# units`` / ``# fps`` comments before the header
    (key → (value, line))."""
    reader = csv.reader(io.StringIO(text))
    header: list[str] | None = None
    comments: dict[str, tuple[str, int]] = {}
    rows, lines = [], []
    for row in reader:
        cells = [c.strip() for c in row]
        if not any(cells):
            continue
        if cells[0].startswith("#"):
            match = _COMMENT_RE.match(",".join(cells))
            if match and header is None:
                key = match.group(1).lower()
                if key in comments:
                    raise CaptureError(
                        f"{src}: line {reader.line_num}: a second '# {key}' line (the first is on line "
                        f"{comments[key][1]}). Keep one."
                    )
                comments[key] = (match.group(2), reader.line_num)
            continue
        if header is None:
            header = cells
            kind = _csv_kind(header, src)
            continue
        if len(cells) != len(header):
            raise CaptureError(
                f"{src}: line {reader.line_num} has {len(cells)} cells but the header has {len(header)} "
                "columns. Every row needs one cell per column (empty for a missing value)."
            )
        rows.append(_numbers(cells, reader.line_num, header, src))
        lines.append(reader.line_num)
    if header is None:
        raise CaptureError(f"{src}: only comments, no header row. Expected one of: {_KNOWN_FORMATS}.")
    return kind, header, np.array(rows, dtype=np.float64).reshape(len(rows), len(header)), lines, comments


def _mimetic_csv(
    header: list[str], values: np.ndarray, lines: list[int], comments: dict[str, tuple[str, int]], src: str
) -> tuple[tuple[str, ...], np.ndarray, np.ndarray, float | None, bool, str | None]:
    """Names, positions (f, m, d), confidence (f,), the file's rate, whether that rate was
    derived from ``time_s``, and the file's units."""
    if len(set(header)) != len(header):
        repeated = sorted({h for h in header if header.count(h) > 1})
        raise CaptureError(f"{src}: the header repeats column(s) {', '.join(map(repr, repeated))}.")
    column = {h: j for j, h in enumerate(header)}
    axes: dict[str, dict[str, int]] = {}
    for j, h in enumerate(header[1:], start=1):
        if h in ("time_s", "confidence"):
            continue
        name, _, axis = h.rpartition("_")
        if not name or axis not in _AXES:
            raise CaptureError(
                f"{src}: header column {h!r} is not <name>_x, <name>_y or <name>_z (nor time_s or "
                "confidence). Rename it, or remove the column."
            )
        axes.setdefault(name, {})[axis] = j
    if not axes:
        raise CaptureError(f"{src}: the header names no point columns (<name>_x, <name>_y[, <name>_z]).")
    names = tuple(axes)
    d = 3 if "z" in axes[names[0]] else 2
    for name in names:
        if sorted(axes[name]) != list(_AXES[:d]):
            given = ", ".join(f"{name}_{a}" for a in axes[name])
            want = ", ".join(f"{name}_{a}" for a in _AXES[:d])
            raise CaptureError(
                f"{src}: point {name!r} has columns {given}; every point needs {want} "
                f"(like {names[0]!r}): all 3D or all 2D."
            )
    if not len(values):
        raise CaptureError(f"{src}: a header but no frames; add one row per frame.")
    _check_frames(values[:, 0], lines, src, "frame")
    index = np.array([[axes[n][a] for a in _AXES[:d]] for n in names])  # (m, d)
    positions = values[:, index]  # (f, m, d)
    confidence = values[:, column["confidence"]] if "confidence" in column else np.ones(len(values))
    _check_confidence(confidence, lines, src)
    units = comments["units"][0] if "units" in comments else None
    derived = "fps" not in comments
    if derived:
        rate = _timestamp_rate(values[:, 0], values[:, column["time_s"]]) if "time_s" in column else None
    else:
        value, line = comments["fps"]
        try:
            rate = float(value)
        except ValueError:
            raise CaptureError(
                f"{src}: line {line}: '# fps: {value}' is not a number; write e.g. '# fps: 60'."
            ) from None
    return names, positions, confidence, rate, derived, units


def _openface(
    header: list[str], values: np.ndarray, lines: list[int], src: str
) -> tuple[tuple[str, ...], np.ndarray, np.ndarray, float | None, str]:
    """Names, positions (f, 68, d), confidence (f,), the timestamps' rate and the units."""
    column = {h: j for j, h in enumerate(header)}
    k = range(_OPENFACE_POINTS)
    if all(f"{a}_{i}" in column for a in "XYZ" for i in k):
        axes, units = "XYZ", "mm"
    elif all(f"{a}_{i}" in column for a in "xy" for i in k):
        axes, units = "xy", "px"
    else:
        raise CaptureError(
            f"{src}: an OpenFace file without the 68 landmark columns (X_0 … Z_67 or x_0 … y_67). "
            "Run FeatureExtraction with -3Dfp (or -2Dfp)."
        )
    if not len(values):
        raise CaptureError(f"{src}: an OpenFace header but no frames.")
    frames = values[:, column["frame"]]
    _check_frames(frames, lines, src, "frame")
    index = np.array([[column[f"{a}_{i}"] for a in axes] for i in k])  # (68, d)
    positions = values[:, index]  # (f, 68, d)
    if axes == "XYZ":
        positions[..., 1:] *= -1.0  # camera (+Y down, +Z away) → +Y up, +Z toward the camera
    confidence = values[:, column["confidence"]].copy()
    failed = values[:, column["success"]] == 0
    positions[failed] = np.nan
    confidence[failed] = 0.0
    _check_confidence(confidence, lines, src)
    names = tuple(f"ibug68_{i + 1:02d}" for i in k)
    return names, positions, confidence, _timestamp_rate(frames, values[:, column["timestamp"]]), units


def _parse_trc(
    text: str, src: str
) -> tuple[tuple[str, ...], np.ndarray, np.ndarray, float | None, str | None]:
    """Names, positions (f, m, 3), confidence (f,) of ones, DataRate and Units of a TRC file."""
    numbered = [(n, line) for n, line in enumerate(text.splitlines(), start=1) if line.strip()]
    if len(numbered) < 5:
        raise CaptureError(
            f"{src}: a TRC file needs 5 header lines (PathFileType, header keys, their values, marker "
            f"names, X1 Y1 Z1 …); it has {len(numbered)} non-empty lines."
        )
    (_, keys), (values_line, values), (_, name_row), (_, axes_row) = numbered[1:5]
    fields = dict(
        zip((c.strip() for c in keys.split("\t")), (c.strip() for c in values.split("\t")), strict=False)
    )

    def number(key: str) -> float:
        try:
            return float(fields[key])
        except KeyError:
            raise CaptureError(
                f"{src}: the TRC header has no {key} (its keys: {', '.join(fields)})."
            ) from None
        except ValueError:
            raise CaptureError(f"{src}: line {values_line}: {key} {fields[key]!r} is not a number.") from None

    names = tuple(c.strip() for c in name_row.split("\t")[2:] if c.strip())
    n_markers = number("NumMarkers")
    if n_markers != len(names):
        raise CaptureError(
            f"{src}: NumMarkers is {n_markers:g} but the marker-name row names {len(names)} markers "
            f"({', '.join(names[:5])}{', …' if len(names) > 5 else ''}). Fix NumMarkers or the name row."
        )
    n_axes = sum(1 for c in axes_row.split("\t") if c.strip())
    if n_axes != 3 * len(names):
        raise CaptureError(
            f"{src}: the X1 Y1 Z1 … row has {n_axes} labels; {len(names)} markers need {3 * len(names)}."
        )
    width = 2 + 3 * len(names)
    header = ["Frame#", "Time", *(f"{n} {a.upper()}" for n in names for a in _AXES)]
    rows, lines = [], []
    for line, row in numbered[5:]:
        cells = [c.strip() for c in row.split("\t")]
        while len(cells) > width and not cells[-1]:
            cells.pop()
        if len(cells) != width:
            raise CaptureError(
                f"{src}: line {line} has {len(cells)} cells; Frame#, Time and 3 per marker make {width}. "
                "Leave a missing marker's cells empty but keep their tabs."
            )
        rows.append(_numbers(cells, line, header, src))
        lines.append(line)
    n_frames = number("NumFrames")
    if n_frames != len(rows):
        raise CaptureError(
            f"{src}: NumFrames is {n_frames:g} but the file has {len(rows)} frame rows; is it truncated?"
        )
    if not rows:
        raise CaptureError(f"{src}: a TRC header but no frames.")
    table = np.array(rows, dtype=np.float64)
    _check_frames(table[:, 0], lines, src, "Frame#")
    positions = table[:, 2:].reshape(len(rows), len(names), 3)
    return names, positions, np.ones(len(rows)), number("DataRate"), fields.get("Units")


def _parse_c3d(data: bytes, src: str) -> tuple[tuple[str, ...], np.ndarray, np.ndarray, float, str | None]:
    """Names, positions (f, m, 3) float64 (NaN where the residual is negative), confidence (f,) of
    ones, POINT:RATE and POINT:UNITS of a C3D file."""
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            reader = c3d.Reader(io.BytesIO(data))
            frames = [points[:, :4].astype(np.float64) for _, points, _ in reader.read_frames(copy=True)]
            expected, used, rate = reader.frame_count, reader.point_used, float(reader.point_rate)
            labels = []
            for k in itertools.count(1):
                param = reader.get(f"POINT:LABELS{k if k > 1 else ''}")
                if param is None:
                    break
                labels += [str(s).strip() for s in np.ravel(param.string_array)]
            units_param = reader.get("POINT:UNITS")
            units = units_param.string_value.strip() if units_param is not None else None
    except _C3D_ERRORS as error:
        raise CaptureError(
            f"{src}: not a readable C3D file, truncated or corrupt ({type(error).__name__}: {error})."
        ) from None
    for warning in caught:
        log.debug("%s: c3d: %s", src, warning.message)
    if len(frames) != expected:
        raise CaptureError(
            f"{src}: the C3D file is truncated: its header promises {expected} frames, the data holds "
            f"{len(frames)}."
        )
    if used == 0 or not frames:
        raise CaptureError(f"{src}: the C3D file holds no points ({used} points, {len(frames)} frames).")
    if len(labels) < used:
        raise CaptureError(f"{src}: POINT:LABELS names {len(labels)} points but POINT:USED is {used}.")
    names = tuple(labels[:used])
    if not all(names):
        raise CaptureError(f"{src}: point {names.index('') + 1} of {used} has an empty POINT:LABELS entry.")
    table = np.stack(frames)  # (f, m, 4): x, y, z, residual
    positions = table[..., :3].copy()
    positions[table[..., 3] < 0] = np.nan
    return names, positions, np.ones(len(table)), rate, units.lower() if units else None


def _resolve_fps(file_fps: float | None, fps: float | None, src: str, *, origin: str, derived: bool) -> float:
    """The frame rate: ``fps`` when given (warning when the file's differs by more than 1 %), else
    the file's. ``derived``: the file's rate comes from timestamps and may be implausible."""
    if fps is not None:
        if not (math.isfinite(fps) and fps > 0):
            raise CaptureError(f"{src}: fps={fps} must be a positive number of frames per second.")
        if file_fps is not None and not abs(file_fps - fps) <= FPS_TOLERANCE * fps:
            warnings.warn(
                f"{src}: fps={fps:g} was passed but the file ({origin}) says {file_fps:.6g} fps; "
                f"using {fps:g}.",
                MimeticWarning,
                stacklevel=3,
            )
        return float(fps)
    if file_fps is None:
        raise CaptureError(f"{src}: the file gives no frame rate; pass it as fps= (e.g. fps=30).")
    limit = MAX_TIMESTAMP_FPS if derived else math.inf
    if not (math.isfinite(file_fps) and 0 < file_fps < limit):
        raise CaptureError(
            f"{src}: the file ({origin}) says {file_fps:.6g} fps, which cannot be the recording's "
            "frame rate; pass the real rate as fps= (e.g. fps=30)."
        )
    return file_fps


def _resolve_units(file_units: str | None, units: str | None, src: str) -> str | None:
    if file_units is not None:
        file_units = file_units.strip().lower() or None
    for value, what in ((file_units, "the file's units"), (units, "units")):
        if value is not None and value not in LENGTH_UNITS:
            raise CaptureError(f"{src}: {what} {value!r} unknown; use one of {', '.join(LENGTH_UNITS)}.")
    if file_units is not None and units is not None and file_units != units:
        raise CaptureError(
            f"{src}: the file says units {file_units!r} but units={units!r} was passed. Drop the argument, "
            "or fix the file's units."
        )
    return file_units or units


def _check_seen(trajectories: Trajectories) -> None:
    """Raise when no point is seen in any frame; warn about points never seen."""
    seen = trajectories.seen  # (f, m)
    if not seen.any():
        raise CaptureError(
            f"{trajectories.source}: no point is seen in any of its {trajectories.n_frames} frames "
            "(every coordinate is missing)."
        )
    never = [n for n, s in zip(trajectories.names, seen.any(axis=0), strict=True) if not s]
    if never:
        shown = ", ".join(never[:8]) + (f" and {len(never) - 8} more" if len(never) > 8 else "")
        warnings.warn(
            f"{trajectories.source}: point(s) {shown} missing in every frame; kept as NaN.",
            MimeticWarning,
            stacklevel=3,
        )


# ---------------------------------------------------------------------------------------------
# writing


def write_trajectories(trajectories: Trajectories, path: str | os.PathLike[str]) -> Path:
    """Write ``trajectories`` to a mimetic CSV (``.csv``) or TRC (``.trc``) file, atomically.

    Numbers are written with ``repr`` precision, so ``read_trajectories`` gives back the same
    names, positions, fps and units (and, for CSV, confidence). See the module docstring for the
    formats.

    Parameters
    ----------
    trajectories : Trajectories
        ``positions`` (f, m, d): d = 3 for TRC; 2 or 3 for CSV.
    path : path-like
        The file to write; its suffix picks the format. Its folder must exist.

    Returns
    -------
    path : Path
        The file written. A failure leaves any existing file at ``path`` untouched.

    Raises
    ------
    CaptureError
        An unknown suffix; a TRC of 2D points or without units.
    WriteError
        The folder does not exist or is not writable.
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix == ".csv":
        text = _csv_text(trajectories)
    elif suffix == ".trc":
        text = _trc_text(trajectories, path.name)
    else:
        raise CaptureError(
            f"cannot write {path}: unknown suffix {suffix or '(none)'!r}; "
            f"use one of {', '.join(_WRITE_SUFFIXES)}."
        )
    with atomic_write(path, "w") as handle:
        handle.write(text)
    return path


def _cell(value: float) -> str:
    return repr(float(value)) if math.isfinite(value) else ""


def _csv_text(t: Trajectories) -> str:
    buffer = io.StringIO()
    if t.units is not None:
        buffer.write(f"# units: {t.units}\n")
    buffer.write(f"# fps: {t.fps!r}\n")
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(
        ["frame", "time_s", *(f"{n}_{a}" for n in t.names for a in _AXES[: t.dims]), "confidence"]
    )
    for i, (frame, confidence) in enumerate(zip(t.positions, t.confidence, strict=True)):
        writer.writerow([i, repr(i / t.fps), *map(_cell, frame.ravel()), repr(float(confidence))])
    return buffer.getvalue()


def _trc_text(t: Trajectories, file_name: str) -> str:
    if t.dims != 3:
        raise CaptureError(
            f"{t.source}: TRC holds 3D markers; these points are 2D. Write them to a .csv file."
        )
    if t.units is None or t.units == "px":
        raise CaptureError(
            f"{t.source}: a TRC file must state a length unit (mm, cm or m); these trajectories have "
            f"{t.units!r}. Set it first, e.g. dataclasses.replace(trajectories, units='mm')."
        )
    if not np.all(t.confidence == 1):
        warnings.warn(
            f"{t.source}: TRC cannot store confidence; it is not written.", MimeticWarning, stacklevel=3
        )
    f, m = t.n_frames, t.n_points
    rate = repr(t.fps)
    lines = [
        f"PathFileType\t4\t(X/Y/Z)\t{file_name}",
        "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames",
        f"{rate}\t{rate}\t{f}\t{m}\t{t.units}\t{rate}\t1\t{f}",
        "\t".join(["Frame#", "Time", *(f"{n}\t\t" for n in t.names)]).rstrip("\t"),
        "\t".join(["", "", *(f"{a}{j}" for j in range(1, m + 1) for a in "XYZ")]),
        "",
    ]
    for i, frame in enumerate(t.positions):
        lines.append("\t".join([str(i + 1), repr(i / t.fps), *map(_cell, frame.ravel())]))
    return "\n".join(lines) + "\n"
