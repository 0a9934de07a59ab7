"""Tests for mimetic.mesh.validate: reports with known answers on synthetic meshes."""

from __future__ import annotations

import dataclasses
import json
import sys

import numpy as np
import pytest

from mimetic.errors import MeshError
from mimetic.mesh.model import Mesh
from mimetic.mesh.validate import MeshReport, validate_mesh
from mimetic.testing import cheek_centre, patch_faces, small_head, unwelded_patch


def counts(report: MeshReport) -> dict[str, int]:
    return {k: v for k, v in report.as_dict().items() if k.startswith("n_")}


def test_validate_mesh_tetrahedron_is_closed_single_component(tetrahedron):
    report = validate_mesh(tetrahedron)
    assert isinstance(report, MeshReport)
    assert counts(report) == dict(
        n_vertices=4,
        n_faces=4,
        n_nonfinite_vertices=0,
        n_out_of_range_faces=0,
        n_degenerate_faces=0,
        n_duplicate_faces=0,
        n_nonmanifold_edges=0,
        n_boundary_loops=0,
        n_boundary_chains=0,
        n_components=1,
        n_unused_vertices=0,
        n_seam_vertices=0,
        n_reversed_faces=0,
    )
    assert report.ok
    assert report.errors == ()
    assert report.warnings == ()
    assert report.bbox_min == (0.0, 0.0, 0.0)
    assert report.bbox_max == (1.0, 1.0, 1.0)
    assert report.extent == 1.0
    assert report.detected_units == "dm"
    report.raise_for_errors()  # no error: no exception


def test_validate_mesh_unit_square_has_one_boundary_loop_and_too_few_faces(unit_square):
    report = validate_mesh(unit_square)
    assert report.n_boundary_loops == 1
    assert report.n_boundary_chains == 0
    assert report.n_components == 1
    assert not report.ok
    assert any("only 2 faces" in e for e in report.errors)


def test_validate_mesh_nan_vertex_is_an_error(tetrahedron):
    vertices = tetrahedron.vertices.copy()
    vertices[2] = [np.nan, 0.0, 0.0]
    report = validate_mesh(tetrahedron.with_vertices(vertices))
    assert report.n_nonfinite_vertices == 1
    assert not report.ok
    assert "vertex 2" in report.errors[0]
    assert report.bbox_max == (1.0, 0.0, 1.0)  # over the finite vertices only
    with pytest.raises(MeshError, match=r"head\.obj: 1 vertices have NaN"):
        report.raise_for_errors("head.obj")


def test_validate_mesh_all_nan_vertices_have_no_bbox_and_are_json_safe(tetrahedron):
    report = validate_mesh(tetrahedron.with_vertices(np.full((4, 3), np.inf)))
    assert report.bbox_min is None
    assert report.extent is None
    assert report.detected_units is None
    json.dumps(report.as_dict(), allow_nan=False)


def test_validate_mesh_fin_reports_nonmanifold_edge_and_open_chain():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, -1, 0], [0.5, 0, 1.0]])
    faces = np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4], [2, 3, 4]])
    report = validate_mesh(Mesh(vertices, faces))
    assert report.n_nonmanifold_edges == 1
    assert report.n_boundary_chains >= 1
    assert report.ok  # non-manifold is a warning, not an error
    assert any("non-manifold" in w and "Select All by Trait" in w for w in report.warnings)


def test_validate_mesh_duplicate_and_degenerate_faces_are_counted(tetrahedron):
    vertices = np.concatenate([tetrahedron.vertices, [[2.0, 0.0, 0.0]]])  # 4: on the line through 0-1
    faces = np.concatenate(
        [
            tetrahedron.faces,
            [[3, 2, 1]],  # duplicate of face 3 in another order
            [[1, 1, 2]],  # repeated index
            [[0, 1, 4]],  # zero area: collinear
        ]
    )
    report = validate_mesh(Mesh(vertices, faces))
    assert report.n_duplicate_faces == 1
    assert report.n_degenerate_faces == 2
    assert report.ok
    assert any("duplicate" in w for w in report.warnings)
    assert any("degenerate" in w for w in report.warnings)


def test_validate_mesh_two_disjoint_tetrahedra_are_two_components(tetrahedron):
    mesh = Mesh.concatenate({"a": tetrahedron, "b": tetrahedron.with_vertices(tetrahedron.vertices + 5)})
    report = validate_mesh(mesh)
    assert report.n_components == 2
    assert report.n_boundary_loops == 0
    assert dict(report.part_faces) == {"a": 4, "b": 4}


def test_validate_mesh_unused_vertex_counts_and_warns(tetrahedron):
    mesh = Mesh(np.concatenate([tetrahedron.vertices, [[0.5, 0.5, 0.5]]]), tetrahedron.faces)
    report = validate_mesh(mesh)
    assert report.n_unused_vertices == 1
    assert report.n_components == 1  # unused vertices are not components
    assert any("Delete Loose" in w for w in report.warnings)


