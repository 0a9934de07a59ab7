"""Tests for mimetic.head.regions: the named skin vertex sets."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from mimetic.head.regions import REGION_NAMES
from mimetic.testing import RANDOM_SEEDS, small_head

DISJOINT = (
    "upper_lip",
    "lower_lip",
    "eyelid_upper_L",
    "eyelid_upper_R",
    "eyelid_lower_L",
    "eyelid_lower_R",
    "brow_L",
    "brow_R",
    "nose",
    "cheek_L",
    "cheek_R",
    "nasolabial_L",
    "nasolabial_R",
    "chin",
)
LID_LANDMARKS = {
    "eyelid_upper": ("eye_upper_lid_outer", "eye_upper_lid", "eye_upper_lid_inner"),
    "eyelid_lower": ("eye_lower_lid_outer", "eye_lower_lid", "eye_lower_lid_inner"),
}


def test_skin_regions_are_sorted_unique_skin_indices(head):
    assert tuple(head.regions) == REGION_NAMES
    for name, ids in head.regions.items():
        assert ids.ndim == 1 and ids.dtype == np.int64, name
        assert len(ids) > 0, f"{name} is empty"
        assert np.all(np.diff(ids) > 0), f"{name} is not sorted and unique"
        if name in ("upper_lip", "lower_lip"):  # the lips continue into the mouth cavity's first loops
            outside = ids[ids >= head.n_skin]
            assert np.isin(outside, head.mesh.part_vertices("mouth")).all(), f"{name} leaves skin and mouth"
            assert 0 < len(outside) < len(ids) / 2, name
        else:
            assert ids[0] >= 0 and ids[-1] < head.n_skin, f"{name} leaves the skin"


def test_skin_regions_pairs_mirror_and_the_rest_are_symmetric(head):
    for name, ids in head.regions.items():
        if name.endswith("_R"):
            continue
        twin = name[:-2] + "_R" if name.endswith("_L") else name
        assert np.array_equal(np.sort(head.mirror[ids]), head.regions[twin]), f"{name} vs {twin}"
        if name.endswith("_L"):
            assert np.all(head.vertices[ids, 0] > 0), f"{name} is on the subject's left (+X)"


def test_skin_regions_face_parts_are_pairwise_disjoint(head):
    overlaps = {
        (a, b): len(np.intersect1d(head.regions[a], head.regions[b]))
        for a, b in itertools.combinations(DISJOINT, 2)
    }
    assert not {k: v for k, v in overlaps.items() if v}, "overlapping regions"


@pytest.mark.parametrize("seed", [None, *RANDOM_SEEDS])
def test_skin_regions_upper_lip_lies_above_lower_lip(seed):
    head = small_head(seed)
    upper = head.vertices[head.regions["upper_lip"]]
    lower = head.vertices[head.regions["lower_lip"]]
    assert upper.shape[1] == lower.shape[1] == 3
    assert upper[:, 1].mean() > lower[:, 1].mean()


def test_skin_regions_eyelids_contain_the_lid_margin_landmarks(head):
    for region, names in LID_LANDMARKS.items():
        for side in "LR":
            ids = head.regions[f"{region}_{side}"]
            for name in names:
                assert head.landmarks[f"{name}_{side}"] in ids, f"{name}_{side} not in {region}_{side}"
            for corner in ("eye_outer_corner", "eye_inner_corner"):
                assert head.landmarks[f"{corner}_{side}"] not in ids, f"the canthus is in {region}_{side}"


def test_skin_regions_contain_their_landmarks(head):
    lm = head.landmarks
    assert lm["nose_tip"] in head.regions["nose"]
    for side in "LR":
        assert lm[f"brow_mid_{side}"] in head.regions[f"brow_{side}"]
    assert lm["upper_lip_top"] in head.regions["upper_lip"]
    assert lm["lower_lip_bottom"] in head.regions["lower_lip"]
    assert lm["pogonion"] in head.regions["chin"]


@pytest.mark.parametrize("seed", RANDOM_SEEDS)
def test_skin_regions_are_the_same_vertices_for_every_parameter_set(head, seed):
    other = small_head(seed).regions
    assert list(other) == list(head.regions)
    for name, ids in head.regions.items():
        assert np.array_equal(other[name], ids), name
