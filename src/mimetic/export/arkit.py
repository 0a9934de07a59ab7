"""The ARKit-52 bake of a muscle rig, and the reverse map from activations to ARKit weights.

The table of shapes (names, the activations that realise each, their status) is the control layer
``mimetic.animate.arkit``; here it meets geometry.

**Bake** (``arkit_shapes``): the 52 shapes as vertex deltas of *any* rigged head, each the
engine's deformation under the activation set that realises it, minus the rest pose. Four
kinds (``STATUS``):

* exact: ``deform(v_k) - rest``;
* split (``SPLIT``): the rig drives both sides with one channel (the midline procerus and
  mentalis), so the pose of such a shape alone moves both sides by half. The bake keeps this
  side's half of the symmetric pair's motion, ``s_L(x) * (deform(v_k + v_pair) - rest)``, with
  ``s_L`` a smooth step across the midline (``s_L + s_R = 1``). So the baked pair adds up to the
  symmetric motion and each half is one-sided, as artists split symmetric shapes. (The eyes turn
  each on its own, so the ``eyeLook`` shapes are exact);
* approximate (``APPROXIMATE``): the nearest motion the rig has (``mouthClose``: the lips
  closing over an open jaw; ``mouthShrugUpper``: the upper lip raised, not everted);
* unsupported (``UNSUPPORTED``): none today (the table can mark a shape the rig cannot make; it
  gets a stand-in posture so that all 52 targets exist, and the reverse map leaves it out).

**Reverse map** (``arkit_weights``): the ARKit weights ``w`` in [0, 1] that best reproduce a
pose's displacement ``d`` with the baked shapes ``S``, on the vertices that at least one shape
moves (the face, lids, eyeballs and the lower teeth; the rest of the head carries no ARKit
information)::

    min_w  |S w - d|^2 + sum_k RIDGE_REL |S_k|^2 w_k^2    subject to 0 <= w <= 1

The small ridge only breaks ties: ``jawLeft`` and ``jawRight`` move along one line in opposite
directions (as do eyeLookIn/Out, Up/Down of one eye), so without it the pair (0.6, 0) and
(1, 0.4) would fit equally; with it the sparser answer wins. Unsupported shapes are not fitted
(their weights are 0): their stand-ins are made of other shapes' muscles. The whole-head
rotation channels are set to 0 first, as ARKit reports head pose separately.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from scipy.optimize import lsq_linear

from mimetic.animate.arkit import ARKIT_NAMES, UNSUPPORTED, ArkitError, arkit_table, ict_name
from mimetic.engines import Engine, make_engine
from mimetic.engines.bake import RIGID
from mimetic.engines.basis import Basis, evaluate_basis
from mimetic.rig.activations import check_activations, check_shape
from mimetic.rig.model import Rig

log = logging.getLogger(__name__)

__all__ = ["ArkitFit", "arkit_shapes", "arkit_weights", "prepare_arkit_fit", "side_weights"]

SPLIT_BLEND_REL = 0.02
"""Half-width of the midline blend of split shapes, as a fraction of the mesh's width (x extent)."""
RIDGE_REL = 1e-8
"""Tie-breaking ridge of the reverse map, relative to each shape's squared norm."""
MOVING_REL = 1e-6
"""A vertex belongs to the fit region when some shape moves it by more than this fraction of the
largest shape displacement."""
CHUNK_FRAMES = 128
"""Frames whose displacements ``arkit_weights`` holds at once (bounds its memory on long clips)."""


def side_weights(vertices: np.ndarray, side: str) -> np.ndarray:
    """Share (n,) of each vertex in one side's half of a split shape; ``side_weights(v, "L") +
    side_weights(v, "R") == 1``. A smooth step across the midline (the middle of the x extent)
    over ``2 * SPLIT_BLEND_REL`` of the width."""
    x = np.asarray(vertices, dtype=np.float64)[:, 0]
    lo, hi = float(x.min()), float(x.max())
    half = max(SPLIT_BLEND_REL * (hi - lo), 1e-12)
    t = np.clip((x - 0.5 * (lo + hi) + half) / (2 * half), 0.0, 1.0)
    left = t * t * (3 - 2 * t)
    return left if side == "L" else 1.0 - left


def _pose_vector(channels: Sequence[str], values: Mapping[str, float], base: np.ndarray) -> np.ndarray:
    index = {name: j for j, name in enumerate(channels)}
    out = base.copy()
    for channel, value in values.items():
        if channel not in index:
            raise ArkitError(f"the ARKit table drives channel {channel!r}, which this rig does not have")
        out[index[channel]] += value
    return out