def test_validate_mesh_out_of_range_face_is_error_not_crash(tetrahedron):
    faces = np.concatenate([tetrahedron.faces, [[0, 1, 9]]])
    report = validate_mesh(Mesh(tetrahedron.vertices, faces))
    assert report.n_out_of_range_faces == 1
    assert report.n_boundary_loops == 0  # the bad face is left out of topology
    assert not report.ok


def test_validate_mesh_empty_mesh_is_error():
    report = validate_mesh(Mesh(np.zeros((0, 3)), np.zeros((0, 3), np.int64)))
    assert report.n_components == 0
    assert any("empty" in e for e in report.errors)
    json.dumps(report.as_dict(), allow_nan=False)


def test_validate_mesh_part_with_missing_face_is_error(tetrahedron):
    report = validate_mesh(Mesh(tetrahedron.vertices, tetrahedron.faces, {"skin": [0, 7]}))
    assert any("part 'skin'" in e for e in report.errors)


def test_validate_mesh_scattered_triangles_are_pieces_not_seams():
    rng = np.random.default_rng(5)
    vertices = rng.random((60, 3)) * 20
    report = validate_mesh(Mesh(vertices, np.arange(60).reshape(-1, 3)))
    assert report.n_components == report.n_boundary_loops == 20
    assert report.n_seam_vertices == 0 and not any("seam" in w for w in report.warnings)


def test_validate_mesh_triangle_soup_names_its_seams():
    head = small_head()
    skin, _ = head.mesh.submesh("skin")
    soup = Mesh(skin.vertices[skin.faces.ravel()], np.arange(3 * skin.n_faces).reshape(-1, 3))
    report = validate_mesh(soup)
    assert report.n_seam_vertices == soup.n_vertices  # every corner lies on another face's corner
    (warning,) = [w for w in report.warnings if "unwelded seams" in w]
    assert (
        f"{soup.n_vertices:,} vertices" in warning
        and "around (" in warning
        and "Merge by Distance" in warning
    )


def test_validate_mesh_unwelded_patch_is_counted_and_located():
    head = small_head()
    mesh = unwelded_patch(head.mesh, cheek_centre(head))
    report = validate_mesh(mesh)
    border = mesh.n_vertices - head.mesh.n_vertices  # the patch's border vertices were duplicated
    assert report.n_seam_vertices == 2 * border
    (warning,) = [w for w in report.warnings if "unwelded seams" in w]
    centre = np.array([float(x) for x in warning.split("around (")[1].split(")")[0].split(",")])
    assert np.linalg.norm(centre - cheek_centre(head)) < 2.0  # cm: the warning says where the seam is


def test_validate_mesh_clean_heads_have_no_seams_or_reversed_faces():
    for mesh in (small_head().mesh, small_head(3).mesh):
        report = validate_mesh(mesh)
        assert report.n_seam_vertices == report.n_reversed_faces == 0
        assert report.warnings == ()


def test_validate_mesh_reports_a_reversed_patch_with_its_count():
    head = small_head()
    faces = head.mesh.faces.copy()
    patch = patch_faces(head.mesh, cheek_centre(head), 2.0)
    faces[patch] = faces[patch, ::-1]
    report = validate_mesh(Mesh(head.mesh.vertices, faces, head.mesh.parts))
    assert report.n_reversed_faces == len(patch)
    (warning,) = [w for w in report.warnings if "wind against" in w]
    assert f"{len(patch):,} faces" in warning and "[skin]" in warning


def test_validate_mesh_declared_units_disagreeing_with_size_warn(tetrahedron):
    scaled = Mesh(tetrahedron.vertices * 22, tetrahedron.faces, units="mm")  # 22 mm: size says cm
    report = validate_mesh(scaled)
    assert report.detected_units == "cm"
    assert any('units="cm"' in w for w in report.warnings)


def test_validate_mesh_implausible_size_warns_with_units_hint(tetrahedron):
    report = validate_mesh(tetrahedron.with_vertices(tetrahedron.vertices * 1e6))
    assert report.detected_units is None
    assert any("--units" in w for w in report.warnings)


def test_mesh_report_as_dict_is_json_safe_and_complete(tetrahedron):
    report = validate_mesh(
        Mesh(tetrahedron.vertices * 20, tetrahedron.faces, {"skin": [0, 1, 2, 3]}, units="cm")
    )
    data = json.loads(json.dumps(report.as_dict(), allow_nan=False))
    assert {f.name for f in dataclasses.fields(MeshReport)} | {"ok"} == set(data)
    assert data["part_faces"] == {"skin": 4}
    assert data["bbox_max"] == [20.0, 20.0, 20.0]
    assert data["ok"] is True


