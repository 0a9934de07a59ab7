"""The ``.mrig`` file format: a versioned, lossless zip of one ``Rig``.

A ``.mrig`` file is a zip archive (ZIP_DEFLATED) of three members:

- ``manifest.json``: ``{"format": "mimetic-rig", "version": 1, "mimetic": "<package version>"}``;
- ``rig.json``: all small structured data (units, scale, landmarks, muscles, wires, bones,
  channels, metadata). Arrays are referenced by their key in ``arrays.npz``;
- ``arrays.npz``: every array, as ``.npy`` members (no pickles): mesh vertices (n, 3) float64,
  faces (m, 3) int64, parts (k,) int64, colors (n, 3) float32, regions and wire vertex sets
  (k,) int64, wire weights (p,) float64, skin weights as CSR ``data`` (nnz,) float64, ``indices``
  (nnz,) int64 and ``indptr`` (n + 1,) int64, and the anatomy's arrays (crease vertices and
  offsets, skull vertices and surface, lip contact pairs, accessory rivets, tissue thickness, lid
  contact vertices, tissue action vertices and offsets).

Versions: 2 adds the rig's anatomy (``Rig.anatomy``: creases, skull, lip contact, accessories,
tissue thickness, and since they were added, ``lids`` and ``actions``). Version-1 files still load:
their anatomy is derived from the rest of the rig by the current rules
(``mimetic.rig.anatomy.derive_anatomy``), with a log line saying so; a version-2 file written before
``lids`` or ``actions`` existed gets them derived the same way (for the channels it has: a rig
saved before the tissue channels existed has no cheek puff or lip roll until it is rebuilt).

Floats are stored bit-exactly (arrays as raw float64; JSON numbers with Python's round-trip
``repr``), and every name and order is kept, so ``load_rig(save_rig(rig, p)) == rig``. Files are
written with fixed timestamps, so the same rig always gives the same bytes.

``load_rig`` raises ``RigFormatError`` for a file it cannot read (missing, not a zip, truncated,
not a rig, a newer version, a missing or mistyped field, a wrong array) and ``RigError`` when the
contents are readable but inconsistent (``validate_rig``).

Over 600 lines because the format's encoder and decoder of every element sit side by side, so a
field's write and read are changed together.
"""

from __future__ import annotations

import io
import json
import logging
import os
import zipfile
import zlib
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import scipy.sparse as sp

from mimetic import __version__
from mimetic.atomic import atomic_write
from mimetic.errors import RigError, RigFormatError
from mimetic.mesh.model import Mesh, SurfacePoint
from mimetic.rig.anatomy import Accessories, Anatomy, Crease, LidContact, Skull, derive_anatomy
from mimetic.rig.model import Bone, Channel, Muscle, Rig, Wire, thaw_json
from mimetic.rig.validate import validate_rig

log = logging.getLogger(__name__)

FORMAT_NAME = "mimetic-rig"
FORMAT_VERSION = 2
"""The version ``save_rig`` writes and the newest ``load_rig`` reads (1 and 2)."""

MANIFEST, RIG_JSON, ARRAYS = "manifest.json", "rig.json", "arrays.npz"
_EPOCH = (1980, 1, 1, 0, 0, 0)  # fixed zip timestamps → reproducible bytes
_RESAVE = "re-save the rig with mimetic.rig.save_rig"


# --------------------------------------------------------------------------- saving


