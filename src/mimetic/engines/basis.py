"""Baked linear rigs: ``Basis``, and ``evaluate_basis``, the one evaluation every consumer calls.

A ``Basis`` is a linearised rig, evaluated frame after frame::

    vertices = neutral + Σ_c a_c · deltas[c] + Σ_k a_i(k) · a_j(k) · correctives[k].delta

Call the channels and the correctives together the *terms* j = 1..T, with activations t_j (a
corrective's is the product of its two channels) and deltas D_j.

Layout
------
Each term moves only its *support* (a muscle moves 5-20 % of the vertices; on the default head
55 % of the vertices move with no channel at all). ``evaluate_basis`` cuts the vertex order into
blocks of ``BLOCK_VERTICES`` vertices and keeps, per block b, one matrix
``W_b = [neutral_b; D_j,b for the k_b terms that move a vertex of b]``, (1 + k_b, 3 m_b). A batch
of frames is then one matrix product per block, ``[1, t][:, terms_b] @ W_b``, written straight
into the output: the neutral is the row multiplied by 1, so there is no separate neutral pass, and
terms that move nothing in a block cost nothing there. On the default head (13,363 vertices, 50
channels, 24 correctives) the blocks hold 27 % of the dense ``[neutral; deltas]`` elements.

One frame reads only the terms that are not 0 (a realistic frame sets 16 of 88): each term is kept
as *runs* of its non-zero elements in the flattened vertex order (``_Runs``; gaps of up to
``RUN_GAP`` zeros stay inside a run, so a run is long enough for the loop to vectorise), and one
compiled call (``kernels.basis_frame``, numba, imported on the first frame) copies the neutral and
adds ``t_j`` times each run of each non-zero term, term after term. Per frame that reads ~80k
elements on the default head instead of the blocks' 1.1 M, and the GEMV per block it replaced cost
~110 µs against ~15 µs. The vertex order is kept (every rig element refers to vertices by index),
so the output needs no reordering. Both layouts are built on first use in each dtype and cached on
the basis (``Basis`` is frozen).

Half the elements those runs read are zeros (a muscle's vertices lie scattered in the vertex
order). Runs over the vertices sorted by which terms move them (lexicographically, larger supports
first) were measured and not kept: the realistic frame then reads 48k elements in 191 runs instead
of 83k in 700, but putting its 6,721 moved vertices back in place (a scatter, ~4 µs) costs more
than the zeros save, 18 µs against 16 µs a warm float32 frame; it pays only from ~25 non-zero
terms on (every channel at once: 34 µs against 50 µs; ``docs/benchmarks.md``).

Precision
---------
``dtype=np.float64`` (the default) gives the float64 sum: zero activations give ``neutral``
exactly, and a channel at 1 gives ``neutral + delta`` up to one rounding. ``dtype=np.float32``
halves the bytes moved, for display (``mimetic.view``) and long clips; per coordinate, its
distance to the exact sum v is at most (rigorous, with the neutral and deltas rounded to float32
and the products summed in any order)::

    |v̂ - v| ≤ γ_(K+3) · (N_max + Σ_j |t_j| M_j) + η · (K + Σ_j |t_j| + Σ_j M_j)

with M_j = max |D_j|, N_max = max |neutral|, K = T + 1, γ_m = m u / (1 - m u), u = 2^-24 and
η = 2^-148 (underflow); the same formula with u = 2^-53 and η = 2^-1071 bounds float64. On the
default head (cm) the float32 bound is ~1e-4 cm for random poses, and float32 stays within 5e-6
cm of float64. Zero activations give the float32-rounded neutral exactly.
"""

from __future__ import annotations

import difflib
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache, cached_property
from types import ModuleType

import numpy as np

from mimetic.errors import ActivationError, RigError
from mimetic.rig.activations import check_shape

BLOCK_VERTICES = 512
"""Vertices per block of the evaluation layout (see the module docstring). Smaller blocks skip more
zeros but cost one more BLAS call each; on the default head 512 was the fastest of 128-2048 for
one frame and for batches, by 10-30 % (``benchmarks/bench_basis.py`` sweeps it)."""

