"""Read and write meshes (.obj, .ply, .stl, .glb, .gltf) without changing their vertex order.

Every rig element refers to vertices by index, so a mesh must come back from disk with exactly
the vertices, in exactly the order, it was written with. What each format keeps:

========  =============  ==========  ===========================  ====================================
format    vertex order   precision   parts                        colours / units
========  =============  ==========  ===========================  ====================================
.obj      exact          float64     ``g`` groups (``o`` too),    ``v x y z r g b``, ``.mtl`` ``Kd`` /
                                     ``usemtl`` materials         ``# units: cm``
.ply      exact          float64     not stored (merged)          uchar RGB / ``comment units cm``
.glb      exact          float32     one node per part            COLOR_0, ``baseColorFactor`` /
                                                                  mesh ``extras.units``
.gltf     exact          float32     one node per part            as .glb
.stl      first use      float32     not stored (merged)          none / none
========  =============  ==========  ===========================  ====================================

OBJ is read and written by mimetic itself: trimesh 5.2 splits OBJ vertices by their ``vt``/``vn``
indices (or, with ``maintain_order=True``, drops unused trailing vertices), and returns groups in
reverse order, merged by name. OBJ polygons are fan-triangulated in place, so face order follows
the file. PLY is read by trimesh and written by mimetic (trimesh writes float32); a PLY mixing
triangles and quads comes back with the triangles first (trimesh's order, deterministic). glTF is
read and written by trimesh with processing off; node order comes from the file's own JSON,
because trimesh's scene graph lists nodes in reverse. STL has no vertex indices at all: loading
merges equal corners in order of first use.

Materials are read, not written: an OBJ's ``usemtl`` materials (with their ``.mtl`` colour and
opacity) and a multi-part glTF's primitive materials become ``Mesh.materials`` of the parts named
after them, and their flat colours become ``Mesh.colors`` when they colour every face. Saving
keeps those colours (as vertex colours) and parts, not the materials themselves.
"""

from __future__ import annotations

import copy
import io
import itertools
import json
import logging
import os
import re
import struct
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from mimetic.atomic import atomic_write_bytes
from mimetic.errors import MeshError, MimeticError, MimeticWarning
from mimetic.mesh.model import Material, Mesh
from mimetic.mesh.units import check_units, detect_units, largest_extent, units_for_extent
from mimetic.mesh.validate import MIN_FACES

log = logging.getLogger(__name__)

SUPPORTED_FORMATS = (".obj", ".ply", ".stl", ".glb", ".gltf")
"""File extensions :func:`load_mesh` and :func:`save_mesh` accept (case-insensitive)."""

DEFAULT_COLOR = 0.6
"""Grey given to vertices of glTF nodes without COLOR_0 when other nodes have it."""

_UNIT_ALIASES = {
    **{u: u for u in ("mm", "cm", "dm", "m", "in")},
    **{
        f"{p}{s}": u
        for p, u in (("millimet", "mm"), ("centimet", "cm"), ("decimet", "dm"), ("met", "m"))
        for s in ("er", "ers", "re", "res")
    },
    "inch": "in",
    "inches": "in",
}


@dataclass
class _Loaded:
    """What a format reader found, before checks: arrays in file order."""

    vertices: np.ndarray  # (n, 3) float64
    faces: np.ndarray  # (m, 3) int64
    parts: dict[str, np.ndarray] = field(default_factory=dict)
    colors: np.ndarray | None = None  # (n, 3) float32 in [0, 1]
    units: str | None = None  # as written in the file, not yet checked
    materials: dict[str, Material] = field(default_factory=dict)  # part name -> its material


# --- public API -----------------------------------------------------------------------------------


def load_mesh(path: str | os.PathLike[str], *, units: str | None = None, check: bool = True) -> Mesh:
    """Read a triangle mesh, keeping its vertices exactly as stored (no merging or reordering).

    Parameters
    ----------
    path : path-like
        A .obj, .ply, .stl, .glb or .gltf file (a .gltf may refer to .bin files beside it).
    units : {"mm", "cm", "dm", "m", "in"}, optional
        The unit the coordinates are in. It wins over anything else; the coordinates are never
        rescaled (use :func:`~mimetic.mesh.units.convert_units` for that). When omitted, the units
        written in the file are used (see the module table), else :func:`detect_units` guesses
        them from the head's size, with a ``MimeticWarning`` that says the guess.
    check : bool
        When True (default), reject meshes every later step would fail on: non-finite
        coordinates, fewer than ``MIN_FACES`` faces, or units that are neither given, stored nor
        detectable. When False, such meshes load (``units`` may be None) so that
        :func:`~mimetic.mesh.validate.validate_mesh` can report on them.

    Returns
    -------
    mesh : Mesh
        ``vertices`` (n, 3) float64 in file order, ``faces`` (m, 3) int64 in file order (OBJ
        polygons are fan-triangulated in place), ``parts`` from OBJ groups or glTF nodes
        (``{}`` for a single geometry), per-vertex ``colors`` when stored, and ``units``.

    Raises
    ------
    MeshError
        Naming the file: it is missing, has an unsupported extension, is not a mesh of its
        format, is truncated or corrupt, has no faces or face indices out of range, or (with
        ``check``) fails the checks above.
    """
    src = str(path)
    path = Path(path)
    ext = _extension(path, src)
    if units is not None:
        units = check_units(units)
    data = read_input(path, src, MeshError, "mesh")
    reader = {".obj": _read_obj, ".ply": _read_ply, ".stl": _read_stl, ".glb": _read_glb, ".gltf": _read_gltf}
    loaded = reader[ext](data, src, path)

    vertices = np.ascontiguousarray(loaded.vertices, dtype=np.float64)
    faces = np.ascontiguousarray(loaded.faces, dtype=np.int64).reshape(-1, 3)
    n, m = len(vertices), len(faces)
    if m == 0:
        raise MeshError(
            f"{src}: contains no faces ({n} vertices): it is empty or a point cloud. mimetic needs a "
            "triangle surface; export the mesh with its faces."
        )
    if faces.min() < 0 or faces.max() >= n:
        bad = int(np.flatnonzero((faces < 0).any(axis=1) | (faces >= n).any(axis=1))[0])
        raise MeshError(
            f"{src}: face {bad} refers to vertex {faces[bad].tolist()} but the file has {n} vertices "
            "(indices 0..n-1). The file is corrupt; re-export it."
        )
    if check:
        _check_loaded(vertices, m, src)
    units = units or _file_units(loaded.units, vertices, src)
    if units is None:
        extent = largest_extent(vertices)
        units = units_for_extent(extent)
        if units is None and check:  # re-run to raise detect_units' own message
            try:
                detect_units(vertices)
            except MeshError as error:
                raise MeshError(f"{src}: {error}") from None
        if units is not None:
            warnings.warn(
                f"{src} does not say its units; its size ({extent:.4g} across) suggests {units}. If that "
                f'is wrong, give them: units="cm" (CLI --units cm; mm, cm, dm, m or in)',
                MimeticWarning,
                stacklevel=2,
            )
    mesh = Mesh(vertices, faces, loaded.parts, loaded.colors, units, loaded.materials)
    log.info("loaded %s: %d vertices, %d faces, %d parts, units %s", src, n, m, len(mesh.parts), units)
    return mesh


