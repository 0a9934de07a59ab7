"""MPEG-4 face animation parameters (FAPs) on the muscle rig: low-level FAPs, visemes, expressions.

MPEG-4 (ISO/IEC 14496-2) animates a face by 68 FAPs. FAPs 3-68 are *low-level*: each moves one
feature point (FP) of the neutral face along one axis, by ``value × FAPU``. The FAP units are
distances between features of the neutral face divided by 1024, measured here on the rig's rest
landmarks (``measure_fapu``)::

    IRISD0 = upper lid - lower lid (FP 3.1 - 3.3, the neutral lids touch the iris), both eyes' mean
    ES0    = pupil separation      (3.5 - 3.6, along x)
    ENS0   = eye - nose separation (pupils - 9.15, along y; 9.15 is the subnasale)
    MNS0   = mouth - nose separation (9.15 - 2.2, along y; 2.2 the inner upper lip)
    MW0    = mouth width            (2.4 - 2.5, along x: the mouth corners)
    AU     = 1e-5 rad (rotations: eyeballs, head)

"Left" and "right" in FAP names and directions are the face's own (+X is the face's left).

**Low-level FAPs** (``fap_pose``). Each supported FAP has a *driver* per direction: channel values
at full strength (``data/mpeg4.json``: open_jaw → ``jaw_open``, raise_l_cornerlip → the zygomatic
major up, the triangularis down). ``calibrate_faps`` measures, on the rig's engine, how far the
FAP's feature point moves along the FAP's axis as the driver is scaled from 0 to 1 (a monotone
response curve ``s(t)``, sampled at ``samples`` points). ``fap_pose`` inverts it,
``t = s^-1(value × FAPU)``, so a FAP alone moves its feature point by value × FAPU (within the
curve's interpolation) up to what the driver reaches at full strength. Several FAPs add their
drivers' offsets (FAPs driving the same channel add up), then every channel is clipped into range.
The eyeball FAPs 23-26 set the rig's gaze channels so that each eye turns as its FAPs say
(``gaze_yaw`` and ``gaze_pitch`` the two eyes' means, ``gaze_convergence`` and
``gaze_vertical_vergence`` their differences, within ±0.4 rad: beyond, clipped with a warning),
the head FAPs 48-50 set the head channels (1 AU = 1e-5 rad).

**Unsupported FAPs** (``UNSUPPORTED``: the tongue, which has no feature points in the rig, cheek
puffs measured sideways, ears, the nose tip, pupils, eyeball thrust, chin depression) and
directions the rig cannot produce (e.g. lowering the upper lip, narrowing a nostril) are
*ignored with a* ``MimeticWarning`` naming them and the reason, not refused: FAP streams usually
carry every parameter, and the rest of the face should still play. Unknown FAPs raise ``FapError``.

**High-level FAPs.** FAP 1 (viseme) blends two of the 14 visemes (0 = none) with
``viseme_blend`` in 0-63: ``v = v1 × blend/63 + v2 × (1 - blend/63)`` (``viseme_pose``); FAP 2
(expression) adds two of the six expressions (1 joy, 2 sadness, 3 anger, 4 fear, 5 disgust,
6 surprise) at intensities 0-63: ``e = e1 × i1/63 + e2 × i2/63`` (``fap_expression_pose``, on
the expression library). In ``fap_pose`` they give the base pose the low-level FAPs add to.
The viseme poses are this module's own tuning: the standard names visemes only by their phonemes.

Over 600 lines because the FAP table, its calibration on the rig, the visemes and the expressions
all rest on the same FAPU measurements.
"""

from __future__ import annotations

import difflib
import json
import logging
import math
import warnings
import weakref
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from importlib import resources
from types import MappingProxyType

import numpy as np

from mimetic.animate.expressions import ExpressionLibrary, blend
from mimetic.engines import Engine
from mimetic.engines.basis import Basis
from mimetic.errors import MimeticError, MimeticWarning
from mimetic.rig.activations import check_activations
from mimetic.rig.model import Rig

