"""Every Python snippet in the README runs as written, in order, in one namespace and one folder.

The README's snippets build on each other the way a reader types them (the quick start saves
``my_head.obj``, the next snippet rigs it). A snippet marked ``<!-- no-test: reason -->`` on the
line before its fence is skipped (none today).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
FENCE = re.compile(r"(<!-- no-test: [^>]*-->\n)?```python\n(.*?)```", re.S)


def _snippets() -> list[str]:
    return [code for marker, code in FENCE.findall(README.read_text(encoding="utf-8")) if not marker]


def test_readme_has_python_snippets():
    assert len(_snippets()) >= 5


def test_readme_python_snippets_run_as_written(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__readme__"}
    for number, code in enumerate(_snippets(), 1):
        try:
            exec(compile(code, f"README.md snippet {number}", "exec"), namespace)
        except Exception as error:
            pytest.fail(f"README snippet {number} failed: {type(error).__name__}: {error}\n\n{code}")
    assert os.listdir(tmp_path)  # the snippets wrote real files
