"""``mimetic render``: a mesh or a rig as an image, from one angle or three."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from mimetic.mesh.units import UNIT_SCALE
from mimetic.render.camera import VIEWS
from mimetic.tasks.base import Progress, Result, Task, TaskOptions, announce, check_output, option
from mimetic.tasks.outputs import IMAGES

UNITS = tuple(UNIT_SCALE)
SHEET_VIEWS = (*VIEWS, "all")


@dataclass(frozen=True)
class RenderOptions(TaskOptions):
    """How ``render`` draws (see ``option`` for the fields' metadata)."""

    view: str = option(
        "all", "front, three_quarter, profile, or all (a labelled sheet of the three).", choices=SHEET_VIEWS
    )
    size: int = option(512, "Image size in pixels (per view).", minimum=64, maximum=4096)
    wireframe: bool = option(False, "Draw the triangle edges.")
    muscles: bool = option(True, "Draw a rig's muscles.")
    units: str | None = option(None, "A mesh's units if the file does not say.", choices=UNITS)


def run(
    source: Path, output: Path, options: RenderOptions = RenderOptions(), progress: Progress | None = None
) -> Result:
    """Render ``source`` (a mesh file or a .mrig rig) to the image ``output`` (.png .jpg .webp):
    one ``options.view``, or a labelled sheet of the three views."""
    from mimetic.render import render as render_mesh
    from mimetic.view import contact_sheet, save_image

    check_output(output, IMAGES)
    views = list(VIEWS) if options.view == "all" else [options.view]
    announce(progress, "render")
    if Path(source).suffix.lower() == ".mrig":
        from mimetic.tasks.prepared import prepared_rig
        from mimetic.view.muscles import render_rig

        rig = prepared_rig(source).rig
        tiles = [
            (v, render_rig(rig, v, size=options.size, muscles=options.muscles, wireframe=options.wireframe))
            for v in views
        ]
    else:
        from mimetic.mesh.io import load_mesh

        mesh = load_mesh(source, units=options.units)
        tiles = [(v, render_mesh(mesh, v, size=options.size, wireframe=options.wireframe)) for v in views]
    image = tiles[0][1] if len(tiles) == 1 else contact_sheet(tiles, columns=len(tiles))
    save_image(image, output)
    return Result((Path(output),), f"{len(views)} view{'s' * (len(views) > 1)} at {options.size} px")


TASK = Task("render", RenderOptions, run, IMAGES, source="mesh or rig")