log = logging.getLogger(__name__)

FORMAT = "mimetic-mpeg4"
VERSION = 1
AU_RAD = 1e-5
"""The angular FAP unit, in radians."""
FAPU_NAMES = ("IRISD", "ES", "ENS", "MNS", "MW", "AU")
DIRECTIONS = MappingProxyType(
    {
        "up": (0.0, 1.0, 0.0),
        "down": (0.0, -1.0, 0.0),
        "left": (1.0, 0.0, 0.0),
        "right": (-1.0, 0.0, 0.0),
        "forward": (0.0, 0.0, 1.0),
    }
)
"""Unit axes of the FAP directions (the face's own left is +X)."""
REACH_TOLERANCE = 0.02
"""Values up to this fraction beyond the rig's reach are clipped silently (a full eyelid closure,
1024 IRISD, reaches 99 % of the lid gap on the generated head)."""
BLEND_MAX = 63
"""Full scale of viseme_blend and expression_intensity (6-bit fields)."""


class FapError(MimeticError, ValueError):
    """An unknown FAP, viseme or expression, or a FAP value that is not a finite number."""


@dataclass(frozen=True)
class Fap:
    """One low-level FAP of the table.

    Attributes
    ----------
    number : int
        3-68.
    name : str
        The standard's name, e.g. "raise_l_cornerlip".
    fapu : "IRISD" | "ES" | "ENS" | "MNS" | "MW" | "AU"
    bidirectional : bool
        False for the FAPs that take positive values only (open_jaw, thrust_jaw, lift_*_cheek).
    positive : str
        Direction of positive values ("up", "down", "left", "right", "forward", ...).
    feature_point : str
        The FP it moves, "group.index" (e.g. "2.4").
    kind : "displacement" | "gaze" | "rotation" | "unsupported"
    drivers : Mapping[str, Mapping[str, float]]
        "+" and/or "-" → channel values at full strength (displacement FAPs).
    rotation : Mapping[str, float]
        Channel → radians per radian of the FAP (head FAPs).
    gaze : str
        "yaw_L", "yaw_R", "pitch_L" or "pitch_R" (eyeball FAPs).
    note : str
        Why the FAP (or its missing direction) is unsupported.
    """

    number: int
    name: str
    fapu: str
    bidirectional: bool
    positive: str
    feature_point: str
    kind: str
    drivers: Mapping[str, Mapping[str, float]]
    rotation: Mapping[str, float]
    gaze: str = ""
    note: str = ""

    @property
    def axis(self) -> np.ndarray:
        """Unit vector (3,) of the positive direction."""
        return np.array(DIRECTIONS[self.positive])


@dataclass(frozen=True)
class Viseme:
    number: int
    phonemes: tuple[str, ...]
    example: str
    description: str
    values: Mapping[str, float]


@dataclass(frozen=True)
class _Tables:
    faps: Mapping[int, Fap]
    feature_points: Mapping[str, object]
    visemes: tuple[Viseme, ...]
    expressions: Mapping[int, str]


def _values(raw: object, where: str) -> dict[str, float]:
    if not isinstance(raw, dict):
        raise FapError(f"{where}: expected an object of channel → number")
    out = {}
    for channel, value in raw.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise FapError(f"{where}: channel {channel!r} = {value!r} is not a finite number")
        out[str(channel)] = float(value)
    return out


