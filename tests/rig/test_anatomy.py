"""Tests for mimetic.rig.anatomy: creases, skull, lip contact, accessories and tissue thickness,
derived by rule on generated heads (whose anatomy is known by construction) and across seams."""

from __future__ import annotations

import numpy as np
import pytest

from mimetic.fit.pipeline import rig_head
from mimetic.mesh.geometry import vertex_normals
from mimetic.rig.anatomy import derive_anatomy, lip_contact, tissue_normals
from mimetic.rig.anatomy.tissue import REGION_THICKNESS_REL
from mimetic.testing import cheek_centre, head_landmarks, small_head, small_rig, unwelded_patch


@pytest.fixture(scope="module")
def rig():
    return small_rig()


def test_rig_anatomy_is_derived_by_rule_and_frozen(rig):
    again = derive_anatomy(
        rig.mesh, rig.landmarks, rig.regions, rig.skin_weights, rig.scale, rig.channel_names
    )
    assert len(again.creases) == len(rig.anatomy.creases)
    for a, b in zip(again.creases, rig.anatomy.creases, strict=True):
        np.testing.assert_array_equal(a.offsets_rel, b.offsets_rel)
    with pytest.raises(ValueError):
        rig.anatomy.thickness_rel[0] = 1.0


def test_creases_sink_inward_and_are_driven_by_their_muscles(rig):
    v = rig.mesh.vertices
    skin = rig.mesh.faces[rig.mesh.parts["skin"]]
    normals = tissue_normals(v, skin, lip_contact(v, rig.regions, rig.scale), rig.scale)
    raw = vertex_normals(v, skin)
    assert (
        np.einsum("kd,kd->k", normals, raw)[np.unique(skin)] > 0.5
    ).mean() > 0.95  # the skin's, smoothed (measured 0.98)
    driven = set()
    for crease in rig.anatomy.creases:
        inward = np.einsum("kd,kd->k", crease.offsets_rel, normals[crease.vertices])
        assert np.all(inward < 0), crease.name
        assert np.linalg.norm(crease.offsets_rel, axis=1).max() <= 0.008  # the deepest fold's depth
        driven |= set(crease.gains)
    for channel in (
        "frontalis_inner_L",
        "corrugator_R",
        "procerus",
        "orbicularis_oculi_outer_L",
        "zygomatic_major_R",
    ):
        assert channel in driven, channel


def test_nasolabial_fold_stays_clear_of_the_lips(rig):
    """The fold ends at the modiolus: no lip vertex sinks, and the skin within 4 mm of the lips sinks
    less than the fold's depth (the default head's corner slivers flipped under it)."""
    from mimetic.rig.anatomy.creases import NASOLABIAL_CLEAR_REL, NASOLABIAL_DEPTH_REL

    lips = np.union1d(rig.regions["upper_lip"], rig.regions["lower_lip"])
    v = rig.mesh.vertices
    for side in "LR":
        (fold,) = [c for c in rig.anatomy.creases if c.name == f"nasolabial_{side}"]
        assert not np.isin(fold.vertices, lips).any()
        depth = np.linalg.norm(fold.offsets_rel, axis=1)
        near = np.linalg.norm(v[fold.vertices, None] - v[lips][None], axis=2).min(axis=1)
        close = near < 0.5 * NASOLABIAL_CLEAR_REL * rig.scale
        assert close.any() and depth[close].max() < 0.6 * NASOLABIAL_DEPTH_REL
        assert depth.max() > 0.5 * NASOLABIAL_DEPTH_REL  # it still folds away from them


def test_skull_lies_under_the_forehead(rig):
    skull = rig.anatomy.skull
    np.testing.assert_array_equal(skull.vertices, rig.regions["forehead"])
    assert np.all(skull.surface[:, 2] <= rig.mesh.vertices[skull.vertices, 2])


