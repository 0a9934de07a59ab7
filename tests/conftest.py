"""Shared fixtures: tiny meshes with known answers.

Meshes are immutable (read-only arrays), so the fixtures are session-scoped.
"""

from __future__ import annotations

import numpy as np
import pytest

from mimetic.mesh.model import Mesh

TETRAHEDRON_VERTICES = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
TETRAHEDRON_FACES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])  # outward, counter-clockwise

UNIT_SQUARE_VERTICES = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
UNIT_SQUARE_FACES = np.array([[0, 1, 2], [0, 2, 3]])  # counter-clockwise seen from +Z


@pytest.fixture(scope="session")
def tetrahedron() -> Mesh:
    """Closed unit right-corner tetrahedron: 4 vertices, 4 outward faces, no parts, no units."""
    return Mesh(TETRAHEDRON_VERTICES, TETRAHEDRON_FACES)


@pytest.fixture(scope="session")
def unit_square() -> Mesh:
    """Open unit square in z = 0: 4 vertices, 2 triangles facing +Z, one boundary loop 0-1-2-3."""
    return Mesh(UNIT_SQUARE_VERTICES, UNIT_SQUARE_FACES)
