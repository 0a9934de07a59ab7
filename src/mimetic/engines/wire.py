"""The ``wire`` engine: the skin/muscle model of the automated rigging thesis (§4.2).

For one wire with control points (CVs) ``c0`` (k, 3) on the rest skin:

1. A muscle's contraction scales its joint about the bony origin ``O`` along the unit axis ``a``
   (origin -> insertion); at full contraction the scale is ``1 - CONTRACTION`` (the reversed
   mentalis: ``1 + CONTRACTION``), so the locator of CV k parented to the joint sits at
   ``c0_k + dL_k`` with ``dL_k = -CONTRACTION ((c0_k - O) . a) a``. A sphincter scales about its
   centre in the face plane instead, and pushes forward (+Z) by PUCKER of that (a pucker).
2. Each CV's cluster is point-constrained, with normalised weights, to one locator per affecting
   muscle (weight ``w_jk``) plus a rest locator (``w0_k``). The thesis keys each muscle's constraint
   weight to its activation ``a_j`` (a set-driven key), ``dc_k = sum_j a_j w_jk dL_jk / (w0_k +
   sum_j a_j w_jk)``, so one muscle alone moves a CV by ``a w dL / (w0 + a w)``: a saturating curve
   (half an activation gives two thirds of the motion), so control layers (ARKit weights, FACS
   intensities) do not land linearly and a baked basis, a secant at full activation, misses the
   middle of every channel. Here each muscle's share is its share at full activation, given the
   other muscles' activations, times its own activation (``locator_shares``)::

       dc_k = sum_j a_j w_jk dL_jk / (w0_k + w_jk + sum_{i != j} a_i w_ik)

   One muscle alone moves a CV linearly, ``a w / (w0 + w)`` of its locator motion. Where every
   activation is 0 or 1 this is the thesis's formula exactly, so poses at full activation do not
   change. Muscles pulling one CV still damp each other (a share falls as the others rise) and
   the shares sum below 1, so a CV stays within the hull of its rest and locator positions. That
   damping is the engine's remaining nonlinearity: several muscles on one CV at half activation
   move it a little more than half as far. (A damping by the ratios of the activations alone would
   make every combination linear along a ray, but it is not bilinear, so a baked basis with
   pairwise correctives fits it worse.)
3. The wire deformer moves each vertex P of the wire's deformation set by
   ``f(d / d0) (D(u) - B(u))``, ``f(x) = (1 - x^2)^2`` for d < d0, where ``u`` is the closest
   point on the rest polyline B, d the distance to it and ``D(u) - B(u)`` the interpolated CV
   motion.

Choices the thesis leaves open, made here: polylines (the thesis's final rig used linear wires);
where several wires reach one vertex their dropoff weights are normalised when they sum past 1
(a partition of unity, so overlapping wires blend instead of adding up); dropoffs are fractions of
the head height. The deformation sets (the skin within the dropoff minus the lip the wire must
not touch) keep the upper and lower lips apart, so they can part. A wire moves the skin within
its dropoff on the mesh at hand (``deformation_set``): a set transferred vertex by vertex from the
reference has holes, each a step from ``f`` to 0 that folds the skin. Where the lips join (the
commissures, and the skin on from each corner where the two lip regions meet) a cut between
them would shear one piece of skin, a saw-toothed lip line with flipped triangles in a smile and
webs between the lips in disgust; so near that joint each lip also takes the other lip's wires,
fully at the joint and not at all ``LIP_JOIN_RADIUS_REL`` of the mouth width away
(``lip_joint``): the corners move as one and the lips part toward the middle. After the muscles
the shared chain runs: skull push-to-surface, creases, skinning, eyelid sculptors
(``chain.Chain``).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from mimetic.engines.chain import Chain
from mimetic.engines.muscles import deformable_vertices, muscle_frame, muscle_mask
from mimetic.mesh.geometry import closest_on_polyline, vertex_adjacency
from mimetic.mesh.weld import find_weld
from mimetic.rig.activations import check_activations
from mimetic.rig.model import Rig, Wire

CONTRACTION = 0.25  # joint scale reduction at full activation (s = 1 - 0.25)
SPHINCTER_CONTRACTION = 0.35  # scale reduction about a sphincter's centre at full activation
PUCKER = 0.6  # forward push of squeezed tissue, relative to its motion toward the centre
LIP_JOIN_RADIUS_REL = 0.2
"""Reach of the lips' joint, a fraction of the mouth width (1 cm on a 5 cm mouth): a lip vertex this
close to where the lips join is moved by the other lip's wires too (``lip_joint``)."""
LEFT_OUT_SHARE = 0.05
"""A wire leaves a lip out when at most this share of the lip's vertices within its dropoff are in its
deformation set (the recipe's sets hold none of the lip they leave out)."""
LIP_EDGE_REL = 0.011
"""Where a wire leaves a lip out, the lip's skin within this fraction of the head height of the
wire's other skin still takes a share of it, falling linearly to 0 (1 at that skin): the step from
``f(d/d0)`` to 0 at the lip region's edge (the nasolabial and marionette lines) spans this distance
at every resolution. 0.011 is the median edge across the lip regions' borders on ICT's 26.7k head
(0.25 cm), where the step spanned one edge and reads as a furrow; on a dense scan it spanned a
fraction of a millimetre, a crack (docs/rigging.md)."""
LIP_JOIN_OUTER_REL = 0.3
"""Where the lips join counts in the outer 30 % of each half of the mouth and beyond the corners, not
in the middle (a mesh that closes its mouth slit with triangles joins the lips all along)."""


