"""Tests for mimetic.rig.model (data types, accessors, equality) and mimetic.rig.validate."""

from __future__ import annotations

import dataclasses
import math
from types import MappingProxyType

import numpy as np
import pytest
import scipy.sparse as sp
import trimesh
from hypothesis import given
from hypothesis import strategies as st

from mimetic.errors import MimeticError, RigError
from mimetic.mesh.model import Mesh, SurfacePoint, surface_positions
from mimetic.rig import Bone, Channel, Muscle, Rig, Wire, rig_differences, rigs_equal, validate_rig

POINT = SurfacePoint(0, (0.2, 0.3, 0.5))
OTHER = SurfacePoint(5, (1.0, 0.0, 0.0))


def muscle(**changes) -> Muscle:
    fields = dict(
        name="zygomatic_major_L",
        kind="linear",
        side="L",
        origin=POINT,
        insertion=OTHER,
        width_rel=0.05,
        falloff_start_rel=0.3,
        falloff_end_rel=1.2,
        angle_rad=0.6,
    )
    return Muscle(**{**fields, **changes})


def wire(**changes) -> Wire:
    fields = dict(
        name="mouth_upper_L",
        side="L",
        points=(POINT, OTHER, POINT),
        dropoff_rel=0.1,
        vertices=np.array([1, 4, 9]),
        muscle_weights={"zygomatic_major_L": np.array([0.2, 1.0, 0.2])},
        rest_weight=np.array([1.0, 1.0, 1.0]),
    )
    return Wire(**{**fields, **changes})


# --------------------------------------------------------------------------- construction


def test_rig_valid_inputs_builds_frozen_readonly_rig(rig):
    n, m = rig.mesh.n_vertices, rig.mesh.n_faces
    assert (n, m) == (162, 320)
    assert rig.skin_weights.shape == (n, len(rig.bones)) and rig.skin_weights.dtype == np.float64
    assert isinstance(rig.skin_weights, sp.csr_matrix)
    for region in rig.regions.values():
        assert region.dtype == np.int64 and region.ndim == 1
        assert not region.flags.writeable
    for w in rig.wires:
        assert w.vertices.dtype == np.int64 and not w.vertices.flags.writeable
        assert w.rest_weight.shape == (len(w.points),) and w.rest_weight.dtype == np.float64
        assert all(not a.flags.writeable for a in w.muscle_weights.values())
    for b in rig.bones:
        assert b.head.shape == (3,) and b.head.dtype == np.float64 and not b.tail.flags.writeable
    for array in (rig.skin_weights.data, rig.skin_weights.indices, rig.skin_weights.indptr):
        assert not array.flags.writeable
    with pytest.raises(dataclasses.FrozenInstanceError):
        rig.scale = 3.0
    with pytest.raises(TypeError):
        rig.regions["new"] = np.arange(3)
    with pytest.raises(ValueError, match="read-only"):
        rig.skin_weights.data[0] = 2.0


def test_rig_metadata_is_deep_frozen(rig):
    assert isinstance(rig.metadata, MappingProxyType)
    assert isinstance(rig.metadata["recipe"], MappingProxyType)
    assert rig.metadata["recipe"]["params"] == (1, 2.5, None, True)


def test_rig_caller_arrays_are_copied_not_shared(rig):
    base = rig
    region = np.arange(0, 20, dtype=np.int64)
    rest = np.ones(3)
    weights = base.skin_weights.copy()
    w = wire(name="w", muscle_weights={}, rest_weight=rest)
    rebuilt = dataclasses.replace(base, regions={"r": region}, wires=(w,), muscles=(), skin_weights=weights)
    region[0] = 99
    rest[0] = -5.0
    weights.data[0] = 7.0
    assert rebuilt.regions["r"][0] == 0
    assert rebuilt.wires[0].rest_weight[0] == 1.0
    assert rebuilt.skin_weights.data[0] != 7.0


