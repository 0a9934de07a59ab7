"""Pictures of rigs and faces: contact sheets, muscle overlays, expression sheets, fit pictures, video.

Built on ``mimetic.render`` (cameras and the offscreen renderers, re-exported here for
convenience). Nothing else in mimetic imports this package; it is for previews, reports and debugging.
"""

from mimetic.render import (
    VIEWS,
    Camera,
    Projection,
    Renderer,
    clip_planes,
    default_renderer,
    frame_camera,
    project,
    rasterize,
    render,
)
from mimetic.view.drawing import (
    contact_sheet,
    draw_lines,
    draw_points,
    overlay_segments,
    save_image,
    save_png,
)

__all__ = [
    "VIEWS",
    "Camera",
    "Projection",
    "Renderer",
    "clip_planes",
    "contact_sheet",
    "default_renderer",
    "draw_lines",
    "draw_points",
    "frame_camera",
    "overlay_segments",
    "project",
    "rasterize",
    "render",
    "save_image",
    "save_png",
]
