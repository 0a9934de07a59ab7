"""Fixtures shared by the capture tests: the test rig's wire basis and its iBUG-68 markers (one of
each per test module, as ``rig`` is)."""

from __future__ import annotations

import pytest

from mimetic.capture import marker_set
from mimetic.engines import make_engine
from mimetic.engines.bake import bake


@pytest.fixture(scope="module")
def baked(rig):
    return bake(make_engine(rig, "wire"), correctives=0, samples=2).basis


@pytest.fixture(scope="module")
def ibug(rig):
    return marker_set(rig, "ibug68")
