"""``mimetic head``: generate the parametric reference head as a mesh (and its rig)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from mimetic.head.model import DEFAULT_RESOLUTION
from mimetic.tasks.base import Progress, Result, Task, TaskOptions, announce, check_output, option
from mimetic.tasks.outputs import MESHES
from mimetic.tasks.parsing import name_values
from mimetic.tasks.rig import RESOLUTIONS


@dataclass(frozen=True)
class HeadOptions(TaskOptions):
    """Which head to make (see ``option`` for the fields' metadata)."""

    seed: int | None = option(None, "Random conformation from this seed.")
    params: tuple[tuple[str, float], ...] = option(
        (),
        "Set a conformation parameter (repeatable).",
        flag="--param",
        metavar="NAME=VALUE",
        parse=name_values,
        cli_type=list[str],
    )
    resolution: int = option(
        DEFAULT_RESOLUTION, "Approximate skin vertex count.", minimum=RESOLUTIONS[0], maximum=RESOLUTIONS[1]
    )
    rig: Path | None = option(None, "Also write the head's rig to this .mrig file.", batch=False)


def run(
    source: None, output: Path, options: HeadOptions = HeadOptions(), progress: Progress | None = None
) -> Result:
    """Generate the head (``HeadParams`` from ``seed`` and ``params``) and write its mesh to ``output``
    (.glb .gltf .obj .ply .stl) and, when ``options.rig`` is given, its rig."""
    from mimetic.head.model import make_head
    from mimetic.head.params import HeadParams
    from mimetic.mesh.io import save_mesh

    check_output(output, MESHES)
    if options.rig is not None:
        check_output(options.rig, (".mrig",), "rig")
    params = HeadParams() if options.seed is None else HeadParams.random(options.seed)
    params = params.with_values(**dict(options.params))
    announce(progress, "head")
    generated = make_head(params, options.resolution)
    written = [save_mesh(generated.mesh, output)]
    if options.rig is not None:
        from mimetic.rig.format import save_rig
        from mimetic.rig.recipe import build_rig

        announce(progress, "rig")
        written.append(save_rig(build_rig(generated), options.rig))
    mesh = generated.mesh
    return Result(tuple(Path(p) for p in written), f"{mesh.n_vertices:,} vertices, {len(mesh.parts)} parts")


TASK = Task("head", HeadOptions, run, MESHES)
