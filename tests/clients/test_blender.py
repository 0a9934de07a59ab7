"""Blender's own glTF importer (bpy 5.0.1 as a Python module) reads the exported .glb.

bpy needs Python 3.11 and numpy < 2, so it lives in its own venv, created once and cached under
``~/.cache/mimetic/bpy-<version>`` (about 1 GB; the first install takes about a minute).
``blender_check.py`` runs inside it and reports shape keys, bones, actions and vertex positions.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest


@pytest.fixture(scope="module")
def blender(bpy_python, exported, tmp_path_factory):
    """What Blender made of the file: the JSON report and the rest and posed vertex arrays."""
    out = tmp_path_factory.mktemp("blender")
    script = Path(__file__).with_name("blender_check.py")
    command = [str(bpy_python), str(script), str(exported.path), str(out), str(exported.seconds)]
    done = subprocess.run(command, capture_output=True, text=True, timeout=600, check=False)
    lines = [line for line in done.stdout.splitlines() if line.startswith("BLENDER_JSON ")]
    assert done.returncode == 0 and lines, (
        f"blender_check.py failed:\n{done.stdout[-3000:]}{done.stderr[-3000:]}"
    )
    report = json.loads(lines[-1].removeprefix("BLENDER_JSON "))
    print(
        "blender:", json.dumps({k: v for k, v in report.items() if k not in ("shape_keys", "vertex_groups")})
    )
    return report, np.load(out / "rest.npy"), np.load(out / "posed.npy"), np.load(out / "posed_blender.npy")


def test_blender_imports_shape_keys_bones_and_materials(blender, exported):
    report, *_ = blender
    rig = exported.rig
    assert report["blender"] == "5.0.1" and report["result"] == ["FINISHED"]
    assert report["shape_keys"] == ["Basis", *exported.targets]
    assert report["bones"] == list(rig.bone_names)
    assert report["vertex_groups"] == list(rig.bone_names)
    assert report["materials"] == list(rig.mesh.parts)
    assert (report["vertices"], report["faces"]) == (rig.n_vertices, rig.mesh.n_faces)


def test_blender_action_covers_the_clip(blender, exported):
    report, *_ = blender
    (action,) = report["actions"]
    assert action["name"] == "clip"
    duration = (exported.clip.n_frames - 1) / exported.clip.fps
    assert action["frame_range"][0] == 0.0
    assert action["frame_range"][1] == pytest.approx(duration * report["fps"], rel=1e-5)
    # 4 fcurves per joint rotation, 3 per joint location, 1 per shape key
    anim = exported.summary["animations"][0]
    bones = 4 * anim["rotation_channels"] + 3 * anim["translation_channels"]
    assert anim["rotation_channels"] >= 5 and anim["translation_channels"] == 1  # jaw, head, eyes, lid
    assert sorted(action["slots"].values()) == sorted([bones, len(exported.targets)])


def test_blender_rest_vertices_keep_rig_order_and_frame(blender, exported):
    _, rest, *_ = blender
    assert rest.shape == exported.rest.shape
    np.testing.assert_allclose(rest, exported.rest, atol=1e-6)
    extent = np.ptp(rest, axis=0)
    assert 0.15 < extent.max() < 0.35  # a head-sized head in metres
    assert np.argmax(extent) == 1  # glTF's frame (+Y up), though the user's mesh was Z-up


def test_blender_draws_the_head_upright_facing_front(blender, exported):
    """As Blender draws it (its own axes: +Z up, the front view looking along +Y): the chin is below the
    brow and the face looks toward -Y, for a rig made from a Z-up scan."""
    *_, drawn = blender
    up = exported.landmark(drawn, "glabella") - exported.landmark(drawn, "subnasale")
    assert up[2] > 0.9 * np.linalg.norm(up)
    forward = exported.landmark(drawn, "nose_tip") - 0.5 * (
        exported.landmark(drawn, "tragion_L") + exported.landmark(drawn, "tragion_R")
    )
    assert -forward[1] > 0.8 * np.linalg.norm(forward)  # the ears are above the nose tip


def test_blender_pose_matches_gltf_vertices(blender, exported):
    _, _, posed, _ = blender
    moved = np.linalg.norm(exported.posed - exported.rest, axis=1).max()
    assert moved > 0.005  # the pose really moves the face (metres)
    np.testing.assert_allclose(posed, exported.posed, atol=1e-6)
