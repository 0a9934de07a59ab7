"""``mimetic export``: a rig as a GLB, FBX or USD scene with named morph targets and its skeleton."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from mimetic.engines import ENGINES
from mimetic.engines.bake import CORRECTIVES as BAKE_CORRECTIVES
from mimetic.engines.basis import basis_bytes, human_bytes
from mimetic.tasks.base import (
    Progress,
    Result,
    Task,
    TaskOptions,
    announce,
    check_folder,
    check_output,
    option,
    stage,
)
from mimetic.tasks.outputs import SCENES


@dataclass(frozen=True)
class ExportOptions(TaskOptions):
    """Which morph targets and where else to write them (see ``option`` for the fields' metadata)."""

    arkit: bool = option(False, "Morph targets are the 52 ARKit blendshapes (else one per muscle).")
    obj_dir: Path | None = option(
        None, "Also write each morph target as a posed OBJ (your own frame) into this folder.", batch=False
    )
    engine: str = option("wire", "Deformation engine baked into the morph targets.", choices=ENGINES)


def run(
    source: Path, output: Path, options: ExportOptions = ExportOptions(), progress: Progress | None = None
) -> Result:
    """Export the rig ``source`` to ``output`` (.glb, .fbx, or .usda/.usdc/.usd with UsdSkel): one morph
    target per muscle channel, or the ARKit-52 shapes baked from the muscles."""
    from mimetic.tasks.outputs import write_scene
    from mimetic.tasks.prepared import prepared_rig

    check_output(output, SCENES)
    if options.obj_dir is not None:
        check_folder(options.obj_dir, create=True)
    prepared = prepared_rig(source)
    if options.arkit:
        from mimetic.export.arkit import arkit_shapes

        engine = prepared.engine(options.engine, stage(progress, f"prepare {options.engine}"))
        announce(progress, "ARKit shapes")
        targets = arkit_shapes(engine)
    else:
        rig = prepared.rig
        size = human_bytes(basis_bytes(len(rig.channels), rig.n_vertices, BAKE_CORRECTIVES))
        targets = prepared.morph_targets(
            options.engine, stage(progress, f"bake {options.engine} (basis {size})")
        )
    n_vertices = prepared.rig.n_vertices
    # each target: float32 positions and normals (a sparse accessor for a local one is smaller)
    size = human_bytes(basis_bytes(len(targets), n_vertices, itemsize=4 * 2))
    announce(
        progress, f"write {Path(output).name} ({len(targets)} targets × {n_vertices:,} vertices, ≤ {size})"
    )
    written = [write_scene(prepared, output, targets, progress=progress)]
    if options.obj_dir is not None:
        from mimetic.mesh.io import save_mesh

        options.obj_dir.mkdir(exist_ok=True)
        rig = prepared.rig
        rest = rig.mesh.vertices
        for name, delta in targets.items():  # in the user's own frame, on top of their mesh at rest
            written.append(save_mesh(rig.source_mesh(rest + delta), options.obj_dir / f"{name}.obj"))
    shapes = "ARKit-52 shapes" if options.arkit else "muscle channels"
    return Result(tuple(Path(p) for p in written), f"{len(targets)} morph targets ({shapes})")


TASK = Task("export", ExportOptions, run, SCENES, source="rig")
