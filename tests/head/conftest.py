"""Fixtures for the head tests: the small default head and its topology, built once per run.

Heads and topologies are immutable and cached by ``mimetic.testing``, so the fixtures are
session-scoped and tests that need other parameter sets call ``small_head(seed)`` or
``head_with(params)`` directly (the same cache).
"""

from __future__ import annotations

import pytest

from mimetic.head.model import Head
from mimetic.head.topology import HeadTopology, build_topology
from mimetic.testing import SMALL_RESOLUTION, small_head


@pytest.fixture(scope="session")
def head() -> Head:
    """The default head at 2,500 requested skin vertices."""
    return small_head()


@pytest.fixture(scope="session")
def topology() -> HeadTopology:
    """The skin topology of ``head`` (2,580 skin vertices)."""
    return build_topology(SMALL_RESOLUTION)
