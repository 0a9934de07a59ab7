"""The project's named landmarks on a user's head mesh, and landmark files.

``Landmarks`` (names, positions (k, 3), confidence (k,), units) is what the fit takes. It comes
from a file or from ``mimetic.fit.autolandmarks.auto_landmarks`` (MediaPipe on renders of the mesh):

* ``read_landmarks(path)``: a JSON file ``{"units": "cm", "landmarks": {"nose_tip": [x, y, z], ...}}``
  or a CSV file of ``name,x,y,z`` rows (optional header row, optional ``# units: mm`` line). Names
  are the project's (``PROJECT_LANDMARKS``, the keys of ``make_head().landmarks``) or
  ``ibug68_01`` ... ``ibug68_68`` (1-based iBUG 68-point order, mapped through
  ``mimetic.head.landmarks.IBUG68``). ``write_landmarks`` writes the same formats.

iBUG 68 has two points for each mouth corner (49/55 on the outer lip contour, 61/65 on the inner
one); both map to ``mouth_corner_R`` / ``mouth_corner_L``. When a file gives both, the outer one
(49, 55) is used and the inner one is ignored.

Lengths are in the landmarks' ``units`` ("mm", "cm", "dm", "m", or None when unknown).
"""

from __future__ import annotations

import csv
import difflib
import io
import json
import logging
import math
import os
import re
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mimetic.atomic import atomic_write
from mimetic.errors import LandmarkError
from mimetic.head.landmarks import IBUG68
from mimetic.mesh.io import read_input
from mimetic.mesh.units import UNIT_SCALE, convert_units

log = logging.getLogger(__name__)

__all__ = [
    "MIN_LANDMARKS",
    "PROJECT_LANDMARKS",
    "Landmarks",
    "read_landmarks",
    "write_landmarks",
]

MIN_LANDMARKS = 8
"""Fewest landmarks a file may give: enough, when well spread, for a robust similarity fit."""

# The keys of make_head().landmarks (tests/fit/test_landmarks.py checks that they agree).
PROJECT_LANDMARKS: tuple[str, ...] = (
    "alar_base_L", "alar_base_R", "alare_L", "alare_R",
    "brow_inner_L", "brow_inner_R", "brow_inner_mid_L", "brow_inner_mid_R", "brow_mid_L", "brow_mid_R",
    "brow_outer_L", "brow_outer_R", "brow_outer_mid_L", "brow_outer_mid_R",
    "eye_inner_corner_L", "eye_inner_corner_R", "eye_lower_lid_L", "eye_lower_lid_R",
    "eye_lower_lid_inner_L", "eye_lower_lid_inner_R", "eye_lower_lid_outer_L", "eye_lower_lid_outer_R",
    "eye_outer_corner_L", "eye_outer_corner_R", "eye_upper_lid_L", "eye_upper_lid_R",
    "eye_upper_lid_inner_L", "eye_upper_lid_inner_R", "eye_upper_lid_outer_L", "eye_upper_lid_outer_R",
    "glabella", "gonion_L", "gonion_R",
    "jaw_L1", "jaw_L2", "jaw_L3", "jaw_L4", "jaw_L5", "jaw_L6", "jaw_L7", "jaw_L8",
    "jaw_R1", "jaw_R2", "jaw_R3", "jaw_R4", "jaw_R5", "jaw_R6", "jaw_R7", "jaw_R8",
    "lower_lip_bottom", "lower_lip_inner", "lower_lip_inner_L", "lower_lip_inner_R",
    "lower_lip_mid_L", "lower_lip_mid_R", "lower_lip_outer_L", "lower_lip_outer_R",
    "menton", "mouth_corner_L", "mouth_corner_R", "nasion", "nose_bridge_lower", "nose_bridge_upper",
    "nose_tip", "nostril_L", "nostril_R", "pogonion", "pupil_L", "pupil_R", "subnasale",
    "tragion_L", "tragion_R", "upper_lip_inner", "upper_lip_inner_L", "upper_lip_inner_R",
    "upper_lip_outer_L", "upper_lip_outer_R", "upper_lip_peak_L", "upper_lip_peak_R", "upper_lip_top",
    "zygion_L", "zygion_R",
)  # fmt: skip
_KNOWN = frozenset(PROJECT_LANDMARKS)


