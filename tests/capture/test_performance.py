"""Solving captured performances: synthetic ground truth (a rig plays a known clip, its markers are
captured with noise, dropouts, spikes and head motion), the smoother, bad input, retargeting, edits."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from mimetic.animate.keyframes import from_clip
from mimetic.capture import (
    CaptureError,
    Performance,
    Trajectories,
    keep_edits,
    retarget,
    solve_performance,
)
from mimetic.capture.expression import determined_channels
from mimetic.capture.smooth import smooth_points, smoothed_noise, smoothing_weight
from mimetic.engines import make_engine
from mimetic.engines.basis import evaluate_basis
from mimetic.engines.skinning import rotation_x, rotation_y, rotation_z
from mimetic.errors import MimeticWarning
from mimetic.rig.activations import Clip

FPS = 60.0
NOISE_MM = 1.0
NOISE = smoothed_noise(0.1 / np.sqrt(3), FPS, 8.0)  # 1 mm (3D RMS) in cm per coordinate, after smoothing


def smooth_clip(rig, names, frames: int, rng) -> np.ndarray:
    """(frames, c) activations: 0.5 s at rest, then each named channel a smooth random curve in range."""
    t = np.arange(frames) / FPS
    ramp = np.clip((t - 0.5) / 0.5, 0.0, 1.0)
    values = np.zeros((frames, len(rig.channels)))
    for name in names:
        ch = rig.channel(name)
        wave = np.sin(2 * np.pi * rng.uniform(0.2, 1.0) * t + rng.uniform(0, 2 * np.pi))
        top = ch.maximum * rng.uniform(0.4, 0.9)
        bottom = ch.minimum * rng.uniform(0.4, 0.9)
        values[:, rig.channel_index(name)] = ramp * np.where(wave > 0, top * wave, -bottom * wave)
    return values


def head_angles(frames: int, scale: float = 1.0) -> np.ndarray:
    t = np.arange(frames) / FPS
    ramp = np.clip((t - 0.5) / 0.5, 0.0, 1.0)
    waves = [
        0.2 * np.sin(2 * np.pi * 0.3 * t),
        0.1 * np.sin(2 * np.pi * 0.5 * t),
        0.05 * np.sin(2 * np.pi * 0.2 * t),
    ]
    return scale * ramp[:, None] * np.stack(waves, axis=1)


def capture(rig, basis, markers, values, *, angles, rng, noise_mm=NOISE_MM, drop=0.1, spikes=0.02):
    """Markers (mm) of the rig playing ``values`` with head motion ``angles`` and capture defects;
    also the spikes planted."""
    points = markers.positions(rig, evaluate_basis(basis, values))  # (f, m, 3) cm
    pivot = rig.bone("head").head
    for t, (yaw, pitch, roll) in enumerate(angles):
        R = rotation_y(yaw) @ rotation_x(pitch) @ rotation_z(-roll)
        points[t] = (points[t] - pivot) @ R.T + pivot + np.array([1.0, 0.5, -2.0]) * np.sin(t / FPS)
    points = 10.0 * points + rng.normal(scale=noise_mm / np.sqrt(3), size=points.shape)
    dropped = rng.random(points.shape[:2]) < drop
    spiked = (rng.random(points.shape[:2]) < spikes) & ~dropped
    dropped[:30] = spiked[:30] = False  # the neutral second stays clean, as a real calibration take does
    points[dropped] = np.nan
    points[spiked] += rng.normal(scale=20.0, size=(spiked.sum(), 3))
    return Trajectories(markers.names, points, FPS, "mm", source="synthetic"), spiked


def test_synthetic_capture_recovers_the_determined_channels(rig, baked, ibug):
    """The issue's ground truth: 1 mm noise, 10 % dropped, 2 % spikes, random head motion."""
    rng = np.random.default_rng(0)
    names = determined_channels(rig, baked, ibug, noise=NOISE, tolerance=0.01)
    assert "jaw_open" in names and len(names) >= 3
    values = smooth_clip(rig, names, 240, rng)
    angles = head_angles(240)
    traj, spiked = capture(rig, baked, ibug, values, angles=angles, rng=rng)
    performance = solve_performance(rig, traj, basis=baked, active=names)
    assert isinstance(performance, Performance)
    columns = [rig.channel_index(n) for n in names]
    error = performance.clip.values[:, columns] - values[:, columns]
    assert np.sqrt(np.mean(error**2)) <= 0.02
    head = [rig.channel_index(n) for n in ("head_yaw", "head_pitch", "head_roll")]
    assert np.degrees(np.abs(performance.clip.values[:, head] - angles)).max() < 1.0
    marker_rms_mm = 10.0 * np.nanmedian(performance.marker_error)
    assert 0.4 < marker_rms_mm < 1.2  # near the noise floor: not overfitting, not missing motion
    found = (performance.outliers & spiked).sum() / spiked.sum()
    assert found > 0.9
    assert performance.units == "mm" and not performance.flagged.any()
    report = performance.report(rig)
    assert report["frames"] == 240 and report["layout"] == "ibug68"


