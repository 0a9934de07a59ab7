"""The weight repairs of rig transfer and its separate parts, on synthetic cases with known answers:
steps of the jaw weight on connected skin, soft mouth parts (gums joined to the tongue) by their
nearer tooth row, and which separate pieces turn with an eyeball."""

from __future__ import annotations

import numpy as np

from mimetic.fit.parts import _on_eyeball, soft_mouth_jaw
from mimetic.fit.transfer import _smooth_jaw


def grid(size: int, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """A flat (size × size) grid in the z = 0 plane centred on the origin: vertices (n, 3), faces (m, 3)."""
    x, y = np.meshgrid(np.arange(size) - (size - 1) / 2, np.arange(size) - (size - 1) / 2, indexing="ij")
    vertices = np.stack([x.ravel(), y.ravel(), np.zeros(x.size)], axis=1) * spacing
    k = np.arange(size * size).reshape(size, size)
    a, b, c, d = k[:-1, :-1].ravel(), k[1:, :-1].ravel(), k[1:, 1:].ravel(), k[:-1, 1:].ravel()
    return vertices, np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def test_a_jaw_weight_step_on_connected_skin_becomes_a_slope():
    """The left half of the lower rows on the jaw, the rest on the head (a commissure fold cut one row
    deep, ending at x = 0): the step becomes a slope a few lengths wide; far away nothing changes."""
    vertices, faces = grid(61, 0.05)  # 3 × 3 cm at 0.5 mm
    weights = np.zeros((len(vertices), 3))  # head, jaw, a third bone
    lower = (vertices[:, 1] < 0) & (vertices[:, 0] < 0)
    weights[lower, 1] = 1.0
    weights[~lower, 0] = 1.0
    before = weights.copy()
    length = 0.15
    out = _smooth_jaw(weights, vertices, faces, length, jaw=1)
    np.testing.assert_array_equal(weights, before)  # the input is not modified
    np.testing.assert_allclose(out.sum(axis=1), 1.0)
    assert np.all(out >= 0) and np.all(out[:, 2] == 0)
    # across the step, away from its ends, neighbours now differ by far less than 1, in the same order
    column = np.flatnonzero((np.abs(vertices[:, 0] + 0.75) < 1e-9) & (np.abs(vertices[:, 1]) < 0.6))
    jaw = out[column[np.argsort(vertices[column, 1])], 1]
    assert np.all(np.diff(jaw) <= 1e-12)
    assert np.abs(np.diff(jaw)).max() < 0.2
    # far from the step (8 lengths), the weights are as they were
    far = (np.abs(vertices[:, 1]) > 8 * length) & (np.abs(vertices[:, 0]) > 8 * length)
    np.testing.assert_allclose(out[far], weights[far], atol=1e-3)


def test_a_jaw_weight_step_across_parted_lips_stays_a_step():
    """Where the lips really part no face spans the opening: the two sheets keep their weights."""
    top, faces = grid(21, 0.05)
    bottom = top - np.array([0.0, 1.05, 0.0])  # a second sheet, not joined to the first
    vertices = np.concatenate([top, bottom])
    faces = np.concatenate([faces, faces + len(top)])
    weights = np.zeros((len(vertices), 2))
    weights[: len(top), 0] = 1.0  # upper lip: head
    weights[len(top) :, 1] = 1.0  # lower lip: jaw
    np.testing.assert_allclose(_smooth_jaw(weights, vertices, faces, 0.15, jaw=1), weights, atol=1e-12)


def test_the_neck_weight_is_diffused_again_over_its_own_length():
    """Neck skin of 1 cm edges (y < 0): the jaw weight steps from 0.5 to 0 across one of them (where
    the chin's ramp meets the still neck); diffused again there over 3 edges, no neck edge keeps a
    step over 0.15, and the skin above the neck keeps what the first, short diffusion gave it."""
    vertices, faces = grid(21, 1.0)
    weights = np.zeros((len(vertices), 2))
    weights[:, 1] = np.where(vertices[:, 1] > -5, 0.5, 0.0)
    weights[:, 0] = 1.0 - weights[:, 1]
    neck = vertices[:, 1] < 0
    plain = _smooth_jaw(weights, vertices, faces, 0.05, 1)
    out = _smooth_jaw(weights, vertices, faces, 0.05, 1, neck=neck, neck_length=3.0)
    np.testing.assert_array_equal(out[~neck], plain[~neck])
    np.testing.assert_allclose(out.sum(axis=1), 1.0)
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    inside = edges[(vertices[edges, 1] < -2).all(axis=1)]
    assert np.abs(np.diff(plain[inside, 1], axis=1)).max() > 0.45
    assert np.abs(np.diff(out[inside, 1], axis=1)).max() < 0.15


def test_soft_mouth_vertices_follow_their_nearer_tooth_row():
    upper = np.array([[x, 1.0, 0.0] for x in np.linspace(-2, 2, 9)])  # a tooth row at y = 1
    lower = upper - np.array([0.0, 2.0, 0.0])  # and one at y = -1
    points = np.array(
        [
            [0.0, 1.6, 0.0],  # upper gum: head
            [0.25, 0.6, 0.0],  # a papilla between upper teeth, reaching down: still head
            [0.0, -1.5, -0.5],  # lower gum: jaw
            [0.0, -0.8, -0.6],  # the tongue's side, inside the lower arch: jaw
            [0.0, 0.0, 0.0],  # halfway: shared
        ]
    )
    jaw = soft_mouth_jaw(points, upper, lower)
    np.testing.assert_allclose(jaw[:2], 0.0, atol=1e-12)
    np.testing.assert_allclose(jaw[2:4], 1.0, atol=1e-12)
    assert abs(jaw[4] - 0.5) < 1e-12


def _sphere_piece(centre, radius, *, theta_max=np.pi, scale=1.0, n=24):
    """A sphere's vertices (k, 3) and faces (t, 3) from its front pole (+Z) out to polar angle
    ``theta_max``, its radius × ``scale``: a globe (π), a cap, or a shell in front."""
    t = np.linspace(0.0, theta_max, n)
    p = np.linspace(0.0, 2 * np.pi, 2 * n, endpoint=False)
    tt, pp = np.meshgrid(t, p, indexing="ij")
    r = radius * scale
    points = centre + r * np.stack([np.sin(tt) * np.cos(pp), np.sin(tt) * np.sin(pp), np.cos(tt)], -1)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(2 * n), indexing="ij")
    a, b = i * 2 * n + j, i * 2 * n + (j + 1) % (2 * n)
    quads = np.stack([a, b, b + 2 * n, a + 2 * n], -1).reshape(-1, 4)
    return points.reshape(-1, 3), np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])


