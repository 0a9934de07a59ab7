"""Tests for mimetic.mesh.io: exact round trips, parts, colours, units, and clear errors."""

from __future__ import annotations

import json
import struct
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mimetic.errors import MeshError, MimeticWarning
from mimetic.mesh.io import SUPPORTED_FORMATS, load_mesh, save_mesh
from mimetic.mesh.model import Material, Mesh
from mimetic.mesh.validate import validate_mesh

# --- builders -------------------------------------------------------------------------------------


def sphere(radius: float, centre, subdivisions: int = 1) -> Mesh:
    s = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return Mesh(np.asarray(s.vertices) + centre, np.asarray(s.faces))


def head_like(*, float32: bool = False, colors: bool = True) -> Mesh:
    """A 22 cm "head": skin sphere plus two eye spheres as parts, jittered, with colours."""
    rng = np.random.default_rng(42)
    mesh = Mesh.concatenate(
        {
            "skin": sphere(11.0, [0, 0, 0], 2),
            "eye_L": sphere(1.2, [3.2, 2.0, 9.0]),
            "eye_R": sphere(1.2, [-3.2, 2.0, 9.0]),
        }
    )
    vertices = mesh.vertices + rng.normal(scale=1e-3, size=mesh.vertices.shape)
    if float32:  # glTF and STL store float32: make the input exactly representable
        vertices = vertices.astype(np.float32).astype(np.float64)
    rgb = (rng.integers(0, 256, size=(mesh.n_vertices, 3)) / 255).astype(np.float32) if colors else None
    return Mesh(vertices, mesh.faces, mesh.parts, rgb, "cm")


def first_use_order(mesh: Mesh) -> Mesh:
    """The same mesh with vertices renumbered in order of first use by the faces (what STL keeps)."""
    flat = mesh.faces.ravel()
    _, first = np.unique(flat, return_index=True)
    order = flat[np.sort(first)]
    rank = np.empty(mesh.n_vertices, dtype=np.int64)
    rank[order] = np.arange(len(order))
    return Mesh(mesh.vertices[order], rank[mesh.faces], mesh.parts, None, mesh.units)


def assert_same_arrays(actual: Mesh, expected: Mesh, *, colors_atol: float = 0.0) -> None:
    """Shapes and dtypes first, then exact vertices and faces."""
    assert actual.vertices.shape == expected.vertices.shape
    assert actual.vertices.dtype == np.float64
    assert actual.faces.shape == expected.faces.shape
    assert actual.faces.dtype == np.int64
    np.testing.assert_array_equal(actual.vertices, expected.vertices)
    np.testing.assert_array_equal(actual.faces, expected.faces)
    if expected.colors is not None and colors_atol is not None:
        assert actual.colors is not None
        assert actual.colors.shape == expected.colors.shape
        assert actual.colors.dtype == np.float32
        np.testing.assert_allclose(actual.colors, expected.colors, atol=colors_atol, rtol=0)


def glb_bytes(header: dict, binary: bytes) -> bytes:
    """A GLB container around a glTF JSON header and one binary buffer."""
    text = json.dumps(header).encode()
    text += b" " * (-len(text) % 4)
    binary += b"\0" * (-len(binary) % 4)
    total = 12 + 8 + len(text) + 8 + len(binary)
    return (
        struct.pack("<4sII", b"glTF", 2, total)
        + struct.pack("<I4s", len(text), b"JSON")
        + text
        + struct.pack("<I4s", len(binary), b"BIN\0")
        + binary
    )


def gltf_header(
    arrays_: list[np.ndarray], meshes: list, nodes: list, roots: list, **extra
) -> tuple[dict, bytes]:
    """glTF JSON and buffer: one bufferView + accessor per array (float32 VEC3 or uint32 SCALAR)."""
    views, accessors, blob = [], [], b""
    for a in arrays_:
        data = a.tobytes()
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(data)})
        if a.dtype == np.float32:
            accessors.append(
                {"bufferView": len(views) - 1, "componentType": 5126, "count": len(a), "type": "VEC3",
                 "min": a.min(axis=0).tolist(), "max": a.max(axis=0).tolist()}
            )  # fmt: skip
        else:
            accessors.append(
                {"bufferView": len(views) - 1, "componentType": 5125, "count": a.size, "type": "SCALAR"}
            )
        blob += data
    header = {
        "asset": {"version": "2.0"},
        "buffers": [{"byteLength": len(blob)}],
        "bufferViews": views,
        "accessors": accessors,
        "meshes": meshes,
        "nodes": nodes,
        "scenes": [{"nodes": roots}],
        "scene": 0,
        **extra,
    }
    return header, blob


