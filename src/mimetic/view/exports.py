"""The web viewer's downloads as bytes: an animated GLB of the rig and a PNG of what it shows."""

from __future__ import annotations

import io
import tempfile
from pathlib import Path

import numpy as np

from mimetic.animate.clip import KeyframeClip
from mimetic.rig.model import Rig
from mimetic.view.session import FPS

PNG_SIZE = 768


def glb_bytes(rig: Rig, engine: str, clip: KeyframeClip | None = None) -> bytes:
    """The rig as a GLB with one morph target per muscle (``engine`` baked) and, when given, ``clip``
    sampled at ``FPS`` as its animation: what ``mimetic export`` / ``mimetic animate -o .glb`` write."""
    from mimetic.export.gltf import export_glb, morph_targets

    sampled = None if clip is None else clip.sample(FPS, channels=rig)
    with tempfile.TemporaryDirectory() as folder:
        path = export_glb(
            rig, Path(folder) / "head.glb", morph_targets=morph_targets(rig, engine), clip=sampled
        )
        return path.read_bytes()


def png_bytes(rig: Rig, vertices: np.ndarray, size: int = PNG_SIZE) -> bytes:
    """A front close-up (size × size) of the rig's mesh at ``vertices`` (n, 3), rig units, as PNG."""
    from PIL import Image

    from mimetic.render.renderer import default_renderer
    from mimetic.view.look import rig_look
    from mimetic.view.sheets import face_camera

    mesh = rig.mesh.with_vertices(np.asarray(vertices, dtype=np.float64))
    image = default_renderer().render(mesh, face_camera(rig), size=(size, size), look=rig_look(rig))
    buffer = io.BytesIO()
    Image.fromarray(image).save(buffer, format="PNG")
    return buffer.getvalue()
