"""The ``fem`` engine: linear finite-element skin with a muscle actuation basis (Choe, Lee & Ko 2001).

Static linear elasticity on the layered tissue volume (``engines.volume``) with the skull nodes
pinned: ``K q = F0 + Σ aᵢ Fᵢ``. ``F0 = K q_init`` holds the neutral, so in displacements
``K u = Σ aᵢ Fᵢ``: one sparse factorisation of ``K`` and one solve per muscle give each muscle's
displacement field ``uᵢ``, and any expression is ``Σ aᵢ uᵢ`` (the paper's Eq. 9). The forces ``Fᵢ``
are the muscles' loads on the fascia (``engines.loads``), each scaled so that the muscle does the
vector engine's work on the skin without moving any skin farther than the vector engine's muscle
does. Skin the eyelid bones hold follows the lids only (``muscles.muscle_mask``), and the shared
chain (skull, creases and tissue actions, jaw and lids as bones, lid contact, accessories) runs
after the tissue, as in every engine.

Kernel: linear tetrahedra with the element stiffness blocks
``K_ab = V (λ g_a g_bᵀ + μ g_b g_aᵀ + μ (g_a · g_b) I)`` for the shape-function gradients ``g`` and
the Lamé parameters of Young's modulus ``E`` and Poisson's ratio ``ν``. Each prism is counted in all
six of its three-tetrahedron splits (each a sixth of the stiffness), so the stiffness does not
depend on how the vertices are numbered and a mirror-symmetric head deforms mirror-symmetrically.
A weak nodal restoration (Lee et al.'s ``h``) ties every node to its rest place, so a piece of
tissue with no pinned node (a floating part of a scan) still has a unique solution; the lips' deep
nodes, which no bone holds, hang on springs to the gums (``LIP_ANCHOR``).

Choices the paper leaves open: ``E`` relative (only the ratio between layers matters, since each
muscle's amplitude is calibrated): the dermal-fatty layer 1, the muscle layer ``MUSCLE_LAYER_E``
(softer, so the fascia slides over the bone); ``ν = POISSON`` (soft tissue is nearly
incompressible; linear tetrahedra lock closer to 0.5); the jaw as a bone rather than a linearised
force field (a jaw opens far beyond where a linear rotation holds).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from mimetic.engines.chain import Chain
from mimetic.engines.cholesky import NestedLU, nested_lu
from mimetic.engines.loads import muscle_loads
from mimetic.engines.muscles import muscle_mask
from mimetic.engines.volume import SPLIT_COUNTS, SPLITS, TissueVolume, build_volume, tet_volumes
from mimetic.rig.activations import check_activations
from mimetic.rig.model import Rig

POISSON = 0.45
"""Poisson's ratio of the tissue."""
MUSCLE_LAYER_E = 0.5
"""Young's modulus of the muscle layer (fascia to skull) relative to the dermal-fatty layer's."""
LIP_ANCHOR = 0.3
"""Stiffness of the springs that hold the lips' deep nodes to the gums, relative to the tissue's over
its own depth (the lips have no bone behind them, but they do not hang free)."""
CHUNK = 20_000
"""Prisms assembled at a time (bounds the memory of ``prism_blocks``)."""
RESTORATION = 1e-4
"""Nodal restoration stiffness relative to the tissue's stiffness over one head height."""