def test_clean_capture_is_recovered(rig, baked, ibug):
    """No noise, no smoothing, no regularisation, no L1 term: the expression and the head motion come
    back (the head from markers the expression barely moves, refined by alternating with the solve)."""
    rng = np.random.default_rng(1)
    names = ("jaw_open", "cheek_puff_L", "mouth_slide_R")
    values = smooth_clip(rig, names, 90, rng)
    angles = head_angles(90)
    traj, _ = capture(rig, baked, ibug, values, angles=angles, rng=rng, noise_mm=0.0, drop=0.0, spikes=0.0)
    performance = solve_performance(
        rig,
        traj,
        basis=baked,
        active=names,
        cutoff_hz=None,
        robust=False,
        regularization=0.0,
        shape_prior=0.0,
        sparsity=0.0,
    )
    columns = [rig.channel_index(n) for n in names]
    np.testing.assert_allclose(performance.clip.values[:, columns], values[:, columns], atol=2e-3)
    head = [rig.channel_index(n) for n in ("head_yaw", "head_pitch", "head_roll")]
    np.testing.assert_allclose(performance.clip.values[:, head], angles, atol=np.radians(0.05))
    assert np.nanmax(performance.marker_error) < 0.005  # rig units (cm): 0.05 mm


def test_marker_solve_is_bounded_least_squares(rig, baked, ibug):
    """The per-frame solve (weights, sliding projectors, damping) equals scipy's BVLS on the stacked rows."""
    from scipy.optimize import lsq_linear

    from mimetic.capture.expression import prepare_marker_solver

    rng = np.random.default_rng(9)
    deltas = np.einsum("mn,cnd->cmd", ibug.weights(rig).toarray(), baked.deltas)[:50]  # (50, 68, 3)
    lower, upper = np.zeros(50), np.ones(50)
    solver = prepare_marker_solver(deltas, ibug, lower, upper, regularization=1e-3)
    y = np.einsum("kmi,fk->fmi", deltas, rng.uniform(-0.2, 1.2, (12, 50))) + rng.normal(
        scale=0.02, size=(12, 68, 3)
    )
    weights = (rng.random((12, 68)) > 0.1).astype(float)
    x, _ = solver.solve(y, weights)
    for t in range(12):
        rows = np.concatenate([np.sqrt(weights[t])[:, None, None] * solver.rows, np.zeros((0, 3, 50))])
        A = np.concatenate([rows.reshape(-1, 50), np.linalg.cholesky(solver.prior()).T])
        projected = np.einsum("mij,mj->mi", solver.projectors, y[t]) * np.sqrt(weights[t])[:, None]
        b = np.concatenate([projected.ravel(), np.zeros(50)])
        expected = lsq_linear(A, b, bounds=(lower, upper), method="bvls", tol=1e-14).x
        np.testing.assert_allclose(x[t], expected, atol=1e-6)


def test_sparsity_zeroes_small_activations(rig, baked, ibug):
    rng = np.random.default_rng(2)
    names = ("jaw_open", "mouth_slide_L", "mouth_slide_R")
    values = smooth_clip(rig, names[:1], 120, rng)
    traj, _ = capture(rig, baked, ibug, values, angles=head_angles(120, 0.0), rng=rng, drop=0.0, spikes=0.0)
    dense = solve_performance(rig, traj, basis=baked, active=names, sparsity=0.0)
    default = solve_performance(rig, traj, basis=baked, active=names)  # SPARSITY
    sparse = solve_performance(rig, traj, basis=baked, active=names, sparsity=0.05)
    idle = [rig.channel_index(n) for n in names[1:]]
    assert np.mean(dense.clip.values[:, idle] == 0) < 0.9  # noise shows up as small activations
    assert np.abs(default.clip.values[:, idle]).mean() < 0.5 * np.abs(dense.clip.values[:, idle]).mean()
    assert np.mean(sparse.clip.values[:, idle] == 0) > 0.95
    j = rig.channel_index("jaw_open")  # a signed channel: no L1 term
    assert np.abs(sparse.clip.values[:, j] - values[:, j]).max() < 0.05


