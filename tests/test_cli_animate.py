"""End-to-end tests of ``mimetic clip new|edit`` and ``mimetic animate``."""

from __future__ import annotations

import imageio_ffmpeg
import numpy as np
import pytest

from mimetic.animate.clipfiles import load_clip
from mimetic.rig.format import save_rig
from mimetic.testing import run_cli, small_rig


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("animate")
    rig_file = save_rig(small_rig(), folder / "small.mrig")
    clip_file = folder / "clip.json"
    result = run_cli("clip", "new", rig_file, "--pose", "0:rest", "--pose", "0.5:joy", "--pose",
                     "1:surprise=0.8+joy=0.2", "--pose", "1.5:rest", "-o", clip_file)  # fmt: skip
    assert result.exit_code == 0, result.output
    return rig_file, clip_file, folder


def test_clip_new_keys_the_expressions(files):
    _, clip_file, _ = files
    clip = load_clip(clip_file)
    rig = small_rig()
    assert clip.duration_s == 1.5
    from mimetic.animate.expressions import expression_pose

    values = clip.evaluate(np.array([0.0, 0.5]))
    np.testing.assert_allclose(values[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(values[1], expression_pose(rig, "joy"), atol=1e-9)


def test_clip_edit_passes_through_the_new_keys_in_its_own_layer(files):
    _, clip_file, folder = files
    out = folder / "edited.json"
    result = run_cli("clip", "edit", clip_file, "--key", "jaw_open@0.75=0.3", "--key", "jaw_open@1.0=0.1",
                     "--knot-spacing", "0.1", "-o", out)  # fmt: skip
    assert result.exit_code == 0, result.output
    before, after = load_clip(clip_file), load_clip(out)
    j = after.channels.index("jaw_open")
    np.testing.assert_allclose(after.evaluate(np.array([0.75, 1.0]))[:, j], [0.3, 0.1], atol=1e-9)
    assert [layer.name for layer in after.layers] == [layer.name for layer in before.layers] + ["edit"]
    far = np.array([0.0, 0.3, 1.45, 1.5])  # beyond the knot spans [0.4, 1.1] and [0.7, 1.4]
    np.testing.assert_array_equal(after.evaluate(far), before.evaluate(far))


def test_animate_renders_an_mp4(files):
    rig_file, clip_file, folder = files
    out = folder / "anim.mp4"
    result = run_cli("animate", rig_file, "--clip", clip_file, "--fps", "20", "--size", "96", "-o", out)
    assert result.exit_code == 0, result.output
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(out))
    assert frames == 31 and seconds == pytest.approx(1.55, abs=0.05)


@pytest.mark.parametrize(
    ("args", "message", "code"),
    [
        (("clip", "edit", "CLIP", "--key", "jaw_open=0.3", "-o", "OUT"), "CHANNEL@TIME", 2),
        (("clip", "edit", "CLIP", "--key", "no_such@0.5=1", "-o", "OUT"), "no_such", 1),
        (("clip", "new", "RIG", "--pose", "later:joy", "-o", "OUT"), "TIME:EXPRESSION", 2),
        (("clip", "new", "RIG", "--pose", "0:no_such_expression", "-o", "OUT"), "no_such_expression", 1),
        (("animate", "RIG", "--clip", "CLIP", "-o", "OUT.avi"), ".mp4", 2),
    ],
)
def test_bad_input_is_one_line_and_writes_nothing(files, args, message, code):
    """Malformed values and unsupported outputs are usage errors (2); unknown names are input errors (1)."""
    rig_file, clip_file, folder = files
    out = folder / "never.json"
    swap = {"CLIP": clip_file, "RIG": rig_file, "OUT": out, "OUT.avi": folder / "never.avi"}
    result = run_cli(*[swap.get(a, a) for a in args])
    assert result.exit_code == code and message in result.output, result.output
    assert not out.exists() and not (folder / "never.avi").exists()


@pytest.mark.parametrize("engine", ["wire", "fem"])
def test_animate_exports_an_animated_glb(files, engine):
    from mimetic.export.gltf import read_glb_summary

    rig_file, clip_file, folder = files
    out = folder / f"anim_{engine}.glb"
    result = run_cli("animate", rig_file, "--clip", clip_file, "--fps", "24", "--engine", engine, "-o", out)
    assert result.exit_code == 0, result.output
    summary = read_glb_summary(out)
    rig = small_rig()
    assert summary["vertices"] == rig.n_vertices
    # one per activation channel: the muscles and the tissue actions' own channels
    assert set(summary["target_names"]) == {c.name for c in rig.channels if c.unit == "activation"}
    assert set(rig.muscle_names) < set(summary["target_names"])
    (animation,) = summary["animations"]
    assert animation["frames"] == 37 and animation["duration_s"] == pytest.approx(1.5)
    assert animation["weights_channels"] == 1 and animation["rotation_channels"] >= 1  # the jaw moves


def test_export_arkit_writes_52_named_targets_and_objs(files):
    from mimetic.animate.arkit import ARKIT_NAMES
    from mimetic.export.gltf import read_glb_summary
    from mimetic.mesh.io import load_mesh

    rig_file, _, folder = files
    out, objs = folder / "arkit.glb", folder / "arkit_objs"
    objs.mkdir()  # a folder that exists already (a second export into it) is written into
    (objs / "jawOpen.obj").write_text("an old shape")
    result = run_cli("export", rig_file, "--arkit", "--obj-dir", objs, "-o", out)
    assert result.exit_code == 0, result.output
    assert list(read_glb_summary(out)["target_names"]) == list(ARKIT_NAMES)
    assert sorted(p.stem for p in objs.glob("*.obj")) == sorted(ARKIT_NAMES)
    rig = small_rig()
    jaw = load_mesh(objs / "jawOpen.obj").vertices - rig.mesh.vertices
    chin = rig.landmarks["pogonion"]
    assert jaw[rig.mesh.faces[chin.face][0], 1] < -0.5  # cm: jawOpen drops the chin


def test_export_and_animate_write_clean_usd(files, usd_ready):
    from mimetic.export.usd import check_usd

    rig_file, clip_file, folder = files
    shapes, anim = folder / "arkit.usda", folder / "anim.usdc"
    assert run_cli("export", rig_file, "--arkit", "-o", shapes).exit_code == 0
    assert run_cli("animate", rig_file, "--clip", clip_file, "-o", anim).exit_code == 0
    from pxr import Usd, UsdSkel

    assert check_usd(shapes) == [] and check_usd(anim) == []
    stage = Usd.Stage.Open(str(shapes))
    names = [p.GetName() for p in stage.Traverse() if p.IsA(UsdSkel.BlendShape)]
    assert len(names) == 52 and "jawOpen" in names
    assert Usd.Stage.Open(str(anim)).GetEndTimeCode() == 45  # 1.5 s at 30 fps: frames 0..45


@pytest.fixture(scope="module")
def usd_ready():
    import os

    try:
        import pxr  # noqa: F401
    except ImportError as error:
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"usd-core is required on CI ({error}); pip install 'mimetic[usd]'")
        pytest.skip(f"usd-core not installed ({error})")
