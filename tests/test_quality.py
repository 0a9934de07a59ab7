"""Tests of ``mimetic.quality``: each metric on a synthetic case with a known answer, then once on a
small generated head (and the shared data's MediaPipe mask where a metric must refuse it)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mimetic import quality
from mimetic.animate.expressions import expression_pose
from mimetic.engines import make_engine
from mimetic.engines.basis import Basis
from mimetic.rig.model import Channel
from mimetic.testing import (
    MEDIAPIPE_INNER_LIPS,
    generated_face_faces,
    ict_identity,
    mediapipe_canonical,
    mediapipe_face_faces,
    mediapipe_landmarks,
    require_shared_data,
    small_head,
    small_rig,
)


def grid(nx: int, ny: int, spacing: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """A flat grid in z = 0: vertices ((nx+1)(ny+1), 3), two triangles per cell facing +Z."""
    x, y = np.meshgrid(np.arange(nx + 1) * spacing, np.arange(ny + 1) * spacing)
    vertices = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    faces = []
    for j in range(ny):
        for i in range(nx):
            a = j * (nx + 1) + i
            b, c, d = a + 1, a + nx + 2, a + nx + 1
            faces += [(a, b, c), (a, c, d)]
    return vertices, np.array(faces, dtype=np.int64)


@pytest.fixture(scope="module")
def rig():
    return small_rig()


@pytest.fixture(scope="module")
def wire(rig):
    return make_engine(rig, "wire")


@pytest.fixture(scope="module")
def rest(rig, wire):
    return wire.deform(np.array([c.default for c in rig.channels]))


# --------------------------------------------------------------------------- edge stretch


def test_edge_stretch_grid_stretched_along_x_has_p99_of_the_stretch():
    vertices, faces = grid(10, 10)
    posed = vertices * [2.0, 1.0, 1.0]
    before = vertices.copy()
    result = quality.edge_stretch(vertices, posed, faces)
    np.testing.assert_array_equal(vertices, before)
    assert result.edges.shape == (len(result.ratio), 2) and result.edges.dtype == np.int64
    assert result.ratio.dtype == np.float64
    # horizontal edges double, vertical ones keep their length, diagonals grow by sqrt(5/2)
    assert sorted(set(np.round(result.ratio, 9))) == pytest.approx([1.0, np.sqrt(2.5), 2.0])
    assert result.p99 == pytest.approx(2.0)  # a third of the edges are horizontal: the top percent
    assert result.widest == pytest.approx(1.0)  # a unit edge grew to 2


def test_edge_stretch_one_moved_vertex_opens_one_edge_by_the_move():
    vertices, faces = grid(4, 4)
    posed = vertices.copy()
    centre = 2 * 5 + 2  # vertex (2, 2)
    posed[centre, 0] += 0.3
    result = quality.edge_stretch(vertices, posed, faces)
    assert result.widest == pytest.approx(0.3)
    np.testing.assert_array_equal(np.sort(result.widest_edge), [centre - 1, centre])
    assert result.ratio.min() == pytest.approx(0.7)  # the edge on the other side shrank by the move


def test_edge_stretch_skips_edges_without_rest_length():
    vertices = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 1, 0]])
    faces = np.array([[0, 1, 2], [2, 1, 3]])  # 2 and 3 coincide
    result = quality.edge_stretch(vertices, vertices * 3.0, faces)
    assert len(result.edges) == 4
    assert np.all(np.isfinite(result.ratio)) and result.p99 == pytest.approx(3.0)


# --------------------------------------------------------------------------- triangles


def test_triangle_flips_counts_only_triangles_turned_past_ninety_degrees():
    rest = np.array(
        [[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0], [3, 0, 0], [2, 1, 0], [5, 0, 0], [6, 0, 0.0]]
    )
    faces = np.array([[0, 1, 2], [3, 4, 5], [6, 7, 6]])  # the last has no area
    posed = rest.copy()
    posed[2] = [0.0, 0.0, 1.0]  # tilted 90°: turned, but not past
    posed[2] += [0.0, -0.05, 0.0]  # just past 90°
    posed[5] = [2.0, np.cos(np.radians(60)), np.sin(np.radians(60))]  # tilted 60°
    flipped = quality.triangle_flips(rest, posed, faces)
    assert flipped.dtype == bool and flipped.shape == (3,)
    np.testing.assert_array_equal(flipped, [True, False, False])


def test_triangle_flips_mirrored_triangle_is_flipped():
    vertices, faces = grid(2, 2)
    posed = vertices * [-1.0, 1.0, 1.0]  # a mirror turns every triangle over
    assert quality.triangle_flips(vertices, posed, faces).all()
    assert not quality.triangle_flips(vertices, vertices + np.array([0.0, 0.0, 5.0]), faces).any()


# --------------------------------------------------------------------------- lid margins


def margins_of(upper: np.ndarray, lower: np.ndarray) -> tuple[quality.LidMargins, np.ndarray]:
    """Synthetic margins: polylines (k, 2) in a frame equal to the world's (u = x, v = y)."""
    vertices = np.vstack([np.column_stack([p, np.zeros(len(p))]) for p in (upper, lower)])
    ids = np.arange(len(vertices))
    margins = quality.LidMargins(
        "L", ids[: len(upper)], ids[len(upper) :], np.zeros(3), np.eye(3), 3.0, False, "", upper[:, 0]
    )
    return margins, vertices


