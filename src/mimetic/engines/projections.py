"""The tissue engine's local step, compiled (numba, in parallel): the springs' and the prisms'
projections of rows ``A x`` (``tissue._local``), and the same gathered straight onto the nodes
(``gathered_targets``), which the solver's iterations use.

Profiling a 10k-node dynamic frame (2 cores): the vectorised numpy version of the prisms' projections
took 12 ms of its 60 ms in dozens of passes over (9, P) arrays, scipy's sparse products with three
columns 13 ms. Compiled, with the sparse products as one pass each, the local step took 3.7 ms per
iteration but ran at the speed of memory (2-3× slower when the machine's other tenants were busy);
gathered onto the nodes without forming ``A x`` it reads a fifth of the bytes.

A prism's deformation gradient is stored column-major as 9 numbers: entry ``3 j + i`` is ``F[i, j]``.
"""

from __future__ import annotations

import numba
import numpy as np

POLAR_STEPS = 6
"""Newton steps of the polar decomposition, at most: they stop once a step changes no entry by more
than ``POLAR_TOLERANCE`` (Newton converges quadratically: a last step of δ leaves about δ²), and the
SVD takes the prisms that have not converged by then. Under extreme activations many prisms need 4-6
steps: with at most 3 the SVD took them and the projections of the default head's tissue cost 25 ms
instead of 7 ms."""
POLAR_TOLERANCE = 1e-4
UNIT_STEPS = 3
"""Newton steps of the projection onto determinant 1, at most (fewer once ``|det - 1|`` is below
``UNIT_TOLERANCE``)."""
UNIT_TOLERANCE = 1e-9
CHUNK = 512
"""Prisms per parallel task (each allocates its scratch once)."""


@numba.njit(cache=True, error_model="numpy", inline="always")
def _cofactor(f, out):
    """Cofactor of ``f`` (9,) into ``out`` (9,) (its columns are cross products of f's columns);
    returns det f."""
    out[0] = f[4] * f[8] - f[5] * f[7]
    out[1] = f[5] * f[6] - f[3] * f[8]
    out[2] = f[3] * f[7] - f[4] * f[6]
    out[3] = f[7] * f[2] - f[8] * f[1]
    out[4] = f[8] * f[0] - f[6] * f[2]
    out[5] = f[6] * f[1] - f[7] * f[0]
    out[6] = f[1] * f[5] - f[2] * f[4]
    out[7] = f[2] * f[3] - f[0] * f[5]
    out[8] = f[0] * f[4] - f[1] * f[3]
    return f[0] * out[0] + f[1] * out[1] + f[2] * out[2]


@numba.njit(cache=True, error_model="numpy")
def _svd(f):
    """``U``, signed singular values and ``Vᵀ`` of ``f`` (9,) with U and V proper rotations (the last
    singular value carries the sign of det f)."""
    m = np.empty((3, 3))
    for j in range(3):
        for i in range(3):
            m[i, j] = f[3 * j + i]
    u, sigma, vt = np.linalg.svd(m)
    if np.linalg.det(u @ vt) < 0:
        u[:, 2] = -u[:, 2]
        sigma[2] = -sigma[2]
    return u, sigma, vt


@numba.njit(cache=True, error_model="numpy")
def _store(m, out):
    for j in range(3):
        for i in range(3):
            out[3 * j + i] = m[i, j]


@numba.njit(cache=True, error_model="numpy")
def _rotation(f, upright, r, cof):
    """The proper rotation nearest to ``f`` (9,) into ``r`` (9,): scaled Newton steps of the polar
    decomposition, ``R ← (ζ R + R⁻ᵀ/ζ)/2`` with ``ζ = |det R|^(-1/3)`` (Higham 1986), or the SVD's
    ``U Vᵀ`` where that has not converged or ``f`` is inverted (``upright`` False); ``cof`` (9,) is
    scratch."""
    change = np.inf
    if upright:
        r[:] = f
        for _ in range(POLAR_STEPS):
            det = _cofactor(r, cof)  # R⁻ᵀ = cof R / det R
            z = np.cbrt(det)
            a, b = 0.5 / z, 0.5 * z / det
            change = 0.0  # of this step
            for k in range(9):
                new = a * r[k] + b * cof[k]
                change = max(change, abs(new - r[k]))
                r[k] = new
            if change <= POLAR_TOLERANCE:
                break
    if not change <= POLAR_TOLERANCE:  # inverted, not converged, or NaN
        u, _, vt = _svd(f)
        _store(u @ vt, r)