def save_mesh(mesh: Mesh, path: str | os.PathLike[str]) -> Path:
    """Write ``mesh`` to ``path`` atomically, in the format its extension names.

    Parameters
    ----------
    mesh : Mesh
        Written in its own vertex and face order.
    path : path-like
        .obj (parts become ``g`` groups; a face in several parts gets ``g a b``), .ply or .stl
        (one merged surface, parts dropped with a log warning), .glb or .gltf (one named node per
        part; the .gltf embeds its buffer). ``mesh.units`` is recorded where the format allows.

    Returns
    -------
    path : Path
        The file written.

    Raises
    ------
    MeshError
        Unsupported extension; a part name an OBJ group cannot hold (empty or with spaces); for
        glTF, parts that are not consecutive blocks of faces and vertices.
    WriteError
        The folder does not exist or is not writable. The target is never left half-written.

    Warns
    -----
    MimeticWarning
        For .stl when the mesh read back would not have the same vertices in the same order.
    """
    src = str(path)
    path = Path(path)
    ext = _extension(path, src)
    encoder = {
        ".obj": encode_obj,
        ".ply": _encode_ply,
        ".stl": _encode_stl,
        ".glb": _encode_glb,
        ".gltf": _encode_gltf,
    }
    data = encoder[ext](mesh, src)
    atomic_write_bytes(path, data)
    log.info("wrote %s: %d vertices, %d faces", src, mesh.n_vertices, mesh.n_faces)
    return path


# --- shared helpers -------------------------------------------------------------------------------


def _extension(path: Path, src: str) -> str:
    ext = path.suffix.lower()
    if ext not in SUPPORTED_FORMATS:
        shown = f"'{path.suffix}'" if path.suffix else "no extension"
        raise MeshError(
            f"{src}: unsupported mesh format ({shown}); supported: {', '.join(SUPPORTED_FORMATS)}. "
            "Convert the file (e.g. in Blender) or fix its extension."
        )
    return ext


def read_input(path: Path, src: str, error: type[MimeticError], kind: str) -> bytes:
    """The bytes of input file ``path`` (``src`` names it in messages); ``error`` when it is missing,
    a folder or unreadable, saying what to do (``kind``: "mesh", "landmark", "trajectory" …)."""
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise error(f"{src}: no such file (looked in {path.absolute().parent}). Check the path.") from None
    except IsADirectoryError:
        raise error(
            f"{src}: is a folder, not a {kind} file. Give the path of a {kind} file inside it."
        ) from None
    except PermissionError:
        raise error(f"{src}: permission denied. Make the file readable.") from None
    except OSError as exc:
        raise error(f"{src}: cannot read the file ({exc.strerror or exc}).") from None


def _check_loaded(vertices: np.ndarray, n_faces: int, src: str) -> None:
    bad = ~np.isfinite(vertices).all(axis=1)
    if bad.any():
        raise MeshError(
            f"{src}: {int(bad.sum())} of {len(vertices)} vertices have NaN or infinite coordinates "
            f"(first: vertex {int(np.argmax(bad))}). Fix or delete them in your modelling tool, or load "
            "with check=False and inspect the mesh with validate_mesh."
        )
    if n_faces < MIN_FACES:
        raise MeshError(
            f"{src}: only {n_faces} face{'s' * (n_faces != 1)}; a head mesh needs at least {MIN_FACES}. "
            "Check that this is the right file, or load with check=False."
        )


def _file_units(raw: str | None, vertices: np.ndarray, src: str) -> str | None:
    """The units written in a file, normalised; None (and a log line) when absent or unknown."""
    if raw is None:
        return None
    units = _UNIT_ALIASES.get(raw.strip().lower())
    if units is None:
        log.warning("%s: ignoring units %r recorded in the file (not one of mm, cm, dm, m)", src, raw)
        return None
    detected = units_for_extent(largest_extent(vertices))
    if detected is not None and detected != units:
        log.warning(
            "%s: the file says units %s but its size suggests %s; using %s", src, units, detected, units
        )
    return units


def _colors_from_u8(rgba: np.ndarray) -> np.ndarray:
    """(n, 3 or 4) uint8 → (n, 3) float32 in [0, 1]."""
    return (np.asarray(rgba)[:, :3].astype(np.float32) / np.float32(255.0)).astype(np.float32)


def _colors_to_u8(colors: np.ndarray) -> np.ndarray:
    """(n, 3) float in [0, 1] → (n, 3) uint8; NaN becomes 0."""
    c = np.nan_to_num(np.asarray(colors, dtype=np.float64), nan=0.0)
    return np.round(np.clip(c, 0.0, 1.0) * 255.0).astype(np.uint8)


def _trimesh_scene(data: bytes, file_type: str, src: str, path: Path, **kwargs):
    """Parse ``data`` with trimesh (processing off); any failure becomes a MeshError."""
    import trimesh

    resolver = trimesh.resolvers.FilePathResolver(str(path.absolute()))
    try:
        return trimesh.load_scene(
            io.BytesIO(data), file_type=file_type, resolver=resolver, process=False, **kwargs
        )
    except Exception as error:  # trimesh raises ValueError, KeyError, IndexError, struct.error, ...
        raise MeshError(
            f"{src}: not a readable {file_type.upper()} file ({type(error).__name__}: {error}). "
            "Check that it is complete and really in this format; re-export it if it was truncated."
        ) from error


