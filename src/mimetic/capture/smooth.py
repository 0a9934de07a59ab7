"""Temporal smoothing of captured points, spike rejection and the capture's noise level.

Each coordinate of each point is smoothed as one banded problem over the whole take,
``(W + λ D₂ᵀD₂) ŷ = W y`` (a Whittaker smoother: W the point's per-frame weight, D₂ the second
difference), with λ set so the response ``H(ω) = 1 / (1 + λ (2 − 2 cos ω)²)`` is one half at
``cutoff_hz``. Missing samples have weight 0, so gaps up to ``MAX_GAP_S`` are filled; spikes are
found by a robust reweighting (Cauchy weights on the smoothing residual) and left out.

For a linear basis D and inactive bounds, smoothing the points first *is* the clip-wide solve with
the points' acceleration penalised — ‖(I⊗D)a − y‖² + λ‖(D₂⊗D)a‖² has normal equations
((I + λD₂ᵀD₂)⊗DᵀD) a = (I⊗Dᵀ) y, the per-frame solve of the smoothed points — but separable per
coordinate, so 10,000 frames take a fraction of a second.

The same residuals measure the capture's noise (``Smoothed.noise``): for white noise of standard
deviation σ per coordinate the residual ``(1 − H) y`` has standard deviation σ·‖1 − H‖ (the RMS of
the response over the band), and real motion faster than the cutoff only adds to a few points'
residuals, so the median over points of their robust residual scales gives σ.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solveh_banded

MAX_GAP_S = 0.25
"""Gaps in a point longer than this stay missing (the smoother's fill is not trusted)."""
CAUCHY_SCALE = 3.0
"""Robust weights 1 / (1 + (r / (CAUCHY_SCALE σ))²), σ a point's residual scale."""
SPIKE_SIGMAS = 6.0
"""Residuals beyond this many σ are spikes: weight 0, reported as outliers."""
SIGMA_FLOOR_REL = 0.002
"""A point's residual scale σ is at least this fraction of the head (0.4 mm on a 22 cm head), and at
least the capture's noise: clean data has a median residual near 0, and a smooth motion's onset
must not count as a spike."""
ROBUST_ROUNDS = 3
CUTOFF_HZ = 8.0
"""Default smoothing cutoff: facial motion (speech included) lives below ~8 Hz, tracker jitter above."""
NOISE_CUTOFF_HZ = 8.0
"""The cutoff at which the noise is measured (and spikes found) when the points are not smoothed."""
CHI_MEDIAN = {1: 0.6745, 2: 1.1774, 3: 1.5382}
"""The median of |e| for e a d-vector of unit normal noise (the χ distribution with d degrees of
freedom): σ per coordinate is a point's median residual distance over this."""


@dataclass(frozen=True, eq=False)
class Smoothed:
    """Smoothed points and what the smoothing learned about the capture.

    Attributes
    ----------
    points : (f, m, d) float64
        Smoothed; NaN in gaps longer than ``MAX_GAP_S``, at unseen ends and for points never seen.
    outliers : (f, m) bool
        Samples rejected as spikes.
    noise : float
        The capture's noise, standard deviation per coordinate of the raw samples, in their units
        (0 when too little was seen to tell).
    kept : float
        The fraction of white noise's standard deviation the smoother keeps (``noise_kept``):
        ``noise * kept`` is the noise left in ``points``.
    """

    points: np.ndarray
    outliers: np.ndarray
    noise: float
    kept: float


def smoothing_weight(fps: float, cutoff_hz: float) -> float:
    """λ of the Whittaker smoother whose response 1 / (1 + λ (2 − 2 cos ω)²) is ½ at ``cutoff_hz``."""
    omega = 2 * np.pi * min(cutoff_hz / fps, 0.5)
    return 1.0 / (2.0 - 2.0 * np.cos(omega)) ** 2


def _response(fps: float, cutoff_hz: float) -> np.ndarray:
    """H(ω) (2049,) over [0, π]."""
    omega = np.linspace(0.0, np.pi, 2049)
    return 1.0 / (1.0 + smoothing_weight(fps, cutoff_hz) * (2.0 - 2.0 * np.cos(omega)) ** 2)


def noise_kept(fps: float, cutoff_hz: float | None) -> float:
    """The fraction of white noise's standard deviation the smoother keeps: the RMS of H over the
    band (about 0.5 for 8 Hz at 60 fps); 1 without smoothing."""
    if cutoff_hz is None:
        return 1.0
    return float(np.sqrt(np.mean(_response(fps, cutoff_hz) ** 2)))


def smoothed_noise(noise: float, fps: float, cutoff_hz: float | None) -> float:
    """The standard deviation white ``noise`` keeps through the smoother (``noise * noise_kept``)."""
    return noise * noise_kept(fps, cutoff_hz)


def _banded(f: int, lam: float, weights: np.ndarray) -> np.ndarray:
    """Upper banded form (3, f) of diag(weights) + λ D₂ᵀ D₂ (D₂ the (f − 2, f) second difference)."""
    diagonal = np.full(f, 6.0)
    off1 = np.full(f - 1, -4.0)
    if f >= 2:
        diagonal[[0, -1]] = 1.0
        off1[[0, -1]] = -2.0
    if f >= 3:
        diagonal[[1, -2]] = 5.0
    if f == 3:
        diagonal[1] = 4.0
    ab = np.zeros((3, f))
    ab[2] = lam * diagonal + weights
    ab[1, 1:] = lam * off1
    ab[0, 2:] = lam
    return ab


def _gaps(seen: np.ndarray, longest: int) -> np.ndarray:
    """(f,) bool: frames inside runs of ``~seen`` longer than ``longest`` frames (or at either end)."""
    edges = np.diff(np.concatenate([[0], (~seen).astype(np.int8), [0]]))
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)  # runs [start, end)
    out = np.zeros(len(seen), bool)
    for start, end in zip(starts, ends, strict=True):
        if end - start > longest or start == 0 or end == len(seen):
            out[start:end] = True
    return out


