"""The package's front door: ``import mimetic`` is light, and every documented name is there."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

import mimetic


def test_import_mimetic_loads_no_heavy_module():
    heavy = "('numpy', 'scipy', 'trimesh', 'numba')"
    code = f"import sys, mimetic; print(sorted(m for m in {heavy} if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize("name", [n for n in mimetic.__all__ if not n.startswith("__")])
def test_every_front_door_name_resolves(name):
    value = getattr(mimetic, name)
    assert value is not None and name in dir(mimetic)


def test_unknown_names_raise_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'rig_everything'"):
        mimetic.rig_everything  # noqa: B018


def test_the_front_door_rigs_poses_and_exports_a_head(tmp_path):
    """The module docstring's walk-through, on a small generated head saved as a user's file."""
    head = mimetic.make_head(mimetic.HeadParams.random(seed=7), resolution=2_500)
    mesh_file = mimetic.save_mesh(head.mesh, tmp_path / "my_head.obj")
    names = ["nose_tip", "subnasale", "glabella", "pogonion", "mouth_corner_L", "mouth_corner_R"]
    names += ["eye_outer_corner_L", "eye_outer_corner_R", "eye_inner_corner_L", "eye_inner_corner_R"]
    rows = [f"{n},{x},{y},{z}" for n, (x, y, z) in zip(names, head.landmark_positions(names), strict=True)]
    (tmp_path / "landmarks.csv").write_text("# units: cm\n" + "\n".join(rows) + "\n")
    result = mimetic.rig_mesh(mesh_file, tmp_path / "landmarks.csv")
    rig = result.rig
    assert result.report.accepted and rig.n_vertices == head.mesh.n_vertices
    mimetic.save_rig(rig, tmp_path / "my_head.mrig")
    assert mimetic.load_rig(tmp_path / "my_head.mrig") == rig
    engine = mimetic.make_engine(rig, "wire")
    joy = engine.deform(mimetic.expression_pose(rig, "joy"))
    assert joy.shape == (rig.n_vertices, 3) and np.abs(joy - rig.mesh.vertices).max() > 0.1
    keys = mimetic.from_expressions(rig, [(0, "rest"), (1, "joy"), (2, "rest")])
    clip = keys.sample(10, channels=rig)
    path = mimetic.export_glb(rig, tmp_path / "joy.glb", morph_targets=mimetic.morph_targets(rig), clip=clip)
    assert path.stat().st_size > 10_000
    image = mimetic.render_pose(rig, engine, clip.values[10], size=96)
    assert mimetic.save_image(image, tmp_path / "joy.png").stat().st_size > 1_000
