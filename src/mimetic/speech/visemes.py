"""Visemes: each phone → a weighted blend of visemes plus channel offsets → channel targets.

A *viseme map* is data: a built-in one (``viseme_map("en" | "nso" | "mpeg4")``, from
``data/visemes_<name>.json``) or a user's file in the same format (``load_viseme_map``)::

    {"visemes": {"PP": {"jaw_open": 0.0, "mentalis": 0.3}, "aa": {"jaw_open": 0.25}, ...},
     "phones": {"P": {"blend": {"PP": 1.0}, "class": "bilabial"},
                "AE": {"blend": {"aa": 0.6, "E": 0.5}, "offsets": {"tongue_tip_up": 0.1},
                       "class": "vowel", "deformability": {"lips": 0.4}, "note": "..."}}}

A viseme is a set of channel values over the rest pose (muscles 0..1, ``jaw_open`` in radians).
A phone's target (``phone_targets``) is ``clip(rest + Σ_v w_v · viseme_v + offsets)``: the weights
need not sum to 1 (Radovan's Northern Sotho /a/ was O + Closed + TH + W at 100 % each), and the
offsets reach channels no viseme sets (the tongue). ``"base": "en"`` makes a map that starts from
a built-in one and replaces or adds the visemes and phones it lists (a phone entry without a
class keeps the base's). ``"format"``, ``"version"``, ``"name"``, ``"language"`` and
``"description"`` are optional; a map without a ``SILENCE`` ("SIL") phone gets one at rest.

**Classes and deformability.** Every phone has a ``class`` (``CLASSES``), which gives its default
*deformability* per articulator group (``GROUPS``: the tongue channels, the jaw channels, and
"lips", every other channel): 0 for a phone that keeps its shape whatever its neighbours do (the
lips of P B M, of F V), 1 for one that takes its neighbours' shape (the lips of T, the tongue of a
vowel: Pelachaud's deformability). ``deformability`` in a phone entry overrides the class: one
number for every group, or ``{"lips": ..., "jaw": ..., "tongue": ...}`` for some.
``mimetic.speech.coarticulation`` turns it into dominance; it also closes the lips at every
"bilabial" and "labiodental" phone (over the first ``closure`` share of a stop, the rest being its
release) and anticipates the lip shape of "rounded" phones earlier.

Built-in maps: "en" (ARPAbet on the 15 visemes of the Oculus/Meta set, with tongue), "nso"
(Northern Sotho after Radovan 2008 ch. 10, with what is approximate in its notes) and "mpeg4" (the
14 MPEG-4 visemes of ``mimetic.animate.mpeg4`` plus neutral, for ARPAbet phones). Each map's
``description`` says how it was made.
"""

from __future__ import annotations

import difflib
import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from functools import cache
from importlib import resources
from pathlib import Path
from types import MappingProxyType

import numpy as np

from mimetic.errors import SpeechError
from mimetic.inputs import read_text
from mimetic.rig.activations import check_activations
from mimetic.rig.model import Channel, Rig
from mimetic.speech.phones import LANGUAGES, SILENCE

FORMAT = "mimetic-visemes"
VERSION = 1
BUILT_IN = ("en", "nso", "mpeg4")
"""The built-in maps: English (ARPAbet), Northern Sotho, and the MPEG-4 visemes for ARPAbet."""
GROUPS = ("lips", "jaw", "tongue")
"""Articulator groups: each has its own dominance in coarticulation and its own JALI dial."""
CLASSES: Mapping[str, Mapping[str, float]] = MappingProxyType(
    {
        name: MappingProxyType(dict(zip(GROUPS, values, strict=True)))
        for name, values in {
            # class: deformability of (lips, jaw, tongue); 0 keeps its shape, 1 takes the neighbours'
            "silence": (0.5, 0.5, 0.5),
            "bilabial": (0.0, 0.1, 1.0),
            "labiodental": (0.05, 0.2, 1.0),
            "dental": (0.7, 0.3, 0.05),
            "alveolar": (0.9, 0.4, 0.05),
            "sibilant": (0.6, 0.1, 0.05),  # sibilants narrow the jaw
            "postalveolar": (0.3, 0.2, 0.1),
            "velar": (0.9, 0.5, 0.05),
            "glottal": (1.0, 1.0, 1.0),
            "liquid": (0.5, 0.5, 0.2),
            "rounded": (0.1, 0.3, 0.7),
            "spread": (0.3, 0.3, 0.7),
            "vowel": (0.6, 0.2, 0.7),
        }.items()
    }
)
"""Phone classes → default deformability (0..1) per group of ``GROUPS``."""
_TOP_KEYS = frozenset({"format", "version", "name", "language", "description", "base", "visemes", "phones"})
_PHONE_KEYS = frozenset({"blend", "offsets", "class", "deformability", "note", "closure"})


