"""End-to-end tests of the ``mimetic`` command: outputs, exit codes and bad input."""

from __future__ import annotations

import json
import zipfile

import numpy as np
import pytest
from PIL import Image

from mimetic.animate.clipfiles import load_clip
from mimetic.animate.keyframes import from_expressions
from mimetic.engines import ENGINES
from mimetic.head.model import make_head
from mimetic.mesh.io import load_mesh, save_mesh
from mimetic.mesh.model import Mesh
from mimetic.rig.format import load_rig
from mimetic.tasks.demo import ANIMATION, FAST_ENGINES
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
    report = json.loads(result.stdout)
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
    out.mkdir()  # an earlier demo's folder: `make demo` runs again into it
    (out / "head.glb").write_bytes(b"an old head")
    result = run_cli("demo", "-o", str(out), "--resolution", RES)
    assert result.exit_code == 0, result.output
    for name in (
        "head.glb",
        "default.mrig",
        "default_views.png",
        "heads_muscles.png",
        "expressions_closeup.png",
        *(f"muscles_{engine}.png" for engine in FAST_ENGINES),
        *(f"expressions_{engine}.png" for engine in FAST_ENGINES if engine != "wire"),
        "expressions_engines.png",
        "talk.mp4",
        "talk.clip.json",
        "capture.mp4",
        "capture.clip.json",
        "capture_compare.png",
        "capture_retargeted.mp4",
        "capture_retargeted.glb",
    ):
        assert (out / name).stat().st_size > 1000, name
    # the capture reads the performance back from its video: joy's smile, surprise's jaw, the head's turn
    performed = from_expressions(load_rig(out / "default.mrig"), list(ANIMATION)).sample(30.0)
    captured = load_clip(out / "capture.clip.json").sample(30.0)
    for channel, least in (("zygomatic_major_L", 0.8), ("jaw_open", 0.6)):
        a, b = performed.select([channel]).values[:, 0], captured.select([channel]).values[:, 0]
        assert np.corrcoef(a, b[: len(a)])[0, 1] > least, channel
    assert np.degrees(np.ptp(captured.select(["head_yaw"]).values)) > 20
    assert len(list((out / "rigs").glob("seed_*.mrig"))) == 8
    assert len(list((out / "heads").glob("seed_*.glb"))) == 8
    assert (
        load_rig(out / "rigs" / "seed_5.mrig").metadata["params"]
        != load_rig(out / "default.mrig").metadata["params"]
    )
    # the physics engines wait for --all: a first run stays quick
    assert not (out / "muscles_tissue.png").exists() and not (out / "jaw_drop_tissue.mp4").exists()
    lines = result.stderr.splitlines()  # piped: one plain line per named step, and no warning
    assert any("] heads" in line for line in lines) and any("] capture: " in line for line in lines)
    assert not [line for line in lines if "warning" in line.lower()], lines


def test_demo_all_adds_the_physics_engines(tmp_path):
    out = tmp_path / "demo"
    result = run_cli("demo", "--all", "-o", str(out), "--resolution", 1500)
    assert result.exit_code == 0, result.output
    for name in (
        *(f"muscles_{engine}.png" for engine in ENGINES),
        *(f"expressions_{engine}.png" for engine in ENGINES if engine != "wire"),
        "jaw_drop_tissue.mp4",
    ):
        assert (out / name).stat().st_size > 1000, name
    fbx = out / "animation.fbx"  # through Blender: a note says why when bpy cannot be installed here
    assert fbx.read_bytes().startswith(b"Kaydara FBX Binary") or "animation.fbx skipped" in result.output
    assert "warning" not in result.stderr.lower()


# --- bad input: a clear one-line error, exit code 1, no file overwritten ------------------------


def test_output_folders_must_be_folders(rig_file, tmp_path):
    taken = tmp_path / "taken"
    taken.write_text("a file")
    _fails_with(run_cli("demo", "-o", taken), "is a file; give a folder")
    result = run_cli("export", rig_file, "-o", tmp_path / "x.glb", "--obj-dir", taken)
    _fails_with(result, "is a file; give a folder")
    _fails_with(run_cli("demo", "-o", tmp_path / "no" / "demo"), "does not exist")
    assert taken.read_text() == "a file" and not (tmp_path / "x.glb").exists()


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
    assert json.loads(result.stdout)["detected_units"] == "mm"


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


def _usage_error(result, *words: str) -> None:
    """Exit 2 with typer's usage message naming the option and the value."""
    assert result.exit_code == 2, result.output
    for word in words:
        assert word in result.output, f"{word!r} not in {result.output!r}"
    assert "Traceback" not in result.output


def test_render_rejects_unknown_view_as_a_usage_error(rig_file, tmp_path):
    _usage_error(
        run_cli("render", str(rig_file), "--view", "top", "-o", str(tmp_path / "x.png")), "--view", "top"
    )
    assert not (tmp_path / "x.png").exists()


@pytest.mark.parametrize("suffix", [".jpg", ".jpeg", ".webp"])
def test_render_writes_the_format_its_suffix_names(rig_file, tmp_path, suffix):
    out = tmp_path / f"r{suffix}"
    assert run_cli("render", str(rig_file), "--view", "front", "--size", "64", "-o", out).exit_code == 0
    image = Image.open(out)
    assert image.format == {".jpg": "JPEG", ".jpeg": "JPEG", ".webp": "WEBP"}[suffix] and image.size == (
        64,
        64,
    )


