"""Shared fixtures: tiny meshes with known answers (built by ``mimetic.testing``).

Meshes are immutable (read-only arrays), so the fixtures are session-scoped.
"""

from __future__ import annotations

import pytest

from mimetic import testing
from mimetic.mesh.model import Mesh


@pytest.fixture(scope="session")
def tetrahedron() -> Mesh:
    """Closed unit right-corner tetrahedron: 4 vertices, 4 outward faces, no parts, no units."""
    return testing.tetrahedron()


@pytest.fixture(scope="session")
def unit_square() -> Mesh:
    """Open unit square in z = 0: 4 vertices, 2 triangles facing +Z, one boundary loop 0-1-2-3."""
    return testing.unit_square()