def dropoff(x: np.ndarray) -> np.ndarray:
    """The wire dropoff f(x) = (1 - x^2)^2 on [0, 1], 0 beyond."""
    return np.where(x < 1.0, (1.0 - np.minimum(x, 1.0) ** 2) ** 2, 0.0)


def locator_motion(rig: Rig, cv: np.ndarray, muscle: str) -> np.ndarray:
    """Motion (k, 3) of the locators at CVs ``cv`` (k, 3) parented to ``muscle``, at full contraction."""
    m = rig.muscle(muscle)
    frame = muscle_frame(rig, muscle)
    if m.kind == "sphincter":
        rel = cv - frame.attachment
        rel[:, 2] = 0.0  # squeeze in the face plane, and bulge forward a quarter as much
        squeeze = -SPHINCTER_CONTRACTION * rel
        return squeeze + PUCKER * np.linalg.norm(squeeze, axis=1, keepdims=True) * np.array([0.0, 0.0, 1.0])
    axis = (frame.insertion - frame.attachment) / frame.length
    along = (cv - frame.attachment) @ axis  # (k,)
    return (CONTRACTION if m.reversed else -CONTRACTION) * along[:, None] * axis


def locator_shares(weights: np.ndarray, rest: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Each muscle locator's share (K, c) of its control point's motion (the module docstring, step 2).

    ``share_kj = a_j w_kj / (w0_k + w_kj + sum_{i != j} a_i w_ki)``: muscle j's share at full
    activation, given the others' activations, times its own activation.

    Parameters
    ----------
    weights : (K, c) float64
        Constraint weight ``w_kj >= 0`` of channel j's locator on control point k (0: not attached).
    rest : (K,) float64
        Rest-locator weight ``w0_k``; ``w0_k + sum_j w_kj > 0``.
    values : (c,) float64
        The pose; only channels with a weight count, and those are activations in [0, 1].

    Returns
    -------
    shares : (K, c) float64, each >= 0, each row summing to less than 1 when ``w0_k > 0``.
    """
    wa = weights * values  # (K, c) activation-keyed constraint weights
    others = (rest + wa.sum(axis=1))[:, None] - wa  # (K, c) w0 + sum_{i != j} a_i w_i
    return np.divide(wa, others + weights, out=np.zeros_like(wa), where=wa > 0)


def lip_joint(rig: Rig) -> np.ndarray:
    """How much (n,) float64 in [0, 1] each lip vertex is moved by the wires of the other lip.

    A wire's deformation set leaves out the lip it must not touch, so the lips can part. But the lips
    are one piece of skin where they join: at the commissures and, on many meshes, along a seam
    that runs on from each corner into the cheek (the ``upper_lip`` and ``lower_lip`` regions meet
    there). Cut at that seam, the two lips' wires shear the skin (flipped triangles, a saw-toothed
    lip line, webs between the lips). So a lip vertex at distance d from the joint also takes
    ``f(d / r)`` of each wire that leaves its lip out (``f`` the wire dropoff, r =
    ``LIP_JOIN_RADIUS_REL`` of the mouth width): at the joint both lips take the same wires alike
    and move as one; a radius away they are free again.

    The joint: vertices whose one-ring (across unwelded seams) holds vertices of both lips, in the
    outer ``LIP_JOIN_OUTER_REL`` of each half of the mouth or beyond its corners; on a mesh whose
    lips share no vertex or edge there, the vertices nearest the ``mouth_corner`` landmarks. 0 for
    every vertex of a rig without the lip regions or the corner landmarks.
    """
    n = rig.n_vertices
    joint = np.zeros(n)
    upper, lower = rig.regions.get("upper_lip"), rig.regions.get("lower_lip")
    corners = ("mouth_corner_L", "mouth_corner_R")
    if upper is None or lower is None or not len(upper) or not len(lower):
        return joint
    if any(c not in rig.landmarks for c in corners):
        return joint
    v, f = rig.mesh.vertices, rig.mesh.faces
    weld = find_weld(rig.mesh)
    k = len(weld.first)
    welded = weld.index[f]  # (m, 3) faces over welded vertices
    near = vertex_adjacency(welded, k) + sp.identity(k, format="csr")  # closed one-rings
    up, low = np.zeros(k), np.zeros(k)
    up[weld.index[upper]] = 1.0
    low[weld.index[lower]] = 1.0
    joined = ((near @ up) > 0) & ((near @ low) > 0)  # (k,)
    left, right = (rig.landmarks[c].position(v, f) for c in corners)
    half = 0.5 * np.linalg.norm(left - right)
    axis = (left - right) / (2 * half)
    outer = np.abs((v - 0.5 * (left + right)) @ axis) >= (1 - LIP_JOIN_OUTER_REL) * half  # (n,)
    at = np.flatnonzero(joined[weld.index] & outer)
    points = v[at] if len(at) else np.array([left, right])
    lips = np.union1d(upper, lower)
    dist, _ = cKDTree(points).query(v[lips])
    joint[lips] = dropoff(dist / (LIP_JOIN_RADIUS_REL * 2 * half))
    return joint


def deformation_set(
    rig: Rig, wire: Wire, cv: np.ndarray, skin: np.ndarray, joint: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The vertices (m,) int64 one wire moves and the share (m,) float64 in (0, 1] of its deformer
    each takes.

    The recipe's deformation set is the skin within the dropoff minus the lip the wire must not
    move; the wire moves exactly that here, on this mesh: its set, every other skin vertex
    (``skin``, sorted) within its dropoff that is not in a lip it leaves out (a transferred set has
    holes where the user's skin lies within the dropoff but its reference point did not, each a
    step from ``f(d/d0)`` to 0 that folds the skin), and, with share ``joint`` (n,)
    (``lip_joint``), the left-out lip's vertices near where the lips join, and those within
    ``LIP_EDGE_REL`` of the set's skin outside both lips (a share falling to 0 across that distance).
    A lip is left out when at most ``LEFT_OUT_SHARE`` of its vertices within the dropoff are in the
    set.
    """
    v = rig.mesh.vertices
    members = np.asarray(wire.vertices, dtype=np.int64)
    _, _, dist = closest_on_polyline(v[skin], cv)
    reach = skin[dist < wire.dropoff_rel * rig.scale]
    out, lips = [np.zeros(0, np.int64)], [np.zeros(0, np.int64)]
    for region in ("upper_lip", "lower_lip"):
        ids = rig.regions.get(region)
        if ids is None:
            continue
        lips.append(np.asarray(ids, dtype=np.int64))
        reached = np.intersect1d(ids, reach)
        if len(reached) and np.isin(reached, members).mean() <= LEFT_OUT_SHARE:
            out.append(np.asarray(ids, dtype=np.int64))
    out = np.unique(np.concatenate(out))
    members = np.union1d(members, np.setdiff1d(reach, out))
    share = joint[out]
    outside = np.setdiff1d(members, np.concatenate(lips))  # the wire's skin that is no lip's
    if len(out) and len(outside):
        edge = LIP_EDGE_REL * rig.scale
        gap, _ = cKDTree(v[outside]).query(v[out], distance_upper_bound=edge)
        share = np.maximum(share, np.clip(1.0 - gap / edge, 0.0, 1.0))  # inf (beyond the edge): 0
    taken = ~np.isin(out, members) & (share > 0)
    return np.concatenate([members, out[taken]]), np.concatenate([np.ones(len(members)), share[taken]])