def _trimesh_colors(geometry) -> np.ndarray | None:
    """Per-vertex colours (n, 3) float32 of a trimesh geometry, or None when it has none."""
    visual = geometry.visual
    if visual is None:
        return None
    if visual.kind == "vertex":
        return _colors_from_u8(visual.vertex_colors)
    color = getattr(visual, "vertex_attributes", {}).get("color")
    if color is not None and len(color) == len(geometry.vertices):
        color = np.asarray(color)
        return (
            _colors_from_u8(color)
            if color.dtype == np.uint8
            else np.clip(color[:, :3], 0, 1).astype(np.float32)
        )
    return None


# --- OBJ ----------------------------------------------------------------------------------------

_OBJ_KEYWORDS = frozenset(
    "v vt vn vp f l p o g s usemtl mtllib cstype deg bmat step curv curv2 surf parm trim hole scrv sp "
    "end con mg bevel c_interp d_interp lod shadow_obj trace_obj maplib usemap".split()
)
_OBJ_V = re.compile(r"^[ \t]*v[ \t]+([^\n]*)", re.MULTILINE)
_OBJ_F = re.compile(r"^[ \t]*f[ \t]+([^\n]*)", re.MULTILINE)
_OBJ_OG = re.compile(r"^[ \t]*(usemtl|[og])(?:[ \t]+([^\n]*))?$", re.MULTILINE)
_OBJ_MTLLIB = re.compile(r"^[ \t]*mtllib[ \t]+([^\n]*?)[ \t]*$", re.MULTILINE)
_OBJ_UNITS = re.compile(r"^[ \t]*#[ \t]*units[ \t]*[:=][ \t]*(\S+)[ \t]*$", re.MULTILINE | re.IGNORECASE)
_AFTER_SLASH = re.compile(r"/\S*")


def _read_obj(data: bytes, src: str, path: Path) -> _Loaded:
    """Parse a Wavefront OBJ: ``v`` (optionally with r g b), ``f`` (any polygon), ``o``, ``g``,
    ``usemtl`` and ``mtllib``.

    A face's part is its current ``g`` group(s) (``g a b`` puts it in both), else its current ``o``
    object; a new ``o`` ends the current groups and a bare ``g`` ends them too. Each material named
    by ``usemtl`` is a part too (named ``<material>_material`` when a group of other faces already
    has its name), with its colour and opacity from the ``.mtl`` files of ``mtllib`` beside the OBJ
    (see ``_read_mtl``); a missing ``.mtl`` warns. When the file has no vertex colours and every
    face's material has a colour, ``colors`` holds them (the mean of the faces around each vertex).
    ``vt``, ``vn``, textures and free-form geometry are ignored. Lines are found with regular
    expressions and numbers parsed with ``np.loadtxt``, so there is no Python loop over lines.
    """
    if b"\x00" in data[:8192]:
        raise MeshError(
            f"{src}: not a Wavefront OBJ file (it is binary; OBJ is text). Check the file's format."
        )
    text = data.decode("utf-8", errors="replace").replace("\r\n", "\n").replace("\r", "\n")
    text = text.replace("\\\n", " ")  # line continuation
    v_rows = _OBJ_V.findall(text)

    # Split the text at o/g/usemtl lines (few); each segment's faces share one part key and material.
    keys: dict[tuple[str, ...], int] = {(): 0}
    material_ids: dict[str, int] = {}
    obj: str | None = None
    groups: tuple[str, ...] = ()
    material = -1
    bounds, seg_keys, seg_materials = [0], [0], [-1]
    for match in _OBJ_OG.finditer(text):
        head, rest = match.group(1), (match.group(2) or "").strip()
        if head == "o":
            obj, groups = rest or None, ()
        elif head == "g":
            groups = tuple(rest.split())
        else:
            material = material_ids.setdefault(rest, len(material_ids)) if rest else -1
        bounds.append(match.start())
        seg_keys.append(keys.setdefault(groups or ((obj,) if obj else ()), len(keys)))
        seg_materials.append(material)
    bounds.append(len(text))
    f_rows: list[str] = []
    f_key: list[np.ndarray] = []
    for lo, hi, key_id, mat in zip(bounds, bounds[1:], seg_keys, seg_materials, strict=False):
        rows = _OBJ_F.findall(text, lo, hi)
        f_rows += rows
        f_key.append(np.tile(np.array([key_id, mat], dtype=np.int64), (len(rows), 1)))

    if not v_rows and not f_rows:
        for lineno, line in enumerate(text.splitlines(), 1):
            head = line.split(None, 1)[:1]
            if head and not head[0].startswith("#") and head[0] not in _OBJ_KEYWORDS:
                raise MeshError(
                    f"{src}: not a Wavefront OBJ file: line {lineno} ({line.strip()[:40]!r}) is not an OBJ "
                    "statement. Check that the file is a mesh and that its extension is right."
                )
        raise MeshError(
            f"{src}: the OBJ file has no vertices and no faces (empty mesh). Re-export it with its geometry."
        )
    vertices, colors = _obj_vertices(v_rows, src, text)
    faces, tri_key = _obj_faces(f_rows, np.concatenate(f_key), len(vertices), src, text)
    tri_key, tri_material = tri_key.reshape(-1, 2).T

    members: dict[str, list[np.ndarray]] = {}
    for key, kid in keys.items():
        ids = np.flatnonzero(tri_key == kid) if key else ()
        if len(ids):
            for name in key:
                members.setdefault(name, []).append(ids)
    parts = {name: np.sort(np.concatenate(ids)) for name, ids in members.items()}
    materials: dict[str, Material] = {}
    if material_ids:
        library = _obj_material_library(text, src, path)
        face_color = np.full((len(faces), 3), np.nan)
        see_through = np.zeros(len(faces), dtype=bool)
        for name, mid in material_ids.items():
            ids = np.flatnonzero(tri_material == mid)
            if not len(ids):
                continue
            part = name if name not in parts or np.array_equal(parts[name], ids) else f"{name}_material"
            parts[part] = ids
            found = library.get(name)
            if found is not None:
                materials[part] = found
                see_through[ids] = found.transparent
                if found.color is not None:
                    face_color[ids] = found.color
        if colors is None and np.isfinite(face_color[~see_through]).all():
            colors = _face_to_vertex_colors(faces, face_color, see_through, len(vertices))
    parts = dict(sorted(parts.items(), key=lambda item: int(item[1][0])))
    units = match.group(1) if (match := _OBJ_UNITS.search(text)) else None
    return _Loaded(vertices, faces, parts, colors, units, materials)


