"""End-to-end tests of ``mimetic pose``: outputs written, and bad input as one line with exit code 1."""

from __future__ import annotations

import json

import numpy as np
import pytest
from PIL import Image

from mimetic.engines import ENGINES
from mimetic.mesh.io import load_mesh
from mimetic.rig.format import save_rig
from mimetic.testing import run_cli, small_rig


@pytest.fixture(scope="module")
def rig_file(tmp_path_factory):
    return save_rig(small_rig(), tmp_path_factory.mktemp("pose") / "small.mrig")


def test_pose_writes_a_png_render(rig_file, tmp_path):
    out = tmp_path / "joy.png"
    result = run_cli("pose", rig_file, "--expr", "joy=0.8", "--expr", "surprise", "--set", "jaw_open=0.1",
                     "--size", "96", "-o", out)  # fmt: skip
    assert result.exit_code == 0, result.output
    assert str(out) in result.output
    image = np.asarray(Image.open(out))
    assert image.shape == (96, 96, 3) and image.std() > 5


def test_pose_view_all_writes_a_three_view_sheet(rig_file, tmp_path):
    out = tmp_path / "all.png"
    result = run_cli("pose", rig_file, "--expr", "quizzical", "--view", "all", "--size", "64", "-o", out)
    assert result.exit_code == 0, result.output
    width, height = Image.open(out).size
    assert width == 3 * 64 and height > 64


@pytest.mark.parametrize("engine", ENGINES)
def test_pose_writes_the_posed_mesh_in_rig_vertex_order(rig_file, tmp_path, engine):
    from mimetic.animate.expressions import expression_pose
    from mimetic.engines import make_engine

    rig = small_rig()
    out = tmp_path / f"joy_{engine}.obj"
    result = run_cli("pose", rig_file, "--expr", "joy", "--engine", engine, "-o", out)
    assert result.exit_code == 0, result.output
    assert f"prepare {engine}" in result.stderr  # the engine's preparation is shown as it starts
    mesh = load_mesh(out)
    assert mesh.vertices.shape == (rig.n_vertices, 3)
    expected = make_engine(rig, engine).deform(expression_pose(rig, "joy"))
    np.testing.assert_allclose(mesh.vertices, expected, atol=1e-5)  # OBJ text precision
    assert not np.allclose(mesh.vertices, rig.mesh.vertices)


def test_pose_a_proxy_too_small_exits_1_saying_what_to_ask(rig_file, tmp_path):
    out = tmp_path / "out.png"
    result = run_cli("pose", rig_file, "--engine", "fem", "--proxy", "10", "-o", out)
    assert result.exit_code == 1
    last = result.output.strip().splitlines()[-1]  # after the preparation's progress line
    assert last.startswith("error: --proxy 10:") and "'auto'" in last and "at least 500" in last
    assert "Traceback" not in result.output and not out.exists()


def test_pose_simulates_through_the_proxy_asked_for(rig_file, tmp_path):
    from mimetic.animate.expressions import expression_pose
    from mimetic.engines import make_engine

    rig = small_rig()
    out = tmp_path / "joy_proxy.obj"
    result = run_cli("pose", rig_file, "--expr", "joy", "--engine", "fem", "--proxy", "1500", "-o", out)
    assert result.exit_code == 0, result.output
    mesh = load_mesh(out)
    assert mesh.vertices.shape == (rig.n_vertices, 3)
    proxied = make_engine(rig, "fem", proxy=1500)
    assert proxied.volume.is_proxy
    np.testing.assert_allclose(mesh.vertices, proxied.deform(expression_pose(rig, "joy")), atol=1e-5)


def test_pose_reads_a_user_library(rig_file, tmp_path):
    library = tmp_path / "mine.json"
    library.write_text(json.dumps({"expressions": {"smirk": {"values": {"zygomatic_major_L": 0.9}}}}))
    out = tmp_path / "smirk.ply"
    result = run_cli("pose", rig_file, "--library", library, "--expr", "smirk", "-o", out)
    assert result.exit_code == 0, result.output
    assert load_mesh(out).vertices.shape == (small_rig().n_vertices, 3)


@pytest.mark.parametrize(
    ("args", "word"),
    [
        (["--expr", "jyo"], "expression"),
        (["--expr", "joy=-1"], "weight"),
        (["--set", "jaw_opn=0.1"], "channel"),
        (["--set", "jaw_open=2"], "range"),
    ],
)
def test_pose_bad_input_exits_1_with_one_line_naming_the_problem(rig_file, tmp_path, args, word):
    out = tmp_path / "out.png"
    result = run_cli("pose", rig_file, *args, "-o", out)
    assert result.exit_code == 1
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:"), result.output
    assert word in lines[0]
    assert not out.exists()


@pytest.mark.parametrize(
    ("args", "word"),
    [
        (["--expr", "joy=abc"], "NAME=WEIGHT"),
        (["--set", "jaw_open"], "CHANNEL=VALUE"),
        (["--engine", "foo"], "--engine"),
        (["--view", "side"], "--view"),
        (["--size", "8"], "--size"),
        (["--proxy", "fast"], "--proxy"),
    ],
)
def test_pose_bad_option_values_are_usage_errors(rig_file, tmp_path, args, word):
    out = tmp_path / "out.png"
    result = run_cli("pose", rig_file, *args, "-o", out)
    assert result.exit_code == 2, result.output
    assert word in result.output and "Traceback" not in result.output
    assert not out.exists()


def test_pose_missing_rig_file_exits_1(tmp_path):
    result = run_cli("pose", tmp_path / "nope.mrig", "-o", tmp_path / "out.png")
    assert result.exit_code == 1
    assert "nope.mrig" in result.output and "Traceback" not in result.output


def test_pose_unsupported_output_is_a_usage_error(rig_file, tmp_path):
    result = run_cli("pose", rig_file, "-o", tmp_path / "out.txt")
    assert result.exit_code == 2 and "unsupported output" in result.output


def test_pose_error_leaves_an_existing_output_alone(rig_file, tmp_path):
    out = tmp_path / "keep.obj"
    out.write_text("precious")
    result = run_cli("pose", rig_file, "--set", "jaw_open=9", "-o", out)
    assert result.exit_code == 1
    assert out.read_text() == "precious"