def channel_group(name: str) -> str:
    """The articulator group (``GROUPS``) of a channel: "tongue" and "jaw" by prefix, else "lips"."""
    for group in ("tongue", "jaw"):
        if name.startswith(group + "_"):
            return group
    return "lips"


@dataclass(frozen=True)
class PhoneVisemes:
    """How one phone looks.

    Attributes
    ----------
    label : str
        The phone ("P", "AA"; Northern Sotho "TLH"; ``SILENCE``).
    blend : Mapping[str, float]
        Viseme name → weight (finite; need not sum to 1).
    offsets : Mapping[str, float]
        Channel → value added after the blend, in the channel's unit.
    kind : str
        Its class (``CLASSES``), "class" in the file.
    deformability : Mapping[str, float]
        Group (``GROUPS``) → 0..1, the class's defaults with the entry's overrides.
    note : str
        What is approximate about it, or where it comes from.
    closure : float
        The share of the phone, from its start, that the lips of a "bilabial" or "labiodental" phone
        are closed: 1 for a nasal or fricative, less for a stop, whose aligned span holds its
        closure and then its release ("closure" in the file; default 1).
    """

    label: str
    blend: Mapping[str, float]
    offsets: Mapping[str, float]
    kind: str
    deformability: Mapping[str, float]
    note: str = ""
    closure: float = 1.0


@dataclass(frozen=True)
class VisemeMap:
    """Visemes (name → channel values) and phones (label → ``PhoneVisemes``) of one language.

    ``language`` is one of ``mimetic.speech.phones.LANGUAGES`` or "" when the file does not say.
    """

    name: str
    language: str
    description: str
    visemes: Mapping[str, Mapping[str, float]]
    phones: Mapping[str, PhoneVisemes]

    def phone(self, label: str) -> PhoneVisemes:
        """The entry of ``label``; ``SpeechError`` with the closest labels when the map lacks it."""
        if label in self.phones:
            return self.phones[label]
        close = difflib.get_close_matches(str(label), list(self.phones), n=3, cutoff=0.5)
        hint = f"did you mean {', '.join(close)}?" if close else f"it has {', '.join(sorted(self.phones))}"
        raise SpeechError(f"phone {label!r} is not in viseme map {self.name!r}; {hint}")

    @property
    def channels(self) -> tuple[str, ...]:
        """The channels the map's visemes and offsets set, sorted."""
        names = {c for values in self.visemes.values() for c in values}
        names.update(c for p in self.phones.values() for c in p.offsets)
        return tuple(sorted(names))


# ---- parsing


def _numbers(raw: object, where: str, *, what: str) -> dict[str, float]:
    if not isinstance(raw, Mapping):
        raise SpeechError(f"{where}: expected an object of {what} → number; got {type(raw).__name__}")
    out = {}
    for key, value in raw.items():
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise SpeechError(f"{where}: {what} {key!r} = {value!r} must be a finite number")
        out[str(key)] = float(value)
    return out


def _deformability(raw: object, kind: str, where: str) -> dict[str, float]:
    out = dict(CLASSES[kind])
    if raw is None:
        return out
    given = dict.fromkeys(GROUPS, raw) if not isinstance(raw, Mapping) else raw
    for group, value in _numbers(given, where, what="group").items():
        if group not in GROUPS:
            raise SpeechError(f"{where}: unknown group {group!r}; groups are {', '.join(GROUPS)}")
        if not 0.0 <= value <= 1.0:
            raise SpeechError(f"{where}: deformability of {group} is {value:g}; it must be in [0, 1]")
        out[group] = value
    return out


