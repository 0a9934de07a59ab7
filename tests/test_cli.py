"""End-to-end tests of the ``mimetic`` command: outputs, exit codes and bad input."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest
from PIL import Image

from mimetic.head.model import make_head
from mimetic.mesh.io import load_mesh, save_mesh
from mimetic.mesh.model import Mesh
from mimetic.rig.format import load_rig
from mimetic.testing import run_cli

RES = "2500"


@pytest.fixture(scope="module")
def rig_file(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli")
    result = run_cli(
        "head", "--seed", "3", "--resolution", RES, "-o", str(out / "h.glb"), "--rig", str(out / "h.mrig")
    )
    assert result.exit_code == 0, result.output
    return out / "h.mrig"


def test_head_writes_a_mesh_with_the_generated_vertices(tmp_path):
    out = tmp_path / "head.obj"
    result = run_cli("head", "--resolution", RES, "--param", "nose_length=1.1", "-o", str(out))
    assert result.exit_code == 0, result.output
    assert str(out) in result.output
    mesh = load_mesh(out)
    from mimetic.head.params import HeadParams

    expected = make_head(HeadParams(nose_length=1.1), 2500).mesh
    assert mesh.vertices.shape == expected.vertices.shape
    np.testing.assert_allclose(mesh.vertices, expected.vertices, atol=1e-9)
    assert set(mesh.parts) == set(expected.parts)


def test_head_with_rig_writes_a_loadable_rig(rig_file):
    rig = load_rig(rig_file)
    assert rig.units == "cm"
    assert len(rig.muscles) >= 26


def test_info_reports_units_parts_and_landmarks_of_a_rig(rig_file):
    result = run_cli("info", str(rig_file), "--json")
    assert result.exit_code == 0, result.output
    report = json.loads(result.output)
    assert report["kind"] == "rig"
    assert report["units"] == "cm"
    assert "skin" in report["parts"] and "eye_L" in report["parts"]
    assert "nose_tip" in report["landmarks"] and len(report["landmarks"]) >= 40


def test_info_on_a_mesh_prints_the_validation_report(rig_file):
    result = run_cli("info", str(rig_file.with_suffix(".glb")))
    assert result.exit_code == 0, result.output
    assert "cm" in result.output and "boundary loops" in result.output and "eye_L" in result.output


def test_render_of_a_rig_writes_a_three_view_sheet(rig_file, tmp_path):
    out = tmp_path / "r.png"
    result = run_cli("render", str(rig_file), "-o", str(out), "--size", "128")
    assert result.exit_code == 0, result.output
    image = np.asarray(Image.open(out))
    assert image.shape[1] == 3 * 128 and image.shape[2] == 3
    assert image.std() > 10  # a shaded head, not a blank canvas


def test_render_single_view_of_a_mesh(rig_file, tmp_path):
    out = tmp_path / "front.png"
    result = run_cli(
        "render", str(rig_file.with_suffix(".glb")), "--view", "profile", "--size", "96", "-o", str(out)
    )
    assert result.exit_code == 0, result.output
    assert Image.open(out).size == (96, 96)


def test_demo_writes_heads_rigs_and_sheets(tmp_path):
    out = tmp_path / "demo"
    result = run_cli("demo", "-o", str(out), "--resolution", RES)
    assert result.exit_code == 0, result.output
    for name in ("head.glb", "default.mrig", "default_views.png", "heads_muscles.png"):
        assert (out / name).stat().st_size > 1000, name
    assert len(list((out / "rigs").glob("seed_*.mrig"))) == 8
    assert len(list((out / "heads").glob("seed_*.glb"))) == 8
    assert (
        load_rig(out / "rigs" / "seed_5.mrig").metadata["params"]
        != load_rig(out / "default.mrig").metadata["params"]
    )


# --- bad input: a clear one-line error, exit code 1, no file overwritten ------------------------


def _fails_with(result, *words: str) -> None:
    assert result.exit_code == 1, result.output
    text = result.output.lower()
    for word in words:
        assert word.lower() in text, f"{word!r} not in {result.output!r}"
    assert "traceback" not in text


def test_info_rejects_a_file_that_is_not_a_mesh(tmp_path):
    bad = tmp_path / "notes.obj"
    bad.write_text("hello world\n")
    _fails_with(run_cli("info", str(bad)), "notes.obj", "not a wavefront obj")


def test_info_rejects_an_empty_mesh(tmp_path):
    empty = tmp_path / "empty.obj"
    empty.write_text("")
    _fails_with(run_cli("info", str(empty)), "empty")


def test_info_reports_nan_coordinates(tmp_path):
    path = tmp_path / "nan.obj"
    path.write_text("v nan 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 3 4\nf 1 4 2\nf 2 4 3\n")
    _fails_with(run_cli("info", str(path)), "nan")


def test_render_rejects_a_two_triangle_mesh_and_keeps_the_old_png(tmp_path):
    path = tmp_path / "two.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n")
    old = tmp_path / "out.png"
    old.write_bytes(b"precious")
    _fails_with(run_cli("render", str(path), "-o", str(old)), "2 faces")
    assert old.read_bytes() == b"precious"


def test_info_detects_millimetres(tmp_path):
    head = make_head(resolution=2500)
    mm = Mesh(head.mesh.vertices * 10.0, head.mesh.faces)
    path = save_mesh(mm, tmp_path / "mm.ply")
    result = run_cli("info", str(path), "--json")
    assert result.exit_code == 0, result.output
    assert json.loads(result.output)["detected_units"] == "mm"


def test_info_rejects_a_truncated_rig(rig_file, tmp_path):
    cut = tmp_path / "cut.mrig"
    cut.write_bytes(rig_file.read_bytes()[: rig_file.stat().st_size // 2])
    _fails_with(run_cli("info", str(cut)), "truncated")


def test_info_rejects_a_rig_from_a_newer_format_version(rig_file, tmp_path):
    newer = tmp_path / "newer.mrig"
    with zipfile.ZipFile(rig_file) as src, zipfile.ZipFile(newer, "w") as dst:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "manifest.json":
                manifest = json.loads(data)
                manifest["version"] = 99
                data = json.dumps(manifest).encode()
            dst.writestr(item, data)
    _fails_with(run_cli("info", str(newer)), "version 99", "upgrade")


def test_head_rejects_unknown_parameter_and_keeps_existing_file(tmp_path):
    out = tmp_path / "head.glb"
    out.write_bytes(b"old")
    _fails_with(
        run_cli("head", "--param", "nose=1.1", "-o", str(out)), "unknown head parameter", "nose_length"
    )
    assert out.read_bytes() == b"old"


def test_head_rejects_out_of_range_parameter(tmp_path):
    _fails_with(
        run_cli("head", "--param", "jaw_width=3", "-o", str(tmp_path / "h.glb")), "jaw_width", "range"
    )


def test_render_rejects_unknown_view(rig_file, tmp_path):
    _fails_with(run_cli("render", str(rig_file), "--view", "top", "-o", str(tmp_path / "x.png")), "top")
