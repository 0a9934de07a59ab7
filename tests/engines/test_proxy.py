"""The physical engines through a proxy: a dense skin simulated on a decimated copy, every vertex
following it, exact at rest, close to the full-resolution answer, chosen automatically or by option."""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from mimetic.animate.expressions import compose_pose
from mimetic.engines import make_engine
from mimetic.engines import volume as volume_module
from mimetic.engines.volume import MIN_PROXY, build_volume, proxy_size, solid_triangles
from mimetic.errors import MimeticError
from mimetic.mesh.weld import find_weld
from mimetic.testing import small_rig

PROXY = 1_500
"""Proxy skin vertices on the small head (2,578 welded skin vertices): coarse, so the test is fast
and the proxy's effect shows."""


@cache
def engine(name: str, proxy: int | str):
    return make_engine(small_rig(None), name, proxy=proxy)


@cache
def joy(name: str, proxy: int | str) -> np.ndarray:
    rig = small_rig(None)
    return engine(name, proxy).deform(compose_pose(rig, (("joy", 1.0),)))


def test_a_skin_above_the_threshold_gets_an_automatic_proxy(monkeypatch):
    rig = small_rig(None)
    full = build_volume(rig, proxy="off").n_skin
    monkeypatch.setattr(volume_module, "PROXY_ABOVE", full - 1)  # the small head counts as dense
    monkeypatch.setattr(volume_module, "PROXY_VERTICES", PROXY)
    volume = build_volume(rig)
    assert volume.is_proxy and volume.proxy_skin.triangles.shape == (int((volume.index >= 0).sum()), 3)
    assert abs(volume.n_skin - PROXY) < 0.05 * PROXY
    monkeypatch.setattr(volume_module, "PROXY_ABOVE", full)
    assert not build_volume(rig).is_proxy  # at the threshold: the full skin


@pytest.mark.parametrize("name", ["fem", "tissue"])
def test_a_proxied_engine_rests_exactly_and_poses(name):
    rig = small_rig(None)
    proxied = engine(name, PROXY)
    rest = proxied.deform(np.zeros(len(rig.channels)))
    assert rest.shape == rig.mesh.vertices.shape and rest.dtype == np.float64
    assert np.array_equal(rest, rig.mesh.vertices)  # exactly the rest, every vertex
    where = np.concatenate([rig.regions["upper_lip"], rig.regions["cheek_L"]])
    moved = np.linalg.norm(joy(name, PROXY)[where] - rig.mesh.vertices[where], axis=1)
    assert moved.max() > 0.02 * rig.scale


@pytest.mark.parametrize("name", ["fem", "tissue"])
def test_the_proxy_answer_is_close_to_the_full_resolution_one(name):
    """Measured on the small head with a proxy of 1,500 of its 2,578 skin vertices, joy: rms 0.28 %
    (fem) and 0.24 % (tissue) of the head height, at most 2.9 % and 2.5 % (at the lips), against a
    motion of 8 % at most."""
    rig = small_rig(None)
    full, proxied = joy(name, "off"), joy(name, PROXY)
    assert engine(name, PROXY).volume.is_proxy and not engine(name, "off").volume.is_proxy
    assert full.shape == proxied.shape == rig.mesh.vertices.shape
    gap = np.linalg.norm(proxied - full, axis=1) / rig.scale
    motion = np.linalg.norm(full - rig.mesh.vertices, axis=1) / rig.scale
    assert np.sqrt(np.mean(gap**2)) < 0.004
    assert gap.max() < 0.04
    assert np.sqrt(np.mean(gap**2)) < 0.25 * np.sqrt(np.mean(motion**2))  # the proxy's error is small
    forehead = rig.regions["forehead"]  # far from the mouth, joy's skin hardly differs
    assert gap[forehead].max() < 0.005