def _parse(data: object, source: str) -> _Tables:
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise FapError(f"{source}: not a {FORMAT!r} file")
    if not isinstance(data.get("version"), int) or data["version"] > VERSION:
        raise FapError(f"{source}: format version {data.get('version')!r} is newer than {VERSION}")
    points = data.get("feature_points", {})
    faps = {}
    for entry in data.get("faps", ()):
        number, name = int(entry["fap"]), str(entry["name"])
        where = f"{source}: FAP {number} ({name})"
        if entry["fapu"] not in FAPU_NAMES:
            raise FapError(f"{where}: unit {entry['fapu']!r} is not one of {FAPU_NAMES}")
        positive = str(entry["positive"])
        drivers = {
            k: MappingProxyType(_values(v, f"{where}.drivers.{k}"))
            for k, v in entry.get("drivers", {}).items()
        }
        rotation = _values(entry.get("rotation", {}), f"{where}.rotation")
        if "unsupported" in entry:
            kind, note = "unsupported", str(entry["unsupported"])
        elif drivers:
            kind, note = "displacement", str(entry.get("missing", ""))
            if set(drivers) - {"+", "-"} or positive not in DIRECTIONS or entry["fp"] not in points:
                raise FapError(
                    f"{where}: drivers are '+'/'-', the direction one of {list(DIRECTIONS)}, the FP mapped"
                )
            if entry["bidirectional"] and len(drivers) == 1 and not note:
                raise FapError(f"{where}: a bidirectional FAP with one driver needs 'missing' (the reason)")
        elif rotation:
            kind, note = "rotation", ""
        elif entry.get("gaze") in ("yaw_L", "yaw_R", "pitch_L", "pitch_R"):
            kind, note = "gaze", ""
        else:
            raise FapError(f"{where}: give 'drivers', 'rotation', 'gaze' or 'unsupported'")
        faps[number] = Fap(
            number,
            name,
            entry["fapu"],
            bool(entry["bidirectional"]),
            positive,
            str(entry["fp"]),
            kind,
            MappingProxyType(drivers),
            MappingProxyType(rotation),
            str(entry.get("gaze", "")),
            note,
        )
    if sorted(faps) != list(range(3, 69)):
        raise FapError(f"{source}: 'faps' must list FAPs 3-68 once each")
    visemes = tuple(
        Viseme(
            int(v["viseme"]),
            tuple(v["phonemes"]),
            str(v.get("example", "")),
            str(v.get("description", "")),
            MappingProxyType(_values(v["values"], f"{source}: viseme {v['viseme']}")),
        )
        for v in data.get("visemes", ())
    )
    if [v.number for v in visemes] != list(range(15)):
        raise FapError(f"{source}: 'visemes' must list visemes 0-14 in order")
    expressions = {int(k): str(v) for k, v in data.get("expressions", {}).items()}
    if sorted(expressions) != list(range(1, 7)):
        raise FapError(f"{source}: 'expressions' must map 1-6 to expression names")
    return _Tables(MappingProxyType(faps), MappingProxyType(points), visemes, MappingProxyType(expressions))


@cache
def _tables() -> _Tables:
    text = resources.files("mimetic.animate").joinpath("data/mpeg4.json").read_text("utf-8")
    return _parse(json.loads(text), "mpeg4.json")


def fap_table() -> Mapping[int, Fap]:
    """FAPs 3-68 by number (read once from ``data/mpeg4.json``)."""
    return _tables().faps


def visemes() -> tuple[Viseme, ...]:
    """The 15 visemes of FAP 1 (0 = none, 1-14 as in the standard), in order."""
    return _tables().visemes


EXPRESSIONS: Mapping[int, str] = _tables().expressions
"""FAP 2's expressions: 1 joy, 2 sadness, 3 anger, 4 fear, 5 disgust, 6 surprise (library names)."""
UNSUPPORTED: Mapping[int, str] = MappingProxyType(
    {f.number: f.note for f in fap_table().values() if f.kind == "unsupported"}
)
"""FAP number → why the rig cannot produce it (such FAPs are ignored with a warning)."""
ONE_WAY: Mapping[int, str] = MappingProxyType(
    {f.number: f.note for f in fap_table().values() if f.kind == "displacement" and f.note}
)
"""Bidirectional FAPs with one direction only → why the other is missing."""