# --- round trips ----------------------------------------------------------------------------------


@pytest.mark.parametrize("ext", [".obj", ".ply"])
def test_save_load_float64_formats_keep_vertices_faces_exactly(tmp_path, ext):
    mesh = head_like()
    path = save_mesh(mesh, tmp_path / f"head{ext}")
    loaded = load_mesh(path)
    assert_same_arrays(loaded, mesh, colors_atol=1e-7)
    assert loaded.units == "cm"


@pytest.mark.parametrize("ext", [".glb", ".gltf"])
def test_save_load_gltf_keeps_float32_vertices_faces_parts_exactly(tmp_path, ext):
    mesh = head_like(float32=True)
    loaded = load_mesh(save_mesh(mesh, tmp_path / f"head{ext}"))
    assert_same_arrays(loaded, mesh, colors_atol=1e-7)
    assert list(loaded.parts) == ["skin", "eye_L", "eye_R"]
    for name in mesh.parts:
        np.testing.assert_array_equal(loaded.parts[name], mesh.parts[name])
    assert loaded.units == "cm"


def test_save_load_glb_float64_vertices_round_to_float32(tmp_path):
    mesh = head_like()
    loaded = load_mesh(save_mesh(mesh, tmp_path / "head.glb"))
    assert loaded.vertices.shape == mesh.vertices.shape
    np.testing.assert_array_equal(loaded.vertices, mesh.vertices.astype(np.float32).astype(np.float64))


def test_save_load_stl_first_use_ordered_mesh_round_trips_exactly(tmp_path):
    mesh = first_use_order(head_like(float32=True, colors=False))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no MimeticWarning: this order survives
        path = save_mesh(mesh, tmp_path / "head.stl")
    loaded = load_mesh(path)
    assert_same_arrays(loaded, mesh)
    assert loaded.parts == {}
    assert loaded.colors is None


def test_save_stl_other_vertex_order_warns_and_reads_back_in_first_use_order(tmp_path, tetrahedron):
    mesh = Mesh(tetrahedron.vertices * 20, tetrahedron.faces)  # faces use 0, 2, 1, 3
    with pytest.warns(MimeticWarning, match="order of first use"):
        save_mesh(mesh, tmp_path / "tet.stl")
    loaded = load_mesh(tmp_path / "tet.stl")
    assert_same_arrays(loaded, first_use_order(mesh))


def test_save_load_obj_overlapping_and_interleaved_parts_round_trip(tmp_path, tetrahedron):
    mesh = Mesh(
        tetrahedron.vertices * 20,
        tetrahedron.faces,
        {"a": [0, 2], "b": [1, 2], "c": [3]},  # face 2 in two parts; a and b interleave
        units="cm",
    )
    text = save_mesh(mesh, tmp_path / "t.obj").read_text()
    assert "g a b" in text
    loaded = load_mesh(tmp_path / "t.obj")
    assert_same_arrays(loaded, mesh)
    assert {k: v.tolist() for k, v in loaded.parts.items()} == {"a": [0, 2], "b": [1, 2], "c": [3]}
    assert all(v.dtype == np.int64 for v in loaded.parts.values())


def test_save_load_obj_faces_outside_parts_stay_outside(tmp_path, tetrahedron):
    mesh = Mesh(tetrahedron.vertices * 20, tetrahedron.faces, {"skin": [1, 2]}, units="cm")
    loaded = load_mesh(save_mesh(mesh, tmp_path / "t.obj"))
    assert {k: v.tolist() for k, v in loaded.parts.items()} == {"skin": [1, 2]}


def test_save_load_obj_without_parts_gives_no_parts(tmp_path, tetrahedron):
    loaded = load_mesh(save_mesh(Mesh(tetrahedron.vertices * 20, tetrahedron.faces), tmp_path / "t.obj"))
    assert loaded.parts == {}
    assert loaded.colors is None
    assert loaded.units == "cm"  # detected: 20 units


