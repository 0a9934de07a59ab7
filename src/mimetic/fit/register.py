"""Non-rigid registration of the reference skin onto a target surface.

The global-fit energy of the automated rigging thesis (§5.6, after Jeong et al. 2002), with the
smoothness term on the displacement instead of the positions, so the reference keeps its
features while it bends:

    E(x) = Σ_i w_i |x_i − q_i|²                    closest-point data, both directions
         + α Σ_i |L (x − x0)_i|²                    smoothness (umbrella Laplacian L)
         + β Σ_l |x_l − t_l|²                       landmark binding

``q_i`` is the point-to-plane target of vertex i: its position moved along the target's normal
onto the tangent plane at its closest target sample (so vertices slide along the surface). Pairs
are kept only when their normals agree (cos ≥ ``NORMAL_COS``) and they are closer than a
distance that shrinks over the schedule, and the target's border (where a scan or a bust is
cut) takes no part, so holes, cut necks, open eyes and mouths and inner parts (eyeballs, teeth)
do not attract the skin. (A target → reference term, pulling each reference vertex toward the
target points nearest to it, crumpled the skin around the nose and mouth on the ICT head, so
there is none.) Every term is
diagonal except the smoothness, so each iteration solves one sparse SPD system
``(W + α LᵀL + β S) x = W q + α LᵀL x0 + β t`` for the three coordinates, and the
correspondences are recomputed between solves while α decreases (coarse to fine).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import cache
from types import ModuleType

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu
from scipy.spatial import cKDTree

from mimetic.errors import MeshError
from mimetic.mesh.closest import closest_points
from mimetic.mesh.geometry import (
    boundary_edges,
    closest_on_polyline,
    connected_components,
    face_normals,
    vertex_adjacency,
    vertex_normals,
)
from mimetic.mesh.model import Mesh

NORMAL_COS = 0.5  # pairs whose normals differ by more than 60° are ignored
MIN_SAMPLES = 40_000  # target surface samples (more for sparse targets, subsampled for dense ones)
MAX_SAMPLES = 200_000
CG_RTOL = 1e-7
CG_MAXITER = 300
OUTER_AREA_SHARE = 0.05  # components with less of the total area are inner parts (eyeballs, teeth)


@dataclass(frozen=True)
class Stage:
    """One step of the schedule: ``iterations`` solves at one stiffness.

    ``stiffness`` is α (unitless: data and smoothness rows are both in length units);
    ``max_distance_rel`` the pair cut-off as a fraction of the head size; ``landmark_weight`` β.
    """

    stiffness: float
    max_distance_rel: float
    landmark_weight: float
    iterations: int = 2


SCHEDULE: tuple[Stage, ...] = (
    Stage(50.0, 0.10, 10.0),
    Stage(20.0, 0.08, 5.0),
    Stage(8.0, 0.06, 2.0),
    Stage(3.0, 0.05, 1.0),
    Stage(1.0, 0.04, 0.5),
    Stage(0.4, 0.03, 0.3, iterations=3),
)


CURVE_WEIGHT = 2.0
"""A curve's vertices are bound to it at least this strongly (the landmark weight when larger): a lid
margin or the lips' line stays on the target's to the end, where the landmarks let go."""


@dataclass(frozen=True)
class Curve:
    """Reference vertices (k,) int64 that slide along a target ``polyline`` (p, 3), p ≥ 2: each is
    bound to its closest point on it, found again before every solve."""

    vertices: np.ndarray
    polyline: np.ndarray


@dataclass(frozen=True)
class TargetSurface:
    """Points and unit normals sampled on a target's outer surface.

    Attributes
    ----------
    points, normals : (m, 3) float64
        Samples (the vertices of the outer components plus area-weighted random points) and their
        interpolated unit normals, in the target's frame.
    vertices : (n, 3) float64
        The target's vertices.
    triangles : (f, 3) int64
        The target triangles kept as outer surface (parts with a small share of the area, such as
        eyeballs and teeth, and the faces on its border are left out).
    """

    points: np.ndarray
    normals: np.ndarray
    vertices: np.ndarray
    triangles: np.ndarray


def outer_faces(mesh: Mesh) -> np.ndarray:
    """Faces (f,) of the connected components holding at least ``OUTER_AREA_SHARE`` of the area,
    without the faces touching a border vertex (a cut neck or a hole is not surface to fit)."""
    _, labels = connected_components(mesh.faces, mesh.n_vertices)
    face_label = labels[mesh.faces[:, 0]]
    area = 0.5 * np.linalg.norm(face_normals(mesh.vertices, mesh.faces, unit=False), axis=1)
    per_component = np.bincount(face_label, weights=area)
    keep = per_component >= OUTER_AREA_SHARE * per_component.sum()
    border = np.zeros(mesh.n_vertices, dtype=bool)
    border[boundary_edges(mesh.faces).ravel()] = True
    keep_face = keep[face_label] & ~border[mesh.faces].any(axis=1)
    return np.nonzero(keep_face)[0]


def _no_surface_message(mesh: Mesh) -> str:
    """Why ``outer_faces`` found nothing to fit, and what to do about it."""
    _, labels = connected_components(mesh.faces, mesh.n_vertices)
    pieces = len(np.unique(labels[mesh.faces[:, 0]])) if len(mesh.faces) else 0
    area = 0.5 * np.linalg.norm(face_normals(mesh.vertices, mesh.faces, unit=False), axis=1)
    weld = (
        "weld its vertices (Blender: Mesh > Clean Up > Merge by Distance; trimesh: mesh.merge_vertices()) "
        "and export it again"
    )
    if not len(mesh.faces) or not np.isfinite(area).all() or area.sum() <= 0:
        faces = f"{len(mesh.faces):,} face{'s' if len(mesh.faces) != 1 else ''}"
        return (
            f"the mesh has no surface to fit ({faces}, total area {area.sum():.3g}): its "
            "faces are missing or degenerate (all corners at one point or on a line); export the head's "
            "surface with its faces"
        )
    share = np.bincount(labels[mesh.faces[:, 0]], weights=area) / area.sum()
    if share.max() < OUTER_AREA_SHARE:
        return (
            f"no connected surface covers {100 * OUTER_AREA_SHARE:.0f} % of the area: the mesh is in "
            f"{pieces:,} pieces for {len(mesh.faces):,} faces (the largest {100 * share.max():.2g} %), as a "
            f"triangle soup or a mesh exported without shared vertices is; {weld}"
        )
    return (
        f"every face of the mesh's large pieces touches an open border ({pieces:,} pieces for "
        f"{len(mesh.faces):,} faces), so there is no surface inside its borders to fit: the vertices look "
        f"unwelded; {weld}"
    )


def sample_surface(mesh: Mesh, *, seed: int = 0) -> TargetSurface:
    """Samples of ``mesh``'s outer surface: between ``MIN_SAMPLES`` and ``MAX_SAMPLES`` points.

    Raises
    ------
    MeshError
        When no outer surface remains (``outer_faces`` is empty or has no area): a triangle soup,
        a mesh without shared vertices, or one of zero area.
    """
    rng = np.random.default_rng(seed)
    faces = outer_faces(mesh)
    f = mesh.faces[faces]
    v = mesh.vertices
    kept_area = 0.5 * np.linalg.norm(face_normals(v, f.reshape(-1, 3), unit=False), axis=1).sum()
    if not len(faces) or not kept_area > 0:
        raise MeshError(_no_surface_message(mesh))
    vn = vertex_normals(v, mesh.faces)
    used = np.unique(f)
    if len(used) > MAX_SAMPLES:
        used = np.sort(rng.choice(used, MAX_SAMPLES, replace=False))
    points, normals = [v[used]], [vn[used]]
    extra = MIN_SAMPLES - len(used)
    if extra > 0:
        area = 0.5 * np.linalg.norm(face_normals(v, f.reshape(-1, 3), unit=False), axis=1)
        pick = rng.choice(len(f), extra, p=area / area.sum())
        r = rng.random((extra, 2))
        flip = r.sum(axis=1) > 1
        r[flip] = 1 - r[flip]
        bary = np.column_stack([1 - r.sum(axis=1), r])  # (extra, 3)
        points.append(np.einsum("kj,kjd->kd", bary, v[f[pick]]))
        normals.append(np.einsum("kj,kjd->kd", bary, vn[f[pick]]))
    n = np.concatenate(normals)
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-30)
    return TargetSurface(np.concatenate(points), n, v, mesh.faces[faces])


@dataclass(frozen=True)
class Registration:
    """The fitted reference.

    Attributes
    ----------
    vertices : (n, 3) float64
        Fitted positions of the registered vertices, in the target's frame.
    distance : (n,) float64
        Distance from each vertex to the target surface at the end (nan where the vertex had no
        compatible target point in the last step: holes, the far side of a face-only scan).
    solves : int
        Linear solves done.
    """

    vertices: np.ndarray
    distance: np.ndarray
    solves: int


def umbrella_laplacian(faces: np.ndarray, n: int) -> sp.csr_matrix:
    """The uniform Laplacian (n, n): ``(L x)_i = x_i − mean of its neighbours``."""
    adjacency = vertex_adjacency(faces, n).astype(np.float64)
    degree = np.asarray(adjacency.sum(axis=1)).ravel()
    inv = np.divide(1.0, degree, out=np.zeros_like(degree), where=degree > 0)
    return (sp.identity(n, format="csr") - sp.diags(inv) @ adjacency).tocsr()


def _with_diagonal(matrix: sp.spmatrix) -> tuple[sp.csr_matrix, np.ndarray]:
    """``matrix`` (n, n) in canonical CSR (sorted, no stored zeros: as ``sp.diags(d) + matrix`` is
    summed) and where its diagonal entries are in its ``data`` (n,), so the registration's system
    ``diags(d) + α matrix`` is a scaled copy with ``d`` added there rather than a sparse sum per solve.
    Every diagonal entry must be stored (LᵀL's are: sums of squares)."""
    out = matrix.tocsr()
    out.sum_duplicates()
    out.eliminate_zeros()
    rows = np.repeat(np.arange(out.shape[0]), np.diff(out.indptr))
    diagonal_at = np.flatnonzero(rows == out.indices)
    assert len(diagonal_at) == out.shape[0], "a diagonal entry of LᵀL is not stored"
    return out, diagonal_at


def _solve_spd(system: sp.csr_matrix, rhs: np.ndarray, guess: np.ndarray) -> np.ndarray:
    """Solve the SPD ``system`` (n, n) for the three columns of ``rhs`` (n, 3).

    Jacobi-preconditioned conjugate gradients warm-started at ``guess`` first: between schedule
    steps the solution moves little, so on a head the target covers this takes tens of
    iterations. Where much of the reference has no data (a face-only mask), the bi-Laplacian
    leaves it badly conditioned and CG stalls; then a sparse LU factorisation (symmetric mode)
    solves it directly, in about 0.2 s for 10k vertices.

    Each column takes the steps of ``scipy.sparse.linalg.cg(system, b, x0=x0, rtol=CG_RTOL,
    maxiter=CG_MAXITER, M=diags(1 / diagonal))`` with the same arithmetic, so the same bits; the three
    run side by side, sharing one pass over the matrix per step (``fit.kernels``), and a column
    stops where scipy's would.
    """
    assert rhs.shape[1] == 3, "the registration solves for three coordinates"
    indptr, indices = system.indptr.astype(np.uint64), system.indices.astype(np.uint64)
    b = np.ascontiguousarray(rhs.T)  # (3, n): each coordinate contiguous, as scipy's vectors are
    x = np.array(guess.T, order="C")
    atol = np.array([CG_RTOL * np.linalg.norm(b[d]) for d in range(3)])
    if _kernels().cg3(indptr, indices, system.data, 1.0 / system.diagonal(), b, x, atol, CG_MAXITER):
        return np.ascontiguousarray(x.T)
    lu = splu(system.tocsc(), permc_spec="MMD_AT_PLUS_A", options={"SymmetricMode": True})
    return lu.solve(rhs)


@cache
def _kernels() -> ModuleType:
    """``mimetic.fit.kernels``, imported on the first solve (numba loads in ~0.3 s)."""
    from mimetic.fit import kernels

    return kernels


def register(
    vertices: np.ndarray,
    faces: np.ndarray,
    target: TargetSurface,
    *,
    projectable: np.ndarray,
    size: float,
    landmarks: np.ndarray | None = None,
    landmark_targets: np.ndarray | None = None,
    landmark_weights: np.ndarray | None = None,
    curves: Sequence[Curve] = (),
    schedule: Sequence[Stage] | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Registration:
    """Fit a surface (the reference skin) to ``target``, starting from ``vertices``.

    Parameters
    ----------
    vertices : (n, 3) float64
        Start positions (already aligned and conformed), target units.
    faces : (m, 3) int64
        The reference's triangles (only used for its Laplacian and normals).
    target : TargetSurface
    projectable : (n,) bool
        Vertices that may take data terms (not the inner lips or the eye's conjunctiva).
    size : float
        Head size (height) in target units; distance cut-offs are fractions of it.
    landmarks : (k,) int64, optional
        Reference vertices bound to ``landmark_targets`` (k, 3) with ``landmark_weights`` (k,).
    curves : sequence of Curve
        Reference vertices that slide along target polylines (lid margins, the lips' line).
    progress : callable(done, total), optional
    """
    schedule = SCHEDULE if schedule is None else schedule
    x0 = np.asarray(vertices, dtype=np.float64)
    n = len(x0)
    lap = umbrella_laplacian(faces, n)
    ltl = (lap.T @ lap).tocsc()
    ltl_x0 = ltl @ x0
    smooth, diagonal_at = _with_diagonal(ltl)  # the systems' pattern: LᵀL's, the diagonal among it
    tree = cKDTree(target.points)
    lm = np.zeros(0, np.int64) if landmarks is None else np.asarray(landmarks, dtype=np.int64)
    lm_w = np.ones(len(lm)) if landmark_weights is None else np.asarray(landmark_weights, dtype=np.float64)
    candidates = np.nonzero(projectable)[0]
    x = x0.copy()
    total = sum(stage.iterations for stage in schedule)
    done = 0
    for stage in schedule:
        limit = stage.max_distance_rel * size
        for _ in range(stage.iterations):
            normals = vertex_normals(x, faces)
            weight = np.zeros(n)
            goal = np.zeros((n, 3))
            # reference → target: slide onto the tangent plane of the closest target sample
            dist, nearest = tree.query(x[candidates], distance_upper_bound=limit)
            ok = np.isfinite(dist)
            ids, near = candidates[ok], nearest[ok]
            ok = np.einsum("kd,kd->k", normals[ids], target.normals[near]) >= NORMAL_COS
            ids, near = ids[ok], near[ok]
            tn = target.normals[near]
            offset = np.einsum("kd,kd->k", x[ids] - target.points[near], tn)
            goal[ids] = x[ids] - offset[:, None] * tn
            weight[ids] = 1.0
            # landmarks
            diag = weight.copy()
            rhs = weight[:, None] * goal
            if len(lm):
                np.add.at(diag, lm, stage.landmark_weight * lm_w)
                np.add.at(rhs, lm, (stage.landmark_weight * lm_w)[:, None] * landmark_targets)
            pull = max(stage.landmark_weight, CURVE_WEIGHT)
            for curve in curves:
                seg, t, _ = closest_on_polyline(x[curve.vertices], curve.polyline)
                on = curve.polyline[seg] + t[:, None] * (curve.polyline[seg + 1] - curve.polyline[seg])
                np.add.at(diag, curve.vertices, pull)
                np.add.at(rhs, curve.vertices, pull * on)
            system = smooth.copy()  # diag(W + β S) + α LᵀL, entry for entry as scipy adds them
            system.data *= stage.stiffness
            system.data[diagonal_at] += diag
            x = _solve_spd(system, rhs + stage.stiffness * ltl_x0, x)
            done += 1
            if progress is not None:
                progress(done, total)
    distance = np.full(n, np.nan)
    distance[ids] = closest_points(target.vertices, target.triangles, x[ids]).distance
    return Registration(x, distance, done)
