"""Geometry of the reference head's skin for one parameter set.

Every skin vertex has a canonical chart position (``topology.py``). A parameter set moves it
in three steps, none of which changes the topology:

1. **Chart warp.** Eye spacing and size, mouth width and nose length move and scale their
   features' chart regions by affine maps that fade out smoothly (a diffeomorphism of the
   chart; it never folds for parameters inside their ranges).
2. **Base surface.** The direction of the warped chart point is cast from the head centre
   onto a smooth union of ellipsoids and superellipsoids (cranium, face, maxilla, mandible,
   chin, neck), found by bisection.
3. **Features.** Brow ridge, eye sockets, nose, cheekbones, nasolabial folds, lips, chin and
   others are heights added along +Z on the face, blending to the outward radial direction
   at the sides (displacing radially would drag features down, see the feasibility note).
   Eyelids lie on a sphere just outside the eyeball; the inner lip rolls back into the mouth.

The default head (every factor 1.0) is a healthy adult face: the base solids, the feature
heights and the nose were fitted by least squares to the mean neutral face of ICT-FaceKit (a
morphable model built from light-stage scans; eye line and outer canthi aligned), to within
0.27 cm RMS over the face, the sides, the top and the back of the head (the previous default:
0.59 cm). Before that fit the cheeks were hollow under the cheekbones, the lower face receded
and the nose was long and heavy.

Units are centimetres; the eye line is at y = 0 and the face looks down +Z.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from mimetic.head.params import HeadParams
from mimetic.head.topology import (
    EYE_CENTRE,
    EYE_OUTER,
    MOUTH_CENTRE,
    MOUTH_OUTER,
    HeadTopology,
    chart_to_direction,
    direction_to_chart,
)

EYE_RADIUS = 1.2  # eyeball radius, cm (scaled by eye_size)
LID_GAP = 0.12  # lid thickness over the eyeball at the margin, cm
NASION_Y = 0.9  # chart Y of the nasion
SUBNASALE_DROP = 5.4  # nasion-to-subnasale chart length at nose_length = 1
SUBNASALE_Y0 = NASION_Y - SUBNASALE_DROP  # canonical chart Y of the subnasale


def smoothstep(e0: float, e1: float, x: np.ndarray) -> np.ndarray:
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def _gauss(X: np.ndarray, Y: np.ndarray, cx: float, cy: float, sx: float, sy: float) -> np.ndarray:
    return np.exp(-(((X - cx) / sx) ** 2) - ((Y - cy) / sy) ** 2)


@dataclass(frozen=True)
class Layout:
    """Feature placement for one parameter set, in chart units (about cm on the face)."""

    eye_centre: np.ndarray  # (2,) left eye; the right eye is its mirror
    eye_scale: float
    mouth_centre: np.ndarray  # (2,)
    mouth_scale: np.ndarray  # (2,) x, y
    subnasale_y: float
    tip_y: float
    nose_projection: float
    alar_half_width: float
    chin_shift: float  # cm the chin and jaw move down

    @staticmethod
    def of(p: HeadParams) -> Layout:
        subnasale = NASION_Y - SUBNASALE_DROP * p.nose_length
        mouth_y = subnasale - 2.5
        return Layout(
            eye_centre=np.array([EYE_CENTRE[0] * p.eye_spacing, EYE_CENTRE[1]]),
            eye_scale=p.eye_size,
            mouth_centre=np.array([0.0, mouth_y]),
            mouth_scale=np.array([p.mouth_width, 1.0]),
            subnasale_y=subnasale,
            tip_y=subnasale + 1.45 * p.nose_length,
            nose_projection=2.5 * p.nose_projection,
            alar_half_width=1.75 * p.nose_width,
            chin_shift=2.6 * (p.chin_height - 1.0),
        )


# --- 1. chart warp ------------------------------------------------------------------------------


def warp_chart(chart: np.ndarray, layout: Layout) -> np.ndarray:
    """Move canonical chart points (k, 2) to this layout's feature positions (k, 2)."""
    X = chart
    out = X.copy()
    for sign in (1.0, -1.0):
        c0 = EYE_CENTRE * np.array([sign, 1.0])
        c1 = layout.eye_centre * np.array([sign, 1.0])
        rho = np.hypot(*((X - c0) / np.array(EYE_OUTER)).T)
        w = 1.0 - smoothstep(1.0, 2.2, rho)
        target = c1 + (X - c0) * layout.eye_scale
        out += w[:, None] * (target - X)
    m0 = MOUTH_CENTRE
    rel = X - m0
    mb = np.where(rel[:, 1] >= 0, MOUTH_OUTER[1], MOUTH_OUTER[2])
    rho = np.hypot(rel[:, 0] / MOUTH_OUTER[0], rel[:, 1] / mb)
    w_mouth = 1.0 - smoothstep(1.0, 2.0, rho)
    target = layout.mouth_centre + rel * layout.mouth_scale
    out += w_mouth[:, None] * (target - X)
    # nose: stretch the midline band between the nasion and the subnasale vertically; it hands
    # over to the mouth's translation below, so the two never add up
    stretch = (layout.subnasale_y - NASION_Y) / (SUBNASALE_Y0 - NASION_Y)
    shift = (stretch - 1.0) * (np.clip(X[:, 1], SUBNASALE_Y0, NASION_Y) - NASION_Y)
    band = (1.0 - smoothstep(0.9, 2.2, np.abs(X[:, 0]))) * (
        1.0 - smoothstep(NASION_Y, NASION_Y + 1.2, X[:, 1])
    )
    band *= smoothstep(SUBNASALE_Y0 - 3.0, SUBNASALE_Y0 - 1.0, X[:, 1])
    out[:, 1] += band * (1.0 - w_mouth) * shift
    return out