@settings(max_examples=25, deadline=None)
@given(
    vertices=arrays(np.float64, (4, 3), elements=st.floats(allow_nan=False, allow_infinity=False)),
    ext=st.sampled_from([".obj", ".ply"]),
)
def test_save_load_any_finite_vertices_are_bit_exact(tetrahedron, vertices, ext):
    mesh = Mesh(vertices, tetrahedron.faces, units="mm")
    with tempfile.TemporaryDirectory() as folder:
        loaded = load_mesh(save_mesh(mesh, Path(folder) / f"m{ext}"))
    assert loaded.vertices.tobytes() == mesh.vertices.tobytes()  # also keeps -0.0 and subnormals
    np.testing.assert_array_equal(loaded.faces, mesh.faces)


def test_save_mesh_glb_interleaved_parts_raise_and_suggest_obj(tmp_path, tetrahedron):
    mesh = Mesh(tetrahedron.vertices * 20, tetrahedron.faces, {"a": [0, 2], "b": [1, 3]})
    with pytest.raises(MeshError, match=r"\.obj"):
        save_mesh(mesh, tmp_path / "t.glb")
    assert not (tmp_path / "t.glb").exists()


def test_save_mesh_obj_part_name_with_space_raises_and_keeps_old_file(tmp_path, tetrahedron):
    target = tmp_path / "t.obj"
    target.write_text("precious")
    mesh = Mesh(tetrahedron.vertices, tetrahedron.faces, {"left eye": [0]})
    with pytest.raises(MeshError, match="left eye"):
        save_mesh(mesh, target)
    assert target.read_text() == "precious"


def test_save_mesh_unknown_extension_raises_listing_formats(tmp_path, tetrahedron):
    with pytest.raises(MeshError, match=r"\.obj, \.ply, \.stl, \.glb, \.gltf"):
        save_mesh(tetrahedron, tmp_path / "t.fbx")


# --- OBJ reading ----------------------------------------------------------------------------------

OBJ_WITH_UV = """\
# exported by a tool that writes UVs and normals
mtllib head.mtl
v 0 0 0
v 10 0 0
v 0 10 0
v 0 0 10
v 10 10 10
v 99 99 99
vt 0 0
vt 1 0
vt 0 1
vt 1 1
vn 0 0 1
vn 1 0 0
o head
g skin
usemtl skin_mat
s 1
f 1/1/1 3/3/1 2/2/1
f 1/4/2 2/2/2 4/3/2
g eye
f 1//1 4//1 3//1
f 2/1 3/2 4/3 5/4
g skin
f -5/1/1 -3/2/1 -4/3/1
"""


def test_load_mesh_obj_with_uv_and_normals_keeps_every_v_line_in_order(tmp_path):
    path = tmp_path / "uv.obj"
    path.write_text(OBJ_WITH_UV)
    with pytest.warns(MimeticWarning, match="head.mtl"):  # its mtllib is not beside it
        mesh = load_mesh(path, units="cm")
    assert mesh.vertices.shape == (6, 3)  # the unused last vertex is kept
    np.testing.assert_array_equal(mesh.vertices[:, 0], [0, 10, 0, 0, 10, 99])
    np.testing.assert_array_equal(
        mesh.faces,
        [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3], [1, 3, 4], [1, 3, 2]],  # quad fanned in place
    )
    assert {k: v.tolist() for k, v in mesh.parts.items()} == {
        "skin": [0, 1, 5],
        "skin_mat": [0, 1, 2, 3, 4, 5],  # usemtl: a material names a part too
        "eye": [2, 3, 4],
    }
    assert mesh.materials == {}  # no .mtl file: nothing known about skin_mat
    assert mesh.units == "cm"


def test_load_mesh_obj_objects_become_parts_and_groups_reset_per_object(tmp_path):
    path = tmp_path / "objects.obj"
    path.write_text(
        "v 0 0 0\nv 20 0 0\nv 0 20 0\nv 0 0 20\n"
        "o Head\nf 1 3 2\nf 1 2 4\ng lips\nf 1 4 3\no Teeth\nf 2 3 4\ng\nf 4 3 2\n"
    )
    mesh = load_mesh(path)
    assert {k: v.tolist() for k, v in mesh.parts.items()} == {"Head": [0, 1], "lips": [2], "Teeth": [3, 4]}