def _phone(label: str, raw: object, visemes: Mapping, base: PhoneVisemes | None, source: str) -> PhoneVisemes:
    where = f"{source}: phone {label!r}"
    if not isinstance(raw, Mapping):
        raise SpeechError(f"{where}: expected an object with 'blend' and 'class'")
    extra = sorted(set(raw) - _PHONE_KEYS)
    if extra:
        raise SpeechError(f"{where}: unknown key(s) {', '.join(map(repr, extra))}; use {sorted(_PHONE_KEYS)}")
    kind = raw.get("class", base.kind if base else None)
    if kind not in CLASSES:
        raise SpeechError(f"{where}: class {kind!r} must be one of {', '.join(CLASSES)}")
    blend = _numbers(raw.get("blend", {}), f"{where}.blend", what="viseme")
    unknown = [v for v in blend if v not in visemes]
    if unknown:
        close = difflib.get_close_matches(unknown[0], list(visemes), n=3)
        hint = f"did you mean {', '.join(close)}?" if close else f"visemes are {', '.join(visemes)}"
        raise SpeechError(f"{where}: blends unknown viseme {unknown[0]!r}; {hint}")
    return PhoneVisemes(
        label,
        MappingProxyType(blend),
        MappingProxyType(_numbers(raw.get("offsets", {}), f"{where}.offsets", what="channel")),
        kind,
        MappingProxyType(_deformability(raw.get("deformability"), kind, f"{where}.deformability")),
        str(raw.get("note", "")),
        _closure(raw.get("closure", base.closure if base else 1.0), f"{where}.closure"),
    )


def _closure(raw: object, where: str) -> float:
    if isinstance(raw, bool) or not isinstance(raw, int | float) or not 0.0 < raw <= 1.0:
        raise SpeechError(
            f"{where}: {raw!r} must be a number in (0, 1]: the share of the phone the lips are closed"
        )
    return float(raw)


def _parse(data: object, source: str, name: str, visemes: Mapping | None = None) -> VisemeMap:
    """A ``VisemeMap`` from the JSON ``data``; ``visemes`` supplies them when the file has none (mpeg4)."""
    if not isinstance(data, Mapping):
        raise SpeechError(f"{source}: a viseme map is a JSON object with 'visemes' and 'phones'")
    extra = sorted(set(data) - _TOP_KEYS)
    if extra:
        raise SpeechError(f"{source}: unknown key(s) {', '.join(map(repr, extra))}; use {sorted(_TOP_KEYS)}")
    if data.get("format", FORMAT) != FORMAT:
        raise SpeechError(f"{source}: format {data['format']!r} is not {FORMAT!r}")
    version = data.get("version", VERSION)
    if not isinstance(version, int) or version > VERSION:
        raise SpeechError(f"{source}: format version {version!r} is newer than {VERSION}; update mimetic")
    base = None
    if "base" in data:
        if data["base"] not in BUILT_IN:
            raise SpeechError(f"{source}: base {data['base']!r} must be one of {', '.join(BUILT_IN)}")
        base = viseme_map(data["base"])
    language = data.get("language", base.language if base else "")
    if language and language not in LANGUAGES:
        raise SpeechError(f"{source}: language {language!r} must be one of {', '.join(LANGUAGES)}")
    all_visemes = dict(base.visemes if base else visemes or {})
    raw_visemes = data.get("visemes", {})
    if not isinstance(raw_visemes, Mapping):
        raise SpeechError(f"{source}: 'visemes' must be an object of viseme name → channel values")
    for viseme, values in raw_visemes.items():
        all_visemes[str(viseme)] = MappingProxyType(
            _numbers(values, f"{source}: viseme {viseme!r}", what="channel")
        )
    raw_phones = data.get("phones")
    if not isinstance(raw_phones, Mapping) or not (raw_phones or base):
        raise SpeechError(f"{source}: 'phones' must be an object of phone label → entry")
    phones = dict(base.phones if base else {})
    for label, raw in raw_phones.items():
        phones[str(label)] = _phone(str(label), raw, all_visemes, phones.get(str(label)), source)
    empty = MappingProxyType({})
    phones.setdefault(SILENCE, PhoneVisemes(SILENCE, empty, empty, "silence", CLASSES["silence"]))
    return VisemeMap(
        str(data.get("name", name)),
        language,
        str(data.get("description", base.description if base else "")),
        MappingProxyType(all_visemes),
        MappingProxyType(phones),
    )


