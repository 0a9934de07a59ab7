"""The ``tissue`` engine: layered mass-spring tissue (Lee, Terzopoulos & Waters 1995), projective dynamics.

The tissue volume under the skin (``engines.volume``: skin, fascia and skull nodes; two prisms per
skin triangle, the dermal-fatty layer and the muscle layer) becomes a mass-spring body whose fascia
the muscles pull (``engines.loads``). The physics gives the muscle-driven skin in the rest frame of
the head; the shared chain (skull, creases and tissue actions, jaw and lids as bones, lid contact,
accessories) runs afterwards, as in every engine.

Model (Lee et al. §3; values are module constants):

* **Springs**: the edges of every prism (its triangles, its vertical edges and both diagonals of
  each quad, so the springs do not depend on how the volume split the prisms and a mirror-symmetric
  head stays symmetric), in four classes by the layers of their ends: epidermal (skin-skin),
  dermal-fatty (skin-fascia), fascia (fascia-fascia) and muscle layer (fascia-skull, skull-skull).
  A spring's stiffness is ``E V / l₀²`` for its class's Young's modulus ``E``, its share ``V`` of
  the volume of the prisms it belongs to (a fifteenth of each) and its rest length ``l₀``: the
  energy density of a uniform strain is then ``E ε²/2`` whatever the mesh's resolution.
* **Biphasic** dermal-fatty springs (Terzopoulos & Waters 1990): a second spring,
  ``BIPHASIC_RATIO - 1`` times as stiff, takes up any length beyond ``1 ± BIPHASIC_STRAIN`` of the
  rest length: soft at first, then stiff, stretched or compressed.
* **Shape and volume** per prism (the paper's ``k2`` and ``k1`` terms): ``F = xᵀ G``, the prism's
  least-squares deformation gradient over its six nodes, is held near its rotation ``R`` (the rest
  shape, turned as the prism turned: ``SHAPE_STIFFNESS``) and near determinant 1 (its rest volume:
  ``VOLUME_STIFFNESS``, off with ``preserve_volume=False``), both times the layer's modulus and the
  prism's volume. The shape term is what a spring network lacks: shear stiffness in the needle-thin
  prisms at the mouth's corners, where springs alone let nodes swing freely. An inverted prism is
  turned back (its nearest proper rotation, by SVD).
* **Skin bending** (ours; the paper's skin is a spring mesh): the skin surface resists bending as a
  plate of the epidermal modulus ``BENDING_THICKNESS_REL`` of the head thick,
  ``w_i/2 |δ_i(x - X)|²`` per skin node for the uniform Laplacian ``δ_i`` of the displacement (the
  mean of its neighbours' minus its own). A spring mesh folds along an edge at no cost, and a
  prism's shape term sees only its mean gradient, not its top triangle: over the thin tissue of
  the inner lip and the mouth's corners (cut back to a fifth of the thickness, on loose skull
  nodes) the skin creased into tiny folds and turned over (lip triangles flipped over the
  expression library: 763 → 58 on ICT-FaceKit), the corners tore and the upper lip everted in a
  smile. Linear in the displacement, so it joins the prefactored global matrix (a little more
  fill) and adds one sparse product per iteration; the physics runs in the head's rest frame,
  where the skin turns by tens of degrees at most (the jaw and lids are bones, applied after it).
* **Skull contact** (§3.7): each fascia node over a pinned skull node stays on the outer side of
  the plane through its skull node across its normal, ``SKULL_GAP`` of its rest height above it,
  and slides along it freely. The skull nodes the volume leaves loose (under the lips: no bone)
  rest on the teeth and gums the same way (they may not sink below their rest place) and are tied
  to it by ``LOOSE_ANCHOR``: without the teeth a lip rolled into the mouth under the platysma, and
  without the tie the lips drifted. Contact is a stiff constraint (``SKULL_WEIGHT``): during a
  simulation a node may sink a little under a strong push; ``equilibrium`` puts any node left
  below its plane onto it (doing so after every time step as well pumped energy into the lips).
* **Nodal restoration** ``h`` (§3.8): a zero-length spring to rest on every node, so weak that a
  node alone on it would swing at ``RESTORATION_HZ`` (it only makes a floating piece well posed).
* **Bone**: the volume's pinned skull nodes are fixed.
* **Muscles**: ``loads @ activations`` as nodal forces on the fascia, per unit volume of tissue
  (``engines.loads``: thin tissue is pulled no harder than it can follow). Each muscle's load is scaled
  once (``MuscleLoads.calibration``) from its response in the linearised tissue at rest
  (``rest_stiffness``; one solve per muscle), so that it does the vector engine's work on the skin,
  or moves no skin farther than the vector engine's muscle does.
* **Mass and damping**: lumped masses from ``DENSITY`` and the prisms' volumes; mass-proportional
  damping ``DAMPING_PER_S``. The head is ``HEAD_HEIGHT_M`` tall (``Rig.scale`` is its height in rig
  units), so stiffness (Pa) and mass (kg) give real time scales: after a step in activation the skin
  overshoots and settles within about 0.2 s.

Solver: projective dynamics (Liu et al. 2013, Bouaziz et al. 2014). Every term above is a
constraint ``w/2 |A x - p|²`` with a linear ``A`` shared by x, y and z, and ``p`` the projection of
``A x`` onto the constraint. Alternating the local step (all projections, compiled in
``engines.projections``) with the global step (one solve of the constant ``Aᵀ W A + diag(h) [+ c M]``,
prefactored once by ``engines.cholesky``, 3 right-hand sides) lowers the energy at every iteration;
Anderson acceleration (Peng et al. 2018) mixes the last ``ANDERSON_DEPTH`` iterates, kept only when
it lowers the energy too. The kernel works in SI units: positions in metres, forces in newtons,
energy in joules.

* ``equilibrium``: the static equilibrium (no inertia), to ``TOLERANCE_M`` (at most
  ``STATIC_ITERATIONS``), from the linearised solution: ``TissueEngine.deform``.
* ``step``: one implicit BDF2 time step (second order; it damps far less than backward Euler, so
  the skin's follow-through survives), at most ``DYNAMIC_ITERATIONS``: ``TissueEngine.simulate``
  divides each frame into steps of at most ``STEP_MAX_S``.

Over 600 lines because the model, its compiled local step and the solver share the model's arrays
and were tuned together.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numba
import numpy as np
import scipy.sparse as sp
from threadpoolctl import ThreadpoolController

from mimetic.engines.chain import Chain
from mimetic.engines.cholesky import Cholesky, cholesky, nested_lu
from mimetic.engines.loads import muscle_loads
from mimetic.engines.muscles import muscle_mask
from mimetic.engines.projections import gathered_targets, prism_targets, spring_targets
from mimetic.engines.skinning import bone_transforms, linear_blend_skinning
from mimetic.engines.volume import TissueVolume, build_volume, triple_products
from mimetic.errors import ActivationError, MimeticWarning
from mimetic.mesh.geometry import vertex_adjacency
from mimetic.rig.activations import check_activations
from mimetic.rig.model import Rig

log = logging.getLogger(__name__)

HEAD_HEIGHT_M = 0.23
"""The physics treats the rig's head height (``Rig.scale``) as this many metres."""
DENSITY = 1000.0
"""Mass density of the tissue, kg/m³."""
EPIDERMAL_E = 4000.0
"""Young's modulus (Pa) of the epidermal springs (skin to skin): the skin is stiffer than the fat."""
DERMAL_E = 1000.0
"""Young's modulus (Pa) of the dermal-fatty springs (skin to fascia), their soft phase."""
FASCIA_E = 2000.0
"""Young's modulus (Pa) of the fascia springs (fascia to fascia)."""
MUSCLE_LAYER_E = 500.0
"""Young's modulus (Pa) of the muscle-layer springs (fascia to skull, skull to skull): the loose
layer the fascia slides on."""
BIPHASIC_STRAIN = 0.2
"""Strain beyond which a dermal-fatty spring stiffens (stretched or compressed)."""
BIPHASIC_RATIO = 5.0
"""A dermal-fatty spring's stiffness beyond ``BIPHASIC_STRAIN`` over its stiffness within it."""
BENDING_THICKNESS_REL = 0.025
"""The skin bends as a plate of the epidermal springs' modulus ``EPIDERMAL_E`` and this many head
heights thick (5.8 mm on the physics' 23 cm head, about the tissue's median depth): bending
stiffness ``D = E t³/12``. Chosen on ICT-FaceKit's neutral (automatic landmarks) and the default
generated head (checked on ICT's landmark-file rig, an identity at σ 1 and σ 2, a random generated
head): about 0.01 (a tenth of the bending) left 50 of the 314 lip triangles four expressions
turned over on ICT (joy, weeping, pucker, sadness; 45 at this value); about 0.05 (ten times)
smoothed the lips further but flattened the generated head's pucker."""
SHAPE_STIFFNESS = 3.0
"""Weight of a prism's shape term over its layer's modulus (dermal-fatty or muscle layer) times
its volume."""
VOLUME_STIFFNESS = 2.0
"""Weight of a prism's volume term over its layer's modulus times its volume."""
RESTORATION_HZ = 0.5
"""Nodal restoration: a node alone on its zero-length spring to rest would swing at this frequency."""
LOOSE_ANCHOR = 1.0
"""A skull node the volume leaves loose (under the lips) is tied to its rest place by this × its
elastic weight (its diagonal of ``Aᵀ W A``): the lips' inner side is bound to the gums by their
lining, so the lips hang and roll but do not drift. At 0.1 the thin, loose tissue at the mouth's
corners took the motion of several muscles pulling at once (``weeping``: the triangularis and the
platysma dragged the lower lip's upper face round the corner until it faced the midline): 33 lip
triangles of ICT-FaceKit's ``weeping`` turned over, 6 at 1.0 (12 at 0.3); the default generated
head's flips do not change (110 → 111 over the library)."""
SKULL_GAP = 0.25
"""A fascia node stays at least this fraction of its rest height above its skull node."""
SKULL_WEIGHT = 1.0
"""Weight of the skull contact over the node's own elastic weight (its diagonal of ``Aᵀ W A``)."""
DAMPING_PER_S = 30.0
"""Mass-proportional damping γ, 1/s: a node's velocity, left alone, decays as ``exp(-γ t)``."""
STEP_MAX_S = 1.0 / 24.0
"""The longest time step; ``simulate`` divides each frame into as many equal steps as needed."""
TOLERANCE_M = 1e-5
"""An iteration has converged when no node moved more than this (metres: 0.004 % of the head) in
its global step."""
STATIC_ITERATIONS = 60
"""Most local/global iterations of an equilibrium."""
DYNAMIC_ITERATIONS = 3
"""Local/global iterations of a time step, at most (from the inertial prediction; the last solve's
result is taken as it is). Fewer than converge, as real-time projective dynamics does: on a 10k-node
head a continuous smile at 30 fps then differs from 8 iterations per step by 0.004 cm rms (0.07 cm
at most; 4 iterations: 0.002 and 0.03 cm), and after a step in activation the skin reaches 93 % of
its new rest in one frame (8 iterations: 97 %), overshoots by 1 % and settles. A fourth iteration
costs a quarter more time per frame."""
BLAS = ThreadpoolController()
"""The BLAS libraries loaded with numpy and scipy, whose threads ``_iterate`` and ``simulate`` hold
to one."""
ANDERSON_DEPTH = 5
"""Previous iterates that Anderson acceleration mixes."""
SPRING_PAIRS = np.array(
    [
        *[(0, 1), (1, 2), (2, 0), (3, 4), (4, 5), (5, 3)],  # the triangles
        *[(0, 3), (1, 4), (2, 5)],  # vertical
        *[(0, 4), (1, 3), (1, 5), (2, 4), (2, 3), (0, 5)],  # the quads' diagonals
    ]
)
"""The springs of a prism (top 0-2, bottom 3-5, node ``i + 3`` under node ``i``): its triangles'
edges, its vertical edges and both diagonals of each quad."""


