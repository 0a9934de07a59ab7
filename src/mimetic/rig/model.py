"""The rig data model: channels, muscles, wires, bones and the ``Rig`` that holds them.

Everything here is a frozen dataclass whose arrays are read-only. Lengths are in rig units
(``Rig.units``); a field ending in ``_rel`` is a fraction of a named reference length (usually
``Rig.scale``, the head height; each docstring says which); angles end in ``_rad``.

Each element checks its own fields when it is built and raises ``RigError`` naming the element
and the field. Checks that need the whole rig (a surface point on a face that exists, a muscle
with a channel of the same name, skin weights that sum to 1) live in ``mimetic.rig.validate``
and run when a ``Rig`` is built.

Over 600 lines because every element of a rig is here with its own checks: the one place the
rig file, the engines and the transfer read what a rig holds.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from types import MappingProxyType
from typing import Any, Literal, get_args

import numpy as np
import scipy.sparse as sp

from mimetic.errors import RigError
from mimetic.mesh.model import Mesh, SurfacePoint
from mimetic.rig.anatomy import Anatomy, derive_anatomy

ChannelUnit = Literal["activation", "rad", "rel"]
MuscleKind = Literal["linear", "sphincter", "sheet"]
Side = Literal["L", "R", "C"]
Units = Literal["mm", "cm", "dm", "m", "in"]

CHANNEL_UNITS: tuple[str, ...] = get_args(ChannelUnit)
MUSCLE_KINDS: tuple[str, ...] = get_args(MuscleKind)
SIDES: tuple[str, ...] = get_args(Side)
UNITS: tuple[str, ...] = get_args(Units)

BARY_TOL = 1e-6
"""Tolerance on barycentric sums (must be 1) and on each weight (must be ≥ −tol)."""


# --------------------------------------------------------------------------- coercion helpers


def _readonly_copy(value: Any, dtype: type, where: str) -> np.ndarray:
    """A C-contiguous read-only copy of ``value`` as ``dtype`` (never a view of the caller's array)."""
    try:
        array = np.array(value, dtype=dtype, copy=True, order="C")
    except (TypeError, ValueError) as error:
        raise RigError(f"{where} cannot be read as a {np.dtype(dtype).name} array: {error}") from None
    array.setflags(write=False)
    return array


def _index_array(value: Any, where: str) -> np.ndarray:
    """Integer indices as a read-only (k,) int64 copy; floats that are not integers are refused."""
    array = np.asarray(value)
    if array.size and not np.issubdtype(array.dtype, np.integer):
        raise RigError(f"{where} must hold integer indices; got dtype {array.dtype}. Pass np.int64 indices.")
    array = _readonly_copy(array, np.int64, where)
    if array.ndim != 1:
        raise RigError(f"{where} must have shape (k,); got {array.shape}")
    return array


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise RigError(f"{where}={value!r} must be a number")
    number = float(value)
    if not math.isfinite(number):
        raise RigError(f"{where}={number} must be finite")
    return number


def _name(value: Any, where: str) -> str:
    if not isinstance(value, str) or not value:
        raise RigError(f"{where}={value!r} must be a non-empty string")
    return value


def _choice(value: Any, options: tuple[str, ...], where: str) -> str:
    if value not in options:
        raise RigError(f"{where}={value!r} must be one of {', '.join(map(repr, options))}")
    return value


def coerce_surface_point(point: Any, where: str) -> SurfacePoint:
    """A ``SurfacePoint`` with ``face`` a Python int and ``bary`` a tuple of three finite floats.

    Checks what can be checked without the mesh: ``face`` ≥ 0, weights sum to 1 (± ``BARY_TOL``)
    and none is below ``-BARY_TOL``. Raises ``RigError`` naming ``where``.
    """
    if not isinstance(point, SurfacePoint):
        raise RigError(f"{where} must be a SurfacePoint(face, bary); got {type(point).__name__}")
    face = point.face
    if isinstance(face, bool) or not isinstance(face, (int, np.integer)):
        raise RigError(f"{where}.face={face!r} must be an integer face index")
    face = int(face)
    if face < 0:
        raise RigError(f"{where}.face={face} must be ≥ 0")
    try:
        bary = tuple(np.asarray(point.bary, dtype=np.float64).ravel().tolist())
    except (TypeError, ValueError):
        raise RigError(f"{where}.bary={point.bary!r} must be 3 numbers") from None
    if len(bary) != 3:
        raise RigError(f"{where}.bary must have 3 weights; got {len(bary)}")
    if not all(math.isfinite(b) for b in bary):
        raise RigError(f"{where}.bary={bary} must be finite")
    total = math.fsum(bary)
    if abs(total - 1.0) > BARY_TOL:
        raise RigError(
            f"{where}.bary={bary} sums to {total:.9g}; barycentric weights must sum to 1 (±{BARY_TOL:g}). "
            "Divide them by their sum."
        )
    if min(bary) < -BARY_TOL:
        raise RigError(f"{where}.bary={bary} has a negative weight; the point must lie inside its face")
    if (
        type(point.face) is int
        and isinstance(point.bary, tuple)
        and all(type(b) is float for b in point.bary)
    ):
        return point
    return SurfacePoint(face, (bary[0], bary[1], bary[2]))


def freeze_json(value: Any, where: str = "metadata") -> Any:
    """A deep read-only copy of JSON-safe data: dicts → MappingProxyType, lists → tuples.

    Accepts str, int, float (finite), bool, None (numpy scalars become Python ones), and
    mappings with str keys and lists/tuples of those. Raises ``RigError`` naming the path of
    the first value that is not JSON-safe.
    """
    if value is None or isinstance(value, (bool, np.bool_)):
        return None if value is None else bool(value)
    if isinstance(value, str):
        return str(value)
    if isinstance(value, (int, np.integer)):
        return int(value)
    if isinstance(value, (float, np.floating)):
        if not math.isfinite(value):
            raise RigError(f"{where}={value} is not JSON-safe: use a finite number or None")
        return float(value)
    if isinstance(value, Mapping):
        out = {}
        for key, item in value.items():
            if not isinstance(key, str):
                raise RigError(f"{where} has key {key!r}; JSON object keys must be strings")
            out[key] = freeze_json(item, f"{where}.{key}")
        return MappingProxyType(out)
    if isinstance(value, (list, tuple)):
        return tuple(freeze_json(item, f"{where}[{i}]") for i, item in enumerate(value))
    raise RigError(
        f"{where}={value!r} ({type(value).__name__}) is not JSON-safe: use str, int, float, bool, None, "
        "lists and dicts with string keys (convert numpy values with .tolist())"
    )


def thaw_json(value: Any) -> Any:
    """The inverse of ``freeze_json``: plain dicts and lists, ready for ``json.dumps``."""
    if isinstance(value, Mapping):
        return {key: thaw_json(item) for key, item in value.items()}
    if isinstance(value, tuple):
        return [thaw_json(item) for item in value]
    return value


def _arrays_identical(a: np.ndarray, b: np.ndarray) -> bool:
    """Same shape, same dtype and the same bits (so 0.0 ≠ -0.0)."""
    return a.shape == b.shape and a.dtype == b.dtype and a.tobytes() == b.tobytes()


# --------------------------------------------------------------------------- elements


@dataclass(frozen=True)
class Channel:
    """One named channel of the activation pivot.

    Attributes
    ----------
    name : str
        Unique in the rig; a muscle's channel has the muscle's name (e.g. "zygomatic_major_L").
    minimum, maximum : float
        Range of the channel, ``minimum < maximum``, in ``unit``.
    default : float
        Rest value in [minimum, maximum]; 0 for muscles.
    unit : "activation" | "rad" | "rel"
        "activation" for muscles (usually [0, 1]); "rad" for jaw_open, eyelid and gaze angles;
        "rel" for translations as a fraction of ``Rig.scale`` (jaw_slide, jaw_protrude).
    group : str
        UI/character-set group, e.g. "muscles", "jaw", "eyes".
    """

    name: str
    minimum: float
    maximum: float
    default: float = 0.0
    unit: ChannelUnit = "activation"
    group: str = "muscles"

    def __post_init__(self) -> None:
        where = f"channel {self.name!r}"
        _name(self.name, f"{where}.name")
        for attr in ("minimum", "maximum", "default"):
            object.__setattr__(self, attr, _number(getattr(self, attr), f"{where}.{attr}"))
        _choice(self.unit, CHANNEL_UNITS, f"{where}.unit")
        _name(self.group, f"{where}.group")
        self.check(where)

    def check(self, where: str) -> None:
        """Raise ``RigError`` (prefixed with ``where``) unless the range and default are consistent."""
        if not self.minimum < self.maximum:
            raise RigError(f"{where}.minimum={self.minimum} must be < maximum={self.maximum}")
        if not self.minimum <= self.default <= self.maximum:
            raise RigError(
                f"{where}.default={self.default} must lie in [minimum, maximum] = "
                f"[{self.minimum}, {self.maximum}]"
            )


@dataclass(frozen=True)
class Muscle:
    """A Waters-style muscle, placed by surface points of the rest mesh.

    Attributes
    ----------
    name : str
        Unique; the rig has a channel of the same name (unit "activation").
    kind : "linear" | "sphincter" | "sheet"
        linear: origin → insertion is the muscle. sphincter: ``origin`` is the centre and
        ``insertion`` a point on the ring giving the semi-major axis; ``width_rel`` is the
        semi-minor axis. sheet: origin → insertion is the central line; ``width_rel`` its half-width.
    side : "L" | "R" | "C"
        The face's own left (+X), right, or centre.
    origin, insertion : SurfacePoint
        Skin points. The bony attachment is ``origin`` moved toward ``Rig.centre`` (see
        ``origin_inset_rel`` and ``Rig.muscle_attachment``).
    width_rel : float
        > 0, fraction of ``Rig.scale``: the semi-minor axis (sphincter) or half-width (sheet);
        for a linear muscle, the lateral reach of its zone of influence.
    falloff_start_rel, falloff_end_rel : float
        Radial falloff zone, as fractions of the muscle length (|insertion − attachment|, or the
        semi-major axis for a sphincter): full effect up to ``falloff_start_rel``, none beyond
        ``falloff_end_rel``. ``0 ≤ start < 1``, ``start < end``.
    angle_rad : float
        In (0, π]: the angular half-extent of the zone of influence about the muscle axis.
    origin_inset_rel : float
        In [0, 1): fraction of the distance from ``Rig.centre`` to ``origin`` by which the
        attachment lies beneath the skin (0.05 = the thesis's scaling by 0.95).
    reversed : bool
        Contraction pushes outward from the origin instead of pulling toward it (the mentalis).
    region : str, optional
        Name of a ``Rig.regions`` vertex set that limits the muscle's effect.
    """

    name: str
    kind: MuscleKind
    side: Side
    origin: SurfacePoint
    insertion: SurfacePoint
    width_rel: float
    falloff_start_rel: float
    falloff_end_rel: float
    angle_rad: float
    origin_inset_rel: float = 0.05
    reversed: bool = False
    region: str | None = None

    def __post_init__(self) -> None:
        where = f"muscle {self.name!r}"
        _name(self.name, f"{where}.name")
        _choice(self.kind, MUSCLE_KINDS, f"{where}.kind")
        _choice(self.side, SIDES, f"{where}.side")
        for attr in ("origin", "insertion"):
            object.__setattr__(self, attr, coerce_surface_point(getattr(self, attr), f"{where}.{attr}"))
        for attr in ("width_rel", "falloff_start_rel", "falloff_end_rel", "angle_rad", "origin_inset_rel"):
            object.__setattr__(self, attr, _number(getattr(self, attr), f"{where}.{attr}"))
        if not isinstance(self.reversed, (bool, np.bool_)):
            raise RigError(f"{where}.reversed={self.reversed!r} must be True or False")
        object.__setattr__(self, "reversed", bool(self.reversed))
        if self.region is not None:
            _name(self.region, f"{where}.region")
        self.check(where)

    def check(self, where: str) -> None:
        """Raise ``RigError`` (prefixed with ``where``) for a field outside its range."""
        if not self.width_rel > 0:
            raise RigError(f"{where}.width_rel={self.width_rel} must be > 0 (a fraction of the head height)")
        if not 0.0 <= self.falloff_start_rel < 1.0:
            raise RigError(f"{where}.falloff_start_rel={self.falloff_start_rel} must be in [0, 1)")
        if not self.falloff_end_rel > self.falloff_start_rel:
            raise RigError(
                f"{where}.falloff_end_rel={self.falloff_end_rel} must be > "
                f"falloff_start_rel={self.falloff_start_rel}"
            )
        if not 0.0 < self.angle_rad <= math.pi:
            raise RigError(f"{where}.angle_rad={self.angle_rad} must be in (0, π]")
        if not 0.0 <= self.origin_inset_rel < 1.0:
            raise RigError(f"{where}.origin_inset_rel={self.origin_inset_rel} must be in [0, 1)")


@dataclass(frozen=True, eq=False)
class Wire:
    """A polyline wire deformer whose control points are pulled by muscles.

    Each control point c follows a normalised weighted average of its rest position (weight
    ``rest_weight[i]``) and one locator per affecting muscle (weight ``muscle_weights[m][i]``);
    the wire then moves the skin vertices of ``vertices`` within ``dropoff_rel`` of it.

    Attributes
    ----------
    name : str
        Unique among wires, e.g. "mouth_upper_L".
    side : "L" | "R" | "C"
    points : tuple[SurfacePoint, ...]
        The p ≥ 2 control points, in order along the wire.
    dropoff_rel : float
        > 0, the dropoff distance d0 as a fraction of ``Rig.scale``.
    vertices : (k,) int64
        Sorted unique indices of the vertices this wire may move (its deformation set).
    muscle_weights : Mapping[str, (p,) float64]
        Muscle name → the non-negative weight of that muscle's locator on each control point.
    rest_weight : (p,) float64
        Non-negative weight of the rest locator on each control point. ``rest_weight`` plus the
        muscle weights is > 0 at every control point.
    """

    name: str
    side: Side
    points: tuple[SurfacePoint, ...]
    dropoff_rel: float
    vertices: np.ndarray
    muscle_weights: Mapping[str, np.ndarray]
    rest_weight: np.ndarray

    def __post_init__(self) -> None:
        where = f"wire {self.name!r}"
        _name(self.name, f"{where}.name")
        _choice(self.side, SIDES, f"{where}.side")
        if isinstance(self.points, (str, bytes)) or not isinstance(self.points, Iterable):
            raise RigError(f"{where}.points must be a sequence of SurfacePoint")
        points = tuple(
            coerce_surface_point(p, f"{where}.points[{i}]") for i, p in enumerate(tuple(self.points))
        )
        object.__setattr__(self, "points", points)
        object.__setattr__(self, "dropoff_rel", _number(self.dropoff_rel, f"{where}.dropoff_rel"))
        object.__setattr__(self, "vertices", _index_array(self.vertices, f"{where}.vertices"))
        if not isinstance(self.muscle_weights, Mapping):
            raise RigError(f"{where}.muscle_weights must be a mapping muscle name → (p,) weights")
        weights = {}
        for key, value in self.muscle_weights.items():
            _name(key, f"{where}.muscle_weights key")
            weights[key] = _readonly_copy(value, np.float64, f"{where}.muscle_weights[{key!r}]")
        object.__setattr__(self, "muscle_weights", MappingProxyType(weights))
        object.__setattr__(
            self, "rest_weight", _readonly_copy(self.rest_weight, np.float64, f"{where}.rest_weight")
        )
        self.check(where)

    def check(self, where: str) -> None:
        """Raise ``RigError`` (prefixed with ``where``) for inconsistent lengths or weights."""
        p = len(self.points)
        if p < 2:
            raise RigError(f"{where}.points has {p} point(s); a wire needs at least 2")
        if not self.dropoff_rel > 0:
            raise RigError(
                f"{where}.dropoff_rel={self.dropoff_rel} must be > 0 (a fraction of the head height)"
            )
        v = self.vertices
        if v.ndim != 1:
            raise RigError(f"{where}.vertices must have shape (k,); got {v.shape}")
        if v.size and v[0] < 0:
            raise RigError(f"{where}.vertices has negative index {int(v.min())}")
        if v.size > 1 and not np.all(v[1:] > v[:-1]):
            raise RigError(f"{where}.vertices must be sorted and unique; pass np.unique(vertices)")
        total = np.zeros(p)
        labelled = [(f"muscle_weights[{k!r}]", w) for k, w in self.muscle_weights.items()]
        for label, w in [*labelled, ("rest_weight", self.rest_weight)]:
            if w.shape != (p,):
                raise RigError(f"{where}.{label} has shape {w.shape}; expected ({p},), one weight per point")
            if not np.all(np.isfinite(w)):
                raise RigError(f"{where}.{label} has non-finite weights")
            if np.any(w < 0):
                raise RigError(f"{where}.{label} has negative weights; weights must be ≥ 0")
            total += w
        if np.any(total <= 0):
            i = int(np.argmax(total <= 0))
            raise RigError(
                f"{where}: control point {i} has zero total weight (rest + muscles); "
                "give it a rest_weight > 0"
            )

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Wire):
            return NotImplemented
        return (
            (self.name, self.side, self.points, self.dropoff_rel)
            == (other.name, other.side, other.points, other.dropoff_rel)
            and _arrays_identical(self.vertices, other.vertices)
            and list(self.muscle_weights) == list(other.muscle_weights)
            and all(_arrays_identical(w, other.muscle_weights[k]) for k, w in self.muscle_weights.items())
            and _arrays_identical(self.rest_weight, other.rest_weight)
        )

    __hash__ = None  # type: ignore[assignment]


