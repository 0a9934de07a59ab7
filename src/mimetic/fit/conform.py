"""Choose the reference head's conformation (``HeadParams``) and pose from landmarks.

The landmarks of a generated head are close to linear in its 15 parameters over their ranges,
so a first-order model ``L(p) ≈ L(p0) + J (p − p0)`` (one finite-difference Jacobian of a low-
resolution head, computed once per process) turns the fit into alternating steps, each with a
closed-form or bounded linear solution:

1. the similarity taking the target landmarks onto the model's (Umeyama);
2. the parameters minimising ``Σ w_k |L_k(p) − T(target_k)|² + λ |(p − p0) / σ|²`` within
   ``PARAM_RANGES`` (``scipy.optimize.lsq_linear``), where σ is the prior spread of
   ``HeadParams.random`` and λ keeps unobserved parameters at their defaults.

Outline landmarks slide. iBUG's 17 contour points (``OUTLINE``: jaw_R1 … jaw_R8, menton,
jaw_L8 … jaw_L1) mark the visible face outline, not fixed anatomy: where along the outline each
one sits, and how far in front of the silhouette a 3D landmark set puts them, differ from one
scheme to the next. The generated head's own jaw_* points lie on its frontal silhouette; the
68-point sets of ICT-FaceKit, OpenFace and MediaPipe (through the usual 468 → 68 map) all put
them on the cheek and chin, 2-6 cm in front of it and 6-18 % of the eye distance inside its
outline seen from the front. So an outline point constrains only its distance across the
model's outline, in the frontal (x, y) plane of the reference frame: the polyline through the
model's 17 outline landmarks, continued past jaw_R1 and jaw_L1 towards the temples
(``outline_feet``). The distance
is measured from that outline moved by one ``outline_offset`` δ for the whole file (a 16th
unknown of step 2, within ``OUTLINE_OFFSET_RANGE_REL``). In step 1 an outline point's target is
its own position moved onto the (offset) outline along the normal (point-to-line, re-associated
every round); in step 2 it adds one row, the outline normal times the Jacobian of its foot point.
Outline points weigh ``SLIDING_WEIGHT`` times a Cauchy factor ``1 / (1 + (r / c)²)``,
``c = SLIDING_SCALE_REL`` of the eye distance: on generated heads fitted with an iBUG-like outline
(or their own jaw_* points), more weight pulled the conformation away from the true correspondence
(front-skin error of the fitted head, mean over three heads: 0.223 % of the head height without
outline, 0.223 % at weight 0.1, 0.232 % at 0.5, 0.244 % at 1), so the outline mostly serves the
gate (``fit.report``), which measures each outline point across the outline. ``menton`` slides
only when jaw_* points are given too (then it is iBUG point 9, the outline's lowest point); alone
it is the anatomical menton, fitted as a point. Other silhouette-like project landmarks (zygion,
gonion, tragion) are anatomical definitions and fit as points.

Point landmarks further than ``TRUSTED_REL`` of the eye distance from the model lose weight as
``(c / r)²``: a few wrong points then neither drag the fit nor hide among the others in the
report. On real heads every point lies within 18 % and keeps its full weight.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
from scipy.optimize import lsq_linear

from mimetic.fit.similarity import Similarity, fit_similarity
from mimetic.head.landmarks import IBUG68
from mimetic.head.model import DEFAULT_RESOLUTION, make_head
from mimetic.head.params import PARAM_RANGES, HeadParams

MODEL_FILE = Path(__file__).with_name("data") / "landmark_model.json"
"""The model of the default resolution, shipped because it takes 16 head builds (~10 s) to compute."""
STEP = 0.02  # finite-difference step in each parameter (they are all near 1)
PRIOR_WEIGHT = 0.05  # λ, relative to the mean landmark weight, in cm² per prior standard deviation²
ROUNDS = 6

OUTLINE: tuple[str, ...] = IBUG68[:17]
"""The face outline in order (iBUG 1-17): from the subject's right ear round the chin to the left."""
OUTLINE_EXTENSION = 3.0  # past jaw_R1 / jaw_L1, in end segments (~4 cm, up to the temples)
SLIDING_WEIGHT = 0.1  # of an outline point (1 row) relative to a point landmark (3 rows)
SLIDING_SCALE_REL = 0.1  # c of the Cauchy weight, fraction of the eye distance
TRUSTED_REL = 0.25  # point landmarks this far off (fraction of the eye distance) lose weight as (c / r)²
OUTLINE_OFFSET_RANGE_REL = (-0.35, 0.05)  # δ, fraction of the eye distance (negative: inside)
EYE_CORNERS = ("eye_outer_corner_L", "eye_outer_corner_R")