def _part(piece, keep):
    """The faces of ``piece`` (vertices, faces) all of whose corners ``keep`` (k,) bool holds."""
    vertices, faces = piece
    return vertices, faces[keep[faces].all(axis=1)]


def _on(piece, radius):
    vertices, faces = piece
    return _on_eyeball(vertices, faces, np.unique(faces), radius)


def test_eyeball_pieces_turn_with_the_eye_and_films_over_it_do_not():
    """A globe, a half globe, a cornea and an iris turn with the gaze, whichever way the eye looks; a
    tear line, an occlusion shell or a blend patch in the inner corner (films over the opening, which
    end along the lids; ICT's eyes have all three) ride the lids."""
    centre, radius = np.array([3.0, 3.5, 8.0]), 1.2
    globe = _sphere_piece(centre, radius)
    half = _sphere_piece(centre, radius, theta_max=np.pi / 2)
    cornea = _sphere_piece(centre + np.array([0, 0, 0.3]), 0.9, theta_max=0.6)
    iris = _sphere_piece(centre, radius * 0.9, theta_max=0.5, scale=1.0)
    turn = np.array([[np.cos(0.4), 0, np.sin(0.4)], [0, 1, 0], [-np.sin(0.4), 0, np.cos(0.4)]])  # 23° aside
    aside = ((cornea[0] - centre) @ turn.T + centre, cornea[1])
    for piece in (globe, half, cornea, iris, aside):
        assert _on(piece, radius)
    # a shell over the opening whose edge follows the lids (an eye-shaped rim, not a circle), a band
    # along the lower lid and a patch in the inner corner
    shell = _sphere_piece(centre, radius, theta_max=1.2, scale=1.05)
    d = shell[0] - centre
    inside_lids = np.abs(d[:, 1]) <= 0.55 * radius * np.cos(0.9 * d[:, 0] / radius)
    opening = _part(shell, inside_lids)
    lower = _part(shell, (d[:, 1] < 0) & (d[:, 1] > -0.6 * radius) & (np.abs(d[:, 0]) < 0.9 * radius))
    corner = _part(shell, (d[:, 0] < -0.5 * radius) & (np.abs(d[:, 1]) < 0.3 * radius))
    for piece in (opening, lower, corner):
        assert not _on(piece, radius)


