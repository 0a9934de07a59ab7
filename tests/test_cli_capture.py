"""End-to-end tests of ``mimetic capture solve|video|retarget``."""

from __future__ import annotations

import json

import numpy as np
import pygltflib
import pytest

from mimetic.animate.clipfiles import load_clip
from mimetic.capture import Trajectories, marker_set, write_trajectories
from mimetic.engines import make_engine
from mimetic.engines.bake import bake
from mimetic.engines.basis import evaluate_basis
from mimetic.rig.format import save_rig
from mimetic.testing import run_cli, small_rig

FPS = 30.0


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    """The small rig, and a TRC (mm) of its iBUG markers while it opens its jaw and turns its head."""
    folder = tmp_path_factory.mktemp("capture")
    rig = small_rig()
    rig_file = save_rig(rig, folder / "small.mrig")
    basis = bake(make_engine(rig, "wire"), correctives=0, samples=2).basis
    markers = marker_set(rig, "ibug68")
    t = np.arange(60) / FPS
    values = np.zeros((60, len(rig.channels)))
    jaw = 0.4 * np.clip((t - 0.5) / 1.5, 0.0, 1.0) ** 2  # within jaw_open's range (max 0.45 rad)
    values[:, rig.channel_index("jaw_open")] = jaw
    points = markers.positions(rig, evaluate_basis(basis, values))
    yaw = 0.2 * np.clip(t - 0.5, 0.0, None)
    pivot = rig.bone("head").head
    for k, angle in enumerate(yaw):
        c, s = np.cos(angle), np.sin(angle)
        points[k] = (points[k] - pivot) @ np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]]).T + pivot
    trc = write_trajectories(Trajectories(markers.names, 10.0 * points, FPS, "mm"), folder / "take.trc")
    return rig_file, trc, folder, jaw, yaw


def test_solve_writes_a_clip_with_the_jaw_and_the_head(files):
    rig_file, trc, folder, jaw, yaw = files
    out, report = folder / "take.json", folder / "take.report.json"  # the report goes beside the clip
    result = run_cli("capture", "solve", rig_file, trc, "--channels", "jaw_open", "-o", out)
    assert result.exit_code == 0, result.output
    assert "1 channels from 68 ibug68 markers" in result.output
    clip = load_clip(out).sample(FPS)
    np.testing.assert_allclose(clip.values[:, clip.channels.index("jaw_open")], jaw, atol=0.01)
    np.testing.assert_allclose(clip.values[:, clip.channels.index("head_yaw")], yaw, atol=0.01)
    summary = json.loads(report.read_text())
    assert summary["frames"] == 60 and summary["units"] == "mm" and summary["flagged_frames"] == 0


def test_retarget_plays_the_clip_on_another_rig_as_glb(files, tmp_path):
    rig_file, trc, folder, _, _ = files
    clip_file = folder / "take-all.json"
    assert run_cli("capture", "solve", rig_file, trc, "-o", clip_file).exit_code == 0
    other = save_rig(small_rig(seed=3), tmp_path / "other.mrig")
    out = tmp_path / "other.glb"
    result = run_cli("capture", "retarget", clip_file, other, "--fps", "15", "-o", out)
    assert result.exit_code == 0, result.output
    gltf = pygltflib.GLTF2().load(str(out))
    assert len(gltf.animations) == 1
    assert "jaw" in {node.name for node in gltf.nodes}


def test_a_corrupt_file_fails_in_one_line_and_keeps_the_old_output(files, tmp_path):
    rig_file, _, _, _, _ = files
    bad = tmp_path / "broken.trc"
    bad.write_text("PathFileType\t4\t(X/Y/Z)\tbroken.trc\nnot a header\n")
    out = tmp_path / "take.json"
    out.write_text("precious")
    result = run_cli("capture", "solve", rig_file, bad, "-o", out)
    assert result.exit_code == 1
    assert "broken.trc" in result.output and "Traceback" not in result.output
    assert out.read_text() == "precious"


def test_unknown_output_type_and_channels_are_usage_errors(files, tmp_path):
    rig_file, trc, _, _, _ = files
    assert run_cli("capture", "solve", rig_file, trc, "-o", tmp_path / "take.obj").exit_code == 2
    result = run_cli("capture", "solve", rig_file, trc, "--channels", "jaw_opn", "-o", tmp_path / "t.json")
    assert result.exit_code == 2 and "jaw_opn" in result.output


def test_video_that_is_not_a_video_fails_clearly(files, tmp_path):
    rig_file, _, _, _, _ = files
    fake = tmp_path / "face.mp4"
    fake.write_bytes(b"\x00\x01not a video" * 100)
    result = run_cli("capture", "video", rig_file, fake, "-o", tmp_path / "face.json")
    assert result.exit_code == 1
    assert "face.mp4" in result.output and "Traceback" not in result.output


def test_edits_survive_a_new_solve_from_the_command_line(files, tmp_path):
    rig_file, trc, _, _, _ = files
    solved, edited, again = tmp_path / "take.json", tmp_path / "edited.json", tmp_path / "again.json"
    assert run_cli("capture", "solve", rig_file, trc, "--channels", "jaw_open", "-o", solved).exit_code == 0
    result = run_cli("clip", "edit", solved, "--key", "jaw_open@1.0=0.35", "-o", edited)
    assert result.exit_code == 0, result.output
    result = run_cli(
        "capture", "solve", rig_file, trc, "--channels", "jaw_open", "--refine", "1", "--edits", edited,
        "-o", again,
    )  # fmt: skip
    assert result.exit_code == 0, result.output
    clip, before = load_clip(again), load_clip(edited)
    assert [layer.name for layer in clip.layers] == ["base", "edit"]
    assert clip.layer("edit") == before.layer("edit")  # the edit is kept as it was made
    j = clip.channels.index("jaw_open")
    # the refined solve moves the base a little; the edit's displacement rides on top of it
    assert clip.evaluate(np.array([1.0]))[0, j] == pytest.approx(0.35, abs=0.01)


def test_markers_placed_on_one_take_are_kept_for_the_next(files, tmp_path):
    rig_file, trc, _, jaw, _ = files
    placed, first, second = tmp_path / "actor.markers.json", tmp_path / "one.json", tmp_path / "two.json"
    result = run_cli("capture", "solve", rig_file, trc, "--markers-out", placed, "-o", first)
    assert result.exit_code == 0, result.output
    document = json.loads(placed.read_text())
    assert document["placed"] and document["layout"] == "ibug68" and len(document["markers"]) == 68
    result = run_cli("capture", "solve", rig_file, trc, "--markers", placed, "-o", second)
    assert result.exit_code == 0, result.output
    a, b = load_clip(first).sample(FPS), load_clip(second).sample(FPS)
    j = a.channels.index("jaw_open")
    # both takes' jaw within 0.02 of the truth (placing the markers again, or reusing the placed set)
    np.testing.assert_allclose(a.values[:, j], jaw, atol=0.02)
    np.testing.assert_allclose(b.values[:, j], jaw, atol=0.02)
    assert (
        run_cli("capture", "solve", rig_file, trc, "--markers-out", tmp_path / "m.txt", "-o", first).exit_code
        == 2
    )