def test_refining_against_the_engine_does_not_hurt(rig, baked, ibug):
    rng = np.random.default_rng(3)
    names = ("jaw_open",)
    values = smooth_clip(rig, names, 40, rng)
    engine = make_engine(rig, "wire")
    vertices = np.stack([engine.deform(v) for v in values])
    points = 10.0 * ibug.positions(rig, vertices)
    traj = Trajectories(ibug.names, points, FPS, "mm")
    linear = solve_performance(rig, traj, basis=baked, active=names, cutoff_hz=None, robust=False)
    refined = solve_performance(
        rig, traj, basis=baked, active=names, cutoff_hz=None, robust=False, refine=2, engine=engine
    )
    assert np.nanmax(refined.marker_error) < np.nanmax(linear.marker_error)  # the engine, not its secant
    j = rig.channel_index("jaw_open")
    assert np.abs(refined.clip.values[:, j] - values[:, j]).max() < 0.01


def test_image_landmarks_are_lifted_and_solved(rig, baked, ibug):
    """2D landmarks (pixels, +y down) of a front view: the jaw's image-plane motion is recovered."""
    rng = np.random.default_rng(4)
    values = smooth_clip(rig, ("jaw_open",), 90, rng)
    points = ibug.positions(rig, evaluate_basis(baked, values))  # (f, m, 3) cm
    pixels = np.stack([200 + 20 * points[..., 0], 300 - 20 * points[..., 1]], axis=2)
    traj = Trajectories(ibug.names, pixels, FPS, "px")
    performance = solve_performance(rig, traj, basis=baked, active=["jaw_open"], robust=False)
    j = rig.channel_index("jaw_open")
    assert performance.units == "px"
    assert np.corrcoef(performance.clip.values[:, j], values[:, j])[0, 1] > 0.98


# --------------------------------------------------------------------------- smoothing


def test_smoother_halves_its_cutoff_and_fills_short_gaps():
    f, fps, cutoff = 600, 60.0, 6.0
    t = np.arange(f) / fps
    at_cutoff = np.sin(2 * np.pi * cutoff * t)
    slow = np.sin(2 * np.pi * 0.5 * t)
    y = np.zeros((f, 2, 3))
    y[:, 0, 0] = at_cutoff
    y[:, 1, 0] = slow
    y[200:206, 1] = np.nan  # 0.1 s gap: filled
    y[400:460, 1] = np.nan  # 1 s gap: left missing
    result = smooth_points(y, fps, cutoff, robust=False)
    smoothed, outliers = result.points, result.outliers
    middle = slice(100, 500)
    assert np.std(smoothed[middle, 0, 0]) / np.std(at_cutoff[middle]) == pytest.approx(0.5, abs=0.08)
    assert np.abs(smoothed[200:206, 1, 0] - slow[200:206]).max() < 0.01
    assert np.isnan(smoothed[400:460, 1]).all() and np.isfinite(smoothed[300, 1]).all()
    assert not outliers.any()
    assert smoothing_weight(fps, cutoff) > smoothing_weight(fps, 2 * cutoff)


def test_smoother_rejects_spikes():
    rng = np.random.default_rng(5)
    f = 300
    y = np.sin(np.arange(f) / 20.0)[:, None, None] * np.ones((f, 1, 3)) + rng.normal(
        scale=0.01, size=(f, 1, 3)
    )
    spikes = rng.choice(f, 6, replace=False)
    clean = y.copy()
    y[spikes, 0] += 1.0
    result = smooth_points(y, 60.0, 8.0)
    smoothed, outliers = result.points, result.outliers
    assert set(np.flatnonzero(outliers[:, 0])) >= set(spikes.tolist())
    assert np.abs(smoothed - clean).max() < 0.05


# --------------------------------------------------------------------------- bad input


def test_bad_captures_get_clear_errors(rig, baked, ibug):
    rng = np.random.default_rng(6)
    values = smooth_clip(rig, ("jaw_open",), 60, rng)
    good, _ = capture(rig, baked, ibug, values, angles=head_angles(60), rng=rng, drop=0.0, spikes=0.0)
    as_metres = Trajectories(good.names, good.positions, FPS, "m")  # millimetre numbers said to be metres
    with pytest.raises(CaptureError, match="looks like mm"):
        solve_performance(rig, as_metres, basis=baked)
    swapped = Trajectories(good.names, good.positions[..., [1, 0, 2]], FPS, "mm")  # x and y swapped
    with pytest.raises(CaptureError, match="mirror image"):
        solve_performance(rig, swapped, basis=baked)
    few = good.select([f"ibug68_{k}" for k in (28, 31, 49, 52, 55, 58)])  # 18 coordinates, ~40 channels
    with pytest.raises(CaptureError, match=r"6 markers per frame .* cannot determine"):
        solve_performance(rig, few, basis=baked)
    with pytest.raises(CaptureError, match="neutral_frame"):
        solve_performance(rig, good, basis=baked, neutral_frame=60)
    unnamed = Trajectories(tuple(f"m{k}" for k in range(good.n_points)), good.positions, FPS, "mm")
    with pytest.raises(CaptureError, match="marker layout"):
        solve_performance(rig, unnamed, basis=baked)