def test_load_mesh_obj_vertex_colors_round_trip_exactly(tmp_path):
    mesh = head_like()
    loaded = load_mesh(save_mesh(mesh, tmp_path / "c.obj"))
    np.testing.assert_array_equal(loaded.colors, mesh.colors)


def test_load_mesh_obj_0_255_colours_are_scaled(tmp_path):
    path = tmp_path / "c.obj"
    rows = ["v 0 0 0 255 0 51", "v 20 0 0 0 0 0", "v 0 20 0 0 0 0", "v 0 0 20 0 0 0"]
    path.write_text("\n".join([*rows, "f 1 3 2", "f 1 2 4", "f 1 4 3", "f 2 3 4", ""]))
    colors = load_mesh(path).colors
    assert colors is not None
    np.testing.assert_allclose(colors[0], [1.0, 0.0, 0.2], rtol=1e-6)


def test_load_mesh_obj_units_comment_wins_over_detection(tmp_path, tetrahedron):
    mesh = Mesh(tetrahedron.vertices * 20, tetrahedron.faces, units="mm")  # 20 mm: detection says cm
    assert load_mesh(save_mesh(mesh, tmp_path / "t.obj")).units == "mm"
    assert load_mesh(tmp_path / "t.obj", units="dm").units == "dm"  # explicit override wins


@pytest.mark.parametrize("ext", [".ply", ".glb"])
def test_load_mesh_units_recorded_in_file_are_used(tmp_path, tetrahedron, ext):
    mesh = Mesh(tetrahedron.vertices * 20, tetrahedron.faces, units="mm")
    assert load_mesh(save_mesh(mesh, tmp_path / f"t{ext}")).units == "mm"


def test_load_mesh_obj_matches_trimesh_positions_where_trimesh_keeps_order(tmp_path):
    # A plain OBJ (no vt/vn) is the one case where trimesh with maintain_order keeps every vertex.
    mesh = head_like(colors=False)
    path = save_mesh(mesh, tmp_path / "plain.obj")
    reference = trimesh.load_mesh(path, process=False, maintain_order=True)
    np.testing.assert_allclose(load_mesh(path).vertices, reference.vertices, rtol=0, atol=0)


OBJ_WITH_MATERIALS = """mtllib head.mtl
v 0 0 0
v 20 0 0
v 0 20 0
v 0 0 20
v 99 99 99
v 20 20 0
g head
usemtl Skin
f 1 2 3
usemtl Film
f 1 3 4
usemtl Lash
f 2 6 3
"""
MTL = """# three materials
newmtl Skin
Kd 0.8 0.5 0.4
newmtl Film
Kd 1 1 1
Tr 0.75
newmtl Lash
Kd 0.1 0.1 0.1
d 1.0
"""


def test_load_mesh_obj_materials_become_parts_with_mtl_colour_and_opacity(tmp_path):
    (tmp_path / "head.obj").write_text(OBJ_WITH_MATERIALS)
    (tmp_path / "head.mtl").write_text(MTL)
    mesh = load_mesh(tmp_path / "head.obj", units="cm", check=False)
    np.testing.assert_array_equal(
        mesh.vertices, [[0, 0, 0], [20, 0, 0], [0, 20, 0], [0, 0, 20], [99, 99, 99], [20, 20, 0]]
    )  # every v line, in order, the unused one too
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2], [0, 2, 3], [1, 5, 2]])
    assert {k: v.tolist() for k, v in mesh.parts.items()} == {
        "head": [0, 1, 2],
        "Skin": [0],
        "Film": [1],
        "Lash": [2],
    }
    assert mesh.materials == {
        "Skin": Material("Skin", (0.8, 0.5, 0.4), 1.0),
        "Film": Material("Film", (1.0, 1.0, 1.0), 0.25),  # Tr 0.75
        "Lash": Material("Lash", (0.1, 0.1, 0.1), 1.0),
    }
    assert mesh.materials["Film"].transparent and not mesh.materials["Skin"].transparent
    # every opaque face is coloured, so the colours become per-vertex: the mean of the opaque faces
    # around a vertex, a see-through face's colour only where no opaque face is, grey if unused
    np.testing.assert_allclose(
        mesh.colors,
        [[0.8, 0.5, 0.4], [0.45, 0.3, 0.25], [0.45, 0.3, 0.25], [1, 1, 1], [0.6, 0.6, 0.6], [0.1, 0.1, 0.1]],
        atol=1e-6,
    )


