"""Finding and installing Blender (bpy) for FBX, without running it: tests/clients run it for real."""

from __future__ import annotations

import stat
import sys
from pathlib import Path

import pytest

from mimetic import blender
from mimetic.blender import BPY_VERSION, Blender, BlenderError


@pytest.fixture
def cache(tmp_path, monkeypatch) -> Path:
    """An empty cache folder, and no override."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.delenv(blender.ENV_VAR, raising=False)
    return tmp_path / "cache" / "mimetic"


def executable(path: Path, text: str) -> Path:
    path.write_text(text)
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    return path


def test_the_venv_lives_in_the_cache_under_the_bpy_version(cache):
    assert blender.venv_dir() == cache / f"bpy-{BPY_VERSION}"
    assert blender.find_blender() is None  # nothing installed in an empty cache


def test_without_python_3_11_the_error_says_what_is_missing_in_one_line(cache, monkeypatch):
    monkeypatch.setattr(blender, "python311", lambda: None)
    with pytest.raises(
        BlenderError, match=r"runs only on Python 3\.11, and no python3\.11 is on PATH"
    ) as info:
        blender.blender()
    assert "\n" not in str(info.value) and "MIMETIC_BLENDER" in str(info.value)
    assert not cache.exists() or not any(cache.iterdir())


def test_a_failed_install_says_where_and_leaves_nothing_behind(cache, monkeypatch, tmp_path, caplog):
    broken = executable(tmp_path / "python3.11", "#!/bin/sh\necho 'No module named venv' >&2\nexit 1\n")
    monkeypatch.setattr(blender, "python311", lambda: str(broken))
    steps = []
    with pytest.raises(BlenderError, match=r"failed at 'create a Python 3\.11 venv' .*No module named venv"):
        blender.install_bpy(lambda step, done, total: steps.append(step))
    assert steps == ["set up FBX: create a Python 3.11 venv"]
    assert list(cache.iterdir()) == []  # the half-made venv is gone
    assert blender.find_blender() is None
    with caplog.at_level("WARNING", logger="mimetic.blender"), pytest.raises(BlenderError):
        blender.blender()  # first use without a progress display: a log line says why it waits
    assert "installing Blender's bpy 5.0.1 for FBX" in caplog.text


def test_the_override_names_a_blender_binary_or_a_python(cache, monkeypatch, tmp_path):
    binary = executable(tmp_path / "blender", "#!/bin/sh\n")
    monkeypatch.setenv(blender.ENV_VAR, str(binary))
    found = blender.find_blender()
    assert found == Blender(binary, is_binary=True)
    script = Path("s.py")
    assert found.command(script, ["a"]) == [
        str(binary), "--background", "--factory-startup", "--python", "s.py", "--", "a"
    ]  # fmt: skip
    monkeypatch.setenv(blender.ENV_VAR, sys.executable)
    assert blender.find_blender().command(script, ["a"]) == [sys.executable, "s.py", "--", "a"]
    monkeypatch.setenv(blender.ENV_VAR, str(tmp_path / "nowhere"))
    with pytest.raises(BlenderError, match=r"MIMETIC_BLENDER=.*nowhere: no such file"):
        blender.find_blender()


def test_a_script_that_blames_the_file_raises_the_callers_error(cache, monkeypatch, tmp_path):
    """Exit code 3 and a MIMETIC_ERROR line: the caller's error with that line; a crash: BlenderError."""
    from mimetic.errors import MeshError

    fake = executable(
        tmp_path / "python",
        "#!/bin/sh\ncase \"$3\" in bad) echo 'MIMETIC_ERROR holds no mesh'; exit 3;;\n"
        "crash) echo 'Segmentation fault' >&2; exit 139;;\n*) echo 'MIMETIC_JSON {\"ok\": 1}';; esac\n",
    )
    monkeypatch.setenv(blender.ENV_VAR, str(fake))
    assert blender.run_script("x.py", ["fine"], error=MeshError) == {"ok": 1}
    with pytest.raises(MeshError, match=r"^holds no mesh$"):
        blender.run_script("x.py", ["bad"], error=MeshError)
    with pytest.raises(BlenderError, match=r"failed running x\.py \(exit 139\): Segmentation fault"):
        blender.run_script("x.py", ["crash"], error=MeshError)