@numba.njit(cache=True, error_model="numpy")
def _unit(f, upright, v, cof):
    """The matrix of determinant 1 nearest to ``f`` (9,) into ``v`` (9,): Newton steps along the
    determinant's gradient (the cofactor), ``F - λ cof F`` with ``λ = (det F - 1) / |cof F|²``; for an
    inverted ``f`` the same steps on its signed singular values, which lead to the branch of positive
    determinant (the result is continuous as a prism passes through flat); ``cof`` (9,) is scratch."""
    if upright:
        v[:] = f
        for _ in range(UNIT_STEPS):
            det = _cofactor(v, cof)
            if abs(det - 1.0) <= UNIT_TOLERANCE:
                break
            scale = (det - 1.0) / max(np.dot(cof, cof), 1e-300)
            for k in range(9):
                v[k] -= scale * cof[k]
        return
    u, sigma, vt = _svd(f)
    for _ in range(UNIT_STEPS):
        g0, g1, g2 = sigma[1] * sigma[2], sigma[0] * sigma[2], sigma[0] * sigma[1]
        scale = (sigma[0] * sigma[1] * sigma[2] - 1.0) / max(g0 * g0 + g1 * g1 + g2 * g2, 1e-300)
        sigma[0] -= scale * g0
        sigma[1] -= scale * g1
        sigma[2] -= scale * g2
    _store((u * sigma) @ vt, v)


@numba.njit(cache=True, error_model="numpy", inline="always")
def _prism_target(f, ws, wv, target, cof, r, v):
    """One prism's target into ``target`` (9,) for its deformation gradient ``f`` (9,) (``prism_targets``);
    returns its energy. ``cof``, ``r``, ``v`` (9,) are scratch."""
    upright = _cofactor(f, cof) > 0
    _rotation(f, upright, r, cof)
    e = 0.0
    for k in range(9):
        e += ws * (f[k] - r[k]) ** 2
    if wv > 0:
        _unit(f, upright, v, cof)
        mix = wv / (ws + wv)
        for k in range(9):
            e += wv * (f[k] - v[k]) ** 2
            target[k] = r[k] + mix * (v[k] - r[k])
    else:
        for k in range(9):
            target[k] = r[k]
    return 0.5 * e


@numba.njit(cache=True, error_model="numpy", inline="always")
def _spring_scale(d0, d1, d2, l0, soft, stiff, strain_limit):
    """The factor that takes an edge vector (d0, d1, d2) to its target (``spring_targets``), and the
    spring's energy."""
    length = max(np.sqrt(d0 * d0 + d1 * d1 + d2 * d2), 1e-300)
    limited = min(max(length, l0 * (1.0 - strain_limit)), l0 * (1.0 + strain_limit))
    scale = (soft * l0 + stiff * limited) / ((soft + stiff) * length)
    return scale, 0.5 * (soft * (length - l0) ** 2 + stiff * (length - limited) ** 2)


@numba.njit(parallel=True, cache=True, error_model="numpy")
def prism_targets(f, shape_weight, volume_weight, target):
    """Each prism's target into ``target`` (P, 9) for its deformation gradient ``f`` (P, 9): the mix
    ``R + wv/(ws + wv) (V - R)`` of its nearest rotation R and nearest unit-determinant matrix V by the
    weights ``shape_weight`` (P,) and ``volume_weight`` (P,) (V only where ``wv`` > 0). Returns the
    energy ``Σ ws/2 |F - R|² + wv/2 |F - V|²`` (the weights' units)."""
    n = f.shape[0]
    chunks = (n + CHUNK - 1) // CHUNK
    energies = np.zeros(chunks)
    for chunk in numba.prange(chunks):
        cof, r, v = np.empty(9), np.empty(9), np.empty(9)  # scratch, once per chunk
        e = 0.0
        for p in range(chunk * CHUNK, min(n, (chunk + 1) * CHUNK)):
            e += _prism_target(f[p], shape_weight[p], volume_weight[p], target[p], cof, r, v)
        energies[chunk] = e
    return energies.sum()


