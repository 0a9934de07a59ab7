"""Accessories riveted to the skin: which pieces qualify, exact rest, and a lash that closes with its lid."""

from __future__ import annotations

import dataclasses
from functools import cache

import numpy as np
import pytest
import scipy.sparse as sp

from mimetic.engines import ENGINES, make_engine
from mimetic.engines.attach import ride
from mimetic.engines.skinning import about, rotation_z
from mimetic.mesh.closest import closest_points
from mimetic.mesh.model import Mesh
from mimetic.rig.activations import pose
from mimetic.rig.anatomy import Accessories, find_accessories
from mimetic.rig.model import Rig
from mimetic.testing import small_rig

LASHES = 8  # lash columns along the upper lid margin


def lid_margin(rig: Rig, side: str = "L", count: int = LASHES) -> np.ndarray:
    """``count`` upper-lid vertices along the margin (the lowest of each column), inner to outer."""
    v = rig.mesh.vertices
    lid = np.asarray(rig.regions[f"eyelid_upper_{side}"])
    centre = rig.bone(f"eye_{side}").head
    radius = np.linalg.norm(rig.bone(f"eye_{side}").tail - centre)
    columns = np.linspace(centre[0] - 0.5 * radius, centre[0] + 0.5 * radius, count)
    margin = []
    for x in columns:
        near = lid[np.abs(v[lid, 0] - x) < 0.15 * radius]
        margin.append(near[np.argmin(v[near, 1])])
    return np.array(margin)


def strip(roots: np.ndarray, tips: np.ndarray, first: int) -> np.ndarray:
    """Triangles (2 (m - 1), 3) of a strip whose vertices are ``first + [roots..., tips...]``."""
    m = len(roots)
    r, t = first + np.arange(m), first + m + np.arange(m)
    return np.concatenate([np.stack([r[:-1], r[1:], t[:-1]], 1), np.stack([r[1:], t[1:], t[:-1]], 1)])


def with_pieces(rig: Rig, pieces: list[tuple[np.ndarray, np.ndarray, str]]) -> Rig:
    """``rig`` with extra components (vertices (k, 3), faces (m, 3) local, part), all weighted to the
    head bone, as a transfer that knows nothing of them would leave them."""
    mesh = rig.mesh
    vertices, faces, parts = [mesh.vertices], [mesh.faces], {k: list(v) for k, v in mesh.parts.items()}
    n, m = mesh.n_vertices, mesh.n_faces
    for v, f, part in pieces:
        vertices.append(v)
        faces.append(f + n)
        parts.setdefault(part, []).extend(range(m, m + len(f)))
        n, m = n + len(v), m + len(f)
    added = n - mesh.n_vertices
    head = np.zeros((added, rig.skin_weights.shape[1]))
    head[:, rig.bone_index("head")] = 1.0
    weights = sp.vstack([rig.skin_weights, sp.csr_matrix(head)]).tocsr()
    colors = None if mesh.colors is None else np.vstack([mesh.colors, np.full((added, 3), 0.5)])
    parts = {k: np.array(v) for k, v in parts.items()}
    new = Mesh(np.vstack(vertices), np.vstack(faces), parts, colors, mesh.units)
    return dataclasses.replace(rig, mesh=new, skin_weights=weights, anatomy=None)


@cache
def lashed_rig() -> tuple[Rig, np.ndarray, np.ndarray]:
    """The small default rig with a lash strip on the left upper lid, a floating piece in front of
    the face and an extra piece of the eye_L part. Returns (rig, lash vertices, other pieces' vertices)."""
    rig = small_rig()
    v, scale = rig.mesh.vertices, rig.scale
    centre = rig.bone("eye_L").head
    margin = lid_margin(rig)
    out = (v[margin] - centre) / np.linalg.norm(v[margin] - centre, axis=1, keepdims=True)
    roots = v[margin] + 0.0005 * scale * out
    up_out = out + np.array([0.0, 0.8, 0.0])  # lashes curl up and out
    tips = roots + 0.03 * scale * up_out / np.linalg.norm(up_out, axis=1, keepdims=True)
    lash = np.vstack([roots, tips])
    floating = lash + np.array([0.0, 0.0, 0.1 * scale])  # 2 cm in front of the lid: not attached
    in_eye_part = lash + np.array([0.0, -0.02 * scale, 0.0])  # attached to nothing: another part
    n = rig.n_vertices
    faces = strip(roots, tips, 0)
    rigged = with_pieces(
        rig, [(lash, faces, "skin"), (floating, faces, "skin"), (in_eye_part, faces, "eye_L")]
    )
    return rigged, n + np.arange(len(lash)), n + len(lash) + np.arange(2 * len(lash))


