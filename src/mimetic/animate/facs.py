"""FACS action units as a control layer: ``facs_pose(rig, {"AU12_L": 0.8, "AU26": "C"})``.

Each action unit (AU) of the Facial Action Coding System (Ekman, Friesen & Hager 2002) is a row
of ``data/facs.json``: its number, name, muscular basis and the channel values that realise it
at intensity E (1.0). A pose adds the AUs' values scaled by their intensities to the rig's
defaults and clips every channel into its range::

    p = clip(d + sum_k i_k v_k, channel minimum, channel maximum)

**Sides.** A sided AU's values name ``{side}`` channels (``"zygomatic_major_{side}"``). "AU12_L"
uses the left values (the subject's own left, +X, as everywhere in mimetic), "AU12_R" the right
ones, and plain "AU12" both: the sum of the two sides, so a midline channel listed in a sided AU
(the procerus in AU4) counts once per side. AUs that act on the midline only (AU17, AU26, ...)
have no sides; a few make sense only on one side (AU46 wink, AU30 jaw sideways).

**Codes.** A key may be "AU12", "12", 12, "AU12L", "AU12_L", "12L" or FACS's own prefix form
"L12" / "R12" (case-insensitive). **Intensities** are numbers in [0, 1] or the FACS letters
A-E, read as 0.2, 0.4, 0.6, 0.8 and 1.0 (OpenFace's 1-5 scale divided by 5; the manual's letter
intervals are unequal, C and D the widest, which this linear reading ignores).

AUs the rig cannot produce at all (AU19 tongue show, AU33 cheek blow, ...) are in the table with
the reason; asking for one raises ``FacsError`` with that reason, as does an unknown AU.
"""

from __future__ import annotations

import difflib
import json
import math
import re
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from importlib import resources
from types import MappingProxyType

import numpy as np

from mimetic.errors import MimeticError
from mimetic.rig.activations import check_activations
from mimetic.rig.model import Rig

FORMAT = "mimetic-facs"
VERSION = 1
SIDES = ("L", "R")
INTENSITY_LETTERS = MappingProxyType({"A": 0.2, "B": 0.4, "C": 0.6, "D": 0.8, "E": 1.0})
"""FACS intensity letters as fractions of the maximum (E = 1)."""

_KEY = re.compile(r"^\s*(?:AU)?\s*([LR])?\s*(\d{1,2})\s*(?:_?\s*([LR]))?\s*$", re.IGNORECASE)
_CODE = re.compile(r"^\s*(?:AU)?\s*([LR])?\s*(\d{1,2})\s*([A-E])?\s*(?:_?\s*([LR]))?\s*$", re.IGNORECASE)
_ENTRY_KEYS = frozenset({"name", "muscles", "sides", "values", "by_side", "status", "note", "unsupported"})


class FacsError(MimeticError, ValueError):
    """An unknown or unsupported action unit, a malformed code, or an intensity out of range."""


@dataclass(frozen=True)
class ActionUnit:
    """One row of the FACS table.

    Attributes
    ----------
    number : int
        The AU number, e.g. 12.
    name : str
        FACS's name, e.g. "Lip corner puller".
    muscles : str
        The muscular basis named by the FACS manual.
    sides : "optional" | "none" | "required"
        "optional": "AU12", "AU12_L" and "AU12_R" all exist; "none": midline only (AU17);
        "required": one side only (AU46 wink).
    values : Mapping[str, Mapping[str, float]]
        Channel values at intensity E for each side key: "" (both sides), "L" and "R" (those
        that ``sides`` allows).
    status : "exact" | "approximate" | "unsupported"
    note : str
        How the rig realises the AU when it is approximate, or why it cannot (unsupported).
    """

    number: int
    name: str
    muscles: str
    sides: str
    values: Mapping[str, Mapping[str, float]]
    status: str = "exact"
    note: str = ""

    @property
    def supported(self) -> bool:
        return self.status != "unsupported"

    def code(self, side: str = "") -> str:
        """The canonical key: "AU12", "AU12_L"."""
        return f"AU{self.number}" + (f"_{side}" if side else "")


def _channel_values(raw: object, where: str) -> dict[str, float]:
    if not isinstance(raw, dict) or not raw:
        raise FacsError(f"{where}: expected a non-empty object of channel → number")
    out = {}
    for channel, value in raw.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise FacsError(f"{where}: channel {channel!r} = {value!r} is not a finite number")
        out[str(channel)] = float(value)
    return out


def _by_side(values: dict[str, float], side: str) -> dict[str, float]:
    return {channel.replace("{side}", side): value for channel, value in values.items()}


def _add(total: dict[str, float], values: Mapping[str, float]) -> dict[str, float]:
    for channel, value in values.items():
        total[channel] = total.get(channel, 0.0) + value
    return total