def test_lip_contact_pairs_touch_and_sit_on_their_lips(rig):
    pairs = rig.anatomy.lip_contact
    assert pairs.shape[1] == 2 and len(pairs) >= 5
    assert np.isin(pairs[:, 0], rig.regions["upper_lip"]).all()
    assert np.isin(pairs[:, 1], rig.regions["lower_lip"]).all()
    v = rig.mesh.vertices
    np.testing.assert_allclose(v[pairs[:, 0]], v[pairs[:, 1]], atol=1e-9 * rig.scale)


def test_tissue_is_thin_on_the_lids_and_thick_on_the_cheeks(rig):
    t = rig.anatomy.thickness_rel
    lids = np.concatenate([rig.regions[f"eyelid_upper_{s}"] for s in "LR"])
    cheeks = np.concatenate([rig.regions[f"cheek_{s}"] for s in "LR"])
    assert np.median(t[lids]) < 0.5 * np.median(t[cheeks])
    assert t.max() <= max(REGION_THICKNESS_REL.values()) and t[rig.mesh.part_vertices("eye_L")].max() == 0.0
    assert 0.005 < np.median(t[cheeks]) * rig.scale / 1.0 < 2.5  # 0.05-2.5 cm on a 22 cm head


def test_generated_heads_carry_no_accessories(rig):
    assert len(rig.anatomy.accessories) == 0


def test_anatomy_across_an_unwelded_seam_gives_every_copy_the_same_data():
    head = small_head(2)
    mesh = unwelded_patch(head.mesh, cheek_centre(head), radius=3.0)
    anatomy = rig_head(mesh, head_landmarks(head)).rig.anatomy
    n = head.mesh.n_vertices
    twins = {}  # each copy appended by unwelded_patch -> the original vertex it lies on
    for k in range(n, mesh.n_vertices):
        (twin,) = np.flatnonzero(np.all(mesh.vertices[:n] == mesh.vertices[k], axis=1))
        twins[k] = int(twin)
    assert len(twins) > 10
    t = anatomy.thickness_rel
    assert all(t[k] == t[twin] for k, twin in twins.items())
    for crease in anatomy.creases:
        on = dict(zip(crease.vertices.tolist(), map(tuple, crease.offsets_rel), strict=True))
        assert all(on.get(k) == on.get(twin) for k, twin in twins.items()), crease.name
    assert len(anatomy.accessories) == 0  # the cut patch is skin, not a piece riding it


def test_closing_pivot_sets_back_only_as_far_as_a_tall_opening_needs():
    """Margins on a circle of radius 1 about the eye's centre (origin; frame axes = world): an
    opening of ±30° closes within 0.85 × 0.75 rad only from behind the centre, and exactly at the
    reserve; one of ±15° keeps the centre."""
    from mimetic.rig.anatomy.lids import CLOSING_RESERVE, LidRims, closing_pivot

    def rims(half_angle: float) -> tuple[LidRims, np.ndarray]:
        u = np.linspace(0.2, 0.8, 7)
        up = np.column_stack([u, np.full(7, np.sin(half_angle)), np.full(7, np.cos(half_angle))])
        low = up * np.array([1.0, -1.0, 1.0])
        vertices = np.vstack([up, low])
        upper, lower = np.arange(7), np.arange(7, 14)
        empty = np.zeros(0, dtype=np.int64)
        return LidRims(np.zeros(3), np.eye(3), 1.0, (upper, empty), (lower, empty), (upper, empty)), vertices

    centre = np.zeros(3)
    short, vertices = rims(np.radians(15))
    np.testing.assert_array_equal(closing_pivot(short, vertices, centre, 0.75), centre)
    tall, vertices = rims(np.radians(30))
    pivot = closing_pivot(tall, vertices, centre, 0.75)
    assert pivot[0] == 0 and pivot[1] == 0 and pivot[2] < 0
    seen = 2 * np.arctan2(np.sin(np.radians(30)), np.cos(np.radians(30)) - pivot[2])
    assert seen == pytest.approx(CLOSING_RESERVE * 0.75, abs=1e-6)