def test_rig_skin_weights_duplicates_and_zeros_are_stored_canonically(rig):
    dense = rig.skin_weights.toarray()
    coo = sp.coo_matrix(dense)
    zeros = np.zeros(3)
    # every entry split in two halves, plus three explicit zeros
    messy = sp.coo_matrix(
        (
            np.r_[coo.data / 2, coo.data / 2, zeros],
            (np.r_[coo.row, coo.row, 0, 1, 2], np.r_[coo.col, coo.col, 0, 0, 0]),
        ),
        shape=coo.shape,
    )
    rebuilt = dataclasses.replace(rig, skin_weights=messy)
    assert isinstance(rebuilt.skin_weights, sp.csr_matrix)
    assert rebuilt.skin_weights.has_canonical_format
    assert rebuilt.skin_weights.nnz == np.count_nonzero(dense)
    np.testing.assert_allclose(rebuilt.skin_weights.toarray(), dense, rtol=0, atol=1e-15)


def test_rig_bad_element_type_raises_rig_error_naming_field(rig):
    with pytest.raises(RigError, match=r"muscles\[1\] must be a Muscle"):
        dataclasses.replace(rig, muscles=(rig.muscles[0], "oops"))
    with pytest.raises(RigError, match=r"mesh must be a mimetic\.mesh\.Mesh"):
        dataclasses.replace(rig, mesh=None)


# --------------------------------------------------------------------------- accessors


def test_rig_accessors_find_elements_by_name(rig):
    assert rig.channel_names == tuple(c.name for c in rig.channels)
    assert len(rig.channel_names) == len(rig.muscles) + 2
    for i, b in enumerate(rig.bones):
        assert rig.bone_index(b.name) == i
        assert rig.bone(b.name) is b
    for mu in rig.muscles:
        assert rig.muscle(mu.name) is mu
        assert rig.channel(mu.name).unit == "activation"
        assert rig.channel_names[rig.channel_index(mu.name)] == mu.name
    assert rig.wire(rig.wires[1].name) is rig.wires[1]
    with pytest.raises(KeyError, match="no muscle 'nope'"):
        rig.muscle("nope")
    with pytest.raises(KeyError, match="no bone"):
        rig.bone_index("nope")


def test_rig_landmark_positions_match_surface_positions(rig):
    names = list(rig.landmarks)
    expected = surface_positions([rig.landmarks[k] for k in names], rig.mesh.vertices, rig.mesh.faces)
    got = rig.landmark_positions()
    assert got.shape == (len(names), 3) and got.dtype == np.float64
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)
    some = rig.landmark_positions(names[2:0:-1])
    assert some.shape == (2, 3)
    np.testing.assert_allclose(some, expected[[2, 1]], rtol=0, atol=1e-12)
    assert rig.landmark_positions([]).shape == (0, 3)
    with pytest.raises(KeyError, match="landmark"):
        rig.landmark_positions(["nope"])


def test_rig_muscle_attachment_scales_origin_about_bbox_centre(rig):
    v = rig.mesh.vertices
    centre = (v.min(axis=0) + v.max(axis=0)) / 2
    assert rig.centre.shape == (3,)
    np.testing.assert_allclose(rig.centre, centre, rtol=0, atol=1e-12)
    for mu in rig.muscles:
        origin = mu.origin.position(v, rig.mesh.faces)
        expected = centre + (1 - mu.origin_inset_rel) * (origin - centre)
        got = rig.muscle_attachment(mu.name)
        assert got.shape == (3,)
        np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9)


