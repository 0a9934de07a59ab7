"""How well the reference fits a user's mesh, and whether the mesh is a head at all.

Residuals are distances between the fitted reference and the user's surface, in % of the head
diagonal (the bounding-box diagonal of the fitted reference skin, so a bust's shoulders do not
dilute them):

* ``surface``: from each fitted reference skin vertex that had a compatible target point (the
  fit's own measure, what ``trimesh.registration`` reports for its source);
* ``coverage``: the share of the reference face (skin vertices looking forward) that found the
  target: a face-only scan covers the face, a cube does not look like one;
* per landmark: the target landmark against the fitted reference's, in % of the inter-ocular
  distance (outer eye corners) and in the user's units; for outline points (``sliding``, see
  ``fit.conform``) the distance across the fitted reference's face outline, seen from the front,
  after moving that outline by the median of those distances (the file's outline convention);
* per region: the mean surface residual of each reference region, flagged above
  ``POOR_REGION_PCT``.

The reject gate fails a fit whose landmarks cannot be explained by a head (landmark RMS after the
similarity and conformation fit above ``MAX_LANDMARK_RMS_PCT`` of the IOD, or any one landmark
further than ``MAX_LANDMARK_PCT`` from where the conformed head has it; the message names the worst
ones, with their iBUG numbers), whose face coverage is
below ``MIN_COVERAGE``, whose mean residual is above ``MAX_MEAN_PCT``, or whose face had to move
more than ``MAX_DEFORMATION_PCT`` from the conformed reference to fit (the surface is not face-
shaped: a box or a sphere can be covered, but only by flattening the nose).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from mimetic.atomic import atomic_write
from mimetic.fit.conform import OUTLINE, outline_feet
from mimetic.fit.reference import ReferenceFit, projectable_vertices
from mimetic.head.landmarks import IBUG68
from mimetic.head.topology import build_topology

POOR_REGION_PCT = 1.0
MAX_LANDMARK_RMS_PCT = 15.0
MAX_LANDMARK_PCT = 30.0  # any one landmark; in real 68-point files (ICT, MediaPipe, OpenFace) at most 18 %
NAMED_LANDMARK_PCT = 20.0  # a refusal names every landmark further off than this (at most 8)
MIN_COVERAGE = 0.45  # MediaPipe's canonical face mask covers 66 % of the reference face
MAX_MEAN_PCT = 1.5
MAX_DEFORMATION_PCT = 4.0  # heads (ICT, MediaPipe, generated) need at most 1.4 %; a box 8 %


@dataclass(frozen=True)
class FitReport:
    """The fit's numbers (see the module docstring); JSON-safe fields only.

    Attributes
    ----------
    units : str
        The user's units; ``head_diagonal`` and the ``*_units`` values are in them.
    head_diagonal : float
    mean_pct, p95_pct, max_pct : float
        Surface residual of the fitted reference, % of the head diagonal.
    coverage : float
        In [0, 1].
    deformation_pct : float
        Mean distance the registration moved the reference face from its conformed start, % of
        the head diagonal: large when the surface is not shaped like a face (a box flattens it).
    landmark_rms_pct : float
        % of the inter-ocular distance.
    landmarks : dict name -> {"error_pct_iod": float, "error_units": float, "sliding": bool}
        The fitted reference's landmarks against the user's (outline points: across the outline).
    regions : dict name -> mean residual, % of the head diagonal
    poor_regions : list of str
    accepted : bool
    reasons : list of str
        Why the gate failed (empty when accepted).
    params : dict
        The fitted ``HeadParams``.
    scale : float
        Reference units (cm of the default head) per user unit.
    """

    units: str
    head_diagonal: float
    mean_pct: float
    p95_pct: float
    max_pct: float
    coverage: float
    deformation_pct: float
    landmark_rms_pct: float
    landmarks: dict
    regions: dict
    poor_regions: list
    accepted: bool
    reasons: list
    params: dict
    scale: float

    def summary(self) -> str:
        """A few lines for a terminal."""
        lines = [
            f"surface residual: mean {self.mean_pct:.3f} %, p95 {self.p95_pct:.3f} %, "
            f"max {self.max_pct:.3f} % of the head diagonal ({self.head_diagonal:.4g} {self.units})",
            f"face coverage: {100 * self.coverage:.1f} %; deformation: {self.deformation_pct:.2f} %; "
            f"landmark RMS: {self.landmark_rms_pct:.2f} % of the IOD",
        ]
        if self.poor_regions:
            lines.append(f"regions fitting poorly (> {POOR_REGION_PCT} %): {', '.join(self.poor_regions)}")
        lines.append("accepted" if self.accepted else "REJECTED: " + "; ".join(self.reasons))
        return "\n".join(lines)

    def to_json(self) -> str:
        return json.dumps(asdict(self), indent=2)

    def save(self, path: str | Path) -> Path:
        """Write the report as JSON (atomically)."""
        path = Path(path)
        with atomic_write(path, "w") as handle:
            handle.write(self.to_json())
        return path


def fit_report(fit: ReferenceFit, units: str) -> FitReport:
    """The report of a reference fit (see the module docstring)."""
    head = fit.head
    skin = head.mesh.vertices[: head.n_skin]
    model_per_user = fit.conformation.to_model.scale  # reference-frame length per user unit
    diagonal_model = float(np.linalg.norm(np.ptp(skin, axis=0)))
    distance = fit.registration.distance  # (n_skin,) reference units, nan where unmatched
    pct = 100.0 * distance / diagonal_model
    matched = np.isfinite(pct)
    front = build_topology(head.resolution).directions[:, 2] > 0.3
    face = front & projectable_vertices(head)
    coverage = float(matched[face].mean())
    moved = np.linalg.norm(skin - fit.start.mesh.vertices[: head.n_skin], axis=1)
    deformation_pct = float(100.0 * moved[face].mean() / diagonal_model)
    values = pct[matched]
    mean_pct = float(values.mean()) if len(values) else float("inf")
    p95_pct = float(np.percentile(values, 95)) if len(values) else float("inf")
    max_pct = float(values.max()) if len(values) else float("inf")

    corners = [n for n in ("eye_outer_corner_L", "eye_outer_corner_R") if n in head.landmarks]
    iod = float(np.linalg.norm(np.subtract(*head.landmark_positions(corners)))) if len(corners) == 2 else 1.0
    fitted = head.landmark_positions(list(fit.landmark_names))
    errors = np.linalg.norm(fitted - fit.landmark_targets, axis=1)
    sliding = fit.conformation.sliding
    if sliding.any():
        across = outline_feet(head.landmark_positions(list(OUTLINE)), fit.landmark_targets[sliding]).distance
        errors[sliding] = np.abs(across - np.median(across))
    landmarks = {
        name: {
            "error_pct_iod": float(100 * e / iod),
            "error_units": float(e / model_per_user),
            "sliding": bool(b),
        }
        for name, e, b in zip(fit.landmark_names, errors, sliding, strict=True)
    }
    conform_pct = 100 * fit.conformation.residual / iod
    conform_rms_pct = float(np.sqrt(np.mean(conform_pct**2)))
    regions = {}
    for name, ids in head.regions.items():
        ids = ids[ids < head.n_skin]
        ok = ids[matched[ids]]
        if len(ok) >= max(3, len(ids) // 4):
            regions[name] = float(pct[ok].mean())
    poor = sorted(n for n, v in regions.items() if v > POOR_REGION_PCT)
    reasons = []
    reason = landmark_reason(fit, conform_pct, conform_rms_pct, model_per_user, units)
    if reason:
        reasons.append(reason)
    if coverage < MIN_COVERAGE:
        reasons.append(
            f"only {100 * coverage:.0f} % of the reference face found the surface (at least "
            f"{100 * MIN_COVERAGE:.0f} % needed): is this a head, with the face where the landmarks say?"
        )
    if deformation_pct > MAX_DEFORMATION_PCT:
        reasons.append(
            f"the reference face had to move {deformation_pct:.1f} % of the head diagonal to fit (limit "
            f"{MAX_DEFORMATION_PCT} %): the surface is not shaped like a face where the landmarks are"
        )
    if mean_pct > MAX_MEAN_PCT:
        reasons.append(
            f"mean surface residual {mean_pct:.2f} % of the head diagonal (limit {MAX_MEAN_PCT} %)"
        )
    return FitReport(
        units=units,
        head_diagonal=diagonal_model / model_per_user,
        mean_pct=mean_pct,
        p95_pct=p95_pct,
        max_pct=max_pct,
        coverage=coverage,
        deformation_pct=deformation_pct,
        landmark_rms_pct=float(100 * np.sqrt(np.mean(errors**2)) / iod),
        landmarks=landmarks,
        regions=regions,
        poor_regions=poor,
        accepted=not reasons,
        reasons=reasons,
        params=fit.conformation.params.as_dict(),
        scale=float(model_per_user),
    )


def ibug_label(name: str) -> str:
    """``name`` with its iBUG 68-point number when it has one: ``"menton = ibug68_09"``."""
    return f"{name} = ibug68_{IBUG68.index(name) + 1:02d}" if name in IBUG68 else name


def landmark_reason(
    fit: ReferenceFit, conform_pct: np.ndarray, rms_pct: float, model_per_user: float, units: str
) -> str:
    """Why the landmarks fail the gate, naming the worst ones and the fix; "" when they pass.

    ``conform_pct`` (k,) is each landmark's conformation residual in % of the eye distance. The text
    is a clause without a final full stop, so callers can append their own advice.
    """
    far = conform_pct > MAX_LANDMARK_PCT
    if rms_pct <= MAX_LANDMARK_RMS_PCT and not far.any():
        return ""
    order = np.argsort(-conform_pct)
    named = int(np.sum(conform_pct > NAMED_LANDMARK_PCT))
    shown = order[: min(named, 8) if named else 3]
    sliding = fit.conformation.sliding
    worst = ", ".join(
        f"{ibug_label(fit.landmark_names[i])} {conform_pct[i]:.0f} %"
        + (" across the face outline" if sliding[i] else "")
        + f" ({fit.conformation.residual[i] / model_per_user:.3g} {units})"
        for i in shown
    )
    if rms_pct > MAX_LANDMARK_RMS_PCT:
        head = (
            f"the landmarks do not fit a head (RMS {rms_pct:.1f} % of the eye distance after alignment, "
            f"limit {MAX_LANDMARK_RMS_PCT:g} %); worst: {worst}"
        )
    else:
        head = (
            f"{int(far.sum())} landmark{'s are' if far.sum() > 1 else ' is'} far from where a head has "
            f"{'them' if far.sum() > 1 else 'it'} (limit {MAX_LANDMARK_PCT:g} % of the eye distance after "
            f"alignment): {worst}"
        )
    return (
        head + "; check that the names and their order match the points (iBUG numbers count from 1, "
        "_L is the subject's left), then move or remove the landmarks named"
    )
