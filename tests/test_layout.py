"""The package's import graph flows one way (STYLE §1): checked on the source, module by module.

* Nothing in the library imports ``mimetic.testing`` (test and benchmark plumbing) or the CLI.
* Only the CLI and the demo import ``mimetic.view``, ``mimetic.export`` and ``mimetic.demo``
  (besides those packages themselves; ``mimetic.testing``, plumbing above everything, films its
  validation takes with ``view``), and ``mimetic.batch``, which runs the commands' jobs on
  workers, imports ``view`` and ``export``; only the CLI imports ``mimetic.batch``. The web viewer's
  downloads (``mimetic.view.exports``) import ``export``: its GLB button writes what the CLI does.
* ``mimetic.render`` (the offscreen renderer) sits below ``fit``: it imports only ``mesh`` and the
  error types, so finding landmarks automatically does not pull in sheets, overlays or video.
* ``mimetic.animate`` (drivers) does not bake geometry: it never imports ``mimetic.export``.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "mimetic"


def _module_name(path: Path) -> str:
    parts = path.relative_to(SRC.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path) -> set[str]:
    """The mimetic modules ``path`` imports (at any depth: lazy imports count too)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return {name for name in found if name == "mimetic" or name.startswith("mimetic.")}


MODULES = {_module_name(p): _imports(p) for p in sorted(SRC.rglob("*.py"))}


def _within(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def _offenders(importer_ok, imported: str) -> list[str]:
    return sorted(
        f"{module} imports {name}"
        for module, names in MODULES.items()
        for name in names
        if _within(name, imported) and not importer_ok(module)
    )


def test_layout_sees_the_whole_package():
    assert {"mimetic.cli", "mimetic.render.renderer", "mimetic.fit.autolandmarks", "mimetic.testing"} <= set(
        MODULES
    )


@pytest.mark.parametrize(
    ("imported", "allowed"),
    [
        ("mimetic.testing", ("mimetic.testing",)),
        ("mimetic.cli", ("mimetic.testing",)),  # testing.run_cli: plumbing above everything
        ("mimetic.demo", ("mimetic.cli", "mimetic.demo")),
        ("mimetic.view", ("mimetic.view", "mimetic.cli", "mimetic.demo", "mimetic.batch", "mimetic.testing")),
        (
            "mimetic.export",
            ("mimetic.export", "mimetic.cli", "mimetic.demo", "mimetic.batch", "mimetic.view.exports"),
        ),
        ("mimetic.batch", ("mimetic.batch", "mimetic.cli")),
    ],
)
def test_nothing_below_imports_the_top_layers(imported, allowed):
    assert _offenders(lambda m: any(_within(m, a) for a in allowed), imported) == []


def test_render_sits_below_fit():
    allowed = ("mimetic.render", "mimetic.mesh", "mimetic.errors")
    bad = sorted(
        f"{module} imports {name}"
        for module, names in MODULES.items()
        if _within(module, "mimetic.render")
        for name in names
        if not any(_within(name, a) for a in allowed)
    )
    assert bad == []


def test_fit_does_not_import_view_and_drivers_do_not_import_export():
    bad = sorted(
        f"{module} imports {name}"
        for module, names in MODULES.items()
        for name in names
        if (_within(module, "mimetic.fit") and _within(name, "mimetic.view"))
        or (_within(module, "mimetic.animate") and _within(name, "mimetic.export"))
    )
    assert bad == []


def test_importing_the_library_and_its_cli_loads_no_test_plumbing():
    code = (
        "import sys, mimetic, mimetic.cli, mimetic.fit, mimetic.engines, mimetic.export, mimetic.view, "
        "mimetic.demo, mimetic.batch; "
        "print(sorted(m for m in sys.modules if m in ('mimetic.testing', 'pytest', 'numba')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