_IBUG_RE = re.compile(r"ibug68_(\d{1,2})")
_UNITS_RE = re.compile(r"#\s*units\s*[:=]\s*(\S*)\s*$", re.IGNORECASE)
_FORMAT_HINT = 'expected {"units": "cm", "landmarks": {"nose_tip": [x, y, z], ...}}'


# ---------------------------------------------------------------------------------------------
# the data type


@dataclass(frozen=True, eq=False)
class Landmarks:
    """Named 3D landmarks on one mesh.

    Attributes
    ----------
    names : tuple of str
        Project landmark names (see ``PROJECT_LANDMARKS``), unique.
    positions : (k, 3) float64
        Positions in ``units``, in the mesh's own frame (not re-oriented). Read-only.
    confidence : (k,) float64
        In [0, 1]; 1.0 for landmarks read from a file. Read-only.
    units : str or None
        "mm", "cm", "dm" or "m"; None when unknown.
    source : str
        Where they came from, e.g. "file:lm.json" or "auto:mediapipe".
    orientation : (3, 3) float64 or None
        For detected landmarks: the rotation ``R`` taking the mesh frame to +Y up, +Z forward
        (``R @ p`` re-orients a point ``p``). None when not detected. Read-only.
    """

    names: tuple[str, ...]
    positions: np.ndarray
    confidence: np.ndarray
    units: str | None
    source: str
    orientation: np.ndarray | None = None

    def __post_init__(self) -> None:
        names = tuple(self.names)
        if not all(isinstance(n, str) for n in names):
            raise TypeError(f"landmark names must be strings; got {names!r}")
        unknown = [n for n in names if n not in _KNOWN]
        if unknown:
            raise LandmarkError(_unknown_message(unknown, "Landmarks"))
        repeated = sorted({n for n in names if names.count(n) > 1})
        if repeated:
            raise LandmarkError(f"Landmarks: {', '.join(map(repr, repeated))} given more than once")
        positions = np.array(self.positions, dtype=np.float64)
        if len(names) == 0 and positions.size == 0:
            positions = positions.reshape(0, 3)
        if positions.shape != (len(names), 3):
            raise ValueError(f"positions must have shape ({len(names)}, 3); got {positions.shape}")
        bad = ~np.isfinite(positions).all(axis=1)
        if bad.any():
            raise LandmarkError(f"Landmarks: {names[int(np.argmax(bad))]!r} has a NaN or infinite coordinate")
        confidence = np.array(self.confidence, dtype=np.float64).reshape(-1)
        if confidence.shape != (len(names),):
            raise ValueError(f"confidence must have shape ({len(names)},); got {confidence.shape}")
        if not np.all((confidence >= 0.0) & (confidence <= 1.0)):
            raise ValueError(
                f"confidence must be in [0, 1]; got values from {confidence.min()} to {confidence.max()}"
            )
        if self.units is not None and self.units not in UNIT_SCALE:
            raise LandmarkError(f"unknown units {self.units!r}; use one of {', '.join(UNIT_SCALE)} or None")
        for array in (positions, confidence):
            array.setflags(write=False)
        object.__setattr__(self, "names", names)
        object.__setattr__(self, "positions", positions)
        object.__setattr__(self, "confidence", confidence)
        if self.orientation is not None:
            rotation = np.array(self.orientation, dtype=np.float64)
            proper = rotation.shape == (3, 3) and np.linalg.det(rotation) > 0
            if not (proper and np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-9)):
                raise ValueError(f"orientation must be a (3, 3) rotation matrix; got {rotation.tolist()}")
            rotation.setflags(write=False)
            object.__setattr__(self, "orientation", rotation)

    def __len__(self) -> int:
        return len(self.names)

    def position(self, name: str) -> np.ndarray:
        """Position (3,) float64 of landmark ``name``, in ``units``."""
        return self.positions[self._index([name])[0]]

    def subset(self, names: Iterable[str]) -> Landmarks:
        """The landmarks ``names`` (in that order) with their positions and confidences."""
        names = list(names)
        index = self._index(names)
        return Landmarks(
            tuple(names),
            self.positions[index],
            self.confidence[index],
            self.units,
            self.source,
            self.orientation,
        )

    def as_dict(self) -> dict[str, list[float]]:
        """``{name: [x, y, z]}`` in ``units``, in ``names`` order (plain floats, JSON-ready)."""
        return {name: [float(c) for c in p] for name, p in zip(self.names, self.positions, strict=True)}

    def _index(self, names: Sequence[str]) -> list[int]:
        lookup = {n: i for i, n in enumerate(self.names)}
        missing = [n for n in names if n not in lookup]
        if missing:
            have = ", ".join(self.names[:6]) + (", …" if len(self.names) > 6 else "")
            raise LandmarkError(
                f"{', '.join(map(repr, missing))} not among these {len(self.names)} landmarks "
                f"({self.source}): {have}. Add them to the landmark file, or use the names present."
            )
        return [lookup[n] for n in names]


