"""The deformation chain's per-frame loops over a few thousand entries, compiled (numba).

Profiling the wire engine's realistic pose on the default head (13,396 vertices; 3.3 ms a frame
with the lids in contact): the lid contact took 2 ms, in some 400 numpy calls on arrays of 5-20
elements (the lower margin's bridging, a (j, j, j) array per layer; eight false-position steps per
crossing vertex), linear blend skinning 0.4 ms in fancy-indexed passes per bone, and the creases'
sparse product 0.1 ms over every channel's entries, zero or not. Here each is one pass. The lids'
sculptor (``sculpt_lids``, ``mimetic.rig.anatomy.eyeball.Eyeball.sculpt``) reads each eye's own
cornea on a grid: in numpy that added up to 1 ms a frame on ICT's head.

Each kernel computes what the numpy code it replaces computed, term for term in the same order
(``bridged_margin`` and ``channel_offsets`` give the same bits); the 3 × 3 products are summed in
index order where numpy's matmul may call BLAS, so skinned positions can differ in the last bit;
``sculpt_lids`` agrees with ``Eyeball.sculpt`` to 1e-9 of the eye's radius (the interpolation's sums).
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, error_model="numpy")
def bridged_margin(u: np.ndarray, v: np.ndarray, span: float, column: float) -> np.ndarray:
    """``v`` (j,) raised to the highest chord between two points a < i < b with ``u[b] - u[a] <= span``
    that passes over a dip (``v[i]`` no higher than ``v[a]`` and ``v[b]``), or with ``u[b] - u[a] <=
    column`` whatever the shape (``chain._lower_line``; ``u`` (j,) sorted). NaN where a chord is NaN,
    as numpy's max gives."""
    j = len(u)
    high = np.full(j, -np.inf)
    for a in range(j):
        for b in range(a + 2, j):
            width = u[b] - u[a]
            if not width <= span:
                continue
            short = width <= column
            slope = (v[b] - v[a]) / max(width, 1e-300)
            for i in range(a + 1, b):
                if not short and (v[i] > v[a] or v[i] > v[b]):  # a long chord bridges dips only
                    continue
                chord = v[a] + (u[i] - u[a]) * slope
                if np.isnan(high[i]):
                    continue
                if np.isnan(chord) or chord > high[i]:
                    high[i] = chord
    out = np.empty(j)
    for i in range(j):
        out[i] = high[i] if np.isnan(high[i]) or high[i] > v[i] else v[i]
    return out


@numba.njit(cache=True, error_model="numpy", inline="always")
def _above(
    i: int,
    delta: float,
    start: np.ndarray,
    scale: np.ndarray,
    along: np.ndarray,
    across: np.ndarray,
    cross: np.ndarray,
    origin: np.ndarray,
    axes: np.ndarray,
    line_u: np.ndarray,
    line_v: np.ndarray,
    reach: float,
    floor: np.ndarray,
) -> float:
    """Clearance of vertex ``i`` turned back by ``delta`` over the margin line, less its floor."""
    c, s = np.cos(-delta), np.sin(-delta)
    d0 = start[i, 0] + scale[i] * ((along[i, 0] + across[i, 0] * c) + cross[i, 0] * s) - origin[0]
    d1 = start[i, 1] + scale[i] * ((along[i, 1] + across[i, 1] * c) + cross[i, 1] * s) - origin[1]
    d2 = start[i, 2] + scale[i] * ((along[i, 2] + across[i, 2] * c) + cross[i, 2] * s) - origin[2]
    u = d0 * axes[0, 0] + d1 * axes[0, 1] + d2 * axes[0, 2]
    if not (u >= line_u[0] - reach and u <= line_u[-1] + reach):
        return np.inf
    v = d0 * axes[1, 0] + d1 * axes[1, 1] + d2 * axes[1, 2]
    return (v - np.interp(u, line_u, line_v)) - floor[i]