def test_a_mouth_modelled_shut_is_cut_along_the_lips_line_and_an_open_one_is_not():
    """A sheet whose lips meet along y = 0 between corners at x = ±1 (a mouth sealed by faces, as
    MediaPipe's canonical mesh): the faces from above the line to below it, between the corners, seal
    it; beside the corners nothing is cut; with a surface behind the lips (a mouth's insides), or a
    slot between them, there is no seal."""
    from mimetic.fit.sides import CORNER_FREE_REL, seal_faces
    from mimetic.mesh.openings import Opening

    vertices, faces = grid(41, 0.1)  # 4 × 4 cm
    x = np.linspace(-1.0, 1.0, 21)
    line = np.column_stack([x, np.full_like(x, 0.05), np.zeros_like(x)])  # between two rows of vertices
    mouth = Opening(line, line)
    sealed = seal_faces(vertices, faces, mouth)
    centres = vertices[faces].mean(axis=1)
    inset = 1.0 - 2.0 * CORNER_FREE_REL  # the corners' inset, along the 2 cm line
    spanning = (vertices[faces, 1].max(axis=1) > 0.05) & (vertices[faces, 1].min(axis=1) < 0.05)
    inside = np.abs(centres[:, 0]) < inset - 0.1
    assert sealed[spanning & inside].all() and sealed.sum() >= 2 * 14
    assert not sealed[~spanning].any() and not sealed[np.abs(centres[:, 0]) > inset + 0.1].any()
    # with a surface 1 cm behind the lips (a mouth's insides), the lips are a mouth's, not a seal
    inside = np.concatenate([vertices, vertices - [0.0, 0.0, 1.0]])
    assert not seal_faces(inside, np.concatenate([faces, faces + len(vertices)]), mouth).any()
    slot = faces[~spanning | (np.abs(centres[:, 0]) > 1.0)]  # the mouth open: no face across it
    assert not seal_faces(vertices, slot, mouth).any()


def test_the_lips_of_mediapipes_sealed_mask_keep_their_jaw_weights():
    """MediaPipe's canonical mesh closes its mouth with faces from the upper lip's inner edge to the
    lower lip's: the lips' split and the jaw weight's diffusion ran through them, and the upper lip's
    inner edge took the jaw weight 0.5-0.6 (the lower lip's 0.5-0.84; a jaw drop opened it 1.05 cm
    from the row above, and the upper lip followed the jaw 0.22)."""
    from mimetic.fit.pipeline import rig_head
    from mimetic.testing import mediapipe_canonical, mediapipe_landmarks, require_shared_data

    require_shared_data("mediapipe/canonical.npz")
    mesh = mediapipe_canonical()
    rig = rig_head(mesh, mediapipe_landmarks(mesh)).rig
    jaw = rig.skin_weights.toarray()[:, rig.bone_index("jaw")]
    upper_middle, lower_middle = [81, 82, 13, 312, 311], [178, 87, 14, 317, 402]  # the inner lip edges
    assert jaw[upper_middle].max() < 0.2 and jaw[13] < 0.1  # 0.51-0.60 before
    assert jaw[lower_middle].min() > 0.65 and jaw[14] > 0.85  # 0.66-0.84 before