# --------------------------------------------------------------------------- element checks


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"width_rel": 0.0}, "width_rel"),
        ({"width_rel": -1.0}, "width_rel"),
        ({"falloff_start_rel": 1.0}, "falloff_start_rel"),
        ({"falloff_start_rel": -0.1}, "falloff_start_rel"),
        ({"falloff_end_rel": 0.3}, "falloff_end_rel"),
        ({"angle_rad": 0.0}, "angle_rad"),
        ({"angle_rad": math.pi + 1e-9}, "angle_rad"),
        ({"angle_rad": float("nan")}, "angle_rad"),
        ({"origin_inset_rel": 1.0}, "origin_inset_rel"),
        ({"kind": "circular"}, "kind"),
        ({"side": "left"}, "side"),
        ({"name": ""}, "name"),
        ({"reversed": "yes"}, "reversed"),
        ({"width_rel": "wide"}, "width_rel"),
        ({"origin": SurfacePoint(0, (0.5, 0.5, 0.5))}, "origin.bary"),
        ({"insertion": SurfacePoint(0, (1.5, -0.5, 0.0))}, "insertion.bary"),
        ({"insertion": SurfacePoint(-1, (1.0, 0.0, 0.0))}, "insertion.face"),
        ({"origin": (0, (1.0, 0.0, 0.0))}, "origin must be a SurfacePoint"),
    ],
)
def test_muscle_out_of_range_field_raises_rig_error_naming_it(changes, field):
    with pytest.raises(RigError, match=r"^muscle '") as info:
        muscle(**changes)
    assert field in str(info.value)
    assert isinstance(info.value, (MimeticError, ValueError))


def test_muscle_numpy_scalars_are_coerced_to_python_types():
    m = muscle(origin=SurfacePoint(np.int64(3), np.array([0.25, 0.25, 0.5])), width_rel=np.float32(0.5))
    assert type(m.origin.face) is int and m.origin.bary == (0.25, 0.25, 0.5)
    assert type(m.width_rel) is float


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"points": (POINT,)}, "points has 1 point"),
        ({"rest_weight": np.ones(2)}, "rest_weight has shape (2,)"),
        ({"muscle_weights": {"zygomatic_major_L": np.ones(4)}}, "muscle_weights['zygomatic_major_L']"),
        ({"muscle_weights": {"m": np.array([0.0, -1.0, 0.0])}}, "negative"),
        ({"rest_weight": np.array([0.0, 1.0, 1.0]), "muscle_weights": {}}, "control point 0"),
        ({"vertices": np.array([4, 1, 9])}, "sorted and unique"),
        ({"vertices": np.array([1, 1, 9])}, "sorted and unique"),
        ({"vertices": np.array([1.5, 2.0])}, "integer indices"),
        ({"dropoff_rel": 0.0}, "dropoff_rel"),
        ({"side": "X"}, "side"),
    ],
)
def test_wire_inconsistent_field_raises_rig_error_naming_it(changes, field):
    with pytest.raises(RigError, match="wire 'mouth_upper_L'") as info:
        wire(**changes)
    assert field in str(info.value)


@pytest.mark.parametrize(
    ("args", "field"),
    [
        (("c", 1.0, 0.0), "minimum"),
        (("c", 0.0, 0.0), "minimum"),
        (("c", 0.0, 1.0, 2.0), "default"),
        (("c", 0.0, 1.0, 0.0, "deg"), "unit"),
        (("c", 0.0, float("inf")), "maximum"),
        (("", 0.0, 1.0), "name"),
    ],
)
def test_channel_bad_range_raises_rig_error_naming_field(args, field):
    with pytest.raises(RigError, match=field):
        Channel(*args)


@given(
    low=st.floats(-10, 10),
    width=st.floats(1e-6, 10),
    t=st.floats(0, 1),
)
def test_channel_any_consistent_range_is_accepted(low, width, t):
    high = low + width
    default = min(max(low + t * (high - low), low), high)
    c = Channel("c", low, high, default, "rad", "jaw")
    assert c.minimum < c.maximum and c.minimum <= c.default <= c.maximum


