"""Tests for mimetic.atomic: a failed write never leaves half a file over a good one."""

from __future__ import annotations

import os
import stat

import pytest

from mimetic.atomic import WriteError, atomic_write, atomic_write_bytes
from mimetic.errors import MimeticError


def leftovers(folder):
    """Temporary files atomic_write may have left behind."""
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".tmp"))


def test_atomic_write_bytes_new_file_has_content(tmp_path):
    target = tmp_path / "out.bin"
    returned = atomic_write_bytes(target, b"\x00\x01payload")
    assert returned == target
    assert target.read_bytes() == b"\x00\x01payload"
    assert leftovers(tmp_path) == []


def test_atomic_write_existing_file_is_replaced_on_success(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with atomic_write(target, "w") as handle:
        handle.write("new é")
    assert target.read_text(encoding="utf-8") == "new é"
    assert leftovers(tmp_path) == []


def test_atomic_write_writer_raises_midway_keeps_original(tmp_path):
    target = tmp_path / "rig.bin"
    target.write_bytes(b"GOOD" * 1000)
    with pytest.raises(RuntimeError, match="disk on fire"):
        with atomic_write(target) as handle:
            handle.write(b"HALF" * 500)
            handle.flush()
            raise RuntimeError("disk on fire")
    assert target.read_bytes() == b"GOOD" * 1000
    assert leftovers(tmp_path) == []


def test_atomic_write_keyboard_interrupt_keeps_original_and_cleans_up(tmp_path):
    target = tmp_path / "out.bin"
    target.write_bytes(b"GOOD")
    with pytest.raises(KeyboardInterrupt):
        with atomic_write(target) as handle:
            handle.write(b"partial")
            raise KeyboardInterrupt
    assert target.read_bytes() == b"GOOD"
    assert leftovers(tmp_path) == []


def test_atomic_write_failure_without_original_creates_nothing(tmp_path):
    target = tmp_path / "new.bin"
    with pytest.raises(ValueError):
        with atomic_write(target) as handle:
            handle.write(b"x")
            raise ValueError("boom")
    assert list(tmp_path.iterdir()) == []


def test_atomic_write_temp_file_is_beside_target_while_writing(tmp_path):
    target = tmp_path / "out.bin"
    with atomic_write(target) as handle:
        handle.write(b"abc")
        assert len(leftovers(tmp_path)) == 1
        assert not target.exists()
    assert target.read_bytes() == b"abc"


@pytest.mark.skipif(os.name != "posix", reason="POSIX permission bits")
def test_atomic_write_replaced_file_keeps_permission_bits(tmp_path):
    target = tmp_path / "script.sh"
    target.write_text("old")
    target.chmod(0o750)
    atomic_write_bytes(target, b"new")
    assert stat.S_IMODE(target.stat().st_mode) == 0o750


@pytest.mark.skipif(os.name != "posix", reason="POSIX permission bits")
def test_atomic_write_new_file_gets_umask_permissions_not_private_temp_ones(tmp_path):
    target = tmp_path / "new.bin"
    atomic_write_bytes(target, b"x")
    umask = os.umask(0)
    os.umask(umask)
    assert stat.S_IMODE(target.stat().st_mode) == 0o666 & ~umask


def test_atomic_write_missing_folder_raises_write_error(tmp_path):
    target = tmp_path / "missing" / "out.bin"
    with pytest.raises(WriteError, match="does not exist") as info:
        atomic_write_bytes(target, b"x")
    assert isinstance(info.value, MimeticError)
    assert isinstance(info.value, OSError)


def test_atomic_write_target_is_folder_raises_write_error(tmp_path):
    with pytest.raises(WriteError, match="is a folder"):
        atomic_write_bytes(tmp_path, b"x")


def test_atomic_write_unknown_mode_raises_value_error(tmp_path):
    with pytest.raises(ValueError, match="mode"):
        with atomic_write(tmp_path / "x", "ab"):
            pass