def test_version_prints_the_package_version():
    import mimetic

    result = run_cli("--version")
    assert result.exit_code == 0 and result.output.strip() == f"mimetic {mimetic.__version__}"


def test_every_command_help_shows_examples():
    for command in ("head", "info", "render", "rig", "pose", "animate", "export", "list", "demo"):
        result = run_cli(command, "--help")
        assert result.exit_code == 0 and "Examples:" in result.output, command
        assert f"mimetic {command}" in result.output, command
    for sub in ("new", "edit"):
        assert "mimetic clip " + sub in run_cli("clip", sub, "--help").output


def test_an_unexpected_error_is_one_line_without_a_traceback(rig_file, tmp_path, monkeypatch):
    import mimetic.tasks.prepared as prepared

    def broken(path):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr(prepared, "prepared_rig", broken)
    result = run_cli("pose", rig_file, "-o", tmp_path / "x.png")
    assert result.exit_code == 1
    (line,) = result.output.strip().splitlines()
    assert line.startswith("error: unexpected ZeroDivisionError: division by zero") and "--debug" in line
    with pytest.raises(ZeroDivisionError):
        run_cli("--debug", "pose", rig_file, "-o", tmp_path / "x.png")


def test_error_messages_keep_their_brackets(rig_file, tmp_path, monkeypatch):
    """Messages are printed as text: an install hint's [track] is not eaten as rich markup."""
    import mimetic.tasks.prepared as prepared
    from mimetic.errors import MissingExtraError, install_hint

    def missing(path):
        raise MissingExtraError(f"face tracking needs the optional extra [track]: {install_hint('track')}")

    monkeypatch.setattr(prepared, "prepared_rig", missing)
    result = run_cli("pose", rig_file, "-o", tmp_path / "x.png")
    assert (
        result.exit_code == 1 and "[track]" in result.output and "pip install -e '.[track]'" in result.output
    )


def test_warnings_are_one_line_each_without_source_lines(tmp_path):
    head = make_head(resolution=2500)
    path = save_mesh(Mesh(head.mesh.vertices * 10.0, head.mesh.faces), tmp_path / "mm.stl")  # no units in STL
    result = run_cli("render", str(path), "--view", "front", "--size", "64", "-o", tmp_path / "r.png")
    assert result.exit_code == 0, result.output
    warning = [line for line in result.output.splitlines() if line.startswith("warning:")]
    assert warning and "mm" in warning[0] and "--units" in warning[0]
    assert "warnings.warn" not in result.output and ".py:" not in result.output


def test_output_folders_are_checked_before_any_work(rig_file, tmp_path, monkeypatch):
    import mimetic.rig.format as rig_format

    def never(path):
        raise AssertionError("the rig was loaded before the output was checked")

    monkeypatch.setattr(rig_format, "load_rig", never)
    result = run_cli("pose", rig_file, "-o", tmp_path / "missing" / "x.png")
    assert result.exit_code == 1 and "does not exist" in result.output and "missing" in result.output


def test_long_lines_are_not_wrapped_when_piped(tmp_path):
    head = make_head(resolution=2500)
    path = save_mesh(
        Mesh(head.mesh.vertices, head.mesh.faces, units="cm"),
        tmp_path / "a_rather_long_file_name_for_a_head_mesh_export.obj",
    )
    result = run_cli("info", str(path))
    assert result.exit_code == 0
    assert any(len(line) > 80 for line in result.output.splitlines())  # rich would wrap at 80


def test_progress_counts_only_a_known_total():
    from rich.progress import Progress

    from mimetic.cli.app import _Count

    with Progress() as bar:
        task = bar.add_task("x", total=None)
        assert str(_Count().render(bar.tasks[task])) == ""
        bar.update(task, completed=3, total=7)
        assert str(_Count().render(bar.tasks[task])) == "3/7"


@pytest.mark.parametrize(
    ("what", "names"),
    [
        ("expressions", ["joy", "surprise", "pucker"]),
        ("channels", ["jaw_open", "zygomatic_major_L", "rad"]),
        ("muscles", ["zygomatic_major_L", "orbicularis_oris", "sphincter"]),
        ("controls", ["Smile/Wide"]),
        ("facs", ["AU12", "Lip corner puller"]),
        ("arkit", ["jawOpen", "eyeBlinkLeft"]),
    ],
)
def test_list_names_what_commands_take(rig_file, what, names):
    result = run_cli("list", what, *([rig_file] if what in ("channels", "muscles") else []))
    assert result.exit_code == 0, result.output
    for name in names:
        assert name in result.output, name


def test_list_channels_as_json_gives_ranges_and_units(rig_file):
    result = run_cli("list", "channels", rig_file, "--json")
    rows = {row["name"]: row for row in json.loads(result.stdout)}
    assert len(rows) == len(load_rig(rig_file).channels)
    assert rows["jaw_open"]["unit"] == "rad" and rows["jaw_open"]["maximum"] > rows["jaw_open"]["minimum"]
    assert rows["zygomatic_major_L"]["unit"] == "activation"
