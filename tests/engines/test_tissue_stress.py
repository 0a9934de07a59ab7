"""Stress the tissue engine's dynamics (issue 12, item 7; the long run is ``benchmarks/stress_physics.py``).

A short clip of random extreme activations (muscles jumping between 0 and 1 in random subsets every
few frames, all of them at once for a while) drives the kernel's BDF2 ``step`` with the engine's
calibrated forces, as ``TissueEngine.simulate`` does; then every activation is released for one
second. The same clip on the same head in millimetres must give the same motion in metres.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from mimetic.engines.tissue import HEAD_HEIGHT_M, TissueEngine, TissueState, prism_volumes, step
from mimetic.engines.volume import tet_volumes
from mimetic.mesh.model import Mesh
from mimetic.rig.recipe import build_rig
from mimetic.testing import small_head, small_rig

FPS = 24.0  # one step per frame, of the longest length (STEP_MAX_S)
STRESS_STEPS = 40  # 1.7 s of clip
RELEASE_STEPS = 24  # 1 s with every activation at 0
MM_STEPS = 8  # the millimetre head follows the first third of a second


def extreme_clip(n_muscles: int, frames: int, seed: int = 0) -> np.ndarray:
    """Activations (frames, a): all muscles at 1 for the first 10 frames, then every 3 frames a random
    subset (each muscle with probability 0.4) jumps to 0 or 1."""
    rng = np.random.default_rng(seed)
    out = np.zeros((frames, n_muscles))
    now = np.ones(n_muscles)
    for f in range(frames):
        if f >= 10 and f % 3 == 0:
            subset = rng.random(n_muscles) < 0.4
            now[subset] = rng.integers(0, 2, subset.sum())
        out[f] = now
    return out


def drive(engine: TissueEngine, clip: np.ndarray) -> tuple[list[TissueState], TissueState]:
    """The states after each frame of ``clip`` (frames, a) at ``FPS``, ramping as ``simulate`` does,
    and the last state; stops at the first non-finite state."""
    model = engine.model
    n_sub = engine.steps_per_frame(FPS)
    h = 1.0 / (FPS * n_sub)
    state, previous, states = TissueState.at_rest(model), np.zeros(clip.shape[1]), []
    for target in clip:
        for i in range(1, n_sub + 1):
            now = previous + (target - previous) * (i / n_sub)
            state = step(model, state, (engine.forces @ now).reshape(-1, 3), h)
        previous = target
        states.append(state)
        if not (np.isfinite(state.x).all() and np.isfinite(state.v).all()):
            break
    return states, state


def skin_displacement(engine: TissueEngine, x: np.ndarray) -> float:
    """Largest skin node displacement from rest over the head height."""
    k = engine.volume.n_skin
    return float(np.linalg.norm(x[:k] - engine.model.rest[:k], axis=1).max()) / HEAD_HEIGHT_M


def kinetic(engine: TissueEngine, state: TissueState) -> float:
    return float(0.5 * np.sum(engine.model.mass[:, None] * state.v**2))


def millimetre_rig():
    """``small_rig(None)`` built ×10 in millimetres (``scale`` about 220)."""
    head = small_head(None)
    m = head.mesh
    big = dataclasses.replace(
        head,
        mesh=Mesh(m.vertices * 10.0, m.faces, m.parts, m.colors, "cm"),  # build_rig labels its rig cm
        eye_centres=head.eye_centres * 10.0,
        eye_radius=head.eye_radius * 10.0,
    )
    rig = build_rig(big)
    return dataclasses.replace(
        rig, mesh=Mesh(rig.mesh.vertices, m.faces, m.parts, m.colors, "mm"), units="mm"
    )


@pytest.fixture(scope="module")
def engine():
    return TissueEngine(small_rig(None))


@pytest.fixture(scope="module")
def stressed(engine):
    """(clip, states) of the stress clip followed by the release."""
    a = len(engine.muscles)
    clip = np.concatenate([extreme_clip(a, STRESS_STEPS), np.zeros((RELEASE_STEPS, a))])
    states, _ = drive(engine, clip)
    return clip, states


def test_extreme_activations_stay_finite_and_bounded(engine, stressed):
    clip, states = stressed
    assert len(states) == len(clip)  # drive stops at the first NaN
    assert all(np.isfinite(s.x).all() and np.isfinite(s.v).all() for s in states)
    worst = max(skin_displacement(engine, s.x) for s in states[:STRESS_STEPS])
    assert 0.02 < worst < 0.3  # measured 0.14 head heights: the clip moves the skin, within a face's reach
    tets = engine.volume.tets
    inverted = max(np.count_nonzero(tet_volumes(s.x, tets) < 0) for s in states[:STRESS_STEPS])
    assert inverted < 0.06 * len(tets)  # measured 945 of 30,468 (3.1 %) at the worst step


def test_release_settles_back_to_rest(engine, stressed):
    _, states = stressed
    peak = max(kinetic(engine, s) for s in states[:STRESS_STEPS])
    after = kinetic(engine, states[-1])
    assert peak > 1e-6  # measured 9.1e-4 J: the jumps do shake the tissue
    assert after < 1e-5 * peak  # measured 1.9e-11 J (2e-8 of the peak) one second after the release
    assert skin_displacement(engine, states[-1].x) < 2e-3  # measured 2.1e-4 head heights from rest
    x = states[-1].x
    assert np.count_nonzero(tet_volumes(x, engine.volume.tets) < 0) == 0  # none at rest
    rest = prism_volumes(engine.model.rest, engine.model.prisms)
    flipped = np.sign(prism_volumes(x, engine.model.prisms)) != np.sign(rest)
    needle = 1e-3 * np.median(np.abs(rest))  # 38 prisms at the mouth's corners are thinner
    assert (
        np.abs(rest[flipped]).max(initial=0.0) < needle
    )  # measured: 2 flipped, the larger 5e-4 of the median


def test_chain_on_a_stressed_frame_with_the_jaw_at_its_ends_is_finite(engine, stressed):
    _, states = stressed
    rig = engine.rig
    jaw = rig.channel_index("jaw_open")
    skin = engine._skin(states[STRESS_STEPS - 1].x)
    for end in (rig.channels[jaw].minimum, rig.channels[jaw].maximum):
        values = np.zeros(len(rig.channels))
        values[engine.muscles] = 1.0
        values[jaw] = end
        assert np.isfinite(engine.chain.apply(skin, values)).all()


def test_millimetre_head_moves_the_same_in_metres(engine, stressed):
    clip, states = stressed
    mm = TissueEngine(millimetre_rig())
    assert mm.rig.units == "mm" and 200 < mm.rig.scale < 240  # measured 220.1
    np.testing.assert_allclose(mm.model.rest, engine.model.rest, rtol=0, atol=1e-12)  # metres both
    mm_states, _ = drive(mm, clip[:MM_STEPS])
    assert len(mm_states) == MM_STEPS
    worst = max(np.abs(a.x - b.x).max() for a, b in zip(mm_states, states[:MM_STEPS], strict=True))
    assert worst < 1e-9  # measured 5.7e-13 m: the physics does not see the units
