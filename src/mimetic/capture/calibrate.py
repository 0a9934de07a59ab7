"""Per-performer calibration: the capture's neutral frame mapped onto the rig, and the layout's
markers moved to where this performer's markers are.

A layout (``marker_set(rig, "ibug68")``) puts each marker at the rig's own landmark, which need not
be where a performer's marker sits: a jaw-line point a tracker puts on the silhouette, a brow marker
stuck a centimetre higher. Solving with markers in the wrong place reads the wrong skin's motion
and tilts the head. So, from the neutral frame (each marker's median around it):

1. **Similarity** ``S`` (capture → rig: scale, rotation, translation; Umeyama) from the neutral's
   fixed markers (not the sliding contour points) to the layout's virtual markers, iteratively
   reweighted (Cauchy weights, scale the median error) so a few badly placed layout markers do
   not tilt it. A mirror image fitting far better (swapped axes) or a scale contradicting the
   stated units is an error; missing units are guessed from the scale.
2. **Placement** (``place=True``): ``S`` refined so the fixed markers lie on the rig's skin:
   point-to-plane ICP (each marker's signed distance along the skin's normal at its closest point,
   Cauchy-weighted so a marker off the face does not pull). Nothing else holds ``S``: a pull toward
   the layout's positions, tried, biased it on ICT-FaceKit's performer (a 2 % smaller scale, markers
   placed 1-3 mm off at a weight of 0.05) more than the face's curvature lets noise slide it
   (0.4 mm). Every marker seen at the neutral is then placed at the skin point closest to
   ``S(P_j)``, less a soft threshold of ``PLACE_NOISE_SIGMAS`` times the neutral's noise (so the
   markers of a performer the layout already fits stay put); contour markers too, which moves
   each one along its contour to where the performer's contour point is at rest.
3. **Checks**: a fixed marker still farther than ``OFF_SKIN_REL`` of the head from the skin (a
   mislabelled marker, one on a hat) is named in a warning and left out of the solve.

The placed ``MarkerSet`` (``placed=True``) can be saved (``markers.save_marker_set``) and given
for every later take of the same performer, which is then not placed again.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from mimetic.capture.markers import MarkerSet, marker_normals, snap_to_skin, with_tangents
from mimetic.capture.trajectories import CaptureError
from mimetic.errors import MimeticWarning
from mimetic.fit.similarity import Similarity, fit_similarity
from mimetic.mesh.geometry import vertex_normals
from mimetic.mesh.units import UNIT_SCALE
from mimetic.rig.model import Rig

MIRROR_RATIO = 0.5
"""A neutral frame that a mirror image fits with less than this fraction of the error of a proper
rotation is a left-handed (axis-swapped) capture."""
UNITS_TOLERANCE = 2.0
"""The calibration's scale may differ from the stated units' by this factor (people differ in size)."""
ROBUST_ROUNDS = 5
CAUCHY_SCALE = 2.0
"""Weights 1 / (1 + (e / (CAUCHY_SCALE · median e))²) in the similarity's robust rounds."""
PLACE_ROUNDS = 20
PLACE_TOLERANCE_REL = 1e-5
"""Placement stops once a round moves the markers by less than this fraction of the head."""
PLACE_NOISE_SIGMAS = 3.0
OFF_SKIN_REL = 0.04
"""A placed fixed marker this far from the skin (a fraction of the head: 0.9 cm on a 22 cm head)
is taken for mislabelled and left out of the solve."""


@dataclass(frozen=True, eq=False)
class Calibration:
    """The neutral frame mapped onto the rig, and the markers placed on this performer.

    Arrays are read-only.

    Attributes
    ----------
    similarity : Similarity
        Capture → rig at the neutral.
    units : str or None
        The capture's length units (guessed from the scale when the capture did not say).
    markers : MarkerSet
        The markers: placed on this performer when ``place`` was asked, else the ones given.
    reference : (m, 3) float64
        Each marker at the neutral in the rig's frame, rig units: the calibrated capture where seen,
        else the marker on the rig.
    moved : (m,) float64
        How far placement moved each marker from where the layout put it, rig units (0 unplaced).
    off_skin : (m,) float64
        Distance of each calibrated neutral marker from the rig's skin, rig units (nan unseen).
    usable : (m,) bool
        False for markers left out of the solve (far off the skin at the neutral).
    """

    similarity: Similarity
    units: str | None
    markers: MarkerSet
    reference: np.ndarray
    moved: np.ndarray
    off_skin: np.ndarray
    usable: np.ndarray

    def __post_init__(self) -> None:
        for name in ("reference", "moved", "off_skin", "usable"):
            getattr(self, name).setflags(write=False)