RUN_GAP = 32
"""A run of a term's non-zero elements (one frame's layout) goes on across at most this many zeros."""

DTYPES = (np.dtype(np.float64), np.dtype(np.float32))
"""The dtypes ``evaluate_basis`` computes in."""

LIMITS = {np.dtype(np.float64): 2.0**1023, np.dtype(np.float32): 2.0**127}
"""Each |t_j| and N_max + Σ_j |t_j| M_j must stay below this, so no partial sum overflows."""


# --------------------------------------------------------------------------- the basis


@dataclass(frozen=True)
class Handover:
    """An array handed to a ``Basis`` or ``Corrective`` to keep as it is, where they copy anything
    else: for a maker (``engines.bake``) that built the array for them and drops its own reference
    (a 1M-vertex basis's deltas are 1.5 GB; a copy doubled the bake's peak). The array must be
    C-contiguous float64; it is made read-only."""

    array: np.ndarray


def _frozen(value: object, where: str, *, ndim: int) -> np.ndarray:
    """A read-only C-contiguous float64 copy of ``value`` (``value.array`` itself for a ``Handover``)
    with ``ndim`` dimensions and finite values."""
    try:
        if isinstance(value, Handover):
            array = value.array
            if array.dtype != np.float64 or not array.flags.c_contiguous:
                raise TypeError("a Handover array must be C-contiguous float64")
        else:
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

    @cached_property
    def _layout64(self) -> _Layout:
        return _Layout.build(self, np.dtype(np.float64))

    @cached_property
    def _layout32(self) -> _Layout:
        return _Layout.build(self, np.dtype(np.float32))

    @cached_property
    def _runs64(self) -> _Runs:
        return _Runs.build(self, np.dtype(np.float64))

    @cached_property
    def _runs32(self) -> _Runs:
        return _Runs.build(self, np.dtype(np.float32))


def basis_bytes(channels: int, vertices: int, correctives: int = 0, *, itemsize: int = 8) -> int:
    """Bytes of a basis's arrays: ``(channels + correctives + 1) × vertices × 3 × itemsize`` (the
    deltas, the correctives' deltas and the neutral; float64 unless ``itemsize`` says otherwise)."""
    return (channels + correctives + 1) * vertices * 3 * itemsize


def human_bytes(size: float) -> str:
    """A byte count for people: '812 kB', '1.4 MiB'…, '2.31 GiB' (binary units above a kilobyte)."""
    if size < 1024:
        return f"{int(size)} B"
    for unit in ("KiB", "MiB", "GiB", "TiB"):
        size /= 1024
        if size < 1024 or unit == "TiB":
            return f"{size:.3g} {unit}" if size < 100 else f"{size:.0f} {unit}"
    raise AssertionError("unreachable")


def check_activations(channels: Sequence[str], activations: object, *, ndim: int | None = None) -> np.ndarray:
    """Activations as float64 (c,) or (f, c) for a basis's ``channels`` (``rig.activations.check_shape``)."""
    return check_shape(channels, activations, ndim=ndim, owner="basis")


# --------------------------------------------------------------------------- evaluation


