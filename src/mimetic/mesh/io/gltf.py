"""glTF 2.0 (.glb and .gltf): read and written by trimesh with processing off, one node per part.

Node order comes from the file's own JSON, because trimesh's scene graph lists nodes in reverse;
a multi-part glTF's primitive materials become ``Mesh.materials`` of the parts named after them.
"""

from __future__ import annotations

import copy
import json
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mimetic.errors import MeshError
from mimetic.mesh.io.common import (
    DEFAULT_COLOR,
    PLACEHOLDER_MATERIAL,
    Loaded,
    colors_to_u8,
    log,
    trimesh_colors,
    trimesh_scene,
)
from mimetic.mesh.model import Material, Mesh

_GLB_MAGIC = b"glTF"
_CHUNK_JSON = 0x4E4F534A


def read_glb(data: bytes, src: str, path: Path) -> Loaded:
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
    scene = trimesh_scene(glb, "glb", src, path, skip_materials=True)
    return _gltf_to_loaded(scene, header, plan, src)


def read_gltf(data: bytes, src: str, path: Path) -> Loaded:
    header = _parse_gltf_json(data, src)
    rewritten, plan = _plan_gltf(header)
    scene = trimesh_scene(json.dumps(rewritten).encode("utf-8"), "gltf", src, path, skip_materials=True)
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


def _gltf_to_loaded(scene, header: dict, plan: dict[str, _Piece], src: str) -> Loaded:
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
        return Loaded(np.zeros((0, 3)), np.zeros((0, 3), np.int64))

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
            c = trimesh_colors(geometry)
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
    return Loaded(
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
        if not (name and PLACEHOLDER_MATERIAL.match(name)):
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
    colors = None if mesh.colors is None else colors_to_u8(mesh.colors)
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


def encode_glb(mesh: Mesh, src: str) -> bytes:
    return _gltf_scene(mesh, src).export(file_type="glb")


def encode_gltf(mesh: Mesh, src: str) -> bytes:
    files = _gltf_scene(mesh, src).export(file_type="gltf", embed_buffers=True)
    (data,) = files.values()
    return data