# ---------------------------------------------------------------------------------------------
# files


@dataclass(frozen=True)
class _Entry:
    key: str  # as written in the file
    name: str  # project name
    xyz: tuple[float, float, float]
    line: int | None  # in a CSV file; None in JSON

    @property
    def where(self) -> str:
        return "" if self.line is None else f" (line {self.line})"


def _unknown_message(unknown: Sequence[str], src: str) -> str:
    hints = []
    for key in unknown[:3]:
        close = difflib.get_close_matches(key, PROJECT_LANDMARKS, n=1)
        if close:
            hints.append(f"{key!r} → {close[0]!r}?")
    examples = ", ".join(("nose_tip", "eye_outer_corner_L", "mouth_corner_R", "menton", "nasion"))
    shown = ", ".join(map(repr, unknown[:5])) + (f" and {len(unknown) - 5} more" if len(unknown) > 5 else "")
    return (
        f"{src}: unknown landmark name{'s' if len(unknown) > 1 else ''} {shown}. "
        + (f"Did you mean {'; '.join(hints)} " if hints else "")
        + f"Use the project's names ({examples}, … {len(PROJECT_LANDMARKS)} in all: "
        "mimetic.fit.landmarks.PROJECT_LANDMARKS) or iBUG 68-point numbers as ibug68_01 … ibug68_68."
    )


def _resolve(key: str) -> str | None:
    """Project name for a file key (a project name or ``ibug68_NN``); None when unknown."""
    if key in _KNOWN:
        return key
    match = _IBUG_RE.fullmatch(key)
    if match and 1 <= int(match.group(1)) <= 68:
        return IBUG68[int(match.group(1)) - 1]
    return None


def _ibug_number(key: str) -> int | None:
    match = _IBUG_RE.fullmatch(key)
    return int(match.group(1)) if match else None


def _check_units(units: str | None, src: str, what: str) -> str | None:
    if units is None:
        return None
    if not isinstance(units, str) or units not in UNIT_SCALE:
        raise LandmarkError(
            f"{src}: unknown {what} {units!r}; use one of {', '.join(map(repr, UNIT_SCALE))}."
        )
    return units


def _coordinates(value, src: str, where: str) -> tuple[float, float, float]:
    ok = isinstance(value, (list, tuple)) and len(value) == 3
    ok = ok and all(isinstance(c, (int, float)) and not isinstance(c, bool) for c in value)
    if not ok:
        raise LandmarkError(f"{src}: {where} must be a list of 3 numbers [x, y, z]; got {value!r}")
    return float(value[0]), float(value[1]), float(value[2])


