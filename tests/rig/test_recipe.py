"""Tests for mimetic.rig.recipe: ``build_rig`` on generated heads."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from mimetic.head.topology import build_topology
from mimetic.rig import Rig, load_rig, rig_differences, save_rig, validate_rig
from mimetic.rig.bones import BONES, CORNER_JAW
from mimetic.rig.recipe import build_rig
from mimetic.rig.validate import MAX_INFLUENCES
from mimetic.testing import SMALL_RESOLUTION, small_head, small_rig

FLIP_X = np.array([-1.0, 1.0, 1.0])
SEEDS = [pytest.param(None, id="default"), pytest.param(0, id="seed=0"), pytest.param(1, id="seed=1")]

THESIS_PAIRED = (
    "frontalis_inner",
    "frontalis_outer",
    "corrugator",
    "orbicularis_oculi_inner",
    "orbicularis_oculi_outer",
    "levator_labii_nasal",
    "levator_labii_mid",
    "zygomatic_major",
    "risorius",
    "triangularis",
    "orbicularis_oris_incisivis",
    "depressor_labii",
)
THESIS_CENTRAL = ("procerus", "mentalis")
EXTRA_PAIRED = ("zygomatic_minor", "buccinator", "levator_palpebrae", "platysma")
SPHINCTERS = ("orbicularis_oris", "orbicularis_oculi_L", "orbicularis_oculi_R")
MODIOLUS = ("zygomatic_major", "risorius", "buccinator", "triangularis", "orbicularis_oris_incisivis")
WIRES_PAIRED = (
    "forehead",
    "eyebrow",
    "nose",
    "cheek",
    "nasolabial",
    "mouth_upper_corner",
    "mouth_lower_corner",
)
WIRES_CENTRAL = ("mouth_upper_center", "mouth_lower_center")


def thesis_names() -> list[str]:
    return [f"{m}_{s}" for m in THESIS_PAIRED for s in "LR"] + list(THESIS_CENTRAL)


def point_position(rig: Rig, point) -> np.ndarray:
    return point.position(rig.mesh.vertices, rig.mesh.faces)


def weights(rig: Rig) -> np.ndarray:
    """Dense skin weights (n, bones)."""
    return rig.skin_weights.toarray()


@pytest.mark.parametrize("seed", SEEDS)
def test_build_rig_gives_a_valid_rig(seed):
    head = small_head(seed)
    rig = small_rig(seed)
    assert isinstance(rig, Rig)
    assert validate_rig(rig) is None
    assert rig.mesh is head.mesh and rig.units == "cm"
    assert (len(rig.muscles), len(rig.wires), len(rig.bones)) == (37, 16, 8)
    skin_top = head.vertices[: head.n_skin, 1].max()
    assert rig.scale == pytest.approx(skin_top - head.vertices[head.landmarks["menton"], 1])
    assert 18.0 < rig.scale < 30.0, "a head height in cm"
    assert rig.metadata["resolution"] == SMALL_RESOLUTION
    assert dict(rig.metadata["params"]) == head.params.as_dict()
    assert list(rig.landmarks) == list(head.landmarks)
    for name, vertex in head.landmarks.items():
        np.testing.assert_array_equal(point_position(rig, rig.landmarks[name]), head.vertices[vertex])


def test_build_rig_leaves_the_head_unchanged():
    head = small_head(2)
    vertices = head.vertices.copy()
    landmarks = dict(head.landmarks)
    regions = {k: v.copy() for k, v in head.regions.items()}
    mirror, centres = head.mirror.copy(), head.eye_centres.copy()
    build_rig(head)
    assert np.array_equal(head.vertices, vertices)
    assert dict(head.landmarks) == landmarks
    assert list(head.regions) == list(regions)
    assert all(np.array_equal(head.regions[k], v) for k, v in regions.items())
    assert np.array_equal(head.mirror, mirror) and np.array_equal(head.eye_centres, centres)


def test_build_rig_has_every_thesis_muscle_and_the_extras():
    rig = small_rig()
    names = set(rig.muscle_names)
    assert len(names) == len(rig.muscles), "unique names"
    missing = [n for n in thesis_names() if n not in names]
    assert not missing, f"thesis muscles missing: {missing}"
    extras = [f"{m}_{s}" for m in EXTRA_PAIRED for s in "LR"] + list(SPHINCTERS)
    assert not [n for n in extras if n not in names]
    assert len(thesis_names()) == 26
    kinds = {m.name: m.kind for m in rig.muscles}
    assert sum(kind == "linear" for kind in kinds.values()) >= 26
    assert all(kinds[n] == "sphincter" for n in SPHINCTERS)
    assert all(kinds[n] == "linear" for n in thesis_names())
    for muscle in rig.muscles:
        expected = muscle.name[-1] if muscle.name.endswith(("_L", "_R")) else "C"
        assert muscle.side == expected, muscle.name


def test_build_rig_only_the_mentalis_is_reversed():
    rig = small_rig()
    assert [m.name for m in rig.muscles if m.reversed] == ["mentalis"]


@pytest.mark.parametrize("seed", SEEDS)
def test_build_rig_left_and_right_elements_are_mirror_images(seed):
    rig = small_rig(seed)
    mirror = small_head(seed).mirror
    for muscle in rig.muscles:
        if not muscle.name.endswith("_L"):
            continue
        twin = rig.muscle(muscle.name[:-2] + "_R")
        for end in ("origin", "insertion"):
            left = point_position(rig, getattr(muscle, end))
            right = point_position(rig, getattr(twin, end))
            assert np.array_equal(right, left * FLIP_X), f"{twin.name}.{end}"
        assert (twin.kind, twin.width_rel, twin.angle_rad, twin.region is None) == (
            muscle.kind,
            muscle.width_rel,
            muscle.angle_rad,
            muscle.region is None,
        )
    for name in ("procerus", "mentalis"):
        muscle = rig.muscle(name)
        assert (
            point_position(rig, muscle.origin)[0] == 0.0 and point_position(rig, muscle.insertion)[0] == 0.0
        )
    for wire in rig.wires:
        if wire.side != "L":
            continue
        twin = rig.wire(wire.name[:-2] + "_R")
        left = np.array([point_position(rig, p) for p in wire.points])
        right = np.array([point_position(rig, p) for p in twin.points])
        assert right.shape == left.shape and np.array_equal(right, left * FLIP_X), twin.name
        assert np.array_equal(np.sort(mirror[wire.vertices]), twin.vertices), f"{twin.name}.vertices"


@pytest.mark.parametrize("seed", SEEDS)
def test_build_rig_mouth_muscles_insert_at_the_mouth_corner(seed):
    rig = small_rig(seed)
    head = small_head(seed)
    for side in "LR":
        corner = head.vertices[head.landmarks[f"mouth_corner_{side}"]]
        for name in MODIOLUS:
            np.testing.assert_array_equal(point_position(rig, rig.muscle(f"{name}_{side}").insertion), corner)


def test_build_rig_has_the_16_thesis_wires():
    rig = small_rig()
    expected = [f"{w}_{s}" for s in "LR" for w in WIRES_PAIRED] + list(WIRES_CENTRAL)
    assert sorted(w.name for w in rig.wires) == sorted(expected)
    assert len(rig.wires) == 16
    for wire in rig.wires:
        assert len(wire.points) >= 2 and len(wire.vertices) > 0, wire.name
        assert set(wire.muscle_weights) <= set(rig.muscle_names), wire.name
        assert any(np.any(w > 0) for w in wire.muscle_weights.values()), f"{wire.name} is driven by no muscle"


def test_build_rig_channels_cover_muscles_jaw_eyelids_gaze_and_head():
    rig = small_rig()
    names = list(rig.channel_names)
    assert len(names) == len(set(names)) == len(rig.channels)
    assert set(rig.muscle_names) <= set(names)
    for muscle in rig.muscles:
        channel = rig.channel(muscle.name)
        assert (channel.unit, channel.minimum, channel.maximum, channel.default) == (
            "activation",
            0.0,
            1.0,
            0.0,
        )
    required = {
        "jaw_open": "rad",
        "jaw_slide": "rel",
        "jaw_protrude": "rel",
        "eyelid_upper_L": "rad",
        "eyelid_upper_R": "rad",
        "eyelid_lower_L": "rad",
        "eyelid_lower_R": "rad",
        "gaze_yaw": "rad",
        "gaze_pitch": "rad",
        "head_yaw": "rad",
        "head_pitch": "rad",
        "head_roll": "rad",
    }
    for name, unit in required.items():
        assert name in names, name
        channel = rig.channel(name)
        assert channel.unit == unit and channel.minimum <= 0.0 <= channel.maximum, name
    assert rig.channel("jaw_open").maximum > 0.2, "the jaw opens by a visible angle"


@pytest.mark.parametrize("seed", SEEDS)
def test_build_rig_skin_weights_are_normalised_with_at_most_4_influences(seed):
    rig = small_rig(seed)
    w = rig.skin_weights
    assert sp.issparse(w) and w.format == "csr"
    assert w.shape == (rig.n_vertices, len(BONES)) and w.dtype == np.float64
    assert rig.bone_names == BONES
    assert np.all(w.data >= 0) and np.isfinite(w.data).all()
    assert np.diff(w.indptr).max() <= MAX_INFLUENCES
    np.testing.assert_allclose(np.asarray(w.sum(axis=1)).ravel(), 1.0, atol=1e-12)


@pytest.mark.parametrize("seed", SEEDS)
def test_build_rig_jaw_carries_the_lower_teeth_tongue_and_lower_lip_only(seed):
    rig, head = small_rig(seed), small_head(seed)
    w = weights(rig)
    jaw, root = rig.bone_index("jaw"), rig.bone_index("head")
    for part in ("teeth_lower", "tongue"):
        ids = head.mesh.part_vertices(part)
        assert np.all(w[ids, jaw] == 1.0), f"{part} is not fully on the jaw"
    for part in ("teeth_upper", "ear_L", "ear_R"):
        ids = head.mesh.part_vertices(part)
        assert np.all(w[ids, root] == 1.0), f"{part} is not fully on the head bone"
    # the lips split at the contact line: the upper lip stays (drawn down toward the corners, where
    # both lips take half the jaw's motion), the lower lip rides the jaw
    assert np.all(w[head.regions["upper_lip"], jaw] <= CORNER_JAW + 1e-12)
    assert np.all(w[head.regions["lower_lip"], jaw] > 0.2)
    assert np.mean(w[head.regions["lower_lip"], jaw]) > 0.6
    assert (
        w[head.landmarks["upper_lip_top"], jaw] <= 0.1 and w[head.landmarks["lower_lip_bottom"], jaw] >= 0.99
    )
    assert np.all(w[head.regions["forehead"], jaw] == 0.0)
    assert w[head.landmarks["pogonion"], jaw] >= 0.99  # the chin's border is smoothed, its core all but 1


def test_build_rig_jaw_translations_reach_a_mandibles_range():
    """At their maxima the lower teeth shift 0.8-1.2 cm to either side (an adult's lateral excursion,
    8-12 mm) and 0.7-1.2 cm forward (protrusion, 7-11 mm), on a head of ordinary height."""
    from mimetic.engines import make_engine
    from mimetic.rig.activations import pose

    rig, head = small_rig(), small_head()
    assert 20.0 < rig.scale < 24.0  # cm: the built-in head is an adult's
    engine = make_engine(rig, "wire")
    teeth = head.mesh.part_vertices("teeth_lower")
    rest = engine.deform(pose(rig))[teeth]
    for name, axis, (low, high) in (("jaw_slide", 0, (0.8, 1.2)), ("jaw_protrude", 2, (0.7, 1.2))):
        channel = rig.channel(name)
        moved = engine.deform(pose(rig, {name: channel.maximum}))[teeth] - rest  # (k, 3) cm
        assert np.allclose(moved, moved[0], atol=1e-9)  # the jaw translates them rigidly
        assert low <= moved[0, axis] <= high, (name, moved[0])
        if name == "jaw_slide":
            assert channel.minimum == -channel.maximum  # either side alike


@pytest.mark.parametrize("seed", SEEDS)
def test_build_rig_eyeballs_follow_their_eye_bones(seed):
    rig, head = small_rig(seed), small_head(seed)
    w = weights(rig)
    for i, side in enumerate("LR"):
        ids = head.mesh.part_vertices(f"eye_{side}")
        assert np.all(w[ids, rig.bone_index(f"eye_{side}")] == 1.0)
        bone = rig.bone(f"eye_{side}")
        assert bone.parent == "head"
        np.testing.assert_array_equal(bone.head, head.eye_centres[i])
        lid = rig.bone_index(f"eyelid_upper_{side}")
        assert 0.5 < w[head.landmarks[f"eye_upper_lid_{side}"], lid] <= 1.0


@pytest.mark.parametrize("seed", SEEDS)
def test_build_rig_mouth_bag_rim_moves_with_the_inner_lip(seed):
    rig, head = small_rig(seed), small_head(seed)
    inner_lip = build_topology(SMALL_RESOLUTION).mouth.index[0]
    rim = head.mesh.part_vertices("mouth")[: len(inner_lip)]
    assert np.array_equal(head.vertices[rim], head.vertices[inner_lip]), "the bag is welded to the inner lip"
    w = weights(rig)
    gap = np.abs(w[rim] - w[inner_lip]).max(axis=1)  # (k,)
    assert gap.shape == (len(rim),)
    assert np.all(gap == 0.0), (
        f"{np.sum(gap > 0)} of {len(rim)} welded rim vertices have other skin weights than the inner lip "
        f"(max difference {gap.max():.3f}); the seam tears when the jaw opens"
    )


def test_build_rig_sphincters_act_on_both_lips_and_both_lids():
    # a muscle's region limits its effect; a sphincter that purses or closes must reach both sides
    rig = small_rig()
    blocked = []
    for name, needs in {
        "orbicularis_oris": ("upper_lip", "lower_lip"),
        "orbicularis_oculi_L": ("eyelid_upper_L", "eyelid_lower_L"),
        "orbicularis_oculi_R": ("eyelid_upper_R", "eyelid_lower_R"),
    }.items():
        region = rig.muscle(name).region
        for target in needs:
            if region is not None and not np.intersect1d(rig.regions[region], rig.regions[target]).size:
                blocked.append(f"{name} (region {region!r}) cannot move {target}")
    assert not blocked, "; ".join(blocked)


@pytest.mark.parametrize("seed", [0, 1])
def test_build_rig_places_elements_at_the_same_surface_points_on_every_head(seed):
    reference, other = small_rig(), small_rig(seed)
    assert other.mesh.vertices.shape == reference.mesh.vertices.shape
    assert not np.array_equal(other.mesh.vertices, reference.mesh.vertices)
    assert dict(other.landmarks) == dict(reference.landmarks)
    assert [(m.name, m.origin, m.insertion, m.region) for m in other.muscles] == [
        (m.name, m.origin, m.insertion, m.region) for m in reference.muscles
    ]
    assert other.muscles == reference.muscles, "muscle parameters are relative, so identical"
    for a, b in zip(other.wires, reference.wires, strict=True):
        assert (a.name, a.points) == (b.name, b.points)
        assert np.array_equal(a.vertices, b.vertices), a.name
    assert other.channels == reference.channels
    assert other.bone_names == reference.bone_names
    assert list(other.regions) == list(reference.regions)


def test_save_rig_load_rig_round_trip_is_equal(tmp_path):
    rig = small_rig()
    path = save_rig(rig, tmp_path / "head.mrig")
    assert path.exists() and path.stat().st_size > 0
    loaded = load_rig(path)
    assert rig_differences(rig, loaded) == []
    assert loaded == rig


def test_build_rig_without_anatomy_is_the_same_rig_with_an_empty_anatomy():
    """``rig_head`` builds the fitted reference's rig so (the transfer derives the user's anatomy)."""
    import dataclasses

    from mimetic.rig.anatomy import Anatomy
    from mimetic.testing import small_head

    head = small_head()
    full, bare = build_rig(head), build_rig(head, anatomy=False)
    empty = Anatomy.none(head.mesh.n_vertices, len(full.bones))
    assert not bare.anatomy.creases and not bare.anatomy.lids and not bare.anatomy.actions
    assert (
        bare.anatomy.thickness_rel.shape == (head.mesh.n_vertices,) and not bare.anatomy.thickness_rel.any()
    )
    assert dataclasses.replace(full, anatomy=empty) == bare