# --- canonical ring shapes (with parameter details), before the warp -----------------------------


def eye_margin(t: np.ndarray) -> np.ndarray:
    """Left-eye lid margin (k, 2) relative to the eye centre; t = 0 at the lateral canthus."""
    c, s = np.cos(t), np.sin(t)
    half = 1.72  # half-width, lateral and medial
    up = 0.61 * (1.0 - 0.18 * c) * np.abs(s) ** 0.85  # upper lid peaks a little medially
    low = -0.44 * (1.0 + 0.15 * c) * np.abs(s) ** 1.1
    y = np.where(s >= 0, up, low) + 0.10 * c - 0.05  # lateral canthus higher (canthal tilt)
    return np.column_stack([half * c * np.abs(c) ** 0.15, y])


def eye_ring_chart(u: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Canonical chart offsets (k, 2) of left-eye ring points (u, t) from the eye centre."""
    margin = eye_margin(t)
    outer = np.column_stack([EYE_OUTER[0] * np.cos(t), EYE_OUTER[1] * np.sin(t)])
    b = np.clip(u, 0.0, 1.0)[:, None]
    ring = (1 - b) * margin + b * outer
    return np.where((u < 0)[:, None], 0.86 * margin, ring)


def lip_profiles(xi: np.ndarray, p: HeadParams) -> tuple[np.ndarray, np.ndarray]:
    """Heights (cm) of the upper and lower vermilion borders above/below the contact line."""
    xi = np.clip(np.abs(xi), 0.0, 1.0)
    bow = 1.0 + 0.14 * np.exp(-(((xi - 0.22) / 0.1) ** 2)) - 0.10 * np.exp(-((xi / 0.07) ** 2))
    upper = 0.80 * p.upper_lip * (1 - xi**2) ** 0.55 * bow
    lower = 1.00 * p.lower_lip * (1 - xi**2) ** 0.6
    return upper, lower


MOUTH_HALF = 2.75  # canonical half-width of the mouth (corner to centre), cm
LIP_BULGE = (0.24, 0.26)  # forward bulge of the upper and lower vermilion, cm


def mouth_ring_chart(u: np.ndarray, t: np.ndarray, p: HeadParams) -> np.ndarray:
    """Canonical chart offsets (k, 2) of mouth ring points (u, t) from the mouth centre."""
    c, s = np.cos(t), np.sin(t)
    c = np.where(np.abs(c) < 1e-12, 0.0, c)
    vermilion = np.clip(u, 0.0, 1.0)
    half = np.where(u < 0, 0.93 * MOUTH_HALF, MOUTH_HALF + 0.12 * vermilion)
    x = half * c
    xi = x / MOUTH_HALF
    contact = -0.10 * np.clip(np.abs(xi), 0, 1) ** 2
    upper, lower = lip_profiles(xi, p)
    y = contact + vermilion * np.where(s > 0, upper, np.where(s < 0, -lower, 0.0))
    inner = np.column_stack([x, y])
    outer = np.column_stack([MOUTH_OUTER[0] * c, np.where(s >= 0, MOUTH_OUTER[1], MOUTH_OUTER[2]) * s])
    b = np.clip(u - 1.0, 0.0, 1.0)[:, None]
    return (1 - b) * inner + b * outer


# --- 2. base surface ----------------------------------------------------------------------------


def _ellipsoid(p: np.ndarray, c, a) -> np.ndarray:
    q = (p - np.asarray(c)) / np.asarray(a)
    return (np.linalg.norm(q, axis=-1) - 1.0) * min(a)


def _superellipsoid(p: np.ndarray, c, a, e_xz: float, e_y: float) -> np.ndarray:
    q = np.abs((p - np.asarray(c)) / np.asarray(a))
    xz = (q[..., 0] ** e_xz + q[..., 2] ** e_xz) ** (1.0 / e_xz)
    f = (xz**e_y + q[..., 1] ** e_y) ** (1.0 / e_y)
    return (f - 1.0) * min(a)


def _smin(a: np.ndarray, b: np.ndarray, k: float) -> np.ndarray:
    h = np.clip(k - np.abs(a - b), 0.0, None) / k
    return np.minimum(a, b) - h * h * k / 4.0


def base_field(p: np.ndarray, params: HeadParams, layout: Layout) -> np.ndarray:
    """Approximate signed distance (…,) of points (…, 3) to the base head (negative inside)."""
    jw, ch = params.jaw_width, layout.chin_shift
    f = _superellipsoid(p, (0, 2.7, -0.3), (7.6, 8.05, 9.4), 2.0, 2.4)  # cranium
    f = _smin(f, _ellipsoid(p, (0, -1.0, 0.8), (7.35, 10.25, 8.8)), 2.0)  # upper face and cheeks
    f = _smin(f, _ellipsoid(p, (0, -3.8, 4.75), (6.4, 4.85, 4.15)), 1.6)  # maxilla and midface
    f = _smin(
        f, _superellipsoid(p, (0, -7.3 - 0.7 * ch, 1.7), (5.4 * jw, 3.4 + 0.3 * ch, 7.95), 2.6, 3.0), 1.4
    )  # mandible
    f = _smin(f, _ellipsoid(p, (0, -10.2 - ch, 6.75), (2.75, 1.6, 2.9)), 1.4)  # chin
    neck = _superellipsoid(p, (0, -14.0, -1.8), (5.4, 10.0, 5.2), 2.0, 6.0)
    f = _smin(f, neck, 1.6)
    return -_smin(-f, p[..., 1] + 19.5, 1.2)  # neck cut


def base_radius(directions: np.ndarray, params: HeadParams, layout: Layout) -> np.ndarray:
    """Distance (k,) from the head centre to the base surface along unit directions (k, 3)."""
    lo = np.zeros(len(directions))
    hi = np.full(len(directions), 30.0)
    for _ in range(34):
        mid = 0.5 * (lo + hi)
        inside = base_field(directions * mid[:, None], params, layout) < 0
        lo = np.where(inside, mid, lo)
        hi = np.where(inside, hi, mid)
    return 0.5 * (lo + hi)


# --- 3. features ------------------------------------------------------------------------------


def nose_height(X: np.ndarray, Y: np.ndarray, L: Layout) -> np.ndarray:
    """Height (k,) of the nose above the base surface at chart points."""
    proj, W = L.nose_projection / 2.5, L.alar_half_width
    length = (L.subnasale_y - NASION_Y) / (SUBNASALE_Y0 - NASION_Y)
    span = NASION_Y - L.tip_y
    top = 2.22 * proj  # ridge height at the tip, before the lobule
    s = np.clip((NASION_Y - Y) / span, 0.0, None)  # 0 nasion .. 1 tip
    rise = np.clip(
        (s - 0.46 / span) / (1.0 - 0.46 / span), 0.0, 1.0
    )  # the dorsum rises 0.46 below the nasion
    dorsum = 0.05 + (top - 0.05) * rise**1.1
    width = 0.5 + 1.07 * np.clip(s, 0, 1) ** 1.5  # narrow root, broad tip
    below = np.clip((L.tip_y - Y) / (L.tip_y - L.subnasale_y), 0.0, None)  # 0 tip .. 1 subnasale
    b = np.clip(below, 0.0, 1.0)
    under = top * (1 - b**1.7) + 0.99 * b
    # under the subnasale the columella base fades into the upper lip, without a step
    under = np.where(below <= 1.0, under, 0.99 * np.exp(-(((L.subnasale_y - Y) / 0.6) ** 2)))
    under_w = 1.57 - 0.75 * b**0.7
    ridge = np.where(
        s <= 1, dorsum * np.exp(-1.4 * (X / width) ** 2), under * np.exp(-1.4 * (X / under_w) ** 2)
    )
    top_fade = smoothstep(-0.6, 0.4, (NASION_Y + 0.5 - Y) / 0.5)
    ridge = ridge * top_fade
    tip = 0.38 * proj * _gauss(X, Y, 0.0, L.tip_y + 0.05, 0.9, 0.87)  # rounded lobule
    alae = 0.0
    for sx in (1.0, -1.0):
        cx, cy = sx * (W - 0.55), L.subnasale_y + 0.6
        alae = alae + 1.3 * _gauss(X, Y, cx, cy, 0.65 * W / 1.75, 0.65 * length)
        alae = alae - 0.08 * np.exp(-(((np.hypot((X - cx) / 0.85, (Y - cy) / 0.8) - 1.0) / 0.18) ** 2))
    return np.maximum(ridge + tip, 0.0) + alae


def nostril_push(X: np.ndarray, Y: np.ndarray, L: Layout) -> np.ndarray:
    """Upward (+Y) push (k,) that hollows the nostrils on the underside of the nose, cm."""
    out = 0.0
    for sx in (1.0, -1.0):
        out = out + _gauss(X, Y, sx * 0.55 * L.alar_half_width / 1.75, L.subnasale_y + 0.32, 0.34, 0.2)
    return 0.25 * out


def feature_height(X: np.ndarray, Y: np.ndarray, params: HeadParams, L: Layout) -> np.ndarray:
    """Height (k,) of all facial features except lips and lids, along +Z on the face, cm."""
    ex, ey = L.eye_centre
    ax = np.abs(X)
    h = nose_height(X, Y, L)
    h += 0.38 * params.brow_ridge * _gauss(ax, Y, ex + 0.1, ey + 1.9, 2.0, 0.7)  # brow ridge
    h += 0.1 * params.brow_ridge * _gauss(X, Y, 0.0, ey + 1.6, 1.1, 0.8)  # glabella
    h -= 1.3 * _gauss(ax, Y, ex - 0.25, ey + 0.05, 1.5, 1.1)  # eye socket
    h -= 0.54 * _gauss(ax, Y, ex - 1.75, ey + 0.2, 0.6, 0.7)  # medial canthus hollow
    h += 0.3 * params.cheekbones * _gauss(ax, Y, ex + 1.5, -1.9, 1.5, 1.1)  # cheekbones
    h += 0.15 * _gauss(ax, Y, ex + 0.2, -3.2, 2.0, 1.5)  # malar fat
    mx, my = L.mouth_centre
    h += 1.31 * _gauss(X, Y, mx, my + 0.3, 2.06 * L.mouth_scale[0], 2.0)  # muzzle
    # nasolabial fold: groove along the line from the alar base to beside the mouth corner
    for sx in (1.0, -1.0):
        a = np.array([sx * (L.alar_half_width + 0.05), L.subnasale_y + 0.2])
        b = np.array([sx * (MOUTH_HALF * L.mouth_scale[0] + 1.3), my - 1.4])
        d = b - a
        tt = np.clip(((X - a[0]) * d[0] + (Y - a[1]) * d[1]) / (d @ d), 0.0, 1.0)
        dist = np.hypot(X - (a[0] + tt * d[0]), Y - (a[1] + tt * d[1]))
        side = np.sign((X - a[0]) * d[1] - (Y - a[1]) * d[0]) * sx
        fade = np.sin(np.pi * np.clip(tt * 0.9 + 0.1, 0, 1)) ** 0.5
        h -= 0.1 * fade * np.exp(-((dist / 0.28) ** 2))
        h += 0.15 * fade * np.exp(-(((dist - 0.6) / 0.5) ** 2)) * (side < 0)
    h -= 0.10 * _gauss(ax, Y, 0.32, L.subnasale_y - 1.0, 0.12, 0.8)  # philtrum groove
    h -= 0.23 * _gauss(X, Y, 0.0, my - 1.85, 1.6, 0.42)  # mentolabial sulcus
    h += 0.22 * _gauss(X, Y, 0.0, my - 3.0 - L.chin_shift, 1.5, 0.9)  # chin boss
    return h


def _blend_direction(d: np.ndarray) -> np.ndarray:
    """Displacement directions (k, 3): +Z on the face, the radial direction toward the sides."""
    w = smoothstep(np.cos(np.radians(75)), np.cos(np.radians(42)), d[:, 2])
    n = w[:, None] * np.array([0.0, 0.0, 1.0]) + (1 - w)[:, None] * d
    return n / np.linalg.norm(n, axis=1, keepdims=True)


@dataclass(frozen=True, eq=False)
class SkinGeometry:
    """Skin vertices and the feature anchors the parts and landmarks need (cm)."""

    vertices: np.ndarray  # (n, 3)
    chart: np.ndarray  # (n, 2) warped chart position of each vertex
    eye_centre_L: np.ndarray  # (3,) eyeball centre; the right one is its mirror
    eye_radius: float
    mouth_anchor: np.ndarray  # (3,) point on the contact line at the midline


@lru_cache(maxsize=8)
def default_skin_geometry(topo: HeadTopology) -> SkinGeometry:
    """``skin_geometry(topo, HeadParams())``, computed once per topology (landmarks and regions are
    defined on it: every ``make_head`` asked for it twice, 0.1 s a rig); its arrays are read-only."""
    geo = skin_geometry(topo, HeadParams())
    for array in (geo.vertices, geo.chart, geo.eye_centre_L, geo.mouth_anchor):
        array.setflags(write=False)
    return geo


def skin_geometry(topo: HeadTopology, params: HeadParams) -> SkinGeometry:
    """Skin vertex positions (n, 3) in cm for a parameter set (before the head scale)."""
    L = Layout.of(params)
    chart0 = direction_to_chart(topo.directions)
    front = topo.directions[:, 2] > 0.25

    # ring vertices: canonical shapes with the parameter details
    for rings, sign in ((topo.eye_L, 1.0), (topo.eye_R, -1.0)):
        idx = rings.index.ravel()
        uv = topo.ring_uv[idx]
        off = eye_ring_chart(uv[:, 0], uv[:, 1])
        chart0[idx] = EYE_CENTRE * np.array([sign, 1.0]) + off * np.array([sign, 1.0])
    idx = topo.mouth.index.ravel()
    uv = topo.ring_uv[idx]
    chart0[idx] = MOUTH_CENTRE + mouth_ring_chart(uv[:, 0], uv[:, 1], params)

    chart = np.where(front[:, None], warp_chart(chart0, L), chart0)
    directions = topo.directions.copy()
    directions[front] = chart_to_direction(chart[front])
    r = base_radius(directions, params, L)
    base = directions * r[:, None]
    normal = _blend_direction(directions)
    X, Y = chart[:, 0], chart[:, 1]
    h = np.where(front, feature_height(X, Y, params, L), 0.0)
    v = base + h[:, None] * normal
    v[:, 1] += np.where(front, nostril_push(X, Y, L), 0.0)
    v[:, 2] -= np.where(front, 0.5 * nostril_push(X, Y, L), 0.0)

    # eyeball and lids
    R = EYE_RADIUS * params.eye_size
    e_dir = chart_to_direction(L.eye_centre[None])[0]
    e_base = e_dir * base_radius(e_dir[None], params, L)[0]
    eye_c = np.array([e_base[0], e_base[1] + 0.05, e_base[2] - R - 0.15])
    for rings, sign in ((topo.eye_L, 1.0), (topo.eye_R, -1.0)):
        c = eye_c * np.array([sign, 1.0, 1.0])
        ring_u = rings.u
        for k, u in enumerate(ring_u):
            ids = rings.index[k]
            p = v[ids]
            rho2 = (p[:, 0] - c[0]) ** 2 + (p[:, 1] - c[1]) ** 2
            lid_r = R + LID_GAP + 0.05 * max(u, 0.0)
            z_sph = c[2] + np.sqrt(np.clip(lid_r**2 - rho2, 0.0, None))
            w = 1.0 - smoothstep(0.35, 0.85, max(u, 0.0))
            z = np.maximum(p[:, 2], w * z_sph + (1 - w) * p[:, 2])
            if u == ring_u[1]:  # a touch of margin thickness
                z = z + 0.02
            p[:, 2] = z
            d = p - c
            dist = np.linalg.norm(d, axis=1, keepdims=True)
            p = np.where(dist < R + 0.06, c + d / dist * (R + 0.06), p)
            if u < 0:  # conjunctiva skirt: tuck inside the eyeball
                p = c + (p - c) / np.linalg.norm(p - c, axis=1, keepdims=True) * (R - 0.25)
            v[ids] = p

    # lips: contact crease, vermilion bulge, inner lip rolled back into the mouth
    m = topo.mouth
    for k, u in enumerate(m.u):
        ids = m.index[k]
        t = topo.ring_uv[ids, 1]
        upper = np.sin(t) > 1e-9
        xi = np.clip(np.abs(np.cos(t)), 0, 1)
        corner_fade = 1 - xi**4
        if u < 0:
            v[ids, 2] -= 0.85 * corner_fade + 0.25
            v[ids, 1] += np.where(upper, 0.30 * params.upper_lip, -0.34 * params.lower_lip) * corner_fade
        elif u == 0:
            v[ids, 2] -= 0.24 * corner_fade + 0.05
        else:
            bulge = np.where(upper, LIP_BULGE[0] * params.upper_lip, LIP_BULGE[1] * params.lower_lip)
            peak = np.where(upper, 0.8, 0.5)
            prof = np.exp(-(((min(u, 1.0) - peak) / 0.55) ** 2)) * np.exp(-((max(u - 1.0, 0.0) / 0.3) ** 2))
            ridge = 0.04 if u == 1 else 0.0
            v[ids, 2] += (bulge * prof - 0.12 * max(1 - u, 0.0) + ridge) * corner_fade
    mouth_mid = m.index[1][len(t) // 4]
    return SkinGeometry(v, chart, eye_c, R, v[mouth_mid].copy())
