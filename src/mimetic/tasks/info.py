"""``mimetic info``: what a mesh or rig file holds, and whether a mesh can be rigged as it is."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from mimetic.tasks.base import Progress, Result, Task, TaskOptions, option
from mimetic.tasks.render import UNITS


@dataclass(frozen=True)
class InfoOptions(TaskOptions):
    """How to read the file (see ``option`` for the fields' metadata)."""

    units: str | None = option(None, "The mesh's units if the file does not say.", choices=UNITS)


def run(
    source: Path, output: None = None, options: InfoOptions = InfoOptions(), progress: Progress | None = None
) -> Result:
    """Validate the mesh or rig ``source`` and report its units, parts, seams, winding and landmarks.

    ``details`` holds the report (``kind``, the validation's counts, ``lines`` for a terminal, and
    ``ok``: False when a mesh cannot be rigged as it is); nothing is written.
    """
    if Path(source).suffix.lower() == ".mrig":
        details = _rig_report(Path(source))
    else:
        details = _mesh_report(Path(source), options.units)
    verdict = "ok" if details["ok"] else "not usable as it is"
    return Result((), f"{details['kind']}, {details['n_vertices']:,} vertices: {verdict}", details=details)


def _mesh_report(file: Path, units: str | None) -> dict:
    from mimetic.mesh.io import load_mesh
    from mimetic.mesh.validate import validate_mesh

    mesh = load_mesh(file, units=units, check=False)
    report = validate_mesh(mesh)
    return {
        "file": str(file),
        "kind": "mesh",
        **report.as_dict(),
        "parts": list(mesh.parts),
        "landmarks": "none (a plain mesh; `mimetic rig` will find them)",
        "lines": report.lines(),
    }


def _rig_report(file: Path) -> dict:
    from mimetic.mesh.validate import validate_mesh
    from mimetic.tasks.prepared import prepared_rig

    rig = prepared_rig(file).rig
    report = validate_mesh(rig.mesh)
    kinds: dict[str, int] = {}
    for m in rig.muscles:
        kinds[m.kind] = kinds.get(m.kind, 0) + 1
    lines = [
        *report.lines(),
        f"scale             {rig.scale:.4g} {rig.units} (head height)",
        f"muscles           {len(rig.muscles)} ({', '.join(f'{n} {k}' for k, n in kinds.items())})",
        f"wires             {len(rig.wires)}",
        f"bones             {', '.join(rig.bone_names)}",
        f"channels          {len(rig.channels)} (mimetic list channels {file.name})",
    ]
    return {
        "file": str(file),
        "kind": "rig",
        **report.as_dict(),
        "ok": True,
        "units": rig.units,
        "parts": list(rig.mesh.parts),
        "landmarks": sorted(rig.landmarks),
        "regions": sorted(rig.regions),
        "muscles": [m.name for m in rig.muscles],
        "channels": list(rig.channel_names),
        "lines": lines,
    }


TASK = Task("info", InfoOptions, run, (), source="mesh or rig")