def test_margin_gap_of_two_lines_is_known_over_their_common_range():
    u = np.linspace(0.0, 2.0, 5)
    upper = np.column_stack([u, 0.5 + 0.1 * u])
    lower = np.column_stack([np.linspace(0.5, 3.0, 4), np.zeros(4)])[::-1]  # any order
    columns, gaps = quality.margin_gap(upper, lower, samples=16)
    assert columns.shape == gaps.shape == (16,)
    assert columns[0] == pytest.approx(0.5) and columns[-1] == pytest.approx(2.0)
    np.testing.assert_allclose(gaps, 0.5 + 0.1 * columns, atol=1e-12)


def test_lid_gap_reports_crossing_margins():
    u = np.linspace(0.0, 2.0, 9)
    margins, vertices = margins_of(np.column_stack([u, 0.2 - 0.3 * u]), np.column_stack([u, 0 * u]))
    gap = quality.lid_gap(margins, vertices)
    assert gap.crossing
    assert gap.smallest == pytest.approx(-0.4) and gap.largest == pytest.approx(0.2)
    apart, vertices = margins_of(np.column_stack([u, 0.05 + 0 * u]), np.column_stack([u, 0 * u]))
    gap = quality.lid_gap(apart, vertices)
    assert not gap.crossing and gap.smallest == pytest.approx(0.05) and gap.largest == pytest.approx(0.05)


def test_margin_roughness_is_small_for_an_arc_and_the_amplitude_for_a_sawtooth():
    t = np.linspace(0.0, 3.0, 33)
    arc = np.column_stack([0.5 * np.sqrt(1 - ((t - 1.5) / 2.0) ** 2), 0.1 * t**2])  # a lid-like arc
    assert quality.margin_roughness(t, arc, 3.0) < 1e-3
    saw = arc.copy()
    saw[:, 0] += 0.05 * (-1.0) ** np.arange(len(t))
    assert quality.margin_roughness(t, saw, 3.0) == pytest.approx(0.05 / 3.0, rel=0.1)
    assert np.isnan(quality.margin_roughness(t[:5], arc[:5], 3.0))


# --------------------------------------------------------------------------- fidelity


def test_expression_fidelity_of_a_known_basis():
    neutral = np.zeros((4, 3))
    deltas = np.zeros((2, 4, 3))
    deltas[0, 0, 0] = 1.0  # channel a moves vertex 0 along x
    deltas[1, 1, 1] = 1.0  # channel b moves vertex 1 along y
    basis = Basis(("a", "b"), neutral, deltas)
    channels = [Channel("a", 0.0, 1.0), Channel("b", 0.0, 1.0)]
    targets = np.zeros((3, 4, 3))
    targets[0, 0, 0] = 0.5  # inside the basis: fitted but for the 1e-3 regularization
    targets[1, 0, 0], targets[1, 2, 2] = 1.0, 1.0  # half of it out of reach: 1/sqrt(2)
    targets[2, 0, 0] = 2.0  # beyond a's bound: a = 1 leaves half
    result = quality.expression_fidelity(basis, targets, names=["in", "out", "bound"], channels=channels)
    assert result.residual.shape == (3,) and result.activations.shape == (3, 2)
    assert result.residual[0] < 2e-3
    assert result.residual[1] == pytest.approx(1 / np.sqrt(2), abs=2e-3)
    assert result.residual[2] == pytest.approx(0.5, abs=1e-9)
    assert result.median == pytest.approx(0.5, abs=1e-9)
    assert result.worst_name == "out" and result.success