def _bake(
    channels: Sequence[str],
    base: np.ndarray,
    deform: Callable[[np.ndarray], np.ndarray],
    rest: np.ndarray,
) -> dict[str, np.ndarray]:
    """The 52 Apple-named deltas (n, 3) from a deform function over pose vectors (c,)."""
    table = arkit_table()
    out: dict[str, np.ndarray] = {}
    sides = {s: side_weights(rest, s)[:, None] for s in ("L", "R")}
    for name, shape in table.items():
        values = dict(shape.values)
        if shape.status == "split":
            for channel, value in table[shape.pair].values.items():
                values[channel] = values.get(channel, 0.0) + value
        delta = deform(_pose_vector(channels, values, base)) - rest
        if shape.status == "split":
            delta *= sides[shape.side]
        out[name] = delta
    return out


def _source(
    source: Rig | Engine | Basis, engine: str
) -> tuple[Sequence[str], np.ndarray, Callable, np.ndarray]:
    """(channels, base pose, deform(pose) -> (n, 3), rest (n, 3)) of a rig, engine or basis."""
    if isinstance(source, Basis):
        base = np.zeros(source.n_channels)
        return source.channels, base, lambda a: evaluate_basis(source, a), source.neutral
    if isinstance(source, Rig):
        source = make_engine(source, engine)
    rig = source.rig
    base = np.array([c.default for c in rig.channels], dtype=np.float64)

    def deform(a: np.ndarray) -> np.ndarray:
        return source.deform(check_activations(rig, a, clip=True))

    return rig.channel_names, base, deform, deform(base)


def arkit_shapes(
    source: Rig | Engine | Basis, *, engine: str = "wire", naming: str = "apple"
) -> dict[str, np.ndarray]:
    """The ARKit-52 bake: each shape's vertex deltas from the muscle rig.

    Parameters
    ----------
    source : Rig, Engine or Basis
        A rig (an engine named ``engine`` is made for it), a prepared engine, or a baked basis
        (shapes evaluated linearly, with its correctives).
    naming : "apple" | "ict"
        Apple's 52 names, or ICT-FaceKit's (``eyeBlink_L``, ``browInnerUp_L``/``_R`` halves,
        ``cheekPuff_L``/``_R`` halves: 54 entries with ``tongueOut``).

    Returns
    -------
    shapes : dict[str, (n, 3) float64]
        Deltas from the rest pose in rig units, in ``ARKIT_NAMES`` order (each C-contiguous).
        Every shape exists; see ``STATUS`` for how faithful each is.
    """
    if naming not in ("apple", "ict"):
        raise ArkitError(f"naming {naming!r} must be 'apple' or 'ict'")
    channels, base, deform, rest = _source(source, engine)
    shapes = _bake(channels, base, deform, rest)
    if naming == "apple":
        return shapes
    out = {}
    for name, delta in shapes.items():
        if arkit_table()[name].halves:
            for s in ("L", "R"):
                out[f"{name}_{s}"] = delta * side_weights(rest, s)[:, None]
        else:
            out[ict_name(name)] = delta
    return out


# ---- the reverse map


@dataclass(frozen=True, eq=False)
class ArkitFit:
    """A prepared reverse map: ARKit weights from vertex displacements (see the module docstring).

    Attributes
    ----------
    fitted : tuple of str
        The Apple names solved for, in ``ARKIT_NAMES`` order; the others read 0.
    vertices : (k,) int64
        The vertices the fit compares (those some fitted shape moves).
    projection : (m, 3k) float64
        ``S^T`` restricted to ``vertices``: shape k's deltas, flattened.
    factor : (m, m) float64
        Lower Cholesky factor L of ``S^T S + ridge``.
    n_vertices : int
        The vertex count of the shapes (and of the displacements ``solve`` takes).
    """

    fitted: tuple[str, ...]
    vertices: np.ndarray
    projection: np.ndarray
    factor: np.ndarray
    n_vertices: int

    def solve(self, displacements: np.ndarray) -> np.ndarray:
        """Weights (52,) or (f, 52) in [0, 1], ARKIT_NAMES order, for displacements (n, 3) or (f, n, 3)."""
        d = np.asarray(displacements, dtype=np.float64)
        if d.ndim not in (2, 3) or d.shape[-2:] != (self.n_vertices, 3):
            raise ArkitError(
                f"displacements must have shape ({self.n_vertices}, 3) or (frames, {self.n_vertices}, 3); "
                f"got {d.shape}"
            )
        frames = d.reshape(-1, self.n_vertices, 3)[:, self.vertices].reshape(len(d) if d.ndim == 3 else 1, -1)
        b = frames @ self.projection.T  # (f, m): S^T d
        rhs = scipy.linalg.solve_triangular(self.factor, b.T, lower=True).T  # (f, m): L^-1 S^T d
        upper = self.factor.T
        index = [ARKIT_NAMES.index(n) for n in self.fitted]
        out = np.zeros((len(frames), len(ARKIT_NAMES)))
        for f, r in enumerate(rhs):
            out[f, index] = np.clip(lsq_linear(upper, r, bounds=(0.0, 1.0), method="bvls").x, 0.0, 1.0)
        return out[0] if d.ndim == 2 else out