def test_every_skin_vertex_follows_its_proxy_triangle_and_seams_move_together():
    rig = small_rig(None)
    volume = engine("fem", PROXY).volume
    weld = find_weld(rig.mesh)
    rng = np.random.default_rng(0)
    linear = rng.normal(size=(3, 2))  # a linear field over the proxy's nodes comes out linear
    nodes = volume.nodes[: volume.n_skin]
    carried = volume.to_vertices(nodes @ linear)  # (n, 2)
    on = volume.index >= 0
    at = np.einsum("nk,nkd->nd", volume.proxy_skin.bary, nodes[volume.proxy_skin.triangles])
    np.testing.assert_allclose(carried[on], at @ linear, atol=1e-9)
    # the proxy's surface lies near the skin: the barycentric points are the dense ones, within 2.5 %
    # of the head (measured: 1.7 % at most, in the upper lip; 0.2 % for 99 % of them)
    assert np.linalg.norm(at - rig.mesh.vertices[on], axis=1).max() < 0.025 * rig.scale
    moved = engine("fem", PROXY).deltas[rig.channel_index("zygomatic_major_L")]
    np.testing.assert_array_equal(moved, moved[weld.first][weld.index])  # both copies of a seam vertex


def test_the_proxy_option_overrides_the_automatic_choice(monkeypatch):
    assert proxy_size(19_167) is None  # ICT-FaceKit's skin: full resolution
    assert proxy_size(300_000) == volume_module.PROXY_VERTICES  # a 420k-vertex scan's skin
    assert proxy_size(50_000, "off") is None  # 'off' keeps a skin the volume can take whole
    assert proxy_size(2_578, 1_500) == 1_500
    assert proxy_size(2_578, 5_000) is None  # a skin no larger than the proxy keeps its resolution
    rig = small_rig(None)
    monkeypatch.setattr(volume_module, "PROXY_ABOVE", 100)
    assert not build_volume(rig, proxy="off").is_proxy


@pytest.mark.parametrize("bad", ["fast", -3, MIN_PROXY - 1, True, 2.5, None])
def test_a_bad_proxy_value_is_refused_with_what_to_say(bad):
    with pytest.raises(MimeticError, match=r"'auto'.*'off'.*at least 500"):
        proxy_size(300_000, bad)


def test_only_a_volume_too_big_even_as_asked_is_refused(monkeypatch):
    monkeypatch.setattr(volume_module, "MAX_NODES", 3 * 20_000)
    assert proxy_size(300_000) == 20_000  # the automatic proxy fits
    with pytest.raises(MimeticError, match=r"a proxy of 25,000 vertices.*at most 60,000 nodes.*proxy='auto'"):
        proxy_size(300_000, 25_000)
    with pytest.raises(MimeticError, match=r"skin has 300,000 vertices.*--proxy auto"):
        proxy_size(300_000, "off")


def test_flat_slivers_and_specks_hold_no_tissue():
    """Quadric collapse of a subdivided scan leaves triangles with a vertex on the opposite edge and
    clusters of three vertices within 1e-7 of each other; their prisms could not be inverted."""
    vertices = np.array(
        [
            [0, 0, 0],
            [1, 0, 0],
            [0, 1, 0],
            [1, 1, 0],
            [0.5, 0.5 + 1e-9, 0],
            [2, 2, 0],
            [2 + 1e-8, 2, 0],
            [2, 2 + 1e-8, 0],
        ],
        dtype=np.float64,
    )
    faces = np.array([[0, 1, 2], [1, 3, 2], [1, 4, 2], [5, 6, 7], [0, 1, 3]])
    keep = solid_triangles(vertices, faces)
    assert keep.shape == (5,) and keep.dtype == bool
    np.testing.assert_array_equal(keep, [True, True, False, False, True])  # the cap on 1-2; the speck


def test_tying_the_skin_in_chunks_ties_it_the_same(monkeypatch):
    rig = small_rig(None)
    whole = engine("fem", PROXY).volume.proxy_skin
    monkeypatch.setattr(volume_module, "EMBED_CHUNK", 1_000)  # the small head's 2,610 in three chunks
    chunked = build_volume(rig, proxy=PROXY).proxy_skin
    assert chunked.triangles.shape == whole.triangles.shape == (2_610, 3)
    np.testing.assert_array_equal(chunked.triangles, whole.triangles)
    np.testing.assert_array_equal(chunked.bary, whole.bary)
