"""The ``vector`` engine: Waters' linear, sphincter and sheet muscles (Parke & Waters 1996).

Each muscle displaces the rest skin inside its zone of influence; the displacement of one
muscle is proportional to its activation. Kernels (for unit activation, lengths in rig units):

* **linear**: bony attachment V1 (origin inset), insertion V2, length L = |V2 - V1|. For a vertex
  P at distance D = |P - V1| and angle mu from the muscle axis, inside the zone (mu < Omega,
  D < Rf): ``dP = K L a r (V1 - P)/|V1 - P|`` (the reversed mentalis pushes away), with the
  angular falloff ``a = cos(mu/Omega * pi/2)`` and the radial falloff ``r = sin(D/Rs * pi/2)`` for
  D < Rs and ``cos((D - Rs)/(Rf - Rs) * pi/2)`` up to Rf (Waters' equations with the pi/2 the
  survey's extraction lost; Rs = falloff_start_rel L, Rf = falloff_end_rel L), times a lateral
  falloff ``cos(pi/2 * l/w)`` with the distance l from the axis and w = 2 width_rel * scale.
* **sphincter**: centre c, semi-axes from the insertion (major) and width_rel (minor) in the face
  plane; elliptical radius rho. Skin inside rho < 1 is drawn toward the centre in the face plane
  by ``K_s rho``-scaled motion (a "string bag") and pushed forward (+Z) by PUCKER of that;
  it falls off with a cosine to 0 at rho = falloff_end_rel. Around an eye only the orbital ring
  squeezes (at 60 %, ramping up smoothly from rho = 0.2 to 0.8): the lids close through their bones.
* **sheet**: parallel fibres along the axis: motion toward the origin along the axis, with the
  linear muscle's radial falloff along the axis and a cosine falloff across its width.

Combination rule (the survey notes Waters' sequential application gives artefacts): every
muscle's displacement is computed on the rest skin and the sum is applied at once, then soft-
limited per vertex to ``SATURATION_REL * scale`` (``|d| -> L tanh(|d|/L)``), so several muscles
on one patch are damped and skin never tears away. The shared chain (skull, creases, skinning,
sculptors) follows.

Lips (``lip_gate``): a muscle whose insertion is on one lip (the levators on the upper lip, the
depressor labii and the platysma on the lower) leaves the other lip alone, so its zone does not drag
the other lip across the seam; a muscle inserting at a mouth corner (the modiolus: zygomatic major,
risorius, buccinator, triangularis, incisivis) moves both lips alike. Two things keep the gate from
tearing the skin:

* it depends on where the insertion is, not on which lip region the vertex at the corner happens to
  be in: the gate ramps in with the insertion's distance from the nearest mouth corner, from
  ``CORNER_FREE_REL`` to ``CORNER_GATED_REL`` of half the mouth width. (Deciding by the corner
  vertex's region tore one corner open on heads whose corner vertex fell in a lip on one side only:
  ICT-FaceKit with automatic landmarks.)
* the held lip is a smooth field (``lip_holds``), not a vertex set: the region diffused over the skin
  by ``LIP_BLEND_REL`` of the head height (so a ragged or speckled region, as a transfer gives, holds
  no lone vertex back while its neighbours move), and let go by the same ramp toward the corners,
  where the two lips are one piece of skin.

Symmetry: a midline sphincter (side "C", the orbicularis oris) is one ellipse about the midline; its
semi-major axis lies along X (the rig's left-right axis) with the in-plane length from the centre to
the insertion, so it does not tilt toward the one corner its insertion names.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from mimetic.engines.chain import Chain
from mimetic.engines.kernels import channel_offsets, row_lengths
from mimetic.engines.muscles import deformable_vertices, muscle_frame, muscle_mask
from mimetic.mesh.geometry import smooth_field
from mimetic.mesh.weld import find_weld
from mimetic.rig.activations import check_activations
from mimetic.rig.model import Muscle, Rig

STRENGTH = 0.22  # K: linear and sheet motion at full activation, fraction of muscle length
SPHINCTER_STRENGTH = 0.35  # K_s: fraction of the distance to the centre at full activation
PUCKER = 0.6  # forward push of squeezed tissue, relative to its motion toward the centre
SATURATION_REL = 0.1  # per-vertex displacement soft limit, fraction of the head height
CORNER_FREE_REL = 0.1  # within this of a mouth corner (fraction of half the mouth width) the lips move as one
CORNER_GATED_REL = 0.3  # from this far on, a muscle inserting on one lip leaves the other lip alone
LIP_BLEND_REL = 0.01  # a lip's hold is its region diffused over the skin by this, fraction of the head height
FORWARD = np.array([0.0, 0.0, 1.0])
LATERAL = np.array([1.0, 0.0, 0.0])


def _radial(x: np.ndarray, start: float, end: float) -> np.ndarray:
    """Waters' radial falloff over a distance fraction x: rises to 1 at ``start``, 0 at ``end``."""
    rise = np.sin(np.clip(x / start, 0.0, 1.0) * np.pi / 2)
    fall = np.cos(np.clip((x - start) / (end - start), 0.0, 1.0) * np.pi / 2)
    return np.where(x < start, rise, fall) * (x < end)