@dataclass(frozen=True)
class Conformation:
    """The result of ``fit_conformation``.

    Attributes
    ----------
    params : HeadParams
        The fitted conformation.
    to_model : Similarity
        Maps the target's frame onto the reference head's (cm, +Y up, +Z forward).
    residual : (k,) float64
        Misfit of each target landmark (mapped by ``to_model``) in cm: the distance from the
        fitted model's landmark, or for a sliding outline point its distance across the model's
        outline (moved by ``outline_offset``), in the frontal plane.
    sliding : (k,) bool
        The landmarks fitted as outline points (see ``sliding_landmarks``).
    outline_offset : float
        δ, cm in the reference frame: how far outside the model's outline the file's outline lies
        (negative: inside; 0 when there are no outline points).
    weights : (k,) float64
        The final weight of each landmark: the given confidence, times ``SLIDING_WEIGHT`` and the
        robust factor for outline points.
    """

    params: HeadParams
    to_model: Similarity
    residual: np.ndarray
    sliding: np.ndarray
    outline_offset: float
    weights: np.ndarray


@dataclass(frozen=True)
class LandmarkModel:
    """Landmark positions of the generated head, linear in its parameters.

    Attributes
    ----------
    resolution : int
        The ``make_head`` resolution the landmarks belong to.
    names : tuple of str, length k
    base : (k, 3) float64
        Landmarks of the default head, cm.
    jacobian : (k, 3, 15) float64
        d(landmark)/d(parameter), cm per unit parameter, parameters in ``PARAM_RANGES`` order.
    defaults : (15,) float64
    """

    resolution: int
    names: tuple[str, ...]
    base: np.ndarray
    jacobian: np.ndarray
    defaults: np.ndarray

    def positions(self, params: np.ndarray, rows: np.ndarray | None = None) -> np.ndarray:
        """Landmarks (k, 3) for the parameter vector ``params`` (15,), optionally only ``rows``."""
        rows = slice(None) if rows is None else rows
        return self.base[rows] + np.einsum("kdp,p->kd", self.jacobian[rows], params - self.defaults)


def compute_landmark_model(resolution: int) -> LandmarkModel:
    """Finite differences of ``make_head`` at ``resolution`` (16 head builds)."""
    base = make_head(HeadParams(), resolution)
    names = tuple(base.landmarks)
    defaults = np.array(list(HeadParams().as_dict().values()))
    l0 = base.landmark_positions(list(names))
    columns = []
    for name, value in HeadParams().as_dict().items():
        head = make_head(HeadParams().with_values(**{name: value + STEP}), resolution)
        columns.append((head.landmark_positions(list(names)) - l0) / STEP)
    return LandmarkModel(resolution, names, l0, np.stack(columns, axis=-1), defaults)


def write_landmark_model(model: LandmarkModel, path: Path = MODEL_FILE) -> None:
    """Save ``model`` as JSON (regenerate the shipped file after changing the head generator)."""
    data = {
        "resolution": model.resolution,
        "params": list(PARAM_RANGES),
        "names": list(model.names),
        "base": model.base.round(9).tolist(),
        "jacobian": model.jacobian.round(9).tolist(),
        "defaults": model.defaults.tolist(),
    }
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(data, separators=(",", ":")))


@lru_cache(maxsize=4)
def landmark_model(resolution: int = DEFAULT_RESOLUTION) -> LandmarkModel:
    """The landmark model at ``resolution``: the shipped file when it matches, else computed."""
    if MODEL_FILE.is_file():
        data = json.loads(MODEL_FILE.read_text())
        if data["resolution"] == resolution and data["params"] == list(PARAM_RANGES):
            return LandmarkModel(
                resolution,
                tuple(data["names"]),
                np.array(data["base"]),
                np.array(data["jacobian"]),
                np.array(data["defaults"]),
            )
    return compute_landmark_model(resolution)


# --------------------------------------------------------------------------- the outline


def sliding_landmarks(names: list[str] | tuple[str, ...]) -> np.ndarray:
    """Which of ``names`` (k,) bool are fitted as sliding outline points: every jaw_* point, and
    ``menton`` when jaw_* points are given too (iBUG point 9, the outline's lowest point)."""
    jaw = np.array([n in OUTLINE and n != "menton" for n in names], dtype=bool)
    return jaw | (np.array([n == "menton" for n in names], dtype=bool) & jaw.any())