# --------------------------------------------------------------------------- the model


@dataclass(frozen=True, eq=False)
class TissueModel:
    """The layered tissue of a ``TissueVolume``, prepared for projective dynamics (SI units).

    The energy is ``Σ_r w_r/2 |A_r x - p_r(x)|² + Σ_i h_i/2 |x_i - X_i|² + ½ tr((x - X)ᵀ B (x - X))``
    (``B`` the skin's ``bending``): each row ``A_r`` of the
    sparse ``A`` (R, N) maps the node positions ``x`` (N, 3) to a 3-vector (a spring's edge, a
    column of a prism's deformation gradient, a contact node's position), ``p_r`` projects it onto
    its constraint, and ``w`` (R,) are the ``weights``. The rows come in three blocks (``blocks``):
    springs (E), prisms (3 each), skull contact (S).

    Attributes
    ----------
    rest : (N, 3) float64
        Rest positions, metres (the volume's nodes × ``metres_per_unit``).
    mass : (N,) float64
        Lumped nodal masses, kg.
    pinned : (N,) bool
        Nodes fixed to the bone; ``free`` (f,) int64 are the others, the unknowns.
    edges : (E, 2) int64
        Spring end nodes; ``rest_lengths`` (E,) m; ``stiffness`` (E,) N/m; ``stiff_phase`` (E,) N/m,
        the biphasic springs' extra stiffness beyond ``strain_limit`` (0 for the others); ``layer``
        (E,) int64: 0 epidermal, 1 dermal-fatty, 2 fascia, 3 muscle layer.
    prisms : (P, 6) int64
        Nodes of each prism (a skin triangle's column in one layer; top 0-2, bottom 3-5);
        ``prism_layer`` (P,) 0 dermal-fatty, 1 muscle layer; ``gradients`` (P, 6, 3) 1/m: the
        prism's deformation gradient is ``F = xᵀ G`` for its nodes' positions ``x`` (6, 3);
        ``shape_stiffness`` (P,) J, the weight of ``|F - R|²``; ``volume_stiffness`` (P,) J, of
        ``|F - V|²`` (V the nearest matrix of determinant 1; zeros without volume preservation).
    restoration : (N,) float64
        Zero-length spring to rest on each node, N/m.
    bending : (N, N) scipy.sparse.csr_matrix
        The skin's bending stiffness ``Lᵀ diag(w) L`` (N/m; ``skin_bending``), on the skin nodes only;
        its rows sum to 0 (a translation does not bend).
    contact : (S,) int64
        Nodes kept on the outer side of a plane: the fascia over pinned skull nodes, then the loose
        skull nodes (on the teeth). ``contact_anchor`` (S, 3) m, a point of the plane (the skull
        node under the fascia node; the loose node's rest place), ``contact_normal`` (S, 3)
        outward, ``contact_gap`` (S,) m the least height over the anchor, ``contact_stiffness``
        (S,) N/m.
    damping : float
        Mass-proportional damping, 1/s.
    metres_per_unit : float
        Metres per rig unit.
    """

    rest: np.ndarray
    mass: np.ndarray
    pinned: np.ndarray
    free: np.ndarray
    edges: np.ndarray
    rest_lengths: np.ndarray
    stiffness: np.ndarray
    stiff_phase: np.ndarray
    layer: np.ndarray
    prisms: np.ndarray
    prism_layer: np.ndarray
    gradients: np.ndarray
    shape_stiffness: np.ndarray
    volume_stiffness: np.ndarray
    restoration: np.ndarray
    bending: sp.csr_matrix
    contact: np.ndarray
    contact_anchor: np.ndarray
    contact_normal: np.ndarray
    contact_gap: np.ndarray
    contact_stiffness: np.ndarray
    strain_limit: float
    damping: float
    metres_per_unit: float
    A: sp.csr_matrix = field(repr=False)
    weights: np.ndarray = field(repr=False)
    _pinned_pull: np.ndarray = field(repr=False)  # (f, 3) A[:, free]ᵀ W A[:, pinned] rest[pinned]
    _bending_free: sp.csr_matrix = field(repr=False)  # (f, f) B[free][:, free] (B is 0 on pinned nodes)
    _bending_pull: np.ndarray = field(repr=False)  # (f, 3) B[free][:, free] rest[free]
    _matrix: sp.csc_matrix = field(repr=False)  # (f, f) A[:, free]ᵀ W A[:, free] + diag(h) + B[free][:, free]
    _factors: dict = field(repr=False)  # inertia coefficient -> Cholesky factor

    @property
    def n_nodes(self) -> int:
        return len(self.rest)

    @property
    def blocks(self) -> tuple[slice, slice, slice]:
        """Row slices of ``A``: springs, prisms (3 each: the columns of F), skull contact."""
        e, p = len(self.edges), 3 * len(self.prisms)
        return slice(0, e), slice(e, e + p), slice(e + p, len(self.weights))

    def global_matrix(self, inertia: float = 0.0) -> sp.csc_matrix:
        """The global step's matrix (f, f) ``A_fᵀ W A_f + diag(h) + inertia M`` over the free nodes,
        ``inertia`` in 1/s²."""
        if not inertia:
            return self._matrix
        return (self._matrix + sp.diags(inertia * self.mass[self.free])).tocsc()

    def factor(self, inertia: float = 0.0) -> Cholesky:
        """The Cholesky factor of ``global_matrix(inertia)`` (computed once per ``inertia``)."""
        key = float(inertia)
        if key not in self._factors:
            self._factors[key] = cholesky(self.global_matrix(key))
        return self._factors[key]


