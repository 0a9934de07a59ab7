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
on one patch are damped and skin never tears away. Muscles whose insertion is on one lip leave
the other lip alone. The shared chain (skull, creases, skinning, sculptors) follows.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from mimetic.engines.common import Chain, deformable_vertices, lip_mask, muscle_frame, muscle_mask
from mimetic.rig.activations import check_activations
from mimetic.rig.model import Rig

STRENGTH = 0.22  # K: linear and sheet motion at full activation, fraction of muscle length
SPHINCTER_STRENGTH = 0.35  # K_s: fraction of the distance to the centre at full activation
PUCKER = 0.6  # forward push of squeezed tissue, relative to its motion toward the centre
SATURATION_REL = 0.1  # per-vertex displacement soft limit, fraction of the head height
FORWARD = np.array([0.0, 0.0, 1.0])


def _radial(x: np.ndarray, start: float, end: float) -> np.ndarray:
    """Waters' radial falloff over a distance fraction x: rises to 1 at ``start``, 0 at ``end``."""
    rise = np.sin(np.clip(x / start, 0.0, 1.0) * np.pi / 2)
    fall = np.cos(np.clip((x - start) / (end - start), 0.0, 1.0) * np.pi / 2)
    return np.where(x < start, rise, fall) * (x < end)


def _on_eyeball(rig: Rig, face: int) -> bool:
    parts = rig.mesh.parts
    return any(face in parts[p] for p in ("eye_L", "eye_R") if p in parts)


def muscle_displacement(rig: Rig, name: str, ids: np.ndarray) -> np.ndarray:
    """Displacement (k, 3) of rest vertices ``ids`` (k,) for one unit of muscle ``name``."""
    m = rig.muscle(name)
    frame = muscle_frame(rig, name)
    p = rig.mesh.vertices[ids]
    if m.kind == "sphincter":
        major = frame.insertion - frame.attachment
        major[2] = 0.0
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
    for m in rig.muscles:
        ids = np.nonzero(skin & lip_mask(rig, m.insertion) & (share > 0))[0]
        d = muscle_displacement(rig, m.name, ids) * share[ids, None]
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

    def __init__(self, rig: Rig, *, skull: bool = True, creases: bool = True) -> None:
        self.rig = rig
        self.channels = rig.channel_names
        self._deltas = vector_deltas(rig)
        self._limit = SATURATION_REL * rig.scale
        self.chain = Chain(rig, skull=skull, creases=creases)

    def deform(self, values: np.ndarray) -> np.ndarray:
        """Vertex positions (n, 3) for one pose ``values`` (c,) in the rig's channel order."""
        values = check_activations(self.rig, values)
        if values.ndim != 1:
            raise ValueError("deform takes one pose (c,); loop over frames or bake a Basis for clips")
        d = (self._deltas @ values).reshape(-1, 3)  # (n, 3), summed on the rest skin
        length = np.linalg.norm(d, axis=1, keepdims=True)
        safe = np.where(length > 0, length, 1.0)
        d *= np.where(length > 0, self._limit * np.tanh(length / self._limit) / safe, 0.0)
        return self.chain.apply(self.rig.mesh.vertices + d, values)
