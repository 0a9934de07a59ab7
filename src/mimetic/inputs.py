"""Reading input files: their bytes with a one-line error, and their text in any common encoding.

Every reader of a user's file goes through ``read_input`` (bytes) or ``read_text`` (text), so a
missing file, a folder, a permission problem or an encoding says what is wrong in one line, in the
reader's own error type (``MeshError``, ``SpeechError``, ``CaptureError`` …).

Text is decoded as people save it (``decode_text``):

1. a byte-order mark names the encoding: UTF-8 ("UTF-8 with BOM", as Notepad and Excel save it),
   UTF-16 or UTF-32, little- or big-endian;
2. otherwise UTF-8 (ASCII included);
3. otherwise UTF-16 without a mark, when one byte of every pair is zero (a text of mostly ASCII
   characters saved as "Unicode" by an old tool);
4. otherwise Windows-1252 (Western "ANSI", what Windows editors save by default, with š, ô, ê of
   Northern Sotho and the accents of Western languages), when every byte is defined there and no
   control character but tab, form feed and line ends occurs;
5. otherwise the file is refused: a binary file, or text in another encoding, with the fix.
"""

from __future__ import annotations

import codecs
import os
import re
from pathlib import Path

from mimetic.errors import MimeticError

BOMS = (
    (codecs.BOM_UTF32_LE, "utf-32-le"),  # before UTF-16 LE: it starts with the same two bytes
    (codecs.BOM_UTF32_BE, "utf-32-be"),
    (codecs.BOM_UTF8, "utf-8"),
    (codecs.BOM_UTF16_LE, "utf-16-le"),
    (codecs.BOM_UTF16_BE, "utf-16-be"),
)
"""Byte-order marks and the encodings they name, in the order they are tried."""

ENCODINGS_READ = "UTF-8 (with or without BOM), UTF-16, UTF-32 or Windows-1252"
"""The encodings ``decode_text`` reads, as messages name them."""

_CONTROL = re.compile(r"[\x00-\x08\x0b\x0e-\x1f\x7f]")
"""Control characters no text file holds (tab, line feed, form feed and carriage return are fine)."""
_CONTROL_BYTES = re.compile(rb"[\x00-\x08\x0b\x0e-\x1f\x7f]")


def read_input(path: str | os.PathLike[str], src: str, error: type[MimeticError], kind: str) -> bytes:
    """The bytes of input file ``path`` (``src`` names it in messages); ``error`` when it is missing,
    a folder or unreadable, saying what to do (``kind``: "mesh", "landmark", "trajectory" …)."""
    path = Path(path)
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise error(f"{src}: no such file (looked in {path.absolute().parent}). Check the path.") from None
    except IsADirectoryError:
        raise error(
            f"{src}: is a folder, not a {kind} file. Give the path of a {kind} file inside it."
        ) from None
    except PermissionError:
        raise error(f"{src}: permission denied. Make the file readable.") from None
    except OSError as exc:
        raise error(f"{src}: cannot read the file ({exc.strerror or exc}).") from None


def decode_text(data: bytes, src: str, error: type[MimeticError] = MimeticError) -> str:
    """``data`` decoded as the module docstring says, without a byte-order mark; ``error`` (one line,
    naming ``src``) when it is not text in one of ``ENCODINGS_READ``."""
    for bom, encoding in BOMS:
        if data.startswith(bom):
            try:
                return _checked(data[len(bom) :].decode(encoding), src, error)
            except UnicodeDecodeError as failure:
                raise error(
                    f"{src}: starts as {encoding.upper()} text but byte {failure.start + len(bom)} is not "
                    f"{encoding.upper()}; save it again as UTF-8"
                ) from None
    if b"\x00" in data and len(data) % 2 == 0:
        for encoding, zeros in (("utf-16-le", data[1::2]), ("utf-16-be", data[0::2])):
            if zeros.count(0) >= 0.9 * len(zeros):
                try:
                    return _checked(data.decode(encoding), src, error)
                except UnicodeDecodeError:
                    break
    try:
        return _checked(data.decode("utf-8"), src, error)
    except UnicodeDecodeError:
        pass
    control = _CONTROL_BYTES.search(data)
    if control is not None:
        raise error(
            f"{src}: a binary file, not text (byte 0x{data[control.start()]:02x} at {control.start()}); "
            "check that this is the right file"
        )
    try:
        return _checked(data.decode("cp1252"), src, error)
    except UnicodeDecodeError as failure:
        byte = data[failure.start]
        raise error(
            f"{src}: not text in {ENCODINGS_READ} (byte 0x{byte:02x} at {failure.start}); save it as UTF-8"
        ) from None


def read_text(
    path: str | os.PathLike[str], error: type[MimeticError] = MimeticError, kind: str = "text"
) -> str:
    """The text of file ``path`` in any encoding ``decode_text`` reads; ``error`` (one line) when it
    cannot be read or is not text."""
    return decode_text(read_input(path, str(path), error, kind), str(path), error)


def _checked(text: str, src: str, error: type[MimeticError]) -> str:
    """``text`` unless it holds control characters (a binary file decoded by accident)."""
    found = _CONTROL.search(text)
    if found is not None:
        line = text.count("\n", 0, found.start()) + 1
        raise error(
            f"{src}: a binary file, not text (character 0x{ord(found.group()):02x} on line {line}); "
            "check that this is the right file"
        )
    return text