def prepare_arkit_fit(
    shapes: Mapping[str, np.ndarray],
    *,
    vertices: np.ndarray | None = None,
    exclude: Sequence[str] = tuple(UNSUPPORTED),
) -> ArkitFit:
    """Prepare the reverse map for baked shapes (``arkit_shapes``'s output, Apple names).

    ``vertices`` (default: every vertex some fitted shape moves) restricts the comparison;
    ``exclude`` names shapes not to fit (default: the unsupported stand-ins).
    """
    missing = [n for n in ARKIT_NAMES if n not in shapes]
    if missing:
        raise ArkitError(f"the shapes lack {', '.join(missing[:4])}{', …' if len(missing) > 4 else ''}")
    fitted = [n for n in ARKIT_NAMES if n not in set(exclude)]
    try:
        stack = np.array([np.asarray(shapes[n], dtype=np.float64) for n in fitted])  # (m, n, 3)
    except ValueError:
        raise ArkitError("the shapes must all have the same shape (n, 3)") from None
    if stack.ndim != 3 or stack.shape[2] != 3:
        raise ArkitError(f"each shape must have shape (n, 3); got {stack.shape[1:]}")
    n = stack.shape[1]
    motion = np.linalg.norm(stack, axis=2)  # (m, n)
    if vertices is None:
        largest = motion.max(axis=0)
        vertices = np.nonzero(largest > MOVING_REL * max(float(largest.max()), 1e-300))[0]
    vertices = np.asarray(vertices, dtype=np.int64)
    moves = motion[:, vertices].max(axis=1) > 0  # a shape that moves nothing here cannot be fitted
    fitted = [name for name, m in zip(fitted, moves, strict=True) if m]
    projection = stack[moves][:, vertices].reshape(len(fitted), -1)  # (m, 3k)
    gram = projection @ projection.T
    gram[np.diag_indices_from(gram)] *= 1.0 + RIDGE_REL
    factor = np.linalg.cholesky(gram)
    log.debug("ARKit fit: %d shapes on %d of %d vertices", len(fitted), len(vertices), n)
    return ArkitFit(tuple(fitted), vertices, projection, factor, n)


def arkit_weights(
    source: Basis | Engine | Rig,
    activations: np.ndarray,
    *,
    shapes: Mapping[str, np.ndarray] | None = None,
    engine: str = "wire",
) -> np.ndarray:
    """ARKit weights (52,) or (f, 52) that best reproduce poses (bounded least squares).

    Parameters
    ----------
    source : Basis, Engine or Rig
        Turns activations into displacements: a basis (fast, for clips), an engine or a rig (an
        engine named ``engine`` is made).
    activations : (c,) or (f, c) float64
        Poses in the source's channel order; the head rotation channels are ignored.
    shapes : Mapping[str, (n, 3)], optional
        The ARKit shapes to fit with (default: ``arkit_shapes(source)``, so the shapes and the
        displacements come from the same model).

    Returns
    -------
    weights : (52,) or (f, 52) float64 in [0, 1], ``ARKIT_NAMES`` order; unsupported shapes read 0.
    """
    channels, base, deform, rest = _source(source, engine)
    a = check_shape(channels, activations)
    poses = np.atleast_2d(a).copy()
    rigid = [j for j, name in enumerate(channels) if name in RIGID]
    poses[:, rigid] = base[rigid]
    if shapes is None:
        shapes = _bake(channels, base, deform, rest)
    fit = prepare_arkit_fit(shapes)
    out = np.zeros((len(poses), len(ARKIT_NAMES)))
    for start in range(0, len(poses), CHUNK_FRAMES):
        chunk = poses[start : start + CHUNK_FRAMES]
        if isinstance(source, Basis):
            displacement = evaluate_basis(source, chunk) - rest  # (f, n, 3)
        else:
            displacement = np.array([deform(p) - rest for p in chunk])
        out[start : start + len(chunk)] = fit.solve(displacement)
    return out[0] if a.ndim == 1 else out
