"""Wavefront OBJ (and its .mtl materials), read and written by mimetic itself.

trimesh 5.2 splits OBJ vertices by their ``vt``/``vn`` indices (or, with ``maintain_order=True``,
drops unused trailing vertices) and returns groups in reverse order, merged by name, so mimetic
parses OBJ itself: polygons are fan-triangulated in place, so face order follows the file. Text in
any encoding ``mimetic.inputs.decode_text`` reads is accepted.
"""

from __future__ import annotations

import itertools
import re
import warnings
from pathlib import Path

import numpy as np

from mimetic.errors import MeshError, MimeticWarning
from mimetic.inputs import decode_text, read_text
from mimetic.mesh.io.common import DEFAULT_COLOR, PLACEHOLDER_MATERIAL, Loaded, log
from mimetic.mesh.model import Material, Mesh

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


def read_obj(data: bytes, src: str, path: Path) -> Loaded:
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
    try:
        text = decode_text(data, src, MeshError)
    except MeshError as error:
        raise MeshError(f"{error} (a Wavefront OBJ file is text). Check the file's format.") from None
    text = text.replace("\r\n", "\n").replace("\r", "\n")
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
    return Loaded(vertices, faces, parts, colors, units, materials)


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
                library.update(_read_mtl(read_text(mtl, MeshError, "material library"), str(mtl)))
            except MeshError as error:
                warnings.warn(
                    f"{src}: cannot read its material library {file!r} ({error}); its parts load without "
                    "material colours or opacity. Put the .mtl file beside the OBJ to use them.",
                    MimeticWarning,
                    stacklevel=4,
                )
    return library


def _read_mtl(text: str, src: str) -> dict[str, Material]:
    """Materials of a Wavefront .mtl file: ``Kd`` colour and ``d`` opacity (else ``1 - Tr``).

    A material with a ``map_Kd`` texture, or with a placeholder name (see ``PLACEHOLDER_MATERIAL``),
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
        if spec.get("texture") or PLACEHOLDER_MATERIAL.match(name):
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
