"""FBX out and in, checked by two independent readers: Blender's own FBX importer and assimp.

The exported .fbx is the client fixture's rig (the small rig as if fitted to a Z-up scan, its baked
muscle targets, a 1 s clip at 60 fps), written by ``export_fbx`` (Blender's FBX exporter, bpy in the
venv ``mimetic.blender`` makes). ``fbx_check.py`` re-imports it in a fresh Blender and reports the
file's header (units, axes, frame rate) and the scene: shape keys and their displacements, bones,
actions, and the evaluated mesh at a few times, all compared with ``gltf_vertices``. assimp (Debian's
``assimp-utils``) reads it a second time: vertex count, bones, morph targets, the animation and the
bounding box in centimetres. The FBX heads read by ``load_mesh`` (``mimetic info`` / ``mimetic
rig``) and the bad files are made by Blender in the tests (``fbx_make.py``).
"""

from __future__ import annotations

import json
import re
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest

from mimetic.errors import MeshError
from mimetic.mesh.units import UNIT_SCALE

HERE = Path(__file__).parent
TIMES_S = (0.25, 0.5, 0.9)
"""Clip times at which Blender's posed mesh is compared with ours (frames 15, 30, 54 at 60 fps)."""


def run_bpy(python: Path, script: str, *args: object) -> subprocess.CompletedProcess:
    command = [str(python), str(HERE / script), *(str(a) for a in args)]
    done = subprocess.run(command, capture_output=True, text=True, timeout=600, check=False)
    assert done.returncode == 0, f"{script} failed:\n{done.stdout[-3000:]}{done.stderr[-3000:]}"
    return done


@pytest.fixture(scope="module")
def fbx(blender_tool, exported, tmp_path_factory) -> tuple[Path, float]:
    """The exported .fbx, and the seconds ``export_fbx`` took."""
    from mimetic.export.fbx import export_fbx

    path = tmp_path_factory.mktemp("fbx") / "face.fbx"
    start = time.perf_counter()
    export_fbx(exported.rig, path, morph_targets=exported.targets, clip=exported.clip)
    return path, time.perf_counter() - start


@pytest.fixture(scope="module")
def blender(bpy_python, fbx, tmp_path_factory):
    """What Blender's FBX importer made of the file: its JSON report and arrays (metres, glTF axes)."""
    out = tmp_path_factory.mktemp("fbx-blender")
    done = run_bpy(bpy_python, "fbx_check.py", fbx[0], out, ",".join(map(str, TIMES_S)))
    line = [x for x in done.stdout.splitlines() if x.startswith("BLENDER_JSON ")][-1]
    report = json.loads(line.removeprefix("BLENDER_JSON "))
    print(
        "blender:", json.dumps({k: v for k, v in report.items() if k not in ("shape_keys", "vertex_groups")})
    )
    with np.load(out / "arrays.npz") as arrays:
        return report, dict(arrays)


def metres(exported, delta: np.ndarray) -> np.ndarray:
    return delta * UNIT_SCALE[exported.rig.units]


def test_export_fbx_is_quick_and_atomic(fbx, tmp_path, exported):
    from mimetic.atomic import WriteError
    from mimetic.export.fbx import export_fbx

    path, seconds = fbx
    print(f"export_fbx: {seconds:.2f} s, {path.stat().st_size / 1024:.0f} KB")
    assert path.read_bytes().startswith(b"Kaydara FBX Binary  \x00")
    assert seconds < 60
    assert [p.name for p in path.parent.iterdir()] == ["face.fbx"]  # no temporary file left beside it
    good = tmp_path / "good.fbx"
    good.write_bytes(b"a good file")
    with pytest.raises(WriteError):
        export_fbx(exported.rig, tmp_path / "missing" / "x.fbx")
    with pytest.raises(ValueError, match=r"x\.glb: an FBX file must end in \.fbx"):
        export_fbx(exported.rig, tmp_path / "x.glb")
    bad = {"jaw_open": np.full((3, 3), np.nan)}
    with pytest.raises(ValueError, match="jaw_open"):
        export_fbx(exported.rig, good, morph_targets=bad)
    assert good.read_bytes() == b"a good file"  # a failed export leaves the old file as it was


def test_fbx_header_says_centimetres_y_up_and_the_clip_rate(blender, exported):
    header = blender[0]["header"]
    assert header["version"] == 7400
    assert header["UnitScaleFactor"] == 1.0  # centimetres
    assert (header["UpAxis"], header["UpAxisSign"]) == (1, 1)  # +Y up
    assert header["CustomFrameRate"] == exported.clip.fps
    assert header["takes"] == ["clip"]