def test_load_mesh_obj_missing_mtl_warns_and_loads_material_parts_without_materials(tmp_path):
    (tmp_path / "head.obj").write_text(OBJ_WITH_MATERIALS)
    with pytest.warns(MimeticWarning, match=r"head\.mtl.*beside the OBJ"):
        mesh = load_mesh(tmp_path / "head.obj", units="cm", check=False)
    assert mesh.n_vertices == 6 and mesh.n_faces == 3
    assert list(mesh.parts) == ["head", "Skin", "Film", "Lash"]
    assert mesh.materials == {}
    assert mesh.colors is None


def test_load_mesh_obj_textured_default_and_uncoloured_materials_leave_colors_unset(tmp_path):
    (tmp_path / "head.obj").write_text(OBJ_WITH_MATERIALS.replace("Film", "Material.001"))
    (tmp_path / "head.mtl").write_text(
        "newmtl Skin\nKd 0.8 0.5 0.4\nmap_Kd skin.png\n"  # Kd only tints the texture
        "newmtl Material.001\nKd 0.8 0.8 0.8\n"  # a modelling tool's placeholder
        "newmtl Lash\nd -halo 0.3\n"  # no Kd; opacity with the -halo option
    )
    mesh = load_mesh(tmp_path / "head.obj", units="cm", check=False)
    assert mesh.materials == {
        "Skin": Material("Skin", None, 1.0),
        "Material.001": Material("Material.001", None, 1.0),
        "Lash": Material("Lash", None, 0.3),
    }
    assert mesh.colors is None  # no face has a colour from the file


def test_save_load_obj_with_materials_keeps_vertices_colours_and_parts(tmp_path):
    (tmp_path / "head.obj").write_text(OBJ_WITH_MATERIALS)
    (tmp_path / "head.mtl").write_text(MTL)
    loaded = load_mesh(tmp_path / "head.obj", units="cm", check=False)
    again = load_mesh(save_mesh(loaded, tmp_path / "copy.obj"), check=False)
    assert_same_arrays(again, loaded)
    np.testing.assert_array_equal(again.colors, loaded.colors)
    assert {k: v.tolist() for k, v in again.parts.items()} == {k: v.tolist() for k, v in loaded.parts.items()}
    assert again.units == "cm"


# --- glTF reading ---------------------------------------------------------------------------------


def test_load_mesh_glb_single_geometry_has_no_parts(tmp_path):
    sphere_mesh = sphere(11.0, [0, 0, 0])
    path = tmp_path / "one.glb"
    path.write_bytes(
        trimesh.Trimesh(sphere_mesh.vertices, sphere_mesh.faces, process=False).export(file_type="glb")
    )
    mesh = load_mesh(path)
    assert mesh.parts == {}
    assert mesh.n_vertices == sphere_mesh.n_vertices
    assert mesh.units == "cm"  # glTF's implicit metres ignored: 22 units is a head in cm


def test_load_mesh_glb_from_trimesh_scene_follows_file_node_order_and_transforms(tmp_path):
    scene = trimesh.Scene()
    pieces = {"zeta": sphere(10.0, [0, 0, 0]), "alpha": sphere(1.0, [0, 0, 0]), "mid": sphere(1.0, [0, 0, 0])}
    shifts = {"zeta": [0, 0, 0], "alpha": [3, 2, 9], "mid": [-3, 2, 9]}
    for name, piece in pieces.items():
        tm = trimesh.Trimesh(piece.vertices, piece.faces, process=False)
        scene.add_geometry(
            tm,
            node_name=name,
            geom_name=name,
            transform=trimesh.transformations.translation_matrix(shifts[name]),
        )
    path = tmp_path / "scene.glb"
    path.write_bytes(scene.export(file_type="glb"))
    mesh = load_mesh(path)
    assert list(mesh.parts) == ["zeta", "alpha", "mid"]
    for name, piece in pieces.items():
        sub, _ = mesh.submesh(name)
        np.testing.assert_allclose(sub.vertices, piece.vertices + shifts[name], atol=1e-5)


