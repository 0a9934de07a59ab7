"""Tests for mimetic.rig.anatomy.gaze: the skin around each eye turns with it, the outer corner more
than the inner, and nothing beyond the orbit moves; on the default head and on random heads
(``case``, from conftest)."""

from __future__ import annotations

import numpy as np


def _skin_near_eye(rig, side: str) -> tuple[np.ndarray, np.ndarray]:
    """The lids' skin (k,) of one eye, and the skin (n,) bool beyond 1.5 eye widths of both eyes'
    centres (the skin's only: eyeballs turn)."""
    v, f = rig.mesh.vertices, rig.mesh.faces
    width = np.linalg.norm(
        rig.landmarks[f"eye_outer_corner_{side}"].position(v, f)
        - rig.landmarks[f"eye_inner_corner_{side}"].position(v, f)
    )
    lids = np.concatenate([rig.regions[f"eyelid_{lid}_{side}"] for lid in ("upper", "lower")])
    far = np.isin(np.arange(rig.n_vertices), rig.mesh.part_vertices("skin"))
    for eye in ("L", "R"):
        far &= np.linalg.norm(v - rig.bone(f"eye_{eye}").head, axis=1) > 1.5 * width
    return lids, far


def _corner_motion(rig, rest, d, side: str) -> np.ndarray:
    """Motion (2, 3) of the inner and outer corner landmarks under ``d`` (n, 3)."""
    at = [rig.landmarks[f"eye_{c}_corner_{side}"] for c in ("inner", "outer")]
    return np.stack([p.position(rest + d, rig.mesh.faces) - p.position(rest, rig.mesh.faces) for p in at])


def test_a_look_aside_carries_the_lids_along_the_outer_corner_most(case):
    rig, rest, motion = case
    d = motion({"gaze_yaw": 0.4})  # both eyes to the subject's left (+X)
    for side in ("L", "R"):
        lids, far = _skin_near_eye(rig, side)
        assert d[lids, 0].mean() > 0.02 * 0.4 * rig.scale / 10, side  # a few millimetres on a 23 cm head
        assert np.abs(d[far]).max() < 1e-9, side
        inner, outer = np.linalg.norm(_corner_motion(rig, rest, d, side), axis=1)
        assert outer > 1.5 * inner, side  # the medial canthal tendon holds the inner corner


def test_converging_eyes_carry_both_eyes_lids_toward_the_nose(case):
    rig, _, motion = case
    d = motion({"gaze_convergence": 0.4})
    for side, toward_nose in (("L", -1.0), ("R", 1.0)):
        lids, _ = _skin_near_eye(rig, side)
        assert toward_nose * d[lids, 0].mean() > 0.0, side
    # one eye alone: the left turns out while the right stays
    d = motion({"gaze_yaw": 0.1, "gaze_convergence": -0.2})
    lids_r, _ = _skin_near_eye(rig, "R")
    lids_l, _ = _skin_near_eye(rig, "L")
    assert np.abs(d[lids_r]).max() < 1e-3 * np.abs(d[lids_l]).max()


def test_looking_up_lifts_both_lids_and_the_skin_around_them(case):
    rig, _, motion = case
    up, down = motion({"gaze_pitch": 0.4}), motion({"gaze_pitch": -0.4})
    for side in ("L", "R"):
        lids, far = _skin_near_eye(rig, side)
        lower = rig.regions[f"eyelid_lower_{side}"]
        assert up[lids, 1].mean() > 0.0 > down[lids, 1].mean(), side
        assert up[lower, 1].mean() > 0.0, side  # the lower lid goes along too (its plate does not follow)
        assert np.abs(up[far]).max() < 1e-9, side


def test_one_eye_looks_down_alone_with_the_vertical_vergence(case):
    rig, _, motion = case
    d = motion({"gaze_pitch": -0.2, "gaze_vertical_vergence": -0.4})  # ARKit's eyeLookDownLeft
    lids_l, _ = _skin_near_eye(rig, "L")
    lids_r, _ = _skin_near_eye(rig, "R")
    both = motion({"gaze_pitch": -0.4})  # both eyes down as far
    assert d[lids_l, 1].mean() < 0.0
    assert np.allclose(d[lids_l], both[lids_l], atol=1e-6 * rig.scale)  # the left eye's lids as in both
    assert np.abs(d[lids_r]).max() < 1e-3 * np.abs(d[lids_l]).max()  # the right eye's lids stay
