"""Muscle forces on the tissue volume, for the physically based engines (``tissue``, ``fem``).

Lee, Terzopoulos and Waters attach each muscle to the fascia nodes within its width and pull them
toward its bony origin, fading with the distance along and across the muscle; Choe, Lee and Ko's
parallel and sphincter muscles do the same on the skin, with the sphincter pulling toward its
centre and pushing the lips forward. The vector engine's Waters fields (``vector.vector_deltas``:
linear, sheet and sphincter zones, the reversed mentalis, the lips' gate and the lids' mask) have
exactly that shape, so they are the force density here: a muscle's force on the fascia node under
skin vertex ``i`` is its Waters motion at ``i`` times the skin area around ``i`` (so the load does
not depend on the mesh's resolution). The forces are computed once on the rest geometry and are
linear in the activations (``K q = F0 + Σ aᵢ Fᵢ``).

For the nonlinear tissue (``per_volume=True``) the field is a force per unit volume instead: times
the tissue column under ``i`` (``tissue_columns``: the skin area around ``i`` times its depth).
Where the volume cut the depth back (the mouth's corners, the inner lip) that tissue is as much
weaker as it is thinner; a load per unit of skin area pulled it out of line with its neighbours and
turned its small triangles over (lip triangles flipped over the expression library: 273 → 155 on
the default head, 1,219 → 825 on ICT). ``fem`` keeps the load per unit area: per volume, its flips
fell on the generated heads (23 → 18) but rose on ICT (2–15 → 8–43).

For the nonlinear tissue (``rollable=True``), where no bone lies behind the tissue (the lips,
``TissueVolume.pinned``) a load's inward component (along the tissue normal) is dropped: a muscle
pulls along the tissue, and over bone its inward push goes into the bone, but a lip, free to turn
in the tissue engine, rolled in over the teeth under it (the platysma's field reaches the lower lip:
58 lip triangles turned over under the platysma alone; over the expression library 169 → 42 on a
4,000-vertex head). Linear elasticity (``fem``) cannot turn a lip, so its loads keep the push.

Their unit (force per unit of the Waters field) is arbitrary; each engine scales each muscle's load
(``MuscleLoads.calibration``) so that the muscle does the same work on the skin as the vector
engine's, unless that would move some skin farther than the vector engine's muscle moves any: then
so that it moves it no farther. Work alone let a compliant spot (a thin lip hanging in front of
the teeth) take all the motion: ICT's pucker pulled its lips into a beak. So the engines stay
interchangeable under one set of control layers, and the tissue decides how the motion spreads.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from mimetic.engines.vector import vector_deltas
from mimetic.engines.volume import TissueVolume
from mimetic.rig.model import Rig


def skin_areas(volume: TissueVolume) -> np.ndarray:
    """Area (k,) around each skin node: a third of the area of its skin triangles, rig units squared."""
    p = volume.nodes[volume.triangles]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    return np.bincount(volume.triangles.ravel(), np.repeat(area / 3.0, 3), minlength=volume.n_skin)


def tissue_columns(volume: TissueVolume) -> np.ndarray:
    """Volume (k,) of the tissue column under each skin node: its ``skin_areas`` times its depth
    (skin to skull), rig units cubed."""
    return skin_areas(volume) * volume.depth


@dataclass(frozen=True, eq=False)
class MuscleLoads:
    """Each channel's forces on the tissue at full activation, and what calibrates them.

    Attributes
    ----------
    forces : (3N, c) scipy.sparse.csc_matrix
        Row ``3 j + axis`` of node ``j`` (layer-major, ``TissueVolume``): forces on the fascia
        nodes only; the columns of channels that are not muscles are empty.
    work : (c,) float64
        ``Σ_j F_j · w_j``: each channel's forces times the Waters motion ``w`` of the skin above them.
    peaks : (c,) float64
        The farthest any skin moves under the channel's Waters field, rig units.
    """

    forces: sp.csc_matrix
    work: np.ndarray
    peaks: np.ndarray

    @property
    def active(self) -> np.ndarray:
        """The channels (a,) with forces: the muscles."""
        return np.flatnonzero(np.diff(self.forces.indptr) > 0)

    def calibration(self, skin_motion: np.ndarray, columns: np.ndarray) -> np.ndarray:
        """Scales (a,) of the forces of channels ``columns`` (a,) (module docstring), given the skin
        nodes' displacement (k, 3, a) under each one's unscaled forces: ``work / Σ_j F_j · u_j``, at
        most ``peaks / max_j |u_j|``; 0 where a channel moves nothing."""
        k = skin_motion.shape[0]
        force = self.forces[3 * k : 6 * k][:, columns].toarray().reshape(k, 3, -1)  # under each skin node
        done = np.einsum("kic,kic->c", force, skin_motion)
        farthest = np.linalg.norm(skin_motion, axis=1).max(axis=0)
        moves = (np.abs(done) > 1e-300) & (farthest > 0)
        by_work = np.divide(self.work[columns], done, out=np.zeros(len(columns)), where=moves)
        by_peak = np.divide(self.peaks[columns], farthest, out=np.zeros(len(columns)), where=moves)
        return np.minimum(by_work, by_peak)


def muscle_loads(
    rig: Rig, volume: TissueVolume, *, rollable: bool = False, per_volume: bool = False
) -> MuscleLoads:
    """Each channel's forces on the fascia of ``volume`` at full activation (``MuscleLoads``);
    ``rollable``: the tissue can turn a lip (module docstring), so no load pushes into one;
    ``per_volume``: the Waters field is a force per unit volume of tissue, not of skin area."""
    deltas = vector_deltas(rig).tocsr()  # (3n, c) on rig vertices, row 3 i + axis
    c = len(rig.channels)
    k = volume.n_skin
    sampling = volume.sampling()  # (k, n): the skin nodes' vertices, or where a proxy's nodes lie
    waters = np.stack([(sampling @ deltas[axis::3]).toarray() for axis in range(3)], axis=1)  # (k, 3, c)
    field = waters * (tissue_columns(volume) if per_volume else skin_areas(volume))[:, None, None]
    if rollable:
        hanging = ~volume.pinned[2 * k :]  # (k,) no bone behind: the lips (and the rims cut back)
        normal = volume.normals[hanging]  # (h, 3) outward
        inward = np.minimum(np.einsum("hic,hi->hc", field[hanging], normal), 0.0)  # (h, c)
        field[hanging] -= inward[:, None, :] * normal[:, :, None]  # no bone there to take the push
    rows = (3 * (k + np.arange(k))[:, None] + np.arange(3)).ravel()  # the fascia node under each
    dense = field.reshape(3 * k, c)
    keep = np.flatnonzero(np.abs(dense).max(axis=1) > 0)
    forces = sp.csc_matrix(
        (dense[keep].ravel(), (np.repeat(rows[keep], c), np.tile(np.arange(c), len(keep)))),
        shape=(3 * volume.n_nodes, c),
    )
    forces.eliminate_zeros()
    work = np.einsum("kic,kic->c", field, waters)
    return MuscleLoads(forces, work, np.linalg.norm(waters, axis=1).max(axis=0))
