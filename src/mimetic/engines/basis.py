"""Baked linear rigs: the float64 reference ``evaluate_basis`` and the fast ``CompactBasis``.

A ``Basis`` is a linearised rig, evaluated frame after frame::

    vertices = neutral + Σ_c a_c · deltas[c] + Σ_k a_i(k) · a_j(k) · correctives[k].delta

``evaluate_basis`` computes it in float64 with one matrix product. ``CompactBasis.build(basis)``
prepares float32 evaluation for many frames, exploiting that each channel moves only its
*support* (a muscle moves 5-20 % of the vertices). A corrective is handled as one more term
whose activation is the product of its two channels.

Compact layouts
---------------
Both layouts keep the caller's vertex order. Reordering vertices would make supports contiguous,
but putting a 13k-vertex result back in order costs 10-50 µs here, as much as a whole frame (and
on the generated head a reordering found by a nearest-neighbour tour of the support signatures
did not even cut the number of contiguous support ranges), so the sparsity is taken in mesh order.

* **runs**, for one frame: each term's non-zero components as runs in mesh order, zero gaps of at
  most ``RUN_GAP_ELEMENTS`` elements included, their values packed in one array. One call of a
  compiled kernel (``mimetic.engines.kernel``, numba, imported on first use) copies the neutral
  and adds every run of every non-zero term; terms at zero cost nothing. Runs read 1.8× the
  non-zero delta components on the generated head's baked basis; a realistic frame takes
  ~15-25 µs, every channel ~50-70 µs.
* **blocks**, for batches: the vertex order cut into contiguous blocks by dynamic programming over
  the support signatures (cost per block ``BLOCK_CALL_ELEMENTS + 3 · vertices · (terms + 1)``).
  Block b stores ``[neutral; deltas of the terms touching b]`` as one (1 + k_b, 3 m_b) matrix
  W_b. A batch is one GEMM per block, ``A[:, terms_b] @ W_b``, written straight into the output
  (no neutral pass); ``evaluate(method="blocks")`` makes it one GEMV per block for one frame.

``plan`` reports the runs or calls of a frame and the bytes it reads.

``float16`` storage halves the bytes of the deltas (the neutral stays float32). It is unpacked
on the fly with two integer operations (float16 bits shifted into place in a float32, the
exponent bias folded into the activation): in the kernel run by run, and by numpy block by block
for batches (numpy's own float16 cast is not vectorised, ~2 ns per value here). It is worth it
only where memory is short: a frame costs the unpacking on top of float32's work.

Exactness contract
------------------
``evaluate`` and ``evaluate_batch`` return float32. Their distance to ``evaluate_basis`` is at
most ``error_bound(activations)`` (rigorous, per frame, in rig units)::

    e_N + Σ_j |t_j| (e_j + u M_j) + γ_(T+1) (N_max + (1 + u) Σ_j |t_j| M_j) + float64 rounding

with t the channel activations followed by the corrective products, e_N and e_j the storage
errors of the neutral and of term j, M_j its largest stored component, N_max the largest
neutral coordinate, u = 2^-24 and γ_K = K u / (1 - K u): storage rounding plus float32
accumulation in any order. Zero activations give the float32-rounded neutral exactly. Terms
whose float32 multiplier is zero are skipped, as BLAS skips an axpy with alpha 0 (an activation
below 2^-150 contributes less than 2^-150 · M_j, far inside the bound).
``compaction_error`` reports what is actually reached on every unit activation.
"""

from __future__ import annotations

import difflib
import functools
import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property
from typing import Literal

import numpy as np
from scipy.linalg import blas

from mimetic.errors import ActivationError, RigError
from mimetic.rig.activations import check_shape

log = logging.getLogger(__name__)

Method = Literal["auto", "runs", "blocks"]

DTYPES = (np.dtype(np.float32), np.dtype(np.float16))
"""Storage dtypes of the deltas."""

RUN_GAP_ELEMENTS = 32
"""Zero gaps of at most this many elements between non-zero components of a term are stored in its
runs, so the kernel's loop runs on through them (16-128 were equally fast on the generated head's
baked basis, 0 was 2.5× slower: a run costs about as much as ~30 streamed floats)."""

BLOCK_CALL_ELEMENTS = 32_000
"""Cost of one more block in the partition, in stored elements: fewer, larger GEMMs suit batches
(OpenBLAS synchronises its threads once per call); a frame costs about the same for 8k-64k."""

BLOCK_GRAIN_VERTICES = 16
"""Blocks start at multiples of this many vertices (keeps the partition search fast)."""