_DEFAULT_MATERIAL = re.compile(
    r"^(default[\w ]*|material|none|lambert1|initialshadinggroup)([._]\d+)?$", re.IGNORECASE
)
"""Names modelling tools give the material of an untouched mesh (Blender "Material", Maya
"lambert1", "default"): their placeholder grey or white says nothing about the surface."""


def _face_to_vertex_colors(
    faces: np.ndarray, face_color: np.ndarray, see_through: np.ndarray, n: int
) -> np.ndarray:
    """Per-vertex colours (n, 3) float32 from face colours (m, 3) (NaN: none): the mean colour of the
    opaque coloured faces around each vertex, else of the see-through (m,) bool ones, else
    ``DEFAULT_COLOR``."""
    out = np.full((n, 3), DEFAULT_COLOR)
    done = np.zeros(n, dtype=bool)
    coloured = np.isfinite(face_color).all(axis=1)
    for use in (coloured & ~see_through, coloured & see_through):
        total = np.zeros((n, 3))
        count = np.zeros(n)
        for k in range(3):
            np.add.at(total, faces[use, k], face_color[use])
            np.add.at(count, faces[use, k], 1.0)
        fill = (count > 0) & ~done
        out[fill] = total[fill] / count[fill, None]
        done |= fill
    return np.clip(out, 0.0, 1.0).astype(np.float32)


def _obj_material_library(text: str, src: str, path: Path) -> dict[str, Material]:
    """The materials of every ``mtllib`` of an OBJ, by name; a missing or unreadable .mtl warns."""
    library: dict[str, Material] = {}
    names = [m.group(1) for m in _OBJ_MTLLIB.finditer(text)]
    if not names:
        log.info("%s: uses materials but names no material library (mtllib)", src)
    for name in names:
        candidates = [name] if (path.parent / name).is_file() else name.split()
        for file in candidates:
            mtl = path.parent / file
            try:
                library.update(_read_mtl(mtl.read_text(encoding="utf-8", errors="replace"), str(mtl)))
            except OSError as error:
                warnings.warn(
                    f"{src}: cannot read its material library {file!r} (looked in {path.absolute().parent}: "
                    f"{error.strerror or error}); its parts load without material colours or opacity. Put "
                    "the .mtl file beside the OBJ to use them.",
                    MimeticWarning,
                    stacklevel=4,
                )
    return library


def _read_mtl(text: str, src: str) -> dict[str, Material]:
    """Materials of a Wavefront .mtl file: ``Kd`` colour and ``d`` opacity (else ``1 - Tr``).

    A material with a ``map_Kd`` texture, or with a placeholder name (see ``_DEFAULT_MATERIAL``),
    gets no colour: its ``Kd`` only tints a texture mimetic does not read, or is a tool's default.
    Unreadable statements are skipped.
    """
    found: dict[str, dict[str, object]] = {}
    current: dict[str, object] | None = None
    for line in text.splitlines():
        words = line.split("#", 1)[0].split()
        if not words:
            continue
        head, args = words[0].lower(), words[1:]
        if head == "newmtl":
            current = found.setdefault(" ".join(args), {})
        elif current is None:
            continue
        elif head == "map_kd":
            current["texture"] = True
        elif head in ("kd", "d", "tr"):
            numbers = [a for a in args if not a.startswith("-")]  # 'd -halo 0.5'
            try:
                values = [float(a) for a in numbers[: 3 if head == "kd" else 1]]
            except ValueError:
                log.info("%s: skipping unreadable %r", src, line.strip())
                continue
            if head == "kd" and len(values) == 3:
                current["kd"] = tuple(float(np.clip(v, 0.0, 1.0)) for v in values)
            elif head != "kd" and values:
                current[head] = float(np.clip(values[0], 0.0, 1.0))
    materials = {}
    for name, spec in found.items():
        opacity = spec["d"] if "d" in spec else 1.0 - spec["tr"] if "tr" in spec else 1.0
        color = spec.get("kd")
        if spec.get("texture") or _DEFAULT_MATERIAL.match(name):
            color = None
        materials[name] = Material(name, color, opacity)  # type: ignore[arg-type]
    return materials


def _line_of(text: str, pattern: re.Pattern, k: int) -> int:
    """Line number (1-based) of the k-th (0-based) match of ``pattern``; for error messages."""
    match = next(itertools.islice(pattern.finditer(text), k, None))
    return text.count("\n", 0, match.start()) + 1


