"""``mimetic.capture``'s names load on first use: the command line reads its constants without the
solvers (and numba), and every documented name is still the function or class it names."""

from __future__ import annotations

import subprocess
import sys

import pytest

import mimetic.capture


def test_importing_the_package_and_its_constants_loads_no_solver():
    heavy = "('numba', 'mimetic.capture.qp', 'mimetic.capture.performance')"
    code = (
        "import sys, mimetic.capture, mimetic.capture.markers, mimetic.capture.smooth; "
        "import mimetic.tasks.capture; "
        f"print(sorted(m for m in {heavy} if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize("name", mimetic.capture.__all__)
def test_every_name_is_what_it_names_even_after_its_module_loaded(name):
    import mimetic.capture.retarget

    value = getattr(mimetic.capture, name)
    assert callable(value) and value.__name__ == name


def test_an_unknown_name_is_an_attribute_error():
    with pytest.raises(AttributeError, match="no attribute 'solve_everything'"):
        mimetic.capture.solve_everything  # noqa: B018
