"""The fem engine and the tissue volume it stands on: continuum answers on a slab of known strain,
the basis against a direct solve, convergence under refinement, and a well-formed volume on heads.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
import scipy.sparse.linalg as sla
from scipy.spatial import cKDTree

from mimetic.engines import make_engine
from mimetic.engines import volume as volume_module
from mimetic.engines.fem import POISSON, FemEngine, prepare_fem, stiffness_matrix
from mimetic.engines.loads import muscle_loads, skin_areas
from mimetic.engines.volume import FASCIA_DEPTH, TissueVolume, build_volume, prism_tets, tet_volumes
from mimetic.errors import MimeticError
from mimetic.rig.activations import pose
from mimetic.testing import small_rig

YOUNG = (1.0, 0.5)


def slab(nx: int = 5, ny: int = 4, depth: float = 0.3, seed: int | None = None) -> TissueVolume:
    """A flat tissue slab: skin on z = 0 over [0, 1] x [0, 0.8], fascia and skull under it at
    ``FASCIA_DEPTH * depth`` and ``depth``; with ``seed``, the skin nodes numbered at random."""
    x, y = np.meshgrid(np.linspace(0, 1, nx), np.linspace(0, 0.8, ny), indexing="ij")
    skin = np.column_stack([x.ravel(), y.ravel(), np.zeros(x.size)])
    ids = np.arange(x.size).reshape(nx, ny)
    quads = np.stack([ids[:-1, :-1], ids[1:, :-1], ids[1:, 1:], ids[:-1, 1:]], axis=-1).reshape(-1, 4)
    tri = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]])
    if seed is not None:
        order = np.random.default_rng(seed).permutation(len(skin))  # new number -> old node
        new = np.argsort(order)
        skin, tri = skin[order], new[tri]
    k = len(skin)
    down = np.array([0.0, 0.0, 1.0])
    nodes = np.concatenate([skin, skin - FASCIA_DEPTH * depth * down, skin - depth * down])
    tets = np.concatenate(
        [
            prism_tets(np.arange(k), np.arange(k) + k, tri),
            prism_tets(*(np.arange(k) + k * i for i in (1, 2)), tri),
        ]
    )
    negative = tet_volumes(nodes, tets) < 0
    tets[negative] = tets[negative][:, [0, 2, 1, 3]]
    none = np.zeros(0, np.int64)
    return TissueVolume(
        nodes,
        np.arange(k),
        np.arange(k),
        tri,
        tets,
        np.repeat([0, 1], 3 * len(tri)),
        np.concatenate([np.zeros(2 * k, bool), np.ones(k, bool)]),
        np.tile(down, (k, 1)),
        np.full(k, depth),
        none,
        none,
        np.zeros(0),
    )


def lame(young: float) -> tuple[float, float]:
    return young * POISSON / ((1 + POISSON) * (1 - 2 * POISSON)), young / (2 * (1 + POISSON))


def test_a_uniform_strain_stores_the_continuum_energy():
    """Linear tetrahedra represent an affine displacement exactly: ½ uᵀKu = Σ_layers V (λ/2 tr(ε)² +
    μ ε:ε) with ε the symmetric part of the displacement gradient."""
    volume = slab()
    K = stiffness_matrix(volume, YOUNG, POISSON)
    gradient = np.array([[0.02, 0.01, -0.03], [0.0, -0.01, 0.02], [0.015, 0.0, 0.03]])
    u = (volume.nodes @ gradient.T).ravel()
    strain = 0.5 * (gradient + gradient.T)
    expected = 0.0
    for layer, young in enumerate(YOUNG):
        lam, mu = lame(young)
        size = volume.rest_volumes[volume.tet_layer == layer].sum()
        expected += size * (0.5 * lam * np.trace(strain) ** 2 + mu * np.sum(strain * strain))
    assert 0.5 * u @ (K @ u) == pytest.approx(expected, rel=1e-10)


def test_rigid_motions_cost_nothing_and_internal_forces_balance():
    volume = slab()
    K = stiffness_matrix(volume, YOUNG, POISSON)
    x = volume.nodes
    scale = np.abs(K).max()
    assert np.abs(K @ np.tile([0.3, -0.2, 0.1], len(x))).max() < 1e-12 * scale
    assert np.abs(K @ np.cross([0.2, 0.5, -0.1], x).ravel()).max() < 1e-12 * scale  # an infinitesimal turn
    u = np.random.default_rng(0).normal(size=3 * len(x))
    force = (K @ u).reshape(-1, 3)
    assert np.abs(force.sum(axis=0)).max() < 1e-12 * np.abs(force).max()  # Newton's third law
    assert np.abs(np.cross(x, force).sum(axis=0)).max() < 1e-12 * np.abs(force).max()  # and no net torque
    assert np.allclose(K.toarray(), K.toarray().T)


def test_the_stiffness_does_not_depend_on_how_the_vertices_are_numbered():
    """Each prism counts all six of its three-tetrahedron splits, so renumbering the skin only
    renumbers the matrix (one split alone changes with the numbering: checked below)."""
    a, b = slab(), slab(seed=4)
    Ka, Kb = stiffness_matrix(a, YOUNG, POISSON).toarray(), stiffness_matrix(b, YOUNG, POISSON).toarray()
    match = cKDTree(b.nodes).query(a.nodes)[1]  # node of b at each node of a
    dofs = (3 * match[:, None] + np.arange(3)).ravel()
    np.testing.assert_allclose(Kb[np.ix_(dofs, dofs)], Ka, atol=1e-12 * np.abs(Ka).max())
    one_a = prism_energy_one_split(a)
    one_b = prism_energy_one_split(b)
    assert not np.allclose(one_a, one_b[np.ix_(dofs, dofs)])


def prism_energy_one_split(volume: TissueVolume) -> np.ndarray:
    from mimetic.engines.fem import assemble, tet_blocks

    young = np.where(volume.tet_layer == 0, YOUNG[0], YOUNG[1])
    return assemble(
        tet_blocks(volume.nodes, volume.tets, young, POISSON), volume.tets, volume.n_nodes
    ).toarray()


@cache
def fem(seed: int | None = None) -> FemEngine:
    return make_engine(small_rig(seed), "fem")


def test_the_fem_basis_is_the_direct_solve_of_the_summed_loads():
    """``K u = Σ aᵢ sᵢ Fᵢ`` solved directly (scipy's spsolve on the free nodes) gives the basis's
    combination Σ aᵢ uᵢ to 1e-8 of its size, muscles only (the lids' mask is 1 away from the eyes)."""
    engine = fem()
    rig, volume = engine.rig, engine.volume
    loads = muscle_loads(rig, volume)
    solver = engine.solver
    columns = np.arange(len(rig.channels))
    unit = solver.solve(loads.forces.toarray())
    scales = loads.calibration(unit[: 3 * volume.n_skin].reshape(volume.n_skin, 3, -1), columns)
    a = np.zeros(len(rig.channels))
    names = ("zygomatic_major_L", "orbicularis_oris", "frontalis_inner_R", "mentalis", "depressor_labii_L")
    for name, value in zip(names, (0.7, 0.4, 1.0, 0.3, 0.5), strict=True):
        a[rig.channel_index(name)] = value
    rhs = loads.forces @ (a * scales)
    K = solver.K[solver.free][:, solver.free].tocsc()
    direct = np.zeros(3 * volume.n_nodes)
    direct[solver.free] = sla.spsolve(K, rhs[solver.free])
    skin = volume.to_vertices(direct[: 3 * volume.n_skin].reshape(-1, 3))
    far_from_lids = np.ones(rig.n_vertices, bool)
    for name in ("eyelid_upper_L", "eyelid_upper_R", "eyelid_lower_L", "eyelid_lower_R"):
        column = rig.skin_weights[:, rig.bone_index(name)].toarray().ravel()
        far_from_lids &= column == 0
    combined = np.einsum("c,cnk->nk", a, engine.deltas)
    size = np.abs(skin).max()
    assert size > 0.01 * rig.scale
    np.testing.assert_allclose(combined[far_from_lids], skin[far_from_lids], atol=1e-8 * size)


def test_the_fem_engine_is_linear_in_the_muscles_before_the_chain():
    engine = fem()
    rig = engine.rig
    one = pose(rig, {"zygomatic_major_L": 0.5})
    two = pose(rig, {"zygomatic_major_L": 1.0})
    rest = rig.mesh.vertices
    # away from the creases and tissue actions the smile's motion doubles exactly
    moved_one, moved_two = engine.deform(one) - rest, engine.deform(two) - rest
    direct = engine.deltas[rig.channel_index("zygomatic_major_L")]
    untouched = np.ones(rig.n_vertices, bool)
    untouched[rig.anatomy.lip_contact.ravel()] = False  # lips that would cross are pressed together
    untouched[rig.anatomy.skull.vertices] = False  # the forehead is pushed out of the skull
    for side in "LR":  # the lid contact and sculptors keep the lids off the eyeball
        eye = rig.bone(f"eye_{side}")
        untouched &= np.linalg.norm(rest - eye.head, axis=1) > 2 * np.linalg.norm(eye.tail - eye.head)
    for fold in rig.anatomy.creases + rig.anatomy.actions:
        if "zygomatic_major_L" in fold.gains:
            untouched[fold.vertices] = False
    np.testing.assert_allclose(moved_one[untouched], 0.5 * direct[untouched], atol=1e-12)
    np.testing.assert_allclose(moved_two[untouched], 2 * moved_one[untouched], atol=1e-12)


def test_a_probe_displacement_converges_under_refinement():
    """A smooth sideways load density on the fascia of a slab pinned at its base, refined in the plane:
    the displacement of the skin at the centre changes less at each refinement, the ratio of
    successive changes falling toward a quarter (second order; measured 0.46 then 0.30)."""
    probes = []
    for n in (9, 17, 33, 65):
        volume = slab(n, n)
        k = volume.n_skin
        skin = volume.nodes[:k]
        density = np.exp(-np.sum((skin[:, :2] - [0.5, 0.4]) ** 2, axis=1) / 0.04)
        forces = np.zeros((volume.n_nodes, 3))
        forces[k : 2 * k, 0] = density * skin_areas(volume)
        u = prepare_fem(volume).solve(forces.ravel()).reshape(-1, 3)
        probes.append(u[np.argmin(np.linalg.norm(skin[:, :2] - [0.5, 0.4], axis=1)), 0])
    steps = np.abs(np.diff(probes))
    assert probes[-1] > 0
    assert steps[1] < 0.5 * steps[0] and steps[2] < 0.35 * steps[1], steps


@pytest.mark.parametrize("seed", [None, 3])
def test_the_tissue_volume_is_well_formed_under_a_head(seed):
    rig = small_rig(seed)
    volume = build_volume(rig)
    k = volume.n_skin
    assert (volume.rest_volumes > 0).all()
    assert (tet_volumes(volume.nodes, volume.tets) > 0).all()  # positively oriented
    thickness = rig.anatomy.thickness_rel[volume.surface] * rig.scale
    assert (volume.depth <= thickness + 1e-12).all() and (volume.depth > 0).all()
    # thin over the nose and the lids, thick over the cheeks
    depth = volume.to_vertices(volume.depth)
    assert np.median(depth[rig.regions["cheek_L"]]) > 2 * np.median(depth[rig.regions["nose"]])
    # no skull node inside an eyeball: the depth is cut back at the openings (skin tucked inside the
    # eyeball at rest, the conjunctiva's skirt, is inside already)
    for side in "LR":
        bone = rig.bone(f"eye_{side}")
        radius = np.linalg.norm(bone.tail - bone.head)
        outside = np.linalg.norm(volume.nodes[:k] - bone.head, axis=1) > radius
        assert np.linalg.norm(volume.nodes[2 * k :][outside] - bone.head, axis=1).min() > radius
    # bone under the forehead and nose; no bone behind the lips
    pinned = volume.to_vertices(volume.pinned[2 * k :].astype(float))
    assert pinned[rig.regions["forehead"]].mean() > 0.9
    assert pinned[rig.regions["upper_lip"]].max() == 0 and pinned[rig.regions["lower_lip"]].max() == 0


def test_the_tissue_volume_is_mirror_symmetric_on_a_symmetric_head():
    rig = small_rig()
    volume = build_volume(rig)
    nodes = volume.nodes
    gap = cKDTree(nodes).query(nodes * [-1.0, 1.0, 1.0])[0]
    # nothing depends on the mouth cavity's or the eyes' triangles, which are not mirror-symmetric
    assert gap.max() < 1e-9 * rig.scale


@pytest.mark.parametrize("name", ["fem", "tissue"])
def test_a_skin_too_big_for_the_physical_engines_takes_a_proxy_or_is_refused_with_what_to_do(
    name, monkeypatch
):
    rig = small_rig()
    nodes = build_volume(rig).n_nodes
    monkeypatch.setattr(volume_module, "MAX_NODES", nodes - 1)
    with pytest.raises(MimeticError, match=rf"{nodes:,} nodes.*at most {nodes - 1:,}.*proxy='auto'"):
        make_engine(rig, name, proxy="off")
    assert make_engine(rig, name, proxy=1_500).volume.n_nodes < nodes  # through a proxy it fits
    monkeypatch.setattr(volume_module, "MAX_NODES", nodes)
    assert build_volume(rig).n_nodes == nodes  # at the limit it builds


def test_the_mouth_lining_follows_the_lips_it_continues():
    engine = fem()
    rig, volume = engine.rig, engine.volume
    assert len(volume.cavity) > 0
    lining = np.setdiff1d(np.unique(rig.mesh.faces[rig.mesh.parts["mouth"]]), volume.surface)
    assert np.isin(volume.cavity, lining).all()
    moved = engine.deltas[rig.channel_index("orbicularis_oris")]
    source = volume.cavity_source
    assert np.abs(moved[source]).max() > 0.01 * rig.scale
    np.testing.assert_allclose(moved[volume.cavity], moved[source] * volume.cavity_fall[:, None], atol=1e-12)
    nearest = np.linalg.norm(rig.mesh.vertices[volume.cavity] - rig.mesh.vertices[source], axis=1)
    assert np.all(np.diff(volume.cavity_fall[np.argsort(nearest)]) <= 1e-12)  # less the deeper it lies


def test_loads_do_not_push_into_a_lip_the_tissue_can_roll():
    """For the tissue engine (``rollable``), where a tissue column hangs (the lips) no muscle's load
    points inward along the tissue normal: over bone the bone takes such a push, in a lip it rolled
    the lip in over the teeth. Over bone the loads keep their inward part (the vector engine's
    field), and the linear fem's loads keep it everywhere."""
    engine = fem()
    volume = engine.volume
    k = volume.n_skin
    hanging = ~volume.pinned[2 * k :]
    assert hanging.sum() > 20

    def push(rollable: bool) -> np.ndarray:
        """(k, c) each column's load along the outward tissue normal, over the largest load."""
        loads = muscle_loads(engine.rig, volume, rollable=rollable).forces.toarray()
        column = loads.reshape(3, k, 3, -1).sum(axis=0)  # (k, 3, c) under each skin node
        return np.einsum("kic,ki->kc", column, volume.normals) / np.abs(column).max()

    rolled, linear = push(True), push(False)
    assert rolled[hanging].min() >= -1e-12
    assert linear[hanging].min() < -1e-3  # the Waters fields do push into the lips
    assert rolled[~hanging].min() < -1e-3  # and over bone, in both