def test_bone_zero_length_or_bad_shape_raises_rig_error():
    with pytest.raises(RigError, match=r"bone 'jaw'.*needs a length"):
        Bone("jaw", "head", np.zeros(3), np.zeros(3))
    with pytest.raises(RigError, match=r"bone 'jaw'.head must have shape \(3,\)"):
        Bone("jaw", "head", np.zeros(2), np.ones(3))
    with pytest.raises(RigError, match=r"bone 'jaw'\.tail.*finite"):
        Bone("jaw", "head", np.zeros(3), np.array([0.0, np.nan, 1.0]))
    with pytest.raises(RigError, match="parent is the bone itself"):
        Bone("jaw", "jaw", np.zeros(3), np.ones(3))


# --------------------------------------------------------------------------- validate_rig


def _replace_muscle(rig: Rig, i: int, **changes) -> dict:
    muscles = list(rig.muscles)
    muscles[i] = dataclasses.replace(muscles[i], **changes)
    return {"muscles": tuple(muscles)}


def _replace_wire(rig: Rig, i: int, **changes) -> dict:
    wires = list(rig.wires)
    wires[i] = dataclasses.replace(wires[i], **changes)
    return {"wires": tuple(wires)}


def _with_weights(rig: Rig, edit) -> dict:
    dense = rig.skin_weights.toarray()
    edit(dense)
    return {"skin_weights": sp.csr_matrix(dense)}


def _bones(rig: Rig, *parents) -> dict:
    bones = tuple(dataclasses.replace(b, parent=p) for b, p in zip(rig.bones, parents, strict=True))
    return {"bones": bones}


def _first_landmark(rig: Rig) -> str:
    return next(iter(rig.landmarks))