def save_rig(rig: Rig, path: str | os.PathLike[str]) -> Path:
    """Write ``rig`` to ``path`` (conventionally ``*.mrig``) and return the path.

    The file is written to a temporary file beside ``path`` and moved into place only when it
    is complete, so a failure never leaves half a file over a good one.
    """
    if not isinstance(rig, Rig):
        raise TypeError(f"save_rig expects a Rig; got {type(rig).__name__}")
    validate_rig(rig)
    members = _encode(rig)
    path = Path(path)
    with atomic_write(path, "wb") as file, zipfile.ZipFile(file, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(_zip_info(name, zipfile.ZIP_DEFLATED), data)
    log.info("rig written to %s (%d vertices, %d muscles)", path, rig.n_vertices, len(rig.muscles))
    return path


def _zip_info(name: str, compression: int) -> zipfile.ZipInfo:
    info = zipfile.ZipInfo(name, date_time=_EPOCH)
    info.compress_type = compression
    info.external_attr = 0o644 << 16
    return info


def _point_json(point: SurfacePoint) -> dict[str, Any]:
    return {"face": int(point.face), "bary": [float(b) for b in point.bary]}


def _encode(rig: Rig) -> dict[str, bytes]:
    """The three archive members of ``rig``: manifest, rig.json and arrays.npz, as bytes."""
    arrays: dict[str, np.ndarray] = {}

    def put(key: str, array: np.ndarray) -> str:
        assert key not in arrays, key
        arrays[key] = np.ascontiguousarray(array)
        return key

    mesh = rig.mesh
    weights = rig.skin_weights
    doc = {
        "units": rig.units,
        "scale": rig.scale,
        "mesh": {
            "units": mesh.units,
            "vertices": put("mesh.vertices", mesh.vertices),
            "faces": put("mesh.faces", mesh.faces),
            "parts": {
                name: put(f"mesh.parts.{i}", faces) for i, (name, faces) in enumerate(mesh.parts.items())
            },
            "colors": None if mesh.colors is None else put("mesh.colors", mesh.colors),
        },
        "landmarks": {name: _point_json(point) for name, point in rig.landmarks.items()},
        "regions": {name: put(f"regions.{i}", v) for i, (name, v) in enumerate(rig.regions.items())},
        "channels": [
            {
                "name": c.name,
                "minimum": c.minimum,
                "maximum": c.maximum,
                "default": c.default,
                "unit": c.unit,
                "group": c.group,
            }
            for c in rig.channels
        ],
        "muscles": [
            {
                "name": m.name,
                "kind": m.kind,
                "side": m.side,
                "origin": _point_json(m.origin),
                "insertion": _point_json(m.insertion),
                "width_rel": m.width_rel,
                "falloff_start_rel": m.falloff_start_rel,
                "falloff_end_rel": m.falloff_end_rel,
                "angle_rad": m.angle_rad,
                "origin_inset_rel": m.origin_inset_rel,
                "reversed": m.reversed,
                "region": m.region,
            }
            for m in rig.muscles
        ],
        "wires": [
            {
                "name": w.name,
                "side": w.side,
                "points": [_point_json(p) for p in w.points],
                "dropoff_rel": w.dropoff_rel,
                "vertices": put(f"wires.{i}.vertices", w.vertices),
                "muscle_weights": {
                    name: put(f"wires.{i}.muscle_weights.{j}", weight)
                    for j, (name, weight) in enumerate(w.muscle_weights.items())
                },
                "rest_weight": put(f"wires.{i}.rest_weight", w.rest_weight),
            }
            for i, w in enumerate(rig.wires)
        ],
        "bones": [
            {"name": b.name, "parent": b.parent, "head": b.head.tolist(), "tail": b.tail.tolist()}
            for b in rig.bones
        ],
        "skin_weights": {
            "shape": list(weights.shape),
            "data": put("skin_weights.data", weights.data),
            "indices": put("skin_weights.indices", weights.indices.astype(np.int64)),
            "indptr": put("skin_weights.indptr", weights.indptr.astype(np.int64)),
        },
        "metadata": thaw_json(rig.metadata),
        "anatomy": _anatomy_json(rig.anatomy, put),
    }
    manifest = {"format": FORMAT_NAME, "version": FORMAT_VERSION, "mimetic": __version__}
    return {
        MANIFEST: json.dumps(manifest, indent=1).encode(),
        RIG_JSON: json.dumps(doc, indent=1, ensure_ascii=False, allow_nan=False).encode(),
        ARRAYS: _npz_bytes(arrays),
    }


def _fields_json(fields: tuple[Crease, ...], key: str, put) -> list[dict[str, Any]]:
    """Creases or actions as rig.json objects, their arrays stored with ``put``."""
    return [
        {
            "name": c.name,
            "gains": dict(c.gains),
            "vertices": put(f"anatomy.{key}.{i}.vertices", c.vertices),
            "offsets_rel": put(f"anatomy.{key}.{i}.offsets_rel", c.offsets_rel),
        }
        for i, c in enumerate(fields)
    ]


def _anatomy_json(anatomy: Anatomy, put) -> dict[str, Any]:
    """rig.json's ``anatomy`` object; ``put(key, array)`` stores an array and returns its key."""
    acc, skull = anatomy.accessories, anatomy.skull
    return {
        "creases": _fields_json(anatomy.creases, "creases", put),
        "actions": _fields_json(anatomy.actions, "actions", put),
        "skull": {
            "vertices": put("anatomy.skull.vertices", skull.vertices),
            "surface": put("anatomy.skull.surface", skull.surface),
        },
        "lip_contact": put("anatomy.lip_contact", anatomy.lip_contact),
        "accessories": {
            name: put(f"anatomy.accessories.{name}", getattr(acc, name))
            for name in ("vertices", "triangles", "bary", "offsets", "weights")
        },
        "thickness_rel": put("anatomy.thickness_rel", anatomy.thickness_rel),
        "lids": [
            {
                "side": c.side,
                "tucked": c.tucked,
                "upper": put(f"anatomy.lids.{i}.upper", c.upper),
                "lower": put(f"anatomy.lids.{i}.lower", c.lower),
            }
            for i, c in enumerate(anatomy.lids)
        ],
    }


def _npz_bytes(arrays: Mapping[str, np.ndarray]) -> bytes:
    """An uncompressed ``.npz`` (the outer zip compresses it) with fixed timestamps and no pickles."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", zipfile.ZIP_STORED) as archive:
        for key, array in arrays.items():
            with archive.open(_zip_info(f"{key}.npy", zipfile.ZIP_STORED), "w", force_zip64=True) as member:
                np.lib.format.write_array(member, array, allow_pickle=False)
    return buffer.getvalue()


# --------------------------------------------------------------------------- loading


def load_rig(path: str | os.PathLike[str]) -> Rig:
    """Read a ``.mrig`` file written by ``save_rig``; the returned rig is validated.

    Raises
    ------
    RigFormatError
        The file is missing, not a zip, truncated, not a mimetic rig, written by a newer format
        version, or has a missing/mistyped field or a wrong array. The message names the
        problem (and the JSON path or array key) and the fix.
    RigError
        The file is readable but its contents are inconsistent (see ``validate_rig``).
    """
    path = Path(path)
    members, version = _read_members(path)
    try:
        doc = _parse_json(members[RIG_JSON], RIG_JSON, path)
        arrays = _load_npz(members[ARRAYS], path)
        if version < 2:
            log.info("%s: a format-1 rig; its anatomy is derived by the current rules", path.name)
        return _decode(doc, arrays, version)
    except RigFormatError as error:
        raise RigFormatError(f"{path.name}: {error}") from None
    except RigError as error:
        raise RigError(f"{path.name}: {error}") from None


def _read_members(path: Path) -> tuple[dict[str, bytes], int]:
    """The archive's manifest-checked members ``rig.json`` and ``arrays.npz``, and its format version."""
    if not path.exists():
        raise RigFormatError(f"{path}: no such file; check the path (rig files end in .mrig)")
    if path.is_dir():
        raise RigFormatError(f"{path} is a directory; give the path of a .mrig file")
    with path.open("rb") as file:
        head = file.read(4)
    if not head:
        raise RigFormatError(f"{path.name} is empty (0 bytes); it was not saved completely — {_RESAVE}")
    if head != b"PK\x03\x04":
        raise RigFormatError(
            f"{path.name} is not a mimetic rig: it is not a zip archive (a .mrig file is the zip written by "
            "mimetic.rig.save_rig). Check that you passed the rig and not a mesh."
        )
    truncated = (
        f"{path.name} is truncated or damaged ({{}}); it was probably cut short by an interrupted copy "
        f"or download — copy it again, or {_RESAVE}"
    )
    try:
        with zipfile.ZipFile(path) as archive:
            names = set(archive.namelist())
            if MANIFEST not in names:
                raise RigFormatError(
                    f"{path.name} is not a mimetic rig: the zip has no {MANIFEST} "
                    f"(it holds {sorted(names)[:5]}); {_RESAVE}"
                )
            manifest = _parse_json(archive.read(MANIFEST), MANIFEST, path)
            version = _check_manifest(manifest, path)
            missing = [name for name in (RIG_JSON, ARRAYS) if name not in names]
            if missing:
                raise RigFormatError(f"{path.name} is incomplete: {', '.join(missing)} is missing; {_RESAVE}")
            return {name: archive.read(name) for name in (RIG_JSON, ARRAYS)}, version
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError) as error:
        raise RigFormatError(truncated.format(error)) from None


