"""Tests for mimetic.head.landmarks: the named landmarks and their iBUG-68 / MediaPipe maps."""

from __future__ import annotations

import collections
import re

import numpy as np
import pytest

from mimetic.head.landmarks import IBUG68, MEDIAPIPE
from mimetic.head.model import Head
from mimetic.head.topology import build_topology
from mimetic.mesh.geometry import vertex_adjacency
from mimetic.testing import RANDOM_SEEDS, SMALL_RESOLUTION, head_with, small_head

FLIP_X = np.array([-1.0, 1.0, 1.0])
CASES = [pytest.param(None, id="default")] + [pytest.param(s, id=f"seed={s}") for s in RANDOM_SEEDS]


def position(head: Head, name: str) -> np.ndarray:
    return head.vertices[head.landmarks[name]]


def other_side(name: str) -> str | None:
    """``x_R`` for ``x_L`` (and ``jaw_R3`` for ``jaw_L3``), and vice versa; None on the midline."""
    match = re.fullmatch(r"(.+)_([LR])(\d*)", name)
    if match is None:
        return None
    base, side, number = match.groups()
    return f"{base}_{'R' if side == 'L' else 'L'}{number}"


def test_skin_landmarks_are_at_least_40_vertex_indices(head):
    names = list(head.landmarks)
    assert len(names) >= 40
    assert all(isinstance(n, str) and n for n in names)
    ids = np.array(list(head.landmarks.values()))
    assert ids.shape == (len(names),) and np.issubdtype(ids.dtype, np.integer)
    assert all(type(i) is int for i in head.landmarks.values())
    assert ids.min() >= 0 and ids.max() < head.mesh.n_vertices
    pupils = {head.landmarks["pupil_L"], head.landmarks["pupil_R"]}
    assert all(i < head.n_skin for n, i in head.landmarks.items() if i not in pupils), "on the skin"


def test_ibug68_maps_every_point_to_a_landmark(head):
    assert isinstance(IBUG68, tuple) and len(IBUG68) == 68
    missing = [n for n in IBUG68 if n not in head.landmarks]
    assert not missing, missing
    # a closed mouth: iBUG 48/60 and 54/64 are the same corners; no other name repeats
    repeats = {n: c for n, c in collections.Counter(IBUG68).items() if c > 1}
    assert repeats == {"mouth_corner_R": 2, "mouth_corner_L": 2}
    assert (IBUG68[48], IBUG68[60], IBUG68[54], IBUG68[64]) == (
        "mouth_corner_R",
        "mouth_corner_R",
        "mouth_corner_L",
        "mouth_corner_L",
    )


def test_mediapipe_names_are_landmarks(head):
    assert all(name in head.landmarks for name in MEDIAPIPE)
    assert len(set(MEDIAPIPE.values())) == len(MEDIAPIPE)


@pytest.mark.parametrize("resolution", [SMALL_RESOLUTION, 10_000])
def test_skin_landmarks_name_distinct_vertices(resolution):
    head = head_with(None, resolution)
    by_vertex = collections.defaultdict(list)
    for name, vertex in head.landmarks.items():
        by_vertex[vertex].append(name)
    shared = [names for names in by_vertex.values() if len(names) > 1]
    assert not shared, f"landmarks on the same vertex: {shared}"


def test_ibug68_contours_run_in_image_order(head):
    p = head.landmark_positions(list(IBUG68))  # (68, 3)
    assert p.shape == (68, 3) and p.dtype == np.float64
    # iBUG runs from the subject's right (-X) to the left along the jaw, brows, lower nose and lips
    for label, run in {
        "jaw": range(0, 17),
        "right brow": range(17, 22),
        "left brow": range(22, 27),
        "lower nose": range(31, 36),
        "upper lip": range(48, 55),
    }.items():
        assert np.all(np.diff(p[list(run), 0]) > 0), f"{label} x is not increasing: {p[list(run), 0]}"
    assert np.all(np.diff(p[27:31, 1]) < 0), "the nose bridge runs down from the nasion to the tip"


@pytest.mark.parametrize("resolution", [SMALL_RESOLUTION, 10_000])
def test_ibug68_jaw_contour_runs_down_to_the_menton(resolution):
    # landmarks are the same vertices for every parameter set, so the default head decides
    head = head_with(None, resolution)
    jaw = head.landmark_positions(list(IBUG68[:17]))  # (17, 3)
    assert jaw.shape == (17, 3)
    menton = position(head, "menton")
    low = [(IBUG68[i], round(float(jaw[i, 1]), 2)) for i in range(17) if jaw[i, 1] < menton[1]]
    assert not low, f"jaw contour points below the menton (y={menton[1]:.2f}), on the neck: {low}"
    assert np.all(np.diff(jaw[:9, 1]) < 0), f"jaw_R1..menton is not descending: {np.round(jaw[:9, 1], 2)}"


