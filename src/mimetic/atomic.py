"""Atomic file writes: a failure never leaves half a file over a good one.

Every writer in mimetic (meshes, rigs, images, videos, USD) goes through :func:`atomic_write`
or, for tools that write to a file name themselves, :func:`atomic_path`. The data is
written to a temporary file in the target's folder, flushed and fsynced, then moved over the
target with ``os.replace`` (atomic on POSIX and Windows when both are on the same volume). If
anything raises before that, the temporary file is deleted and the target is untouched.
"""

from __future__ import annotations

import contextlib
import logging
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any

from mimetic.errors import MimeticError

log = logging.getLogger(__name__)

_MODES = ("wb", "w", "wt")


class WriteError(MimeticError, OSError):
    """An output file cannot be written: its folder is missing, or it is not writable."""


def _default_mode() -> int:
    """Permission bits a new file gets from ``open()``: 0o666 minus the process umask."""
    umask = os.umask(0)
    os.umask(umask)
    return 0o666 & ~umask


# Read once at import: os.umask can only be read by setting it, which is not thread-safe later.
_NEW_FILE_MODE = _default_mode()


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str], *, keep_suffix: bool = False) -> Iterator[Path]:
    """A temporary file path beside ``path``; on success it is moved over ``path``.

    For writers that need a file name rather than an open file (ffmpeg, USD). With
    ``keep_suffix`` the temporary name ends in the target's suffix (lower case), for tools that
    pick the format by it. After the ``with`` block the file is fsynced and replaces ``path``
    with its permission bits (new targets get ``0o666 & ~umask``); on any exception it is removed
    and ``path`` is untouched.

    Raises
    ------
    WriteError
        The folder does not exist, ``path`` is a folder, or the folder is not writable.
    """
    target = Path(path)
    folder = target.parent
    if target.is_dir():
        raise WriteError(f"cannot write {target}: it is a folder. Give a file name, e.g. {target / 'out'}.")
    if not folder.is_dir():
        raise WriteError(f"cannot write {target}: the folder {folder} does not exist. Create it first.")
    suffix = ".tmp" + (target.suffix.lower() if keep_suffix else "")
    try:
        fd, tmp_name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=suffix, dir=folder)
    except PermissionError as error:
        raise WriteError(f"cannot write {target}: no permission to create files in {folder}.") from error
    os.close(fd)
    tmp = Path(tmp_name)
    try:
        yield tmp
        with open(tmp, "rb+") as handle:
            os.fsync(handle.fileno())
        try:
            file_mode = target.stat().st_mode & 0o7777
        except FileNotFoundError:
            file_mode = _NEW_FILE_MODE
        os.chmod(tmp, file_mode)
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            tmp.unlink()
        raise
    _fsync_folder(folder)
    log.debug("wrote %s", target)


@contextlib.contextmanager
def atomic_write(
    path: str | os.PathLike[str], mode: str = "wb", *, encoding: str = "utf-8"
) -> Iterator[IO[Any]]:
    """Open a temporary file beside ``path``; on success move it over ``path`` (see ``atomic_path``).

    Parameters
    ----------
    path : path-like
        The file to create or replace. Its folder must exist.
    mode : {"wb", "w", "wt"}
        Binary (default) or text mode.
    encoding : str
        Text encoding for text modes; ignored for "wb".

    Yields
    ------
    file : the open temporary file. Write to it; do not close it.

    Raises
    ------
    WriteError
        The folder does not exist, ``path`` is a folder, or the folder is not writable.
    """
    if mode not in _MODES:
        raise ValueError(f"atomic_write mode must be one of {_MODES}; got {mode!r}")
    text = "b" not in mode
    with atomic_path(path) as tmp, open(tmp, mode, encoding=encoding if text else None) as handle:
        yield handle


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically (see :func:`atomic_write`); return the path."""
    with atomic_write(path, "wb") as handle:
        handle.write(data)
    return Path(path)


def _fsync_folder(folder: Path) -> None:
    """Make the rename durable on POSIX; a no-op where folders cannot be opened (Windows)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)