# --------------------------------------------------------------------------- on a generated head


def test_expression_fidelity_recovers_shapes_the_baked_rig_can_make(rig, wire):
    from mimetic.engines import bake, evaluate_basis
    from mimetic.rig.activations import pose

    basis = bake(wire, samples=2).basis
    poses = np.stack(
        [
            pose(rig, {"zygomatic_major_L": 0.6, "jaw_open": 0.2}),
            pose(rig, {"frontalis_inner_R": 0.8, "orbicularis_oris": 0.5}),
        ]
    )
    deltas = evaluate_basis(basis, poses) - basis.neutral
    result = quality.expression_fidelity(basis, deltas, names=["smile_open", "brow_pucker"], channels=rig)
    assert result.residual.shape == (2,)
    assert result.worst < 0.02  # reproduced but for the regularization's shrinkage
    random = np.random.default_rng(0).normal(0.0, 0.1, deltas.shape)  # noise no rig makes
    noise = quality.expression_fidelity(basis, random, names=["a", "b"], channels=rig)
    assert noise.median > 0.9


def test_chin_drop_of_a_translation_is_its_length(rig, rest):
    assert quality.chin_drop(rig, rest, rest + np.array([0.0, -2.0, 0.0])) == pytest.approx(2.0)


def test_matched_jaw_open_reaches_the_asked_drop(rig, wire, rest):
    target = 0.1 * rig.scale
    match = quality.matched_jaw_open(wire, target)
    assert match.reached and 0 < match.value < rig.channel("jaw_open").maximum
    assert match.drop == pytest.approx(target, rel=1e-3)
    assert quality.chin_drop(rig, rest, match.vertices) == pytest.approx(match.drop)
    assert match.evaluations < 40
    far = quality.matched_jaw_open(wire, 10 * rig.scale)
    assert not far.reached and far.value == rig.channel("jaw_open").maximum


def test_upper_lip_follow_known_motions(rig, rest):
    lower_only = rest.copy()
    lower_only[rig.regions["lower_lip"]] += [0.0, -1.0, 0.0]
    follow = quality.upper_lip_follow(rig, rest, lower_only)
    assert follow.ratio == pytest.approx(0.0) and follow.lower_mean == pytest.approx(1.0)
    assert len(follow.upper) > 0 and len(follow.lower) > 0
    assert quality.upper_lip_follow(rig, rest, rest + np.array([0.0, -1.0, 0.0])).ratio == pytest.approx(1.0)


def test_upper_lip_follow_jaw_open_moves_the_lower_lip_more(rig, wire, rest):
    match = quality.matched_jaw_open(wire, quality.ICT_JAW_DROP_REL * rig.scale)
    follow = quality.upper_lip_follow(rig, rest, match.vertices)
    assert follow.lower_mean > 0.2 * match.drop
    assert follow.ratio < 0.5


def test_lip_faces_lie_in_the_lip_regions(rig):
    faces = generated_face_faces(small_head())
    lips = quality.lip_faces(rig, faces)
    inside = np.union1d(rig.regions["upper_lip"], rig.regions["lower_lip"])
    assert len(lips) > 0 and np.isin(lips, inside).all()
    assert len(lips) < len(faces)


def test_lip_flips_none_at_rest_and_counted_in_a_pose(rig, wire, rest):
    lips = quality.lip_faces(rig, generated_face_faces(small_head()))
    assert not quality.triangle_flips(rest, rest, lips).any()
    flipped = quality.triangle_flips(rest, wire.deform(expression_pose(rig, "jaw_drop")), lips)
    assert flipped.shape == (len(lips),)


def test_edge_stretch_jaw_open_stretches_the_face(rig, wire, rest):
    faces = generated_face_faces(small_head())
    match = quality.matched_jaw_open(wire, quality.ICT_JAW_DROP_REL * rig.scale)
    stretch = quality.edge_stretch(rest, match.vertices, faces)
    assert stretch.p99 > 1.05 and stretch.widest > 0
    assert quality.edge_stretch(rest, rest, faces).p99 == pytest.approx(1.0)