class _Pairs(list):
    """A JSON object kept as its (key, value) pairs, so repeated keys are seen."""


def _parse_json(text: str, src: str) -> tuple[list[tuple[str, object]], str | None]:
    try:
        data = json.loads(text, object_pairs_hook=_Pairs)
    except json.JSONDecodeError as error:
        raise LandmarkError(
            f"{src}: not valid JSON ({error.msg} at line {error.lineno}, column {error.colno}); "
            f"{_FORMAT_HINT}."
        ) from None
    if not isinstance(data, _Pairs):
        raise LandmarkError(
            f"{src}: the top level is a JSON {type(data).__name__}, not an object; {_FORMAT_HINT}."
        )
    top = dict(data)
    if "landmarks" not in top:
        raise LandmarkError(
            f'{src}: no "landmarks" key (found {", ".join(map(repr, top)) or "none"}); {_FORMAT_HINT}.'
        )
    pairs = top["landmarks"]
    if not isinstance(pairs, _Pairs):
        raise LandmarkError(f'{src}: "landmarks" must be an object of name: [x, y, z]; {_FORMAT_HINT}.')
    units = top.get("units")
    if units is not None and not isinstance(units, str):
        raise LandmarkError(f'{src}: "units" must be a string such as "cm" or null; got {units!r}.')
    return list(pairs), units


def _parse_csv(text: str, src: str) -> tuple[list[tuple[str, object, int]], str | None]:
    rows, units, seen_data = [], None, False
    for lineno, row in enumerate(csv.reader(io.StringIO(text)), start=1):
        cells = [c.strip() for c in row]
        if not any(cells):
            continue
        if cells[0].startswith("#"):
            match = _UNITS_RE.match(",".join(row).strip())
            if match:
                if units is not None and units != match.group(1):
                    raise LandmarkError(
                        f"{src}: line {lineno}: a second units line ({match.group(1)!r} after {units!r})"
                    )
                units = match.group(1)
            continue
        if len(cells) != 4:
            raise LandmarkError(
                f"{src}: line {lineno}: expected 4 values name,x,y,z; got {len(cells)} ({','.join(row)!r})"
            )
        try:
            xyz = [float(c) for c in cells[1:]]
        except ValueError:
            if not seen_data and cells[0].lower() == "name":
                seen_data = True  # a header row
                continue
            raise LandmarkError(
                f"{src}: line {lineno}: x, y, z must be numbers; got {','.join(cells[1:])!r}. "
                "Write rows as name,x,y,z (an optional first row name,x,y,z is a header)."
            ) from None
        seen_data = True
        rows.append((cells[0], xyz, lineno))
    return rows, units


def _read_text(path: Path, src: str) -> str:
    data = read_input(path, src, LandmarkError, "landmark")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise LandmarkError(
            f"{src}: not UTF-8 text (byte {error.start}); landmark files are JSON or CSV text."
        ) from None