def _check_manifest(manifest: Any, path: Path) -> int:
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT_NAME:
        found = manifest.get("format") if isinstance(manifest, dict) else manifest
        raise RigFormatError(
            f"{path.name} is not a mimetic rig: {MANIFEST} has format={found!r}, expected {FORMAT_NAME!r}"
        )
    version = manifest.get("version")
    if isinstance(version, bool) or not isinstance(version, int):
        raise RigFormatError(f"{path.name}: {MANIFEST}: version should be an integer; got {version!r}")
    if version > FORMAT_VERSION:
        writer = manifest.get("mimetic")
        by = f" (mimetic {writer})" if isinstance(writer, str) else ""
        raise RigFormatError(
            f"{path.name} was written by mimetic format version {version}{by}; this mimetic ({__version__}) "
            f"reads versions ≤ {FORMAT_VERSION} — upgrade mimetic (pip install -U mimetic)"
        )
    if version < 1:
        raise RigFormatError(f"{path.name}: {MANIFEST}: version={version} is not a valid format version")
    return version


class _DuplicateKey(Exception):
    pass


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for key, value in pairs:
        if key in out:
            raise _DuplicateKey(key)
        out[key] = value
    return out


def _reject_constant(name: str) -> Any:
    raise ValueError(f"{name} is not valid JSON (numbers must be finite)")