@dataclass(frozen=True, eq=False)
class Bone:
    """A skinning bone, as in Blender: the joint at ``head``, pointing toward ``tail``.

    Attributes
    ----------
    name : str
        Unique; expected names include "head", "jaw", "eyelid_upper_L/R", "eyelid_lower_L/R",
        "eye_L/R".
    parent : str, optional
        Name of the parent bone; None for the root. Parents are listed before their children.
    head, tail : (3,) float64
        Rest positions in rig units; ``tail ≠ head``.
    """

    name: str
    parent: str | None
    head: np.ndarray
    tail: np.ndarray

    def __post_init__(self) -> None:
        where = f"bone {self.name!r}"
        _name(self.name, f"{where}.name")
        if self.parent is not None:
            _name(self.parent, f"{where}.parent")
        object.__setattr__(self, "head", _readonly_copy(self.head, np.float64, f"{where}.head"))
        object.__setattr__(self, "tail", _readonly_copy(self.tail, np.float64, f"{where}.tail"))
        self.check(where)

    def check(self, where: str) -> None:
        """Raise ``RigError`` (prefixed with ``where``) for bad shapes or a zero-length bone."""
        for attr in ("head", "tail"):
            value = getattr(self, attr)
            if value.shape != (3,):
                raise RigError(f"{where}.{attr} must have shape (3,); got {value.shape}")
            if not np.all(np.isfinite(value)):
                raise RigError(f"{where}.{attr}={value.tolist()} must be finite")
        if np.array_equal(self.head, self.tail):
            raise RigError(f"{where}: head and tail are both {self.head.tolist()}; a bone needs a length")
        if self.parent == self.name:
            raise RigError(f"{where}.parent is the bone itself")

    @property
    def length(self) -> float:
        """|tail − head| in rig units."""
        return float(np.linalg.norm(self.tail - self.head))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Bone):
            return NotImplemented
        return (
            (self.name, self.parent) == (other.name, other.parent)
            and _arrays_identical(self.head, other.head)
            and _arrays_identical(self.tail, other.tail)
        )

    __hash__ = None  # type: ignore[assignment]