def _on_eyeball(rig: Rig, face: int) -> bool:
    parts = rig.mesh.parts
    return any(face in parts[p] for p in ("eye_L", "eye_R") if p in parts)


def _smoothstep(x: np.ndarray | float) -> np.ndarray:
    t = np.clip(x, 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def _mouth_corners(rig: Rig, lips: np.ndarray) -> np.ndarray:
    """The mouth corners (2, 3): the ``mouth_corner_L/R`` landmarks, else the lips' extreme-X vertices."""
    v, f = rig.mesh.vertices, rig.mesh.faces
    names = ("mouth_corner_L", "mouth_corner_R")
    if all(n in rig.landmarks for n in names):
        return np.stack([rig.landmarks[n].position(v, f) for n in names])
    x = v[lips, 0]
    return v[lips[[np.argmax(x), np.argmin(x)]]]


def _corner_ramp(rig: Rig, points: np.ndarray) -> np.ndarray:
    """0 (k,) for points (k, 3) at a mouth corner, rising smoothly to 1 at ``CORNER_GATED_REL``."""
    lips = np.union1d(rig.regions["upper_lip"], rig.regions["lower_lip"])
    corners = _mouth_corners(rig, lips)  # (2, 3)
    half_width = max(0.5 * float(np.linalg.norm(corners[0] - corners[1])), 1e-12)
    t = np.linalg.norm(points[:, None, :] - corners[None], axis=2).min(axis=1) / half_width  # (k,)
    return _smoothstep((t - CORNER_FREE_REL) / (CORNER_GATED_REL - CORNER_FREE_REL))


def lip_holds(rig: Rig) -> dict[str, np.ndarray]:
    """How firmly (n,) float64 in [0, 1] each lip stays put under a muscle of the other lip.

    For ``upper_lip`` and ``lower_lip``: the region's indicator diffused by ``LIP_BLEND_REL *
    rig.scale`` (``mesh.geometry.smooth_field``) over the outer skin (the ``skin`` part, else every
    deformable face), then over the rest of the deformable surface (the mouth cavity) with the outer
    skin's values held, times ``_corner_ramp`` of each vertex (0 at the mouth corners); on the surface
    with its unwelded seams merged (``mesh.weld.find_weld``), so coincident copies hold alike. The outer skin
    comes first so that its holds do not depend on the cavity's triangulation (a generated head's
    cavity is mirror-symmetric in its positions, not in its triangles). Empty when the rig lacks
    either region.
    """
    upper, lower = rig.regions.get("upper_lip"), rig.regions.get("lower_lip")
    if upper is None or lower is None or not len(upper) or not len(lower):
        return {}
    weld = find_weld(rig.mesh)  # diffused across unwelded seams, so copies of a vertex hold alike
    k = len(weld.first)
    v, f = rig.mesh.vertices[weld.first], weld.index[rig.mesh.faces]  # (k, 3), (m, 3) welded
    deformable = np.zeros(k, dtype=bool)
    deformable[weld.index[deformable_vertices(rig)]] = True
    surface = f[deformable[f].all(axis=1)]  # every deformable face
    outer = f[rig.mesh.parts["skin"]] if "skin" in rig.mesh.parts else surface
    inside = np.zeros((k, 2))
    inside[weld.index[upper], 0] = 1.0
    inside[weld.index[lower], 1] = 1.0
    length = LIP_BLEND_REL * rig.scale
    spread = smooth_field(inside, v, outer, length)  # (k, 2)
    rest = deformable.copy()
    rest[outer.ravel()] = False  # the cavity: diffused with the outer skin's values as its boundary
    if rest.any():
        spread = smooth_field(spread, v, surface, length, free=rest)
    held = np.clip(spread[weld.index], 0.0, 1.0) * _corner_ramp(rig, rig.mesh.vertices)[:, None]
    return {"upper_lip": held[:, 0], "lower_lip": held[:, 1]}


def lip_gate(rig: Rig, muscle: Muscle, holds: dict[str, np.ndarray] | None = None) -> np.ndarray:
    """How much (n,) float64 in [0, 1] of a muscle's motion each vertex takes, as far as the lips go.

    ``1 - owned * holds[other]``: ``other`` is the lip opposite the one the insertion is on (the lip
    region holding the vertex of its largest barycentric weight), ``owned`` is ``_corner_ramp`` of the
    insertion (0 for a muscle inserting at a mouth corner, which moves both lips) and ``holds`` is
    ``lip_holds(rig)`` (pass it to reuse it). All ones for an insertion on neither lip, and for a rig
    without ``upper_lip`` / ``lower_lip`` regions.
    """
    holds = lip_holds(rig) if holds is None else holds
    if not holds:
        return np.ones(rig.n_vertices)
    v, f = rig.mesh.vertices, rig.mesh.faces
    vertex = f[muscle.insertion.face][int(np.argmax(muscle.insertion.bary))]
    if np.isin(vertex, rig.regions["upper_lip"]):
        other = "lower_lip"
    elif np.isin(vertex, rig.regions["lower_lip"]):
        other = "upper_lip"
    else:
        return np.ones(rig.n_vertices)
    owned = _corner_ramp(rig, muscle.insertion.position(v, f)[None])[0]
    return 1.0 - owned * holds[other]


def muscle_displacement(rig: Rig, name: str, ids: np.ndarray) -> np.ndarray:
    """Displacement (k, 3) of rest vertices ``ids`` (k,) for one unit of muscle ``name``."""
    m = rig.muscle(name)
    frame = muscle_frame(rig, name)
    p = rig.mesh.vertices[ids]
    if m.kind == "sphincter":
        major = frame.insertion - frame.attachment
        major[2] = 0.0
        if m.side == "C":  # one ellipse about the midline, not tilted toward the corner it names
            major = np.linalg.norm(major) * LATERAL
        minor_dir = np.cross(FORWARD, major)
        minor_dir /= np.linalg.norm(minor_dir)
        rel = p - frame.attachment
        px = rel @ major / (major @ major)
        py = rel @ minor_dir / (m.width_rel * rig.scale)
        rho = np.hypot(px, py)
        fall = np.cos(
            np.clip((rho - m.falloff_start_rel) / (m.falloff_end_rel - m.falloff_start_rel), 0, 1) * np.pi / 2
        )
        fall *= rho < m.falloff_end_rel
        if _on_eyeball(rig, m.origin.face):  # the orbital ring squeezes; the lids close by their bones
            ring = np.clip((rho - 0.2) / 0.6, 0.0, 1.0)
            fall *= ring * ring * (3 - 2 * ring) * 0.6
        in_plane = rel - np.outer(rel @ FORWARD, FORWARD)
        squeeze = -SPHINCTER_STRENGTH * in_plane
        push = PUCKER * np.linalg.norm(squeeze, axis=1, keepdims=True) * FORWARD
        return (squeeze + push) * fall[:, None]
    axis = (frame.insertion - frame.attachment) / frame.length
    rel = p - frame.attachment
    along = rel @ axis  # (k,)
    dist = np.linalg.norm(rel, axis=1)
    lateral = np.linalg.norm(rel - along[:, None] * axis, axis=1)
    width = 2.0 * m.width_rel * rig.scale
    across = np.cos(np.clip(lateral / width, 0.0, 1.0) * np.pi / 2) * (lateral < width)
    sign = 1.0 if m.reversed else -1.0
    if m.kind == "sheet":
        radial = _radial(along / frame.length, m.falloff_start_rel, m.falloff_end_rel) * (along > 0)
        return sign * STRENGTH * frame.length * (radial * across)[:, None] * axis
    mu = np.arccos(np.clip(along / np.maximum(dist, 1e-12), -1.0, 1.0))
    angular = np.cos(np.clip(mu / m.angle_rad, 0.0, 1.0) * np.pi / 2) * (mu < m.angle_rad)
    radial = _radial(dist / frame.length, m.falloff_start_rel, m.falloff_end_rel)
    toward = -rel / np.maximum(dist, 1e-12)[:, None]  # unit, toward the attachment
    return -sign * STRENGTH * frame.length * (angular * radial * across)[:, None] * toward


def vector_deltas(rig: Rig) -> sp.csr_matrix:
    """Displacements (3n, c) per unit of each muscle channel, as a sparse matrix (bones: 0)."""
    skin = np.zeros(rig.n_vertices, dtype=bool)
    skin[deformable_vertices(rig)] = True
    share = muscle_mask(rig)
    rows, cols, vals = [], [], []
    holds = lip_holds(rig)
    for m in rig.muscles:
        gate = lip_gate(rig, m, holds) * share
        ids = np.nonzero(skin & (gate > 0))[0]
        d = muscle_displacement(rig, m.name, ids) * gate[ids, None]
        keep = np.abs(d).max(axis=1) > 0
        ids, d = ids[keep], d[keep]
        rows.append((3 * ids[:, None] + np.arange(3)).ravel())
        cols.append(np.full(d.size, rig.channel_index(m.name)))
        vals.append(d.ravel())
    return sp.csr_matrix(
        (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
        shape=(3 * rig.n_vertices, len(rig.channels)),
    )


class VectorEngine:
    """Waters vector muscles plus the shared deformation chain; prepare once, deform often."""

    name = "vector"

    def __init__(self, rig: Rig, *, skull: bool = True) -> None:
        self.rig = rig
        self.channels = rig.channel_names
        self._deltas = vector_deltas(rig)
        self._columns = self._deltas.tocsc()  # (3n, c): each channel's entries together
        self._limit = SATURATION_REL * rig.scale
        self.chain = Chain(rig, skull=skull)

    def deform(self, values: np.ndarray) -> np.ndarray:
        """Vertex positions (n, 3) for one pose ``values`` (c,) in the rig's channel order."""
        values = check_activations(self.rig, values)
        if values.ndim != 1:
            raise ValueError("deform takes one pose (c,); loop over frames or bake a Basis for clips")
        # deltas @ values over the channels that are not 0 (the same sums in the same order), compiled
        c = self._columns
        d = channel_offsets(c.indptr, c.indices, c.data, values, c.shape[0]).reshape(-1, 3)  # (n, 3)
        length = row_lengths(d)  # (n,) as np.linalg.norm gives it
        moved = np.flatnonzero(length > 0)
        scale = length[moved]
        d[moved] *= (self._limit * np.tanh(scale / self._limit) / scale)[
            :, None
        ]  # soft limit, |d| -> L tanh(|d|/L)
        return self.chain.apply(self.rig.mesh.vertices + d, values)