@dataclass(frozen=True, eq=False)
class _Layout:
    """A basis cut into blocks for ``evaluate_basis``, in one dtype (module docstring, "Layout").

    Attributes
    ----------
    blocks : tuple of (start, stop, column, matrix)
        Block b covers the output elements ``start:stop`` of the flattened (3n,) vertices; its
        ``matrix`` W_b (1 + k_b, stop - start) multiplies the columns ``column:column + 1 + k_b``
        of the gathered activations.
    gather : (Σ_b (1 + k_b),) int64
        The columns of ``[1, t]`` (1 + T) that the blocks read, block after block.
    peaks : (T,) float64
        M_j = max |D_j| of each term, channels then correctives.
    neutral_peak : float
        N_max = max |neutral|.
    """

    blocks: tuple[tuple[int, int, int, np.ndarray], ...]
    gather: np.ndarray
    peaks: np.ndarray
    neutral_peak: float

    @classmethod
    def build(cls, basis: Basis, dtype: np.dtype) -> _Layout:
        n = basis.n_vertices
        terms = np.concatenate([basis.deltas, basis.corrective_deltas])  # (T, n, 3)
        largest = np.abs(terms).max(axis=2)  # (T, n): each term's largest component at each vertex
        moves = largest > 0  # (T, n): the supports
        blocks, gather = [], []
        for lo in range(0, n, BLOCK_VERTICES):
            hi = min(n, lo + BLOCK_VERTICES)
            touching = np.flatnonzero(moves[:, lo:hi].any(axis=1))  # (k_b,) terms moving the block
            rows = np.concatenate([basis.neutral[None, lo:hi], terms[touching, lo:hi]])  # (1 + k_b, m_b, 3)
            matrix = rows.reshape(len(rows), -1).astype(dtype)  # (1 + k_b, 3 m_b)
            matrix.setflags(write=False)
            blocks.append((3 * lo, 3 * hi, len(gather), matrix))
            gather += [0, *(touching + 1).tolist()]  # column 0 of [1, t] multiplies the neutral
        gather_array = np.array(gather, np.int64)
        peaks = largest.max(axis=1, initial=0.0)  # (T,)
        for array in (gather_array, peaks):
            array.setflags(write=False)
        return cls(tuple(blocks), gather_array, peaks, float(np.abs(basis.neutral).max()))


@dataclass(frozen=True, eq=False)
class _Runs:
    """A basis as runs of non-zero elements per term, for one frame in one dtype (module docstring,
    "Layout"; ``kernels.basis_frame`` reads it).

    Attributes
    ----------
    neutral : (3n,) the neutral, flattened.
    term_runs : (T + 1,) int64
        Term j's runs are ``runs[term_runs[j] : term_runs[j + 1]]``.
    runs : (R, 3) int64
        (first element of the flattened vertices, length, first element of ``values``) of each run:
        a stretch of the term's flattened delta from one non-zero element to another, with gaps of
        at most ``RUN_GAP`` zeros inside.
    values : (Σ length,) the runs' elements, run after run.
    peaks : (T,) float64 and neutral_peak : float, as in ``_Layout``.
    """

    neutral: np.ndarray
    term_runs: np.ndarray
    runs: np.ndarray
    values: np.ndarray
    peaks: np.ndarray
    neutral_peak: float

    @classmethod
    def build(cls, basis: Basis, dtype: np.dtype) -> _Runs:
        terms = np.concatenate([basis.deltas, basis.corrective_deltas]).reshape(-1, 3 * basis.n_vertices)
        cast = terms.astype(dtype)  # (T, 3n)
        term_runs, runs, values, at = [0], [], [], 0
        for row in cast:
            nz = np.flatnonzero(row)
            if len(nz):
                cut = np.flatnonzero(np.diff(nz) > RUN_GAP + 1)  # a longer gap of zeros ends a run
                first = nz[np.r_[0, cut + 1]]
                last = nz[np.r_[cut, len(nz) - 1]] + 1
                length = last - first
                runs.append(np.column_stack([first, length, at + np.cumsum(length) - length]))
                values += [row[i:j] for i, j in zip(first, last, strict=True)]
                at += int(length.sum())
            term_runs.append(term_runs[-1] + (len(runs[-1]) if len(nz) else 0))
        arrays = (
            basis.neutral.reshape(-1).astype(dtype),
            np.array(term_runs, np.int64),
            np.concatenate(runs).astype(np.int64) if runs else np.zeros((0, 3), np.int64),
            np.concatenate(values) if values else np.zeros(0, dtype),
            np.abs(terms).max(axis=1, initial=0.0),
        )
        for array in arrays:
            array.setflags(write=False)
        return cls(*arrays, float(np.abs(basis.neutral).max()))