def _check_channels(vmap: VisemeMap, names: Sequence[str]) -> None:
    known = set(names)
    used = [(c, f"viseme {v!r}") for v, values in vmap.visemes.items() for c in values]
    used += [(c, f"phone {p.label!r}'s offsets") for p in vmap.phones.values() for c in p.offsets]
    for channel, where in used:
        if channel not in known:
            close = difflib.get_close_matches(channel, names, n=3)
            hint = f"did you mean {', '.join(close)}? " if close else ""
            raise SpeechError(
                f"viseme map {vmap.name!r}: {where} sets channel {channel!r}, which the rig does not have; "
                f"{hint}valid channels: {', '.join(names)}"
            )


def _channels(channels: Rig | Sequence[Channel]) -> tuple[Channel, ...]:
    return tuple(channels.channels if isinstance(channels, Rig) else channels)


def _unknown(name: str) -> str:
    """The message for a viseme map name that is neither built in nor a file."""
    close = difflib.get_close_matches(str(name), BUILT_IN, n=1)
    hint = f"did you mean {close[0]!r}? " if close else ""
    return (
        f"unknown viseme map {name!r}; {hint}use a built-in map ({', '.join(BUILT_IN)}) or a map .json file"
    )


@cache
def viseme_map(name: str) -> VisemeMap:
    """A built-in map (``BUILT_IN``: "en", "nso", "mpeg4"), read once."""
    if name not in BUILT_IN:
        raise SpeechError(_unknown(name))
    text = resources.files("mimetic.speech").joinpath(f"data/visemes_{name}.json").read_text("utf-8")
    visemes = None
    if name == "mpeg4":
        from mimetic.animate.mpeg4 import visemes as mpeg4_visemes

        visemes = {"_".join(v.phonemes) or "neutral": v.values for v in mpeg4_visemes()}
    return _parse(json.loads(text), f"visemes_{name}.json", name, visemes)


def load_viseme_map(
    source: str | os.PathLike | Mapping, *, channels: Rig | Sequence[Channel] | None = None
) -> VisemeMap:
    """A user's viseme map from a JSON file (or its parsed contents), checked.

    Parameters
    ----------
    source : path or Mapping
        The file (format in the module docstring), or the dict it holds.
    channels : Rig or sequence of Channel, optional
        When given, every channel the map sets must be one of these (``phone_targets`` checks it
        anyway, when the map is used).

    Raises ``SpeechError`` for a name that is no file and no ``.json`` (listing the built-in maps),
    and naming the viseme, phone or channel at fault: unknown keys, classes,
    visemes or channels (with the valid names), weights that are not finite numbers,
    deformability outside [0, 1].
    """
    if isinstance(source, Mapping):
        vmap = _parse(source, "viseme map", "user")
    else:
        path = Path(source)
        if not path.exists() and path.suffix.lower() != ".json":
            raise SpeechError(_unknown(os.fspath(source)))
        try:
            data = json.loads(read_text(path, SpeechError, "viseme map"))
        except json.JSONDecodeError as error:
            raise SpeechError(f"{path.name}: not valid JSON ({error})") from None
        vmap = _parse(data, path.name, path.stem)
    if channels is not None:
        _check_channels(vmap, [c.name for c in _channels(channels)])
    return vmap


def phone_targets(
    viseme_map: VisemeMap, labels: Sequence[str], channels: Rig | Sequence[Channel]
) -> np.ndarray:
    """Channel targets (p, c) float64 of phones: ``clip(rest + Σ_v w_v · viseme_v + offsets)``.

    Parameters
    ----------
    viseme_map : VisemeMap
    labels : sequence of str, length p
        Phone labels (``SILENCE`` gives the rest pose).
    channels : Rig or sequence of Channel, length c
        Column order, rest values (``Channel.default``) and ranges.

    Raises ``SpeechError`` for a phone the map lacks (with suggestions) or a channel the rig lacks.
    """
    chans = _channels(channels)
    names = [c.name for c in chans]
    _check_channels(viseme_map, names)
    index = {n: j for j, n in enumerate(names)}
    rest = np.array([c.default for c in chans], dtype=np.float64)
    unique: dict[str, np.ndarray] = {}
    for label in dict.fromkeys(labels):
        entry = viseme_map.phone(label)
        target = rest.copy()
        for viseme, weight in entry.blend.items():
            for channel, value in viseme_map.visemes[viseme].items():
                target[index[channel]] += weight * value
        for channel, value in entry.offsets.items():
            target[index[channel]] += value
        unique[label] = target
    out = np.array([unique[label] for label in labels], dtype=np.float64).reshape(len(labels), len(chans))
    return check_activations(chans, out, clip=True)
