"""Bake any engine into a linear ``Basis`` (neutral + per-channel deltas + a few correctives).

Whole-head rotation (``head_yaw``, ``head_pitch``, ``head_roll``) is a rigid motion that a basis
cannot represent; its deltas are zero, and exports keep it as the head bone.

For a channel with range [lo, hi]: if lo < 0 < hi and the range is symmetric enough (gaze, head
rotation), its delta is the central secant ``(deform(+x) - deform(-x)) / 2x`` at
``x = min(-lo, hi)``; otherwise the secant to its maximum, ``(deform(hi) - neutral) / hi``. So a
basis reproduces every single channel exactly at rest and at its extreme, and interpolates in
between.

Correctives capture the strongest interactions: for a pair (i, j) at their extremes,
``C_ij = (deform(x_i + x_j) - deform(x_i) - deform(x_j) + neutral) / (x_i x_j)`` (the jaw rotating
muscle-displaced lower lip skin, two muscles damping each other on a shared control point). The
pairs with the largest effect are kept. ``bake`` reports the error of the basis against the
engine over random poses, so users can judge the linearisation. Warnings the engine gives while it
poses (the tissue engine's equilibrium stopping short of its tolerance) come once per kind, with how
many of the bake's poses gave them, not once per pose.
"""

from __future__ import annotations

import heapq
import logging
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from itertools import combinations
from typing import TYPE_CHECKING

import numpy as np

from mimetic.engines.basis import Basis, Corrective, Handover, basis_bytes, evaluate_basis, human_bytes

if TYPE_CHECKING:  # mimetic.engines imports this module
    from mimetic.engines import Engine

log = logging.getLogger(__name__)

CORRECTIVES = 24
"""Pairwise correctives a bake keeps by default (the strongest pairs)."""
SAMPLES = 32
"""Random poses a bake checks its basis on by default."""

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class BakeReport:
    """Basis-versus-engine error over random poses, in rig units (and % of the head height)."""

    samples: int
    max_error: float  # worst vertex error with the correctives
    rms_error: float
    max_error_linear: float  # the same without the correctives
    rms_error_linear: float
    scale: float  # the rig's head height, for relative numbers

    def lines(self) -> list[str]:
        pct = 100.0 / self.scale
        return [
            f"bake error over {self.samples} random poses: max {self.max_error:.3g} "
            f"({self.max_error * pct:.2f} % of head height), rms {self.rms_error:.3g}",
            f"without correctives: max {self.max_error_linear:.3g} "
            f"({self.max_error_linear * pct:.2f} %), rms {self.rms_error_linear:.3g}",
        ]


@dataclass(frozen=True)
class BakeResult:
    basis: Basis
    report: BakeReport


def channel_extent(lo: float, hi: float) -> tuple[float, bool]:
    """The bake amplitude of a channel and whether it uses a central secant."""
    if lo < 0 < hi and min(-lo, hi) >= 0.5 * max(-lo, hi):
        return min(-lo, hi), True
    return (hi if hi > 0 else lo), False


RIGID = ("head_yaw", "head_pitch", "head_roll")  # whole-head rotation: a bone in exports, not in a basis


def random_poses(engine: Engine, count: int, rng: np.random.Generator, density: float = 0.3) -> np.ndarray:
    """Random poses (count, c): each channel active with probability ``density``, uniform in range;
    the rigid head rotation channels stay at 0."""
    lo = np.array([c.minimum for c in engine.rig.channels])
    hi = np.array([c.maximum for c in engine.rig.channels])
    muscle = np.array([c.unit == "activation" for c in engine.rig.channels])
    values = rng.uniform(np.where(muscle, 0.0, lo), hi, size=(count, len(lo)))
    values *= rng.random((count, len(lo))) < density
    values[:, [j for j, ch in enumerate(engine.rig.channels) if ch.name in RIGID]] = 0.0
    return values


