"""Similarity transforms: Umeyama's closed-form fit and the axis-aligned orientation of a mesh.

A ``Similarity`` maps ``x ↦ s R x + t`` (``s`` > 0, ``R`` a rotation, det +1). ``fit_similarity``
is Umeyama (1991): the least-squares scale, rotation and translation between two point sets
with correspondence, optionally weighted.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from mimetic.errors import LandmarkError


@dataclass(frozen=True)
class Similarity:
    """``x ↦ scale · rotation @ x + translation``.

    Attributes
    ----------
    scale : float
        > 0, unitless (target length per source length).
    rotation : (3, 3) float64
        Proper rotation (det +1).
    translation : (3,) float64
        In target units.
    """

    scale: float
    rotation: np.ndarray
    translation: np.ndarray

    def __post_init__(self) -> None:
        for name in ("rotation", "translation"):
            array = np.array(getattr(self, name), dtype=np.float64)
            array.setflags(write=False)
            object.__setattr__(self, name, array)
        object.__setattr__(self, "scale", float(self.scale))

    @staticmethod
    def identity() -> Similarity:
        return Similarity(1.0, np.eye(3), np.zeros(3))

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Transformed points (k, 3) of ``points`` (k, 3)."""
        return self.scale * np.asarray(points, dtype=np.float64) @ self.rotation.T + self.translation

    def inverse(self) -> Similarity:
        rt = self.rotation.T
        return Similarity(1.0 / self.scale, rt, -(rt @ self.translation) / self.scale)

    def then(self, other: Similarity) -> Similarity:
        """The composition ``other ∘ self`` (apply self first)."""
        return Similarity(
            self.scale * other.scale,
            other.rotation @ self.rotation,
            other.scale * other.rotation @ self.translation + other.translation,
        )

    def matrix(self) -> np.ndarray:
        """The 4×4 homogeneous matrix."""
        m = np.eye(4)
        m[:3, :3] = self.scale * self.rotation
        m[:3, 3] = self.translation
        return m


def fit_similarity(
    source: np.ndarray, target: np.ndarray, *, weights: np.ndarray | None = None, scale: bool = True
) -> Similarity:
    """The similarity minimising ``Σ w_i |s R source_i + t − target_i|²`` (Umeyama 1991).

    Parameters
    ----------
    source, target : (k, 3) float64
        Corresponding points, k ≥ 3 and not all collinear.
    weights : (k,) float64, optional
        Non-negative; at least 3 positive.
    scale : bool
        False fixes s = 1 (a rigid fit).

    Raises
    ------
    LandmarkError
        When the points are too few or degenerate (collinear), so no rotation is determined.
    """
    src = np.asarray(source, dtype=np.float64)
    dst = np.asarray(target, dtype=np.float64)
    if src.shape != dst.shape or src.ndim != 2 or src.shape[1] != 3:
        raise ValueError(f"source and target must both be (k, 3); got {src.shape} and {dst.shape}")
    w = np.ones(len(src)) if weights is None else np.asarray(weights, dtype=np.float64)
    if np.count_nonzero(w > 0) < 3:
        raise LandmarkError(
            f"a similarity needs at least 3 weighted point pairs; got {np.count_nonzero(w > 0)}"
        )
    w = w / w.sum()
    mu_s, mu_d = w @ src, w @ dst
    a, b = src - mu_s, dst - mu_d
    cov = (b * w[:, None]).T @ a  # (3, 3) Σ w b aᵀ
    u, d, vt = np.linalg.svd(cov)
    if d[1] <= 1e-9 * max(d[0], 1e-300):
        raise LandmarkError(
            "the landmarks are (nearly) collinear, so the orientation is undetermined; "
            "give points spread over the face (eyes, nose tip, mouth corners, chin)"
        )
    sign = np.ones(3)
    sign[2] = np.sign(np.linalg.det(u @ vt)) or 1.0
    rotation = (u * sign) @ vt
    var_s = float(w @ (a * a).sum(axis=1))
    s = float((d * sign).sum() / var_s) if scale else 1.0
    return Similarity(s, rotation, mu_d - s * rotation @ mu_s)


def axis_rotations() -> np.ndarray:
    """The 24 proper rotations (24, 3, 3) that map coordinate axes onto coordinate axes."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            m = np.zeros((3, 3))
            m[np.arange(3), perm] = signs
            if np.linalg.det(m) > 0:
                out.append(m)
    return np.array(out)


def nearest_axis_rotation(rotation: np.ndarray) -> np.ndarray:
    """The axis-aligned rotation (3, 3) closest to ``rotation`` (largest trace of Qᵀ R)."""
    candidates = axis_rotations()
    return candidates[int(np.argmax(np.einsum("kij,ij->k", candidates, rotation)))]