def tet_gradients(nodes: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shape-function gradients (t, 4, 3) and unsigned volumes (t,) of tetrahedra ``tets`` (t, 4) over
    ``nodes`` (N, 3); a tetrahedron's four gradients sum to 0."""
    p = nodes[tets]
    edges = np.transpose(p[:, 1:] - p[:, :1], (0, 2, 1))  # (t, 3, 3): columns x_b - x_0
    inverse = np.linalg.inv(edges)  # rows: gradients of the shape functions of nodes 1..3
    gradients = np.concatenate([-inverse.sum(axis=1, keepdims=True), inverse], axis=1)
    return gradients, np.abs(tet_volumes(nodes, tets))


def isotropic_blocks(moments: np.ndarray, young: np.ndarray, poisson: float) -> np.ndarray:
    """Linear-elastic stiffness blocks (e, k, k, 3, 3) from the gradient moments ``moments``
    (e, k, k, 3, 3), ``[a, b, i, j] = Σ V g_a,i g_b,j`` over an element's tetrahedra, and Young's moduli
    ``young`` (e,): ``[a, b]`` is the 3×3 block coupling node ``a``'s force to node ``b``'s
    displacement, ``λ Σ V g_a g_bᵀ + μ Σ V g_b g_aᵀ + μ Σ V (g_a · g_b) I``."""
    lam = (young * poisson / ((1 + poisson) * (1 - 2 * poisson)))[:, None, None, None, None]
    mu = (young / (2 * (1 + poisson)))[:, None, None, None, None]
    blocks = lam * moments + mu * np.swapaxes(moments, 3, 4)
    blocks += mu * np.trace(moments, axis1=3, axis2=4)[..., None, None] * np.eye(3)
    return blocks


def tet_blocks(nodes: np.ndarray, tets: np.ndarray, young: np.ndarray, poisson: float) -> np.ndarray:
    """Stiffness blocks (t, 4, 4, 3, 3) of tetrahedra ``tets`` (t, 4) with Young's moduli ``young`` (t,)
    (``isotropic_blocks``)."""
    g, volume = tet_gradients(nodes, tets)
    moments = volume[:, None, None, None, None] * np.einsum("tai,tbj->tabij", g, g)
    return isotropic_blocks(moments, young, poisson)


def prism_blocks(nodes: np.ndarray, prisms: np.ndarray, young: np.ndarray, poisson: float) -> np.ndarray:
    """Stiffness blocks (p, 6, 6, 3, 3) of prisms ``prisms`` (p, 6: top triangle, then the nodes under
    it) with moduli ``young`` (p,): the mean over the prism's six splits into tetrahedra, so it does not
    depend on the order of its nodes. The twelve distinct tetrahedra's gradients are spread over the
    prism's six nodes, so the moments are one batched product per chunk."""
    out = np.empty((len(prisms), 6, 6, 3, 3))
    for start in range(0, len(prisms), CHUNK):
        part = prisms[start : start + CHUNK]
        spread = np.zeros((len(part), len(SPLITS), 6, 3))  # [p, tet, prism node, axis]
        weights = np.empty((len(part), len(SPLITS)))
        for k, (tet, count) in enumerate(zip(SPLITS, SPLIT_COUNTS, strict=True)):
            spread[:, k, tet], volume = tet_gradients(nodes, part[:, tet])
            weights[:, k] = volume * (count / 6.0)
        flat = spread.reshape(len(part), len(SPLITS), 18)
        moments = np.matmul(np.swapaxes(flat * weights[..., None], 1, 2), flat)  # (p, 18, 18)
        moments = moments.reshape(-1, 6, 3, 6, 3).transpose(0, 1, 3, 2, 4)
        out[start : start + CHUNK] = isotropic_blocks(moments, young[start : start + CHUNK], poisson)
    return out


def assemble(blocks: np.ndarray, elements: np.ndarray, n_nodes: int) -> sp.csr_matrix:
    """The global matrix (3N, 3N) of element blocks (e, k, k, 3, 3) over node indices ``elements`` (e, k);
    row and column ``3 j + axis`` belong to node ``j``."""
    keys = (elements[:, :, None] * n_nodes + elements[:, None, :]).ravel()  # (e k k,) node pairs
    pairs, where = np.unique(keys, return_inverse=True)
    summed = np.stack(
        [np.bincount(where, blocks[..., i, j].ravel(), len(pairs)) for i in range(3) for j in range(3)],
        axis=1,
    ).reshape(-1, 3, 3)
    rows, cols = pairs // n_nodes, pairs % n_nodes
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=n_nodes))])
    return sp.bsr_matrix((summed, cols, indptr), shape=(3 * n_nodes, 3 * n_nodes)).tocsr()


def stiffness_matrix(volume: TissueVolume, young: tuple[float, float], poisson: float) -> sp.csr_matrix:
    """Linear-elastic stiffness (3N, 3N) of ``volume``'s prisms, Young's modulus ``young`` per layer
    (dermal-fatty, muscle). Symmetric positive semi-definite; its null space is the rigid motions of
    each connected piece."""
    prisms = volume.prisms
    moduli = np.repeat(np.asarray(young, dtype=np.float64), len(volume.triangles))
    return assemble(prism_blocks(volume.nodes, prisms, moduli, poisson), prisms, volume.n_nodes)