def _parse_json(data: bytes, member: str, path: Path) -> Any:
    try:
        return json.loads(data, object_pairs_hook=_no_duplicates, parse_constant=_reject_constant)
    except _DuplicateKey as error:
        raise RigFormatError(
            f"{path.name}: {member} has a duplicate key {error.args[0]!r}; {_RESAVE}"
        ) from None
    except ValueError as error:  # JSONDecodeError, UnicodeDecodeError, NaN
        raise RigFormatError(f"{path.name}: {member} is not valid JSON ({error}); {_RESAVE}") from None


def _load_npz(data: bytes, path: Path) -> dict[str, np.ndarray]:
    """Every array of ``arrays.npz``, loaded without pickles (object arrays are refused)."""
    try:
        npz = np.load(io.BytesIO(data), allow_pickle=False)
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as error:
        raise RigFormatError(f"{ARRAYS} is not a valid .npz archive ({error}); {_RESAVE}") from None
    if not isinstance(npz, np.lib.npyio.NpzFile):
        raise RigFormatError(f"{ARRAYS} is a single .npy array, not an .npz archive; {_RESAVE}")
    arrays = {}
    with npz:
        for key in npz.files:
            try:
                arrays[key] = npz[key]
            except ValueError as error:
                if "allow_pickle" in str(error):
                    raise RigFormatError(
                        f"{ARRAYS}: array {key!r} holds Python objects (a pickle), which mimetic never "
                        "writes and refuses to load because unpickling can run code; the file was not "
                        f"written by mimetic or was modified — {_RESAVE}"
                    ) from None
                raise RigFormatError(f"{ARRAYS}: array {key!r} is damaged ({error}); {_RESAVE}") from None
            except (OSError, EOFError, zipfile.BadZipFile, zlib.error) as error:
                raise RigFormatError(f"{ARRAYS}: array {key!r} is damaged ({error}); {_RESAVE}") from None
    return arrays


# ---- typed access to rig.json, naming the JSON path in every error

_MISSING = object()
_KINDS: dict[str, tuple[type, ...]] = {
    "a string": (str,),
    "a number": (int, float),
    "an integer": (int,),
    "a boolean": (bool,),
    "a list": (list,),
    "an object": (dict,),
}


def _json_type(value: Any) -> str:
    return {
        dict: "object",
        list: "list",
        str: "string",
        bool: "boolean",
        int: "integer",
        float: "number",
    }.get(type(value), type(value).__name__)


def _get(obj: dict, key: str, path: str, kind: str, *, nullable: bool = False) -> Any:
    """``obj[key]`` checked to be of ``kind`` (a key of ``_KINDS``); ``path`` names ``obj``."""
    where = f"{path}.{key}" if path else key
    if key not in obj:
        raise RigFormatError(f"rig.json: {where} is missing; {_RESAVE}")
    value = obj[key]
    if value is None and nullable:
        return None
    numeric = kind in ("a number", "an integer")
    if not isinstance(value, _KINDS[kind]) or (numeric and isinstance(value, bool)):
        shown = json.dumps(value)
        shown = shown if len(shown) <= 40 else shown[:37] + "..."
        raise RigFormatError(
            f"rig.json: {where} should be {kind}{' or null' if nullable else ''}; "
            f"got {shown} ({_json_type(value)}); {_RESAVE}"
        )
    return float(value) if kind == "a number" else value