# --------------------------------------------------------------------------- the rig


def _skin_weights(value: Any, where: str = "skin_weights") -> sp.csr_matrix:
    """A canonical read-only copy: csr_matrix float64, duplicates summed, indices sorted, no stored zeros."""
    if not (sp.issparse(value) or isinstance(value, np.ndarray)):
        raise RigError(
            f"{where} must be a scipy.sparse matrix (n_vertices, n_bones); got {type(value).__name__}"
        )
    if value.ndim != 2:
        raise RigError(f"{where} must be 2-D (n_vertices, n_bones); got shape {value.shape}")
    if not np.issubdtype(value.dtype, np.number) or np.issubdtype(value.dtype, np.complexfloating):
        raise RigError(f"{where} must hold real numbers; got dtype {value.dtype}")
    weights = sp.csr_matrix(value, dtype=np.float64, copy=True)
    weights.sum_duplicates()
    weights.eliminate_zeros()
    for array in (weights.data, weights.indices, weights.indptr):
        array.setflags(write=False)
    return weights


@dataclass(frozen=True, eq=False)
class Rig:
    """A rigged head: the rest mesh and everything that moves it.

    Building a ``Rig`` copies and freezes its arrays and runs ``validate_rig`` (a few ms even for
    a 30k-vertex head), so every ``Rig`` in memory is consistent.

    Attributes
    ----------
    mesh : Mesh
        The rest mesh, vertices (n, 3) float64 in ``units``; its vertex order is never changed.
    units : "mm" | "cm" | "dm" | "m" | "in"
        Length unit of the mesh and of every absolute length in the rig.
    scale : float
        > 0, the head height in ``units``; ``_rel`` lengths are fractions of it.
    landmarks : Mapping[str, SurfacePoint]
        Named points on the rest mesh, in a fixed order.
    regions : Mapping[str, (k,) int64]
        Named vertex sets (sorted unique indices), e.g. "lips_upper", "forehead".
    muscles, wires, bones, channels : tuple
        In a fixed order; names unique within each. Bones are ordered parents first.
    skin_weights : scipy.sparse.csr_matrix, (n, n_bones) float64
        Linear blend skinning weights: non-negative, ≤ 4 non-zeros and summing to 1 per vertex;
        column j is ``bones[j]``. Stored canonically (sorted indices, no explicit zeros).
    metadata : Mapping[str, JSON-safe]
        Free-form provenance (source mesh, recipe version, fit residuals); deep read-only.
    anatomy : Anatomy
        Creases, the forehead skull, lip contact pairs, accessories riding the skin and the
        soft-tissue thickness (``mimetic.rig.anatomy``), which the engines read. Derived from the
        fields above by ``derive_anatomy`` when not given (pass ``anatomy=None`` to
        ``dataclasses.replace`` after changing the mesh, regions or skin weights).
    """

    mesh: Mesh
    units: Units
    scale: float
    landmarks: Mapping[str, SurfacePoint]
    regions: Mapping[str, np.ndarray]
    muscles: tuple[Muscle, ...]
    wires: tuple[Wire, ...]
    bones: tuple[Bone, ...]
    skin_weights: sp.csr_matrix
    channels: tuple[Channel, ...]
    metadata: Mapping[str, Any] = field(default_factory=dict)
    anatomy: Anatomy | None = None

    def __post_init__(self) -> None:
        from mimetic.rig.validate import validate_rig

        if not isinstance(self.mesh, Mesh):
            raise RigError(f"mesh must be a mimetic.mesh.Mesh; got {type(self.mesh).__name__}")
        object.__setattr__(self, "scale", _number(self.scale, "scale"))
        if not isinstance(self.landmarks, Mapping):
            raise RigError("landmarks must be a mapping name → SurfacePoint")
        landmarks = {
            _name(k, "landmarks key"): coerce_surface_point(p, f"landmarks[{k!r}]")
            for k, p in self.landmarks.items()
        }
        object.__setattr__(self, "landmarks", MappingProxyType(landmarks))
        if not isinstance(self.regions, Mapping):
            raise RigError("regions must be a mapping name → (k,) int64 vertex indices")
        regions = {
            _name(k, "regions key"): _index_array(v, f"regions[{k!r}]") for k, v in self.regions.items()
        }
        object.__setattr__(self, "regions", MappingProxyType(regions))
        for attr, kind in (("muscles", Muscle), ("wires", Wire), ("bones", Bone), ("channels", Channel)):
            items = getattr(self, attr)
            if isinstance(items, (str, bytes, Mapping)) or not isinstance(items, Iterable):
                raise RigError(f"{attr} must be a sequence of {kind.__name__}")
            items = tuple(items)
            for i, item in enumerate(items):
                if not isinstance(item, kind):
                    raise RigError(f"{attr}[{i}] must be a {kind.__name__}; got {type(item).__name__}")
            object.__setattr__(self, attr, items)
        object.__setattr__(self, "skin_weights", _skin_weights(self.skin_weights))
        if not isinstance(self.metadata, Mapping):
            raise RigError(f"metadata must be a mapping; got {type(self.metadata).__name__}")
        object.__setattr__(self, "metadata", freeze_json(self.metadata))
        if self.anatomy is None:
            anatomy = derive_anatomy(
                self.mesh, self.landmarks, self.regions, self.skin_weights, self.scale, self.channel_names
            )
            object.__setattr__(self, "anatomy", anatomy)
        elif not isinstance(self.anatomy, Anatomy):
            kind = type(self.anatomy).__name__
            raise RigError(f"anatomy must be a mimetic.rig.anatomy.Anatomy; got {kind}")
        validate_rig(self)

    def __repr__(self) -> str:
        return (
            f"Rig({self.n_vertices} vertices, {self.mesh.n_faces} faces, {len(self.muscles)} muscles, "
            f"{len(self.wires)} wires, {len(self.bones)} bones, {len(self.channels)} channels, "
            f"units={self.units!r}, scale={self.scale:g})"
        )

    # ---- the user's own frame

    @cached_property
    def source_rotation(self) -> np.ndarray:
        """(3, 3) float64 rotation from the rig frame (+Y up, +Z forward) to the frame of the mesh the
        rig was made from (``metadata["source_rotation"]``, written by ``rig_head``; the identity for
        generated heads and meshes already in that convention). Read-only."""
        raw = self.metadata.get("source_rotation")
        if raw is None:
            rotation = np.eye(3)
        else:
            try:
                rotation = np.array(thaw_json(raw), dtype=np.float64)
            except (TypeError, ValueError):
                raise RigError(f"metadata source_rotation={raw!r} is not a 3x3 matrix") from None
            if rotation.shape != (3, 3) or not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-6):
                raise RigError(
                    f"metadata source_rotation must be a 3x3 rotation matrix; got {rotation.tolist()}"
                )
        rotation.setflags(write=False)
        return rotation

    def to_source_frame(self, vertices: np.ndarray) -> np.ndarray:
        """Positions (..., 3) in rig units and the rig frame → the same points in the user's source
        frame (same units): what OBJ, PLY and STL outputs hold, so a rest pose lies exactly on the
        user's input mesh."""
        return np.asarray(vertices, dtype=np.float64) @ self.source_rotation.T

    def source_mesh(self, vertices: np.ndarray | None = None) -> Mesh:
        """The rig's mesh (all parts, same vertex order) in the user's source frame, at the rest pose
        or at ``vertices`` (n, 3) (a posed frame from an engine, rig frame)."""
        v = self.mesh.vertices if vertices is None else vertices
        return self.mesh.with_vertices(self.to_source_frame(v))

    # ---- sizes and names

    @property
    def n_vertices(self) -> int:
        return self.mesh.n_vertices

    @property
    def n_bones(self) -> int:
        return len(self.bones)

    @cached_property
    def channel_names(self) -> tuple[str, ...]:
        """Channel names in pivot order: column j of an activations array is ``channel_names[j]``."""
        return tuple(c.name for c in self.channels)

    @cached_property
    def muscle_names(self) -> tuple[str, ...]:
        return tuple(m.name for m in self.muscles)

    @cached_property
    def bone_names(self) -> tuple[str, ...]:
        return tuple(b.name for b in self.bones)

    @cached_property
    def _index(self) -> Mapping[str, Mapping[str, int]]:
        return MappingProxyType(
            {
                "channel": {c.name: i for i, c in enumerate(self.channels)},
                "muscle": {m.name: i for i, m in enumerate(self.muscles)},
                "wire": {w.name: i for i, w in enumerate(self.wires)},
                "bone": {b.name: i for i, b in enumerate(self.bones)},
            }
        )

    def _lookup(self, kind: str, name: str) -> int:
        index = self._index[kind]
        if name not in index:
            names = list(index)
            shown = ", ".join(names[:5]) + (", …" if len(names) > 5 else "")
            raise KeyError(f"no {kind} {name!r}; the rig has {len(names)} {kind}s ({shown})")
        return index[name]

    def channel_index(self, name: str) -> int:
        """Column of channel ``name`` in an activations array."""
        return self._lookup("channel", name)

    def channel(self, name: str) -> Channel:
        return self.channels[self._lookup("channel", name)]

    def muscle(self, name: str) -> Muscle:
        return self.muscles[self._lookup("muscle", name)]

    def wire(self, name: str) -> Wire:
        return self.wires[self._lookup("wire", name)]

    def bone_index(self, name: str) -> int:
        """Column of bone ``name`` in ``skin_weights``."""
        return self._lookup("bone", name)

    def bone(self, name: str) -> Bone:
        return self.bones[self._lookup("bone", name)]

    # ---- positions on the rest mesh

    def landmark_positions(self, names: Sequence[str] | None = None) -> np.ndarray:
        """Rest positions (k, 3) float64 of the named landmarks (all, in order, when ``names`` is None)."""
        if names is None:
            names = list(self.landmarks)
        missing = [n for n in names if n not in self.landmarks]
        if missing:
            raise KeyError(f"no landmark(s) {missing}; the rig has {len(self.landmarks)} landmarks")
        points = [self.landmarks[n] for n in names]
        if not points:
            return np.zeros((0, 3))
        face_ids = np.array([p.face for p in points], dtype=np.int64)
        bary = np.array([p.bary for p in points], dtype=np.float64)  # (k, 3)
        return np.einsum("kj,kjd->kd", bary, self.mesh.vertices[self.mesh.faces[face_ids]])  # (k, 3)

    @cached_property
    def centre(self) -> np.ndarray:
        """Centre (3,) float64 of the rest mesh's bounding box: muscle origins are inset toward it."""
        v = self.mesh.vertices
        centre = (v.min(axis=0) + v.max(axis=0)) / 2
        centre.setflags(write=False)
        return centre

    def muscle_attachment(self, name: str) -> np.ndarray:
        """The bony attachment (3,) of muscle ``name``: its origin moved toward ``centre``.

        ``attachment = centre + (1 − origin_inset_rel) · (origin − centre)``, the thesis's
        uniform scaling of origins by 0.95 about the bounding-box centre when the inset is 0.05.
        """
        muscle = self.muscle(name)
        origin = muscle.origin.position(self.mesh.vertices, self.mesh.faces)
        return self.centre + (1.0 - muscle.origin_inset_rel) * (origin - self.centre)

    # ---- equality

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Rig):
            return NotImplemented
        return rigs_equal(self, other)

    __hash__ = None  # type: ignore[assignment]