INCONSISTENCIES = {
    "muscle origin face": (
        lambda r: _replace_muscle(r, 0, origin=SurfacePoint(99999, (1.0, 0.0, 0.0))),
        ["muscles[0] 'linear_", ".origin.face=99999 is out of range (the mesh has 320 faces)"],
    ),
    "wire point face": (
        lambda r: _replace_wire(
            r, 1, points=(r.wires[1].points[0], SurfacePoint(320, (1.0, 0.0, 0.0)), *r.wires[1].points[2:])
        ),
        ["wires[1]", ".points[1].face=320 is out of range"],
    ),
    "landmark face": (
        lambda r: {"landmarks": {**r.landmarks, "chin": SurfacePoint(400, (1.0, 0.0, 0.0))}},
        ["landmarks['chin'].face=400"],
    ),
    "region out of range": (
        lambda r: {"regions": {**r.regions, "lips": np.array([0, 5, 162])}},
        ["regions['lips']", "index 162", "162 vertices"],
    ),
    "region unsorted": (
        lambda r: {"regions": {**r.regions, "lips": np.array([5, 0])}},
        ["regions['lips']", "sorted and unique"],
    ),
    "muscle without channel": (
        lambda r: {"channels": tuple(c for c in r.channels if c.name != r.muscles[2].name)},
        ["muscles[2] 'sphincter_", "no channel of the same name", "Channel("],
    ),
    "muscle channel unit": (
        lambda r: {
            "channels": tuple(
                dataclasses.replace(c, unit="rad") if c.name == r.muscles[1].name else c for c in r.channels
            )
        },
        ["muscles[1]", "unit='rad'"],
    ),
    "muscle unknown region": (
        lambda r: _replace_muscle(r, 3, region="cheeks"),
        ["muscles[3]", ".region='cheeks' is not in regions"],
    ),
    "muscle zero length": (
        lambda r: _replace_muscle(r, 0, insertion=r.muscles[0].origin),
        ["muscles[0]", "same point"],
    ),
    "duplicate muscle": (
        lambda r: {"muscles": (*r.muscles, r.muscles[0])},
        ["muscles[4]", "same name as muscles[0]"],
    ),
    "duplicate channel": (
        lambda r: {"channels": (*r.channels, r.channels[1])},
        ["channels[6]", "same name"],
    ),
    "wire unknown muscle": (
        lambda r: _replace_wire(
            r,
            0,
            muscle_weights={"frontalis": np.ones(len(r.wires[0].points))},
            rest_weight=r.wires[0].rest_weight,
        ),
        ["wires[0]", ".muscle_weights['frontalis'] names no muscle"],
    ),
    "wire vertices out of range": (
        lambda r: _replace_wire(r, 0, vertices=np.array([3, 500])),
        ["wires[0]", ".vertices has index 500"],
    ),
    "skin weights shape": (
        lambda r: {"skin_weights": sp.csr_matrix(np.c_[r.skin_weights.toarray(), np.zeros(162)])},
        ["skin_weights has shape (162, 5)", "(162, 4)"],
    ),
    "skin weights negative": (
        lambda r: _with_weights(r, lambda d: d.__setitem__((3, slice(None)), [1.5, -0.5, 0.0, 0.0])),
        ["skin_weights row 3", "negative"],
    ),
    "skin weights sum": (
        lambda r: _with_weights(r, lambda d: d.__setitem__(7, d[7] * 0.9)),
        ["skin_weights row 7", "sum", "to 1"],
    ),
    "skin weights unweighted vertex": (
        lambda r: _with_weights(r, lambda d: d.__setitem__(0, 0.0)),
        ["skin_weights row 0", "sums to 0"],
    ),
    "skin weights five bones": (
        lambda r: {
            **_bones_plus_one(r),
            "skin_weights": sp.csr_matrix(np.full((162, 5), 0.2)),
        },
        ["skin_weights row 0", "5 non-zero", "at most 4"],
    ),
    "bone unknown parent": (
        lambda r: _bones(r, None, "skull", r.bones[0].name, r.bones[0].name),
        ["bones[1]", ".parent='skull' is not a bone"],
    ),
    "bone parent after child": (
        lambda r: _bones(r, None, r.bones[3].name, r.bones[0].name, r.bones[0].name),
        ["bones[1]", "listed after it (bones[3])", "before its children"],
    ),
    "two roots": (
        lambda r: _bones(r, None, None, r.bones[0].name, r.bones[0].name),
        ["single root", "found roots"],
    ),
    "no bones": (
        lambda r: {"bones": (), "skin_weights": sp.csr_matrix((162, 0))},
        ["bones is empty"],
    ),
    "units": (lambda r: {"units": "inch"}, ["units='inch'", "mm, cm, dm, m"]),
    "scale zero": (lambda r: {"scale": 0.0}, ["scale=0.0", "> 0"]),
    "scale nan": (lambda r: {"scale": float("nan")}, ["scale=nan", "finite"]),
    "mesh units mismatch": (
        lambda r: {"mesh": Mesh(r.mesh.vertices, r.mesh.faces, r.mesh.parts, r.mesh.colors, "cm")},
        ["mesh.units='cm' differs from units='mm'"],
    ),
    "metadata not json": (
        lambda r: {"metadata": {"fit": {"residuals": {1, 2}}}},
        ["metadata.fit.residuals", "not JSON-safe"],
    ),
    "metadata nan": (lambda r: {"metadata": {"error": float("nan")}}, ["metadata.error=nan"]),
}


def _bones_plus_one(rig: Rig) -> dict:
    extra = Bone("extra", rig.bones[0].name, np.zeros(3), np.ones(3))
    return {"bones": (*rig.bones, extra)}


@pytest.mark.parametrize("case", list(INCONSISTENCIES))
def test_validate_rig_inconsistency_raises_rig_error_naming_field(rig, case):
    edit, expected = INCONSISTENCIES[case]
    with pytest.raises(RigError) as info:
        dataclasses.replace(rig, **edit(rig))
    message = str(info.value)
    for part in expected:
        assert part in message, f"{part!r} not in {message!r}"


def test_validate_rig_rechecks_elements_changed_behind_its_back(rig_builder):
    rig = rig_builder(2)  # a private rig: this test mutates it
    validate_rig(rig)
    object.__setattr__(rig.muscles[1], "width_rel", -1.0)  # bypass the frozen dataclass
    with pytest.raises(RigError, match=r"muscles\[1\] 'linear_\d+'.width_rel=-1.0 must be > 0"):
        validate_rig(rig)