@contextmanager
def _warnings_summarised(count: Callable[[], int]) -> Iterator[None]:
    """Hold the warnings raised inside; then give one per category: how many there were, of the
    ``count()`` poses, and the first one's message."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        yield
    by_category: dict[type[Warning], list[str]] = {}
    for w in caught:
        by_category.setdefault(w.category, []).append(str(w.message))
    for category, messages in by_category.items():
        more = f" ({len(messages)} of {count()} poses; the first shown)" if len(messages) > 1 else ""
        warnings.warn(f"bake: {messages[0]}{more}", category, stacklevel=4)


def bake(
    engine: Engine,
    *,
    correctives: int | None = None,
    samples: int | None = None,
    seed: int = 0,
    progress: Progress | None = None,
) -> BakeResult:
    """Linearise ``engine`` into a ``Basis`` with up to ``correctives`` pairwise terms; report its error
    over ``samples`` random poses. Both default to the engine's ``bake_correctives`` and
    ``bake_samples`` where it has them (the tissue engine solves a pose in about a quarter of a second,
    so it bakes without correctives and checks 4 poses), else to ``CORRECTIVES`` and ``SAMPLES``.
    The basis's size is logged (info) before it is made."""
    correctives = getattr(engine, "bake_correctives", CORRECTIVES) if correctives is None else correctives
    samples = getattr(engine, "bake_samples", SAMPLES) if samples is None else samples
    poses = 0

    def deform(values: np.ndarray) -> np.ndarray:
        nonlocal poses
        poses += 1
        return engine.deform(values)

    with _warnings_summarised(lambda: poses):
        return _bake(engine, deform, correctives, samples, seed, progress)


def _bake(
    engine: Engine,
    deform: Callable[[np.ndarray], np.ndarray],
    correctives: int,
    samples: int,
    seed: int,
    progress: Progress | None,
) -> BakeResult:
    """``bake`` with ``deform`` (``engine.deform``) for every pose."""
    rig = engine.rig
    c = len(rig.channels)
    zero = np.array([ch.default for ch in rig.channels])
    neutral = deform(zero)
    amplitude = np.zeros(c)
    held: dict[int, np.ndarray] = {}  # the posed vertices of channels a delta cannot give back
    moving: dict[int, np.ndarray] = {}  # (n,) bool: the vertices each channel moves
    log.info(
        "baking %d channels (+ up to %d correctives) of %s vertices: the basis will hold %s (float64)",
        c,
        correctives,
        f"{rig.n_vertices:,}",
        human_bytes(basis_bytes(c, rig.n_vertices, correctives)),
    )
    deltas = np.zeros((c, rig.n_vertices, 3))
    steps = c + samples
    done = 0
    for j, ch in enumerate(rig.channels):
        if ch.name in RIGID:
            amplitude[j] = 1.0
            held[j] = neutral
            moving[j] = np.zeros(rig.n_vertices, dtype=bool)
            continue
        x, central = channel_extent(ch.minimum, ch.maximum)
        amplitude[j] = x
        plus = zero.copy()
        plus[j] = x
        posed = deform(plus)
        if central:
            minus = zero.copy()
            minus[j] = -x
            deltas[j] = (posed - deform(minus)) / (2 * x)
            held[j] = posed
        else:
            deltas[j] = (posed - neutral) / x
        moving[j] = np.abs(posed - neutral).max(axis=1) > 1e-9 * rig.scale
        done += 1
        if progress:
            progress(done, steps)

    terms = []
    if correctives:
        candidates = [(i, j) for i, j in combinations(range(c), 2) if np.any(moving[i] & moving[j])]
        del moving
        strongest = _strongest_pairs(deform, zero, neutral, held, deltas, amplitude, candidates, correctives)
        names = rig.channel_names
        terms = [Corrective((names[i], names[j]), Handover(d)) for i, j, d in strongest]
        del strongest
    basis = Basis(rig.channel_names, neutral, Handover(deltas), tuple(terms))
    del deltas, held, terms  # the basis holds them
    # the error over random poses, one pose at a time and with the basis's equation written out:
    # (samples, n, 3) frames, or evaluate_basis's layouts (copies of every term), would not fit at 1M
    pairs = [(rig.channel_index(a), rig.channel_index(b)) for a, b in (t.channels for t in basis.correctives)]
    e_max = e_sum = el_max = el_sum = 0.0
    for pose in random_poses(engine, samples, np.random.default_rng(seed)):
        truth = deform(pose)
        linear = basis.neutral + np.tensordot(pose, basis.deltas, axes=1)  # (n, 3)
        fitted = linear.copy()
        for (i, j), term in zip(pairs, basis.correctives, strict=True):
            fitted += (pose[i] * pose[j]) * term.delta
        e = np.linalg.norm(fitted - truth, axis=1)
        el = np.linalg.norm(linear - truth, axis=1)
        e_max, e_sum = max(e_max, float(e.max())), e_sum + float(np.sum(e**2))
        el_max, el_sum = max(el_max, float(el.max())), el_sum + float(np.sum(el**2))
        done += 1
        if progress:
            progress(done, steps)
    count = max(samples * rig.n_vertices, 1)
    report = BakeReport(
        samples, e_max, float(np.sqrt(e_sum / count)), el_max, float(np.sqrt(el_sum / count)), rig.scale
    )
    return BakeResult(basis, report)