BLOCK_MAX_VERTICES = 4_096
"""Longest block the partition search considers."""

BATCH_CHUNK_FRAMES = 1_024
"""Frames evaluated together by ``evaluate_batch`` (bounds the gathered activations)."""

U32 = 2.0**-24  # unit roundoff of float32
U64 = 2.0**-53
F16_BIAS = 2.0**112  # float16 bits shifted into a float32 read as value · 2^-112
F16_HEADROOM_EXP = 15  # float16 storage maps each term's largest |delta| into [2^14, 2^15]
F16_MIN_NORMAL = 2.0**-14
ALPHA_LIMIT = 2.0**127  # |activation · scale| of a term must stay below it: float32 overflows at 2^128
_F16_UNPACK_MASK = np.int32(-1879048193)  # 0x8FFFFFFF: keeps the sign and 31-3 = 28 low bits


# --------------------------------------------------------------------------- the reference basis


def _frozen(value: object, where: str, *, ndim: int) -> np.ndarray:
    """A read-only C-contiguous float64 copy of ``value`` with ``ndim`` dimensions and finite values."""
    try:
        array = np.array(value, dtype=np.float64, copy=True, order="C")
    except (TypeError, ValueError) as error:
        raise RigError(f"{where} cannot be read as a float64 array: {error}") from None
    if array.ndim != ndim or array.shape[-1] != 3:
        shape = "(n, 3)" if ndim == 2 else "(channels, n, 3)"
        raise RigError(f"{where} must have shape {shape}; got {array.shape}")
    if not np.isfinite(array).all():
        index = tuple(int(i) for i in np.argwhere(~np.isfinite(array))[0])
        raise RigError(f"{where} has a non-finite value at {index}; bake the basis again")
    array.setflags(write=False)
    return array


def _unknown_channel(name: str, channels: Sequence[str], where: str) -> RigError:
    close = difflib.get_close_matches(name, channels, n=3)
    hint = f"did you mean {', '.join(close)}?" if close else f"channels are {', '.join(channels[:6])}, …"
    return RigError(f"{where} names unknown channel {name!r}; {hint}")


@dataclass(frozen=True, eq=False)
class Corrective:
    """A pairwise interaction term: adds ``a_i · a_j · delta`` (e.g. jaw_open × a lip muscle).

    Attributes
    ----------
    channels : (str, str)
        The two channel names; both must be channels of the basis (they may be equal, for a
        quadratic term of one channel).
    delta : (n, 3) float64
        Displacement per unit of the product, in rig units; read-only.
    """

    channels: tuple[str, str]
    delta: np.ndarray

    def __post_init__(self) -> None:
        names = (self.channels,) if isinstance(self.channels, str) else tuple(self.channels)
        if len(names) != 2 or not all(isinstance(n, str) and n for n in names):
            raise RigError(f"a corrective needs two channel names; got {self.channels!r}")
        object.__setattr__(self, "channels", names)
        object.__setattr__(self, "delta", _frozen(self.delta, f"corrective {names}.delta", ndim=2))