def _parse_unit(key: str, entry: object, source: str) -> ActionUnit:
    where = f"{source}: AU {key!r}"
    if not key.isdigit():
        raise FacsError(f'{where}: keys are AU numbers, e.g. "12"')
    if not isinstance(entry, dict) or not isinstance(entry.get("name"), str):
        raise FacsError(f"{where}: expected an object with a 'name'")
    extra = sorted(set(entry) - _ENTRY_KEYS)
    if extra:
        raise FacsError(f"{where}: unknown key(s) {', '.join(map(repr, extra))}; use {sorted(_ENTRY_KEYS)}")
    number, name, muscles = int(key), entry["name"], str(entry.get("muscles", ""))
    if "unsupported" in entry:
        return ActionUnit(
            number, name, muscles, "none", MappingProxyType({}), "unsupported", entry["unsupported"]
        )
    if ("values" in entry) == ("by_side" in entry):
        raise FacsError(f"{where}: give either 'values' (with '{{side}}' channels if sided) or 'by_side'")
    if "by_side" in entry:
        raw = entry["by_side"]
        if not isinstance(raw, dict) or set(raw) != set(SIDES):
            raise FacsError(f"{where}: 'by_side' must hold exactly 'L' and 'R'")
        sided = {s: _channel_values(raw[s], f"{where}.by_side.{s}") for s in SIDES}
        bilateral = _add(_add({}, sided["L"]), sided["R"])
    else:
        values = _channel_values(entry["values"], f"{where}.values")
        templated = any("{side}" in c for c in values)
        sided = {s: _by_side(values, s) for s in SIDES} if templated else {}
        bilateral = _add(_add({}, sided["L"]), sided["R"]) if templated else values
    default_sides = "optional" if sided else "none"
    sides = entry.get("sides", default_sides)
    if sides not in ("optional", "none", "required"):
        raise FacsError(f"{where}: 'sides' is {sides!r}; use 'optional', 'none' or 'required'")
    if sides != "none" and not sided:
        raise FacsError(f"{where}: sided AUs need '{{side}}' channels in 'values', or 'by_side'")
    table: dict[str, Mapping[str, float]] = {}
    if sides != "required":
        table[""] = MappingProxyType(bilateral)
    if sides != "none":
        for s in SIDES:
            table[s] = MappingProxyType(sided[s])
    status = entry.get("status", "exact")
    if status not in ("exact", "approximate"):
        raise FacsError(f"{where}: 'status' is {status!r}; use 'exact' or 'approximate'")
    return ActionUnit(
        number, name, muscles, sides, MappingProxyType(table), status, str(entry.get("note", ""))
    )


def _parse_table(data: object, source: str) -> dict[int, ActionUnit]:
    if not isinstance(data, dict) or data.get("format") != FORMAT:
        raise FacsError(f"{source}: not a {FORMAT!r} file")
    if not isinstance(data.get("version"), int) or data["version"] > VERSION:
        raise FacsError(
            f"{source}: format version {data.get('version')!r} is newer than {VERSION}; upgrade mimetic"
        )
    entries = data.get("action_units")
    if not isinstance(entries, dict) or not entries:
        raise FacsError(f"{source}: 'action_units' must be a non-empty object")
    units = [_parse_unit(key, entry, source) for key, entry in entries.items()]
    return {u.number: u for u in sorted(units, key=lambda u: u.number)}


@cache
def action_units() -> Mapping[int, ActionUnit]:
    """The built-in FACS table (``data/facs.json``), AU number → ActionUnit, read once."""
    text = resources.files("mimetic.animate").joinpath("data/facs.json").read_text("utf-8")
    return MappingProxyType(_parse_table(json.loads(text), "facs.json"))


def action_unit(number: int) -> ActionUnit:
    """The table's row for AU ``number``; ``FacsError`` names the nearest AUs when it is unknown."""
    units = action_units()
    if number not in units:
        near = sorted(units, key=lambda n: abs(n - number))[:3]
        raise FacsError(
            f"unknown action unit AU{number}; the table has AU{', AU'.join(map(str, units))} "
            f"(nearest: AU{', AU'.join(map(str, near))})"
        )
    return units[number]


def parse_key(key: str | int) -> tuple[int, str]:
    """(AU number, side) of a key: "AU12" → (12, ""), "AU12_L" / "AU12L" / "L12" → (12, "L")."""
    if isinstance(key, bool) or not isinstance(key, (str, int, np.integer)):
        raise FacsError(f"action unit key {key!r} must be a string like 'AU12_L' or an AU number")
    match = _KEY.match(str(key))
    if not match or (match.group(1) and match.group(3)):
        raise FacsError(
            f"cannot read action unit {key!r}; write 'AU12', '12', 'AU12_L', 'AU12L' or 'L12' "
            "(an intensity goes in the value, not the key)"
        )
    side = (match.group(1) or match.group(3) or "").upper()
    return int(match.group(2)), side


