"""Baking engines to a linear basis: exact at rest and at each channel's extreme, bounded error."""

from __future__ import annotations

import logging
import warnings
from functools import cache

import numpy as np
import pytest

from mimetic.engines import ENGINES, make_engine
from mimetic.engines.bake import RIGID, bake, channel_extent, random_poses
from mimetic.engines.basis import basis_bytes, evaluate_basis, human_bytes
from mimetic.errors import MimeticWarning
from mimetic.testing import small_rig


@cache
def baked(name: str, seed: int | None = None):
    """An engine and its bake, with at most 12 correctives and 16 sample poses (fewer where the engine
    bakes with fewer: the tissue engine takes none and 4)."""
    engine = make_engine(small_rig(seed), name)
    correctives = min(12, getattr(engine, "bake_correctives", 12))
    return engine, bake(engine, correctives=correctives, samples=min(16, getattr(engine, "bake_samples", 16)))


@pytest.mark.parametrize("name", ENGINES)
def test_bake_reproduces_rest_and_each_channel_at_its_extreme(name):
    engine, result = baked(name)
    basis, rig = result.basis, engine.rig
    assert basis.channels == rig.channel_names
    assert basis.neutral.shape == rig.mesh.vertices.shape and basis.deltas.shape == (
        len(rig.channels),
        rig.n_vertices,
        3,
    )
    zero = np.zeros(len(rig.channels))
    np.testing.assert_array_equal(evaluate_basis(basis, zero), rig.mesh.vertices)
    for j, ch in enumerate(rig.channels):
        if not ch.name.startswith(("zygomatic_major", "frontalis", "mentalis", "eyelid_upper", "jaw_open")):
            continue
        x, central = channel_extent(ch.minimum, ch.maximum)
        values = zero.copy()
        values[j] = x
        if central:
            continue  # a central secant is exact only for the odd part; checked by the error bound
        np.testing.assert_allclose(
            evaluate_basis(basis, values), engine.deform(values), atol=1e-9, err_msg=ch.name
        )


@pytest.mark.parametrize("name", ENGINES)
def test_bake_error_is_within_the_reported_bound(name):
    engine, result = baked(name)
    report = result.report
    assert report.samples == min(16, getattr(engine, "bake_samples", 16))
    # correctives, measured at the channels' extremes, lower the error over random poses; at the worst
    # vertex of the worst pose they may overshoot a little (wire, default head: 0.7655 against 0.7644)
    assert report.rms_error <= report.rms_error_linear
    assert 0 <= report.max_error <= 1.01 * report.max_error_linear
    assert report.rms_error <= report.max_error
    assert report.max_error < 0.1 * engine.rig.scale
    # fresh random poses (another seed) stay within twice the reported worst error
    poses = random_poses(engine, 8, np.random.default_rng(123))
    worst = max(
        np.linalg.norm(evaluate_basis(result.basis, p) - engine.deform(p), axis=1).max() for p in poses
    )
    assert worst <= 2.0 * report.max_error + 1e-9
    assert any("bake error" in line for line in report.lines())


@pytest.mark.parametrize("name", [e for e in ENGINES if e != "tissue"])  # the tissue engine bakes none
def test_bake_correctives_make_their_pairs_exact(name):
    engine, result = baked(name)
    rig, basis = engine.rig, result.basis
    assert 0 < len(basis.correctives) <= 12
    index = {n: j for j, n in enumerate(rig.channel_names)}
    for corrective in basis.correctives:
        values = np.zeros(len(rig.channels))
        for channel in corrective.channels:
            ch = rig.channel(channel)
            values[index[channel]] = channel_extent(ch.minimum, ch.maximum)[0]
        if any(
            channel_extent(rig.channel(c).minimum, rig.channel(c).maximum)[1] for c in corrective.channels
        ):
            continue  # central secants are exact only for the odd part
        np.testing.assert_allclose(evaluate_basis(basis, values), engine.deform(values), atol=1e-9)


def test_evaluate_rigid_turns_the_head_as_the_engine_does(rig, engine):
    from mimetic.engines.bake import evaluate_rigid

    basis = bake(engine, correctives=0, samples=2).basis
    pose = np.zeros(len(rig.channels))
    pose[rig.channel_index("head_yaw")] = 0.3
    pose[rig.channel_index("head_pitch")] = -0.1
    pose[rig.channel_index("head_roll")] = 0.05
    turned = evaluate_rigid(rig, basis, pose)
    np.testing.assert_allclose(turned, engine.deform(pose), atol=1e-9)
    assert np.abs(turned - evaluate_basis(basis, pose)).max() > 1.0  # the basis alone does not turn


class _WarningEngine:
    """Wraps an engine; warns (``MimeticWarning``) on every pose that moves the jaw, as the tissue
    engine does when an equilibrium stops short."""

    def __init__(self, engine, jaw: int):
        self.engine, self.rig, self.jaw = engine, engine.rig, jaw

    def deform(self, values):
        if values[self.jaw] != 0.0:
            warnings.warn(f"stopped short at jaw {values[self.jaw]:.3f}", MimeticWarning, stacklevel=2)
        return self.engine.deform(values)


def test_bake_gives_an_engines_warning_once_with_how_many_poses_gave_it(rig, engine):
    jaw = rig.channel_index("jaw_open")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = bake(_WarningEngine(engine, jaw), correctives=0, samples=40, seed=1)
    mine = [w for w in caught if issubclass(w.category, MimeticWarning)]
    assert len(mine) == 1
    moved = 1 + int(np.count_nonzero(random_poses(engine, 40, np.random.default_rng(1))[:, jaw]))
    # the neutral, one pose per channel but the rigid ones (two for a central secant), the samples
    poses = 1 + sum(
        1 + channel_extent(ch.minimum, ch.maximum)[1] for ch in rig.channels if ch.name not in RIGID
    )
    poses += 40
    assert f"({moved} of {poses} poses; the first shown)" in str(mine[0].message)
    assert str(mine[0].message).startswith("bake: stopped short at jaw")
    assert mine[0].filename == __file__  # points at the caller of bake
    assert result.basis.deltas.shape[0] == len(rig.channels)


def test_bake_keeps_the_strongest_pairs_and_says_the_basis_size_first(caplog):
    engine = make_engine(small_rig(), "wire")
    with caplog.at_level(logging.INFO, logger="mimetic.engines.bake"):
        few = bake(engine, correctives=3, samples=1).basis
    c, n = len(engine.rig.channels), engine.rig.n_vertices
    said = [r.getMessage() for r in caplog.records if "the basis will hold" in r.getMessage()]
    assert len(said) == 1 and human_bytes(basis_bytes(c, n, 3)) in said[0] and f"{n:,} vertices" in said[0]
    # the pairs kept with a budget of 3 are the 3 strongest of a budget of 12, in the same order
    many = baked("wire")[1].basis
    assert [t.channels for t in few.correctives] == [t.channels for t in many.correctives[:3]]
    for a, b in zip(few.correctives, many.correctives, strict=False):
        np.testing.assert_array_equal(a.delta, b.delta)


def test_basis_bytes_and_human_bytes():
    assert basis_bytes(64, 1_000_000) == 65 * 1_000_000 * 24
    assert basis_bytes(2, 10, 1, itemsize=4) == 4 * 10 * 12
    assert [human_bytes(x) for x in (0, 1023, 1536, 5 * 2**20, 1.5 * 2**30, 300 * 2**30)] == [
        "0 B",
        "1023 B",
        "1.5 KiB",
        "5 MiB",
        "1.5 GiB",
        "300 GiB",
    ]
