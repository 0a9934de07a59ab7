"""The fit report as a picture: the user's mesh coloured by residual, beside the fitted reference.

Each user vertex is coloured by its distance to the fitted reference surface, in % of the head
diagonal, from blue (0) through yellow to red (``RESIDUAL_RED_PCT`` and more); the fitted
reference skin is shown from the same cameras, with the target landmarks (green) and the
reference's (red) drawn on top.
"""

from __future__ import annotations

import numpy as np

from mimetic.fit.pipeline import RigResult
from mimetic.mesh.closest import closest_points
from mimetic.mesh.model import Mesh
from mimetic.render.camera import frame_camera, project
from mimetic.render.renderer import Renderer, default_renderer
from mimetic.view.drawing import contact_sheet, draw_points

RESIDUAL_RED_PCT = 1.0
_STOPS = np.array([[0.15, 0.35, 0.85], [0.95, 0.85, 0.25], [0.85, 0.15, 0.12]], dtype=np.float32)


def residual_colors(percent: np.ndarray, red: float = RESIDUAL_RED_PCT) -> np.ndarray:
    """RGB colours (n, 3) float32 for residuals (n,) in %: blue at 0, yellow at red/2, red at ``red``."""
    t = np.clip(np.nan_to_num(percent, nan=red) / red, 0.0, 1.0) * 2.0
    low = np.minimum(t, 1.0)[:, None]
    high = np.maximum(t - 1.0, 0.0)[:, None]
    out = np.where(
        t[:, None] <= 1.0,
        _STOPS[0] + low * (_STOPS[1] - _STOPS[0]),
        _STOPS[1] + high * (_STOPS[2] - _STOPS[1]),
    )
    return out.astype(np.float32)


def user_residuals(result: RigResult) -> np.ndarray:
    """Distance (n_user,) of each user vertex to the fitted reference, % of the head diagonal."""
    fit = result.fit
    head = fit.head
    hit = closest_points(head.mesh.vertices, head.mesh.faces, fit.target.vertices)
    diagonal = float(np.linalg.norm(np.ptp(head.mesh.vertices[: head.n_skin], axis=0)))
    return 100.0 * hit.distance / diagonal


def fit_report_image(result: RigResult, *, size: int = 384, renderer: Renderer | None = None) -> np.ndarray:
    """A labelled sheet (2 rows × 2 views) of the fit: residual-coloured user mesh, fitted reference."""
    renderer = renderer or default_renderer()
    fit = result.fit
    head = fit.head
    percent = user_residuals(result)
    user = Mesh(fit.target.vertices, fit.target.faces, colors=residual_colors(percent))
    skin, _ = head.mesh.submesh("skin")
    face = head.mesh.vertices[: head.n_skin]
    top = face[face[:, 1] > face[:, 1].max() - 0.8 * np.ptp(face[:, 1])]
    lo, hi = top.min(axis=0), top.max(axis=0)
    fitted_lm = head.landmark_positions(list(fit.landmark_names))
    tiles = []
    for yaw, label in ((0.0, "front"), (60.0, "side")):
        camera = frame_camera(lo, hi, yaw_deg=yaw, fill=0.9)
        image = renderer.render(user, camera, size=(size, size))
        tiles.append((f"residual, {label} (red: {RESIDUAL_RED_PCT:g} % and more)", image))
        image = renderer.render(skin, camera, size=(size, size))
        image = draw_points(image, project(fit.landmark_targets, camera, size).pixels, colors=(0.1, 0.8, 0.2))
        image = draw_points(image, project(fitted_lm, camera, size).pixels, colors=(0.9, 0.1, 0.1))
        tiles.append((f"fitted reference, {label}", image))
    return contact_sheet(tiles, columns=2)