@dataclass(frozen=True)
class OutlineFeet:
    """Where points lie across an outline (see ``outline_feet``).

    Attributes
    ----------
    distance : (k,) float64
        Signed distance in the frontal (x, y) plane from the outline, positive outside it.
    normal : (k, 3) float64
        The outline's outward unit normal at each foot point, in the (x, y) plane (z = 0).
    coefficients : (k, 17) float64
        Each foot point as a combination of the 17 ``OUTLINE`` landmark positions.
    """

    distance: np.ndarray
    normal: np.ndarray
    coefficients: np.ndarray


def _outline_vertices() -> np.ndarray:
    """(19, 17): the polyline's vertices as combinations of the ``OUTLINE`` landmarks: the 17 and
    one point past each end, ``OUTLINE_EXTENSION`` end segments further on."""
    k = len(OUTLINE)
    c = np.zeros((k + 2, k))
    c[1:-1] = np.eye(k)
    c[0, :2] = (1 + OUTLINE_EXTENSION, -OUTLINE_EXTENSION)
    c[-1, -2:] = (-OUTLINE_EXTENSION, 1 + OUTLINE_EXTENSION)
    return c


def outline_feet(outline: np.ndarray, points: np.ndarray) -> OutlineFeet:
    """The nearest points of the face outline to ``points``, seen from the front.

    Parameters
    ----------
    outline : (17, 3) float64
        Positions of the ``OUTLINE`` landmarks in the reference frame (+Y up, +Z forward).
    points : (k, 3) float64
        Points in the same frame; only their x and y matter.
    """
    combine = _outline_vertices()  # (19, 17)
    vertices = (combine @ outline)[:, :2]  # (19, 2)
    a, ab = vertices[:-1], np.diff(vertices, axis=0)  # (18, 2) segment starts and directions
    p = np.asarray(points, dtype=np.float64)[:, None, :2]  # (k, 1, 2)
    u = np.clip(np.einsum("ksd,sd->ks", p - a, ab) / np.einsum("sd,sd->s", ab, ab), 0.0, 1.0)  # (k, 18)
    foot = a + u[..., None] * ab  # (k, 18, 2)
    gap = np.linalg.norm(p - foot, axis=2)
    s = np.argmin(gap, axis=1)
    k = np.arange(len(s))
    u, foot, gap = u[k, s], foot[k, s], gap[k, s]
    tangent = ab[s] / np.linalg.norm(ab[s], axis=1, keepdims=True)
    normal = np.column_stack([tangent[:, 1], -tangent[:, 0]])  # right of the direction of travel: outward
    # past a corner the nearest point is the vertex: measure along the line to it instead
    corner = ((u == 0.0) | (u == 1.0)) & (gap > 1e-12)
    away = (p[:, 0] - foot) / np.maximum(gap, 1e-300)[:, None]
    normal[corner] = away[corner] * np.sign(np.einsum("kd,kd->k", away[corner], normal[corner]))[:, None]
    distance = np.einsum("kd,kd->k", p[:, 0] - foot, normal)
    coefficients = (1.0 - u)[:, None] * combine[s] + u[:, None] * combine[s + 1]
    return OutlineFeet(distance, np.column_stack([normal, np.zeros(len(s))]), coefficients)


def eye_distance(model: LandmarkModel, positions: np.ndarray) -> float:
    """Distance (cm) between the outer eye corners in ``positions`` (all the model's landmarks)."""
    left, right = (model.names.index(n) for n in EYE_CORNERS)
    return float(np.linalg.norm(positions[left] - positions[right]))


# --------------------------------------------------------------------------- the fit