def fap(key: int | str) -> Fap:
    """A FAP by number (3-68) or name ("open_jaw"); ``FapError`` with suggestions otherwise."""
    table = fap_table()
    if isinstance(key, (int, np.integer)) and not isinstance(key, bool):
        if int(key) in table:
            return table[int(key)]
        if int(key) in (1, 2):
            raise FapError(f"FAP {key} is high-level: pass viseme=... or expression=... (see fap_pose)")
        raise FapError(f"unknown FAP {key}; low-level FAPs are numbered 3-68")
    if isinstance(key, str):
        names = {f.name: f for f in table.values()}
        text = key.strip()
        if text.isdigit():
            return fap(int(text))
        if text.lower() in names:
            return names[text.lower()]
        close = difflib.get_close_matches(text.lower(), list(names), n=3)
        hint = f"did you mean {', '.join(close)}?" if close else "see mimetic.animate.mpeg4.fap_table()"
        raise FapError(f"unknown FAP {key!r}; {hint}")
    raise FapError(f"a FAP is a number (3-68) or a name; got {key!r}")


# ---- FAP units and feature points


@dataclass(frozen=True)
class Fapu:
    """The neutral face's FAPU reference distances (rig units); ``unit(name)`` is one FAPU.

    Attributes
    ----------
    irisd0, es0, ens0, mns0, mw0 : float
        Lid separation, pupil separation, eye-nose, mouth-nose separation and mouth width.
    """

    irisd0: float
    es0: float
    ens0: float
    mns0: float
    mw0: float

    def unit(self, name: str) -> float:
        """One FAPU: the reference distance / 1024 (rig units), or AU_RAD for "AU"."""
        if name == "AU":
            return AU_RAD
        return {"IRISD": self.irisd0, "ES": self.es0, "ENS": self.ens0, "MNS": self.mns0, "MW": self.mw0}[
            name
        ] / 1024.0


def _feature_point_vertices(rig: Rig) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """FP → (vertex ids (3,), barycentric weights (3,)) on the rig's mesh."""
    out = {}
    f = rig.mesh.faces
    for fp, where in _tables().feature_points.items():
        if isinstance(where, str):
            if where not in rig.landmarks:
                continue
            point = rig.landmarks[where]
            out[fp] = (f[point.face].copy(), np.asarray(point.bary, dtype=np.float64))
            continue
        anchor = where["near"]
        if anchor not in rig.landmarks:
            continue
        target = rig.landmark_positions([anchor])[0] + rig.scale * np.asarray(where["offset_rel"])
        ids = rig.regions.get(where.get("region", ""), np.arange(rig.n_vertices))
        nearest = int(ids[np.argmin(np.linalg.norm(rig.mesh.vertices[ids] - target, axis=1))])
        out[fp] = (np.array([nearest, nearest, nearest]), np.array([1.0, 0.0, 0.0]))
    return out


def _positions(
    vertices: np.ndarray, points: Mapping[str, tuple[np.ndarray, np.ndarray]]
) -> dict[str, np.ndarray]:
    return {fp: w @ vertices[ids] for fp, (ids, w) in points.items()}


def feature_point_positions(rig: Rig, vertices: np.ndarray | None = None) -> dict[str, np.ndarray]:
    """Positions (3,) of the MPEG-4 feature points the rig has, on ``vertices`` (n, 3) (default: rest).

    Keys are "group.index" ("2.1" chin, "2.4" left mouth corner, ...); most are rig landmarks
    (``data/mpeg4.json``), the cheek points 5.3/5.4 the cheek vertex 0.065 head heights below
    the lower lid.
    """
    v = rig.mesh.vertices if vertices is None else np.asarray(vertices, dtype=np.float64)
    if v.shape != (rig.n_vertices, 3):
        raise FapError(f"vertices must have shape ({rig.n_vertices}, 3); got {v.shape}")
    return _positions(v, _feature_point_vertices(rig))


