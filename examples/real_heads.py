"""Rig real scanned heads from the shared test data and write what ``make demo-all`` shows of them.

Run by ``make demo-all`` after ``mimetic demo --all``: ``python examples/real_heads.py [OUT_DIR]`` (default
``mimetic-demo``). It needs the shared data folder (``../shared/data`` beside the repository, or
``$MIMETIC_SHARED_DATA``) and says so, without failing, when that is absent.

Three heads, each rigged automatically (MediaPipe landmarks, or ICT's own landmark vertices when
MediaPipe is missing or finds no face), each in its own folder of ``OUT_DIR``:

* ``ict/``: the ICT-FaceKit neutral head, all its parts (the renderer leaves its eye films out);
* ``ict_id_s1_sigma1/``, ``ict_id_s1_sigma2/``: ICT identity heads (``mimetic.testing.ict_identity``:
  the neutral plus ICT's 20 identity modes weighted by N(0, 1) and N(0, 2) draws, seed 1).

Each folder gets the rig (``NAME.mrig``), the landmarks used (``landmarks.json``), the fit report
(``NAME.fit.json``, ``NAME.fit.png``), the expression library with the wire engine
(``expressions.png``: front and three-quarter) and its close-ups (``expressions_closeup.png``: each
expression's face, eyes and mouth corners); ``ict/`` also gets the vector engine's close-ups
(``expressions_closeup_vector.png``).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

from mimetic.animate.expressions import load_library
from mimetic.engines import make_engine
from mimetic.errors import MimeticError
from mimetic.fit.autolandmarks import auto_landmarks
from mimetic.fit.landmarks import Landmarks, write_landmarks
from mimetic.fit.pipeline import rig_head
from mimetic.mesh.model import Mesh
from mimetic.render import Renderer
from mimetic.rig.format import save_rig
from mimetic.testing import ict_identity, ict_landmarks, load_ict, shared_data_dir
from mimetic.view import save_png
from mimetic.view.fitreport import fit_report_image
from mimetic.view.sheets import closeup_sheet, expression_sheet

IDENTITIES = ((1, 1.0), (1, 2.0))
"""(seed, sigma) of the ICT identity heads: one plausible head, one with stronger features."""


def landmarks_of(mesh: Mesh, meta: dict, renderer: Renderer) -> Landmarks:
    """Automatic landmarks of ``mesh``, or ICT's own landmark vertices (same topology as the
    neutral) when MediaPipe is not installed or finds no face."""
    try:
        return auto_landmarks(mesh, renderer=renderer)
    except MimeticError as error:  # MissingExtraError without [track]; LandmarkError: no face found
        print(f"note: rigged from ICT's own landmark vertices ({error})")
        return ict_landmarks(mesh, meta)


def rig_and_show(
    name: str, mesh: Mesh, meta: dict, folder: Path, renderer: Renderer, engines: tuple[str, ...] = ("wire",)
) -> list[Path]:
    """Rig ``mesh`` automatically and write its rig, fit report, expression sheet and close-up sheets
    (one per engine in ``engines``; the wire one is ``expressions_closeup.png``) into ``folder``."""
    landmarks = landmarks_of(mesh, meta, renderer)
    folder.mkdir(parents=True, exist_ok=True)
    result = rig_head(mesh, landmarks, metadata={"source": f"ict-facekit: {name}"})
    rig = result.rig
    files = [
        write_landmarks(landmarks, folder / "landmarks.json"),
        save_rig(rig, folder / f"{name}.mrig"),
        result.report.save(folder / f"{name}.fit.json"),
        save_png(fit_report_image(result, renderer=renderer), folder / f"{name}.fit.png"),
    ]
    library = load_library()
    wire = make_engine(rig, "wire")
    files.append(
        save_png(expression_sheet(rig, wire, library, renderer=renderer), folder / "expressions.png")
    )
    for engine in engines:
        sheet = closeup_sheet(rig, wire if engine == "wire" else engine, library, renderer=renderer)
        suffix = "" if engine == "wire" else f"_{engine}"
        files.append(save_png(sheet, folder / f"expressions_closeup{suffix}.png"))
    return files


def main(out_dir: str = "mimetic-demo") -> int:
    data = shared_data_dir()
    if data is None or not (data / "ict-facekit" / "neutral.npz").is_file():
        print("real heads skipped: no shared data (set MIMETIC_SHARED_DATA to its data folder)")
        return 0
    renderer = Renderer()
    neutral, meta = load_ict(data / "ict-facekit")
    heads = [("ict", neutral, ("wire", "vector"))]
    for seed, sigma in IDENTITIES:
        mesh = ict_identity(seed, sigma, data / "ict-facekit")
        heads.append((f"ict_id_s{seed}_sigma{sigma:g}", mesh, ("wire",)))
    for name, mesh, engines in heads:
        start = time.perf_counter()
        for path in rig_and_show(name, mesh, meta, Path(out_dir) / name, renderer, engines):
            print(f"wrote {path}")
        print(f"{name}: {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:2]))