def prism_volumes(nodes: np.ndarray, prisms: np.ndarray) -> np.ndarray:
    """Volumes (P,) of prisms (P, 6) over ``nodes`` (N, 3), top 0-2 over bottom 3-5: the divergence
    theorem over its two triangles and three quads, each quad taken as the mean of its two
    triangulations, so the volume does not depend on the order of the prism's nodes. Signed:
    positive when the top triangle, counter-clockwise, faces away from the bottom."""
    top = [nodes[prisms[:, i]] for i in range(3)]  # (P, 3) each
    bottom = [nodes[prisms[:, i]] for i in range(3, 6)]
    total = triple_products(*top) - triple_products(*bottom)
    for a, b in ((0, 1), (1, 2), (2, 0)):  # quad a, b, b', a' (outward with the top counter-clockwise)
        q = (top[b], top[a], bottom[a], bottom[b])
        for i, j, m in ((0, 1, 2), (0, 2, 3), (0, 1, 3), (1, 2, 3)):  # both triangulations, halved
            total += 0.5 * triple_products(q[i], q[j], q[m])
    return total / 6.0


def skin_bending(volume: TissueVolume, rest: np.ndarray, thickness: float) -> sp.csr_matrix:
    """The skin's bending stiffness (N, N) ``Lᵀ diag(w) L`` over the nodes ``rest`` (N, 3) (metres) of
    ``volume``: ``L`` (k, N) the uniform Laplacian of the skin triangles (a skin node's neighbours'
    mean minus itself), ``w_i = 16 D a_i / h_i⁴`` N/m for the plate's bending stiffness ``D = E t³/12``
    (``E = EPIDERMAL_E``, ``t = thickness`` m), the skin area ``a_i`` around node ``i`` and its mean
    edge length ``h_i``: on a regular mesh ``δ_i ≈ h_i² ∇²u / 4``, so ``Σ w_i/2 |δ_i|²`` is the plate's
    ``∫ D/2 (∇²u)² dA`` whatever the resolution."""
    n, k = volume.n_nodes, volume.n_skin
    adjacency = vertex_adjacency(volume.triangles, k)  # (k, k)
    degree = np.asarray(adjacency.sum(axis=1)).ravel()
    laplacian = (sp.diags(1.0 / np.maximum(degree, 1.0)) @ adjacency - sp.eye(k)).tocsr()
    i, j = sp.triu(adjacency).nonzero()
    length = np.linalg.norm(rest[i] - rest[j], axis=1)
    mean_edge = np.bincount(np.r_[i, j], np.r_[length, length], k) / np.maximum(degree, 1.0)
    corners = rest[volume.triangles]  # (m, 3, 3)
    area = 0.5 * np.linalg.norm(
        np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1
    )
    around = np.bincount(volume.triangles.ravel(), np.repeat(area / 3.0, 3), k)
    plate = EPIDERMAL_E * thickness**3 / 12.0  # D, N·m
    w = 16.0 * plate * around / np.maximum(mean_edge, 1e-12) ** 4  # (k,) N/m
    B = (laplacian.T @ sp.diags(w) @ laplacian).tocoo()
    return sp.csr_matrix((B.data, (B.row, B.col)), shape=(n, n))


