"""Muscle forces on the tissue volume, for the physically based engines (``tissue``, ``fem``).

Lee, Terzopoulos and Waters attach each muscle to the fascia nodes within its width and pull them
toward its bony origin, fading with the distance along and across the muscle; Choe, Lee and Ko's
parallel and sphincter muscles do the same on the skin, with the sphincter pulling toward its
centre and pushing the lips forward. The vector engine's Waters fields (``vector.vector_deltas``:
linear, sheet and sphincter zones, the reversed mentalis, the lips' gate and the lids' mask) have
exactly that shape, so they are the force density here: a muscle's force on the fascia node under
skin vertex ``i`` is its Waters motion at ``i`` times the skin area around ``i`` (so the load does
not depend on the mesh's resolution). The forces are computed once on the rest geometry and are
linear in the activations (``K q = F0 + Σ aᵢ Fᵢ``). Their unit (force per unit of the Waters
field) is arbitrary: each engine scales each muscle's load so that it does the same work on the
skin as the vector engine's muscle (``calibration``), which keeps the engines interchangeable under
one set of control layers.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from mimetic.engines.vector import vector_deltas
from mimetic.engines.volume import TissueVolume
from mimetic.rig.model import Rig


def skin_areas(volume: TissueVolume) -> np.ndarray:
    """Area (k,) around each skin node: a third of the area of its skin triangles, rig units squared."""
    tets = volume.tets[volume.tet_layer == 0]
    k = volume.n_skin
    top = tets[(tets < k).sum(axis=1) == 3][:, :3]  # the tetrahedron holding each skin triangle
    p = volume.nodes[top]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    return np.bincount(top.ravel(), np.repeat(area / 3.0, 3), minlength=k)


def muscle_loads(rig: Rig, volume: TissueVolume) -> tuple[sp.csc_matrix, np.ndarray]:
    """Nodal forces (3N, c) per unit activation of each channel, and the work each does in the vector
    engine.

    Returns
    -------
    loads : (3N, c) scipy.sparse.csc_matrix
        Row ``3 j + axis`` of node ``j`` (layer-major, ``TissueVolume``): forces on the fascia nodes
        only; columns of non-muscle channels are empty.
    work : (c,) float64
        ``Σ_j F_j · w_j``: each channel's load times the Waters motion ``w`` of the skin node above it
        (0 for non-muscle channels). An engine whose skin moves ``u`` under the load calibrates the
        muscle by ``work / Σ_j F_j · u_j`` (``calibration``), so the muscle does the same work on
        the skin as in the vector engine: where the tissue spreads the motion, it moves less at the
        insertion, as a physical muscle of the same strength would.
    """
    deltas = vector_deltas(rig).tocsc()  # (3n, c) on rig vertices
    n, c = rig.n_vertices, len(rig.channels)
    motion = deltas.toarray().reshape(n, 3, c)
    k = volume.n_skin
    waters = motion[volume.surface]  # (k, 3, c) at the skin nodes
    field = waters * skin_areas(volume)[:, None, None]
    work = np.einsum("kic,kic->c", field, waters)
    rows = (3 * (k + np.arange(k))[:, None] + np.arange(3)).ravel()  # the fascia node under each
    dense = field.reshape(3 * k, c)
    keep = np.flatnonzero(np.abs(dense).max(axis=1) > 0)
    loads = sp.csc_matrix(
        (dense[keep].ravel(), (np.repeat(rows[keep], c), np.tile(np.arange(c), len(keep)))),
        shape=(3 * volume.n_nodes, c),
    )
    loads.eliminate_zeros()
    return loads, work


def calibration(loads: sp.csc_matrix, work: np.ndarray, skin_motion: np.ndarray) -> np.ndarray:
    """Scale (c,) of each channel's load so that it does ``work`` (c,) on the skin (``muscle_loads``).

    ``skin_motion`` (k, 3, c): the skin nodes' displacement under each unscaled load (the first k
    nodes carry the rows ``3 j + axis`` of the fascia node under skin node ``j``). 0 where a channel
    has no load or moves nothing.
    """
    k = skin_motion.shape[0]
    force = loads[3 * k : 6 * k].toarray().reshape(k, 3, -1)  # the fascia forces, under each skin node
    done = np.einsum("kic,kic->c", force, skin_motion)
    return np.divide(work, done, out=np.zeros_like(work), where=np.abs(done) > 1e-300)
