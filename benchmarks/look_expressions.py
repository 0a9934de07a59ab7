"""The six basic expressions on many heads and every engine, side by side, to look at (issue 28).

    python benchmarks/look_expressions.py [--quick] [--engines wire,vector,fem,tissue] [--size 192]

One sheet per head, written to ``benchmarks/out/expressions/HEAD.png``: a row per engine, the rest
face then joy, sadness, anger, fear, surprise and disgust at weight 1, each tile framed on the face
(``view.sheets.face_camera``). Heads: the default generated head, three random generated heads
(seeds 1-3), ICT-FaceKit's scan rigged with automatic landmarks, and an identity drawn from ICT's
modes at σ 3 (seed 106). ``--quick``: the default head and ICT only. What to look for: each
expression reads as its name on every head and engine (FACS: AU 6+12, 1+4+15, 4+5+7+23, 1+2+4+5+20+26,
1+2+5+26, 9+10+15+17), no torn corners, rolled lips or lumpy cheeks. Prints the time per sheet.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np
from PIL import Image

import report
from mimetic.animate.expressions import expression_pose
from mimetic.engines import make_engine
from mimetic.fit.autolandmarks import auto_landmarks
from mimetic.fit.pipeline import rig_head
from mimetic.head.model import DEFAULT_RESOLUTION, make_head
from mimetic.head.params import HeadParams
from mimetic.mesh.model import Mesh
from mimetic.rig.activations import pose
from mimetic.rig.recipe import build_rig
from mimetic.testing import ict_folder, ict_identity, load_ict
from mimetic.view.drawing import contact_sheet
from mimetic.view.sheets import pose_tiles

BASIC = ("joy", "sadness", "anger", "fear", "surprise", "disgust")
OUT = report.OUT / "expressions"


def heads(quick: bool):
    """(name, rig) pairs, built on demand."""
    yield "default", build_rig(make_head(resolution=DEFAULT_RESOLUTION))
    if not quick:
        for seed in (1, 2, 3):
            yield (
                f"generated-s{seed}",
                build_rig(make_head(HeadParams.random(seed), resolution=DEFAULT_RESOLUTION)),
            )
    folder = ict_folder()
    if folder is None:
        report.console.print("ICT-FaceKit not found: its heads are left out")
        return
    scans = [("ict", load_ict(folder)[0])]
    if not quick:
        scans.append(("ict-s106-sigma3", ict_identity(106, 3.0, folder)))
    for name, scan in scans:
        mesh = Mesh(scan.vertices, scan.faces, units="cm")  # as a user has it: no parts, no landmarks
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield name, rig_head(mesh, auto_landmarks(mesh)).rig


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--engines", default="wire,vector,fem,tissue")
    parser.add_argument("--size", type=int, default=192)
    args = parser.parse_args()
    OUT.mkdir(parents=True, exist_ok=True)
    engines = args.engines.split(",")
    for name, rig in heads(args.quick):
        begin = time.perf_counter()
        poses = [("rest", pose(rig), None)] + [(e, expression_pose(rig, e), None) for e in BASIC]
        tiles = []
        for engine_name in engines:
            engine = make_engine(rig, engine_name)
            row = pose_tiles(rig, engine, poses, views=("front",), size=args.size)
            tiles += [(f"{engine_name}: {label}", image) for label, image in row]
        path = OUT / f"{name}.png"
        Image.fromarray(np.asarray(contact_sheet(tiles, columns=len(poses)))).save(path)
        report.console.print(f"{name}: {path} ({time.perf_counter() - begin:.0f} s)")


if __name__ == "__main__":
    main()
