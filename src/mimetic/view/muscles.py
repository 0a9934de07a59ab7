"""Draw a rig's anatomy over a render: muscles as lines from bony attachment to insertion."""

from __future__ import annotations

import numpy as np

from mimetic.render.camera import VIEWS, Camera, frame_camera, project
from mimetic.render.renderer import Renderer, default_renderer
from mimetic.rig.model import Rig
from mimetic.view.drawing import draw_lines, overlay_segments
from mimetic.view.look import rig_look

KIND_COLORS = {"linear": (0.95, 0.25, 0.2), "sphincter": (1.0, 0.85, 0.2), "sheet": (0.2, 0.8, 0.95)}


def muscle_segments(
    rig: Rig, *, ring_segments: int = 24, vertices: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Line segments (k, 2, 3) in rig units, their colours (k, 3) and a ring flag (k,) bool, on the
    rest mesh or on posed ``vertices`` (n, 3) (the bony attachments stay where they are).

    Linear and sheet muscles are one segment from the bony attachment (the origin inset toward
    the head centre) to the insertion. A sphincter is an ellipse of ``ring_segments`` segments
    around its centre, with semi-axes from the insertion and ``width_rel``.
    """
    v = rig.mesh.vertices if vertices is None else vertices
    f = rig.mesh.faces
    segments, colors, ring_flags = [], [], []
    for m in rig.muscles:
        insertion = m.insertion.position(v, f)
        color = KIND_COLORS[m.kind]
        if m.kind == "sphincter":
            centre = m.origin.position(v, f)
            major = insertion - centre
            minor = np.cross(np.array([0.0, 0.0, 1.0]), major)
            minor *= m.width_rel * rig.scale / max(np.linalg.norm(minor), 1e-12)
            t = np.linspace(0, 2 * np.pi, ring_segments + 1)
            ring = centre + np.cos(t)[:, None] * major + np.sin(t)[:, None] * minor  # (s+1, 3)
            segments.extend(np.stack([ring[:-1], ring[1:]], axis=1))
            colors.extend([color] * ring_segments)
            ring_flags.extend([True] * ring_segments)
        else:
            segments.append(np.stack([rig.muscle_attachment(m.name), insertion]))
            colors.append(color)
            ring_flags.append(False)
    return (
        np.asarray(segments).reshape(-1, 2, 3),
        np.asarray(colors, dtype=np.float64).reshape(-1, 3),
        np.asarray(ring_flags, dtype=bool),
    )


def render_rig(
    rig: Rig,
    view: str | Camera = "front",
    *,
    size: int = 512,
    muscles: bool = True,
    wireframe: bool = False,
    renderer: Renderer | None = None,
) -> np.ndarray:
    """Shaded image (size, size, 3) uint8 of a rig's rest mesh (drawn as ``rig_look`` says: eyes,
    lashes and films as what they are), muscles drawn on top."""
    renderer = renderer or default_renderer()
    if isinstance(view, str):
        if view not in VIEWS:
            raise ValueError(f"unknown view {view!r}; choose one of {', '.join(VIEWS)}")
        v = rig.mesh.vertices
        view = frame_camera(v.min(axis=0), v.max(axis=0), yaw_deg=VIEWS[view], fill=0.85)
    image = renderer.render(rig.mesh, view, size=(size, size), wireframe=wireframe, look=rig_look(rig))
    if muscles:
        segments, colors, ring = muscle_segments(rig)
        image = overlay_segments(image, view, segments[~ring], colors[~ring], width=2)
        pixels = project(segments[ring].reshape(-1, 3), view, (size, size)).pixels.reshape(-1, 2, 2)
        visible = np.isfinite(pixels).all(axis=(1, 2))
        image = draw_lines(image, pixels[visible], colors[ring][visible], width=2)
    return image
