"""Fixtures shared by the animate tests: the small rig and its wire engine (a module may override
``rig``, e.g. with the full-resolution head; ``engine`` follows it)."""

from __future__ import annotations

import pytest

from mimetic.engines import make_engine
from mimetic.testing import small_rig


@pytest.fixture(scope="module")
def rig():
    return small_rig()


@pytest.fixture(scope="module")
def engine(rig):
    return make_engine(rig, "wire")