def test_find_lid_margins_open_eyes_of_a_symmetric_head(rig, rest):
    gaps = {}
    for side in "LR":
        margins = quality.find_lid_margins(rig, side)
        assert margins.usable and not margins.bridged
        assert len(margins.upper) >= 3 and len(margins.lower) >= 3
        assert np.isin(margins.upper, rig.regions[f"eyelid_upper_{side}"]).mean() > 0.5
        gaps[side] = quality.lid_gap(margins, rest)
        assert not gaps[side].crossing and gaps[side].smallest > 0
    # the generated head is mirror symmetric: both eyes measure the same
    np.testing.assert_allclose(gaps["L"].gaps, gaps["R"].gaps, atol=1e-9)


def test_find_lid_margins_ignores_separate_pieces_the_lid_regions_reach(rig):
    """ICT's transferred lid regions hold its eyelashes, separate pieces in front of the eye with rims
    of their own: margins come from the skin alone. Here the eyeball's front stands in for them."""
    eyeball = np.unique(rig.mesh.faces[rig.mesh.parts["eye_L"]])
    front = eyeball[(rig.mesh.vertices[eyeball] - rig.bone("eye_L").head)[:, 2] > 0.0]
    regions = dict(rig.regions)
    regions["eyelid_upper_L"] = np.union1d(regions["eyelid_upper_L"], front)
    regions["eyelid_lower_L"] = np.union1d(regions["eyelid_lower_L"], front)
    reaching = dataclasses.replace(rig, regions=regions, anatomy=rig.anatomy)
    clean, margins = quality.find_lid_margins(rig, "L"), quality.find_lid_margins(reaching, "L")
    assert margins.usable
    np.testing.assert_array_equal(margins.upper, clean.upper)
    np.testing.assert_array_equal(margins.lower, clean.lower)


def test_lid_gap_closes_with_both_upper_lids_at_maximum(rig, wire, rest):
    closed = wire.deform(quality.closed_lids_pose(rig))
    for side in "LR":
        margins = quality.find_lid_margins(rig, side)
        assert quality.lid_gap(margins, closed).largest < 0.5 * quality.lid_gap(margins, rest).largest


def test_seen_opening_of_a_slot_is_its_height_and_nothing_once_covered():
    """A skin plane at z = 1 with a slot 8 wide and 4 tall over an eyeball plane at z = 0, and a lash
    sheet at z = 2: from the front the eye shows the slot's height in every column (the lashes are
    not skin); the slot closed hides it, and so does the sheet when it is passed as skin; a skin
    behind the eyeball hides nothing (the whole window, 20 tall, is eyeball)."""
    skin_v, skin_f = grid(24, 24)  # -12..12 in x and y, unit cells
    skin_v += [-12.0, -12.0, 1.0]
    centres = skin_v[skin_f].mean(axis=1)
    slot = (np.abs(centres[:, 0]) < 4.0) & (np.abs(centres[:, 1]) < 2.0)
    eye_v, eye_f = grid(6, 6, 4.0)
    eye_v += [-12.0, -12.0, 0.0]
    lash_v = eye_v + np.array([0.0, 0.0, 2.0])
    vertices = np.vstack([skin_v, eye_v, lash_v])
    eye, lashes = eye_f + len(skin_v), eye_f + len(skin_v) + len(eye_v)
    corners = np.array([[-5.0, 0.0, 1.0], [5.0, 0.0, 1.0]])
    heights = quality.seen_opening(vertices, eye, skin_f[~slot], corners)
    assert heights.shape == (71,)  # 70 % of 10 wide, steps of 0.1: x in -3.5..3.5, inside the slot
    np.testing.assert_allclose(heights, 4.0, atol=0.11)
    assert quality.seen_opening(vertices, eye, skin_f, corners).max() == 0.0
    assert quality.seen_opening(vertices, eye, np.vstack([skin_f[~slot], lashes]), corners).max() == 0.0
    # with the eyeball's sphere, only hits on its surface count (not a piece deep inside it)
    far, near = (np.array([0.0, 0.0, -20.0]), 20.0), (np.array([0.0, 0.0, -1.0]), 20.0)
    np.testing.assert_allclose(
        quality.seen_opening(vertices, eye, skin_f[~slot], corners, sphere=far), heights
    )
    assert quality.seen_opening(vertices, eye, skin_f[~slot], corners, sphere=near).max() == 0.0
    behind = vertices.copy()
    behind[: len(skin_v), 2] = -1.0
    np.testing.assert_allclose(quality.seen_opening(behind, eye, skin_f, corners), 20.1, atol=0.11)