def test_mesh_report_lines_show_errors_and_warnings(tetrahedron):
    faces = np.concatenate([tetrahedron.faces, tetrahedron.faces[:1]])
    vertices = tetrahedron.vertices.copy()
    vertices[0, 0] = np.nan
    lines = validate_mesh(Mesh(vertices, faces)).lines()
    assert all(isinstance(line, str) for line in lines)
    assert lines[0].startswith("vertices")
    assert any(line.startswith("error: ") for line in lines)
    assert any(line.startswith("warning: ") and "duplicate" in line for line in lines)
    assert lines[-1].startswith("not usable")


def test_mesh_report_lines_label_part_sizes_as_face_counts():
    mesh = small_head().mesh
    (line,) = [line for line in validate_mesh(mesh).lines() if line.startswith("parts")]
    assert line.startswith("parts (faces) ")
    assert f"skin {len(mesh.parts['skin']):,}" in line


def test_mesh_report_is_frozen(tetrahedron):
    report = validate_mesh(tetrahedron)
    with pytest.raises(dataclasses.FrozenInstanceError):
        report.n_faces = 3  # type: ignore[misc]
    with pytest.raises(TypeError):
        report.part_faces["x"] = 1  # type: ignore[index]


def test_validate_mesh_does_not_change_the_mesh(tetrahedron):
    before_v, before_f = tetrahedron.vertices.copy(), tetrahedron.faces.copy()
    validate_mesh(tetrahedron)
    np.testing.assert_array_equal(tetrahedron.vertices, before_v)
    np.testing.assert_array_equal(tetrahedron.faces, before_f)


def test_mesh_report_as_dict_overflowing_extent_is_null(tetrahedron):
    vertices = np.array([[-1e308, 0, 0], [1e308, 0, 0], [0, 1, 0], [0, 0, 1]])  # extent overflows to inf
    report = validate_mesh(tetrahedron.with_vertices(vertices))
    assert report.extent == np.inf
    data = report.as_dict()
    assert data["extent"] is None
    json.dumps(data, allow_nan=False)


def test_validate_mesh_places_two_separate_seams_in_two_clusters():
    head = small_head()
    centre = cheek_centre(head)
    other = centre * np.array([-1.0, 1.0, 1.0])  # the other cheek
    mesh = unwelded_patch(unwelded_patch(head.mesh, centre), other)
    report = validate_mesh(mesh)
    (warning,) = [w for w in report.warnings if "unwelded seams" in w]
    places = warning.split(": ", 1)[1].split(". mimetic")[0].split("; ")
    assert len(places) == 2, warning
    centres = [np.array([float(x) for x in p.split("(")[1].split(")")[0].split(",")]) for p in places]
    found = sorted(centres, key=lambda c: c[0])
    expected = sorted([centre, other], key=lambda c: c[0])
    for got, want in zip(found, expected, strict=True):
        assert np.linalg.norm(got - want) < 2.0  # cm


def test_validate_mesh_of_a_real_head_soup_stays_small_in_memory():
    """ICT's head unwelded into a triangle soup (156,660 vertices): the seam locator used to list
    every pair of seam points within 5 % of the head (killed at 16 GiB); now well under 1 GiB."""
    from mimetic.testing import require_shared_data
    from mimetic.testing.memory import peak_rss

    folder = require_shared_data("ict-facekit")
    code = f"""
from pathlib import Path
from mimetic.mesh.validate import validate_mesh
from mimetic.testing import load_ict, triangle_soup
soup = triangle_soup(load_ict(Path({str(folder)!r}))[0])
report = validate_mesh(soup)
print(soup.n_vertices, report.n_seam_vertices)
"""
    measured = peak_rss(code)
    n_vertices, n_seam = map(int, measured.stdout.split())
    assert n_vertices == 156_660 and n_seam > 100_000
    assert measured.peak_gib < 1.0


def test_peak_rss_counts_the_child_not_the_large_caller():
    """The caller holds 1.5 GB; the measured child allocates 0.4 GB and is measured at that (the
    kernel's ru_maxrss would report the caller's size it forked from)."""
    from mimetic.testing.memory import peak_rss

    ballast = np.ones(200_000_000)  # 1.6 GB held by this process while the child runs
    measured = peak_rss("import numpy as np; a = np.ones(50_000_000); print(a.sum())")
    assert float(measured.stdout) == 50_000_000
    assert 0.35 < measured.peak_gib < 0.8
    del ballast


@pytest.mark.skipif(sys.platform != "linux", reason="RLIMIT_AS caps the address space on Linux")
def test_peak_rss_with_an_address_space_cap_fails_the_child_not_the_caller():
    """A child capped at 1 GiB that asks for 2 GiB raises MemoryError in itself; the caller gets a
    RuntimeError naming it, and a child within its cap is measured as without one."""
    from mimetic.testing.memory import peak_rss

    with pytest.raises(RuntimeError, match="MemoryError"):
        peak_rss("import numpy as np; a = np.ones(2**28); print(a.sum())", max_address_space=2**30)
    measured = peak_rss("import numpy as np; a = np.ones(2**24); print(a.sum())", max_address_space=2**30)
    assert float(measured.stdout) == 2**24
    assert 0.1 < measured.peak_gib < 1.0
