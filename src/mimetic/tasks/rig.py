"""``mimetic rig``: fit the reference head to a mesh and write its rig, fit report and picture."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

from mimetic.fit.working import MIN_WORKING_VERTICES, WORKING_THRESHOLD, WORKING_VERTICES
from mimetic.head.model import DEFAULT_RESOLUTION
from mimetic.mesh.units import UNIT_SCALE
from mimetic.tasks.base import Progress, Result, Task, TaskError, TaskOptions, beside, check_output, option

UNITS = tuple(UNIT_SCALE)
RESOLUTIONS = (1_500, 250_000)
"""Skin vertex counts the reference head can be made with."""


@dataclass(frozen=True)
class RigOptions(TaskOptions):
    """How ``rig`` finds landmarks and fits (see ``option`` for the fields' metadata)."""

    landmarks: Path | None = option(
        None,
        "Landmark file (JSON or CSV; project names or ibug68_01..ibug68_68); in a batch, one per head "
        "with a template such as '{dir}/{stem}.json'.",
    )
    auto_landmarks: bool = option(False, "Find landmarks with MediaPipe (the default without --landmarks).")
    units: str | None = option(
        None, "The mesh's units if the file does not say (else guessed from its size).", choices=UNITS
    )
    force: bool = option(False, "Write the rig even if the fit looks wrong.")
    resolution: int = option(
        DEFAULT_RESOLUTION,
        "Skin vertex count of the reference head.",
        minimum=RESOLUTIONS[0],
        maximum=RESOLUTIONS[1],
    )
    picture: bool = option(True, "Write the fit's picture, NAME.fit.png, beside the rig.")
    working_resolution: str = option(
        "auto",
        "Vertices of the decimated copy a dense mesh is rigged on before the rig is carried to every "
        f"vertex: a count, 'full' (fit every vertex) or 'auto' ({WORKING_VERTICES:,} above "
        f"{WORKING_THRESHOLD:,} vertices, else full).",
        metavar="N|full|auto",
    )

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.landmarks is not None and self.auto_landmarks:
            raise TaskError("give landmarks or auto_landmarks, not both")
        working_vertices(self.working_resolution)


def working_vertices(text: str) -> int | str | None:
    """``rig_head``'s ``working_vertices`` from the option's text: "auto" → None, "full", or a count
    of at least ``MIN_WORKING_VERTICES``."""
    text = str(text).strip().lower().replace("_", "").replace(",", "")
    if text == "auto":
        return None
    if text == "full":
        return "full"
    if not text.isdigit() or int(text) < MIN_WORKING_VERTICES:
        raise TaskError(
            f"working resolution {text!r} must be 'auto', 'full' or a vertex count of at least "
            f"{MIN_WORKING_VERTICES:,} (e.g. --working-resolution 100000)"
        )
    return int(text)


def outputs(main: Path, options: RigOptions) -> tuple[Path, ...]:
    """The fit report (NAME.fit.json) and, unless ``picture`` is off, its picture (NAME.fit.png)."""
    return (beside(main, ".fit.json"), *((beside(main, ".fit.png"),) if options.picture else ()))


def run(
    source: Path, output: Path, options: RigOptions = RigOptions(), progress: Progress | None = None
) -> Result:
    """Rig the mesh ``source`` (``fit.pipeline.rig_mesh``): ``output`` (.mrig), NAME.fit.json and
    NAME.fit.png beside it. The residual is the mean surface residual, % of the head diagonal."""
    from mimetic.fit.pipeline import rig_mesh
    from mimetic.rig.format import save_rig

    check_output(output, (".mrig",))
    result = rig_mesh(
        source,
        options.landmarks,
        units=options.units,
        resolution=options.resolution,
        force=options.force,
        progress=progress,
        working_vertices=working_vertices(options.working_resolution),
    )
    report_file, *picture = outputs(Path(output), options)
    written = [save_rig(result.rig, output), result.report.save(report_file)]
    if picture:
        from mimetic.view import save_image
        from mimetic.view.fitreport import fit_report_image

        if progress is not None:
            progress("fit picture", 0, 1)
        written.append(save_image(fit_report_image(result), picture[0]))
    report = result.report
    verdict = "accepted" if report.accepted else "forced past: " + "; ".join(report.reasons)
    summary = (
        f"fit {verdict}: surface residual mean {report.mean_pct:.3f} %, max {report.max_pct:.3f} % of the "
        f"head diagonal ({report.head_diagonal:.4g} {report.units}); landmark RMS "
        f"{report.landmark_rms_pct:.2f} % of the eye distance"
    )
    return Result(tuple(Path(p) for p in written), summary, float(report.mean_pct), asdict(report))


TASK = Task("rig", RigOptions, run, (".mrig",), outputs, source="mesh")