def _vector(obj: dict, key: str, path: str, length: int) -> list[float]:
    values = _get(obj, key, path, "a list")
    if len(values) != length or any(isinstance(v, bool) or not isinstance(v, (int, float)) for v in values):
        raise RigFormatError(
            f"rig.json: {path}.{key} should be a list of {length} numbers; got {values!r}"[:200]
        )
    return [float(v) for v in values]


def _point(obj: dict, key: str, path: str) -> SurfacePoint:
    return _point_value(_get(obj, key, path, "an object"), f"{path}.{key}" if path else key)


def _point_value(point: Any, where: str) -> SurfacePoint:
    if not isinstance(point, dict):
        raise RigFormatError(
            f"rig.json: {where} should be an object {{face, bary}}; got a {_json_type(point)}"
        )
    face = _get(point, "face", where, "an integer")
    bary = _vector(point, "bary", where, 3)
    return SurfacePoint(face, (bary[0], bary[1], bary[2]))


class _Arrays:
    """Arrays of ``arrays.npz`` fetched by the key stored in rig.json, checked for dtype and shape."""

    def __init__(self, arrays: Mapping[str, np.ndarray]) -> None:
        self.arrays = arrays

    def get(self, obj: dict, key: str, path: str, dtype: type, shape: tuple[int | None, ...]) -> np.ndarray:
        where = f"{path}.{key}" if path else key
        ref = _get(obj, key, path, "a string")
        if ref not in self.arrays:
            raise RigFormatError(
                f"{ARRAYS} has no array {ref!r} (referenced by rig.json: {where}); the file is incomplete — "
                f"{_RESAVE}"
            )
        array = self.arrays[ref]
        expected = (
            "("
            + ", ".join("?" if s is None else str(s) for s in shape)
            + ("," if len(shape) == 1 else "")
            + ")"
        )
        if array.ndim != len(shape) or any(
            s is not None and s != a for s, a in zip(shape, array.shape, strict=True)
        ):
            raise RigFormatError(
                f"{ARRAYS}: array {ref!r} (rig.json: {where}) has shape {array.shape}; expected {expected}; "
                f"{_RESAVE}"
            )
        if array.dtype != np.dtype(dtype):
            raise RigFormatError(
                f"{ARRAYS}: array {ref!r} (rig.json: {where}) has dtype {array.dtype}; "
                f"expected {np.dtype(dtype)}; {_RESAVE}"
            )
        return array