def evaluate_basis(
    basis: Basis, activations: np.ndarray, *, dtype: type | np.dtype = np.float64
) -> np.ndarray:
    """Vertex positions of a baked rig for one frame or many.

    Parameters
    ----------
    basis : Basis
        ``neutral`` (n, 3) float64 in rig units; ``deltas`` (c, n, 3) float64, the displacement
        caused by one unit of each channel; ``correctives`` add ``a_i a_j delta``.
    activations : (c,) or (f, c) float64
        Muscle channels in [0, 1]; jaw and gaze channels in radians.
    dtype : np.float64 or np.float32
        What the vertices are computed and returned in. float64 (default) is exact at rest and
        agrees with the written-out sum to float64 rounding; float32 moves half the bytes, within
        the bound in the module docstring ("Precision"): use it to display or stream frames, not
        to measure errors or fit.

    Returns
    -------
    vertices : (n, 3) or (f, n, 3) ``dtype``, C-contiguous, a new array; same units and vertex
        order as ``basis.neutral``.

    Raises
    ------
    ActivationError
        Activations of the wrong shape or not finite, or so large that the sum would overflow
        ``dtype`` (see ``LIMITS``).
    """
    dtype = np.dtype(dtype)
    if dtype not in DTYPES:
        raise ValueError(f"dtype must be float64 or float32; got {dtype}")
    if (
        type(activations) is np.ndarray
        and activations.dtype == np.float64
        and activations.shape == (len(basis.channels),)
    ):
        a = activations  # (c,) as given: the kernel refuses NaN and inf, and they are checked below then
    else:
        a = check_activations(basis.channels, activations)  # (c,) or (f, c)
    if a.ndim == 1 or len(a) == 1:  # one frame: the runs of the terms that are not 0, compiled (numba)
        runs = basis._runs64 if dtype == np.float64 else basis._runs32
        pairs = basis.corrective_pairs
        v = _kernels().basis_frame(
            runs.neutral,
            a.reshape(-1),
            pairs,
            runs.peaks,
            runs.neutral_peak,
            LIMITS[dtype],
            runs.term_runs,
            runs.runs,
            runs.values,
        )  # (n, 3)
        if len(v):
            return v if a.ndim == 1 else v[None]
        a = np.atleast_2d(check_activations(basis.channels, a))  # the kernel refused the frame: say why
        with np.errstate(over="ignore", invalid="ignore"):
            t = np.concatenate([a, a[:, pairs[:, 0]] * a[:, pairs[:, 1]]], axis=1)
        _check_range(t, runs, dtype)
    a = np.atleast_2d(a)  # (f, c)
    layout = basis._layout64 if dtype == np.float64 else basis._layout32
    pairs = basis.corrective_pairs  # (k, 2)
    with np.errstate(over="ignore", invalid="ignore"):  # a product that overflows is refused just below
        x = np.concatenate([np.ones((len(a), 1)), a, a[:, pairs[:, 0]] * a[:, pairs[:, 1]]], axis=1)  # [1, t]
        _check_range(x[:, 1:], layout, dtype)
    x = x[:, layout.gather].astype(dtype, copy=False)  # (f, Σ (1 + k_b))
    out = np.empty((len(a), 3 * basis.n_vertices), dtype)  # (f, 3n)
    for start, stop, column, matrix in layout.blocks:
        # (f, 1 + k_b) @ (1 + k_b, 3 m_b): the block's neutral plus its terms, straight into the output
        np.matmul(x[:, column : column + len(matrix)], matrix, out=out[:, start:stop])
    out = out.reshape(len(a), basis.n_vertices, 3)
    return out[0] if np.ndim(activations) == 1 else out


@cache
def _kernels() -> ModuleType:
    """``mimetic.engines.kernels``, imported on the first single frame (numba loads in ~0.3 s)."""
    from mimetic.engines import kernels

    return kernels


def _check_range(t: np.ndarray, layout: _Layout | _Runs, dtype: np.dtype) -> None:
    """Refuse frames of term activations ``t`` (f, T) whose sum could overflow ``dtype``."""
    limit = LIMITS[dtype]
    size = np.abs(t)  # (f, T)
    magnitude = layout.neutral_peak + size @ layout.peaks  # (f,) N_max + Σ |t_j| M_j; nan or inf if t is
    fine = (magnitude < limit) & (size.max(axis=1, initial=0.0) < limit)
    if not fine.all():
        frame = int(np.argmin(fine))
        where = f" of frame {frame}" if len(t) > 1 else ""
        raise ActivationError(
            f"activations{where} too large to evaluate in {dtype.name}: |neutral| + Σ |activation · delta| "
            f"reaches {magnitude[frame]:.3g} rig units (limit {limit:.3g}); check their units"
        )
