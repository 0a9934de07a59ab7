"""Tests of the baked linear rig: the float64 reference ``evaluate_basis`` and ``CompactBasis``.

Bases are built synthetically (``regional_basis``): a few hundred vertices in a shuffled order,
so that every regional support is fragmented in vertex order as on a real mesh; one channel
moves every vertex (like a head rotation), one moves nothing, one moves a single vertex.
Tolerances: the reference path is compared at 1e-12 (float64 rounding of sums of a few terms
of magnitude ≤ 10); the compact path within its own ``error_bound`` and ``compaction_error``.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

import mimetic.engines.basis as basis_module
from mimetic.engines.basis import (
    Basis,
    CompactBasis,
    Corrective,
    check_activations,
    evaluate_basis,
)
from mimetic.errors import ActivationError, RigError

DTYPES = (np.float32, np.float16)
METHODS = ("runs", "blocks")


def methods_of(compact: CompactBasis) -> tuple[str, ...]:
    """The evaluation methods of ``compact`` (every storage dtype has both)."""
    return METHODS


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
COMPACT = {
    (dtype, corrected): CompactBasis.build(BASIS_WITH_CORRECTIVES if corrected else SMALL_BASIS, dtype=dtype)
    for dtype in DTYPES
    for corrected in (False, True)
}


def random_activations(rng: np.random.Generator, *shape: int, active: float = 0.5) -> np.ndarray:
    """Activations in [-0.5, 1], each channel non-zero with probability ``active``."""
    a = rng.uniform(-0.5, 1.0, size=(*shape, N_CHANNELS))
    return np.where(rng.random(a.shape) < active, a, 0.0)


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


def test_evaluate_basis_shapes_and_dtypes():
    n = SMALL_BASIS.n_vertices
    one = evaluate_basis(SMALL_BASIS, np.zeros(N_CHANNELS))
    many = evaluate_basis(SMALL_BASIS, np.zeros((5, N_CHANNELS)))
    none = evaluate_basis(SMALL_BASIS, np.zeros((0, N_CHANNELS)))
    assert one.shape == (n, 3) and one.dtype == np.float64
    assert many.shape == (5, n, 3) and many.dtype == np.float64
    assert none.shape == (0, n, 3)


def test_evaluate_basis_zero_activations_give_exactly_the_neutral():
    for basis in (SMALL_BASIS, BASIS_WITH_CORRECTIVES):
        np.testing.assert_array_equal(evaluate_basis(basis, np.zeros(N_CHANNELS)), basis.neutral)
        np.testing.assert_array_equal(evaluate_basis(basis, np.zeros((3, N_CHANNELS)))[2], basis.neutral)
        np.testing.assert_array_equal(evaluate_basis(basis, -np.zeros(N_CHANNELS)), basis.neutral)


@given(
    a=arrays(np.float64, N_CHANNELS, elements=st.floats(0, 1)),
    b=arrays(np.float64, N_CHANNELS, elements=st.floats(0, 1)),
)
def test_evaluate_basis_is_linear_in_activations(a, b):
    def offset(x):
        return evaluate_basis(SMALL_BASIS, x) - SMALL_BASIS.neutral

    np.testing.assert_allclose(offset(a + b), offset(a) + offset(b), atol=1e-12)


def test_evaluate_basis_matches_the_sum_written_out():
    rng = np.random.default_rng(2)
    a = random_activations(rng, 4)
    basis = BASIS_WITH_CORRECTIVES
    expected = np.array(
        [
            basis.neutral
            + sum(frame[c] * basis.deltas[c] for c in range(N_CHANNELS))
            + sum(
                frame[basis.channels.index(i)] * frame[basis.channels.index(j)] * k.delta
                for k in basis.correctives
                for i, j in [k.channels]
            )
            for frame in a
        ]
    )
    got = evaluate_basis(basis, a)
    assert got.shape == expected.shape
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-12)
    np.testing.assert_allclose(evaluate_basis(basis, a[1]), got[1], rtol=0, atol=1e-12)  # GEMV vs GEMM


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


def test_evaluate_basis_quadratic_corrective_scales_with_the_square():
    basis = BASIS_WITH_CORRECTIVES  # corrective 2 pairs channel_6 with itself
    linear = Basis(basis.channels, basis.neutral, basis.deltas)
    a = np.zeros(N_CHANNELS)
    a[6] = 0.5
    np.testing.assert_allclose(
        evaluate_basis(basis, a) - evaluate_basis(linear, a), 0.25 * basis.correctives[2].delta, atol=1e-12
    )


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
def test_evaluate_basis_rejects_bad_activations(activations, message):
    with pytest.raises(ActivationError, match=message):
        evaluate_basis(SMALL_BASIS, activations)


def test_check_activations_demands_the_number_of_dimensions():
    with pytest.raises(ActivationError, match=r"\(8,\); got \(1, 8\)"):
        check_activations(SMALL_BASIS.channels, np.zeros((1, N_CHANNELS)), ndim=1)
    with pytest.raises(ActivationError, match=r"\(frames, 8\); got \(8,\)"):
        check_activations(SMALL_BASIS.channels, np.zeros(N_CHANNELS), ndim=2)


def test_evaluate_basis_does_not_modify_its_inputs():
    a = frozen_copy(random_activations(np.random.default_rng(3), 3))
    before = a.copy()
    evaluate_basis(BASIS_WITH_CORRECTIVES, a)
    evaluate_basis(BASIS_WITH_CORRECTIVES, a[0])
    np.testing.assert_array_equal(a, before)


# --------------------------------------------------------------------------- CompactBasis


@pytest.mark.parametrize("dtype", DTYPES)
def test_compact_shapes_and_dtypes(dtype):
    compact = COMPACT[dtype, True]
    n = compact.n_vertices
    assert compact.channels == BASIS_WITH_CORRECTIVES.channels
    assert compact.dtype == np.dtype(dtype)
    for method in ("auto", *methods_of(compact)):
        one = compact.evaluate(np.zeros(N_CHANNELS), method=method)
        assert one.shape == (n, 3) and one.dtype == np.float32 and one.flags.c_contiguous
    many = compact.evaluate_batch(np.zeros((5, N_CHANNELS)))
    assert many.shape == (5, n, 3) and many.dtype == np.float32 and many.flags.c_contiguous
    assert compact.evaluate_batch(np.zeros((0, N_CHANNELS))).shape == (0, n, 3)
    assert isinstance(compact.error_bound(np.zeros(N_CHANNELS)), float)
    assert compact.error_bound(np.zeros((5, N_CHANNELS))).shape == (5,)
    assert isinstance(compact.nbytes, int) and compact.nbytes > 0
    assert compact.stored_nbytes >= compact.nbytes


@pytest.mark.parametrize("dtype", DTYPES)
def test_compact_writes_into_out(dtype):
    compact = COMPACT[dtype, False]
    a = random_activations(np.random.default_rng(4), 3)
    out = np.full((compact.n_vertices, 3), np.nan, np.float32)
    for method in methods_of(compact):
        assert compact.evaluate(a[0], out=out, method=method) is out
        np.testing.assert_array_equal(out, compact.evaluate(a[0], method=method))
    batch = np.full((3, compact.n_vertices, 3), np.nan, np.float32)
    assert compact.evaluate_batch(a, out=batch) is batch
    np.testing.assert_array_equal(batch, compact.evaluate_batch(a))


@pytest.mark.parametrize(
    "out",
    [np.zeros((300, 3)), np.zeros((299, 3), np.float32), np.zeros((3, 300), np.float32).T, [[0.0] * 3] * 300],
)
def test_compact_rejects_a_bad_out(out):
    with pytest.raises(
        ValueError, match=r"out must be a writeable C-contiguous float32 array of shape \(300, 3\)"
    ):
        COMPACT[np.float32, False].evaluate(np.zeros(N_CHANNELS), out=out)


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("corrected", [False, True])
def test_compact_zero_activations_give_the_neutral_within_compaction_error(dtype, corrected):
    compact = COMPACT[dtype, corrected]
    neutral = (BASIS_WITH_CORRECTIVES if corrected else SMALL_BASIS).neutral
    error = compact.compaction_error
    assert 0 <= error.neutral <= error.absolute
    rounded = neutral.astype(np.float32)  # exactly the float32 neutral, whatever the path
    for method in ("auto", *methods_of(compact)):
        got = compact.evaluate(np.zeros(N_CHANNELS), method=method)
        np.testing.assert_array_equal(got, rounded)
        assert np.abs(got - neutral).max() <= error.neutral
    np.testing.assert_array_equal(compact.evaluate_batch(np.zeros((2, N_CHANNELS))), [rounded, rounded])


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("corrected", [False, True])
def test_compact_unit_activations_are_within_compaction_error(dtype, corrected):
    compact = COMPACT[dtype, corrected]
    basis = BASIS_WITH_CORRECTIVES if corrected else SMALL_BASIS
    units = np.eye(N_CHANNELS)
    reference = evaluate_basis(basis, units)
    error = compact.compaction_error
    worst = [
        np.abs(compact.evaluate(u, method=m) - r).max()
        for u, r in zip(units, reference, strict=True)
        for m in methods_of(compact)
    ]
    worst.append(np.abs(compact.evaluate_batch(units) - reference).max())
    assert max(worst) == error.absolute  # compaction_error is the worst of these
    assert error.relative == pytest.approx(error.absolute / max(np.abs(basis.deltas).max(), 1e-300))
    assert error.absolute <= compact.error_bound(units).max()
    assert error.storage <= error.absolute + error.neutral


def test_compact_float32_and_float16_compaction_errors_are_small():
    float32 = COMPACT[np.float32, True].compaction_error
    float16 = COMPACT[np.float16, True].compaction_error
    assert float32.relative < 1e-6  # float32 rounding of neutral (~5) and deltas (≤ 1)
    assert 1e-5 < float16.relative < 2.0**-11  # one float16 rounding of deltas scaled per channel


@pytest.mark.parametrize("dtype", DTYPES)
@pytest.mark.parametrize("corrected", [False, True])
def test_compact_matches_reference_within_error_bound(dtype, corrected):
    compact = COMPACT[dtype, corrected]
    basis = BASIS_WITH_CORRECTIVES if corrected else SMALL_BASIS
    rng = np.random.default_rng(5)
    a = np.concatenate([random_activations(rng, 20, active=p) for p in (0.1, 0.5, 1.0)])  # (60, c)
    reference = evaluate_basis(basis, a)
    bound = compact.error_bound(a)  # (60,)
    batch_error = np.abs(compact.evaluate_batch(a) - reference).max(axis=(1, 2))
    assert np.all(batch_error <= bound)
    for frame, ref, limit in zip(a, reference, bound, strict=True):
        for method in ("auto", *methods_of(compact)):
            assert np.abs(compact.evaluate(frame, method=method) - ref).max() <= limit
    assert bound.max() < (1e-4 if dtype == np.float32 else 0.1)  # the bound itself is useful


@settings(max_examples=50, deadline=None)
@given(
    a=arrays(
        np.float64,
        N_CHANNELS,
        elements=st.one_of(st.just(0.0), st.floats(-1, 1, allow_subnormal=False)),
    )
)
def test_compact_paths_agree_with_reference_for_any_sparse_frame(a):
    reference = evaluate_basis(BASIS_WITH_CORRECTIVES, a)
    for dtype in DTYPES:
        compact = COMPACT[dtype, True]
        bound = compact.error_bound(a)
        for method in methods_of(compact):
            assert np.abs(compact.evaluate(a, method=method) - reference).max() <= bound
        assert np.abs(compact.evaluate_batch(a[None])[0] - reference).max() <= bound


@pytest.mark.parametrize("dtype", DTYPES)
def test_compact_corrective_acts_only_when_both_channels_are_nonzero(dtype):
    compact = COMPACT[dtype, True]
    basis = BASIS_WITH_CORRECTIVES  # corrective 0 pairs channel_3 and channel_4
    linear = CompactBasis.build(Basis(basis.channels, basis.neutral, basis.deltas), dtype=dtype)
    delta = basis.correctives[0].delta

    def corrective_part(a3, a4, method):
        a = np.zeros(N_CHANNELS)
        a[3], a[4] = a3, a4
        with_it = compact.evaluate(a, method=method).astype(np.float64)
        return with_it - linear.evaluate(a, method=method), compact.error_bound(a) + linear.error_bound(a)

    for method in methods_of(compact):
        for alone in ((0.7, 0.0), (0.0, -0.4)):
            part, bound = corrective_part(*alone, method)
            assert np.abs(part).max() <= bound
        part, bound = corrective_part(0.5, 0.8, method)
        assert np.abs(part - 0.4 * delta).max() <= bound
        assert np.abs(part).max() > 10 * bound  # the corrective does act


@pytest.mark.parametrize("pair", [(3, 4), (4, 3), (6, 6)])
def test_compact_corrective_is_read_exactly_when_both_channels_are_nonzero(pair):
    """Whichever channel the corrective names first (or both, for a quadratic term)."""
    basis = regional_basis(1, correctives=(pair,))  # seed 1: channels 3 and 4 overlap
    assert np.abs(basis.correctives[0].delta).max() > 0
    compact = CompactBasis.build(basis)
    linear = CompactBasis.build(Basis(basis.channels, basis.neutral, basis.deltas))
    i, j = pair
    frames = []
    for ai, aj in ((0.0, 0.0), (0.6, 0.0), (0.0, -0.4), (0.6, -0.4)):
        a = np.zeros(N_CHANNELS)
        a[5] = 0.3  # another channel, always on
        a[i], a[j] = ai, aj
        frames.append(a)
    frames.append(np.full(N_CHANNELS, 0.5))  # every channel and the corrective
    for a in frames:
        extra = compact.plan(a).bytes_read - linear.plan(a).bytes_read
        assert (extra > 0) == (a[i] != 0 and a[j] != 0)
        reference = evaluate_basis(basis, a)
        for method in ("auto", *methods_of(compact)):
            got = compact.evaluate(a, method=method)
            assert got.shape == reference.shape and got.dtype == np.float32
            assert np.abs(got - reference).max() <= compact.error_bound(a)


def test_compact_plan_skips_channels_at_zero():
    compact = COMPACT[np.float32, False]
    neutral_bytes = compact.n_vertices * 3 * 4
    zero = compact.plan(np.zeros(N_CHANNELS))
    assert (zero.runs, zero.gemv_calls, zero.bytes_read) == (0, 0, neutral_bytes)  # the neutral only
    one = np.zeros(N_CHANNELS)
    one[5] = 0.3  # a regional channel
    runs = compact.plan(one)  # auto: the kernel, over the non-zero components and short zero gaps
    assert runs.gemv_calls == 0 and runs.runs >= 1
    assert neutral_bytes < runs.bytes_read < compact.plan(one, method="blocks").bytes_read
    everything = compact.plan(np.ones(N_CHANNELS), method="blocks")
    assert everything.gemv_calls == compact.n_blocks and everything.runs == 0
    assert compact.nbytes == compact.plan(np.ones(N_CHANNELS)).bytes_read
    assert compact.plan(np.ones(N_CHANNELS)).runs == compact.n_runs


def test_compact_float16_halves_the_bytes_of_the_deltas():
    float32, float16 = COMPACT[np.float32, False], COMPACT[np.float16, False]
    neutral_bytes = float32.n_vertices * 3 * 4  # float32 in both
    everything = np.ones(N_CHANNELS)
    for method in METHODS:
        deltas32 = float32.plan(everything, method=method).bytes_read - neutral_bytes
        deltas16 = float16.plan(everything, method=method).bytes_read - neutral_bytes
        assert deltas16 * 2 == deltas32
    assert float16.stored_nbytes < float32.stored_nbytes


@pytest.mark.parametrize("dtype", DTYPES)
def test_compact_is_correct_with_gapless_runs_tiny_blocks_and_chunks(monkeypatch, dtype):
    """Runs without gaps, blocks of at most 2 grains, batches of 4 frames."""
    monkeypatch.setattr(basis_module, "RUN_GAP_ELEMENTS", 0)
    monkeypatch.setattr(basis_module, "BLOCK_MAX_VERTICES", 2 * basis_module.BLOCK_GRAIN_VERTICES)
    monkeypatch.setattr(basis_module, "BLOCK_CALL_ELEMENTS", 0)
    monkeypatch.setattr(basis_module, "BATCH_CHUNK_FRAMES", 4)
    compact = CompactBasis.build(BASIS_WITH_CORRECTIVES, dtype=dtype)
    a = random_activations(np.random.default_rng(7), 10)
    reference = evaluate_basis(BASIS_WITH_CORRECTIVES, a)
    bound = compact.error_bound(a)
    assert np.all(np.abs(compact.evaluate_batch(a) - reference).max(axis=(1, 2)) <= bound)
    for frame, ref, limit in zip(a, reference, bound, strict=True):
        for method in ("auto", *methods_of(compact)):
            assert np.abs(compact.evaluate(frame, method=method) - ref).max() <= limit
    assert compact.n_blocks > 5


@pytest.mark.parametrize("dtype", DTYPES)
def test_compact_runs_without_gaps_read_exactly_the_nonzero_components(monkeypatch, dtype):
    monkeypatch.setattr(basis_module, "RUN_GAP_ELEMENTS", 0)
    basis = BASIS_WITH_CORRECTIVES
    compact = CompactBasis.build(basis, dtype=dtype)
    stored = np.concatenate([basis.deltas, basis.corrective_deltas]).astype(dtype)  # (T, n, 3)
    nonzero = np.count_nonzero(stored.reshape(len(stored), -1), axis=1)  # (T,)
    pairs = basis.corrective_pairs
    rng = np.random.default_rng(11)
    for a in [np.zeros(N_CHANNELS), np.ones(N_CHANNELS), *random_activations(rng, 10, active=0.3)]:
        t = np.r_[a, a[pairs[:, 0]] * a[pairs[:, 1]]]  # (T,) term activations
        plan = compact.plan(a, method="runs")
        itemsize = np.dtype(dtype).itemsize
        assert plan.bytes_read == 12 * compact.n_vertices + itemsize * nonzero[t != 0].sum()
        reference = evaluate_basis(basis, a)
        assert np.abs(compact.evaluate(a, method="runs") - reference).max() <= compact.error_bound(a)


@pytest.mark.parametrize("dtype", DTYPES)
def test_compact_runs_accepts_activations_in_any_layout(dtype):
    """Read-only, strided, float32 or a list: each is the same frame (one compiled signature)."""
    compact = COMPACT[dtype, True]
    a = random_activations(np.random.default_rng(12), active=0.6)
    expected = compact.evaluate(a, method="runs")
    strided = np.repeat(a, 2)[::2]
    assert not strided.flags.c_contiguous
    for frame in (frozen_copy(a), strided, a.tolist()):
        np.testing.assert_array_equal(compact.evaluate(frame, method="runs"), expected)
    single = a.astype(np.float32)
    reference = evaluate_basis(BASIS_WITH_CORRECTIVES, single.astype(np.float64))
    assert np.abs(compact.evaluate(single) - reference).max() <= compact.error_bound(single)


@pytest.mark.parametrize("dtype", DTYPES)
def test_compact_runs_leaves_out_untouched_when_an_activation_is_not_finite_or_too_large(dtype):
    compact = COMPACT[dtype, True]
    out = np.full((compact.n_vertices, 3), 7.0, np.float32)
    a = np.zeros(N_CHANNELS)
    a[4] = np.nan
    with pytest.raises(ActivationError, match="channel 'channel_4' is not finite"):
        compact.evaluate(a, out=out, method="runs")
    a[4] = 1e300 if dtype == np.float32 else 1e30  # float16 deltas are scaled by ~2^112 in the kernel
    with pytest.raises(ActivationError, match=f"activations too large for {np.dtype(dtype).name}"):
        compact.evaluate(a, out=out, method="runs")
    assert np.all(out == 7.0)
    with pytest.raises(ValueError, match="method must be 'auto', 'runs' or 'blocks'; got 'ranges'"):
        compact.evaluate(np.zeros(N_CHANNELS), method="ranges")


def test_compact_drop_below_leaves_dust_out_and_accounts_for_it():
    basis = SMALL_BASIS
    dusty_deltas = basis.deltas + 1e-9 * np.random.default_rng(10).standard_normal(basis.deltas.shape)
    dusty = Basis(basis.channels, basis.neutral, dusty_deltas)
    exact, cleaned = CompactBasis.build(dusty), CompactBasis.build(dusty, drop_below=1e-8)
    a = random_activations(np.random.default_rng(11), 6, active=0.3)
    for frame in a:
        assert cleaned.plan(frame).bytes_read <= exact.plan(frame).bytes_read
    assert cleaned.stored_nbytes < exact.stored_nbytes  # the empty and one-vertex channels stay small
    assert cleaned.compaction_error.storage >= 1e-9  # the dust it dropped
    reference = evaluate_basis(dusty, a)
    assert np.all(np.abs(cleaned.evaluate_batch(a) - reference).max(axis=(1, 2)) <= cleaned.error_bound(a))
    for frame, ref in zip(a, reference, strict=True):
        assert np.abs(cleaned.evaluate(frame) - ref).max() <= cleaned.error_bound(frame)
    with pytest.raises(ValueError, match="drop_below must be a finite number"):
        CompactBasis.build(basis, drop_below=-1.0)


def test_compact_handles_a_basis_of_one_vertex_and_one_channel():
    basis = Basis(("only",), [[1.0, 2.0, 3.0]], [[[0.5, 0.0, -0.5]]])
    compact = CompactBasis.build(basis)
    for method in methods_of(compact):
        np.testing.assert_array_equal(compact.evaluate([2.0], method=method), [[2.0, 2.0, 2.0]])
    np.testing.assert_array_equal(
        compact.evaluate_batch([[0.0], [2.0]]), [[[1.0, 2.0, 3.0]], [[2.0, 2.0, 2.0]]]
    )
    assert compact.compaction_error.absolute == 0.0


@pytest.mark.parametrize(
    ("activations", "message"),
    [
        (np.zeros(N_CHANNELS - 1), f"got {N_CHANNELS - 1} channels; this basis has {N_CHANNELS} "),
        (np.zeros((1, N_CHANNELS)), r"must have shape \(8,\); got \(1, 8\)"),
        (np.r_[np.zeros(N_CHANNELS - 1), np.nan], "channel 'channel_7' is not finite"),
        (np.r_[np.inf, np.zeros(N_CHANNELS - 1)], "channel 'channel_0' is not finite"),
        ("not numbers", "cannot be read as float64"),
    ],
)
def test_compact_evaluate_rejects_bad_activations(activations, message):
    compact = COMPACT[np.float32, True]
    with pytest.raises(ActivationError, match=message):
        compact.evaluate(activations)
    with pytest.raises(ActivationError, match=message):
        compact.plan(activations)


@pytest.mark.parametrize(
    ("activations", "message"),
    [
        (np.zeros(N_CHANNELS), r"must have shape \(frames, 8\); got \(8,\)"),
        (np.zeros((3, N_CHANNELS + 2)), f"got {N_CHANNELS + 2} channels"),
        (np.r_[[np.zeros(N_CHANNELS)], [np.r_[np.nan, np.zeros(N_CHANNELS - 1)]]], "'channel_0' in frame 1"),
    ],
)
def test_compact_evaluate_batch_rejects_bad_activations(activations, message):
    with pytest.raises(ActivationError, match=message):
        COMPACT[np.float32, True].evaluate_batch(activations)


@pytest.mark.parametrize(("dtype", "huge"), [(np.float32, 1e200), (np.float16, 1e40)])
def test_compact_rejects_activations_beyond_the_range_of_its_storage(dtype, huge):
    """Finite, but float32 would turn the term into inf: refused by every path, not returned as inf."""
    compact = COMPACT[dtype, False]
    a = np.zeros(N_CHANNELS)
    a[0] = huge
    for method in METHODS:
        with pytest.raises(ActivationError, match=f"too large for {np.dtype(dtype).name}"):
            compact.evaluate(a, method=method)
    with pytest.raises(ActivationError, match=f"too large for {np.dtype(dtype).name}"):
        compact.evaluate_batch(a[None])


def test_compact_build_and_evaluate_reject_bad_options():
    with pytest.raises(ValueError, match="dtype must be float32 or float16; got float64"):
        CompactBasis.build(SMALL_BASIS, dtype=np.float64)
    with pytest.raises(TypeError, match="needs a Basis"):
        CompactBasis.build(SMALL_BASIS.deltas)
    with pytest.raises(TypeError, match=r"CompactBasis.build\(basis\)"):
        CompactBasis()
    with pytest.raises(ValueError, match="method must be"):
        COMPACT[np.float32, False].evaluate(np.zeros(N_CHANNELS), method="dense")


@pytest.mark.parametrize("dtype", DTYPES)
def test_compact_does_not_modify_its_inputs(dtype):
    basis = BASIS_WITH_CORRECTIVES
    arrays_before = [basis.neutral.copy(), basis.deltas.copy(), basis.corrective_deltas.copy()]
    compact = CompactBasis.build(basis, dtype=dtype)
    a = frozen_copy(random_activations(np.random.default_rng(8), 4))
    before = a.copy()
    for method in ("auto", *methods_of(compact)):
        compact.evaluate(a[0], method=method)
    compact.evaluate(list(a[1]))
    compact.evaluate_batch(a)
    compact.error_bound(a)
    compact.plan(a[2])
    np.testing.assert_array_equal(a, before)
    for array, copy in zip(
        (basis.neutral, basis.deltas, basis.corrective_deltas), arrays_before, strict=True
    ):
        np.testing.assert_array_equal(array, copy)
