"""End-to-end tests of ``mimetic rig``: a mesh and landmarks in, a rig, a report and a picture out."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from mimetic.head.model import make_head
from mimetic.head.params import HeadParams
from mimetic.mesh.io import save_mesh
from mimetic.rig.format import load_rig
from mimetic.testing import run_cli


@pytest.fixture(scope="module")
def head_files(tmp_path_factory):
    """A random generated head in millimetres (OBJ) and a landmark file in iBUG and project names."""
    folder = tmp_path_factory.mktemp("rig")
    head = make_head(HeadParams.random(4), 3_000)
    mesh = head.mesh.with_vertices(10 * head.mesh.vertices)
    mesh = type(mesh)(mesh.vertices, mesh.faces, units="mm")
    mesh_file = save_mesh(mesh, folder / "head.obj")
    names = ["nose_tip", "subnasale", "glabella", "pogonion", "upper_lip_top", "lower_lip_bottom"]
    marks = {n: (head.landmark_positions([n])[0]).tolist() for n in names}
    from mimetic.head.landmarks import IBUG68

    for k in (37, 40, 43, 46, 49, 55, 18, 27):  # 1-based iBUG numbers: eye corners, mouth corners, brows
        marks[f"ibug68_{k:02d}"] = head.landmark_positions([IBUG68[k - 1]])[0].tolist()
    lm_file = folder / "lm.json"
    lm_file.write_text(json.dumps({"units": "cm", "landmarks": marks}))
    return head, mesh_file, lm_file, folder


def test_rig_writes_rig_report_and_picture(head_files):
    head, mesh_file, lm_file, folder = head_files
    out = folder / "head.mrig"
    result = run_cli("rig", mesh_file, "--landmarks", lm_file, "-o", out)
    assert result.exit_code == 0, result.output
    assert "accepted" in result.output
    rig = load_rig(out)
    assert rig.units == "mm" and rig.n_vertices == head.mesh.n_vertices
    np.testing.assert_allclose(rig.mesh.vertices, 10 * head.mesh.vertices, atol=1e-4)  # OBJ text precision
    report = json.loads((folder / "head.fit.json").read_text())
    assert report["accepted"] and report["mean_pct"] < 0.1 and report["units"] == "mm"
    image = np.asarray(Image.open(folder / "head.fit.png"))
    assert image.ndim == 3 and image.std() > 10
    # every other command takes the rig
    posed = folder / "joy.png"
    assert run_cli("pose", out, "--expr", "joy", "--size", "64", "-o", posed).exit_code == 0
    info = run_cli("info", out, "--json")
    assert info.exit_code == 0 and '"kind": "rig"' in info.output


def test_rig_refuses_both_landmark_sources(head_files, tmp_path):
    _, mesh_file, lm_file, _ = head_files
    result = run_cli("rig", mesh_file, "--landmarks", lm_file, "--auto-landmarks", "-o", tmp_path / "x.mrig")
    assert result.exit_code == 2 and "not both" in result.output  # a usage error
    assert not (tmp_path / "x.mrig").exists()


def test_rig_refuses_a_box_and_writes_nothing(tmp_path, head_files):
    import trimesh

    head, _, lm_file, _ = head_files
    lo, hi = 10 * head.mesh.vertices.min(axis=0), 10 * head.mesh.vertices.max(axis=0)
    box = trimesh.creation.box(extents=hi - lo)
    box.apply_translation((hi + lo) / 2)
    mesh_file = tmp_path / "box.stl"
    box.export(mesh_file)
    out = tmp_path / "box.mrig"
    out.write_bytes(b"a good old file")
    result = run_cli("rig", mesh_file, "--units", "mm", "--landmarks", lm_file, "-o", out)
    assert result.exit_code == 1 and "does not look like a head" in result.output
    assert out.read_bytes() == b"a good old file"


def test_rig_names_a_bad_landmark_file(head_files, tmp_path):
    _, mesh_file, _, _ = head_files
    bad = tmp_path / "lm.json"
    bad.write_text('{"units": "cm", "landmarks": {"nose_tip": [0, 0, 1]}}')
    result = run_cli("rig", mesh_file, "--landmarks", bad, "-o", tmp_path / "x.mrig")
    assert result.exit_code == 1 and "at least 8" in result.output


@pytest.fixture(scope="module")
def z_up_rig(head_files):
    """The head of ``head_files`` exported the Blender way, Z up with the face toward -Y, in mm with
    no units in the file (an STL), rigged from the same landmarks turned likewise."""
    head, _, _, folder = head_files
    to_z_up = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # (x, y, z) -> (x, -z, y)
    vertices = 10 * head.mesh.vertices @ to_z_up.T
    mesh_file = save_mesh(type(head.mesh)(vertices, head.mesh.faces), folder / "z_up.obj")
    names = ["nose_tip", "subnasale", "glabella", "pogonion", "upper_lip_top", "lower_lip_bottom"]
    names += ["eye_outer_corner_L", "eye_outer_corner_R", "mouth_corner_L", "mouth_corner_R"]
    marks = {n: (10 * head.landmark_positions([n])[0] @ to_z_up.T).tolist() for n in names}
    lm_file = folder / "z_up_lm.json"
    lm_file.write_text(json.dumps({"units": "mm", "landmarks": marks}))
    out = folder / "z_up.mrig"
    result = run_cli("rig", mesh_file, "--units", "mm", "--landmarks", lm_file, "-o", out)
    assert result.exit_code == 0, result.output
    return vertices, out, folder


def test_pose_and_export_objs_of_a_z_up_head_lie_on_the_users_mesh(z_up_rig):
    from mimetic.mesh.io import load_mesh

    vertices, rig_file, folder = z_up_rig
    rest = folder / "rest.obj"
    assert run_cli("pose", rig_file, "-o", rest).exit_code == 0
    np.testing.assert_allclose(load_mesh(rest).vertices, vertices, atol=1e-4)  # OBJ text precision
    smile = folder / "smile.ply"
    assert run_cli("pose", rig_file, "--set", "zygomatic_major_L=1", "-o", smile).exit_code == 0
    moved = np.linalg.norm(load_mesh(smile).vertices - vertices, axis=1)
    assert (
        moved.max() > 1.0 and moved.max() < 30.0
    )  # mm, in the user's frame: a smile moves the corner a few mm
    shapes = folder / "shapes"
    assert run_cli("export", rig_file, "-o", folder / "z_up.glb", "--obj-dir", shapes).exit_code == 0
    smile_shape = load_mesh(shapes / "zygomatic_major_L.obj").vertices
    offsets = np.linalg.norm(smile_shape - vertices, axis=1)
    assert np.median(offsets) < 1e-3 and offsets.max() > 1.0  # on the user's mesh; the cheek moves (mm)


def test_export_of_a_z_up_head_is_an_upright_glb(z_up_rig):
    import pygltflib as gl

    from mimetic.export import read_accessor

    _, rig_file, folder = z_up_rig
    path = folder / "upright.glb"
    assert run_cli("export", rig_file, "-o", path).exit_code == 0
    doc = gl.GLTF2.load(path)
    assert all(node.rotation is None and node.matrix is None for node in doc.nodes)
    skin = read_accessor(doc, doc.meshes[0].primitives[0].attributes.POSITION)
    extent = np.ptp(skin, axis=0)
    assert np.argmax(extent[:2]) == 1 and 0.15 < extent[1] < 0.35  # metres, tall along +Y


def test_rig_of_a_real_head_as_a_triangle_soup_stays_within_2_gib(tmp_path):
    """ICT's head unwelded into a soup (52,220 triangles, 156,660 vertices), rigged from the command
    line in a fresh process: it used to be killed at 16 GiB inside mesh validation."""
    from mimetic.fit.landmarks import write_landmarks
    from mimetic.testing import ict_landmarks, load_ict, require_shared_data, triangle_soup
    from mimetic.testing.memory import peak_rss

    neutral, meta = load_ict(require_shared_data("ict-facekit"))
    save_mesh(triangle_soup(neutral), tmp_path / "soup.obj")
    write_landmarks(ict_landmarks(neutral, meta), tmp_path / "soup.json")
    code = (
        "from mimetic.cli import app\n"
        "try:\n"
        "    app(['rig', 'soup.obj', '--landmarks', 'soup.json', '-o', 'soup.mrig'])\n"
        "except SystemExit as end:\n"
        "    assert not end.code, end.code\n"
    )
    measured = peak_rss(code, cwd=tmp_path)
    assert load_rig(tmp_path / "soup.mrig").n_vertices == 156_660
    assert measured.peak_gib < 2.0, f"peak {measured.peak_gib:.2f} GiB"