def test_seen_eyeball_open_at_rest_and_hidden_with_the_lids_closed(rig, wire, rest):
    closed = wire.deform(quality.closed_lids_pose(rig))
    for side in "LR":
        open_ = quality.seen_eyeball(rig, rest, side)
        shut = quality.seen_eyeball(rig, closed, side)
        assert open_.max() > 0.2 * rig.scale * 0.1  # an open eye shows a band of eyeball
        assert shut.max() <= 0.1 * open_.max()
    assert quality.most_eyeball_seen(rig, closed) == max(
        quality.seen_eyeball(rig, closed, s).max() for s in "LR"
    )


def test_lid_roughness_of_the_rest_margin_is_small(rig, wire, rest):
    margins = quality.find_lid_margins(rig, "L")
    assert quality.lid_roughness(margins, rest) < 0.01
    assert np.isfinite(quality.lid_roughness(margins, wire.deform(expression_pose(rig, "wink"))))


def test_find_lid_margins_mediapipe_mask_has_no_real_lids():
    require_shared_data("mediapipe/canonical.npz")
    from mimetic.fit.pipeline import rig_head

    mesh = mediapipe_canonical()
    rig = rig_head(mesh, mediapipe_landmarks(mesh)).rig
    margins = quality.find_lid_margins(rig, "L")
    assert not margins.usable and margins.bridged and "no real lids" in margins.reason
    with pytest.raises(ValueError, match="not usable"):
        quality.lid_gap(margins, rig.mesh.vertices)


# --------------------------------------------------------------------------- case builders


def test_mediapipe_face_faces_leave_out_the_slit_and_eye_triangles():
    require_shared_data("mediapipe/canonical.npz")
    mesh = mediapipe_canonical()
    faces = mediapipe_face_faces(mesh)
    assert faces.shape == (mesh.n_faces - 46, 3)  # 18 across the mouth, 14 across each eye
    assert not np.isin(faces, MEDIAPIPE_INNER_LIPS).all(axis=1).any()
    assert np.isin(mesh.faces, MEDIAPIPE_INNER_LIPS).all(axis=1).sum() == 18


def test_ict_identity_is_deterministic_and_scales_with_sigma():
    require_shared_data("ict-facekit/identities.npz")
    a, b = ict_identity(3, 1.0), ict_identity(3, 1.0)
    np.testing.assert_array_equal(a.vertices, b.vertices)
    neutral = ict_identity(3, 0.0).vertices
    wide = ict_identity(3, 2.0).vertices
    np.testing.assert_allclose(wide - neutral, 2 * (a.vertices - neutral), atol=1e-9)
    assert a.units == "cm" and a.n_vertices == 26_719


def test_rigid_motion_recovers_a_known_rotation_and_translation():
    rng = np.random.default_rng(0)
    points = rng.normal(size=(30, 3))
    angle = 0.4
    turn = np.array([[1, 0, 0], [0, np.cos(angle), -np.sin(angle)], [0, np.sin(angle), np.cos(angle)]])
    shift = np.array([0.1, -2.0, 0.5])
    rotation, translation = quality.rigid_motion(points, points @ turn.T + shift)
    np.testing.assert_allclose(rotation, turn, atol=1e-12)
    np.testing.assert_allclose(translation, shift, atol=1e-12)


def test_implied_weights_are_the_share_of_the_bone_motion_each_vertex_takes():
    motion = np.array([[0.0, -1.0, 0.0], [0.0, -2.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    offsets = np.array([[0.0, -0.5, 0.0], [0.3, -2.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 3.0, 0.0]])
    # half the motion; all of it (the sideways part is not the bone's); against it: 0; past it: 1
    np.testing.assert_allclose(quality.implied_weights(offsets, motion), [0.5, 1.0, 0.0, 1.0])
