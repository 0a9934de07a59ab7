"""The package's import graph flows one way (STYLE §1), as ``src/mimetic/layers.toml`` declares it.

The layers file lists the layers bottom to top; a module imports only its own layer and the layers
below (lazy imports count too). So, among others: nothing in the library imports ``mimetic.testing``
or the CLI; the renderer sits below ``fit``; drivers (``animate``, ``speech``) never import
``export``; the pictures (``view``) sit below the tasks, and the front ends (the web viewer, batch,
the CLI) above them.
"""

from __future__ import annotations

import ast
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src" / "mimetic"
LAYERS = tomllib.loads((SRC / "layers.toml").read_text(encoding="utf-8"))["layer"]


def _module_name(path: Path) -> str:
    parts = path.relative_to(SRC.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path) -> set[str]:
    """The mimetic modules ``path`` imports (at any depth: lazy imports count too)."""
    found = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            found.add(node.module)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    return {name for name in found if name == "mimetic" or name.startswith("mimetic.")}


MODULES = {_module_name(p): _imports(p) for p in sorted(SRC.rglob("*.py"))}


def _within(module: str, package: str) -> bool:
    return module == package or module.startswith(package + ".")


def layer_of(module: str) -> int:
    """The index (0 at the bottom) of the layer whose entry is ``module``'s longest matching prefix."""
    matches = [
        (len(prefix), index)
        for index, layer in enumerate(LAYERS)
        for prefix in layer["modules"]
        if _within(module, prefix)
    ]
    return max(matches)[1]


def test_layout_sees_the_whole_package():
    assert {"mimetic.cli", "mimetic.render.renderer", "mimetic.fit.autolandmarks", "mimetic.testing"} <= set(
        MODULES
    )


def test_every_package_has_a_declared_layer():
    declared = {prefix for layer in LAYERS for prefix in layer["modules"]}
    packages = {".".join(module.split(".")[:2]) for module in MODULES}
    assert packages <= declared, packages - declared


@pytest.mark.parametrize(
    ("module", "layer"),
    [
        ("mimetic.view.web", "the web viewer"),
        ("mimetic.view.sheets", "pictures"),
        ("mimetic.render.renderer", "render"),
        ("mimetic.speech.lipsync", "drivers"),
        ("mimetic.batch.jobs", "batch"),
        ("mimetic.tasks.rig", "tasks"),
    ],
)
def test_a_module_takes_the_layer_of_its_longest_prefix(module, layer):
    assert LAYERS[layer_of(module)]["name"].startswith(layer)


def test_nothing_imports_a_layer_above_its_own():
    bad = sorted(
        f"{module} ({LAYERS[layer_of(module)]['name'].split(':')[0]}) imports {name} "
        f"({LAYERS[layer_of(name)]['name'].split(':')[0]})"
        for module, names in MODULES.items()
        for name in names
        if layer_of(name) > layer_of(module)
    )
    assert bad == []


def test_the_check_catches_an_import_upwards():
    """The rule bites: a renderer importing fit, a driver importing export, fit importing the CLI."""
    for low, high in (
        ("mimetic.render.renderer", "mimetic.fit.pipeline"),
        ("mimetic.animate.keyframes", "mimetic.export.gltf"),
        ("mimetic.fit.pipeline", "mimetic.cli"),
        ("mimetic.tasks.pose", "mimetic.view.web"),
        ("mimetic.cli.app", "mimetic.testing"),
    ):
        assert layer_of(high) > layer_of(low), (low, high)


def test_importing_the_library_and_its_cli_loads_no_test_plumbing():
    code = (
        "import sys, mimetic, mimetic.cli, mimetic.fit, mimetic.engines, mimetic.export, mimetic.view, "
        "mimetic.tasks, mimetic.batch; "
        "print(sorted(m for m in sys.modules if m in ('mimetic.testing', 'pytest', 'numba')))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


LONG_LINES = 600
"""A module longer than this says why in its docstring ("Over 600 lines because …")."""


def test_a_module_over_600_lines_says_why_in_its_docstring():
    unexplained = sorted(
        f"{_module_name(path)} ({lines} lines)"
        for path in SRC.rglob("*.py")
        if (lines := len(path.read_text(encoding="utf-8").splitlines())) > LONG_LINES
        and f"Over {LONG_LINES} lines because" not in (ast.get_docstring(ast.parse(path.read_text())) or "")
    )
    assert unexplained == []