def intensity(value: float | str, where: str = "intensity") -> float:
    """An intensity in [0, 1]: a number, or a FACS letter A-E (0.2 … 1.0)."""
    if isinstance(value, str):
        letter = value.strip().upper()
        if letter not in INTENSITY_LETTERS:
            raise FacsError(f"{where}: {value!r} is not a FACS intensity; use A-E or a number in [0, 1]")
        return INTENSITY_LETTERS[letter]
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise FacsError(f"{where}: {value!r} must be a number in [0, 1] or a letter A-E")
    number = float(value)
    if not math.isfinite(number) or not -1e-9 <= number <= 1.0 + 1e-9:
        hint = " (divide OpenFace's 0-5 intensities by 5)" if 1.0 < number <= 5.0 else ""
        raise FacsError(f"{where}: {number:g} is outside [0, 1]{hint}")
    return min(max(number, 0.0), 1.0)


def au_values(key: str | int, value: float | str = 1.0) -> dict[str, float]:
    """Channel values of one action unit at an intensity: ``au_values("AU12_L", "C")``."""
    number, side = parse_key(key)
    unit = action_unit(number)
    if not unit.supported:
        raise FacsError(f"AU{number} ({unit.name}) is not supported by the rig: {unit.note}; leave it out")
    if side and unit.sides == "none":
        raise FacsError(f"AU{number} ({unit.name}) acts on the midline and has no sides; write 'AU{number}'")
    if not side and unit.sides == "required":
        raise FacsError(f"AU{number} ({unit.name}) is one-sided; write 'AU{number}_L' or 'AU{number}_R'")
    scale = intensity(value, f"AU{number}{'_' + side if side else ''}")
    return {channel: scale * v for channel, v in unit.values[side].items()}


def parse_facs(code: str, default: float | str = 1.0) -> dict[str, float]:
    """A FACS code string as intensities.

    ``"AU1+2+4B+L12C"`` → ``{"AU1": 1.0, "AU2": 1.0, "AU4": 0.4, "AU12_L": 0.6}``.

    Items are joined by "+"; each may carry a side (prefix "L"/"R" or suffix "L"/"_L") and an
    intensity letter after the number. Items without a letter take ``default``.
    """
    out: dict[str, float] = {}
    for item in str(code).split("+"):
        match = _CODE.match(item)
        if not item.strip() or not match or (match.group(1) and match.group(4)):
            raise FacsError(
                f"cannot read {item!r} in FACS code {code!r}; write items like 'AU12', 'L12C', '12C_L'"
            )
        side = (match.group(1) or match.group(4) or "").upper()
        key = f"AU{int(match.group(2))}" + (f"_{side}" if side else "")
        if key in out:
            raise FacsError(f"{key} appears twice in FACS code {code!r}")
        out[key] = intensity(match.group(3) or default, key)
    return out


def facs_values(intensities: Mapping[str | int, float | str]) -> dict[str, float]:
    """Summed channel values (unclipped) of several AUs: channel → value."""
    seen: dict[tuple[int, str], str | int] = {}
    total: dict[str, float] = {}
    for key, value in intensities.items():
        parsed = parse_key(key)
        if parsed in seen:
            raise FacsError(f"action unit {key!r} is given twice (also as {seen[parsed]!r})")
        seen[parsed] = key
        _add(total, au_values(key, value))
    return total


def facs_pose(rig: Rig, intensities: Mapping[str | int, float | str]) -> np.ndarray:
    """A pose (c,) float64 from FACS action-unit intensities.

    Parameters
    ----------
    rig : Rig
        Gives the channel order, defaults and ranges.
    intensities : Mapping[str | int, float | str]
        AU key → intensity, e.g. ``{"AU6": 1.0, "AU12_L": 0.8, "26": "C"}`` (see the module
        docstring for the keys and letters).

    Returns
    -------
    pose : (c,) float64, ``clip(d + sum_k i_k v_k)`` in the rig's channel order.
    """
    values = facs_values(intensities)
    index = {name: j for j, name in enumerate(rig.channel_names)}
    default = np.array([c.default for c in rig.channels], dtype=np.float64)
    out = default.copy()
    for channel, value in values.items():
        if channel not in index:
            close = difflib.get_close_matches(channel, list(index), n=3)
            hint = f"; did you mean {', '.join(close)}?" if close else ""
            raise FacsError(f"the FACS table drives channel {channel!r}, which this rig does not have{hint}")
        out[index[channel]] += value
    return check_activations(rig, out, clip=True)