def test_load_mesh_glb_hierarchy_primitives_and_mirror_are_resolved(tmp_path):
    shared = np.array([[0, 0, 0], [20, 0, 0], [0, 20, 0], [0, 0, 20]], dtype=np.float32)
    other = np.array([[0, 0, 0], [5, 0, 0], [0, 5, 0]], dtype=np.float32)
    tri_a = np.array([0, 2, 1], dtype=np.uint32)
    tri_b = np.array([1, 2, 3], dtype=np.uint32)
    tri_c = np.array([0, 1, 2], dtype=np.uint32)
    meshes = [
        {"name": "face_mesh", "primitives": [
            {"attributes": {"POSITION": 0}, "indices": 1, "material": 0},
            {"attributes": {"POSITION": 0}, "indices": 2, "material": 1},  # shares POSITION
        ]},
        {"name": "other_mesh", "primitives": [{"attributes": {"POSITION": 3}, "indices": 4}]},
    ]  # fmt: skip
    nodes = [
        {"name": "root", "translation": [0, 5, 0], "children": [1]},
        {"name": "face", "mesh": 0, "scale": [-1, 1, 1]},
        {"name": "other", "mesh": 1},
    ]
    header, blob = gltf_header(
        [shared, tri_a, tri_b, other, tri_c],
        meshes,
        nodes,
        roots=[2, 0],
        materials=[{"name": "skin"}, {"name": "eyes"}],
    )
    path = tmp_path / "built.glb"
    path.write_bytes(glb_bytes(header, blob))
    mesh = load_mesh(path, units="cm", check=False)
    # depth-first from the scene roots [2, 0]: other, then root's child face (two primitives)
    assert list(mesh.parts) == ["other", "face_skin", "face_eyes"]
    assert mesh.vertices.shape == (7, 3)  # the shared POSITION accessor is used once
    expected_face = shared.astype(np.float64) * [-1, 1, 1] + [0, 5, 0]
    np.testing.assert_array_equal(mesh.vertices[:3], other)
    np.testing.assert_array_equal(mesh.vertices[3:], expected_face)
    # the mirror reverses winding, so faces are flipped back to stay outward
    np.testing.assert_array_equal(mesh.faces, [[0, 1, 2], [3, 4, 5], [4, 6, 5]])
    assert {k: v.tolist() for k, v in mesh.parts.items()} == {
        "other": [0],
        "face_skin": [1],
        "face_eyes": [2],
    }