@numba.njit(cache=True, error_model="numpy")
def least_opening(
    start: np.ndarray,
    scale: np.ndarray,
    along: np.ndarray,
    across: np.ndarray,
    cross: np.ndarray,
    origin: np.ndarray,
    axes: np.ndarray,
    line_u: np.ndarray,
    line_v: np.ndarray,
    reach: float,
    floor: np.ndarray,
    most: float,
    steps: int,
) -> np.ndarray:
    """``chain._least_opening`` for the clearance of ``chain.keep_lids_apart``, vertex by vertex.

    Vertex i turned back by δ sits at ``start_i + scale_i (along_i + across_i cos δ - cross_i sin δ)``
    (Rodrigues about the lid's hinge); its clearance is its height in the eye frame (``origin`` (3,),
    ``axes`` (3, 3) rows u, v, w) over the margin (``line_u``, ``line_v``) at its u, +inf beyond the
    margin's ends by more than ``reach``, less ``floor_i``. Returns the upper end of each bracket after
    ``steps`` Illinois false-position steps on [0, ``most``] (bisection where an end is infinite).
    """
    k = len(floor)
    out = np.empty(k)
    for i in range(k):
        lo, hi = 0.0, most
        g_lo = _above(i, lo, start, scale, along, across, cross, origin, axes, line_u, line_v, reach, floor)
        g_hi = _above(i, hi, start, scale, along, across, cross, origin, axes, line_u, line_v, reach, floor)
        last = 0
        for _ in range(steps):
            if np.isfinite(g_lo) and np.isfinite(g_hi) and g_hi > g_lo:
                x = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
                x = min(max(x, lo), hi) if not np.isnan(x) else x
            else:
                x = 0.5 * (lo + hi)
            g = _above(i, x, start, scale, along, across, cross, origin, axes, line_u, line_v, reach, floor)
            up = g >= 0
            if up and last == 1:
                g_lo = 0.5 * g_lo
            if not up and last == -1:
                g_hi = 0.5 * g_hi
            if up:
                hi, g_hi = x, g
                last = 1
            else:
                lo, g_lo = x, g
                last = -1
        out[i] = hi
    return out


@numba.njit(cache=True, error_model="numpy")
def blend_skinning(
    vertices: np.ndarray,
    indptr: np.ndarray,
    indices: np.ndarray,
    data: np.ndarray,
    transforms: np.ndarray,
    bones: np.ndarray,
) -> np.ndarray:
    """``skinning.linear_blend_skinning`` over CSC weights (``indptr``, ``indices``, ``data``) for the
    ``bones`` (k,) whose transform is not the identity: v + Σ_b w_vb (M_b v - v)."""
    out = vertices.copy()
    for b in bones:
        m = transforms[b]
        for e in range(indptr[b], indptr[b + 1]):
            r = indices[e]
            w = data[e]
            p0, p1, p2 = vertices[r, 0], vertices[r, 1], vertices[r, 2]
            for d in range(3):
                moved = p0 * m[d, 0] + p1 * m[d, 1] + p2 * m[d, 2] + m[d, 3]
                out[r, d] += w * (moved - vertices[r, d])
    return out


@numba.njit(cache=True, error_model="numpy")
def channel_offsets(
    indptr: np.ndarray, indices: np.ndarray, data: np.ndarray, values: np.ndarray, size: int
) -> np.ndarray:
    """``matrix.T @ values`` for a CSR ``matrix`` (c, size), skipping the channels at 0: the same sums
    in the same order as scipy's product (a channel at 0 adds only zeros)."""
    out = np.zeros(size)
    for c in range(len(values)):
        a = values[c]
        if a == 0.0:
            continue
        for e in range(indptr[c], indptr[c + 1]):
            out[indices[e]] += data[e] * a
    return out


