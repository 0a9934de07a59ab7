"""Compiled loops (numba) for ``mesh``: the closest point on each query's candidate triangles
(``mesh.closest``), the first hits of a grid of rays (``mesh.openings.front_depth``) and the
closest points on a polyline (``mesh.geometry.closest_on_polyline``), each with the arithmetic of
the numpy or trimesh code it replaces, so the same bits (``tests/mesh``).

Profiling ``rig_head`` on ICT's head, ``trimesh.triangles.closest_point`` over every (query,
candidate) pair was the largest cost after the registration's solves (12 calls, a fifth of the
rig): it needs the pairs' triangles and queries copied out ((q k, 3, 3) and (q k, 3), 30 MB for a
27k-vertex head) and makes some thirty passes over them. Here each pair is one pass, with trimesh's
arithmetic term for term (Ericson's "ClosestPtPointTriangle", its branches in its order, its dot
products summed x + y, then + z), so the points are the same bits.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, error_model="numpy")
def _dot(x0: float, x1: float, x2: float, y0: float, y1: float, y2: float) -> float:
    return (x0 * y0 + x1 * y1) + x2 * y2


@numba.njit(cache=True, error_model="numpy")
def closest_on_triangles(
    vertices: np.ndarray, faces: np.ndarray, near: np.ndarray, queries: np.ndarray, zero: float
) -> tuple[np.ndarray, np.ndarray]:
    """The closest points (q, k, 3) of ``queries`` (q, 3) on their candidate triangles ``faces[near]``
    (``near`` (q, k) rows of ``faces`` (m, 3), over ``vertices`` (n, 3)), as
    ``trimesh.triangles.closest_point`` finds them with ``trimesh.tol.zero`` = ``zero``, and their
    distances (q, k) as ``np.linalg.norm(points - queries[:, None], axis=2)`` gives them."""
    q, k = near.shape
    out = np.empty((q, k, 3))
    dist = np.empty((q, k))
    r = np.empty(3)
    for i in range(q):
        p0, p1, p2 = queries[i, 0], queries[i, 1], queries[i, 2]
        for j in range(k):
            f = near[i, j]
            a = vertices[faces[f, 0]]
            b = vertices[faces[f, 1]]
            c = vertices[faces[f, 2]]
            ab0, ab1, ab2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
            ac0, ac1, ac2 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
            ap0, ap1, ap2 = p0 - a[0], p1 - a[1], p2 - a[2]
            d1 = _dot(ab0, ab1, ab2, ap0, ap1, ap2)
            d2 = _dot(ac0, ac1, ac2, ap0, ap1, ap2)
            remain = True
            if d1 < zero and d2 < zero:  # vertex region of A
                r[0], r[1], r[2] = a[0], a[1], a[2]
                remain = False
            if ab0 == 0.0 and ab1 == 0.0 and ab2 == 0.0:  # A = B: the segment AC (trimesh sets it last)
                length_squared = (ac0**2 + ac1**2) + ac2**2
                factor = 0.0
                if length_squared > 0:
                    factor = _dot(ap0, ap1, ap2, ac0, ac1, ac2) / length_squared
                factor = min(max(factor, 0.0), 1.0)
                r[0], r[1], r[2] = a[0] + factor * ac0, a[1] + factor * ac1, a[2] + factor * ac2
                remain = False
            bp0, bp1, bp2 = p0 - b[0], p1 - b[1], p2 - b[2]
            d3 = _dot(ab0, ab1, ab2, bp0, bp1, bp2)
            d4 = _dot(ac0, ac1, ac2, bp0, bp1, bp2)
            if remain and d3 > -zero and d4 <= d3:  # vertex region of B
                r[0], r[1], r[2] = b[0], b[1], b[2]
                remain = False
            vc = (d1 * d4) - (d3 * d2)
            if remain and vc < zero and d1 > -zero and d3 < zero:  # edge AB
                v = d1 / (d1 - d3)
                r[0], r[1], r[2] = a[0] + v * ab0, a[1] + v * ab1, a[2] + v * ab2
                remain = False
            cp0, cp1, cp2 = p0 - c[0], p1 - c[1], p2 - c[2]
            d5 = _dot(ab0, ab1, ab2, cp0, cp1, cp2)
            d6 = _dot(ac0, ac1, ac2, cp0, cp1, cp2)
            if remain and d6 > -zero and d5 <= d6:  # vertex region of C
                r[0], r[1], r[2] = c[0], c[1], c[2]
                remain = False
            vb = (d5 * d2) - (d1 * d6)
            if remain and vb < zero and d2 > -zero and d6 < zero:  # edge AC
                w = d2 / (d2 - d6)
                r[0], r[1], r[2] = a[0] + w * ac0, a[1] + w * ac1, a[2] + w * ac2
                remain = False
            va = (d3 * d6) - (d5 * d4)
            if remain and va < zero and (d4 - d3) > -zero and (d5 - d6) > -zero:  # edge BC
                d43 = d4 - d3
                w = d43 / (d43 + (d5 - d6))
                r[0] = b[0] + w * (c[0] - b[0])
                r[1] = b[1] + w * (c[1] - b[1])
                r[2] = b[2] + w * (c[2] - b[2])
                remain = False
            if remain:  # inside the face
                denom = 1.0 / ((va + vb) + vc)
                v = vb * denom
                w = vc * denom
                r[0] = (a[0] + ab0 * v) + ac0 * w
                r[1] = (a[1] + ab1 * v) + ac1 * w
                r[2] = (a[2] + ab2 * v) + ac2 * w
            out[i, j, 0], out[i, j, 1], out[i, j, 2] = r[0], r[1], r[2]
            e0, e1, e2 = r[0] - p0, r[1] - p1, r[2] - p2
            dist[i, j] = np.sqrt((e0 * e0 + e1 * e1) + e2 * e2)
    return out, dist


@numba.njit(cache=True, error_model="numpy")
def first_hits(
    triangles: np.ndarray,
    first: np.ndarray,
    last: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    top: float,
    zero: float,
    flat: float,
) -> np.ndarray:
    """The depth (len(y), len(x)) where rays from ``(x[c], y[r], top)`` going down −Z first meet
    ``triangles`` (m, 3, 3), NaN where none does, testing each triangle only on the grid cells from
    ``first`` to ``last`` ((m, 2) column and row, inclusive).

    Each pair takes the steps of trimesh's ray query (``openings.front_depth`` used them): the face's
    unit normal as ``Trimesh.face_normals`` makes it (a cross product of the edges b − a and c − b,
    unitised where its length exceeds ``flat``, else zero), the plane hit of
    ``intersections.planes_lines`` (kept where the direction's projection on the normal exceeds
    1e-5), the hit's barycentric coordinates by ``triangles.points_to_barycentric`` (Cramer's rule),
    inside within ``zero``; the first hit along a ray is the nearest to its origin, the earlier
    triangle on a tie. Same arithmetic, so the same bits."""
    ny, nx = len(y), len(x)
    depth = np.full((ny, nx), np.nan)
    nearest = np.full((ny, nx), np.inf)
    for t in range(len(triangles)):
        a, b, c = triangles[t, 0], triangles[t, 1], triangles[t, 2]
        u0, u1, u2 = b[0] - a[0], b[1] - a[1], b[2] - a[2]
        v0, v1, v2 = c[0] - b[0], c[1] - b[1], c[2] - b[2]
        n0, n1, n2 = u1 * v2 - u2 * v1, u2 * v0 - u0 * v2, u0 * v1 - u1 * v0
        norm = np.sqrt(_dot(n0, n1, n2, n0, n1, n2))
        if norm > flat:
            inverse = 1.0 / norm
            n0, n1, n2 = n0 * inverse, n1 * inverse, n2 * inverse
        else:
            n0, n1, n2 = 0.0, 0.0, 0.0
        towards = _dot(0.0, 0.0, -1.0, n0, n1, n2)
        if not abs(towards) > 1e-5:
            continue
        e0, e1, e2 = u0, u1, u2
        f0, f1, f2 = c[0] - a[0], c[1] - a[1], c[2] - a[2]
        dot00 = _dot(e0, e1, e2, e0, e1, e2)
        dot01 = _dot(e0, e1, e2, f0, f1, f2)
        dot11 = _dot(f0, f1, f2, f0, f1, f2)
        inverse_denominator = 1.0 / (dot00 * dot11 - dot01 * dot01)
        for row in range(first[t, 1], last[t, 1] + 1):
            for column in range(first[t, 0], last[t, 0] + 1):
                o0, o1 = x[column], y[row]
                distance = _dot(a[0] - o0, a[1] - o1, a[2] - top, n0, n1, n2) / towards
                p0, p1, p2 = 0.0 * distance + o0, 0.0 * distance + o1, -1.0 * distance + top
                w0, w1, w2 = p0 - a[0], p1 - a[1], p2 - a[2]
                dot02 = _dot(e0, e1, e2, w0, w1, w2)
                dot12 = _dot(f0, f1, f2, w0, w1, w2)
                b2 = (dot00 * dot12 - dot01 * dot02) * inverse_denominator
                b1 = (dot11 * dot02 - dot01 * dot12) * inverse_denominator
                b0 = 1 - b1 - b2
                inside = b0 > -zero and b0 < 1 + zero and b1 > -zero and b1 < 1 + zero
                if inside and b2 > -zero and b2 < 1 + zero and top - p2 < nearest[row, column]:
                    nearest[row, column] = top - p2
                    depth[row, column] = p2
    return depth


@numba.njit(cache=True, error_model="numpy")
def closest_on_segments(
    points: np.ndarray, polyline: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For each of ``points`` (m, 3), the segment (m,) of ``polyline`` (k, 3) nearest to it, the
    parameter (m,) in [0, 1] along it and the distance (m,), as numpy computed them (the formula in
    ``tests/mesh/test_kernels.py``: einsum's sums (x + z) + y, the norm's (x + y) + z, the first
    nearest segment on a tie), so the same bits, without its (m, k − 1, 3) arrays."""
    m, s = len(points), len(polyline) - 1
    seg = np.zeros(m, dtype=np.int64)
    t_best = np.zeros(m)
    d_best = np.full(m, np.inf)
    for j in range(s):
        a0, a1, a2 = polyline[j, 0], polyline[j, 1], polyline[j, 2]
        e0, e1, e2 = polyline[j + 1, 0] - a0, polyline[j + 1, 1] - a1, polyline[j + 1, 2] - a2
        length_sq = max((e0 * e0 + e2 * e2) + e1 * e1, 1e-30)  # einsum's order
        for i in range(m):
            w0, w1, w2 = points[i, 0] - a0, points[i, 1] - a1, points[i, 2] - a2
            t = ((w0 * e0 + w2 * e2) + w1 * e1) / length_sq
            t = min(max(t, 0.0), 1.0)
            r0 = points[i, 0] - (a0 + t * e0)
            r1 = points[i, 1] - (a1 + t * e1)
            r2 = points[i, 2] - (a2 + t * e2)
            d = np.sqrt((r0 * r0 + r1 * r1) + r2 * r2)
            if j == 0 or d < d_best[i]:
                seg[i], t_best[i], d_best[i] = j, t, d
    return seg, t_best, d_best