def test_blender_reads_mesh_parts_bones_and_shape_key_names(blender, exported):
    report, _ = blender
    rig = exported.rig
    assert report["blender"] == "5.0.1" and report["result"] == ["FINISHED"]
    assert report["meshes"] == ["face_mesh"] and report["armatures"] == ["face"]
    assert (report["vertices"], report["faces"]) == (rig.n_vertices, rig.mesh.n_faces)
    assert report["materials"] == list(rig.mesh.parts)
    assert report["bones"] == list(rig.bone_names)
    assert set(report["vertex_groups"]) == set(rig.bone_names)
    assert report["shape_keys"] == ["Basis", *exported.targets]


def test_blender_rest_and_shape_key_deltas_match_ours(blender, exported):
    _, arrays = blender
    np.testing.assert_allclose(arrays["rest"], exported.rest, atol=1e-6)  # metres
    ours = np.array([metres(exported, d) for d in exported.targets.values()])
    assert np.abs(ours).max() > 1e-3  # the targets really move the face
    assert arrays["keys"].shape == ours.shape
    np.testing.assert_allclose(arrays["keys"] * 100, ours * 100, atol=1e-4)  # centimetres, the file's unit


def test_blender_action_covers_the_clip(blender, exported):
    report, _ = blender
    assert report["fps"] == exported.clip.fps
    last = exported.clip.n_frames - 1
    names = sorted(a["name"] for a in report["actions"])
    assert names == ["Key|clip", "face|clip"]  # the bones' and the shape keys' curves of the take
    assert all(a["frame_range"] == [0.0, float(last)] for a in report["actions"])


def test_blender_posed_vertices_match_ours(blender, exported):
    from mimetic.export import gltf_vertices

    _, arrays = blender
    clip = exported.clip
    for t, posed in zip(TIMES_S, arrays["posed"], strict=True):
        frame = round(t * clip.fps)
        ours = gltf_vertices(
            exported.rig, exported.targets, dict(zip(clip.channels, clip.values[frame], strict=True))
        )
        assert np.linalg.norm(ours - exported.rest, axis=1).max() > 0.002  # the pose moves the face (m)
        np.testing.assert_allclose(posed, ours, atol=1e-6)


# --------------------------------------------------------------------------- assimp, a second reader


