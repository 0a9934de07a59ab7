"""Choose the reference head's conformation (``HeadParams``) and pose from landmarks.

The landmarks of a generated head are close to linear in its 15 parameters over their ranges,
so a first-order model ``L(p) ≈ L(p0) + J (p − p0)`` (one finite-difference Jacobian of a low-
resolution head, computed once per process) turns the fit into alternating steps, each with a
closed-form or bounded linear solution:

1. the similarity taking the target landmarks onto the model's (Umeyama);
2. the parameters minimising ``Σ w_k |L_k(p) − T(target_k)|² + λ |(p − p0) / σ|²`` within
   ``PARAM_RANGES`` (``scipy.optimize.lsq_linear``), where σ is the prior spread of
   ``HeadParams.random`` and λ keeps unobserved parameters at their defaults.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np
from scipy.optimize import lsq_linear

from mimetic.fit.similarity import Similarity, fit_similarity
from mimetic.head.model import DEFAULT_RESOLUTION, make_head
from mimetic.head.params import PARAM_RANGES, HeadParams

MODEL_FILE = Path(__file__).with_name("data") / "landmark_model.json"
"""The model of the default resolution, shipped because it takes 16 head builds (~10 s) to compute."""
STEP = 0.02  # finite-difference step in each parameter (they are all near 1)
PRIOR_WEIGHT = 0.05  # λ, relative to the mean landmark weight, in cm² per prior standard deviation²
ROUNDS = 6


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
        Distance of each target landmark (mapped by ``to_model``) from the fitted model's, in cm.
    """

    params: HeadParams
    to_model: Similarity
    residual: np.ndarray


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
        Project landmark names (keys of ``Head.landmarks``).
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
    w = np.ones(len(names)) if weights is None else np.asarray(weights, dtype=np.float64)
    jac_k, l0_k, p0 = lm.jacobian[rows], lm.base[rows], lm.defaults  # (k, 3, 15), (k, 3), (15,)
    low = np.array([r[0] for r in PARAM_RANGES.values()])
    high = np.array([r[1] for r in PARAM_RANGES.values()])
    sigma = (high - low) / 4  # HeadParams.random's spread
    p = p0.copy()
    root_w = np.sqrt(w / w.mean())
    for _ in range(ROUNDS):
        model = l0_k + np.einsum("kdp,p->kd", jac_k, p - p0)
        to_model = fit_similarity(points, model, weights=w)
        aligned = to_model.apply(points)
        # min Σ w |l0 + J(p − p0) − aligned|² + λ |(p − p0)/σ|², p in range
        a = np.vstack(
            [(jac_k * root_w[:, None, None]).reshape(-1, len(p0)), np.diag(np.sqrt(PRIOR_WEIGHT) / sigma)]
        )
        b = np.concatenate([((aligned - l0_k) * root_w[:, None]).ravel(), np.zeros(len(p0))])
        p = p0 + lsq_linear(a, b, bounds=(low - p0, high - p0)).x
    model = l0_k + np.einsum("kdp,p->kd", jac_k, p - p0)
    to_model = fit_similarity(points, model, weights=w)
    params = HeadParams(**dict(zip(PARAM_RANGES, np.clip(p, low, high).tolist(), strict=True)))
    residual = np.linalg.norm(to_model.apply(points) - model, axis=1)
    return Conformation(params, to_model, residual)