def test_empty_frames_and_lost_markers_are_flagged_not_invented(rig, baked, ibug):
    rng = np.random.default_rng(7)
    names = ("jaw_open", "cheek_puff_L")
    values = smooth_clip(rig, names, 120, rng)
    traj, _ = capture(rig, baked, ibug, values, angles=head_angles(120), rng=rng, drop=0.0, spikes=0.0)
    positions = traj.positions.copy()
    positions[70:100] = np.nan  # the tracker lost the face for half a second
    positions[:, 60] = np.nan  # one marker never appears
    lost = Trajectories(traj.names, positions, FPS, "mm")
    with pytest.warns(MimeticWarning) as caught:
        performance = solve_performance(rig, lost, basis=baked, active=names)
    messages = " ".join(str(w.message) for w in caught)
    assert "never appear" in messages and "flagged" in messages
    assert performance.flagged[70:100].all() and not performance.flagged[:60].any()
    assert not performance.used[:, 60].any()
    j = rig.channel_index("jaw_open")
    good = ~performance.flagged
    assert np.abs(performance.clip.values[good, j] - values[good, j]).max() < 0.05


# --------------------------------------------------------------------------- retarget and edit


def test_retarget_matches_channels_by_name_and_clips_ranges(rig):
    clip = Clip(
        ("jaw_open", "smile_extra", "cheek_puff_L"), np.array([[0.2, 1.0, 0.5], [9.0, 0.0, -3.0]]), 30.0
    )
    with pytest.warns(MimeticWarning, match="smile_extra.*dropped.*clipped"):
        played = retarget(clip, rig)
    assert played.channels == rig.channel_names
    j, k = rig.channel_index("jaw_open"), rig.channel_index("cheek_puff_L")
    assert played.values[0, j] == 0.2 and played.values[1, j] == rig.channel("jaw_open").maximum
    assert played.values[1, k] == rig.channel("cheek_puff_L").minimum
    other = [c for c in range(len(rig.channels)) if c not in (j, k)]
    defaults = np.array([rig.channels[c].default for c in other])
    np.testing.assert_array_equal(played.values[:, other], np.broadcast_to(defaults, (2, len(other))))


def test_edits_survive_a_new_solve():
    first = Clip(("jaw_open",), np.full((61, 1), 0.1), 30.0)
    edited = from_clip(first).edit("jaw_open", {1.0: 0.4}, knot_spacing_s=0.2)
    second = Clip(("jaw_open",), np.full((61, 1), 0.2), 30.0)  # the capture solved again
    kept = keep_edits(edited, second)
    assert [layer.name for layer in kept.layers] == [layer.name for layer in edited.layers]
    values = kept.sample(30.0).values[:, 0]
    assert values[30] == pytest.approx(0.5, abs=1e-6)  # the new base plus the edit's +0.3 at 1 s
    assert values[0] == pytest.approx(0.2) and values[-1] == pytest.approx(0.2)  # away from the edit


def test_solved_clip_plays_on_another_rig(rig, baked, ibug):
    from mimetic import testing

    rng = np.random.default_rng(8)
    values = smooth_clip(rig, ("jaw_open",), 60, rng)
    traj, _ = capture(rig, baked, ibug, values, angles=head_angles(60), rng=rng, drop=0.0, spikes=0.0)
    performance = solve_performance(rig, traj, basis=baked, active=["jaw_open"])
    other = testing.small_rig(seed=3)  # another identity: other shape, same channels
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # same channel names and ranges: nothing to drop or clip
        played = retarget(performance.clip, other)
    j = other.channel_index("jaw_open")
    np.testing.assert_allclose(played.values[:, j], performance.clip.values[:, rig.channel_index("jaw_open")])


