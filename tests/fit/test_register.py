"""``fit.register``: the target surface it samples, and a clear MeshError when there is none.

(Registration quality itself is measured end to end in test_rig_head.py and bench_rig.py.)
"""

from __future__ import annotations

import numpy as np
import pytest

from mimetic.errors import MeshError
from mimetic.fit.reference import fit_reference
from mimetic.fit.register import MIN_SAMPLES, outer_faces, sample_surface
from mimetic.mesh.model import Mesh
from mimetic.testing import small_head


def _soup(mesh: Mesh) -> Mesh:
    """Every triangle with its own three vertices: what an export without shared vertices gives."""
    vertices = mesh.vertices[mesh.faces.ravel()]
    return Mesh(vertices, np.arange(len(vertices)).reshape(-1, 3), units=mesh.units)


def test_sample_surface_covers_a_head_with_unit_normals() -> None:
    head = small_head()
    mesh = Mesh(head.mesh.vertices, head.mesh.faces, units="cm")
    surface = sample_surface(mesh)
    assert surface.points.shape == surface.normals.shape and surface.points.shape[1] == 3
    assert len(surface.points) >= MIN_SAMPLES and surface.points.dtype == np.float64
    np.testing.assert_allclose(np.linalg.norm(surface.normals, axis=1), 1.0, atol=1e-9)
    assert 0 < len(surface.triangles) <= mesh.n_faces


def test_sample_surface_of_a_triangle_soup_raises_mesh_error_saying_weld() -> None:
    soup = _soup(small_head().mesh)
    before = soup.vertices.copy()
    assert len(outer_faces(soup)) == 0  # no piece holds 5 % of the area
    with pytest.raises(MeshError, match="triangle soup") as caught:
        sample_surface(soup)
    message = str(caught.value)
    assert "Merge by Distance" in message and f"{soup.n_faces:,} pieces" in message
    np.testing.assert_array_equal(soup.vertices, before)


def test_sample_surface_of_degenerate_faces_raises_mesh_error() -> None:
    flat = Mesh(np.zeros((3, 3)), np.array([[0, 1, 2]]), units="cm")
    with pytest.raises(MeshError, match="no surface to fit"):
        sample_surface(flat)


def test_fit_reference_on_a_triangle_soup_raises_mesh_error() -> None:
    """Not the ``ValueError: a must be a positive integer`` of numpy's sampler."""
    head = small_head()
    names = [n for n in head.landmarks if not n.startswith("pupil")]
    with pytest.raises(MeshError, match="weld its vertices"):
        fit_reference(_soup(head.mesh), names, head.landmark_positions(names))


def test_solve_spd_takes_scipy_s_cg_steps_bit_for_bit() -> None:
    """``register._solve_spd`` runs scipy's Jacobi-preconditioned cg on the three columns side by side
    (one compiled product for the three): each column the same bits as scipy's, a zero column zero."""
    import scipy.sparse as sp
    from scipy.sparse.linalg import cg

    from mimetic.fit.register import CG_MAXITER, CG_RTOL, _solve_spd

    rng = np.random.default_rng(0)
    n = 300
    lap = sp.random(n, n, density=0.02, random_state=1)
    system = (lap @ lap.T + sp.diags(rng.uniform(0.5, 2.0, n))).tocsr()
    rhs, guess = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    rhs[:, 2] = 0.0
    found = _solve_spd(system, rhs, guess)
    assert found.shape == (n, 3) and found.dtype == np.float64
    preconditioner = sp.diags(1.0 / system.diagonal())
    for d in range(2):
        expected, info = cg(
            system, rhs[:, d], x0=guess[:, d], rtol=CG_RTOL, maxiter=CG_MAXITER, M=preconditioner
        )
        assert info == 0
        np.testing.assert_array_equal(found[:, d], expected)
    np.testing.assert_array_equal(found[:, 2], 0.0)