@dataclass(frozen=True, eq=False)
class Basis:
    """A baked, linearised rig (see the module docstring for the equation).

    Attributes
    ----------
    channels : tuple of str, (c,)
        Unique channel names, in the order of ``deltas`` and of the activations.
    neutral : (n, 3) float64
        Rest vertices in rig units, in the mesh's vertex order; read-only.
    deltas : (c, n, 3) float64
        Displacement per unit of each channel (muscles per unit activation, jaw, eyelid and gaze
        channels per radian, translations per unit of their channel); read-only.
    correctives : tuple of Corrective
        Pairwise interaction terms, each with a (n, 3) ``delta``.
    """

    channels: tuple[str, ...]
    neutral: np.ndarray
    deltas: np.ndarray
    correctives: tuple[Corrective, ...] = ()

    def __post_init__(self) -> None:
        channels = (self.channels,) if isinstance(self.channels, str) else tuple(self.channels)
        for name in channels:
            if not isinstance(name, str) or not name:
                raise RigError(f"basis channel names must be non-empty strings; got {name!r}")
        if not channels:
            raise RigError("a basis needs at least one channel")
        repeated = sorted({n for n in channels if channels.count(n) > 1})
        if repeated:
            raise RigError(f"basis channel names must be unique; repeated: {', '.join(repeated)}")
        neutral = _frozen(self.neutral, "basis.neutral", ndim=2)
        if len(neutral) == 0:
            raise RigError("basis.neutral has no vertices")
        deltas = _frozen(self.deltas, "basis.deltas", ndim=3)
        n, c = len(neutral), len(channels)
        if deltas.shape != (c, n, 3):
            raise RigError(
                f"basis.deltas must have shape (channels, n, 3) = ({c}, {n}, 3) to match "
                f"{c} channels and neutral {neutral.shape}; got {deltas.shape}"
            )
        correctives = tuple(self.correctives)
        for k, corrective in enumerate(correctives):
            if not isinstance(corrective, Corrective):
                raise RigError(
                    f"basis.correctives[{k}] must be a Corrective; got {type(corrective).__name__}"
                )
            for name in corrective.channels:
                if name not in channels:
                    raise _unknown_channel(name, channels, f"corrective {corrective.channels}")
            if corrective.delta.shape != (n, 3):
                raise RigError(
                    f"corrective {corrective.channels}.delta must have shape ({n}, 3) like the "
                    f"neutral; got {corrective.delta.shape}"
                )
        object.__setattr__(self, "channels", channels)
        object.__setattr__(self, "neutral", neutral)
        object.__setattr__(self, "deltas", deltas)
        object.__setattr__(self, "correctives", correctives)

    @property
    def n_vertices(self) -> int:
        return len(self.neutral)

    @property
    def n_channels(self) -> int:
        return len(self.channels)

    @cached_property
    def corrective_pairs(self) -> np.ndarray:
        """(k, 2) int64: the channel indices of each corrective; read-only."""
        index = {name: i for i, name in enumerate(self.channels)}
        pairs = np.array([[index[a], index[b]] for a, b in (k.channels for k in self.correctives)], np.int64)
        pairs = pairs.reshape(len(self.correctives), 2)
        pairs.setflags(write=False)
        return pairs

    @cached_property
    def corrective_deltas(self) -> np.ndarray:
        """(k, n, 3) float64: the corrective deltas stacked; read-only."""
        stacked = np.array([k.delta for k in self.correctives], np.float64).reshape(-1, self.n_vertices, 3)
        stacked.setflags(write=False)
        return stacked


def check_activations(channels: Sequence[str], activations: object, *, ndim: int | None = None) -> np.ndarray:
    """Activations as float64 (c,) or (f, c) for a basis's ``channels`` (``rig.activations.check_shape``)."""
    return check_shape(channels, activations, ndim=ndim, owner="basis")


def evaluate_basis(basis: Basis, activations: np.ndarray) -> np.ndarray:
    """Vertex positions of a baked rig for one frame or many (the float64 reference).

    Parameters
    ----------
    basis : Basis
        ``neutral`` (n, 3) float64 in rig units; ``deltas`` (c, n, 3) float64, the displacement
        caused by one unit of each channel; ``correctives`` add ``a_i a_j delta``.
    activations : (c,) or (f, c) float64
        Muscle channels in [0, 1]; jaw and gaze channels in radians.

    Returns
    -------
    vertices : (n, 3) or (f, n, 3) float64, same units and vertex order as ``basis.neutral``.
    """
    a = np.atleast_2d(check_activations(basis.channels, activations))  # (f, c)
    c, n = basis.n_channels, basis.n_vertices
    v = (a @ basis.deltas.reshape(c, -1)).reshape(len(a), n, 3)  # (f, n, 3)
    if basis.correctives:
        pairs = basis.corrective_pairs  # (k, 2)
        products = a[:, pairs[:, 0]] * a[:, pairs[:, 1]]  # (f, k): a_i a_j
        v += (products @ basis.corrective_deltas.reshape(len(basis.correctives), -1)).reshape(len(a), n, 3)
    v += basis.neutral
    return v[0] if np.ndim(activations) == 1 else v


# --------------------------------------------------------------------------- the compact evaluator


@dataclass(frozen=True)
class CompactionError:
    """How far compact evaluation is from ``evaluate_basis``, in rig units (per coordinate).

    Attributes
    ----------
    absolute : float
        Max |compact - float64| over every unit activation (each channel at 1, the others at
        0), through every evaluation path (one frame by the kernel and by GEMV, batches).
    relative : float
        ``absolute`` divided by the largest |delta| component of the basis.
    storage : float
        Max |stored - float64| over every delta and corrective component (the rounding to the
        storage dtype, and ``drop_below``).
    neutral : float
        Max |float32 neutral - neutral|.
    """

    absolute: float
    relative: float
    storage: float
    neutral: float


@dataclass(frozen=True)
class FramePlan:
    """How ``evaluate`` computes one frame: what it walks and the bytes of stored data it reads."""

    runs: int  # stored runs of the non-zero terms walked by the compiled kernel (one call in all)
    gemv_calls: int  # one per block, for method="blocks"
    bytes_read: int  # the float32 neutral and the stored deltas


