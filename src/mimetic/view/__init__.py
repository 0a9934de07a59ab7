"""Pictures of meshes: cameras and named views, GL and CPU rendering, overlays, contact sheets.

Nothing else in mimetic imports this package; it is for previews, reports and debugging.
"""

from mimetic.view.camera import VIEWS, Camera, Projection, clip_planes, frame_camera, project
from mimetic.view.raster import rasterize
from mimetic.view.render import Renderer, default_renderer, render
from mimetic.view.sheet import contact_sheet, draw_lines, draw_points, overlay_segments, save_png

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
    "save_png",
]