@numba.njit(parallel=True, cache=True, error_model="numpy")
def spring_targets(d, rest, soft, stiff, strain_limit, target):
    """Each spring's target into ``target`` (E, 3) for its edge vectors ``d`` (E, 3): along the edge,
    the length ``(k l₀ + k' clip(l, l₀(1 ± ε)))/(k + k')`` that mixes the soft spring ``soft`` (E,) to
    its rest length ``rest`` (E,) with the stiff phase ``stiff`` (E,) into ``strain_limit`` ε. Returns
    the energy ``Σ k/2 (l - l₀)² + k'/2 (l - clip)²``."""
    n = d.shape[0]
    chunks = (n + CHUNK - 1) // CHUNK
    energies = np.zeros(chunks)
    for chunk in numba.prange(chunks):
        e = 0.0
        for s in range(chunk * CHUNK, min(n, (chunk + 1) * CHUNK)):
            scale, energy = _spring_scale(d[s, 0], d[s, 1], d[s, 2], rest[s], soft[s], stiff[s], strain_limit)
            for k in range(3):
                target[s, k] = d[s, k] * scale
            e += energy
        energies[chunk] = e
    return energies.sum()


@numba.njit(parallel=True, cache=True, error_model="numpy")
def gathered_targets(
    x, edges, rest, soft, stiff, strain_limit, prisms, gradients, shape_weight, volume_weight, out, n_threads
):
    """The local step of springs and prisms gathered onto the nodes, without the rows of ``A``: into
    ``out`` (N, 3) ``Σ_r w_r A_rᵀ p_r`` for the positions ``x`` (N, 3), where a spring (i, j)'s row is
    ``x_j - x_i`` with weight ``soft + stiff`` and target as ``spring_targets``, and a prism's three
    rows are the columns of ``F = xᵀ G`` (``gradients`` (P, 6, 3)) with weight ``ws + wv`` and target as
    ``prism_targets``. Returns their energy.

    Each of ``n_threads`` tasks (``numba.get_num_threads()``) gathers into its own copy of the nodes,
    and the copies are summed. The arrays read are the elements' own, a few MB on a 10k-node tissue,
    where forming ``A x``, its targets and ``Aᵀ W p`` moved about 25 MB per iteration."""
    n_nodes, n_edges, n_prisms = x.shape[0], edges.shape[0], prisms.shape[0]
    copies = np.zeros((n_threads, n_nodes, 3))
    energies = np.zeros(n_threads)
    for t in numba.prange(n_threads):
        into = copies[t]
        e = 0.0
        for s in range((t * n_edges) // n_threads, ((t + 1) * n_edges) // n_threads):
            i, j = edges[s, 0], edges[s, 1]
            d0, d1, d2 = x[j, 0] - x[i, 0], x[j, 1] - x[i, 1], x[j, 2] - x[i, 2]
            scale, energy = _spring_scale(d0, d1, d2, rest[s], soft[s], stiff[s], strain_limit)
            w = (soft[s] + stiff[s]) * scale
            into[j, 0] += w * d0
            into[j, 1] += w * d1
            into[j, 2] += w * d2
            into[i, 0] -= w * d0
            into[i, 1] -= w * d1
            into[i, 2] -= w * d2
            e += energy
        f, target = np.empty(9), np.empty(9)
        cof, r, v = np.empty(9), np.empty(9), np.empty(9)
        for p in range((t * n_prisms) // n_threads, ((t + 1) * n_prisms) // n_threads):
            g = gradients[p]
            for k in range(9):
                f[k] = 0.0
            for a in range(6):
                node = prisms[p, a]
                for j in range(3):
                    for i in range(3):
                        f[3 * j + i] += x[node, i] * g[a, j]
            ws, wv = shape_weight[p], volume_weight[p]
            e += _prism_target(f, ws, wv, target, cof, r, v)
            w = ws + wv
            for a in range(6):
                node = prisms[p, a]
                for i in range(3):
                    pulled = 0.0
                    for j in range(3):
                        pulled += g[a, j] * target[3 * j + i]
                    into[node, i] += w * pulled
        energies[t] = e
    for node in numba.prange(n_nodes):
        for i in range(3):
            total = 0.0
            for t in range(n_threads):
                total += copies[t, node, i]
            out[node, i] = total
    return energies.sum()