@dataclass(frozen=True)
class _Block:
    lo3: int  # first output element (3 × first vertex)
    hi3: int
    xo: int  # first column of this block in the gathered term activations
    matrix: np.ndarray  # (1 + k, hi3 - lo3) [neutral; deltas] float32, or (k, hi3 - lo3) deltas float16


def _partition(support: np.ndarray) -> list[tuple[int, int, np.ndarray]]:
    """Cut the vertex order into blocks minimising Σ (BLOCK_CALL_ELEMENTS + 3 · len · (terms + 1)).

    ``support`` (T, n) bool. Returns [(start, stop, term indices)], covering 0..n in order.
    Dynamic programming over grains of BLOCK_GRAIN_VERTICES vertices; a grain's signature is the
    set of terms touching any of its vertices, kept as a Python int bit set.
    """
    n = support.shape[1]
    bounds = np.r_[np.arange(0, n, BLOCK_GRAIN_VERTICES), n]
    grains = np.logical_or.reduceat(support, bounds[:-1], axis=1)  # (T, grains)
    packed = np.packbits(grains, axis=0, bitorder="little").T.copy()  # (grains, ceil(T / 8)) uint8
    signature = [int.from_bytes(row.tobytes(), "little") for row in packed]
    bounds_list = bounds.tolist()
    best = [0.0] * len(bounds_list)  # best[j]: cheapest cover of vertices [0, bounds[j])
    cut = [0] * len(bounds_list)
    reach = max(1, BLOCK_MAX_VERTICES // BLOCK_GRAIN_VERTICES)
    for j in range(1, len(bounds_list)):
        union, stop = 0, bounds_list[j]
        for i in range(j - 1, max(-1, j - 1 - reach), -1):
            union |= signature[i]
            cost = best[i] + BLOCK_CALL_ELEMENTS + 3 * (stop - bounds_list[i]) * (union.bit_count() + 1)
            if i == j - 1 or cost < best[j]:
                best[j], cut[j] = cost, i
    blocks = []
    j = len(bounds_list) - 1
    while j > 0:
        i = cut[j]
        terms = np.flatnonzero(grains[:, i:j].any(axis=1))
        blocks.append((bounds_list[i], bounds_list[j], terms))
        j = i
    return blocks[::-1]


def _f16_storage(values: np.ndarray) -> tuple[np.ndarray, float]:
    """float16 copy of ``values`` scaled by a power of two, subnormals flushed; returns (stored, scale).

    ``stored · scale`` approximates ``values``; the largest |value| maps into [2^14, 2^15].
    """
    peak = float(np.abs(values).max(initial=0.0))
    scale = 2.0 ** (math.ceil(math.log2(peak)) - F16_HEADROOM_EXP) if peak > 0 else 1.0
    stored = (values / scale).astype(np.float16)
    stored[np.abs(stored) < F16_MIN_NORMAL] = 0  # no float32 subnormals after unpacking
    return stored, scale


def _unpack_f16(stored: np.ndarray, out: np.ndarray) -> np.ndarray:
    """float16 values as float32 ``value · 2^-112``, exactly, into ``out`` (int32, same shape)."""
    np.left_shift(stored.view(np.int16), 13, out=out, dtype=np.int32)  # sign-extended: 111 above the sign
    np.bitwise_and(out, _F16_UNPACK_MASK, out=out)  # sign | 000 | exponent | mantissa
    return out.view(np.float32)


@functools.cache
def _kernel():  # -> the mimetic.engines.kernel module
    """The compiled kernel's module, imported on first use: ``import mimetic`` stays fast without numba."""
    from mimetic.engines import kernel

    return kernel


class CompactBasis:
    """Fast float32 evaluation of a ``Basis``: build once, evaluate many frames.

    ``CompactBasis.build(basis)`` prepares the two layouts described in the module docstring.
    ``evaluate`` (one frame) and ``evaluate_batch`` (many) return float32 vertices in the basis's
    vertex order, within ``error_bound`` of ``evaluate_basis``.

    Attributes
    ----------
    channels : tuple of str, (c,)
    n_vertices : int
    dtype : np.dtype
        Storage of the deltas: float32 or float16 (the neutral is always float32).
    compaction_error : CompactionError
        Errors reached on every unit activation (see ``CompactionError``).
    n_blocks, n_runs : int
        Blocks of the batch layout, and stored runs of the kernel over all terms.
    stored_nbytes : int
        Bytes held.
    """

    def __init__(self) -> None:
        raise TypeError("build a CompactBasis with CompactBasis.build(basis)")

    # ---- construction

    @classmethod
    def build(
        cls, basis: Basis, *, dtype: type | np.dtype = np.float32, drop_below: float = 0.0
    ) -> CompactBasis:
        """Prepare compact evaluation of ``basis``, with deltas stored as ``dtype``.

        Parameters
        ----------
        basis : Basis
        dtype : np.float32 or np.float16
            float16 halves the bytes of the deltas (relative error ≤ 2^-12 of each term's
            largest component) but costs integer unpacking on every evaluation.
        drop_below : float
            A vertex leaves a term's support when all three components of its delta are at most
            this (rig units). 0 keeps every non-zero value; a small value keeps engines whose
            deltas are dense with numerical dust (e.g. FEM) compact. Dropped values count in
            ``compaction_error`` and ``error_bound``.
        """
        if not isinstance(basis, Basis):
            raise TypeError(f"CompactBasis.build needs a Basis; got {type(basis).__name__}")
        dtype = np.dtype(dtype)
        if dtype not in DTYPES:
            raise ValueError(f"dtype must be float32 or float16; got {dtype}")
        if not (math.isfinite(drop_below) and drop_below >= 0):
            raise ValueError(f"drop_below must be a finite number ≥ 0 (rig units); got {drop_below}")
        self = object.__new__(cls)
        self.channels = basis.channels
        self.n_vertices = n = basis.n_vertices
        self.dtype = dtype
        self._n_channels = basis.n_channels
        self._pairs = basis.corrective_pairs  # (k, 2)
        c = basis.n_channels
        correctives_of: list[list[tuple[int, int]]] = [[] for _ in range(c)]
        for k, (i, j) in enumerate(self._pairs.tolist()):
            correctives_of[i].append((c + k, j))  # term c + k is a_i · a_j
        self._correctives_of = tuple(tuple(terms) for terms in correctives_of)  # (c,) by first channel
        self._no_products = [0.0] * len(self._pairs)
        self._neutral = np.ascontiguousarray(basis.neutral, dtype=np.float32)  # (n, 3)
        self._neutral.setflags(write=False)
        self._neutral_flat = self._neutral.reshape(-1)  # (3n,)

        # 1. every term (the channels, then the correctives): its support and its stored values
        deltas = np.concatenate([basis.deltas, basis.corrective_deltas]).reshape(-1, 3 * n)  # (T, 3n)
        T = self._n_terms = len(deltas)
        support = np.any(np.abs(deltas.reshape(T, n, 3)) > drop_below, axis=2)  # (T, n)
        kept = np.repeat(support, 3, axis=1)  # (T, 3n)
        if dtype == np.float16:
            stored, scales = zip(
                *(_f16_storage(d * k) for d, k in zip(deltas, kept, strict=True)), strict=True
            )
            stored = np.stack(stored)  # (T, 3n) float16
            self._scale = np.array(scales) * F16_BIAS  # folded into each term's activation
            exact = stored.astype(np.float64) * np.array(scales)[:, None]
        else:
            stored = np.where(kept, deltas, 0.0).astype(np.float32)  # (T, 3n)
            self._scale = np.ones(T)
            exact = stored.astype(np.float64)
        self._peak = np.abs(exact).max(axis=1, initial=0.0)  # (T,) M_j
        self._storage_error = np.abs(exact - deltas).max(axis=1, initial=0.0)  # (T,) e_j
        self._neutral_error = float(np.abs(self._neutral - basis.neutral).max())
        self._neutral_peak = float(np.abs(self._neutral).max())

        # 2. runs, for the kernel: each term's non-zero components, short gaps included
        self._run_pairs = np.ascontiguousarray(self._pairs, np.int32)  # (k, 2)
        self._build_runs(stored)

        # 3. blocks, for the GEMMs: [neutral; deltas of the terms touching the block]
        neutral_row = dtype == np.float32  # float16 blocks get the float32 neutral row when unpacked
        blocks, gather = [], []
        for lo, hi, terms in _partition(support):
            rows = stored[terms, 3 * lo : 3 * hi]  # (k_b, 3 m_b)
            if neutral_row:
                rows = np.concatenate([self._neutral_flat[None, 3 * lo : 3 * hi], rows])
            matrix = np.ascontiguousarray(rows)
            matrix.setflags(write=False)
            blocks.append(_Block(3 * lo, 3 * hi, len(gather), matrix))
            gather += [0, *(terms + 1).tolist()]  # column 0 of the term activations is 1 (the neutral)
        self._blocks = tuple(blocks)
        self._gather = np.array(gather, np.int64)  # (Σ (1 + k_b),) into [1, t]
        self.stored_nbytes = int(
            self._neutral.nbytes
            + sum(b.matrix.nbytes for b in blocks)
            + sum(x.nbytes for x in (self._runs, self._run_index, self._run_data))
        )

        # 4. what is reached on unit activations, through every path
        self.compaction_error = self._measure(basis)
        log.debug(
            "compact basis: %d vertices, %d terms, %s; %d blocks, %d runs, %.2f MB; error %.3g",
            n,
            T,
            dtype.name,
            len(blocks),
            self.n_runs,
            self.stored_nbytes / 1e6,
            self.compaction_error.absolute,
        )
        return self

    def _build_runs(self, stored: np.ndarray) -> None:
        """The kernel's layout of ``stored`` (T, 3n): non-zero runs, gaps ≤ RUN_GAP_ELEMENTS; float16
        values are kept as their bits (int16)."""
        T, size = stored.shape
        starts, stops, counts = [], [], []
        for j in range(T):
            nonzero = np.flatnonzero(stored[j])
            breaks = np.flatnonzero(np.diff(nonzero) > RUN_GAP_ELEMENTS + 1)
            starts.append(nonzero[np.r_[0, breaks + 1]] if len(nonzero) else nonzero)
            stops.append(nonzero[np.r_[breaks, len(nonzero) - 1]] + 1 if len(nonzero) else nonzero)
            counts.append(len(starts[-1]))
        start, stop = np.concatenate(starts), np.concatenate(stops)  # (R,) output elements
        length = stop - start
        offset = np.cumsum(length) - length  # (R,) first element of each run in the data
        total = int(length.sum())
        assert size < 2**31 and total < 2**31, "the kernel indexes in int32"
        element = np.repeat(start - offset, length) + np.arange(total)  # (total,) output element
        term = np.repeat(np.repeat(np.arange(T), counts), length)  # (total,)
        data = np.ascontiguousarray(stored[term, element])
        self._run_data = data.view(np.int16) if data.dtype == np.float16 else data  # (total,)
        self._runs = np.stack([start, length, offset], axis=1).astype(np.int32)  # (R, 3)
        self._run_index = np.r_[0, np.cumsum(counts)].astype(np.int32)  # (T + 1,)
        for array in (self._run_data, self._runs, self._run_index, self._run_pairs, self._scale):
            array.setflags(write=False)
        self._kernel_inputs = (
            self._neutral,
            self._scale,
            self._run_pairs,
            self._run_index,
            self._runs,
            self._run_data,
            int(length.max(initial=0)),
        )

    def _measure(self, basis: Basis) -> CompactionError:
        c = self._n_channels
        methods = ("runs", "blocks")
        worst = 0.0
        for start in range(0, c, 32):
            units = np.eye(c)[start : start + 32]  # (u, c)
            reference = evaluate_basis(basis, units)  # (u, n, 3)
            worst = max(worst, float(np.abs(self.evaluate_batch(units) - reference).max()))
            for a, ref in zip(units, reference, strict=True):
                for method in methods:
                    worst = max(worst, float(np.abs(self.evaluate(a, method=method) - ref).max()))
        peak = max(float(np.abs(basis.deltas).max()), float(np.abs(basis.corrective_deltas).max(initial=0)))
        return CompactionError(
            absolute=worst,
            relative=worst / peak if peak > 0 else 0.0,
            storage=float(self._storage_error.max(initial=0.0)),
            neutral=self._neutral_error,
        )

    @property
    def n_blocks(self) -> int:
        return len(self._blocks)

    @property
    def n_runs(self) -> int:
        return len(self._runs)

    # ---- one frame

    def _frame(self, activations: np.ndarray) -> tuple[list[float], list[int]]:
        """Term activations of one frame as Python floats, (T,): the channels, then the corrective
        products; and the indices of the non-zero ones, ascending.

        The common case (a finite (c,) vector) is checked in about a microsecond; anything else
        goes through ``check_activations`` for a precise message. Only the correctives of non-zero
        channels are multiplied out (a zero frame costs no corrective work).
        """
        try:
            a = np.asarray(activations, dtype=np.float64)
            t = a.tolist() if a.shape == (self._n_channels,) else None
        except (TypeError, ValueError):
            t = None
        if t is None or not math.isfinite(sum(t)):  # the sum is NaN or inf if any value is
            a = check_activations(self.channels, activations, ndim=1)  # raises, or the sum overflowed
            t = a.tolist()
        active = a.nonzero()[0].tolist()
        t += self._no_products
        products = []
        for i in active:
            for k, j in self._correctives_of[i]:
                product = t[i] * t[j]
                if product:  # zero when channel j is, or on underflow
                    t[k] = product
                    products.append(k)
        if products:
            products.sort()
            active += products
        return t, active

    def plan(self, activations: np.ndarray, *, method: Method = "auto") -> FramePlan:
        """What ``evaluate(activations, method=method)`` walks and the bytes it reads."""
        _, active = self._frame(activations)
        if _checked(method) == "blocks":
            neutral = 4 * (self.dtype == np.float16)  # float16 blocks read the float32 neutral apart
            read = sum(b.matrix.nbytes + (b.hi3 - b.lo3) * neutral for b in self._blocks)
            return FramePlan(runs=0, gemv_calls=len(self._blocks), bytes_read=int(read))
        index = self._run_index
        runs = sum(int(index[j + 1] - index[j]) for j in active)
        elements = sum(int(self._runs[index[j] : index[j + 1], 1].sum()) for j in active)
        read = self._neutral.nbytes + self.dtype.itemsize * elements
        return FramePlan(runs=runs, gemv_calls=0, bytes_read=int(read))

    @property
    def nbytes(self) -> int:
        """Bytes ``evaluate`` reads for a frame with every channel non-zero (see ``plan``)."""
        return self.plan(np.ones(self._n_channels)).bytes_read

    def evaluate(
        self, activations: np.ndarray, *, out: np.ndarray | None = None, method: Method = "auto"
    ) -> np.ndarray:
        """Vertex positions for one frame.

        Parameters
        ----------
        activations : (c,) float64
            In the order of ``channels``.
        out : (n, 3) float32, optional
            Written in place and returned (saves an allocation per frame).
        method : "auto", "runs" or "blocks"
            "runs" (= "auto"): one call of the compiled kernel over the stored runs of the non-zero
            terms; "blocks": one GEMV per block. Both give results within ``error_bound``.

        Returns
        -------
        vertices : (n, 3) float32, the basis's vertex order, rig units (a new array unless ``out``).
        """
        if method == "auto" or _checked(method) == "runs":
            return self._evaluate_runs(activations, out)
        t, _ = self._frame(activations)  # (T,) floats
        out = _output(out, (self.n_vertices, 3))
        self._gemv(t, out.reshape(-1))
        return out

    def _evaluate_runs(self, activations: object, out: np.ndarray | None) -> np.ndarray:
        """``evaluate`` by the compiled kernel. A float64 (c,) vector and a float32 (n, 3) ``out``
        cost one call, whose checks are in the kernel; anything else is converted, or refused with
        the precise message of ``check_activations`` or ``_output``."""
        kernel = _kernel()
        if out is None:
            out = np.empty((self.n_vertices, 3), np.float32)
        try:
            status = kernel.evaluate_runs(out, activations, *self._kernel_inputs)
        except TypeError:  # numba has no version for these types (a list, float32, a read-only out, …)
            status = kernel.BAD_SHAPE
        if status == kernel.OK:
            return out
        if status == kernel.TOO_LARGE:
            raise self._too_large()
        a = np.ascontiguousarray(check_activations(self.channels, activations, ndim=1))  # may raise
        status = kernel.evaluate_runs(_output(out, (self.n_vertices, 3)), a, *self._kernel_inputs)
        if status == kernel.TOO_LARGE:
            raise self._too_large()
        if status != kernel.OK:
            raise AssertionError(f"the kernel refused inputs check_activations accepts (status {status})")
        return out

    def _too_large(self) -> ActivationError:
        if self.dtype == np.float16:
            return ActivationError(
                "activations too large for float16 storage (|activation · delta| ≥ 2^30 rig units); "
                "build the CompactBasis with dtype=np.float32"
            )
        return ActivationError("activations too large for float32 (|activation| ≥ 2^127); check their units")

    def _alphas(self, t: np.ndarray) -> np.ndarray:
        """Term activations (..., T) as they multiply the stored values (float16 scale folded in)."""
        alphas = t * self._scale
        if not np.all(np.abs(alphas) < ALPHA_LIMIT):
            raise self._too_large()
        return alphas

    def _gemv(self, t: list[float], flat: np.ndarray) -> None:
        """flat[block] = W_b^T [1, t[terms_b]] for every block b (the neutral included)."""
        x = np.empty(self._n_terms + 1, np.float32)
        x[0] = 1.0
        x[1:] = self._alphas(np.array(t))
        x = x[self._gather]  # (Σ (1 + k_b),)
        buffer = self._unpack_buffer()
        sgemv = blas.sgemv
        for block in self._blocks:
            matrix = self._block_matrix(block, buffer)  # (1 + k_b, 3 m_b)
            sgemv(1.0, matrix.T, x, 0.0, flat, block.xo, 1, block.lo3, 1, 0, 1)

    def _unpack_buffer(self) -> np.ndarray | None:
        if self.dtype == np.float32:
            return None
        return np.empty(max(b.matrix.size + b.matrix.shape[1] for b in self._blocks), np.int32)

    def _block_matrix(self, block: _Block, buffer: np.ndarray | None) -> np.ndarray:
        """The block's (1 + k, 3 m) float32 matrix [neutral; deltas] (float16 unpacked into ``buffer``)."""
        if buffer is None:
            return block.matrix
        k, m3 = block.matrix.shape
        work = buffer[: (k + 1) * m3].reshape(k + 1, m3)
        work[0] = self._neutral_flat[block.lo3 : block.hi3].view(np.int32)
        _unpack_f16(block.matrix, work[1:])
        return work.view(np.float32)

    # ---- many frames

    def evaluate_batch(self, activations: np.ndarray, *, out: np.ndarray | None = None) -> np.ndarray:
        """Vertex positions for many frames: one GEMM per block, ``A[:, terms_b] @ W_b``.

        Parameters
        ----------
        activations : (f, c) float64
        out : (f, n, 3) float32, optional
            Written in place and returned.

        Returns
        -------
        vertices : (f, n, 3) float32, the basis's vertex order, rig units.
        """
        a = check_activations(self.channels, activations, ndim=2)  # (f, c)
        f = len(a)
        out = _output(out, (f, self.n_vertices, 3))
        flat = out.reshape(f, 3 * self.n_vertices)  # (f, 3n)
        buffer = self._unpack_buffer()
        for start in range(0, f, BATCH_CHUNK_FRAMES):
            stop = min(f, start + BATCH_CHUNK_FRAMES)
            x = np.empty((stop - start, self._n_terms + 1), np.float32)  # (f', 1 + T)
            x[:, 0] = 1.0
            x[:, 1:] = self._alphas(self._terms(a[start:stop]))
            x = x[:, self._gather]  # (f', Σ (1 + k_b)), C-contiguous
            for block in self._blocks:
                matrix = self._block_matrix(block, buffer)  # (1 + k_b, 3 m_b)
                columns = x[:, block.xo : block.xo + len(matrix)]
                np.matmul(columns, matrix, out=flat[start:stop, block.lo3 : block.hi3])
        return out

    def _terms(self, a: np.ndarray) -> np.ndarray:
        """Term activations (f, T) float64 of checked activations (f, c)."""
        if len(self._pairs) == 0:
            return a
        return np.concatenate([a, a[:, self._pairs[:, 0]] * a[:, self._pairs[:, 1]]], axis=1)

    # ---- accuracy

    def error_bound(self, activations: np.ndarray) -> float | np.ndarray:
        """Rigorous bound on max |compact - evaluate_basis|: (c,) -> float, (f, c) -> (f,).

        See "Exactness contract" in the module docstring; K counts the neutral and the non-zero
        terms of each frame.
        """
        a = check_activations(self.channels, activations)
        t = np.abs(self._terms(np.atleast_2d(a)))  # (f, T)
        K = 1 + np.count_nonzero(t, axis=1)  # (f,)
        gamma = K * U32 / (1 - K * U32)
        magnitude = self._neutral_peak + t @ self._peak  # (f,) N_max + Σ |t_j| M_j
        bound = (
            self._neutral_error
            + t @ (self._storage_error + U32 * self._peak)
            + gamma * (1 + U32) * magnitude
            + 2 * K * U64 * (magnitude + t @ self._storage_error)  # the float64 reference's own rounding
        )
        return float(bound[0]) if a.ndim == 1 else bound


def _checked(method: str) -> Method:
    if method not in ("auto", "runs", "blocks"):
        raise ValueError(f"method must be 'auto', 'runs' or 'blocks'; got {method!r}")
    return method


def _output(out: np.ndarray | None, shape: tuple[int, ...]) -> np.ndarray:
    if out is None:
        return np.empty(shape, np.float32)
    if not (
        isinstance(out, np.ndarray)
        and out.shape == shape
        and out.dtype == np.float32
        and out.flags.c_contiguous
        and out.flags.writeable
    ):
        got = f"{out.shape} {out.dtype}" if isinstance(out, np.ndarray) else type(out).__name__
        raise ValueError(f"out must be a writeable C-contiguous float32 array of shape {shape}; got {got}")
    return out
