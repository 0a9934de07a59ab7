"""Rig real scanned heads from the shared test data and write what ``make demo`` shows of them.

Run by ``make demo`` after ``mimetic demo``: ``python examples/real_heads.py [OUT_DIR]`` (default
``mimetic-demo``). It needs the shared data folder (``../shared/data`` beside the repository, or
``$MIMETIC_SHARED_DATA``) and says so, without failing, when that is absent.

Writes into ``OUT_DIR/ict/``: the ICT-FaceKit neutral head rigged automatically (MediaPipe
landmarks, or ICT's own 68 landmark vertices without the ``[track]`` extra) as ``ict.mrig``, the
landmarks used (``landmarks.json``), its fit report (``ict.fit.json``, ``ict.fit.png``) and the
expression library on ICT's own mesh (``expressions.png``).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from mimetic.animate.expressions import load_library
from mimetic.errors import MissingExtraError
from mimetic.fit.autolandmarks import auto_landmarks
from mimetic.fit.landmarks import write_landmarks
from mimetic.fit.pipeline import rig_head
from mimetic.mesh.model import Mesh
from mimetic.render import Renderer
from mimetic.rig.format import save_rig
from mimetic.testing import ict_landmarks, load_ict, shared_data_dir
from mimetic.view import save_png
from mimetic.view.fitreport import fit_report_image
from mimetic.view.sheets import expression_sheet

ICT_SHELLS = ("Lacrimal fluid", "Eye blend", "Eye occlusion")


def without_ict_shells(mesh: Mesh, meta: dict) -> Mesh:
    """ICT's head without its transparent eye shells (lacrimal fluid, eye blend, eye occlusion),
    which render as dark caps over the eyes without a transparency pass. They come after the
    eyeballs, so the vertices before them keep their indices (the 68 landmarks among them)."""
    drop = np.zeros(mesh.n_vertices, dtype=bool)
    for part in meta["parts"]:
        if part["name"].startswith(ICT_SHELLS):
            first, last = part["vertex_range"]
            drop[first : last + 1] = True
    keep = np.nonzero(~drop)[0]
    remap = np.full(mesh.n_vertices, -1)
    remap[keep] = np.arange(len(keep))
    faces = mesh.faces[~drop[mesh.faces].any(axis=1)]
    return Mesh(mesh.vertices[keep], remap[faces], units=mesh.units)


def rig_ict(folder: Path, renderer: Renderer) -> list[Path]:
    """Rig the ICT-FaceKit neutral head automatically and pose it; returns the files written."""
    data = shared_data_dir()
    mesh, meta = load_ict(data / "ict-facekit")
    mesh = without_ict_shells(mesh, meta)
    try:
        landmarks = auto_landmarks(mesh, renderer=renderer)
    except MissingExtraError as error:
        landmarks = ict_landmarks(mesh, meta)
        print(f"note: ICT-FaceKit head rigged from its own landmark vertices ({error})")
    folder.mkdir(parents=True, exist_ok=True)
    result = rig_head(mesh, landmarks, metadata={"source": "ict-facekit/neutral.npz"})
    files = [
        write_landmarks(landmarks, folder / "landmarks.json"),
        save_rig(result.rig, folder / "ict.mrig"),
        result.report.save(folder / "ict.fit.json"),
        save_png(fit_report_image(result, renderer=renderer), folder / "ict.fit.png"),
    ]
    sheet = expression_sheet(result.rig, "wire", load_library(), size=256, renderer=renderer)
    files.append(save_png(sheet, folder / "expressions.png"))
    return files


def main(out_dir: str = "mimetic-demo") -> int:
    data = shared_data_dir()
    if data is None or not (data / "ict-facekit" / "neutral.npz").is_file():
        print("real heads skipped: no shared data (set MIMETIC_SHARED_DATA to its data folder)")
        return 0
    renderer = Renderer()
    for path in rig_ict(Path(out_dir) / "ict", renderer):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:2]))