def test_load_mesh_gltf_with_missing_bin_names_the_problem(tmp_path):
    header, _ = gltf_header(
        [np.eye(3, dtype=np.float32) * 20, np.array([0, 1, 2], np.uint32)],
        [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        [{"mesh": 0}],
        roots=[0],
    )
    header["buffers"][0]["uri"] = "missing.bin"
    path = tmp_path / "external.gltf"
    path.write_text(json.dumps(header))
    with pytest.raises(MeshError, match=r"external\.gltf: not a readable GLTF file"):
        load_mesh(path)


def test_load_mesh_glb_accessor_past_buffer_end_raises(tmp_path):
    header, blob = gltf_header(
        [np.eye(3, dtype=np.float32) * 20, np.array([0, 1, 2], np.uint32)],
        [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
        [{"mesh": 0}],
        roots=[0],
    )
    header["accessors"][0]["count"] = 1000
    path = tmp_path / "bad.glb"
    path.write_bytes(glb_bytes(header, blob))
    with pytest.raises(MeshError, match=r"bad\.glb"):
        load_mesh(path)


def test_load_mesh_glb_materials_give_parts_colours_and_opacity(tmp_path):
    big = (np.array([[0, 0, 0], [20, 0, 0], [0, 20, 0], [0, 0, 20]]) + 0.0).astype(np.float32)
    small = (big / 10 + 5).astype(np.float32)
    tri = np.array([0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3], dtype=np.uint32)
    meshes = [
        {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]},
        {"primitives": [{"attributes": {"POSITION": 2}, "indices": 3, "material": 1}]},
        {"primitives": [{"attributes": {"POSITION": 4}, "indices": 5, "material": 2}]},
    ]
    materials = [
        {"name": "SkinMat", "pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.5, 0.4, 1.0]}},
        {"name": "Shell", "alphaMode": "BLEND",
         "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.9, 1, 0.2]}},
        {"name": "Cut", "alphaMode": "MASK", "alphaCutoff": 0.5,
         "pbrMetallicRoughness": {"baseColorFactor": [0.1, 0.1, 0.1, 0.4]}},
    ]  # fmt: skip
    nodes = [{"name": "skin", "mesh": 0}, {"name": "occlusion", "mesh": 1}, {"name": "lashes", "mesh": 2}]
    header, blob = gltf_header(
        [big, tri, small, tri, small + 1, tri], meshes, nodes, [0, 1, 2], materials=materials
    )
    path = tmp_path / "materials.glb"
    path.write_bytes(glb_bytes(header, blob))
    mesh = load_mesh(path, units="cm", check=False)
    assert list(mesh.parts) == ["skin", "occlusion", "lashes"]
    assert mesh.materials["skin"] == Material("SkinMat", (0.8, 0.5, 0.4), 1.0)
    assert mesh.materials["occlusion"].opacity == pytest.approx(0.2)
    assert mesh.materials["occlusion"].transparent
    assert mesh.materials["lashes"].opacity == 0.0  # MASK: alpha below the cutoff
    assert mesh.n_vertices == 12  # vertex order and count as stored
    np.testing.assert_array_equal(mesh.vertices[:4], big)
    np.testing.assert_allclose(mesh.colors[:4], np.tile([0.8, 0.5, 0.4], (4, 1)), atol=1e-6)
    np.testing.assert_allclose(mesh.colors[4:8], np.tile([0.9, 0.9, 1.0], (4, 1)), atol=1e-6)


def test_load_mesh_glb_white_factor_or_texture_is_no_colour(tmp_path):
    big = (np.array([[0, 0, 0], [20, 0, 0], [0, 20, 0], [0, 0, 20]]) + 0.0).astype(np.float32)
    tri = np.array([0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3], dtype=np.uint32)
    meshes = [
        {"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "material": 0}]},
        {"primitives": [{"attributes": {"POSITION": 2}, "indices": 3, "material": 1}]},
    ]
    materials = [
        {"name": "plain", "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 1]}},
        {"name": "painted", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 0.2, 0.2, 1],
                                                      "baseColorTexture": {"index": 0}}},
    ]  # fmt: skip
    nodes = [{"name": "a", "mesh": 0}, {"name": "b", "mesh": 1}]
    header, blob = gltf_header([big, tri, big + 30, tri], meshes, nodes, [0, 1], materials=materials)
    path = tmp_path / "plain.glb"
    path.write_bytes(glb_bytes(header, blob))
    mesh = load_mesh(path, units="cm", check=False)
    assert mesh.materials == {"a": Material("plain", None, 1.0), "b": Material("painted", None, 1.0)}
    assert mesh.colors is None


# --- loader errors --------------------------------------------------------------------------------


def test_load_mesh_missing_file_raises_naming_it(tmp_path):
    with pytest.raises(MeshError, match=r"nothere\.obj: no such file"):
        load_mesh(tmp_path / "nothere.obj")


def test_load_mesh_unknown_extension_lists_supported(tmp_path):
    path = tmp_path / "cloud.xyz"
    path.write_text("0 0 0\n")
    with pytest.raises(MeshError, match=r"cloud\.xyz: unsupported mesh format \('\.xyz'\)") as info:
        load_mesh(path)
    for ext in SUPPORTED_FORMATS:
        assert ext in str(info.value)


def test_load_mesh_text_file_named_obj_is_not_a_mesh(tmp_path):
    path = tmp_path / "notes.obj"
    path.write_text("Shopping list\nmilk\neggs\n")
    with pytest.raises(MeshError, match=r"notes\.obj: not a Wavefront OBJ file: line 1"):
        load_mesh(path)


@pytest.mark.parametrize(
    ("ext", "message"),
    [(".glb", "not a GLB"), (".ply", "not a PLY"), (".stl", "not an STL"), (".obj", "binary")],
)
def test_load_mesh_random_bytes_raise_mesh_error(tmp_path, ext, message):
    path = tmp_path / f"noise{ext}"
    path.write_bytes(np.random.default_rng(1).integers(0, 256, 3000, dtype=np.uint8).tobytes())
    with pytest.raises(MeshError, match=rf"noise\{ext}: .*{message}"):
        load_mesh(path)


def test_load_mesh_text_file_named_ply_or_gltf_is_rejected(tmp_path):
    for ext in (".ply", ".gltf", ".stl"):
        path = tmp_path / f"notes{ext}"
        path.write_text("hello, this is text\n")
        with pytest.raises(MeshError, match=rf"notes\{ext}: not a"):
            load_mesh(path)


@pytest.mark.parametrize("keep", [0.5, 0.9, 30 / 1000])
def test_load_mesh_truncated_glb_raises(tmp_path, keep):
    data = save_mesh(head_like(float32=True), tmp_path / "good.glb").read_bytes()
    path = tmp_path / "cut.glb"
    path.write_bytes(data[: int(len(data) * keep)])
    with pytest.raises(MeshError, match=r"cut\.glb: .*(truncated|corrupt)"):
        load_mesh(path)


@pytest.mark.parametrize("text", ["", "# only a comment\n\n"])
def test_load_mesh_empty_obj_raises(tmp_path, text):
    path = tmp_path / "empty.obj"
    path.write_text(text)
    with pytest.raises(MeshError, match=r"empty\.obj: the OBJ file has no vertices and no faces"):
        load_mesh(path)


def test_load_mesh_obj_with_vertices_only_is_not_a_surface(tmp_path):
    path = tmp_path / "points.obj"
    path.write_text("v 0 0 0\nv 1 0 0\n")
    with pytest.raises(MeshError, match=r"points\.obj: contains no faces \(2 vertices\)"):
        load_mesh(path)


def test_load_mesh_obj_face_index_out_of_range_gives_line_number(tmp_path):
    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n")
    with pytest.raises(MeshError, match=r"bad\.obj: line 5: face 'f 1 2 9'"):
        load_mesh(path)


def test_load_mesh_obj_bad_number_gives_line_number(tmp_path):
    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 zero 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(MeshError, match=r"line 2: cannot read 'v 1 zero 0'"):
        load_mesh(path)


def test_load_mesh_folder_raises(tmp_path):
    folder = tmp_path / "head.obj"
    folder.mkdir()
    with pytest.raises(MeshError, match="is a folder"):
        load_mesh(folder)


def test_load_mesh_nan_vertex_rejected_unless_unchecked(tmp_path, tetrahedron):
    vertices = tetrahedron.vertices * 20
    vertices[1, 2] = np.nan
    path = save_mesh(Mesh(vertices, tetrahedron.faces), tmp_path / "nan.obj")
    with pytest.raises(MeshError, match=r"nan\.obj: 1 of 4 vertices have NaN .*check=False"):
        load_mesh(path)
    mesh = load_mesh(path, check=False)
    assert np.isnan(mesh.vertices[1, 2])
    assert validate_mesh(mesh).n_nonfinite_vertices == 1


def test_load_mesh_too_few_faces_rejected_unless_unchecked(tmp_path, unit_square):
    path = save_mesh(Mesh(unit_square.vertices * 20, unit_square.faces), tmp_path / "square.ply")
    with pytest.raises(MeshError, match=r"square\.ply: only 2 faces"):
        load_mesh(path)
    assert load_mesh(path, check=False).n_faces == 2


def test_load_mesh_undetectable_units_raise_with_hint_unless_given(tmp_path, tetrahedron):
    path = save_mesh(Mesh(tetrahedron.vertices * 1e6, tetrahedron.faces), tmp_path / "huge.ply")
    with pytest.raises(MeshError, match=r'huge\.ply: cannot tell the units: .*1e\+06.*units="cm"'):
        load_mesh(path)
    assert load_mesh(path, units="mm").units == "mm"
    assert load_mesh(path, check=False).units is None


def test_load_mesh_bad_units_argument_lists_allowed(tmp_path, tetrahedron):
    path = save_mesh(Mesh(tetrahedron.vertices * 20, tetrahedron.faces), tmp_path / "t.ply")
    with pytest.raises(MeshError, match="'mm', 'cm', 'dm', 'm'"):
        load_mesh(path, units="inches")
