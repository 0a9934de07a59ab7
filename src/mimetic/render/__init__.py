"""Offscreen rendering of meshes: cameras and named views, GL (EGL) and CPU rasterizers.

The core below ``fit`` (automatic landmarks render the mesh) and ``view`` (sheets, overlays,
video), which both import it. Conventions are in ``camera``: +Y up, +Z forward, pixels with y down.
"""

from mimetic.render.camera import VIEWS, Camera, Projection, clip_planes, frame_camera, project
from mimetic.render.raster import rasterize
from mimetic.render.renderer import Renderer, default_renderer, render

__all__ = [
    "VIEWS",
    "Camera",
    "Projection",
    "Renderer",
    "clip_planes",
    "default_renderer",
    "frame_camera",
    "project",
    "rasterize",
    "render",
]