@pytest.fixture(scope="module")
def assimp_read(assimp, fbx, tmp_path_factory):
    """``assimp info`` of the file, and the file converted by assimp to glTF (its JSON)."""
    info = subprocess.run(
        [assimp, "info", str(fbx[0])], capture_output=True, text=True, timeout=120, check=False
    )
    assert info.returncode == 0, info.stdout[-2000:] + info.stderr[-2000:]
    out = tmp_path_factory.mktemp("assimp") / "face.gltf"
    command = [assimp, "export", str(fbx[0]), str(out), "-fgltf2"]
    done = subprocess.run(command, capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
    return info.stdout, json.loads(out.read_text())


def _field(text: str, name: str) -> str:
    return re.search(rf"^{name}:?\s+(.+)$", text, re.MULTILINE).group(1).strip()


def test_assimp_counts_vertices_faces_and_animation(assimp_read, exported):
    info, _ = assimp_read
    assert int(_field(info, "Vertices")) == exported.rig.n_vertices
    assert int(_field(info, "Faces")) == exported.rig.mesh.n_faces
    assert int(_field(info, "Animations")) == 1
    assert int(_field(info, "Meshes")) == len(exported.rig.mesh.parts)  # assimp splits by material


def test_assimp_box_is_ours_in_centimetres_y_up(assimp_read, exported):
    info, _ = assimp_read
    low = np.array(_field(info, "Minimum point").strip("()").split(), dtype=float)
    high = np.array(_field(info, "Maximum point").strip("()").split(), dtype=float)
    cm = exported.rest * 100
    np.testing.assert_allclose(low, cm.min(axis=0), atol=1e-3)
    np.testing.assert_allclose(high, cm.max(axis=0), atol=1e-3)


def test_assimp_sees_the_bones_and_one_morph_target_per_shape_key(assimp_read, exported):
    _, gltf = assimp_read
    (skin,) = gltf["skins"]
    names = {gltf["nodes"][j]["name"] for j in skin["joints"]}
    assert names == set(exported.rig.bone_names)
    (mesh,) = gltf["meshes"]
    assert {len(p.get("targets", [])) for p in mesh["primitives"]} == {len(exported.targets)}
    (animation,) = gltf["animations"]
    assert len(animation["channels"]) > 0


# --------------------------------------------------------------------------- commands that write FBX


def test_cli_export_and_animate_write_fbx(bpy_python, exported, tmp_path):
    """``export --arkit -o head.fbx``: the 52 ARKit shape keys, and an armature not named like its bone."""
    from mimetic.animate.arkit import ARKIT_NAMES
    from mimetic.animate.clipfiles import save_clip
    from mimetic.rig.format import save_rig
    from mimetic.testing import run_cli

    rig = save_rig(exported.rig, tmp_path / "face.mrig")
    result = run_cli("export", rig, "--arkit", "-o", tmp_path / "head.fbx")
    assert result.exit_code == 0, result.output
    assert "52 morph targets" in result.output
    done = run_bpy(bpy_python, "fbx_check.py", tmp_path / "head.fbx", tmp_path, "0")
    report = json.loads([x for x in done.stdout.splitlines() if x.startswith("BLENDER_JSON ")][-1][13:])
    assert report["shape_keys"] == ["Basis", *ARKIT_NAMES]
    assert report["armatures"] == ["head_rig"] and "head" in report["bones"]
    clip = save_clip(exported.clip, tmp_path / "clip.json")
    result = run_cli("animate", rig, "--clip", clip, "--fps", 30, "-o", tmp_path / "anim.fbx")
    assert result.exit_code == 0, result.output
    assert (tmp_path / "anim.fbx").read_bytes().startswith(b"Kaydara FBX Binary  \x00")


# --------------------------------------------------------------------------- FBX heads in


def test_load_mesh_reads_our_fbx_back_in_rig_order_with_parts(fbx, exported):
    from mimetic.mesh.io import load_mesh

    mesh = load_mesh(fbx[0])
    assert mesh.units == "cm"
    np.testing.assert_allclose(mesh.vertices, exported.rest * 100, atol=1e-5)
    np.testing.assert_array_equal(mesh.faces, exported.rig.mesh.faces)
    assert list(mesh.parts) == list(exported.rig.mesh.parts)
    for name, faces in exported.rig.mesh.parts.items():
        np.testing.assert_array_equal(mesh.parts[name], faces)


@pytest.fixture(scope="module")
def made(bpy_python, exported, tmp_path_factory):
    """FBX files Blender writes for the reading tests: name → path."""
    folder = tmp_path_factory.mktemp("fbx-made")
    files = {}
    for kind in ("no_mesh", "body", "head_mm_z_up"):
        files[kind] = folder / f"{kind}.fbx"
        run_bpy(bpy_python, "fbx_make.py", kind, files[kind], exported.path)
    return files


def test_an_fbx_head_in_millimetres_and_z_up_comes_in_y_up_in_millimetres(made, exported):
    from mimetic.mesh.io import load_mesh

    mesh = load_mesh(made["head_mm_z_up"])
    assert mesh.units == "mm"
    np.testing.assert_allclose(mesh.vertices, exported.rest * 1000, atol=1e-3)
    assert set(mesh.parts) == set(exported.rig.mesh.parts)


def test_cli_info_and_rig_read_an_fbx_head(made, tmp_path):
    from mimetic.rig.format import load_rig
    from mimetic.testing import run_cli

    result = run_cli("info", made["head_mm_z_up"], "--json")
    assert result.exit_code == 0, result.output
    report = json.loads(result.stdout)
    assert (report["kind"], report["units"], report["n_vertices"]) == ("mesh", "mm", 4221)
    result = run_cli("rig", made["head_mm_z_up"], "-o", tmp_path / "head.mrig")
    assert result.exit_code == 0, result.output
    assert "fit accepted" in result.output
    rig = load_rig(tmp_path / "head.mrig")
    assert (rig.units, rig.n_vertices) == ("mm", 4221)


@pytest.mark.parametrize(
    ("kind", "message"),
    [
        ("no_mesh", r"no_mesh\.fbx: holds no mesh \(only armature, empty\)"),
        ("body", r"body\.fbx: holds 7 meshes 1\.\d\d m across by its units: a whole body"),
    ],
)
def test_bad_binary_fbx_is_one_clear_line(made, kind, message):
    from mimetic.mesh.io import load_mesh

    with pytest.raises(MeshError, match=message) as info:
        load_mesh(made[kind])
    assert "\n" not in str(info.value)


def test_ascii_fbx_is_refused_before_blender_starts(tmp_path):
    from mimetic.mesh.io import load_mesh

    path = tmp_path / "ascii.fbx"
    path.write_text("; FBX 7.4.0 project file\nFBXHeaderExtension:  {\n\tFBXHeaderVersion: 1003\n}\n")
    with pytest.raises(
        MeshError, match=r"ascii\.fbx: ASCII FBX is not supported by Blender's importer; save as binary$"
    ):
        load_mesh(path)


def test_corrupt_fbx_is_one_clear_line(fbx, tmp_path):
    from mimetic.mesh.io import load_mesh

    truncated = tmp_path / "truncated.fbx"
    truncated.write_bytes(fbx[0].read_bytes()[:5000])
    with pytest.raises(MeshError, match=r"truncated\.fbx: not a readable binary FBX .*corrupt or truncated"):
        load_mesh(truncated)
    other = tmp_path / "other.fbx"
    other.write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(200))
    with pytest.raises(MeshError, match=r"other\.fbx: not a binary FBX file"):
        load_mesh(other)