def test_skin_landmarks_left_and_right_are_mirror_pairs(head):
    lm = head.landmarks
    left = [n for n in lm if other_side(n) is not None and re.search(r"_L\d*$", n)]
    assert len(left) >= 15
    for name in lm:
        twin = other_side(name)
        if twin is None:
            continue
        assert twin in lm, f"{name} has no {twin}"
        assert lm[twin] == head.mirror[lm[name]], f"{twin} is not the mirror image of {name}"
    for name in left:
        assert position(head, name)[0] > 0, f"{name} is on the subject's left (+X)"
    midline = [n for n in lm if other_side(n) is None]
    assert {"nose_tip", "menton", "nasion", "pogonion", "subnasale"} <= set(midline)
    for name in midline:
        assert head.mirror[lm[name]] == lm[name], f"{name} is not on the midline"
        assert position(head, name)[0] == 0.0


@pytest.mark.parametrize("seed", CASES)
def test_skin_landmarks_are_the_same_vertices_for_every_parameter_set(head, seed):
    assert dict(small_head(seed).landmarks) == dict(head.landmarks)


def test_skin_landmarks_mouth_corners_join_the_upper_and_lower_lip(head):
    topo = build_topology(SMALL_RESOLUTION)
    contact = topo.mouth.index[1]  # u = 0, where the lips meet
    assert topo.mouth.u[1] == 0.0
    adjacency = vertex_adjacency(head.mesh.faces[head.mesh.parts["skin"]], head.n_skin)
    upper, lower = set(head.regions["upper_lip"].tolist()), set(head.regions["lower_lip"].tolist())
    for side in "LR":
        corner = head.landmarks[f"mouth_corner_{side}"]
        assert corner in contact
        neighbours = set(adjacency[corner].indices.tolist())
        assert neighbours & upper and neighbours & lower, f"mouth_corner_{side} touches both lips"
        assert corner not in upper and corner not in lower
    assert position(head, "mouth_corner_L")[0] > position(head, "upper_lip_outer_L")[0]


@pytest.mark.parametrize("seed", CASES)
def test_skin_landmarks_pupils_are_the_front_of_their_eyeballs(seed):
    head = small_head(seed)
    for side in "LR":
        ids = head.mesh.part_vertices(f"eye_{side}")
        front = ids[np.argmax(head.vertices[ids, 2])]
        assert head.landmarks[f"pupil_{side}"] == front
        assert np.sum(head.vertices[ids, 2] == head.vertices[front, 2]) == 1, "a unique front pole"


@pytest.mark.parametrize("seed", CASES)
def test_skin_landmarks_upper_lip_lies_above_lower_lip(seed):
    head = small_head(seed)
    y = {
        n: position(head, n)[1]
        for n in ("upper_lip_top", "upper_lip_inner", "lower_lip_inner", "lower_lip_bottom")
    }
    assert y["upper_lip_top"] > y["upper_lip_inner"] >= y["lower_lip_inner"] > y["lower_lip_bottom"], y
    for side in "LR":
        assert position(head, f"upper_lip_peak_{side}")[1] > position(head, f"lower_lip_mid_{side}")[1]


@pytest.mark.parametrize("seed", CASES)
def test_skin_landmarks_eye_inner_corners_are_nearer_the_midline(seed):
    head = small_head(seed)
    for side in "LR":
        inner = abs(position(head, f"eye_inner_corner_{side}")[0])
        outer = abs(position(head, f"eye_outer_corner_{side}")[0])
        pupil = abs(position(head, f"pupil_{side}")[0])
        assert inner < pupil < outer


@pytest.mark.parametrize("seed", CASES)
def test_skin_landmarks_nose_tip_is_the_most_anterior_central_skin_vertex(seed):
    head = small_head(seed)
    skin = head.vertices[: head.n_skin]
    central = np.nonzero(
        (np.abs(skin[:, 0]) < 3.0)
        & (skin[:, 1] < position(head, "glabella")[1])
        & (skin[:, 1] > position(head, "menton")[1])
    )[0]
    front = central[np.argmax(skin[central, 2])]
    tip = head.landmarks["nose_tip"]
    if seed is None:
        assert tip == front
    # tolerance: 0.05 cm of depth, for ties between neighbouring vertices on a flat tip
    behind = skin[front, 2] - skin[tip, 2]
    assert behind <= 0.05, (
        f"nose_tip (vertex {tip}) is {behind:.3f} cm behind the most anterior vertex {front}, "
        f"{np.linalg.norm(skin[front] - skin[tip]):.2f} cm away"
    )


@pytest.mark.parametrize("seed", CASES)
def test_skin_landmarks_chin_brows_and_ears_are_in_place(seed):
    head = small_head(seed)
    assert position(head, "menton")[1] < position(head, "pogonion")[1]
    assert position(head, "pogonion")[2] > position(head, "menton")[2]
    for side in "LR":
        brows = head.landmark_positions(
            [n for n in head.landmarks if n.startswith("brow_") and n.endswith(side)]
        )
        lids = head.landmark_positions(
            [n for n in head.landmarks if n.startswith("eye_") and n.endswith(side)]
        )
        assert brows.shape == (5, 3) and lids.shape == (8, 3)
        assert brows[:, 1].min() > lids[:, 1].max(), f"brows above the {side} eye"
        tragion = position(head, f"tragion_{side}")
        ear = head.vertices[head.mesh.part_vertices(f"ear_{side}")]
        gap = np.linalg.norm(ear - tragion, axis=1).min()
        assert gap < 0.5, f"tragion_{side} is {gap:.2f} cm from the ear"
        assert np.sign(tragion[0]) == (1 if side == "L" else -1)
