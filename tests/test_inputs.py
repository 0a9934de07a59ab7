"""Tests for mimetic.inputs: text in the encodings people save it in, read or refused in one line."""

from __future__ import annotations

import pytest

from mimetic.errors import MimeticError, SpeechError
from mimetic.inputs import decode_text, read_text

SEPEDI = "Dumela, o kae? Ke a leboga, ke gona. Šega bohobe! Ôna ke êna.\r\nMoletši o a opela.\n"
"""A Northern Sotho transcript with its š, ô and ê (all in Windows-1252)."""


@pytest.mark.parametrize(
    "encoding", ["utf-8", "utf-8-sig", "utf-16", "utf-16-le", "utf-16-be", "utf-32", "cp1252"]
)
def test_decode_text_reads_the_common_encodings(encoding):
    data = SEPEDI.encode(encoding)
    assert decode_text(data, "talk.txt") == SEPEDI


def test_decode_text_drops_the_byte_order_mark():
    assert decode_text(b"\xef\xbb\xbfphoneme,start,end\n", "t.csv").startswith("phoneme")


@pytest.mark.parametrize(
    ("data", "says"),
    [
        (bytes(range(256)), "binary file"),  # control bytes: no text file holds them
        (b"fine text \x81\x8d\x90 here", "not text in UTF-8"),  # undefined in Windows-1252 too
        ("ok".encode("utf-16") + b"\x00\xd8", "not UTF-16-LE"),  # a lone surrogate after a BOM
    ],
)
def test_decode_text_refuses_in_one_line_naming_the_file(data, says):
    with pytest.raises(SpeechError, match=says) as caught:
        decode_text(data, "talk.txt", SpeechError)
    message = str(caught.value)
    assert message.startswith("talk.txt: ") and "\n" not in message


def test_read_text_names_a_missing_file_in_the_readers_error_type(tmp_path):
    with pytest.raises(SpeechError, match=r"nothing.txt: no such file"):
        read_text(tmp_path / "nothing.txt", SpeechError)
    with pytest.raises(MimeticError, match="is a folder"):
        read_text(tmp_path)


def test_a_windows_1252_textgrid_and_a_utf16_csv_read_as_timings(tmp_path):
    from mimetic.speech.timings import load_timings, naive_timings, save_timings

    timings = naive_timings("Šega bohobe, Dumela", language="nso")
    grid = save_timings(timings, tmp_path / "utf8.TextGrid")
    for encoding in ("cp1252", "utf-16", "utf-8-sig"):
        copy = tmp_path / f"{encoding}.TextGrid"
        copy.write_bytes(grid.read_text(encoding="utf-8").encode(encoding))
        assert load_timings(copy, language="nso") == load_timings(grid, language="nso")
    table = save_timings(timings, tmp_path / "utf8.csv")
    copy = tmp_path / "utf16.csv"
    copy.write_bytes(table.read_text(encoding="utf-8").encode("utf-16"))
    assert load_timings(copy, language="nso") == load_timings(table, language="nso")