def measure_fapu(rig: Rig) -> Fapu:
    """The FAPU reference distances of a rig's rest landmarks (see the module docstring)."""
    p = _positions(rig.mesh.vertices, _feature_point_vertices(rig))
    need = ("3.1", "3.2", "3.3", "3.4", "3.5", "3.6", "9.15", "2.2", "2.4", "2.5")
    missing = [fp for fp in need if fp not in p]
    if missing:
        names = [str(_tables().feature_points[fp]) for fp in missing]
        raise FapError(f"the rig lacks the landmarks {', '.join(names)} needed for the FAP units")
    irisd0 = 0.5 * ((p["3.1"][1] - p["3.3"][1]) + (p["3.2"][1] - p["3.4"][1]))
    pupils_y = 0.5 * (p["3.5"][1] + p["3.6"][1])
    fapu = Fapu(
        float(irisd0),
        float(p["3.5"][0] - p["3.6"][0]),
        float(pupils_y - p["9.15"][1]),
        float(p["9.15"][1] - p["2.2"][1]),
        float(p["2.4"][0] - p["2.5"][0]),
    )
    bad = [
        n
        for n, v in zip(("IRISD0", "ES0", "ENS0", "MNS0", "MW0"), vars(fapu).values(), strict=True)
        if v <= 0
    ]
    if bad:
        raise FapError(
            f"FAP units {', '.join(bad)} are not positive: is the face upright (+Y up, looking +Z)?"
        )
    return fapu


# ---- calibration


@dataclass(frozen=True, eq=False)
class FapCalibration:
    """A rig's FAP units and the measured response of every supported low-level FAP.

    Attributes
    ----------
    channels : tuple of str
        The rig's channel names (the order of the driver vectors).
    fapu : Fapu
    curves : Mapping[(int, str), ((k,) float64, (k,) float64)]
        (FAP number, "+" or "-") → (driver scale t in [0, 1], feature point motion s(t) along the
        FAP's direction for "+" or against it for "-", rig units, non-decreasing).
    drivers : Mapping[(int, str), (c,) float64]
        The channel offsets at t = 1.
    n_vertices : int
        The rig's vertex count (with ``channels`` and ``fapu``, what ``fap_pose`` checks).
    """

    channels: tuple[str, ...]
    fapu: Fapu
    curves: Mapping[tuple[int, str], tuple[np.ndarray, np.ndarray]]
    drivers: Mapping[tuple[int, str], np.ndarray]
    n_vertices: int

    def reach(self, number: int, direction: str = "+") -> float:
        """The largest |value| (in the FAP's units) the rig reaches in one direction (0 if none)."""
        curve = self.curves.get((number, direction))
        return 0.0 if curve is None else float(curve[1][-1]) / self.fapu.unit(fap(number).fapu)

    def offset(self, number: int, value: float) -> tuple[np.ndarray, str]:
        """Channel offsets (c,) of one displacement FAP at ``value`` and a problem ("" if none)."""
        spec = fap(number)
        direction = "+" if value >= 0 else "-"
        out = np.zeros(len(self.channels))
        if value == 0:
            return out, ""
        if (number, direction) not in self.curves:
            reason = spec.note or (
                "it takes positive values only"
                if not spec.bidirectional
                else "no driver moves its feature point"
            )
            return out, f"{spec.name} {'+' if value > 0 else '-'}: {reason}"
        t, s = self.curves[(number, direction)]
        target = abs(value) * self.fapu.unit(spec.fapu)
        problem = ""
        if target > s[-1] * (1 + REACH_TOLERANCE):
            problem = (
                f"{spec.name} = {value:g} exceeds what the rig reaches ({self.reach(number, direction):.4g})"
            )
        return float(np.interp(target, s, t)) * self.drivers[(number, direction)], problem


Deform = Callable[[np.ndarray], np.ndarray]
"""Vertex positions (n, 3) of one pose (c,) in the rig's channel order: ``engine.deform``, or a
baked basis evaluated (``evaluate_basis``)."""


def _deform(rig: Rig, engine: str | Engine | Basis | Deform) -> Deform:
    """``engine`` as a deform function: a named engine is made for ``rig``, a basis evaluated."""
    if isinstance(engine, str):
        from mimetic.engines import make_engine

        return make_engine(rig, engine).deform
    if isinstance(engine, Basis):
        from mimetic.engines.basis import evaluate_basis

        return lambda values: evaluate_basis(engine, values)
    deform = getattr(engine, "deform", engine)
    if not callable(deform):
        raise FapError(
            f"engine={engine!r}: give an engine name, an engine, a baked Basis or a deform function"
        )
    return deform


