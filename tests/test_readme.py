"""Every Python snippet in the README and in ``docs/`` runs as written, in order.

The snippets of one page build on each other the way a reader types them (the README's quick start
saves ``my_head.obj``, the next snippet rigs it), so each page runs in one namespace and one folder
of its own. A snippet marked ``<!-- no-test: reason -->`` on the line before its fence is skipped.
The README stays short (≤ 300 lines, with a table of contents) and every page it links to exists.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DOCS = sorted((ROOT / "docs").glob("*.md"))
FENCE = re.compile(r"(<!-- no-test: [^>]*-->\n)?```python\n(.*?)```", re.S)


def _snippets(page: Path) -> list[str]:
    return [code for marker, code in FENCE.findall(page.read_text(encoding="utf-8")) if not marker]


def _run_page(page: Path, folder: Path, monkeypatch) -> None:
    monkeypatch.chdir(folder)
    namespace: dict = {"__name__": "__readme__"}
    for number, code in enumerate(_snippets(page), 1):
        try:
            exec(compile(code, f"{page.name} snippet {number}", "exec"), namespace)
        except Exception as error:
            pytest.fail(f"{page.name} snippet {number} failed: {type(error).__name__}: {error}\n\n{code}")


def test_readme_has_python_snippets():
    assert len(_snippets(README)) >= 3


def test_readme_is_short_with_a_table_of_contents_and_links_that_resolve():
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 300
    assert "**Contents**" in text
    headings = {
        re.sub(r"[^\w\- ]", "", line[3:].strip().lower()).replace(" ", "-")
        for line in text.splitlines()
        if line.startswith("## ")
    }
    anchors = set(re.findall(r"\]\(#([\w-]+)\)", text))
    assert anchors and anchors <= headings, anchors - headings
    for page in (*re.findall(r"\]\((docs/[\w./-]+)\)", text), *(f"docs/{p.name}" for p in DOCS)):
        assert (ROOT / page).is_file(), page
    linked = set(re.findall(r"\]\(docs/([\w.-]+\.md)\)", text))
    assert {p.name for p in DOCS} <= linked, "a docs page the README does not list"


def test_readme_python_snippets_run_as_written(tmp_path, monkeypatch):
    _run_page(README, tmp_path, monkeypatch)
    assert os.listdir(tmp_path)  # the snippets wrote real files


@pytest.mark.parametrize("page", [p for p in DOCS if _snippets(p)], ids=lambda p: p.name)
def test_docs_python_snippets_run_as_written(page, tmp_path, monkeypatch):
    _run_page(page, tmp_path, monkeypatch)