def rig_differences(a: Rig, b: Rig, limit: int = 10) -> list[str]:
    """Paths of the fields where two rigs differ (at most ``limit``); empty when they are identical.

    Arrays must match in shape, dtype and bits (so 0.0 ≠ -0.0), mappings in key order, and
    sequences element by element. Skin weights are compared by value in canonical CSR form.
    """
    out: list[str] = []

    def array(path: str, x: np.ndarray | None, y: np.ndarray | None) -> None:
        if x is None or y is None:
            if (x is None) != (y is None):
                out.append(f"{path}: one is None")
        elif not _arrays_identical(x, y):
            out.append(f"{path}: {x.dtype}{x.shape} vs {y.dtype}{y.shape} or different values")

    def mapping(path: str, x: Mapping, y: Mapping, each) -> None:
        if list(x) != list(y):
            out.append(f"{path}: keys {list(x)[:5]} vs {list(y)[:5]} (or their order) differ")
            return
        for key in x:
            each(f"{path}[{key!r}]", x[key], y[key])

    def value(path: str, x: Any, y: Any) -> None:
        if type(x) is not type(y) or x != y:
            out.append(f"{path}: {x!r} vs {y!r}")

    ma, mb = a.mesh, b.mesh
    array("mesh.vertices", ma.vertices, mb.vertices)
    array("mesh.faces", ma.faces, mb.faces)
    mapping("mesh.parts", ma.parts, mb.parts, array)
    array("mesh.colors", ma.colors, mb.colors)
    value("mesh.units", ma.units, mb.units)
    value("units", a.units, b.units)
    value("scale", a.scale, b.scale)
    mapping("landmarks", a.landmarks, b.landmarks, value)
    mapping("regions", a.regions, b.regions, array)
    for attr in ("muscles", "wires", "bones", "channels"):
        xs, ys = getattr(a, attr), getattr(b, attr)
        if len(xs) != len(ys):
            out.append(f"{attr}: {len(xs)} vs {len(ys)} items")
            continue
        for i, (x, y) in enumerate(zip(xs, ys, strict=True)):
            if x != y:
                out.append(f"{attr}[{i}] {x.name!r} vs {y.name!r}: fields differ")
    wa, wb = a.skin_weights, b.skin_weights
    if wa.shape != wb.shape:
        out.append(f"skin_weights: shape {wa.shape} vs {wb.shape}")
    else:
        array("skin_weights.data", wa.data, wb.data)
        if not (np.array_equal(wa.indices, wb.indices) and np.array_equal(wa.indptr, wb.indptr)):
            out.append("skin_weights: different sparsity pattern")
    if json.dumps(thaw_json(a.metadata)) != json.dumps(thaw_json(b.metadata)):
        out.append("metadata: differs")
    anatomy_differences(a.anatomy, b.anatomy, array, value, out)
    return out[:limit]


