"""``Material`` and ``Mesh.materials``: validation, and materials riding along a deformation."""

from __future__ import annotations

import numpy as np
import pytest

from mimetic.mesh.model import Material, Mesh


def test_material_transparent_below_half_opacity():
    assert Material("film", opacity=0.49).transparent
    assert not Material("skin", (0.8, 0.6, 0.5), 0.5).transparent
    assert Material("skin", [0.8, 0.6, 0.5]).color == (0.8, 0.6, 0.5)  # any sequence → a tuple


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [({"opacity": 1.5}, "opacity"), ({"color": (1.2, 0, 0)}, "color"), ({"color": (0.5, 0.5)}, "color")],
)
def test_material_out_of_range_values_raise(kwargs, message):
    with pytest.raises(ValueError, match=message):
        Material("bad", **kwargs)


def test_mesh_materials_must_belong_to_parts(tetrahedron):
    with pytest.raises(ValueError, match="not a part"):
        Mesh(tetrahedron.vertices, tetrahedron.faces, {"a": [0]}, materials={"b": Material("b")})
    with pytest.raises(ValueError, match="must be a Material"):
        Mesh(tetrahedron.vertices, tetrahedron.faces, {"a": [0]}, materials={"a": (1, 1, 1)})


def test_mesh_with_vertices_keeps_materials_and_they_are_read_only(tetrahedron):
    mesh = Mesh(
        tetrahedron.vertices,
        tetrahedron.faces,
        {"film": [0, 1]},
        materials={"film": Material("f", None, 0.1)},
    )
    moved = mesh.with_vertices(mesh.vertices + 1.0)
    assert moved.materials == {"film": Material("f", None, 0.1)}
    np.testing.assert_array_equal(moved.parts["film"], [0, 1])
    with pytest.raises(TypeError):
        moved.materials["skin"] = Material("skin")  # type: ignore[index]