def fit_conformation(
    names: list[str],
    points: np.ndarray,
    *,
    weights: np.ndarray | None = None,
    resolution: int = DEFAULT_RESOLUTION,
) -> Conformation:
    """Fit ``HeadParams`` and a similarity to landmarks given in the target's frame.

    Parameters
    ----------
    names : list of str, length k
        Project landmark names (keys of ``Head.landmarks``). Outline points (``sliding_landmarks``)
        slide along the face outline.
    points : (k, 3) float64
        Their positions on the target, in the target's units and frame.
    weights : (k,) float64, optional
        Confidence of each landmark (1 by default).
    resolution : int
        Resolution of the reference head the landmarks refer to.
    """
    lm = landmark_model(resolution)
    index = {n: i for i, n in enumerate(lm.names)}
    rows = np.array([index[n] for n in names])
    outline_rows = np.array([index[n] for n in OUTLINE])
    points = np.asarray(points, dtype=np.float64)
    w = np.ones(len(names)) if weights is None else np.asarray(weights, dtype=np.float64)
    slide = sliding_landmarks(names)
    fixed = ~slide
    n_params = len(lm.defaults)
    jac_k, l0_k, p0 = lm.jacobian[rows], lm.base[rows], lm.defaults  # (k, 3, 15), (k, 3), (15,)
    jac_o, l0_o = lm.jacobian[outline_rows], lm.base[outline_rows]  # (17, 3, 15), (17, 3)
    low = np.array([r[0] for r in PARAM_RANGES.values()])
    high = np.array([r[1] for r in PARAM_RANGES.values()])
    sigma = (high - low) / 4  # HeadParams.random's spread
    prior = np.diag(np.sqrt(PRIOR_WEIGHT) / sigma)  # (15, 15)
    p, offset = p0.copy(), 0.0
    first = fixed if np.count_nonzero(fixed & (w > 0)) >= 3 else np.ones(len(names), dtype=bool)
    to_model = fit_similarity(points[first], l0_k[first], weights=w[first])

    def state(p: np.ndarray):
        model_all = lm.positions(p)
        return model_all[rows], model_all[outline_rows], eye_distance(lm, model_all)

    def robust(aligned: np.ndarray, model: np.ndarray, feet: OutlineFeet, offset: float, iod: float):
        """The weight (k,) of each landmark: its confidence, for outline points times
        SLIDING_WEIGHT and a Cauchy factor, for point landmarks beyond TRUSTED_REL times (c / r)²."""
        out = w.copy()
        r = (feet.distance - offset) / (SLIDING_SCALE_REL * iod)
        out[slide] *= SLIDING_WEIGHT / (1.0 + r**2)
        r = np.linalg.norm(aligned[fixed] - model[fixed], axis=1) / (TRUSTED_REL * iod)
        out[fixed] /= np.maximum(r, 1.0) ** 2
        return out

    for round_ in range(ROUNDS + 1):
        model, outline, iod = state(p)
        aligned = to_model.apply(points)
        feet = outline_feet(outline, aligned[slide])
        wk = robust(aligned, model, feet, offset, iod)
        # 1. similarity: outline points onto the offset outline, keeping their depth and place along it
        goal = model.copy()
        goal[slide] = aligned[slide] - (feet.distance - offset)[:, None] * feet.normal
        to_model = fit_similarity(points, goal, weights=wk)
        aligned = to_model.apply(points)
        feet = outline_feet(outline, aligned[slide])
        if round_ == ROUNDS:
            break
        # 2. parameters and offset: min Σ w |l0 + J(p − p0) − aligned|² + Σ_outline w (n·(f(p) − a) + δ)²
        #    + λ |(p − p0)/σ|², p in range, δ in OUTLINE_OFFSET_RANGE_REL × iod
        root = np.sqrt(wk / w.mean())
        a_fixed = (jac_k[fixed] * root[fixed, None, None]).reshape(-1, n_params)
        b_fixed = ((aligned[fixed] - l0_k[fixed]) * root[fixed, None]).ravel()
        jac_feet = np.einsum("kj,jdp->kdp", feet.coefficients, jac_o)  # (s, 3, 15)
        a_slide = np.einsum("kd,kdp->kp", feet.normal, jac_feet) * root[slide, None]
        b_slide = np.einsum("kd,kd->k", feet.normal, aligned[slide] - feet.coefficients @ l0_o) * root[slide]
        a = np.vstack([a_fixed, a_slide, prior])
        b = np.concatenate([b_fixed, b_slide, np.zeros(n_params)])
        column = np.concatenate([np.zeros(len(a_fixed)), root[slide], np.zeros(n_params)])
        lo_rel, hi_rel = OUTLINE_OFFSET_RANGE_REL
        if slide.any():
            a = np.column_stack([a, column])
            x = lsq_linear(
                a, b, bounds=(np.append(low - p0, lo_rel * iod), np.append(high - p0, hi_rel * iod))
            ).x
            p, offset = p0 + x[:n_params], float(x[n_params])
        else:
            p = p0 + lsq_linear(a, b, bounds=(low - p0, high - p0)).x
    p = np.clip(p, low, high)
    model, outline, iod = state(p)
    params = HeadParams(**dict(zip(PARAM_RANGES, p.tolist(), strict=True)))
    residual = np.linalg.norm(aligned - model, axis=1)
    residual[slide] = np.abs(feet.distance - offset)
    return Conformation(params, to_model, residual, slide, offset, robust(aligned, model, feet, offset, iod))