@dataclass(frozen=True, eq=False)
class FemSolver:
    """A factorised stiffness with the pinned nodes removed: ``solve(F) -> u``.

    Attributes
    ----------
    K : (3N, 3N) scipy.sparse.csr_matrix
        The full stiffness (with the nodal restoration), rig units.
    free : (f,) int64
        The degrees of freedom solved for (those of the nodes not pinned).
    """

    K: sp.csr_matrix
    free: np.ndarray
    _factor: NestedLU

    def solve(self, forces: np.ndarray) -> np.ndarray:
        """Displacements (3N,) or (3N, c) for nodal forces ``forces`` (3N,) or (3N, c); pinned: 0."""
        forces = np.asarray(forces, dtype=np.float64)
        u = np.zeros_like(forces)
        u[self.free] = self._factor.solve(forces[self.free])
        return u


def prepare_fem(
    volume: TissueVolume, *, muscle_layer_e: float = MUSCLE_LAYER_E, poisson: float = POISSON
) -> FemSolver:
    """Assemble and factorise the stiffness of ``volume`` (module docstring) once."""
    K = stiffness_matrix(volume, (1.0, muscle_layer_e), poisson)
    extent = float(np.ptp(volume.nodes, axis=0).max())
    nodal = volume.nodal_volumes
    spring = RESTORATION * nodal / extent**2
    k = volume.n_skin
    hanging = np.flatnonzero(~volume.pinned[2 * k :])  # skull nodes under the lips: on the gums
    spring[2 * k + hanging] += LIP_ANCHOR * nodal[2 * k + hanging] / volume.depth[hanging] ** 2
    K = (K + sp.diags(np.repeat(spring, 3))).tocsr()
    free = np.flatnonzero(np.repeat(~volume.pinned, 3))
    return FemSolver(K, free, nested_lu(K[free][:, free]))


def fem_deltas(rig: Rig, volume: TissueVolume, solver: FemSolver) -> np.ndarray:
    """Skin displacements (c, n, 3) per unit of each channel (muscles; 0 for the others), rig units.

    Each muscle's field is its solve ``K u = F`` on the skin nodes, scaled as ``MuscleLoads.calibration``
    says, times ``muscle_mask`` (the lids follow their bones).
    """
    loads = muscle_loads(rig, volume)
    active = loads.active
    u = solver.solve(loads.forces[:, active].toarray())  # (3N, a)
    skin = u[: 3 * volume.n_skin].reshape(volume.n_skin, 3, len(active))
    skin *= loads.calibration(skin, active)[None, None, :]
    motion = volume.to_vertices(skin) * muscle_mask(rig)[:, None, None]  # (n, 3, a)
    deltas = np.zeros((len(rig.channels), rig.n_vertices, 3))
    deltas[active] = np.transpose(motion, (2, 0, 1))
    return deltas


class FemEngine:
    """Linear FEM skin (a precomputed per-muscle basis) plus the shared chain; prepare once.

    Options: ``skull`` (the chain's, as every engine) and ``proxy`` (``engines.volume.proxy_size``:
    "auto", "off" or a skin vertex count), the skin the tissue volume lies under.
    """

    name = "fem"

    def __init__(self, rig: Rig, *, skull: bool = True, proxy: int | str = "auto", progress=None) -> None:
        report = progress or (lambda done, total: None)  # (done, total) of the 3 stages below
        self.rig = rig
        self.channels = rig.channel_names
        report(0, 3)
        self.volume = build_volume(rig, proxy=proxy)
        report(1, 3)
        self.solver = prepare_fem(self.volume)
        report(2, 3)
        self.deltas = fem_deltas(rig, self.volume, self.solver)  # (c, n, 3)
        self._flat = self.deltas.reshape(len(self.channels), -1).T  # (3n, c)
        self.chain = Chain(rig, skull=skull)
        report(3, 3)

    def deform(self, values: np.ndarray) -> np.ndarray:
        """Vertex positions (n, 3) for one pose ``values`` (c,) in the rig's channel order."""
        values = check_activations(self.rig, values)
        if values.ndim != 1:
            raise ValueError("deform takes one pose (c,); loop over frames or bake a Basis for clips")
        moved = self.rig.mesh.vertices + (self._flat @ values).reshape(-1, 3)
        return self.chain.apply(moved, values)