def calibrate_faps(
    rig: Rig, *, engine: str | Engine | Basis | Deform = "wire", samples: int = 13
) -> FapCalibration:
    """Measure the response of every supported low-level FAP on ``rig``.

    Each driver is scaled to ``samples`` values of t in [0, 1]; ``engine`` deforms the rig and the
    FAP's feature point motion along its axis is recorded (about ``samples`` × 60 evaluations; 1-2 s
    on a 13k-vertex head with the wire engine, a fraction of that on a baked basis). ``engine`` is an
    engine's name (made here), an engine, a baked ``Basis`` or any deform function (pose → vertices).
    Driver values outside a channel's range are clipped.
    """
    if samples < 2:
        raise FapError(f"samples={samples} must be at least 2")
    deform = _deform(rig, engine)
    channels = rig.channel_names
    index = {n: j for j, n in enumerate(channels)}
    base = np.array([c.default for c in rig.channels], dtype=np.float64)
    points = _feature_point_vertices(rig)
    fapu = measure_fapu(rig)
    ts = np.linspace(0.0, 1.0, samples)
    rest = _positions(deform(base), points)
    groups: dict[tuple, list[tuple[int, str]]] = {}
    vectors: dict[tuple[int, str], np.ndarray] = {}
    for spec in fap_table().values():
        if spec.kind != "displacement" or spec.feature_point not in points:
            continue
        for direction, values in spec.drivers.items():
            vector = np.zeros(len(channels))
            for channel, value in values.items():
                if channel not in index:
                    break
                vector[index[channel]] = value
            else:
                key = tuple(np.round(vector, 12))
                groups.setdefault(key, []).append((spec.number, direction))
                vectors[(spec.number, direction)] = vector
    curves = {}
    drivers = {}
    for members in groups.values():
        vector = vectors[members[0]]
        moved = [_positions(deform(check_activations(rig, base + t * vector, clip=True)), points) for t in ts]
        clipped = check_activations(rig, base + vector, clip=True) - base
        for number, direction in members:
            spec = fap_table()[number]
            sign = 1.0 if direction == "+" else -1.0
            fp = spec.feature_point
            s = np.array([sign * (m[fp] - rest[fp]) @ spec.axis for m in moved])
            s = np.maximum.accumulate(np.maximum(s, 0.0))
            if s[-1] <= 1e-9 * rig.scale:
                log.debug("FAP %d %s: the driver does not move FP %s", number, direction, fp)
                continue
            curves[(number, direction)] = (ts, s)
            drivers[(number, direction)] = clipped
    log.debug("calibrated %d FAP directions with %d drivers", len(curves), len(groups))
    return FapCalibration(channels, fapu, MappingProxyType(curves), MappingProxyType(drivers), rig.n_vertices)


_CALIBRATIONS: dict[tuple[int, str], FapCalibration] = {}


def _calibration(rig: Rig, engine: str) -> FapCalibration:
    """The calibration of ``rig`` with a named engine, computed once per rig object."""
    key = (id(rig), engine)
    if key not in _CALIBRATIONS:
        _CALIBRATIONS[key] = calibrate_faps(rig, engine=engine)
        weakref.finalize(rig, _CALIBRATIONS.pop, key, None)
    return _CALIBRATIONS[key]


# ---- high-level FAPs


def _viseme(key: int | str) -> Viseme:
    table = visemes()
    if isinstance(key, (int, np.integer)) and not isinstance(key, bool) and 0 <= int(key) < len(table):
        return table[int(key)]
    if isinstance(key, str):
        for v in table:
            if key.strip() in v.phonemes:
                return v
    phonemes = ", ".join(f"{v.number}: {'/'.join(v.phonemes) or 'none'}" for v in table)
    raise FapError(f"unknown viseme {key!r}; use 0-14 or a phoneme ({phonemes})")