def _merge(entries: list[_Entry], src: str) -> dict[str, _Entry]:
    """One entry per project name; raise on repeated keys and on aliases that disagree."""
    by_key: dict[str, _Entry] = {}
    for entry in entries:
        number = _ibug_number(entry.key)
        key = entry.key if number is None else f"ibug68_{number:02d}"  # ibug68_7 is ibug68_07
        if key in by_key:
            raise LandmarkError(
                f"{src}: {key!r} is given twice"
                + ("" if entry.line is None else f" (lines {by_key[key].line} and {entry.line})")
                + ". Keep one."
            )
        by_key[key] = entry
    groups: dict[str, list[_Entry]] = {}
    for entry in entries:
        groups.setdefault(entry.name, []).append(entry)
    points = np.array([e.xyz for e in entries]).reshape(-1, 3)
    extent = np.ptp(points, axis=0) if len(points) else np.zeros(3)
    atol = 1e-6 * float(np.linalg.norm(extent)) + 1e-12  # "the same position"
    merged = {}
    for name, group in groups.items():
        ibug = [e for e in group if _ibug_number(e.key) is not None]
        if len(ibug) > 1:  # the mouth corners: outer (49, 55) before inner (61, 65)
            keep = min(ibug, key=lambda e: _ibug_number(e.key))
            dropped = [e.key for e in ibug if e is not keep]
            log.debug("%s: %s maps to %r like %s; using %s", src, dropped, name, keep.key, keep.key)
            group = [e for e in group if e not in ibug or e is keep]
        first = group[0]
        for other in group[1:]:
            if not np.allclose(first.xyz, other.xyz, rtol=0.0, atol=atol):
                raise LandmarkError(
                    f"{src}: {name!r} is given twice with different positions: as {first.key!r} "
                    f"{list(first.xyz)}{first.where} and as {other.key!r} {list(other.xyz)}{other.where}. "
                    "Remove one of them."
                )
        merged[name] = first
    return merged


def _check_spread(names: Sequence[str], positions: np.ndarray, src: str) -> None:
    """Raise unless there are at least MIN_LANDMARKS points spanning 3D (not a line, not a plane)."""
    if len(names) < MIN_LANDMARKS:
        raise LandmarkError(
            f"{src}: only {len(names)} landmark{'s' if len(names) != 1 else ''} "
            f"({', '.join(names) or 'none'}); at least {MIN_LANDMARKS} are needed. Add well-spread points "
            "such as the eye corners, mouth corners, nose tip and menton, or run auto_landmarks on the mesh."
        )
    centred = positions - positions.mean(axis=0)
    s = np.linalg.svd(centred, compute_uv=False)  # (3,) spread along the principal axes, largest first
    if s[0] <= 1e-12 * max(1.0, float(np.abs(positions).max())):
        raise LandmarkError(
            f"{src}: all {len(names)} landmarks are at the same point {positions[0].tolist()}."
        )
    if s[1] < 0.05 * s[0]:
        raise LandmarkError(
            f"{src}: the {len(names)} landmarks lie nearly on one line (spread across it is "
            f"{s[1] / s[0]:.1%} of the spread along it). Use points spread over the face: eye corners, "
            "mouth corners, nose tip and chin."
        )
    if s[2] < 0.01 * s[0]:
        raise LandmarkError(
            f"{src}: the {len(names)} landmarks lie in one plane (depth spread {s[2] / s[0]:.2%} of their "
            "width); 3D positions on the mesh are needed. 2D image landmarks (z = 0) cannot be used: "
            "pick the points on the mesh, or run auto_landmarks."
        )


def _resolve_units(file_units: str | None, units: str | None, src: str) -> str | None:
    file_units = _check_units(file_units, src, "units in the file")
    units = _check_units(units, src, "units argument")
    if file_units is not None and units is not None and file_units != units:
        raise LandmarkError(
            f"{src}: the file says units {file_units!r} but units={units!r} was passed. "
            "Drop the argument, or fix the file's units."
        )
    return file_units or units