class WireEngine:
    """The wire skin/muscle model with the thesis's deformation chain; prepare once, deform often.

    Prepared data: ``weights`` (K, c) constraint weight of each channel's locator on each of the
    K control points of all wires, ``rest`` (K,) rest-locator weights, ``motion`` (K, c, 3)
    locator motion at full contraction, ``joint`` (n,) how much each lip vertex takes of the other
    lip's wires (``lip_joint``), and ``spread`` (n, K) sparse CSR, the wire deformers'
    dropoff-weighted interpolation from CV motion (K, 3) to vertex motion (n, 3).
    """

    name = "wire"

    def __init__(self, rig: Rig, *, skull: bool = True) -> None:
        self.rig = rig
        self.channels = rig.channel_names
        v, f = rig.mesh.vertices, rig.mesh.faces
        c = len(rig.channels)
        cvs = [np.array([p.position(v, f) for p in w.points]) for w in rig.wires]
        starts = np.cumsum([0] + [len(p) for p in cvs])
        k_total = int(starts[-1])
        self.weights = np.zeros((k_total, c))
        self.rest = np.concatenate([w.rest_weight for w in rig.wires])
        self.motion = np.zeros((k_total, c, 3))
        self.joint = lip_joint(rig)  # (n,) how much each lip vertex the other lip's wires move
        skin = deformable_vertices(rig)
        rows, cols, vals = [], [], []
        for wire, cv, start in zip(rig.wires, cvs, starts, strict=False):
            for muscle, w in wire.muscle_weights.items():
                j = rig.channel_index(muscle)
                self.weights[start : start + len(cv), j] = w
                self.motion[start : start + len(cv), j] = locator_motion(rig, cv, muscle)
            ids, share = deformation_set(rig, wire, cv, skin, self.joint)
            r, k, val = _spread(rig, ids, share, cv, wire.dropoff_rel)
            rows.append(r)
            cols.append(start + k)
            vals.append(val)
        rows, cols, vals = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
        total = np.bincount(rows, weights=vals, minlength=rig.n_vertices)  # summed dropoff per vertex
        vals = vals / np.maximum(total[rows], 1.0) * muscle_mask(rig)[rows]  # overlapping wires blend
        self.spread = sp.csr_matrix((vals, (rows, cols)), shape=(rig.n_vertices, k_total))  # (n, K)
        self.chain = Chain(rig, skull=skull)

    def cv_motion(self, values: np.ndarray) -> np.ndarray:
        """Control-point motion (K, 3) for a pose (c,) (the module docstring, step 2)."""
        return np.einsum("kc,kcd->kd", locator_shares(self.weights, self.rest, values), self.motion)

    def muscle_offsets(self, values: np.ndarray) -> np.ndarray:
        """Skin displacement (n, 3) from the muscles alone, for a pose (c,)."""
        return self.spread @ self.cv_motion(values)  # (n, K) @ (K, 3)

    def deform(self, values: np.ndarray) -> np.ndarray:
        """Vertex positions (n, 3) for one pose ``values`` (c,) in the rig's channel order."""
        values = check_activations(self.rig, values)
        if values.ndim != 1:
            raise ValueError("deform takes one pose (c,); loop over frames or bake a Basis for clips")
        return self.chain.apply(self.rig.mesh.vertices + self.muscle_offsets(values), values)