def test_generated_heads_have_no_accessories():
    for seed in (None, 3):
        rig = small_rig(seed)
        assert len(find_accessories(rig.mesh, rig.scale, rig.skin_weights)) == 0


def test_only_small_skin_pieces_near_the_skin_are_attached():
    rig, lash, _ = lashed_rig()
    found = find_accessories(rig.mesh, rig.scale, rig.skin_weights)
    np.testing.assert_array_equal(np.sort(found.vertices), lash)  # not the floating or eye_L piece
    np.testing.assert_allclose(found.weights.sum(axis=1), 1.0)
    # the rivets carry the lid's weight, not the head weight the pieces were given
    lid = rig.bone_index("eyelid_upper_L")
    assert np.all(found.weights[:, lid] > 0.2)
    roots = found.vertices < lash[0] + LASHES
    np.testing.assert_array_less(np.linalg.norm(found.offsets[roots], axis=1), 0.002 * rig.scale)


@pytest.mark.parametrize("name", ENGINES)
def test_a_lash_closes_with_its_lid_in_one_piece(name):
    rig, lash, others = lashed_rig()
    engine = make_engine(rig, name)
    rest = rig.mesh.vertices
    assert np.array_equal(engine.deform(pose(rig)), rest)  # the rest pose stays exact
    lid = rig.channels[rig.channel_index("eyelid_upper_L")]
    closed = engine.deform(pose(rig, {"eyelid_upper_L": lid.maximum}))
    roots, tips = lash[:LASHES], lash[LASHES:]
    # the roots stay on the lid: as close to the deformed skin as at rest
    skin = rig.mesh.faces[small_rig().mesh.parts["skin"]]  # the head's own skin triangles
    gap = closest_points(closed, skin, closed[roots]).distance
    assert gap.max() < 0.002 * rig.scale
    # the lash swings down with the lid in one piece (its ends turn less, as the lid's corners do)
    assert np.all(closed[tips, 1] < rest[tips, 1] - 0.01 * rig.scale)
    f = strip(rest[roots], rest[tips], lash[0])
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    before = np.linalg.norm(rest[edges[:, 0]] - rest[edges[:, 1]], axis=1)
    after = np.linalg.norm(closed[edges[:, 0]] - closed[edges[:, 1]], axis=1)
    np.testing.assert_allclose(after / before, 1.0, atol=0.3)
    # the pieces that are not attached keep their head weight: they do not move
    np.testing.assert_allclose(closed[others], rest[others], atol=1e-12)


def test_ride_adds_the_rivet_shift_and_turns_the_offset_by_the_blended_bones():
    rest = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0.2, 0.2, 0.5]])
    attachments = Accessories(
        vertices=np.array([3]),
        triangles=np.array([[0, 1, 2]]),
        bary=np.array([[0.6, 0.2, 0.2]]),
        offsets=np.array([[0.0, 0.0, 0.5]]) + rest[3] - np.array([0.2, 0.2, 0.5]),
        weights=np.array([[0.25, 0.75]]),
    )
    turn = about(rotation_z(0.3), np.zeros(3))
    transforms = np.stack([np.eye(4), turn])
    shift = np.array([0.1, -0.2, 0.3])
    deformed = rest.copy()
    deformed[:3] += shift
    out = ride(attachments, rest, deformed, transforms)
    linear = 0.25 * np.eye(3) + 0.75 * turn[:3, :3]
    np.testing.assert_allclose(out[3], rest[3] + shift + (linear - np.eye(3)) @ attachments.offsets[0])
    np.testing.assert_array_equal(out[:3], deformed[:3])
    np.testing.assert_array_equal(ride(attachments, rest, rest, np.stack([np.eye(4)] * 2)), rest)
