"""``benchmarks/write_docs.py``: fresh benchmark tables replace a marked section of the docs, nothing else."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).resolve().parents[1] / "benchmarks"


def _module(name: str):
    """A script of ``benchmarks/`` imported by path (the folder is not a package)."""
    spec = importlib.util.spec_from_file_location(f"_bench_{name}", BENCHMARKS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.path.insert(0, str(BENCHMARKS))  # report.py imports as the scripts import it
    try:
        spec.loader.exec_module(module)
    finally:
        sys.path.remove(str(BENCHMARKS))
    return module


write_docs = _module("write_docs")

DOCUMENT = """# Benchmarks

## Render
Prose before.
<!-- bench:render -->
| case | time |
|---|---|
| old | 1 s |
<!-- /bench:render -->
Prose after.

## Export
<!-- bench:export -->
| case | time |
|---|---|
| untouched | 2 s |
<!-- /bench:export -->
"""


def test_replace_section_replaces_only_between_its_markers():
    before = DOCUMENT
    fresh = "*Run today*\n\n| case | time |\n|---|---|\n| new | 0.5 s |\n"
    out = write_docs.replace_section(DOCUMENT, "render", fresh)
    assert isinstance(out, str)
    assert DOCUMENT == before
    assert "| new | 0.5 s |" in out and "| old | 1 s |" not in out
    assert "Prose before.\n<!-- bench:render -->\n*Run today*" in out
    assert "| new | 0.5 s |\n<!-- /bench:render -->\nProse after." in out
    export = DOCUMENT[DOCUMENT.index("## Export") :]
    assert out.endswith(export)


def test_replace_section_twice_is_the_same_as_once():
    once = write_docs.replace_section(DOCUMENT, "render", "| a |\n|---|\n")
    assert write_docs.replace_section(once, "render", "| a |\n|---|\n") == once


@pytest.mark.parametrize(
    "document",
    [
        DOCUMENT.replace("<!-- bench:render -->\n", ""),
        DOCUMENT.replace("<!-- /bench:render -->\n", ""),
        DOCUMENT.replace("<!-- bench:export -->", "<!-- bench:render -->"),
        DOCUMENT.replace("<!-- /bench:render -->", "@")
        .replace("<!-- bench:render -->", "<!-- /bench:render -->")
        .replace("@", "<!-- bench:render -->"),
    ],
    ids=["no opening", "no closing", "twice", "reversed"],
)
def test_replace_section_without_its_markers_raises_naming_them(document):
    with pytest.raises(ValueError, match=r"section 'render'.*<!-- bench:render -->.*<!-- /bench:render -->"):
        write_docs.replace_section(document, "render", "| new |")


def test_write_docs_rewrites_fresh_sections_and_keeps_the_rest(tmp_path):
    doc = tmp_path / "benchmarks.md"
    doc.write_text(DOCUMENT, encoding="utf-8")
    out = tmp_path / "out"
    out.mkdir()
    (out / "render.md").write_text("| new |\n|---|\n", encoding="utf-8")
    assert write_docs.write_docs(doc, out) == ["render"]
    text = doc.read_text(encoding="utf-8")
    assert "| new |" in text and "| old | 1 s |" not in text and "| untouched | 2 s |" in text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["benchmarks.md", "out"]  # no temporary file left


def test_write_docs_with_an_unmarked_section_leaves_the_document_as_it_was(tmp_path):
    doc = tmp_path / "benchmarks.md"
    doc.write_text(DOCUMENT, encoding="utf-8")
    out = tmp_path / "out"
    out.mkdir()
    (out / "render.md").write_text("| new |\n|---|\n", encoding="utf-8")
    (out / "speech.md").write_text("| words |\n|---|\n", encoding="utf-8")
    with pytest.raises(ValueError, match="section 'speech'"):
        write_docs.write_docs(doc, out)
    assert doc.read_text(encoding="utf-8") == DOCUMENT
