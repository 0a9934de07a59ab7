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

And a dense head, ``ict_dense/``: ICT subdivided once (105,569 vertices, 76,837 welded skin vertices,
``trimesh.remesh.subdivide``), rigged the same way and posed in joy and anger by the tissue engine,
which simulates it through its automatic proxy (``engines.volume``: about 20,000 skin vertices) and
carries the motion to every vertex (``expressions_tissue.png``, front and three-quarter); about two
minutes more on two cores.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np
import trimesh

from mimetic.animate.expressions import compose_pose, load_library
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
from mimetic.view.drawing import contact_sheet
from mimetic.view.fitreport import fit_report_image
from mimetic.view.sheets import closeup_sheet, expression_sheet, pose_tiles

DENSE_EXPRESSIONS = ("joy", "anger")
"""What the dense head shows with the tissue engine."""
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


def dense_head(mesh: Mesh, meta: dict, folder: Path, renderer: Renderer) -> list[Path]:
    """ICT subdivided once, rigged from ICT's own landmark vertices (subdivision keeps them) and posed
    in ``DENSE_EXPRESSIONS`` by the tissue engine through its automatic proxy."""
    vertices, faces = trimesh.remesh.subdivide(mesh.vertices, mesh.faces)
    dense = Mesh(np.ascontiguousarray(vertices), np.ascontiguousarray(faces, dtype=np.int64), units="cm")
    folder.mkdir(parents=True, exist_ok=True)
    rig = rig_head(dense, ict_landmarks(dense, meta), metadata={"source": "ict-facekit: subdivided"}).rig
    tissue = make_engine(rig, "tissue")
    print(f"ict_dense: {rig.n_vertices:,} vertices, {tissue.volume.n_skin:,} proxy skin vertices")
    poses = [("rest", np.zeros(len(rig.channels)), None)]
    poses += [(name, compose_pose(rig, ((name, 1.0),)), None) for name in DENSE_EXPRESSIONS]
    tiles = pose_tiles(rig, tissue, poses, views=("front", "three_quarter"), size=384, renderer=renderer)
    return [save_png(contact_sheet(tiles, columns=2), folder / "expressions_tissue.png")]


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
    start = time.perf_counter()
    for path in dense_head(neutral, meta, Path(out_dir) / "ict_dense", renderer):
        print(f"wrote {path}")
    print(f"ict_dense (tissue engine through its proxy): {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:2]))