def _rms(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


def _robust_similarity(source: np.ndarray, target: np.ndarray, *, scale: bool) -> Similarity:
    """Umeyama from ``source`` to ``target`` (k, 3), reweighted ``ROBUST_ROUNDS`` times."""
    weights = np.ones(len(source))
    similarity = fit_similarity(source, target, scale=scale)
    for _ in range(ROBUST_ROUNDS):
        error = np.linalg.norm(similarity.apply(source) - target, axis=1)
        typical = max(float(np.median(error)), 1e-12 * float(np.abs(target).max(initial=1.0)))
        weights = 1.0 / (1.0 + (error / (CAUCHY_SCALE * typical)) ** 2)
        similarity = fit_similarity(source, target, weights=weights, scale=scale)
    return similarity


def _checked_similarity(
    reference: np.ndarray, neutral: np.ndarray, *, units: str | None, rig_units: str | None, source: str
) -> tuple[Similarity, str | None]:
    """The robust similarity neutral → reference (k, 3), checked for mirroring and units."""
    similarity = _robust_similarity(neutral, reference, scale=True)
    mirrored = neutral * np.array([-1.0, 1.0, 1.0])
    mirror = _robust_similarity(mirrored, reference, scale=True)
    error = _rms(similarity.apply(neutral), reference)
    mirror_error = _rms(mirror.apply(mirrored), reference)
    if mirror_error < MIRROR_RATIO * error:
        raise CaptureError(
            f"{source}: the neutral frame fits the rig as a mirror image ({mirror_error:.3g} against "
            f"{error:.3g} rig units when rotated): two of its axes are swapped or one is flipped "
            "(a left-handed export). Fix the export (right-handed, +Y up, +Z toward the camera) or "
            "negate one axis of the file"
        )
    if rig_units not in UNIT_SCALE or units == "px":
        return similarity, units
    metres = similarity.scale * UNIT_SCALE[rig_units]  # metres per capture unit
    guess = min(("mm", "cm", "m"), key=lambda u: abs(np.log(UNIT_SCALE[u] / metres)))
    if units is None:
        return similarity, guess
    ratio = similarity.scale / (UNIT_SCALE[units] / UNIT_SCALE[rig_units])
    if not 1 / UNITS_TOLERANCE <= ratio <= UNITS_TOLERANCE:
        raise CaptureError(
            f"{source}: the file says its units are {units}, but the face it holds is {1 / ratio:.3g} "
            f"times the rig's size in those units; it looks like {guess}. Give the units as {guess} "
            "(CLI --units) or fix the file"
        )
    return similarity, units


def _place(rig: Rig, neutral: np.ndarray, normals: np.ndarray, similarity: Similarity) -> Similarity:
    """The similarity that puts the neutral's fixed markers (k, 3) on the rig's skin: point-to-plane
    ICP (Gauss-Newton on rotation, translation and log-scale about the markers' centroid; Cauchy
    weights on the distances), from ``similarity``; each marker on skin facing as its layout marker's
    ``normals`` (k, 3)."""
    mesh = rig.mesh
    skin_normals = vertex_normals(mesh.vertices, mesh.faces)
    s, R, t = similarity.scale, similarity.rotation, similarity.translation
    floor = PLACE_TOLERANCE_REL * rig.scale
    for _ in range(PLACE_ROUNDS):
        q = s * neutral @ R.T + t  # (k, 3) rig units
        skin = snap_to_skin(rig, q, normals)
        corners = mesh.faces[[p.face for p in skin.points]]  # (k, 3)
        bary = np.array([p.bary for p in skin.points])  # (k, 3)
        n = np.einsum("kc,kcd->kd", bary, skin_normals[corners])
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        r = np.einsum("kd,kd->k", n, q - skin.positions)  # signed distances from the skin
        w = 1.0 / (1.0 + (r / (CAUCHY_SCALE * max(float(np.median(np.abs(r))), floor))) ** 2)
        c = q.mean(axis=0)
        # ∂r/∂(ω, δt, ρ) for q' = c + e^ρ exp([ω]×) (q − c) + δt
        J = np.concatenate([np.cross(q - c, n), n, np.einsum("kd,kd->k", n, q - c)[:, None]], axis=1)
        step = np.linalg.solve(J.T @ (w[:, None] * J) + 1e-12 * np.eye(7), -J.T @ (w * r))
        dR = _rotation(step[:3])
        R = dR @ R
        s = s * np.exp(step[6])
        t = np.exp(step[6]) * (dR @ (t - c)) + c + step[3:6]
        moved = max(float(np.abs(step[[0, 1, 2, 6]]).max()) * rig.scale, float(np.abs(step[3:6]).max()))
        if moved <= floor:
            break
    return Similarity(s, R, t)


def _rotation(omega: np.ndarray) -> np.ndarray:
    """exp([ω]×) (3, 3) of a rotation vector (3,)."""
    angle = float(np.linalg.norm(omega))
    if angle == 0.0:
        return np.eye(3)
    k = omega / angle
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * K @ K


def calibrate_performer(
    rig: Rig,
    markers: MarkerSet,
    neutral: np.ndarray,
    *,
    units: str | None,
    place: bool = True,
    noise: float = 0.0,
    source: str = "capture",
) -> Calibration:
    """Map a capture's neutral frame onto ``rig`` and place ``markers`` where the performer's are.

    Parameters
    ----------
    rig : Rig
    markers : MarkerSet
        The layout on the rig, in the order of ``neutral``.
    neutral : (m, 3) float64
        Each marker at the neutral, capture units; NaN for markers not seen there.
    units : str or None
        The capture's length units ("px" for image points), None when unknown.
    place : bool
        Move the markers to the performer's (step 2 of the module docstring); False keeps them
        (a marker file placed on an earlier take of the same performer).
    noise : float
        The neutral's noise per coordinate, in rig units: a marker is moved by its distance from the
        layout's less ``PLACE_NOISE_SIGMAS`` times that (3D), so noise alone moves none.
    source : str
        The capture's name, for messages.

    Raises
    ------
    CaptureError
        Fewer than 4 fixed markers seen at the neutral, a mirror-image capture, or a scale that
        contradicts ``units``.
    """
    seen = np.isfinite(neutral).all(axis=1)
    fixed = seen & ~markers.sliding
    if fixed.sum() < 4:
        raise CaptureError(
            f"{source}: the neutral frame shows {fixed.sum()} fixed (non-contour) markers; calibrating "
            "needs at least 4. Pick a frame where the face is seen (CLI --neutral-frame)"
        )
    layout = markers.positions(rig)  # (m, 3) rig units
    similarity, units = _checked_similarity(
        layout[fixed], neutral[fixed], units=units, rig_units=rig.units, source=source
    )
    scale = rig.scale
    moved = np.zeros(len(neutral))
    if place:
        normals = marker_normals(markers, rig)
        similarity = _place(rig, neutral[fixed], normals[fixed], similarity)
        # each marker moved as far as the neutral's noise lets it be told from the layout's
        target = similarity.apply(neutral[seen])
        offset = target - layout[seen]
        distance = np.linalg.norm(offset, axis=1, keepdims=True)
        keep = np.clip(
            1.0 - PLACE_NOISE_SIGMAS * np.sqrt(3.0) * noise / np.maximum(distance, 1e-300), 0.0, 1.0
        )
        skin = snap_to_skin(rig, layout[seen] + keep * offset, normals[seen])
        points = list(markers.points)
        for j, point in zip(np.flatnonzero(seen), skin.points, strict=True):
            points[j] = point
        placed = with_tangents(markers.replace(points=tuple(points), placed=True), rig)
        moved = np.linalg.norm(placed.positions(rig) - layout, axis=1)
        markers = placed
    reference = markers.positions(rig)
    reference[seen] = similarity.apply(neutral[seen])
    off_skin = np.full(len(neutral), np.nan)
    off_skin[seen] = snap_to_skin(rig, reference[seen], marker_normals(markers, rig)[seen]).distances
    usable = ~(fixed & (off_skin > OFF_SKIN_REL * scale))
    if not usable.all():
        unit = rig.units or "units"
        bad = [f"{markers.names[j]} ({off_skin[j]:.2g} {unit})" for j in np.flatnonzero(~usable)]
        warnings.warn(
            f"{source}: marker(s) {', '.join(bad[:5])} sit far from the face at the neutral frame "
            "(mislabelled, or not on the skin); solving without them",
            MimeticWarning,
            stacklevel=3,
        )
    return Calibration(similarity, units, markers, reference, moved, off_skin, usable)