def _spring_rows(edges: np.ndarray, n: int) -> sp.csr_matrix:
    """Rows (E, n): ``x_j - x_i`` for each edge (i, j)."""
    e = len(edges)
    return sp.csr_matrix((np.tile([-1.0, 1.0], e), (np.repeat(np.arange(e), 2), edges.ravel())), shape=(e, n))


def prepare_tissue(
    volume: TissueVolume,
    scale: float,
    *,
    preserve_volume: bool = True,
    skull_contact: bool = True,
    damping: float = DAMPING_PER_S,
) -> TissueModel:
    """Springs, prism terms, skull contact, masses and the global matrix of ``volume`` (module docstring).

    Parameters
    ----------
    volume : TissueVolume
        From ``build_volume(rig)``, in rig units.
    scale : float
        The head height in rig units (``Rig.scale``): ``HEAD_HEIGHT_M`` metres.
    preserve_volume, skull_contact : bool
        Include the prisms' volume terms; keep the fascia outside the skull.
    damping : float
        Mass-proportional damping, 1/s.
    """
    mpu = HEAD_HEIGHT_M / scale
    rest = volume.nodes * mpu
    n, k = volume.n_nodes, volume.n_skin
    pinned = np.array(volume.pinned, dtype=bool)
    free = np.flatnonzero(~pinned)
    prisms = volume.prisms  # (P, 6): the dermal-fatty layer's, then the muscle layer's
    prism_layer = np.repeat([0, 1], len(volume.triangles))
    size = np.abs(prism_volumes(rest, prisms))  # (P,) m³

    # 1. springs: the unique edges of the prisms, each with its share of their volume
    pairs = np.sort(prisms[:, SPRING_PAIRS].reshape(-1, 2), axis=1)
    keys, inverse = np.unique(pairs[:, 0] * n + pairs[:, 1], return_inverse=True)
    edges = np.column_stack([keys // n, keys % n])
    share = np.bincount(inverse, np.repeat(size / len(SPRING_PAIRS), len(SPRING_PAIRS)), len(keys))
    lo, hi = np.sort(edges // k, axis=1).T  # the end nodes' layers: 0 skin, 1 fascia, 2 skull
    layer = np.select([hi == 0, lo == 0, hi == 1], [0, 1, 2], 3)
    keep = ~(pinned[edges[:, 0]] & pinned[edges[:, 1]])
    edges, share, layer = edges[keep], share[keep], layer[keep]
    lengths = np.linalg.norm(rest[edges[:, 1]] - rest[edges[:, 0]], axis=1)
    young = np.array([EPIDERMAL_E, DERMAL_E, FASCIA_E, MUSCLE_LAYER_E])[layer]
    stiffness = young * share / lengths**2  # (E,) N/m: a uniform strain ε stores E V ε²/2
    stiff_phase = np.where(layer == 1, (BIPHASIC_RATIO - 1.0) * stiffness, 0.0)

    # 2. prisms: F = xᵀ G with G = C (CᵀC)⁻¹ for the centred rest positions C (6, 3), so F = I at rest
    centred = rest[prisms] - rest[prisms].mean(axis=1, keepdims=True)  # (P, 6, 3)
    gradients = centred @ np.linalg.inv(np.einsum("pai,paj->pij", centred, centred))
    modulus = np.where(prism_layer == 0, DERMAL_E, MUSCLE_LAYER_E) * size  # (P,) J
    shape_stiffness = SHAPE_STIFFNESS * modulus
    volume_stiffness = VOLUME_STIFFNESS * modulus if preserve_volume else np.zeros(len(prisms))
    p = len(prisms)
    prism_rows = sp.csr_matrix(
        (
            gradients.ravel(),
            (
                np.broadcast_to(3 * np.arange(p)[:, None, None] + np.arange(3), (p, 6, 3)).ravel(),
                np.broadcast_to(prisms[:, :, None], (p, 6, 3)).ravel(),
            ),
        ),
        shape=(3 * p, n),
    )
    springs = _spring_rows(edges, n)
    elastic = sp.vstack([springs, prism_rows]).tocsr()
    w = np.concatenate([stiffness + stiff_phase, np.repeat(shape_stiffness + volume_stiffness, 3)])
    diagonal = np.asarray((elastic.T @ sp.diags(w) @ elastic).diagonal()).ravel()  # (N,) N/m

    # 3. skull contact: the fascia over pinned skull nodes; mass; restoration
    fascia = np.flatnonzero(pinned[2 * k :]) + k
    teeth = np.flatnonzero(~pinned[2 * k :]) + 2 * k  # loose skull nodes rest on the teeth and gums
    contact = np.concatenate([fascia, teeth]) if skull_contact else np.zeros(0, dtype=np.int64)
    fascia, teeth = contact[contact < 2 * k], contact[contact >= 2 * k]
    anchor = np.concatenate([rest[fascia + k], rest[teeth]])
    normal = np.asarray(volume.normals, dtype=np.float64)[contact % k]
    gap = np.einsum("si,si->s", rest[contact] - anchor, normal) * SKULL_GAP  # 0 on the teeth
    contact_stiffness = SKULL_WEIGHT * diagonal[contact]
    contact_rows = sp.csr_matrix(
        (np.ones(len(contact)), (np.arange(len(contact)), contact)), shape=(len(contact), n)
    )
    mass = np.bincount(prisms.ravel(), np.repeat(DENSITY * size / 6.0, 6), n)
    restoration = mass * (2.0 * np.pi * RESTORATION_HZ) ** 2
    loose = np.flatnonzero(~pinned[2 * k :]) + 2 * k
    restoration[loose] += LOOSE_ANCHOR * diagonal[loose]

    # 4. the skin's bending (on skin nodes, never pinned)
    bending = skin_bending(volume, rest, BENDING_THICKNESS_REL * HEAD_HEIGHT_M)
    bending_free = bending[free][:, free].tocsr()

    A = sp.vstack([elastic, contact_rows]).tocsr()
    weights = np.concatenate([w, contact_stiffness])
    free_rows = A[:, free].tocsr()
    gather = (free_rows.T @ sp.diags(weights)).tocsr()
    arrays = dict(
        rest=rest,
        mass=mass,
        pinned=pinned,
        free=free,
        edges=edges,
        rest_lengths=lengths,
        stiffness=stiffness,
        stiff_phase=stiff_phase,
        layer=layer,
        prisms=prisms,
        prism_layer=prism_layer,
        gradients=gradients,
        shape_stiffness=shape_stiffness,
        volume_stiffness=volume_stiffness,
        restoration=restoration,
        bending=bending,
        contact=contact,
        contact_anchor=anchor,
        contact_normal=normal,
        contact_gap=gap,
        contact_stiffness=contact_stiffness,
    )
    for array in arrays.values():
        if isinstance(array, np.ndarray):
            array.setflags(write=False)
    log.debug(
        "tissue: %d nodes (%d free), %d springs, %d prisms, %d contacts",
        n,
        len(free),
        len(edges),
        p,
        len(contact),
    )
    return TissueModel(
        **arrays,
        strain_limit=BIPHASIC_STRAIN,
        damping=float(damping),
        metres_per_unit=mpu,
        A=A,
        weights=weights,
        _pinned_pull=gather @ (A[:, np.flatnonzero(pinned)] @ rest[pinned]),
        _bending_free=bending_free,
        _bending_pull=bending_free @ rest[free],
        _matrix=(gather @ free_rows + sp.diags(restoration[free]) + bending_free).tocsc(),
        _factors={},
    )


# --------------------------------------------------------------------------- the local step


def _local(model: TissueModel, ax: np.ndarray) -> tuple[np.ndarray, float]:
    """The local step: each row's projection ``p`` (R, 3) of ``ax = A x`` (R, 3), and the energy of
    the constraints at ``ax``, joules.

    Springs go to their rest length; contact nodes onto the outer side of their skull planes (free
    to slide along them). Two terms share each biphasic spring's row and each prism's rows: the
    soft spring (to ``l₀``) and the stiff phase (into ``[1 - ε, 1 + ε] l₀``); a prism's shape term
    (F to its rotation R) and its volume term (to V, determinant 1). Two terms ``w₁/2 |y - p₁|² +
    w₂/2 |y - p₂|²`` are one of weight ``w₁ + w₂`` and target ``(w₁ p₁ + w₂ p₂)/(w₁ + w₂)``, plus
    ``w₁ w₂ / (2 (w₁ + w₂)) |p₁ - p₂|²`` (in the energy).
    """
    springs, prisms, contact = model.blocks
    p = np.empty_like(ax)
    energy = spring_targets(
        ax[springs], model.rest_lengths, model.stiffness, model.stiff_phase, model.strain_limit, p[springs]
    )
    f = np.ascontiguousarray(ax[prisms]).reshape(-1, 9)  # (P, 9): entry 3 j + i is F[i, j]
    energy += prism_targets(f, model.shape_stiffness, model.volume_stiffness, p[prisms].reshape(-1, 9))

    p[contact], contact_energy = _contact_targets(model, ax[contact])
    return p, float(energy + contact_energy)


def _contact_targets(model: TissueModel, y: np.ndarray) -> tuple[np.ndarray, float]:
    """The skull contact's projections (S, 3) of its nodes' positions ``y`` (S, 3) onto the outer side
    of their planes, and its energy, joules."""
    height = np.minimum(
        np.einsum("si,si->s", y - model.contact_anchor, model.contact_normal) - model.contact_gap, 0.0
    )
    return y - height[:, None] * model.contact_normal, 0.5 * float(model.contact_stiffness @ height**2)


def _gathered_local(model: TissueModel, x: np.ndarray, out: np.ndarray) -> float:
    """The local step gathered onto the nodes: ``Aᵀ W p(A x)`` (N, 3) into ``out`` for positions ``x``
    (N, 3), without forming ``A x`` (``projections.gathered_targets``; the contact rows are the
    contact nodes themselves); returns the constraints' energy (``_local``'s)."""
    energy = gathered_targets(
        x,
        model.edges,
        model.rest_lengths,
        model.stiffness,
        model.stiff_phase,
        model.strain_limit,
        model.prisms,
        model.gradients,
        model.shape_stiffness,
        model.volume_stiffness,
        out,
        numba.get_num_threads(),
    )
    targets, contact_energy = _contact_targets(model, x[model.contact])
    out[model.contact] += model.contact_stiffness[:, None] * targets  # contact nodes are distinct
    return energy + contact_energy


def project(model: TissueModel, ax: np.ndarray) -> np.ndarray:
    """The local step: the projection ``p`` (R, 3) of each row of ``ax = A x`` (R, 3) (``_local``)."""
    return _local(model, ax)[0]


def internal_forces(model: TissueModel, x: np.ndarray) -> np.ndarray:
    """The tissue's own forces (N, 3) on its nodes at positions ``x`` (N, 3) metres, newtons.

    Springs and prism terms, ``-Aᵀ W (A x - p(A x))`` over their rows, and the skin's bending
    ``-B (x - X)``: they act between nodes, so they sum to zero; a pinned node's entry is the force
    on the bone there. The ties to the ground (restoration, skull contact) are not included.
    """
    ax = model.A @ x
    tissue = slice(0, model.blocks[1].stop)
    r = (ax[tissue] - project(model, ax)[tissue]) * model.weights[tissue, None]
    return -(model.A[tissue].T @ r) - model.bending @ (x - model.rest)


def energy(model: TissueModel, x: np.ndarray, v: np.ndarray | None = None) -> float:
    """Potential (springs, prisms, skin bending, skull contact, restoration) plus kinetic energy, joules.

    ``x`` (N, 3) metres; ``v`` (N, 3) m/s, or None for none.
    """
    d = x - model.rest
    potential = _local(model, model.A @ x)[1] + 0.5 * np.einsum("n,ni,ni->", model.restoration, d, d)
    potential += 0.5 * np.einsum("ni,ni->", d, model.bending @ d)
    kinetic = 0.0 if v is None else 0.5 * np.einsum("n,ni,ni->", model.mass, v, v)
    return float(potential + kinetic)


def inside_skull(model: TissueModel, x: np.ndarray) -> np.ndarray:
    """How far (S,) metres each contact node of ``x`` (N, 3) lies inside its skull plane (its gap
    above the skull node included); 0 or less is outside."""
    c = model.contact
    return model.contact_gap - np.einsum("si,si->s", x[c] - model.contact_anchor, model.contact_normal)


def _clear_skull(model: TissueModel, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``x`` (N, 3) with every contact node below its plane moved onto it (in place), and which
    contacts (S,) bool were moved."""
    depth = inside_skull(model, x)
    below = depth > 0
    x[model.contact[below]] += depth[below, None] * model.contact_normal[below]
    return x, below


# --------------------------------------------------------------------------- the solvers


@dataclass(frozen=True)
class TissueResult:
    """A static equilibrium and how the iteration went."""

    x: np.ndarray  # (N, 3) float64 metres
    success: bool
    message: str  # e.g. "converged: largest step 8.1e-06 m < 1e-05 m after 14 iterations"
    iterations: int
    residuals: np.ndarray  # (iterations,) the largest node step of each global solve, metres


def _iterations(
    model: TissueModel, x: np.ndarray, constant: np.ndarray, inertia: float, limit: int
) -> tuple[np.ndarray, np.ndarray]:
    """Local/global iterations from ``x`` (N, 3) until no free node moves ``TOLERANCE_M``, at most
    ``limit``; returns the positions and each step (metres).

    Minimises ``Φ(x) = Σ w/2 |A x - p|² + Σ (h + inertia m)/2 |x|² - x · constant + ½ (x - X)ᵀ B (x - X)``
    over the free nodes: ``constant`` (f, 3) holds the free rows of ``inertia M s + f + diag(h) X``
    (the inertia ``inertia/2 |x - s|²_M``, the forces and the restoration, up to a constant); the
    bending ``B`` is in the matrix and its pull ``B X`` is added here. Every PD iteration
    (local step, then one solve with the constant matrix) lowers Φ; an Anderson iterate (the last
    ``ANDERSON_DEPTH`` steps mixed) is kept only if it lowers Φ too.
    """
    factor = model.factor(inertia)
    free = model.free
    diagonal = (model.restoration + inertia * model.mass)[free, None]

    bending, bending_pull = model._bending_free, model._bending_pull
    known = constant - model._pinned_pull + bending_pull  # the right-hand side's constant part
    positions, gathered = model.rest.copy(), np.empty_like(x)  # the pinned nodes at rest, as _pinned_pull

    def local(xf: np.ndarray) -> tuple[np.ndarray, float]:
        positions[free] = xf
        constraints = _gathered_local(model, positions, gathered)
        linear = 0.5 * diagonal * xf - constant + 0.5 * (bending @ xf) - bending_pull
        phi = constraints + np.einsum("fi,fi->", linear, xf)
        return gathered[free] + known, phi

    xf = x[free]
    rhs, phi = local(xf)
    steps, residuals, images = [], [], []
    for iteration in range(limit):
        g = factor.solve(rhs)
        f = g - xf
        steps.append(float(np.sqrt(np.einsum("ni,ni->n", f, f).max())))
        if steps[-1] < TOLERANCE_M or iteration == limit - 1:  # the last: no local step to judge a mix
            xf = g
            break
        residuals.append(f.ravel())
        images.append(g.ravel())
        del residuals[: -ANDERSON_DEPTH - 1], images[: -ANDERSON_DEPTH - 1]
        candidate = g
        if len(residuals) > 1 and ANDERSON_DEPTH:  # Anderson: g minus the mix of past steps cancelling f
            df = np.diff(residuals, axis=0)  # (m, 3f)
            gram = df @ df.T
            gram += 1e-12 * np.trace(gram) * np.eye(len(gram))
            gamma = np.linalg.solve(gram, df @ residuals[-1])
            candidate = g - (gamma @ np.diff(images, axis=0)).reshape(g.shape)
        new_rhs, new_phi = local(candidate)
        if candidate is not g and not new_phi < phi:  # no lower: take the plain PD iterate
            del residuals[:-1], images[:-1]
            candidate = g
            new_rhs, new_phi = local(g)
        xf, rhs, phi = candidate, new_rhs, new_phi
    out = x.copy()
    out[free] = xf
    return out, np.array(steps)


def _iterate(
    model: TissueModel, x: np.ndarray, constant: np.ndarray, inertia: float, limit: int
) -> tuple[np.ndarray, np.ndarray]:
    """``_iterations`` with BLAS on one thread: the compiled local step runs on every core, and idle
    OpenBLAS threads spinning beside it starved it (a 10k-node frame took 53 ms instead of 24)."""
    with BLAS.limit(limits=1, user_api="blas"):
        return _iterations(model, x, constant, inertia, limit)


def equilibrium(model: TissueModel, forces: np.ndarray, *, x0: np.ndarray | None = None) -> TissueResult:
    """The static equilibrium under nodal ``forces`` (N, 3) newtons, from ``x0`` (N, 3) metres (rest).

    Projective dynamics without inertia: ``(Aᵀ W A + diag(h)) x = Aᵀ W p(A x) + f + diag(h) X``,
    iterated until no node moves ``TOLERANCE_M`` (at most ``STATIC_ITERATIONS``); contact nodes
    left below the skull are put on it. Forces on pinned nodes do nothing. Not converging is not
    an error: ``success`` is False and ``message`` says how far it got.
    """
    x = model.rest.copy() if x0 is None else np.array(x0, dtype=np.float64)
    x[model.pinned] = model.rest[model.pinned]
    constant = (forces + model.restoration[:, None] * model.rest)[model.free]
    x, steps = _iterate(model, x, constant, 0.0, STATIC_ITERATIONS)
    x = _clear_skull(model, x)[0]
    last = steps[-1] if len(steps) else 0.0
    success = bool(last < TOLERANCE_M)
    verdict = "converged" if success else "did not converge"
    relation = "<" if success else ">="
    message = (
        f"{verdict}: largest step {last:.2g} m {relation} {TOLERANCE_M:g} m after {len(steps)} iterations"
    )
    return TissueResult(x, success, message, len(steps), steps)


@dataclass(frozen=True)
class TissueState:
    """A moment of a simulation: positions ``x`` (N, 3) metres and velocities ``v`` (N, 3) m/s, with
    the previous step's (``x_prev``, ``v_prev``) for BDF2 and that step's length ``h`` (s; 0 for a
    state at rest, whose past is the same rest whatever the step)."""

    x: np.ndarray
    v: np.ndarray
    x_prev: np.ndarray
    v_prev: np.ndarray
    h: float = 0.0

    @classmethod
    def at_rest(cls, model: TissueModel) -> TissueState:
        zero = np.zeros_like(model.rest)
        return cls(model.rest.copy(), zero, model.rest.copy(), zero.copy(), 0.0)


def step(model: TissueModel, state: TissueState, forces: np.ndarray, h: float) -> TissueState:
    """The state ``h`` seconds later under nodal ``forces`` (N, 3) newtons: one implicit BDF2 step.

    With ``β = 2h/3``, ``x̂ = (4 x - x_prev)/3`` and ``v̂ = (4 v - v_prev)/3`` (backward Euler:
    ``β = h``, ``x̂ = x``, ``v̂ = v``, when the previous step was not ``h`` long), BDF2 with the
    damping force ``-γ M v`` makes the new positions minimise ``c/2 |x - s|²_M + E(x) - x · f``
    with ``c = 1/β² + γ/β`` and ``s = x̂ + β v̂ / (1 + γ β)``; then ``v = (x - x̂)/β``. Projective
    dynamics from ``s``, at most ``DYNAMIC_ITERATIONS``; the matrix ``Aᵀ W A + diag(h) + c M`` is
    factored once per ``h``.
    """
    if state.h in (0.0, h):
        beta = 2.0 * h / 3.0
        x_hat = (4.0 * state.x - state.x_prev) / 3.0
        v_hat = (4.0 * state.v - state.v_prev) / 3.0
    else:
        beta, x_hat, v_hat = h, state.x, state.v
    gamma = model.damping
    c = 1.0 / beta**2 + gamma / beta
    s = x_hat + (beta / (1.0 + gamma * beta)) * v_hat
    constant = (c * model.mass[:, None] * s + forces + model.restoration[:, None] * model.rest)[model.free]
    x, _ = _iterate(model, s, constant, c, DYNAMIC_ITERATIONS)
    v = (x - x_hat) / beta
    return TissueState(x, v, state.x, state.v, float(h))


def rest_stiffness(model: TissueModel) -> sp.csr_matrix:
    """The Hessian (3N, 3N) of the energy at rest, N/m: the linearised tissue, row ``3 j + axis``.

    A spring stiffens only along itself (``w n nᵀ``), its stiff phase not at all (slack within the
    strain limit); a prism's shape term resists its strain, ``w_s |sym δF|²`` (not a turn), its
    volume term a change of volume, ``w_v/3 (tr δF)²``, with ``δF = Σ_a δx_a g_aᵀ``; the skin's
    bending is ``B`` on each axis; the restoration holds every node; the skull contact is slack.
    """
    n = model.n_nodes
    axes = np.arange(3)
    i, j = model.edges.T
    d = model.rest[j] - model.rest[i]
    unit = d / np.linalg.norm(d, axis=1, keepdims=True)
    block = model.stiffness[:, None, None] * np.einsum("ei,ej->eij", unit, unit)  # (E, 3, 3)
    ends = np.stack([np.stack([i, i], 1), np.stack([j, j], 1), np.stack([i, j], 1), np.stack([j, i], 1)], 1)
    values = np.array([1.0, 1.0, -1.0, -1.0])[None, :, None, None] * block[:, None]  # (E, 4, 3, 3)
    rows = np.broadcast_to(3 * ends[:, :, 0, None, None] + axes[:, None], values.shape)
    cols = np.broadcast_to(3 * ends[:, :, 1, None, None] + axes, values.shape)
    springs = sp.coo_matrix((values.ravel(), (rows.ravel(), cols.ravel())), shape=(3 * n, 3 * n))
    # prisms: vec(δF)[3 i + j] = Σ_a δx_a,i g_a,j, i.e. vec(δF) = D δx, D[(i, j), (a, k)] = δ_ik g_a,j
    D = np.einsum("ik,paj->pijak", np.eye(3), model.gradients).reshape(-1, 9, 18)
    swap = np.eye(9).reshape(3, 3, 3, 3).transpose(0, 1, 3, 2).reshape(9, 9)  # vec(δF) -> vec(δFᵀ)
    hessian = model.shape_stiffness[:, None, None] * (np.swapaxes(D, 1, 2) @ (0.5 * (np.eye(9) + swap) @ D))
    trace = np.einsum("b,pbd->pd", np.eye(3).ravel(), D)  # (P, 18): tr δF = trace · δx
    hessian += (model.volume_stiffness / 3.0)[:, None, None] * np.einsum("pa,pb->pab", trace, trace)
    dof = (3 * model.prisms[:, :, None] + axes).reshape(-1, 18)
    prisms = sp.coo_matrix(
        (hessian.ravel(), (np.repeat(dof, 18, axis=1).ravel(), np.tile(dof, (1, 18)).ravel())),
        shape=(3 * n, 3 * n),
    )
    bending = sp.kron(model.bending, sp.eye(3), format="csr")  # row 3 j + axis, as the others
    return (springs.tocsr() + prisms.tocsr() + sp.diags(np.repeat(model.restoration, 3)) + bending).tocsr()


# --------------------------------------------------------------------------- the engine


def muscle_responses(model: TissueModel, forces: sp.spmatrix) -> np.ndarray:
    """Displacements (3N, a) metres of the linearised tissue (``rest_stiffness``) under each column of
    ``forces`` (3N, a) newtons; the pinned nodes stay."""
    dof = (3 * model.free[:, None] + np.arange(3)).ravel()
    out = np.zeros(forces.shape)
    out[dof] = nested_lu(rest_stiffness(model)[dof][:, dof]).solve(forces.tocsr()[dof].toarray())
    return out


VISIBLE_REL = 1e-3
"""An equilibrium that stops short of its tolerance warns only when its last step is this fraction of
the head or more (0.2 mm on a 22 cm head, half a pixel of a 512-pixel render): 0.018 mm against the
0.01 mm tolerance is not worth a warning."""


class TissueEngine:
    """Layered mass-spring tissue (projective dynamics) plus the shared chain; prepare once.

    ``deform(values)`` gives the static equilibrium of one pose; ``simulate(values, fps)`` a clip
    with inertia (the skin lags, overshoots and settles). Options: ``skull`` (the
    chain's, as every engine), ``preserve_volume``, ``skull_contact`` and ``damping`` (1/s) for the
    tissue (``prepare_tissue``), ``proxy`` the skin the volume lies under
    (``engines.volume.proxy_size``: "auto", "off" or a skin vertex count).

    Attributes beyond the ``Engine`` protocol's: ``volume`` (``TissueVolume``), ``model``
    (``TissueModel``), ``muscles`` (a,) the channels with loads, ``forces`` (3N, a) their
    calibrated nodal forces at full activation (newtons, sparse), ``linear`` (3N, a) the
    linearised tissue's response to them (metres), where each equilibrium starts.
    """

    name = "tissue"
    bake_correctives = 0  # a pose takes a solve: bake the channels alone (``engines.bake.bake``)
    bake_samples = 4

    def __init__(
        self,
        rig: Rig,
        *,
        skull: bool = True,
        preserve_volume: bool = True,
        skull_contact: bool = True,
        damping: float = DAMPING_PER_S,
        proxy: int | str = "auto",
        progress=None,
    ) -> None:
        report = progress or (lambda done, total: None)  # (done, total) of the 3 stages below
        self.rig = rig
        self.channels = rig.channel_names
        report(0, 3)
        self.volume = build_volume(rig, proxy=proxy)
        report(1, 3)
        self.model = prepare_tissue(
            self.volume,
            rig.scale,
            preserve_volume=preserve_volume,
            skull_contact=skull_contact,
            damping=damping,
        )
        report(2, 3)
        loads = muscle_loads(rig, self.volume, rollable=True, per_volume=True)
        self.muscles = loads.active  # (a,) channel indices
        forces = loads.forces[:, self.muscles].tocsc()  # (3N, a), unscaled
        linear = muscle_responses(self.model, forces)  # (3N, a) m
        k = self.volume.n_skin
        skin = linear[: 3 * k].reshape(k, 3, -1) / self.model.metres_per_unit
        scale = loads.calibration(skin, self.muscles)  # (a,)
        self.forces = (forces @ sp.diags(scale)).tocsc()  # (3N, a) newtons at full activation
        self.linear = linear * scale  # (3N, a) metres: the linearised response, the iteration's start
        self.mask = muscle_mask(rig)[:, None]  # (n, 1) the lids follow their bones
        self.chain = Chain(rig, skull=skull)
        self.model.factor(0.0)
        report(3, 3)

    def _muscle_values(self, values: np.ndarray) -> np.ndarray:
        return values[..., self.muscles]

    def _skin(self, x: np.ndarray) -> np.ndarray:
        """Rest vertices (n, 3) moved by the tissue at node positions ``x`` (N, 3) metres."""
        k = self.volume.n_skin
        motion = (x[:k] - self.model.rest[:k]) / self.model.metres_per_unit
        return self.rig.mesh.vertices + self.volume.to_vertices(motion) * self.mask

    def deform(self, values: np.ndarray) -> np.ndarray:
        """Vertex positions (n, 3) for one pose ``values`` (c,) in the rig's channel order: the
        tissue's static equilibrium under the pose's muscles, then the chain. All muscles at rest
        give the rest skin exactly."""
        values = check_activations(self.rig, values)
        if values.ndim != 1:
            raise ValueError("deform takes one pose (c,); use simulate for clips, or bake a Basis")
        a = self._muscle_values(values)
        moved = self.rig.mesh.vertices
        if np.any(a):
            forces = (self.forces @ a).reshape(-1, 3)
            start = self.model.rest + (self.linear @ a).reshape(-1, 3)
            result = equilibrium(self.model, forces, x0=start)
            log.debug("tissue equilibrium: %s", result.message)
            off_m = float(result.residuals[-1]) if len(result.residuals) else 0.0
            if not result.success and off_m > VISIBLE_REL * self.rig.scale * self.model.metres_per_unit:
                warnings.warn(
                    f"tissue engine: the equilibrium {result.message}", MimeticWarning, stacklevel=2
                )
            moved = self._skin(result.x)
        return self.chain.apply(moved, values)

    def steps_per_frame(self, fps: float) -> int:
        """Time steps ``simulate`` takes per frame at ``fps``: each at most ``STEP_MAX_S`` long."""
        return max(1, int(np.ceil(1.0 / (fps * STEP_MAX_S) - 1e-9)))

    def _inertia(self, values: np.ndarray, fps: float) -> np.ndarray:
        """The inertial force (f, N, 3) newtons of each frame of a clip (f, c) at ``fps``: the tissue is
        carried by the bones (the jaw, the head, the lids: the chain skins it after the physics), so
        in the rest frame its nodes feel ``-m a`` for the acceleration ``a`` of the place the bones
        carry them to (the skin vertex's, for every layer under it; second differences between
        frames, the clip held still before its first and after its last). Rotation of that frame is
        neglected: a frame turns the jaw by a few degrees at most."""
        sampling = self.volume.sampling()  # (k, n): where the skin nodes lie on the rig's skin
        rest = sampling @ self.rig.mesh.vertices
        weights = sampling @ self.chain.weights
        places = np.stack(
            [linear_blend_skinning(rest, weights, bone_transforms(self.rig, v)) for v in values]
        )  # (f, k, 3) rig units
        padded = np.concatenate([places[:1], places, places[-1:]])
        accel = (padded[2:] - 2 * padded[1:-1] + padded[:-2]) * (fps**2 * self.model.metres_per_unit)
        return -self.model.mass[None, :, None] * np.tile(accel, (1, 3, 1))

    def simulate(
        self, values: np.ndarray, fps: float, *, progress: Callable[[int, int], None] | None = None
    ) -> np.ndarray:
        """Vertex positions (f, n, 3) of a clip ``values`` (f, c) at ``fps``, with the tissue's inertia.

        The tissue starts at rest; each frame's activations are reached at its end, ramping linearly
        from the previous frame's (from rest before the first), over ``steps_per_frame(fps)`` BDF2
        steps (``step``), with the bones' inertial pull (``_inertia``: a jaw that drops fast leaves the
        lower lip and cheeks behind for a moment); the chain runs on every frame.
        """
        values = check_activations(self.rig, values)
        if values.ndim != 2:
            raise ActivationError(
                f"simulate takes a clip (frames, {len(self.channels)}); got shape {values.shape}"
            )
        if not (np.isfinite(fps) and fps > 0):
            raise ActivationError(f"fps must be positive; got {fps}")
        n_steps = self.steps_per_frame(fps)
        h = 1.0 / (fps * n_steps)
        a = self._muscle_values(values)  # (f, a)
        carried = self._inertia(values, fps)  # (f, N, 3) newtons: the bones' pull on the tissue's mass
        state = TissueState.at_rest(self.model)
        previous = np.zeros(a.shape[1])
        out = np.empty((len(values), self.rig.n_vertices, 3))
        with BLAS.limit(limits=1, user_api="blas"):  # the chain's BLAS idles between steps too
            for frame in range(len(values)):
                for i in range(1, n_steps + 1):
                    now = previous + (a[frame] - previous) * (i / n_steps)
                    forces = (self.forces @ now).reshape(-1, 3) + carried[frame]
                    state = step(self.model, state, forces, h)
                previous = a[frame]
                out[frame] = self.chain.apply(self._skin(state.x), values[frame])
                if progress is not None:
                    progress(frame + 1, len(values))
        return out
