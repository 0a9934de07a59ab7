"""Tests of the baked linear rig: ``Basis`` and ``evaluate_basis`` in float64 and float32.

Bases are built synthetically (``regional_basis``): a few hundred vertices in a shuffled order,
so that every regional support is fragmented in vertex order as on a real mesh; one channel
moves every vertex (like a head rotation), one moves nothing, one moves a single vertex.
Tolerances: float64 is compared with the sum written out at 1e-12 (float64 rounding of sums of a
few terms of magnitude ≤ 10); float32 with float64 within ``error_bound``, the rigorous bound of
the module docstring ("Precision") for each of the two.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import mimetic.engines.basis as basis_module
from mimetic.engines.basis import Basis, Corrective, Handover, check_activations, evaluate_basis
from mimetic.errors import ActivationError, RigError

UNIT_ROUNDOFF = {np.float32: 2.0**-24, np.float64: 2.0**-53}
UNDERFLOW = {np.float32: 2.0**-148, np.float64: 2.0**-1071}


def regional_basis(
    seed: int = 0, *, n: int = 300, channels: int = 8, correctives: tuple[tuple[int, int], ...] = ()
) -> Basis:
    """A basis of ``n`` vertices in a shuffled order with regional, smoothly falling-off deltas.

    Channel 0 moves every vertex; channel 1 moves nothing; channel 2 moves one vertex; the others
    move the vertices within a random radius of a random centre (5-30 % of them). Each corrective
    (i, j) moves the intersection of the two supports.
    """
    rng = np.random.default_rng(seed)
    neutral = rng.normal(scale=5.0, size=(n, 3))
    deltas = np.zeros((channels, n, 3))
    deltas[0] = np.cross([0.0, 1.0, 0.0], neutral) * 0.1  # a rotation about +Y
    deltas[2, rng.integers(n)] = rng.normal(size=3)
    for c in range(3, channels):
        centre = neutral[rng.integers(n)]
        distance = np.linalg.norm(neutral - centre, axis=1)
        radius = np.quantile(distance, rng.uniform(0.05, 0.3))
        falloff = np.clip(1 - (distance / radius) ** 2, 0, None) ** 2  # (n,)
        deltas[c] = falloff[:, None] * rng.normal(size=3)
    names = tuple(f"channel_{c}" for c in range(channels))
    pairs = []
    for i, j in correctives:
        overlap = np.minimum(np.abs(deltas[i]).sum(1), np.abs(deltas[j]).sum(1))  # (n,)
        pairs.append(Corrective((names[i], names[j]), overlap[:, None] * rng.normal(size=3)))
    return Basis(names, neutral, deltas, tuple(pairs))


SMALL_BASIS = regional_basis(0)
N_CHANNELS = SMALL_BASIS.n_channels
BASIS_WITH_CORRECTIVES = regional_basis(1, correctives=((3, 4), (0, 5), (6, 6)))


def random_activations(rng: np.random.Generator, *shape: int, active: float = 0.5) -> np.ndarray:
    """Activations in [-0.5, 1], each channel non-zero with probability ``active``."""
    a = rng.uniform(-0.5, 1.0, size=(*shape, N_CHANNELS))
    return np.where(rng.random(a.shape) < active, a, 0.0)


def error_bound(basis: Basis, activations: np.ndarray, dtype: type) -> np.ndarray:
    """The bound (f,) on max |evaluate_basis(..., dtype=dtype) - exact sum| of the module docstring:
    γ_(K+3) (N_max + Σ_j |t_j| M_j) + η (K + Σ_j |t_j| + Σ_j M_j)."""
    a = np.atleast_2d(activations)
    pairs = basis.corrective_pairs
    t = np.abs(np.concatenate([a, a[:, pairs[:, 0]] * a[:, pairs[:, 1]]], axis=1))  # (f, T)
    peaks = np.abs(np.concatenate([basis.deltas, basis.corrective_deltas])).max(axis=(1, 2))  # (T,) M_j
    K = 1 + t.shape[1]
    u, eta = UNIT_ROUNDOFF[dtype], UNDERFLOW[dtype]
    gamma = (K + 3) * u / (1 - (K + 3) * u)
    return gamma * (np.abs(basis.neutral).max() + t @ peaks) + eta * (K + t.sum(axis=1) + peaks.sum())


def float32_within_bound(basis: Basis, activations: np.ndarray) -> np.ndarray:
    """Whether each frame of float32 evaluation is within the two bounds of the float64 one, (f,)."""
    a = np.atleast_2d(activations)
    error = np.abs(evaluate_basis(basis, a, dtype=np.float32) - evaluate_basis(basis, a)).max(axis=(1, 2))
    return error <= error_bound(basis, a, np.float32) + error_bound(basis, a, np.float64)


def frozen_copy(array: np.ndarray) -> np.ndarray:
    copy = np.array(array)
    copy.setflags(write=False)
    return copy


# --------------------------------------------------------------------------- Basis


def test_basis_holds_read_only_float64_copies():
    neutral = np.zeros((4, 3), np.float32)
    deltas = np.ones((2, 4, 3), np.int64)
    basis = Basis(["a", "b"], neutral, deltas, [Corrective(["a", "b"], np.ones((4, 3)))])
    assert basis.channels == ("a", "b")
    assert basis.neutral.shape == (4, 3) and basis.neutral.dtype == np.float64
    assert basis.deltas.shape == (2, 4, 3) and basis.deltas.dtype == np.float64
    assert basis.correctives[0].channels == ("a", "b")
    assert basis.corrective_pairs.tolist() == [[0, 1]]
    assert basis.corrective_deltas.shape == (1, 4, 3)
    for array in (basis.neutral, basis.deltas, basis.correctives[0].delta, basis.corrective_pairs):
        assert not array.flags.writeable
    neutral[0, 0] = 7.0  # the caller's array is not aliased
    assert basis.neutral[0, 0] == 0.0


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"neutral": np.zeros((4, 2))}, r"basis.neutral must have shape \(n, 3\); got \(4, 2\)"),
        ({"neutral": np.zeros((0, 3)), "deltas": np.zeros((2, 0, 3))}, "no vertices"),
        ({"deltas": np.zeros((3, 4, 3))}, r"\(channels, n, 3\) = \(2, 4, 3\).*got \(3, 4, 3\)"),
        ({"deltas": np.zeros((2, 5, 3))}, r"got \(2, 5, 3\)"),
        ({"deltas": np.zeros((2, 4))}, r"basis.deltas must have shape \(channels, n, 3\)"),
        ({"channels": ("a", "a")}, "unique; repeated: a"),
        ({"channels": ("a", "")}, "non-empty strings"),
        ({"channels": (), "deltas": np.zeros((0, 4, 3))}, "at least one channel"),
        ({"neutral": np.full((4, 3), np.nan)}, r"non-finite value at \(0, 0\)"),
        ({"deltas": np.full((2, 4, 3), np.inf)}, "basis.deltas has a non-finite value"),
        ({"neutral": [["x", 1, 2]] * 4}, "cannot be read as a float64 array"),
        ({"correctives": (Corrective(("a", "jaw_opn"), np.zeros((4, 3))),)}, "unknown channel 'jaw_opn'"),
        ({"correctives": (Corrective(("a", "b"), np.zeros((5, 3))),)}, r"must have shape \(4, 3\)"),
        ({"correctives": (("a", "b"),)}, "must be a Corrective"),
    ],
)
def test_basis_rejects_inconsistent_arrays(kwargs, message):
    fields = {"channels": ("a", "b"), "neutral": np.zeros((4, 3)), "deltas": np.zeros((2, 4, 3))} | kwargs
    with pytest.raises(RigError, match=message):
        Basis(**fields)


def test_corrective_unknown_channel_suggests_close_names():
    corrective = Corrective(("jaw_opn", "lip"), np.zeros((1, 3)))
    with pytest.raises(RigError, match="did you mean jaw_open"):
        Basis(("jaw_open", "lip"), np.zeros((1, 3)), np.zeros((2, 1, 3)), (corrective,))


@pytest.mark.parametrize("channels", ["a", ("a",), ("a", "b", "c"), ("a", 1)])
def test_corrective_needs_two_channel_names(channels):
    with pytest.raises(RigError, match="two channel names"):
        Corrective(channels, np.zeros((1, 3)))


# --------------------------------------------------------------------------- evaluate_basis

DTYPES = (np.float64, np.float32)


@pytest.mark.parametrize("dtype", DTYPES)
def test_evaluate_basis_shapes_and_dtypes(dtype):
    n = SMALL_BASIS.n_vertices
    one = evaluate_basis(SMALL_BASIS, np.zeros(N_CHANNELS), dtype=dtype)
    many = evaluate_basis(SMALL_BASIS, np.zeros((5, N_CHANNELS)), dtype=dtype)
    none = evaluate_basis(SMALL_BASIS, np.zeros((0, N_CHANNELS)), dtype=dtype)
    for got, shape in ((one, (n, 3)), (many, (5, n, 3)), (none, (0, n, 3))):
        assert got.shape == shape and got.dtype == dtype
        assert got.flags.c_contiguous and got.flags.writeable
    assert evaluate_basis(SMALL_BASIS, np.zeros(N_CHANNELS)).dtype == np.float64  # the default


def test_evaluate_basis_zero_activations_give_exactly_the_neutral():
    for basis in (SMALL_BASIS, BASIS_WITH_CORRECTIVES):
        np.testing.assert_array_equal(evaluate_basis(basis, np.zeros(N_CHANNELS)), basis.neutral)
        np.testing.assert_array_equal(evaluate_basis(basis, np.zeros((3, N_CHANNELS)))[2], basis.neutral)
        np.testing.assert_array_equal(evaluate_basis(basis, -np.zeros(N_CHANNELS)), basis.neutral)
        rounded = basis.neutral.astype(np.float32)  # float32: exactly the rounded neutral
        np.testing.assert_array_equal(evaluate_basis(basis, np.zeros(N_CHANNELS), dtype=np.float32), rounded)
        np.testing.assert_array_equal(
            evaluate_basis(basis, -np.zeros((2, N_CHANNELS)), dtype=np.float32), [rounded, rounded]
        )


@given(
    a=arrays(np.float64, N_CHANNELS, elements=st.floats(0, 1)),
    b=arrays(np.float64, N_CHANNELS, elements=st.floats(0, 1)),
)
def test_evaluate_basis_is_linear_in_activations(a, b):
    def offset(x):
        return evaluate_basis(SMALL_BASIS, x) - SMALL_BASIS.neutral

    np.testing.assert_allclose(offset(a + b), offset(a) + offset(b), atol=1e-12)


def written_out(basis: Basis, a: np.ndarray) -> np.ndarray:
    """The basis equation term by term, in float64: (f, c) -> (f, n, 3)."""
    return np.array(
        [
            basis.neutral
            + sum(frame[c] * basis.deltas[c] for c in range(basis.n_channels))
            + sum(
                frame[basis.channels.index(i)] * frame[basis.channels.index(j)] * k.delta
                for k in basis.correctives
                for i, j in [k.channels]
            )
            for frame in a
        ]
    )


def test_evaluate_basis_matches_the_sum_written_out():
    rng = np.random.default_rng(2)
    a = random_activations(rng, 4)
    basis = BASIS_WITH_CORRECTIVES
    expected = written_out(basis, a)
    got = evaluate_basis(basis, a)
    assert got.shape == expected.shape
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(evaluate_basis(basis, a[1]), got[1], rtol=0, atol=1e-12)  # GEMV vs GEMM
    error = np.abs(evaluate_basis(basis, a, dtype=np.float32) - expected).max(axis=(1, 2))
    assert np.all(error <= error_bound(basis, a, np.float32) + error_bound(basis, a, np.float64))


def summed_in_term_order(basis: Basis, a: np.ndarray, dtype: type) -> np.ndarray:
    """One frame (c,) -> (n, 3) as the single-frame layout promises to sum it: the neutral, then
    t_j D_j for each non-zero term j in order (channels, then correctives), every product and sum
    rounded to ``dtype`` (t_j in float64, then rounded)."""
    pairs = basis.corrective_pairs
    t = np.concatenate([a, a[pairs[:, 0]] * a[pairs[:, 1]]])  # (T,)
    terms = np.concatenate([basis.deltas, basis.corrective_deltas]).astype(dtype)  # (T, n, 3)
    v = basis.neutral.astype(dtype)
    for t_j, delta in zip(t.astype(dtype), terms, strict=True):
        if t_j != 0:
            v = v + t_j * delta
    return v


@pytest.mark.parametrize("dtype", DTYPES)
def test_evaluate_basis_one_frame_adds_the_terms_to_the_neutral_in_order_bit_for_bit(dtype):
    """Supports scattered in the vertex order (each term many runs): a layout that reads them in
    another order, or writes a vertex to the wrong place, changes bits here."""
    basis = regional_basis(4, n=3000, correctives=((3, 4), (0, 5), (6, 6)))
    assert not np.any(basis.neutral == 0)  # a -0.0 plus a zero product may come out +0.0
    rng = np.random.default_rng(11)
    frames = [random_activations(rng, active=p) for p in (0.2, 0.5, 1.0)] + [np.eye(N_CHANNELS)[3]]
    for a in frames:
        expected = summed_in_term_order(basis, a, dtype)
        got = evaluate_basis(basis, a, dtype=dtype)
        assert got.shape == expected.shape and got.dtype == expected.dtype == dtype
        np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("corrected", [False, True])
def test_evaluate_basis_float32_is_within_its_bound_of_float64(corrected):
    basis = BASIS_WITH_CORRECTIVES if corrected else SMALL_BASIS
    rng = np.random.default_rng(5)
    a = np.concatenate([random_activations(rng, 20, active=p) for p in (0.1, 0.5, 1.0)])  # (60, c)
    assert np.all(float32_within_bound(basis, a))  # a batch
    assert all(float32_within_bound(basis, frame)[0] for frame in a[::7])  # single frames
    units = np.eye(N_CHANNELS)
    assert np.all(float32_within_bound(basis, units))
    assert error_bound(basis, a, np.float32).max() < 1e-4  # the bound itself is useful (coordinates ~5)
    error = np.abs(evaluate_basis(basis, a, dtype=np.float32) - evaluate_basis(basis, a)).max()
    assert 0 < error < 1e-5  # float32 does round: the float32 path really ran


@settings(max_examples=50, deadline=None)
@given(
    a=arrays(
        np.float64,
        N_CHANNELS,
        elements=st.one_of(st.just(0.0), st.floats(-1, 1, allow_subnormal=False)),
    )
)
def test_evaluate_basis_agrees_with_the_sum_written_out_for_any_sparse_frame(a):
    basis = BASIS_WITH_CORRECTIVES
    expected = written_out(basis, a[None])[0]
    np.testing.assert_allclose(evaluate_basis(basis, a), expected, rtol=0, atol=1e-12)
    assert float32_within_bound(basis, a)[0]
    assert float32_within_bound(basis, a[None])[0]


@pytest.mark.parametrize("block", [1, 7, 64, 10_000])
def test_evaluate_basis_gives_the_same_vertices_with_any_block_size(monkeypatch, block):
    """Blocks of one vertex (most move with only a few terms, some with none) up to one block."""
    monkeypatch.setattr(basis_module, "BLOCK_VERTICES", block)
    original = BASIS_WITH_CORRECTIVES
    basis = Basis(original.channels, original.neutral, original.deltas, original.correctives)  # no layout yet
    a = random_activations(np.random.default_rng(7), 10, active=0.4)
    np.testing.assert_allclose(evaluate_basis(basis, a), written_out(basis, a), rtol=0, atol=1e-12)
    assert np.all(float32_within_bound(basis, a))
    np.testing.assert_allclose(evaluate_basis(basis, a[3]), evaluate_basis(basis, a)[3], rtol=0, atol=1e-12)
    assert len(basis._layout64.blocks) == -(-basis.n_vertices // block)


def test_evaluate_basis_layout_skips_the_terms_that_do_not_move_a_block(monkeypatch):
    monkeypatch.setattr(basis_module, "BLOCK_VERTICES", 16)
    basis = Basis(SMALL_BASIS.channels, SMALL_BASIS.neutral, SMALL_BASIS.deltas)
    evaluate_basis(basis, np.zeros(N_CHANNELS), dtype=np.float32)
    layout = basis._layout32
    columns = layout.gather.tolist()  # column j + 1 of [1, t] is channel j

    def column(channel: int) -> int:
        return channel + 1

    assert column(1) not in columns  # channel 1 moves nothing: no block holds it
    assert columns.count(column(2)) == 1  # channel 2 moves one vertex: one block
    assert (
        columns.count(column(0)) == len(layout.blocks) == columns.count(0)
    )  # every block: channel 0, neutral
    stored = sum(matrix.size for *_, matrix in layout.blocks)
    assert stored < (1 + N_CHANNELS) * 3 * basis.n_vertices
    assert basis._layout32 is layout  # built once, cached


@pytest.mark.parametrize("dtype", DTYPES)
def test_evaluate_basis_handles_a_basis_of_one_vertex_and_one_channel(dtype):
    basis = Basis(("only",), [[1.0, 2.0, 3.0]], [[[0.5, 0.0, -0.5]]])
    np.testing.assert_array_equal(evaluate_basis(basis, [2.0], dtype=dtype), [[2.0, 2.0, 2.0]])
    np.testing.assert_array_equal(
        evaluate_basis(basis, [[0.0], [2.0]], dtype=dtype), [[[1.0, 2.0, 3.0]], [[2.0, 2.0, 2.0]]]
    )


def test_evaluate_basis_corrective_acts_only_when_both_channels_are_nonzero():
    basis = BASIS_WITH_CORRECTIVES  # corrective 0 pairs channel_3 and channel_4
    linear = Basis(basis.channels, basis.neutral, basis.deltas)
    delta = basis.correctives[0].delta

    def corrective_part(a3, a4):
        a = np.zeros(N_CHANNELS)
        a[3], a[4] = a3, a4
        return evaluate_basis(basis, a) - evaluate_basis(linear, a)

    np.testing.assert_array_equal(corrective_part(0.7, 0.0), 0.0)
    np.testing.assert_array_equal(corrective_part(0.0, -0.4), 0.0)
    np.testing.assert_allclose(corrective_part(0.5, 0.8), 0.4 * delta, rtol=0, atol=1e-12)
    np.testing.assert_allclose(corrective_part(1.0, 0.8), 2 * corrective_part(0.5, 0.8), rtol=0, atol=1e-12)
    np.testing.assert_allclose(corrective_part(-0.5, 0.8), -corrective_part(0.5, 0.8), rtol=0, atol=1e-12)


@pytest.mark.parametrize("pair", [(3, 4), (4, 3), (6, 6)])
def test_evaluate_basis_reads_a_corrective_whichever_channel_it_names_first(pair):
    basis = regional_basis(1, correctives=(pair,))  # seed 1: channels 3 and 4 overlap
    assert np.abs(basis.correctives[0].delta).max() > 0
    i, j = pair
    frames = []
    for ai, aj in ((0.0, 0.0), (0.6, 0.0), (0.0, -0.4), (0.6, -0.4)):
        a = np.zeros(N_CHANNELS)
        a[5] = 0.3  # another channel, always on
        a[i], a[j] = ai, aj
        frames.append(a)
    frames.append(np.full(N_CHANNELS, 0.5))  # every channel and the corrective
    frames = np.array(frames)
    np.testing.assert_allclose(evaluate_basis(basis, frames), written_out(basis, frames), rtol=0, atol=1e-12)
    assert np.all(float32_within_bound(basis, frames))


def test_evaluate_basis_quadratic_corrective_scales_with_the_square():
    basis = BASIS_WITH_CORRECTIVES  # corrective 2 pairs channel_6 with itself
    linear = Basis(basis.channels, basis.neutral, basis.deltas)
    a = np.zeros(N_CHANNELS)
    a[6] = 0.5
    np.testing.assert_allclose(
        evaluate_basis(basis, a) - evaluate_basis(linear, a), 0.25 * basis.correctives[2].delta, atol=1e-12
    )


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize(
    ("activations", "message"),
    [
        (np.zeros(N_CHANNELS - 1), f"got {N_CHANNELS - 1} channels; this basis has {N_CHANNELS} "),
        (np.zeros((2, N_CHANNELS + 1)), "Reorder with clip.select"),
        (np.zeros((2, 2, N_CHANNELS)), r"shape \(8,\) or \(frames, 8\); got \(2, 2, 8\)"),
        (0.0, r"got \(\)"),
        (np.r_[np.zeros(N_CHANNELS - 1), np.nan], "channel 'channel_7' is not finite"),
        (np.r_[[np.zeros(N_CHANNELS)], [np.r_[np.inf, np.zeros(N_CHANNELS - 1)]]], "channel_0' in frame 1"),
        (["a"] * N_CHANNELS, "cannot be read as float64"),
    ],
)
def test_evaluate_basis_rejects_bad_activations(dtype, activations, message):
    with pytest.raises(ActivationError, match=message):
        evaluate_basis(SMALL_BASIS, activations, dtype=dtype)


def test_evaluate_basis_rejects_activations_that_would_overflow_its_dtype():
    """Finite, but the sum would be inf: refused, not returned as inf or nan."""
    a = np.zeros((2, N_CHANNELS))
    a[1, 0] = 1e200  # fine in float64 (|neutral| + 1e200 · 0.5), not in float32
    assert np.isfinite(evaluate_basis(SMALL_BASIS, a)).all()
    with pytest.raises(ActivationError, match="activations of frame 1 too large to evaluate in float32"):
        evaluate_basis(SMALL_BASIS, a, dtype=np.float32)
    b = np.zeros(N_CHANNELS)
    b[1] = 1e39  # channel 1 moves nothing, but its float32 activation would be inf
    with pytest.raises(ActivationError, match=r"too large to evaluate in float32.*check their units"):
        evaluate_basis(SMALL_BASIS, b, dtype=np.float32)
    c = np.zeros(N_CHANNELS)
    c[3] = c[4] = 1e160  # corrective (3, 4): the product 1e320 overflows float64
    with pytest.raises(ActivationError, match="too large to evaluate in float64"):
        evaluate_basis(BASIS_WITH_CORRECTIVES, c)


@pytest.mark.parametrize("dtype", [np.float16, np.int64, "complex128"])
def test_evaluate_basis_rejects_other_dtypes(dtype):
    with pytest.raises(ValueError, match="dtype must be float64 or float32"):
        evaluate_basis(SMALL_BASIS, np.zeros(N_CHANNELS), dtype=dtype)


def test_check_activations_demands_the_number_of_dimensions():
    with pytest.raises(ActivationError, match=r"\(8,\); got \(1, 8\)"):
        check_activations(SMALL_BASIS.channels, np.zeros((1, N_CHANNELS)), ndim=1)
    with pytest.raises(ActivationError, match=r"\(frames, 8\); got \(8,\)"):
        check_activations(SMALL_BASIS.channels, np.zeros(N_CHANNELS), ndim=2)


@pytest.mark.parametrize("dtype", DTYPES)
def test_evaluate_basis_does_not_modify_its_inputs(dtype):
    basis = BASIS_WITH_CORRECTIVES
    arrays_before = [basis.neutral.copy(), basis.deltas.copy(), basis.corrective_deltas.copy()]
    a = frozen_copy(random_activations(np.random.default_rng(3), 3))
    before = a.copy()
    evaluate_basis(basis, a, dtype=dtype)
    evaluate_basis(basis, a[0], dtype=dtype)
    evaluate_basis(basis, list(a[1]), dtype=dtype)
    np.testing.assert_array_equal(a, before)
    for array, copy in zip(
        (basis.neutral, basis.deltas, basis.corrective_deltas), arrays_before, strict=True
    ):
        np.testing.assert_array_equal(array, copy)


def test_evaluate_basis_results_do_not_alias_each_other_or_the_basis():
    first = evaluate_basis(SMALL_BASIS, np.zeros(N_CHANNELS))
    first += 1.0  # the caller owns the result
    np.testing.assert_array_equal(evaluate_basis(SMALL_BASIS, np.zeros(N_CHANNELS)), SMALL_BASIS.neutral)


def test_basis_keeps_a_handover_array_without_copying_it():
    deltas = np.zeros((2, 5, 3))
    kept = Basis(("a", "b"), np.zeros((5, 3)), Handover(deltas))
    assert kept.deltas is deltas and not deltas.flags.writeable
    source = np.zeros((2, 5, 3))
    copied = Basis(("a", "b"), np.zeros((5, 3)), source)
    assert copied.deltas is not source and source.flags.writeable
    with pytest.raises(RigError, match="C-contiguous float64"):
        Basis(("a", "b"), np.zeros((5, 3)), Handover(np.zeros((2, 5, 3), np.float32)))