def _fraction(value: float, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise FapError(f"{where} must be a number in [0, {BLEND_MAX}]; got {value!r}")
    number = float(value)
    if not (math.isfinite(number) and 0.0 <= number <= BLEND_MAX):
        raise FapError(f"{where} = {number:g} must lie in [0, {BLEND_MAX}]")
    return number / BLEND_MAX


def _add(rig: Rig, out: np.ndarray, values: Mapping[str, float], scale: float, what: str) -> None:
    index = {n: j for j, n in enumerate(rig.channel_names)}
    for channel, value in values.items():
        if channel not in index:
            raise FapError(f"{what} drives channel {channel!r}, which this rig does not have")
        out[index[channel]] += scale * value


def viseme_pose(rig: Rig, viseme1: int | str, viseme2: int | str = 0, blend: float = BLEND_MAX) -> np.ndarray:
    """FAP 1: a pose (c,) blending two visemes, ``v1 × blend/63 + v2 × (1 - blend/63)``, clipped.

    Visemes are 0-14 (0 = none) or one of their phonemes ("p", "A:", "tS", ...).
    """
    b = _fraction(blend, "viseme_blend")
    out = np.array([c.default for c in rig.channels], dtype=np.float64)
    for key, weight in ((viseme1, b), (viseme2, 1.0 - b)):
        v = _viseme(key)
        _add(rig, out, v.values, weight, f"viseme {v.number}")
    return check_activations(rig, out, clip=True)


def fap_expression_pose(
    rig: Rig,
    expression1: int | str,
    intensity1: float = BLEND_MAX,
    expression2: int | str = 0,
    intensity2: float = 0,
    *,
    library: ExpressionLibrary | None = None,
) -> np.ndarray:
    """FAP 2: a pose (c,) adding two expressions, ``e1 × i1/63 + e2 × i2/63`` (the library's blend).

    Expressions are 0 (none), 1 joy, 2 sadness, 3 anger, 4 fear, 5 disgust, 6 surprise, or those
    names; intensities lie in [0, 63].
    """
    items = []
    for key, intensity, where in ((expression1, intensity1, "1"), (expression2, intensity2, "2")):
        weight = _fraction(intensity, f"expression_intensity{where}")
        if isinstance(key, str) and not key.strip().isdigit():
            name = key.strip()
            if name not in EXPRESSIONS.values():
                raise FapError(
                    f"unknown MPEG-4 expression {key!r}; use {', '.join(EXPRESSIONS.values())} or 1-6"
                )
        else:
            number = int(key)
            if number == 0:
                continue
            if number not in EXPRESSIONS:
                raise FapError(f"unknown MPEG-4 expression {key!r}; use 0-6 (1 joy … 6 surprise)")
            name = EXPRESSIONS[number]
        items.append((name, weight))
    return blend(rig, items, library=library)


# ---- the pose


def _gaze(values: Mapping[str, float]) -> dict[str, float]:
    """Gaze channels from eyeball FAP angles (rad, FAP signs): each eye's turn exactly, as
    ``engines.skinning`` composes it from the shared and the difference channels."""
    yaw_l, yaw_r = values.get("yaw_L", 0.0), values.get("yaw_R", 0.0)  # + = to the face's left
    out: dict[str, float] = {}
    if "yaw_L" in values or "yaw_R" in values:
        out["gaze_yaw"] = 0.5 * (yaw_l + yaw_r)
        out["gaze_convergence"] = yaw_r - yaw_l  # > 0: both eyes turn toward the nose
    if "pitch_L" in values or "pitch_R" in values:
        pitch_l, pitch_r = values.get("pitch_L", 0.0), values.get("pitch_R", 0.0)  # + = down
        out["gaze_pitch"] = -0.5 * (pitch_l + pitch_r)
        out["gaze_vertical_vergence"] = pitch_r - pitch_l  # > 0: the left eye higher
    return out


def fap_pose(
    rig: Rig,
    faps: Mapping[int | str, float | Sequence[float]],
    *,
    viseme: Sequence[int | str | float] | None = None,
    expression: Sequence[int | str | float] | None = None,
    calibration: FapCalibration | None = None,
    engine: str = "wire",
) -> np.ndarray:
    """A pose (c,) float64 from MPEG-4 FAPs.

    Parameters
    ----------
    rig : Rig
    faps : Mapping[int | str, float]
        Low-level FAP number or name → value in its FAPU (e.g. ``{"open_jaw": 300, 12: 120}``).
        Key 1 / "viseme" and 2 / "expression" may hold the high-level tuples below.
    viseme : (viseme1, viseme2, blend), optional
        FAP 1 (see ``viseme_pose``); ``(viseme1,)`` means blend 63.
    expression : (expression1, intensity1, expression2, intensity2), optional
        FAP 2 (see ``fap_expression_pose``).
    calibration : FapCalibration, optional
        From ``calibrate_faps(rig)``; by default made once per rig object with ``engine``.

    Returns
    -------
    pose : (c,) float64: the high-level base pose plus every low-level FAP's offset, clipped.

    Unsupported FAPs, missing directions and values beyond the rig's reach give one
    ``MimeticWarning`` listing them; the rest of the pose is still made.
    """
    low: dict[int, float] = {}
    for key, value in faps.items():
        if key in (1, "1", "viseme", 2, "2", "expression"):
            fields = tuple(value) if isinstance(value, Sequence) and not isinstance(value, str) else (value,)
            if key in (1, "1", "viseme"):
                viseme = fields
            else:
                expression = fields
            continue
        spec = fap(key)
        if spec.number in low:
            raise FapError(f"FAP {spec.number} ({spec.name}) is given twice")
        if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
            raise FapError(f"FAP {spec.name}: value {value!r} must be a number (in {spec.fapu} units)")
        if not math.isfinite(float(value)):
            raise FapError(f"FAP {spec.name}: value {value!r} is not finite")
        low[spec.number] = float(value)
    out = np.array([c.default for c in rig.channels], dtype=np.float64)
    if viseme is not None:
        out = viseme_pose(rig, *viseme)
    if expression is not None:
        out = out + fap_expression_pose(rig, *expression) - np.array([c.default for c in rig.channels])
    problems = []
    gaze: dict[str, float] = {}
    needs_calibration = any(fap_table()[n].kind == "displacement" and v for n, v in low.items())
    if needs_calibration and calibration is None:
        calibration = _calibration(rig, engine)
    if needs_calibration and (
        calibration.channels != rig.channel_names
        or calibration.n_vertices != rig.n_vertices
        or calibration.fapu != measure_fapu(rig)
    ):
        raise FapError("the calibration was made for another rig; pass calibrate_faps(rig)")
    for number, value in low.items():
        spec = fap_table()[number]
        if value == 0:
            continue
        if spec.kind == "unsupported":
            problems.append(f"{spec.name}: {spec.note}")
        elif spec.kind == "rotation":
            _add(rig, out, spec.rotation, value * AU_RAD, f"FAP {spec.name}")
        elif spec.kind == "gaze":
            gaze[spec.gaze] = value * AU_RAD
        else:
            offset, problem = calibration.offset(number, value)
            out += offset
            if problem:
                problems.append(problem)
    if gaze:
        values = _gaze(gaze)
        _add(rig, out, values, 1.0, "the eyeball FAPs")
        beyond = [c for c, x in values.items() if not rig.channel(c).minimum <= x <= rig.channel(c).maximum]
        if beyond:
            problems.append(f"the eyeball FAPs turn the eyes beyond {', '.join(beyond)}'s range; clipped")
    if problems:
        warnings.warn("FAPs not (fully) realised: " + "; ".join(problems), MimeticWarning, stacklevel=2)
    return check_activations(rig, out, clip=True)