def _decode(doc: Any, arrays: Mapping[str, np.ndarray], version: int = FORMAT_VERSION) -> Rig:
    """Build a ``Rig`` from parsed rig.json and the loaded arrays (types checked before values); a
    version-1 document has no anatomy, which the ``Rig`` then derives."""
    if not isinstance(doc, dict):
        raise RigFormatError(f"rig.json should hold an object; got a {_json_type(doc)}")
    A = _Arrays(arrays)

    # mesh
    m = _get(doc, "mesh", "", "an object")
    vertices = A.get(m, "vertices", "mesh", np.float64, (None, 3))
    faces = A.get(m, "faces", "mesh", np.int64, (None, 3))
    parts_doc = _get(m, "parts", "mesh", "an object")
    parts = {name: A.get(parts_doc, name, "mesh.parts", np.int64, (None,)) for name in parts_doc}
    colors = None
    if _get(m, "colors", "mesh", "a string", nullable=True) is not None:
        colors = A.get(m, "colors", "mesh", np.float32, (len(vertices), 3))
    mesh = Mesh(vertices, faces, parts, colors, _get(m, "units", "mesh", "a string", nullable=True))

    landmarks_doc = _get(doc, "landmarks", "", "an object")
    landmarks = {name: _point(landmarks_doc, name, "landmarks") for name in landmarks_doc}
    regions_doc = _get(doc, "regions", "", "an object")
    regions = {name: A.get(regions_doc, name, "regions", np.int64, (None,)) for name in regions_doc}

    channels = []
    for i, c in enumerate(_get(doc, "channels", "", "a list")):
        where = f"channels[{i}]"
        if not isinstance(c, dict):
            raise RigFormatError(f"rig.json: {where} should be an object; got a {_json_type(c)}")
        channels.append(
            Channel(
                name=_get(c, "name", where, "a string"),
                minimum=_get(c, "minimum", where, "a number"),
                maximum=_get(c, "maximum", where, "a number"),
                default=_get(c, "default", where, "a number"),
                unit=_get(c, "unit", where, "a string"),
                group=_get(c, "group", where, "a string"),
            )
        )

    muscles = []
    for i, mu in enumerate(_get(doc, "muscles", "", "a list")):
        where = f"muscles[{i}]"
        if not isinstance(mu, dict):
            raise RigFormatError(f"rig.json: {where} should be an object; got a {_json_type(mu)}")
        muscles.append(
            Muscle(
                name=_get(mu, "name", where, "a string"),
                kind=_get(mu, "kind", where, "a string"),
                side=_get(mu, "side", where, "a string"),
                origin=_point(mu, "origin", where),
                insertion=_point(mu, "insertion", where),
                width_rel=_get(mu, "width_rel", where, "a number"),
                falloff_start_rel=_get(mu, "falloff_start_rel", where, "a number"),
                falloff_end_rel=_get(mu, "falloff_end_rel", where, "a number"),
                angle_rad=_get(mu, "angle_rad", where, "a number"),
                origin_inset_rel=_get(mu, "origin_inset_rel", where, "a number"),
                reversed=_get(mu, "reversed", where, "a boolean"),
                region=_get(mu, "region", where, "a string", nullable=True),
            )
        )

    wires = []
    for i, w in enumerate(_get(doc, "wires", "", "a list")):
        where = f"wires[{i}]"
        if not isinstance(w, dict):
            raise RigFormatError(f"rig.json: {where} should be an object; got a {_json_type(w)}")
        points_doc = _get(w, "points", where, "a list")
        points = tuple(_point_value(p, f"{where}.points[{j}]") for j, p in enumerate(points_doc))
        p = len(points)
        weights_doc = _get(w, "muscle_weights", where, "an object")
        wires.append(
            Wire(
                name=_get(w, "name", where, "a string"),
                side=_get(w, "side", where, "a string"),
                points=points,
                dropoff_rel=_get(w, "dropoff_rel", where, "a number"),
                vertices=A.get(w, "vertices", where, np.int64, (None,)),
                muscle_weights={
                    name: A.get(weights_doc, name, f"{where}.muscle_weights", np.float64, (p,))
                    for name in weights_doc
                },
                rest_weight=A.get(w, "rest_weight", where, np.float64, (p,)),
            )
        )

    bones = []
    for i, b in enumerate(_get(doc, "bones", "", "a list")):
        where = f"bones[{i}]"
        if not isinstance(b, dict):
            raise RigFormatError(f"rig.json: {where} should be an object; got a {_json_type(b)}")
        bones.append(
            Bone(
                name=_get(b, "name", where, "a string"),
                parent=_get(b, "parent", where, "a string", nullable=True),
                head=np.array(_vector(b, "head", where, 3)),
                tail=np.array(_vector(b, "tail", where, 3)),
            )
        )

    s = _get(doc, "skin_weights", "", "an object")
    shape = _get(s, "shape", "skin_weights", "a list")
    if len(shape) != 2 or any(isinstance(v, bool) or not isinstance(v, int) or v < 0 for v in shape):
        raise RigFormatError(f"rig.json: skin_weights.shape should be 2 non-negative integers; got {shape!r}")
    data = A.get(s, "data", "skin_weights", np.float64, (None,))
    indices = A.get(s, "indices", "skin_weights", np.int64, (len(data),))
    indptr = A.get(s, "indptr", "skin_weights", np.int64, (shape[0] + 1,))
    try:
        skin_weights = sp.csr_matrix((data, indices, indptr), shape=tuple(shape))
        skin_weights.check_format(full_check=True)
    except ValueError as error:
        raise RigFormatError(
            f"{ARRAYS}: the skin_weights CSR arrays are inconsistent ({error}); {_RESAVE}"
        ) from None

    units, scale = _get(doc, "units", "", "a string"), _get(doc, "scale", "", "a number")
    anatomy = None
    if version >= 2:
        anatomy_doc = _get(doc, "anatomy", "", "an object")
        anatomy = _decode_anatomy(anatomy_doc, A, len(bones))
        missing = [key for key in ("lids", "actions") if key not in anatomy_doc]
        if missing:  # written before the lids' contact and the tissue actions were stored
            log.info("rig.json: the anatomy has no %s; derived by the current rules", " or ".join(missing))
            names = tuple(c.name for c in channels)
            derived = derive_anatomy(mesh, landmarks, regions, skin_weights, scale, names)
            anatomy = replace(anatomy, **{key: getattr(derived, key) for key in missing})
    return Rig(
        mesh=mesh,
        units=units,
        scale=scale,
        landmarks=landmarks,
        regions=regions,
        muscles=tuple(muscles),
        wires=tuple(wires),
        bones=tuple(bones),
        skin_weights=skin_weights,
        channels=tuple(channels),
        metadata=_get(doc, "metadata", "", "an object"),
        anatomy=anatomy,
    )