def test_validate_rig_large_mesh_accepts_valid_rig(rig_builder):
    """A 10k-vertex rig validates (speed is measured in benchmarks, not asserted here)."""
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=100.0)
    mesh = Mesh(sphere.vertices, sphere.faces, {"skin": np.arange(len(sphere.faces))}, None, "mm")
    n = mesh.n_vertices
    small = rig_builder(3)
    weights = sp.csr_matrix((np.ones(n), (np.arange(n), np.zeros(n, dtype=np.int64))), shape=(n, 4))
    big = dataclasses.replace(small, mesh=mesh, skin_weights=weights, anatomy=None)
    validate_rig(big)
    assert big.skin_weights.shape == (n, 4)


# --------------------------------------------------------------------------- equality


def test_rigs_equal_identical_rebuild_is_equal(rig, rig_builder):
    again = rig_builder(0)
    assert again is not rig
    assert rigs_equal(rig, again) and rig == again
    assert rig_differences(rig, again) == []


def test_rigs_equal_one_changed_bit_is_not_equal(rig):
    vertices = rig.mesh.vertices.copy()
    vertices[10, 2] = np.nextafter(vertices[10, 2], np.inf)
    other = dataclasses.replace(rig, mesh=rig.mesh.with_vertices(vertices))
    assert not rigs_equal(rig, other)
    assert rig_differences(rig, other)[0].startswith("mesh.vertices")


def test_rigs_equal_reordered_landmarks_is_not_equal(rig):
    reordered = dict(reversed(list(rig.landmarks.items())))
    other = dataclasses.replace(rig, landmarks=reordered)
    assert rig != other
    assert "landmarks" in rig_differences(rig, other)[0]


def test_rigs_equal_metadata_int_vs_float_is_not_equal(rig):
    as_int = dataclasses.replace(rig, metadata={"count": 1})
    as_float = dataclasses.replace(rig, metadata={"count": 1.0})
    assert as_int != as_float
    assert rig_differences(as_int, as_float) == ["metadata: differs"]


def test_wire_and_bone_equality_is_bitwise():
    assert wire() == wire()
    assert wire() != wire(rest_weight=np.array([1.0, 1.0, np.nextafter(1.0, 2.0)]))
    assert Bone("a", None, np.zeros(3), np.ones(3)) == Bone("a", None, np.zeros(3), np.ones(3))
    assert Bone("a", None, np.zeros(3), np.ones(3)) != Bone("a", None, -np.zeros(3), np.ones(3))


@given(seed=st.integers(0, 2**32 - 1), n_bones=st.integers(1, 6), n_wires=st.integers(0, 3))
def test_rig_random_valid_inputs_build_and_equal_their_rebuild(rig_builder, seed, n_bones, n_wires):
    a = rig_builder(seed, n_bones=n_bones, n_wires=n_wires)
    b = rig_builder(seed, n_bones=n_bones, n_wires=n_wires)
    assert a.skin_weights.shape == (a.n_vertices, n_bones)
    np.testing.assert_allclose(np.asarray(a.skin_weights.sum(axis=1)).ravel(), 1.0, rtol=0, atol=1e-12)
    assert a == b


def test_rig_repr_is_one_line_summary(rig):
    assert repr(rig) == (
        "Rig(162 vertices, 320 faces, 4 muscles, 2 wires, 4 bones, 6 channels, units='mm', scale=200)"
    )


def test_rig_metadata_numpy_scalars_become_python_values(rig):
    other = dataclasses.replace(rig, metadata={"n": np.int64(3), "x": np.float32(0.5), "ok": np.bool_(True)})
    assert [type(v) for v in other.metadata.values()] == [int, float, bool]
    assert dict(other.metadata) == {"n": 3, "x": 0.5, "ok": True}