def _strongest_pairs(
    deform: Callable[[np.ndarray], np.ndarray],
    zero: np.ndarray,
    neutral: np.ndarray,
    held: dict[int, np.ndarray],
    deltas: np.ndarray,
    amplitude: np.ndarray,
    candidates: list[tuple[int, int]],
    keep: int,
) -> list[tuple[int, int, np.ndarray]]:
    """The ``keep`` candidate pairs (i, j) with the strongest corrections, strongest first (ties in
    candidate order), each with its correction (n, 3); pairs without any correction are left out.
    A channel alone at its amplitude is ``held[j]`` (channels a delta cannot give back: central
    secants, the rigid head), else ``neutral + amplitude[j] * deltas[j]``.

    Only the ``keep`` strongest corrections seen so far are held (a heap), not one per candidate:
    about 950 candidates of (n, 3) float64 were 22 GiB at 1M vertices.
    """

    def single(j: int) -> np.ndarray:
        return held[j] if j in held else neutral + amplitude[j] * deltas[j]

    heap: list[tuple[float, int, int, int, np.ndarray]] = []
    for order, (i, j) in enumerate(candidates):
        both = zero.copy()
        both[i], both[j] = amplitude[i], amplitude[j]
        delta = (deform(both) - single(i) - single(j) + neutral) / (amplitude[i] * amplitude[j])
        strength = float(np.abs(delta).max() * abs(amplitude[i] * amplitude[j]))
        if strength <= 0:
            continue
        item = (strength, -order, i, j, delta)
        if len(heap) < keep:
            heapq.heappush(heap, item)
        elif item[:2] > heap[0][:2]:
            heapq.heapreplace(heap, item)
    return [(i, j, d) for _, _, i, j, d in sorted(heap, key=lambda s: (-s[0], -s[1]))]


def evaluate_rigid(rig, basis: Basis, activations: np.ndarray, *, dtype=np.float64) -> np.ndarray:
    """Vertex positions (n, 3) of ``basis`` at one pose ``activations`` (c,), with the whole-head
    rotation (``RIGID``, which the basis cannot hold) applied as the head bone turns it: every bone
    is a child of the head, so the head's transform moves every vertex rigidly."""
    from mimetic.engines.skinning import bone_transforms

    vertices = evaluate_basis(basis, activations, dtype=dtype)
    index = [j for j, name in enumerate(rig.channel_names) if name in RIGID]
    if not np.any(np.asarray(activations)[index]):
        return vertices
    head = bone_transforms(rig, np.asarray(activations, dtype=np.float64))[rig.bone_index("head")]
    return (vertices @ head[:3, :3].T.astype(dtype) + head[:3, 3].astype(dtype)).astype(dtype)
