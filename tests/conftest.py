"""Shared fixtures: tiny meshes with known answers (built by ``mimetic.testing``), a GL renderer, and
the small rig with its wire engine (a module may override ``rig``, e.g. with the full-resolution head;
``engine`` follows it).

Meshes are immutable (read-only arrays), so the fixtures are session-scoped.
"""

from __future__ import annotations

import os

import numpy as np
import pytest
import trimesh

from mimetic import testing
from mimetic.engines import make_engine
from mimetic.errors import RenderError
from mimetic.mesh.model import Mesh
from mimetic.render import Renderer


@pytest.fixture(scope="session")
def tetrahedron() -> Mesh:
    """Closed unit right-corner tetrahedron: 4 vertices, 4 outward faces, no parts, no units."""
    return testing.tetrahedron()


@pytest.fixture(scope="session")
def unit_square() -> Mesh:
    """Open unit square in z = 0: 4 vertices, 2 triangles facing +Z, one boundary loop 0-1-2-3."""
    return testing.unit_square()


def to_mesh(tm: trimesh.Trimesh, colors: np.ndarray | None = None) -> Mesh:
    return Mesh(np.asarray(tm.vertices, np.float64), np.asarray(tm.faces, np.int64), colors=colors)


@pytest.fixture(scope="session")
def gl_renderer():
    """A Renderer forced to EGL; skips when EGL is missing, except on CI (CI=true), where it fails."""
    renderer = Renderer("egl")
    try:
        renderer._ensure_backend()
    except RenderError as error:
        reason = f"GL tests need EGL: {error}"
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(f"{reason} (CI=true: EGL is required on CI)")
        pytest.skip(reason)
    yield renderer
    renderer.release()


@pytest.fixture(scope="session")
def sphere() -> Mesh:
    """Unit icosphere, 1280 triangles."""
    return to_mesh(trimesh.creation.icosphere(subdivisions=3))


@pytest.fixture(scope="session")
def torus() -> Mesh:
    """A torus in the XY plane (non-convex: it hides parts of itself)."""
    return to_mesh(trimesh.creation.torus(major_radius=1.0, minor_radius=0.35))


@pytest.fixture(scope="module")
def rig():
    return testing.small_rig()


@pytest.fixture(scope="module")
def engine(rig):
    return make_engine(rig, "wire")