def read_landmarks(
    path: str | os.PathLike[str], *, units: str | None = None, mesh_units: str | None = None
) -> Landmarks:
    """Read named landmark positions from a JSON or CSV file.

    JSON: ``{"units": "cm", "landmarks": {"nose_tip": [x, y, z], "ibug68_37": [x, y, z], ...}}``
    (``units`` optional). CSV (``.csv`` or ``.txt``): one ``name,x,y,z`` row per landmark, an
    optional header row ``name,x,y,z`` and an optional ``# units: mm`` comment line. Names are
    project names (``PROJECT_LANDMARKS``) or ``ibug68_01`` … ``ibug68_68`` (1-based iBUG order).

    Parameters
    ----------
    path : path-like
        The file. ``.json`` is read as JSON, ``.csv`` / ``.txt`` as CSV; other suffixes by content.
    units : {"mm", "cm", "dm", "m"}, optional
        The file's units when it does not say; must agree with the file when it does.
    mesh_units : {"mm", "cm", "dm", "m"}, optional
        Convert the positions to these units when the file's units are known.

    Returns
    -------
    Landmarks
        ``positions`` (k, 3) float64 in ``mesh_units`` when both units are known, else in the
        file's units (``units`` None when unknown); ``confidence`` all 1.0;
        ``source`` "file:<name>"; names in file order.

    Raises
    ------
    LandmarkError
        Unreadable or corrupt file, unknown names, NaN or infinite coordinates, a landmark given
        twice with different positions, fewer than ``MIN_LANDMARKS`` landmarks, points that lie
        on a line or in a plane, unknown or conflicting units.
    """
    path = Path(path)
    src = path.name or str(path)
    text = _read_text(path, src)
    suffix = path.suffix.lower()
    is_json = suffix == ".json" or (suffix not in (".csv", ".txt") and text.lstrip().startswith("{"))
    entries, unknown = [], []
    if is_json:
        pairs, file_units = _parse_json(text, src)
        raw = [(key, value, None) for key, value in pairs]
    else:
        rows, file_units = _parse_csv(text, src)
        raw = rows
    for key, value, line in raw:
        name = _resolve(key)
        if name is None:
            unknown.append(key)
            continue
        where = "" if line is None else f" (line {line})"
        entries.append(_Entry(key, name, _coordinates(value, src, f"landmark {key!r}{where}"), line))
    if unknown:
        raise LandmarkError(_unknown_message(unknown, src))
    for entry in entries:
        if not all(math.isfinite(c) for c in entry.xyz):
            raise LandmarkError(
                f"{src}: landmark {entry.key!r}{entry.where} has a NaN or infinite coordinate "
                f"{list(entry.xyz)}. Give its position on the mesh, or leave it out."
            )
    merged = _merge(entries, src)
    names = list(merged)
    positions = np.array([merged[n].xyz for n in names], dtype=np.float64).reshape(-1, 3)
    _check_spread(names, positions, src)
    file_units = _resolve_units(file_units, units, src)
    mesh_units = _check_units(mesh_units, src, "mesh_units")
    if file_units is not None and mesh_units is not None:
        positions = convert_units(positions, file_units, mesh_units)
        file_units = mesh_units
    return Landmarks(tuple(names), positions, np.ones(len(names)), file_units, f"file:{src}")


def write_landmarks(landmarks: Landmarks, path: str | os.PathLike[str]) -> Path:
    """Write ``landmarks`` to ``path`` in the format ``read_landmarks`` reads, atomically.

    A ``.csv`` path gets ``name,x,y,z`` rows with a header (and a ``# units:`` line when known);
    any other path gets JSON ``{"units": ..., "landmarks": {name: [x, y, z]}}``. Coordinates are
    written with full precision, so reading the file back gives the same names, positions (k, 3)
    and units. Confidence, source and orientation are not stored.

    Returns
    -------
    path : Path
        The file written. A failure leaves any existing file at ``path`` untouched.
    """
    path = Path(path)
    if path.suffix.lower() == ".csv":
        lines = [f"# units: {landmarks.units}"] if landmarks.units else []
        lines.append("name,x,y,z")
        lines += [f"{n},{x!r},{y!r},{z!r}" for n, (x, y, z) in landmarks.as_dict().items()]
    else:
        items = [f"    {json.dumps(n)}: {json.dumps(p)}" for n, p in landmarks.as_dict().items()]
        body = ",\n".join(items)
        lines = ["{", f'  "units": {json.dumps(landmarks.units)},', '  "landmarks": {', body, "  }", "}"]
    with atomic_write(path, "w") as handle:
        handle.write("\n".join(lines) + "\n")
    return path