@numba.njit(cache=True, error_model="numpy")
def basis_frame(
    neutral: np.ndarray,
    a: np.ndarray,
    pairs: np.ndarray,
    peaks: np.ndarray,
    neutral_peak: float,
    limit: float,
    term_runs: np.ndarray,
    runs: np.ndarray,
    values: np.ndarray,
) -> np.ndarray:
    """One frame (n, 3) of a basis (``basis.evaluate_basis``, "Layout"): ``neutral + Σ_j t_j D_j``
    over the stored runs of the terms with t_j ≠ 0, in ``neutral``'s dtype (``neutral`` (3n,)); an
    empty array when the frame is out of range (``basis._check_range``; NaN and inf included).

    Term j < c has activation a_j; term c + k the product a_(pairs[k, 0]) a_(pairs[k, 1]). Term j's
    runs are ``runs[term_runs[j] : term_runs[j + 1]]``, each (first element of the flattened output,
    length, first element of ``values``).
    """
    c = len(a)
    t = np.empty(c + len(pairs))
    t[:c] = a
    for k in range(len(pairs)):
        t[c + k] = a[pairs[k, 0]] * a[pairs[k, 1]]
    magnitude = neutral_peak
    for j in range(len(t)):  # N_max + Σ |t_j| M_j, and each |t_j|, below the dtype's limit
        size = abs(t[j])
        if not size < limit:
            return neutral[:0].copy().reshape((0, 3))
        magnitude += size * peaks[j]
    if not magnitude < limit:
        return neutral[:0].copy().reshape((0, 3))
    out = neutral.copy()
    cast = np.empty(len(t), neutral.dtype)
    cast[:] = t  # each term's activation rounded to the output's dtype
    for j in range(len(t)):
        if t[j] == 0.0:
            continue
        alpha = cast[j]
        for r in range(term_runs[j], term_runs[j + 1]):
            start, length, at = runs[r, 0], runs[r, 1], runs[r, 2]
            y = out[start : start + length]
            x = values[at : at + length]
            for e in range(length):  # views indexed from 0: LLVM vectorises the loop
                y[e] += alpha * x[e]
    return out.reshape((len(out) // 3, 3))


@numba.njit(cache=True, error_model="numpy")
def triangle_heights(
    xy: np.ndarray,
    transform: np.ndarray,
    simplices: np.ndarray,
    heights: np.ndarray,
    cell_first: np.ndarray,
    cell_triangles: np.ndarray,
    grid: np.ndarray,
) -> np.ndarray:
    """The heights (k,) of a triangulated height field (a ``LinearNDInterpolator``'s triangulation
    ``transform`` (S, 3, 2), ``simplices`` (S, 3) and corner ``heights``) under points ``xy`` (k, 2):
    scipy's barycentric interpolation, term for term, in the first triangle of the point's grid cell
    that holds it (all three coordinates >= 0). NaN where none does (the caller asks scipy there).

    The grid: ``grid`` = (x0, y0, cell size, columns, rows); cell (i, j) lists the triangles whose
    bounding box meets it, ``cell_triangles[cell_first[c] : cell_first[c + 1]]`` with c = j columns + i.
    """
    k = len(xy)
    out = np.full(k, np.nan)
    x0, y0, size, nx, ny = grid[0], grid[1], grid[2], int(grid[3]), int(grid[4])
    for p in range(k):
        x, y = xy[p, 0], xy[p, 1]
        i, j = int(np.floor((x - x0) / size)), int(np.floor((y - y0) / size))
        if i < 0 or j < 0 or i >= nx or j >= ny:
            continue
        cell = j * nx + i
        for e in range(cell_first[cell], cell_first[cell + 1]):
            s = cell_triangles[e]
            dx, dy = x - transform[s, 2, 0], y - transform[s, 2, 1]
            c0 = 0.0
            c0 += transform[s, 0, 0] * dx
            c0 += transform[s, 0, 1] * dy
            c1 = 0.0
            c1 += transform[s, 1, 0] * dx
            c1 += transform[s, 1, 1] * dy
            c2 = 1.0
            c2 -= c0
            c2 -= c1
            if c0 >= 0.0 and c1 >= 0.0 and c2 >= 0.0:
                z = 0.0
                z += c0 * heights[simplices[s, 0]]
                z += c1 * heights[simplices[s, 1]]
                z += c2 * heights[simplices[s, 2]]
                out[p] = z
                break
    return out


@numba.njit(cache=True, error_model="numpy")
def row_lengths(d: np.ndarray) -> np.ndarray:
    """``np.linalg.norm(d, axis=1)`` for (n, 3) ``d``, with numpy's sum order: √((x² + y²) + z²)."""
    out = np.empty(len(d))
    for i in range(len(d)):
        out[i] = np.sqrt((d[i, 0] * d[i, 0] + d[i, 1] * d[i, 1]) + d[i, 2] * d[i, 2])
    return out


@numba.njit(cache=True, error_model="numpy", inline="always")
def _profile(theta: float, iris: float, bulge: float) -> float:
    """``mimetic.head.parts.eyeball_profile`` at one angle (rad)."""
    if theta >= iris:
        return 1.0
    c = max(np.cos(min(theta, np.pi) / iris * np.pi / 2), 0.0)
    return 1.0 + bulge * c * c


@numba.njit(cache=True, error_model="numpy")
def sculpt_lids(
    v: np.ndarray,
    ids: np.ndarray,
    centre: np.ndarray,
    turn: np.ndarray,
    axes: np.ndarray,
    radius: float,
    keep: np.ndarray,
    radii: np.ndarray,
    first: float,
    step: float,
    reach: float,
    excess: float,
    iris: float,
    bulge: float,
    steps: int,
    tol: float,
) -> None:
    """``Eyeball.sculpt`` on the rows ``ids`` (k,) of ``v`` (n, 3), in place: the eye at ``centre``
    (3,) turned by ``turn`` (3, 3), its rest ``axes`` (3, 3), sphere ``radius``, the lids' ``keep``
    (k, 2), its own surface ``radii`` (g, g) on the grid from ``first`` in steps of ``step`` (rad;
    (0, 0): the generic eyeball), ``reach`` and ``excess`` as ``Eyeball``'s, the generic profile's
    ``iris`` and ``bulge``, ``steps`` forward pushes down to ``tol`` × the radius."""
    rest = np.empty((3, 3))  # the rest axes, turned with the eye
    for a in range(3):
        for b in range(3):
            rest[a, b] = turn[b, 0] * axes[a, 0] + turn[b, 1] * axes[a, 1] + turn[b, 2] * axes[a, 2]
    gaze = rest[2]
    g = radii.shape[0]
    for k in range(len(ids)):
        i = ids[k]
        d0, d1, d2 = v[i, 0] - centre[0], v[i, 1] - centre[1], v[i, 2] - centre[2]
        dist = np.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
        cos = (d0 * gaze[0] + d1 * gaze[1] + d2 * gaze[2]) / max(dist, 1e-300)
        theta = np.arccos(min(max(cos, -1.0), 1.0))
        sphere = radius * _profile(theta, iris, bulge)
        limit = sphere + keep[k, 0]
        if dist < limit:  # radially out of the generic eyeball
            scale = limit / max(dist, 1e-300)
            v[i, 0], v[i, 1], v[i, 2] = centre[0] + d0 * scale, centre[1] + d1 * scale, centre[2] + d2 * scale
            dist = limit
        if g == 0 or theta > reach or dist >= sphere + excess * radius + keep[k, 1]:
            continue
        for _ in range(steps):  # forward out of the eye's own surface
            d0, d1, d2 = v[i, 0] - centre[0], v[i, 1] - centre[1], v[i, 2] - centre[2]
            x = d0 * rest[0, 0] + d1 * rest[0, 1] + d2 * rest[0, 2]
            y = d0 * rest[1, 0] + d1 * rest[1, 1] + d2 * rest[1, 2]
            z = d0 * rest[2, 0] + d1 * rest[2, 1] + d2 * rest[2, 2]
            dist = np.sqrt(x * x + y * y + z * z)
            theta = np.arccos(min(max(z / max(dist, 1e-300), -1.0), 1.0))
            across = np.sqrt(x * x + y * y)
            if theta > reach:
                own = _profile(theta, iris, bulge)
            else:
                scale = theta / across if across > 1e-12 else 0.0
                r = min(max((y * scale - first) / step, 0.0), g - 1.0)  # row, as map_coordinates' "nearest"
                c = min(max((x * scale - first) / step, 0.0), g - 1.0)
                r0, c0 = min(int(r), g - 2), min(int(c), g - 2)
                fr, fc = r - r0, c - c0
                own = (1 - fr) * ((1 - fc) * radii[r0, c0] + fc * radii[r0, c0 + 1]) + fr * (
                    (1 - fc) * radii[r0 + 1, c0] + fc * radii[r0 + 1, c0 + 1]
                )
            limit = radius * own + keep[k, 1]
            if dist >= limit - tol * radius:
                break
            along = d0 * gaze[0] + d1 * gaze[1] + d2 * gaze[2]
            push = -along + np.sqrt(max(along * along - dist * dist + limit * limit, 0.0))
            v[i, 0] += push * gaze[0]
            v[i, 1] += push * gaze[1]
            v[i, 2] += push * gaze[2]
