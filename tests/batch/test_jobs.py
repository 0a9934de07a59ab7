"""Tests of ``mimetic.batch.jobs``: each batch job writes what its single-file command writes.

The small rig (2,500 skin vertices) runs on the session's 2-worker Dask cluster; the same input runs
through the command in this process, and the files are compared byte for byte.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from mimetic.animate.clipfiles import save_clip
from mimetic.animate.keyframes import from_expressions
from mimetic.batch import animate_many, capture_many, render_many, speak_many
from mimetic.batch.jobs import one_line
from mimetic.capture import Trajectories, marker_set, write_trajectories
from mimetic.engines import make_engine
from mimetic.engines.bake import bake
from mimetic.engines.basis import evaluate_basis
from mimetic.errors import MeshError
from mimetic.mesh.io import save_mesh
from mimetic.rig.format import save_rig
from mimetic.testing import run_cli, small_head, small_rig

FPS = 30.0


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """The small rig and head, a clip through joy, and a TRC (mm) of the rig's iBUG markers opening its
    jaw."""
    folder = tmp_path_factory.mktemp("inputs")
    rig = small_rig()
    rig_file = save_rig(rig, folder / "small.mrig")
    mesh_file = save_mesh(small_head().mesh, folder / "head.obj")
    clip_file = save_clip(from_expressions(rig, [(0.0, "rest"), (0.3, "joy")]), folder / "joy.json")
    basis = bake(make_engine(rig, "wire"), correctives=0, samples=2).basis
    markers = marker_set(rig, "ibug68")
    values = np.zeros((30, len(rig.channels)))
    values[:, rig.channel_index("jaw_open")] = np.linspace(0.0, 0.3, 30)
    points = 10.0 * markers.positions(rig, evaluate_basis(basis, values))
    take = write_trajectories(Trajectories(markers.names, points, FPS, "mm"), folder / "take.trc")
    (folder / "broken.trc").write_text("not a TRC file\n")
    return folder, rig_file, mesh_file, clip_file, take


def test_one_line_keeps_mimetic_messages_and_names_other_errors():
    assert one_line(MeshError("head.obj: no such file (looked in /x). Check the path.")) == (
        "head.obj: no such file (looked in /x). Check the path."
    )
    assert one_line(ZeroDivisionError("division by zero")) == "ZeroDivisionError: division by zero"
    assert one_line(KeyError("jaw")) == "KeyError: 'jaw'"
    assert one_line(RuntimeError("two\n  lines")) == "RuntimeError: two lines"
    assert one_line(MemoryError()) == "MemoryError"


def test_render_many_matches_mimetic_render(files, client, tmp_path):
    _, rig_file, mesh_file, _, _ = files
    manifest = render_many([rig_file, mesh_file], tmp_path / "batch", client=client, view="front", size=64)
    assert [(r.item, r.status) for r in manifest.rows] == [("small", "ok"), ("head", "ok")]
    for source, name in ((rig_file, "small"), (mesh_file, "head")):
        single = tmp_path / f"{name}.png"
        assert run_cli("render", source, "--view", "front", "--size", 64, "-o", single).exit_code == 0
        assert (tmp_path / "batch" / f"{name}.png").read_bytes() == single.read_bytes()


def test_animate_many_matches_mimetic_animate(files, client, tmp_path):
    _, rig_file, _, clip_file, _ = files
    manifest = animate_many([rig_file], tmp_path / "batch", client=client, clip=clip_file, fps=10)
    assert manifest.rows[0].status == "ok" and manifest.rows[0].residual is None
    single = tmp_path / "small.glb"
    assert run_cli("animate", rig_file, "--clip", clip_file, "--fps", 10, "-o", single).exit_code == 0
    assert (tmp_path / "batch" / "small.glb").read_bytes() == single.read_bytes()


def test_speak_many_matches_mimetic_speak(files, client, tmp_path):
    _, rig_file, _, _, _ = files
    manifest = speak_many([rig_file], tmp_path / "batch", client=client, text="Hello there", format="json")
    assert manifest.rows[0].outputs == (tmp_path / "batch" / "small.json",)
    single = tmp_path / "small.json"
    assert run_cli("speak", rig_file, "--text", "Hello there", "-o", single).exit_code == 0
    assert (tmp_path / "batch" / "small.json").read_bytes() == single.read_bytes()


def test_capture_many_matches_mimetic_capture_solve_and_fails_a_broken_take(files, client, tmp_path):
    folder, rig_file, _, _, take = files
    manifest = capture_many(
        rig_file, folder / "*.trc", tmp_path / "batch", client=client, channels="jaw_open"
    )
    broken, solved = manifest.rows
    assert (
        broken.status == "failed"
        and broken.error.startswith(f"{folder / 'broken.trc'}: not a known")
        and "\n" not in broken.error
    )
    assert solved.status == "ok" and 0 <= solved.residual < 0.01  # median marker RMS, rig units (cm)
    clip, report = tmp_path / "take.json", tmp_path / "take.report.json"
    result = run_cli("capture", "solve", rig_file, take, "--channels", "jaw_open", "-o", clip)
    assert result.exit_code == 0, result.output
    assert (tmp_path / "batch" / "take.json").read_bytes() == clip.read_bytes()
    assert (tmp_path / "batch" / "take.report.json").read_bytes() == report.read_bytes()
    assert json.loads(report.read_text())["marker_rms_median"] == solved.residual