def _spread(
    rig: Rig, ids: np.ndarray, share: np.ndarray, cv: np.ndarray, dropoff_rel: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Entries (vertex, CV, weight) of one wire's deformer on vertices ``ids`` (m,), each taking
    ``share`` (m,) of it: s f(d/d0) (1 - t), s f(d/d0) t.

    A vertex equally close to two segments (the midline of a symmetric wire) takes the mean of
    both closest points, so mirror-symmetric wires deform mirror-symmetrically.
    """
    points = rig.mesh.vertices[ids]
    seg, t, dist = closest_on_polyline(points, cv)
    f = share * dropoff(dist / (dropoff_rel * rig.scale))
    rows, cols, vals = [ids, ids], [seg, seg + 1], [f * (1 - t), f * t]
    if len(cv) > 2:  # ties: the closest point on the other segments
        mask = np.ones((len(ids), len(cv) - 1), bool)
        mask[np.arange(len(ids)), seg] = False
        best = np.full(len(ids), np.inf)
        seg2 = np.zeros(len(ids), int)
        t2 = np.zeros(len(ids))
        for k in range(len(cv) - 1):
            _, tk, dk = closest_on_polyline(points, cv[k : k + 2])
            better = mask[:, k] & (dk < best)
            best[better], seg2[better], t2[better] = dk[better], k, tk[better]
        tie = np.abs(best - dist) <= 1e-12 * rig.scale
        half = np.where(tie, 0.5, 1.0)
        vals = [vals[0] * half, vals[1] * half]
        rows += [ids[tie], ids[tie]]
        cols += [seg2[tie], seg2[tie] + 1]
        vals += [0.5 * f[tie] * (1 - t2[tie]), 0.5 * f[tie] * t2[tie]]
    rows, cols, vals = np.concatenate(rows), np.concatenate(cols), np.concatenate(vals)
    keep = vals > 0
    return rows[keep], cols[keep], vals[keep]