def _loadtxt(rows: list[str], dtype: type) -> np.ndarray | None:
    """Rows of whitespace-separated numbers as a 2-D array, or None if ragged or unreadable."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return np.loadtxt(rows, dtype=dtype, ndmin=2, comments="#")
    except ValueError:
        return None


def _obj_vertices(rows: list[str], src: str, text: str) -> tuple[np.ndarray, np.ndarray | None]:
    if not rows:
        return np.zeros((0, 3)), None
    table = _loadtxt(rows, np.float64)  # fast path: every row has the same count
    if table is None or table.shape[0] != len(rows):
        tokens = [r.split("#", 1)[0].split() for r in rows]
        width = min(map(len, tokens))
        if width < 3:
            k = next(i for i, t in enumerate(tokens) if len(t) < 3)
            raise MeshError(
                f"{src}: line {_line_of(text, _OBJ_V, k)}: a vertex needs x y z; got 'v {rows[k]}'."
            )
        try:
            table = np.array([t[: min(width, 6)] for t in tokens], dtype=np.float64)
        except ValueError:
            k = next(i for i, t in enumerate(tokens) if not _floats_ok(t[:width]))
            raise MeshError(
                f"{src}: line {_line_of(text, _OBJ_V, k)}: cannot read 'v {rows[k]}' as numbers."
            ) from None
    if table.shape[1] < 3:
        raise MeshError(f"{src}: line {_line_of(text, _OBJ_V, 0)}: a vertex needs x y z; got 'v {rows[0]}'.")
    colors = None
    if table.shape[1] == 6:  # x y z r g b (7 or more columns are ambiguous: ignored)
        rgb = table[:, 3:6]
        if np.isfinite(rgb).all():
            if rgb.max() > 1.0:  # 0-255 colours
                rgb = rgb / 255.0
            colors = np.clip(rgb, 0.0, 1.0).astype(np.float32)
    return np.ascontiguousarray(table[:, :3]), colors


def _floats_ok(tokens: list[str]) -> bool:
    try:
        [float(t) for t in tokens]
    except ValueError:
        return False
    return True


def _obj_faces(
    rows: list[str], key: np.ndarray, n: int, src: str, text: str
) -> tuple[np.ndarray, np.ndarray]:
    """Fan-triangulated faces (t, 3) int64 (0-based) and the part key (t,) of each triangle."""
    if not rows:
        return np.zeros((0, 3), np.int64), np.zeros(0, np.int64)
    rows_v = _AFTER_SLASH.sub("", "\n".join(rows)).split("\n")  # keep v of v/vt/vn
    table = _loadtxt(rows_v, np.int64)
    if table is not None and table.shape[0] == len(rows) and table.shape[1] >= 3:
        counts = np.full(len(rows), table.shape[1], dtype=np.int64)
        flat = table.ravel()
    else:  # mixed polygon sizes, or an error to report
        tokens = [r.split() for r in rows_v]
        counts = np.fromiter(map(len, tokens), dtype=np.int64, count=len(tokens))
        if (short := np.flatnonzero(counts < 3)).size:
            k = int(short[0])
            raise MeshError(
                f"{src}: line {_line_of(text, _OBJ_F, k)}: a face needs at least 3 vertices; "
                f"got 'f {rows[k]}'."
            )
        try:
            flat = np.array(list(itertools.chain.from_iterable(tokens)), dtype=np.int64)
        except ValueError:
            k = next(i for i, t in enumerate(tokens) if not all(x.lstrip("-").isdigit() for x in t))
            raise MeshError(
                f"{src}: line {_line_of(text, _OBJ_F, k)}: cannot read 'f {rows[k]}' as vertex indices."
            ) from None
    if (flat < 0).any():  # relative indices: -1 is the latest vertex defined before the face line
        v_pos = np.array([m.start() for m in _OBJ_V.finditer(text)], dtype=np.int64)
        f_pos = np.array([m.start() for m in _OBJ_F.finditer(text)], dtype=np.int64)
        before = np.repeat(np.searchsorted(v_pos, f_pos), counts)  # (sum counts,)
        index = np.where(flat > 0, flat - 1, before + flat)
    else:
        index = flat - 1
    if (bad := np.flatnonzero((flat == 0) | (index < 0) | (index >= n))).size:
        k = int(np.searchsorted(np.cumsum(counts), bad[0], side="right"))
        raise MeshError(
            f"{src}: line {_line_of(text, _OBJ_F, k)}: face 'f {rows[k]}' refers to a vertex that does not "
            f"exist (the file has {n}; OBJ indices start at 1; negative ones count back from the latest)."
        )
    if (counts == 3).all():
        return index.reshape(-1, 3), key
    # Fan triangulation: polygon p with c corners starting at s gives (s, s+i, s+i+1), i = 1..c-2.
    start = np.cumsum(counts) - counts  # (P,)
    n_tri = counts - 2  # (P,)
    poly = np.repeat(np.arange(len(counts)), n_tri)  # (T,)
    i = np.arange(len(poly)) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri) + 1
    s = start[poly]
    faces = np.column_stack([index[s], index[s + i], index[s + i + 1]])  # (T, 3)
    log.debug("%s: fan-triangulated %d polygons", src, int((counts > 3).sum()))
    return faces, key[poly]


def encode_obj(mesh: Mesh, src: str) -> bytes:
    """The OBJ text ``save_mesh`` writes for ``mesh`` (vertices in order, parts as groups), as bytes;
    ``src`` names the destination in error messages."""
    names = [name for name, ids in mesh.parts.items() if len(ids)]
    for name in names:
        if not name or any(c.isspace() for c in name):
            raise MeshError(
                f"{src}: part name {name!r} cannot be an OBJ group name (empty or containing spaces). "
                "Rename the part, e.g. with underscores."
            )
    if len(names) < len(mesh.parts):
        log.warning("%s: empty parts are not stored in OBJ: %s", src, sorted(set(mesh.parts) - set(names)))
    out = ["# written by mimetic"]
    if mesh.units:
        out.append(f"# units: {mesh.units}")
    v = mesh.vertices.tolist()
    if mesh.colors is not None:
        c = mesh.colors.astype(np.float64).tolist()  # float32 values, printed exactly
        out.extend(
            f"v {x!r} {y!r} {z!r} {r!r} {g!r} {b!r}" for (x, y, z), (r, g, b) in zip(v, c, strict=True)
        )
    else:
        out.extend(f"v {x!r} {y!r} {z!r}" for x, y, z in v)
    faces = (mesh.faces + 1).tolist()
    member = np.zeros((mesh.n_faces, len(names)), dtype=bool)  # (m, P)
    for k, name in enumerate(names):
        member[mesh.parts[name], k] = True
    changes = np.flatnonzero((member[1:] != member[:-1]).any(axis=1)) + 1
    bounds = [0, *changes.tolist(), mesh.n_faces]
    current: list[str] = []
    for lo, hi in itertools.pairwise(bounds):
        group = [names[k] for k in np.flatnonzero(member[lo])] if names else []
        if group != current:
            out.append("g " + " ".join(group) if group else "g")
            current = group
        out.extend(f"f {a} {b} {c}" for a, b, c in faces[lo:hi])
    out.append("")
    return "\n".join(out).encode("utf-8")


# --- PLY ----------------------------------------------------------------------------------------

_PLY_UNITS = re.compile(rb"^comment\s+units\s+(\S+)\s*$", re.MULTILINE)


def _read_ply(data: bytes, src: str, path: Path) -> _Loaded:
    if not data.startswith(b"ply"):
        raise MeshError(f"{src}: not a PLY file (it does not start with 'ply'). Check the file's format.")
    end = data.find(b"end_header")
    if end < 0:
        raise MeshError(f"{src}: the PLY header has no 'end_header'; the file is truncated or corrupt.")
    match = _PLY_UNITS.search(data[:end])
    scene = _trimesh_scene(data, "ply", src, path)
    loaded = _single_geometry(scene, src, "PLY")
    loaded.units = match.group(1).decode("ascii", "replace") if match else None
    return loaded


def _single_geometry(scene, src: str, fmt: str) -> _Loaded:
    import trimesh

    geometries = [g for g in scene.geometry.values()]
    if not geometries:
        raise MeshError(f"{src}: the {fmt} file contains no geometry (empty mesh).")
    if len(geometries) > 1 or not isinstance(geometries[0], trimesh.Trimesh):
        g = geometries[0]
        if len(geometries) == 1 and isinstance(g, trimesh.PointCloud):
            return _Loaded(np.asarray(g.vertices, dtype=np.float64), np.zeros((0, 3), np.int64))
        raise MeshError(
            f"{src}: expected one triangle mesh in the {fmt} file; found {len(geometries)} geometries."
        )
    g = geometries[0]
    return _Loaded(np.asarray(g.vertices, np.float64), np.asarray(g.faces, np.int64), {}, _trimesh_colors(g))


def _encode_ply(mesh: Mesh, src: str) -> bytes:
    """Binary little-endian PLY with float64 positions (trimesh's own writer uses float32)."""
    _warn_parts_dropped(mesh, src, "PLY")
    vertex_dtype = [("x", "<f8"), ("y", "<f8"), ("z", "<f8")]
    if mesh.colors is not None:
        vertex_dtype += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    vertex = np.zeros(mesh.n_vertices, dtype=vertex_dtype)
    for d, axis in enumerate("xyz"):
        vertex[axis] = mesh.vertices[:, d]
    if mesh.colors is not None:
        rgb = _colors_to_u8(mesh.colors)
        for d, channel in enumerate(("red", "green", "blue")):
            vertex[channel] = rgb[:, d]
    face = np.zeros(mesh.n_faces, dtype=[("count", "u1"), ("index", "<i4", (3,))])
    face["count"] = 3
    face["index"] = mesh.faces
    header = ["ply", "format binary_little_endian 1.0", "comment written by mimetic"]
    if mesh.units:
        header.append(f"comment units {mesh.units}")
    header.append(f"element vertex {mesh.n_vertices}")
    header += [f"property {'double' if t == '<f8' else 'uchar'} {name}" for name, t in vertex_dtype]
    header += [f"element face {mesh.n_faces}", "property list uchar int vertex_indices", "end_header", ""]
    return "\n".join(header).encode("ascii") + vertex.tobytes() + face.tobytes()


def _warn_parts_dropped(mesh: Mesh, src: str, fmt: str) -> None:
    if mesh.parts:
        log.warning(
            "%s: %s cannot store parts; writing one merged surface (parts %s dropped)",
            src,
            fmt,
            list(mesh.parts),
        )


# --- STL ----------------------------------------------------------------------------------------


def _read_stl(data: bytes, src: str, path: Path) -> _Loaded:
    binary = len(data) >= 84 and len(data) == 84 + 50 * struct.unpack_from("<I", data, 80)[0]
    if not binary:
        head = data.lstrip()[:5].lower()
        if head != b"solid" or b"\x00" in data[:4096]:
            raise MeshError(
                f"{src}: not an STL file (neither a binary STL of the size its header gives, nor text "
                "starting with 'solid'). The file is truncated or in another format."
            )
    scene = _trimesh_scene(data, "stl", src, path)
    import trimesh

    geometries = [g for g in scene.geometry.values() if isinstance(g, trimesh.Trimesh)]
    if not geometries:
        return _Loaded(np.zeros((0, 3)), np.zeros((0, 3), np.int64))
    corners = np.concatenate([np.asarray(g.vertices)[np.asarray(g.faces)].reshape(-1, 3) for g in geometries])
    vertices, faces = _merge_corners(corners)
    parts: dict[str, np.ndarray] = {}
    if len(geometries) > 1:
        offsets = np.cumsum([0] + [len(g.faces) for g in geometries])
        parts = {
            str(name): np.arange(lo, hi)
            for name, lo, hi in zip(scene.geometry, offsets, offsets[1:], strict=False)
        }
    return _Loaded(vertices, faces, parts)


def _merge_corners(corners: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indexed mesh from triangle corners (3m, 3): equal corners merged, in order of first use.

    Returns vertices (n, 3) float64 and faces (m, 3) int64. Sorts rows with ``np.lexsort``
    (``np.unique(axis=0)`` is several times slower).
    """
    c = np.asarray(corners, dtype=np.float64)
    order = np.lexsort((c[:, 2], c[:, 1], c[:, 0]))  # stable: equal rows keep file order
    sc = c[order]
    new = np.r_[True, (sc[1:] != sc[:-1]).any(axis=1)]  # (3m,) starts a new distinct row
    group = np.cumsum(new) - 1  # distinct-row id of each sorted corner
    first = order[new]  # first use of each distinct row
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first, kind="stable")] = np.arange(len(first))
    inverse = np.empty(len(c), dtype=np.int64)
    inverse[order] = rank[group]
    return c[np.sort(first)], inverse.reshape(-1, 3)


def _encode_stl(mesh: Mesh, src: str) -> bytes:
    import trimesh

    _warn_parts_dropped(mesh, src, "STL")
    stored = mesh.vertices.astype(np.float32)[mesh.faces].reshape(-1, 3)
    vertices, faces = _merge_corners(stored)
    if len(vertices) != mesh.n_vertices or not np.array_equal(faces, mesh.faces):
        warnings.warn(
            f"{src}: STL stores bare triangles, so this mesh will read back with {len(vertices)} vertices in "
            f"order of first use, not its {mesh.n_vertices} in their own order. Save as .ply or .obj to keep "
            "vertex order.",
            MimeticWarning,
            stacklevel=3,
        )
    tm = trimesh.Trimesh(mesh.vertices, mesh.faces, process=False, validate=False)
    return tm.export(file_type="stl")


# --- glTF -----------------------------------------------------------------------------------------

_GLB_MAGIC = b"glTF"
_CHUNK_JSON = 0x4E4F534A


def _read_glb(data: bytes, src: str, path: Path) -> _Loaded:
    if len(data) < 20 or data[:4] != _GLB_MAGIC:
        raise MeshError(f"{src}: not a GLB file (it does not start with 'glTF'). Check the file's format.")
    version, total, json_length, json_type = struct.unpack_from("<IIII", data, 4)
    if version != 2:
        raise MeshError(f"{src}: glTF version {version}; only glTF 2.0 is supported. Re-export as glTF 2.0.")
    if total > len(data) or 20 + json_length > total or json_type != _CHUNK_JSON:
        raise MeshError(
            f"{src}: the GLB is truncated or corrupt (its header promises {total} bytes; the file has "
            f"{len(data)}). Re-export or re-download it."
        )
    header = _parse_gltf_json(data[20 : 20 + json_length], src)
    rewritten, plan = _plan_gltf(header)
    text = json.dumps(rewritten).encode("utf-8")
    text += b" " * (-len(text) % 4)
    rest = data[20 + json_length : total]
    glb = (
        struct.pack("<4sIIII", _GLB_MAGIC, 2, 20 + len(text) + len(rest), len(text), _CHUNK_JSON)
        + text
        + rest
    )
    scene = _trimesh_scene(glb, "glb", src, path, skip_materials=True)
    return _gltf_to_loaded(scene, header, plan, src)


def _read_gltf(data: bytes, src: str, path: Path) -> _Loaded:
    header = _parse_gltf_json(data, src)
    rewritten, plan = _plan_gltf(header)
    scene = _trimesh_scene(json.dumps(rewritten).encode("utf-8"), "gltf", src, path, skip_materials=True)
    return _gltf_to_loaded(scene, header, plan, src)


def _parse_gltf_json(data: bytes, src: str) -> dict:
    try:
        header = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as error:
        raise MeshError(
            f"{src}: not a glTF file (its JSON is unreadable: {error}). The file is corrupt."
        ) from None
    if not isinstance(header, dict) or "asset" not in header:
        raise MeshError(f"{src}: not a glTF file (its JSON has no 'asset'). Check the file's format.")
    return header


@dataclass(frozen=True)
class _Piece:
    """One glTF (node, primitive) pair in the loaded scene."""

    rank: int  # depth-first position of the node in the scene
    node: int  # node index in the file
    mesh: int  # mesh index in the file
    primitive: int  # primitive index within the mesh


def _plan_gltf(header: dict) -> tuple[dict, dict[str, _Piece]]:
    """A copy of ``header`` that trimesh loads with predictable names, and what each name means.

    trimesh names scene nodes after glTF node names (made unique), lists them in reverse, and
    names the extra frames of multi-primitive meshes with random ids. Here every primitive gets a
    mesh of its own and every (node, primitive) a node named ``mimetic_<node>_<primitive>``.
    """
    h = copy.deepcopy(header)
    meshes = h.get("meshes") or []
    nodes = h.setdefault("nodes", [])
    if not nodes and meshes:
        nodes.extend({"mesh": i} for i in range(len(meshes)))
    if not h.get("scenes"):
        children = {c for node in nodes for c in node.get("children", [])}
        h["scenes"], h["scene"] = [{"nodes": [i for i in range(len(nodes)) if i not in children]}], 0
    roots = h["scenes"][h.get("scene", 0)].get("nodes", [])

    rank: dict[int, int] = {}
    stack = list(reversed(roots))
    while stack:  # depth-first, file order
        b = stack.pop()
        if b in rank or not 0 <= b < len(nodes):
            continue
        rank[b] = len(rank)
        stack.extend(reversed(nodes[b].get("children", [])))

    new_meshes, first = [], []
    for m in meshes:
        first.append(len(new_meshes))
        new_meshes.extend({"primitives": [p]} for p in m.get("primitives", []))
    for k, m in enumerate(new_meshes):
        m["name"] = f"mimetic_mesh_{k}"
    h["meshes"] = new_meshes

    plan: dict[str, _Piece] = {}
    for b in range(len(nodes)):
        node = nodes[b]
        node["name"] = f"mimetic_node_{b}"
        i = node.get("mesh")
        if i is None:
            continue
        if not isinstance(i, int) or not 0 <= i < len(meshes) or not meshes[i].get("primitives"):
            node.pop("mesh", None)
            continue
        node["name"] = f"mimetic_{b}_0"
        node["mesh"] = first[i]
        plan[node["name"]] = _Piece(rank.get(b, -1), b, i, 0)
        for j in range(1, len(meshes[i]["primitives"])):
            child = {"name": f"mimetic_{b}_{j}", "mesh": first[i] + j}
            node.setdefault("children", []).append(len(nodes))
            nodes.append(child)
            plan[child["name"]] = _Piece(rank.get(b, -1), b, i, j)
    return h, plan


def _gltf_to_loaded(scene, header: dict, plan: dict[str, _Piece], src: str) -> _Loaded:
    """Concatenate the scene's triangle meshes in node order, each under its world transform."""
    import trimesh

    found = []
    skipped = 0
    for node_name in scene.graph.nodes_geometry:
        transform, geometry_name = scene.graph[node_name]
        geometry = scene.geometry[geometry_name]
        piece = plan.get(node_name)
        if piece is None or not isinstance(geometry, trimesh.Trimesh):
            skipped += 1
            continue
        found.append((piece.rank, piece.node, piece.primitive, piece, np.asarray(transform), geometry))
    if skipped:
        log.warning(
            "%s: skipped %d glTF node(s) that are not triangle meshes (points or lines)", src, skipped
        )
    found.sort(key=lambda item: item[:3])
    if not found:
        return _Loaded(np.zeros((0, 3)), np.zeros((0, 3), np.int64))

    meshes, nodes = header.get("meshes", []), header.get("nodes", [])
    materials = header.get("materials", [])
    vertices, faces, colors, names, piece_materials = [], [], [], [], []
    factors: list[tuple[float, float, float] | None] = []  # flat colour of each vertex block
    shared: dict[tuple[int, int], int] = {}  # (node, POSITION accessor) -> vertex offset
    n = 0
    any_color = False
    for _, b, j, piece, transform, geometry in found:
        primitive = meshes[piece.mesh]["primitives"][j]
        material = _gltf_material(materials, primitive.get("material"))
        piece_materials.append(material)
        f = np.asarray(geometry.faces, dtype=np.int64)
        linear = transform[:3, :3]
        if np.linalg.det(linear) < 0:  # mirrored: keep faces outward
            f = f[:, [0, 2, 1]]
        accessor = primitive.get("attributes", {}).get("POSITION", -1)
        if (b, accessor) in shared:  # primitives sharing vertices
            faces.append(f + shared[(b, accessor)])
        else:
            v = np.asarray(geometry.vertices, dtype=np.float64)
            if not np.array_equal(transform, np.eye(4)):
                v = v @ linear.T + transform[:3, 3]
            shared[(b, accessor)] = n
            faces.append(f + n)
            vertices.append(v)
            c = _trimesh_colors(geometry)
            factor = None if material is None else material.color
            if c is not None and factor is not None:  # glTF: COLOR_0 times baseColorFactor
                c = (c * np.float32(factor)).astype(np.float32)
            any_color |= c is not None
            colors.append(c)
            factors.append(factor)
            n += len(v)
        names.append(_piece_name(nodes[b], meshes[piece.mesh], primitive, j, b, materials))

    all_faces = np.concatenate(faces)
    parts: dict[str, np.ndarray] = {}
    part_materials: dict[str, Material] = {}
    if len(found) > 1:
        offsets = np.cumsum([0] + [len(f) for f in faces])
        for name, lo, hi, material in zip(names, offsets, offsets[1:], piece_materials, strict=False):
            unique = name
            k = 1
            while unique in parts:
                k += 1
                unique = f"{name}_{k}"
            parts[unique] = np.arange(lo, hi)
            if material is not None:
                part_materials[unique] = material
    if any_color or all(factor is not None for factor in factors):
        # vertex colours, else every block's flat colour; a block with neither is grey
        colors = [
            c if c is not None else np.full((len(v), 3), DEFAULT_COLOR if k is None else k, np.float32)
            for c, k, v in zip(colors, factors, vertices, strict=True)
        ]
        any_color = True
    units = next(
        (
            m["extras"]["units"]
            for m in meshes
            if isinstance(m.get("extras"), dict) and isinstance(m["extras"].get("units"), str)
        ),
        None,
    )
    return _Loaded(
        np.concatenate(vertices),
        all_faces,
        parts,
        np.concatenate(colors) if any_color else None,
        units,
        part_materials,
    )


def _gltf_material(materials: list, index) -> Material | None:
    """The ``Material`` of a glTF primitive's ``material`` index, or None when it has none.

    The colour is ``pbrMetallicRoughness.baseColorFactor`` when the file states one, it is not
    plain white (the default, which only passes a texture or vertex colours through) and there is
    no ``baseColorTexture``. Opacity follows ``alphaMode``: OPAQUE (the default) 1; MASK 1 or 0 by
    the factor's alpha against ``alphaCutoff``; BLEND the factor's alpha.
    """
    if (
        not isinstance(index, int)
        or not 0 <= index < len(materials)
        or not isinstance(materials[index], dict)
    ):
        return None
    spec = materials[index]
    name = spec.get("name") if isinstance(spec.get("name"), str) else None
    pbr = spec.get("pbrMetallicRoughness") if isinstance(spec.get("pbrMetallicRoughness"), dict) else {}
    try:
        factor = np.clip(np.asarray(pbr.get("baseColorFactor", [1, 1, 1, 1]), dtype=np.float64), 0, 1)
        factor = factor.reshape(4) if np.all(np.isfinite(factor)) else np.ones(4)
        cutoff = float(spec.get("alphaCutoff", 0.5))
    except (TypeError, ValueError):
        factor, cutoff = np.ones(4), 0.5
    color = None
    if "baseColorTexture" not in pbr and not np.all(factor[:3] == 1.0):
        if not (name and _DEFAULT_MATERIAL.match(name)):
            color = (float(factor[0]), float(factor[1]), float(factor[2]))
    mode = spec.get("alphaMode", "OPAQUE")
    opacity = float(factor[3]) if mode == "BLEND" else float(factor[3] >= cutoff) if mode == "MASK" else 1.0
    return Material(name, color, opacity)


def _piece_name(node: dict, mesh: dict, primitive: dict, j: int, b: int, materials: list) -> str:
    base = node.get("name") or mesh.get("name") or f"node_{b}"
    if len(mesh.get("primitives", [])) == 1:
        return str(base)
    material = primitive.get("material")
    label = (
        materials[material].get("name") if isinstance(material, int) and material < len(materials) else None
    )
    return f"{base}_{label or j}"


def part_blocks(mesh: Mesh, src: str) -> list[tuple[str, slice, slice]]:
    """(name, vertex slice, face slice) of each part, when parts are consecutive blocks.

    glTF gives every node its own vertices, so a mesh can be written part by part without
    reordering only if each part owns a run of faces and a run of vertices, in the same order,
    together covering every face (vertices used by no face join the part before them).
    """
    m, n = mesh.n_faces, mesh.n_vertices
    parts = sorted(
        ((name, np.asarray(ids)) for name, ids in mesh.parts.items() if len(ids)), key=lambda p: p[1].min()
    )
    if not parts:
        return [("mesh", slice(0, n), slice(0, m))]

    def fail(reason: str) -> MeshError:
        return MeshError(
            f"{src}: glTF stores each part as a node with its own vertices, so parts must be consecutive "
            f"blocks of faces and vertices (as Mesh.concatenate builds them); {reason}. Save as .obj to keep "
            "these parts as groups, or drop them: Mesh(mesh.vertices, mesh.faces, colors=mesh.colors, "
            "units=mesh.units)."
        )

    f0 = 0
    v_lo = []
    for name, ids in parts:
        if not np.array_equal(ids, np.arange(f0, f0 + len(ids))):
            raise fail(f"part {name!r} is not the run of faces {f0}..{f0 + len(ids) - 1}")
        v_lo.append(0 if f0 == 0 else int(mesh.faces[ids].min()))
        f0 += len(ids)
    if f0 != m:
        raise fail(f"{m - f0} faces are in no part")
    v_bounds = [*v_lo, n]
    blocks = []
    f0 = 0
    for k, (name, ids) in enumerate(parts):
        lo, hi = v_bounds[k], v_bounds[k + 1]
        used = mesh.faces[ids]
        if hi <= lo or used.min() < lo or used.max() >= hi:
            raise fail(f"part {name!r} uses vertices outside its block {lo}..{hi - 1}")
        blocks.append((name, slice(lo, hi), slice(f0, f0 + len(ids))))
        f0 += len(ids)
    return blocks


def _gltf_scene(mesh: Mesh, src: str):
    import trimesh

    scene = trimesh.Scene()
    colors = None if mesh.colors is None else _colors_to_u8(mesh.colors)
    for name, vs, fs in part_blocks(mesh, src):
        kwargs = {}
        if colors is not None:
            kwargs["vertex_colors"] = np.column_stack(
                [colors[vs], np.full(vs.stop - vs.start, 255, np.uint8)]
            )
        tm = trimesh.Trimesh(
            mesh.vertices[vs], mesh.faces[fs] - vs.start, process=False, validate=False, **kwargs
        )
        if mesh.units:
            tm.metadata["units"] = mesh.units
        scene.add_geometry(tm, node_name=name, geom_name=name)
    return scene


def _encode_glb(mesh: Mesh, src: str) -> bytes:
    return _gltf_scene(mesh, src).export(file_type="glb")


def _encode_gltf(mesh: Mesh, src: str) -> bytes:
    files = _gltf_scene(mesh, src).export(file_type="gltf", embed_buffers=True)
    (data,) = files.values()
    return data