def _decode_fields(doc: dict, key: str, A: _Arrays) -> tuple[Crease, ...]:
    """Creases or actions (``key``) from rig.json's ``anatomy`` object; absent actions are none."""
    if key == "actions" and key not in doc:
        return ()
    out = []
    for i, c in enumerate(_get(doc, key, "anatomy", "a list")):
        where = f"anatomy.{key}[{i}]"
        if not isinstance(c, dict):
            raise RigFormatError(f"rig.json: {where} should be an object; got a {_json_type(c)}")
        vertices = A.get(c, "vertices", where, np.int64, (None,))
        gains = _get(c, "gains", where, "an object")
        for channel, gain in gains.items():
            if isinstance(gain, bool) or not isinstance(gain, (int, float)):
                raise RigFormatError(f"rig.json: {where}.gains[{channel!r}] should be a number; got {gain!r}")
        out.append(
            Crease(
                name=_get(c, "name", where, "a string"),
                gains=gains,
                vertices=vertices,
                offsets_rel=A.get(c, "offsets_rel", where, np.float64, (len(vertices), 3)),
            )
        )
    return tuple(out)


def _decode_anatomy(doc: dict, A: _Arrays, n_bones: int) -> Anatomy:
    """``Anatomy`` from rig.json's ``anatomy`` object (array shapes and dtypes checked)."""
    skull_doc = _get(doc, "skull", "anatomy", "an object")
    skull_ids = A.get(skull_doc, "vertices", "anatomy.skull", np.int64, (None,))
    acc_doc = _get(doc, "accessories", "anatomy", "an object")
    acc_ids = A.get(acc_doc, "vertices", "anatomy.accessories", np.int64, (None,))
    a = len(acc_ids)
    return Anatomy(
        creases=_decode_fields(doc, "creases", A),
        skull=Skull(skull_ids, A.get(skull_doc, "surface", "anatomy.skull", np.float64, (len(skull_ids), 3))),
        lip_contact=A.get(doc, "lip_contact", "anatomy", np.int64, (None, 2)),
        accessories=Accessories(
            acc_ids,
            A.get(acc_doc, "triangles", "anatomy.accessories", np.int64, (a, 3)),
            A.get(acc_doc, "bary", "anatomy.accessories", np.float64, (a, 3)),
            A.get(acc_doc, "offsets", "anatomy.accessories", np.float64, (a, 3)),
            A.get(acc_doc, "weights", "anatomy.accessories", np.float64, (a, n_bones)),
        ),
        thickness_rel=A.get(doc, "thickness_rel", "anatomy", np.float64, (None,)),
        lids=tuple(_decode_lid(c, i, A) for i, c in enumerate(_get(doc, "lids", "anatomy", "a list")))
        if "lids" in doc
        else (),
        actions=_decode_fields(doc, "actions", A),
    )


def _decode_lid(doc: Any, i: int, A: _Arrays) -> LidContact:
    """One ``LidContact`` from rig.json's ``anatomy.lids[i]``."""
    where = f"anatomy.lids[{i}]"
    if not isinstance(doc, dict):
        raise RigFormatError(f"rig.json: {where} should be an object; got a {_json_type(doc)}")
    return LidContact(
        side=_get(doc, "side", where, "a string"),
        upper=A.get(doc, "upper", where, np.int64, (None,)),
        lower=A.get(doc, "lower", where, np.int64, (None,)),
        tucked=_get(doc, "tucked", where, "a boolean"),
    )