def anatomy_differences(a: Anatomy, b: Anatomy, array, value, out: list[str]) -> None:
    """Append to ``out`` the paths where two anatomies differ (``array``/``value`` compare and report)."""
    for key in ("creases", "actions"):
        fa, fb = getattr(a, key), getattr(b, key)
        if len(fa) != len(fb):
            out.append(f"anatomy.{key}: {len(fa)} vs {len(fb)} items")
            continue
        for i, (x, y) in enumerate(zip(fa, fb, strict=True)):
            value(f"anatomy.{key}[{i}].name", x.name, y.name)
            value(f"anatomy.{key}[{i}].gains", dict(x.gains), dict(y.gains))
            array(f"anatomy.{key}[{i}].vertices", x.vertices, y.vertices)
            array(f"anatomy.{key}[{i}].offsets_rel", x.offsets_rel, y.offsets_rel)
    array("anatomy.skull.vertices", a.skull.vertices, b.skull.vertices)
    array("anatomy.skull.surface", a.skull.surface, b.skull.surface)
    array("anatomy.lip_contact", a.lip_contact, b.lip_contact)
    for name in ("vertices", "triangles", "bary", "offsets", "weights"):
        array(f"anatomy.accessories.{name}", getattr(a.accessories, name), getattr(b.accessories, name))
    array("anatomy.thickness_rel", a.thickness_rel, b.thickness_rel)
    if len(a.lids) != len(b.lids):
        out.append(f"anatomy.lids: {len(a.lids)} vs {len(b.lids)} items")
    else:
        for i, (x, y) in enumerate(zip(a.lids, b.lids, strict=True)):
            value(f"anatomy.lids[{i}].side", x.side, y.side)
            value(f"anatomy.lids[{i}].tucked", x.tucked, y.tucked)
            array(f"anatomy.lids[{i}].upper", x.upper, y.upper)
            array(f"anatomy.lids[{i}].lower", x.lower, y.lower)


def rigs_equal(a: Rig, b: Rig) -> bool:
    """True when two rigs are identical field by field, bit for bit (see ``rig_differences``)."""
    return not rig_differences(a, b, limit=1)