def test_noise_gain_matches_the_spread_of_solves_of_noisy_markers(rig, baked, ibug):
    """The predicted per-channel standard deviation against 400 solves of pure noise."""
    from mimetic.capture.expression import marker_deltas, noise_gain, prepare_marker_solver

    rng = np.random.default_rng(10)
    names = ("jaw_open", "cheek_puff_L", "mouth_slide_R")
    index = [baked.channels.index(n) for n in names]
    deltas = marker_deltas(rig, baked, ibug)[index]
    solver = prepare_marker_solver(deltas, ibug, np.full(3, -np.inf), np.full(3, np.inf))
    noise = 0.05
    y = rng.normal(scale=noise, size=(400, ibug.n_markers, 3))
    x, _ = solver.solve(y, np.ones((400, ibug.n_markers)))
    np.testing.assert_allclose(x.std(axis=0), noise * noise_gain(solver), rtol=0.15)


def test_a_capture_that_loses_everything_after_the_neutral_frame_is_flagged(rig, baked, ibug):
    """Markers seen once are kept as captured (too few samples to smooth), so the neutral frame still
    calibrates; every later frame is flagged, none is invented."""
    rng = np.random.default_rng(11)
    values = smooth_clip(rig, ("jaw_open",), 40, rng)
    traj, _ = capture(rig, baked, ibug, values, angles=head_angles(40), rng=rng, drop=0.0, spikes=0.0)
    positions = traj.positions.copy()
    positions[1:] = np.nan
    with pytest.warns(MimeticWarning, match="39 of 40 frames are flagged"):
        performance = solve_performance(rig, Trajectories(traj.names, positions, FPS, "mm"), basis=baked)
    assert performance.flagged[1:].all() and not performance.flagged[0]
    assert not performance.used[1:].any()


def test_a_jaw_line_alone_still_gives_the_head(rig, baked, ibug):
    """Sliding contour markers that are also the only stable ones still carry the head's motion."""
    rng = np.random.default_rng(12)
    values = smooth_clip(rig, ("jaw_open",), 60, rng)
    traj, _ = capture(rig, baked, ibug, values, angles=head_angles(60), rng=rng, drop=0.0, spikes=0.0)
    jaw_line = traj.select([f"ibug68_{k:02d}" for k in range(1, 18)])
    performance = solve_performance(rig, jaw_line, basis=baked, active=["jaw_open"])
    assert performance.head.fitted.all()
    head = [rig.channel_index(n) for n in ("head_yaw", "head_pitch", "head_roll")]
    assert np.degrees(np.abs(performance.clip.values[:, head] - head_angles(60)).max()) < 2.0


def test_a_wide_jaw_on_clean_markers_is_not_taken_for_an_outlier(rig, baked, ibug):
    """Outliers are judged against the capture's noise and gross errors, never against what the rig
    fits less well: a jaw opened to its limit, captured cleanly, loses no marker."""
    rng = np.random.default_rng(13)
    f = 120
    values = np.zeros((f, len(rig.channels)))
    t = np.arange(f) / FPS
    jaw = rig.channel("jaw_open").maximum
    values[:, rig.channel_index("jaw_open")] = jaw * np.clip((t - 0.5) / 0.8, 0.0, 1.0)
    values[:, rig.channel_index("zygomatic_major_L")] = np.clip((t - 0.7) / 0.8, 0.0, 1.0)
    traj, _ = capture(
        rig, baked, ibug, values, angles=head_angles(f), rng=rng, noise_mm=0.3, drop=0.0, spikes=0.0
    )
    performance = solve_performance(rig, traj, basis=baked)
    assert not performance.outliers.any()
    j = rig.channel_index("jaw_open")
    assert np.abs(performance.clip.values[:, j] - values[:, j]).max() < 0.03


def test_a_marker_swapped_with_its_neighbour_for_a_second_is_rejected(rig, baked, ibug):
    """A labelling error: two markers 1.6 cm apart trade names for a second. Each sample is then far from
    any face the rig makes, so both are left out there and the jaw is still recovered."""
    rng = np.random.default_rng(14)
    names = ("jaw_open", "zygomatic_major_L", "zygomatic_major_R")
    values = smooth_clip(rig, names, 180, rng)
    traj, _ = capture(rig, baked, ibug, values, angles=head_angles(180), rng=rng, drop=0.0, spikes=0.0)
    a, b = ibug.names.index("ibug68_49"), ibug.names.index("ibug68_55")  # the mouth corners
    positions = traj.positions.copy()
    positions[60:120, [a, b]] = positions[60:120, [b, a]]
    swapped = Trajectories(traj.names, positions, FPS, "mm")
    performance = solve_performance(rig, swapped, basis=baked, active=names)
    rejected = performance.outliers[60:120][:, [a, b]]
    assert rejected.mean() > 0.9 and performance.outliers[:55].sum() == 0
    j = rig.channel_index("jaw_open")
    assert np.abs(performance.clip.values[:, j] - values[:, j]).max() < 0.05