def smooth_points(
    y: np.ndarray, fps: float, cutoff_hz: float | None, *, robust: bool = True, size: float = 1.0
) -> Smoothed:
    """Whittaker-smooth point trajectories, filling short gaps, rejecting spikes, measuring the noise.

    Parameters
    ----------
    y : (f, m, d) float64
        Point positions (d = 2 or 3), NaN where missing.
    fps : float
    cutoff_hz : float or None
        The frequency where the response is ½. None leaves the points as they are, but still
        measures the noise (at ``NOISE_CUTOFF_HZ``) and finds spikes.
    robust : bool
        Reweight by the smoothing residual and drop spikes beyond ``SPIKE_SIGMAS``.
    size : float
        The head's size in the points' units, for the floor of the robust scale
        (``SIGMA_FLOOR_REL`` of it).
    """
    f, m, d = y.shape
    seen = np.isfinite(y).all(axis=2)
    outliers = np.zeros((f, m), bool)
    if f < 3:
        return Smoothed(np.where(seen[..., None], y, np.nan), outliers, 0.0, 1.0)
    cutoff = NOISE_CUTOFF_HZ if cutoff_hz is None else cutoff_hz
    lam = smoothing_weight(fps, cutoff)
    residual_gain = float(np.sqrt(np.mean((1.0 - _response(fps, cutoff)) ** 2)))
    filled = np.nan_to_num(y)
    fits = np.full_like(y, np.nan)
    scales = np.full(m, np.nan)  # per point: residual scale per coordinate, first (unweighted) pass
    residuals = np.zeros((f, m))
    for j in range(m):
        if seen[:, j].sum() < 3:  # too few samples to smooth: kept as captured
            fits[:, j] = np.where(seen[:, j, None], y[:, j], np.nan)
            continue
        weights = seen[:, j].astype(np.float64)
        fits[:, j] = solveh_banded(_banded(f, lam, weights), weights[:, None] * filled[:, j])
        residuals[:, j] = np.linalg.norm(filled[:, j] - fits[:, j], axis=1)
        scales[j] = np.median(residuals[seen[:, j], j]) / CHI_MEDIAN[d]
    known = np.isfinite(scales)
    noise = float(np.median(scales[known]) / residual_gain) if known.any() else 0.0
    floor = max(SIGMA_FLOOR_REL * size, noise * residual_gain)
    for j in np.flatnonzero(known) if robust else ():
        weights = seen[:, j].astype(np.float64)
        for _ in range(ROBUST_ROUNDS):
            sigma = max(np.median(residuals[seen[:, j], j]) / CHI_MEDIAN[d], floor)
            spike = seen[:, j] & (residuals[:, j] > SPIKE_SIGMAS * sigma)
            new = np.where(
                seen[:, j] & ~spike, 1.0 / (1.0 + (residuals[:, j] / (CAUCHY_SCALE * sigma)) ** 2), 0.0
            )
            if np.array_equal(spike, outliers[:, j]) and np.allclose(new, weights, atol=1e-3):
                break
            outliers[:, j] = spike
            weights = new
            fits[:, j] = solveh_banded(_banded(f, lam, weights), weights[:, None] * filled[:, j])
            residuals[:, j] = np.linalg.norm(filled[:, j] - fits[:, j], axis=1)
    if cutoff_hz is None:  # spikes found at the noise cutoff; the points themselves stay raw
        fits = np.where((seen & ~outliers)[..., None], y, np.nan)
        return Smoothed(fits, outliers, noise, 1.0)
    longest = max(1, round(MAX_GAP_S * fps))
    for j in range(m):
        fits[_gaps(seen[:, j] & ~outliers[:, j], longest), j] = np.nan
    return Smoothed(fits, outliers, noise, noise_kept(fps, cutoff_hz))
