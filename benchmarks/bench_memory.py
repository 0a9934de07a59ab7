"""Peak memory and time of every stage of ``mimetic rig``, then bake and GLB/USD export, up to 1.7M vertices.

    python benchmarks/bench_memory.py [--quick] [--bound-gib 8] [--keep DIR]

The inputs are ICT-FaceKit's neutral head (26,719 vertices, all its parts, cm) and its midpoint
subdivisions (``trimesh.remesh.subdivide``: 105k, 420k and 1.68M vertices; ``--quick`` stops at
420k). Subdivision keeps the vertices it starts from, so ICT's 49 iBUG landmark vertices stay where
they were and every size is the same surface. Four subdivisions would give 6.7M vertices, over
``rig_head``'s ``MAX_VERTICES`` (2M): 1.68M is the largest size here.

Each stage runs in a fresh interpreter (``mimetic.testing.memory.peak_rss``: the child's own
high-water mark, ``VmHWM``) that reads the stage's inputs from the files the stage before it wrote,
so its peak includes holding them, as ``mimetic rig``'s one process holds them; the time is the
stage's work only (not the imports or the reading). The stages, as ``fit.pipeline.rig_head`` runs
them (above ``fit.working.WORKING_THRESHOLD`` vertices through a working copy; at or below it the
working-copy and carry stages do not run, "rigged directly"):

1. load + validate: ``load_mesh`` of a binary PLY, ``validate_mesh``;
2. weld: ``find_weld``;
3. working copy: ``working_copy`` (each piece decimated, every vertex embedded in its piece's copy);
4. landmarks: ``auto_landmarks`` (MediaPipe on renders of the working copy, or of the mesh); the
   fit takes ICT's landmark file instead;
5. fit: ``fit_reference`` (similarity, conformation, registration) and ``fit_report`` on the copy
   (or the welded mesh);
6. transfer: ``build_rig`` of the fitted reference, ``transfer_rig`` (correspondence, skin weights,
   regions, wires), ``unweld_rig``;
7. carry: ``carry_rig``, the copy's rig on every vertex of the mesh;
8. save: ``save_rig`` (.mrig);
9. bake: ``load_rig``, the wire engine, ``bake`` (a linear basis with its 24 correctives);
10. export GLB: ``load_rig`` and the baked deltas, ``morph_targets_from_basis``, ``export_glb``
    (mesh, bones, skin weights and one morph target per muscle channel, with normals);
11. export USD: the same with ``export_usd`` (.usdc, UsdSkel blend shapes).

Besides, "rig_mesh end to end": ``rig_mesh`` of the PLY with landmarks found by MediaPipe, in
one process, as ``mimetic rig`` runs it (without writing the .mrig, stage 8).

Each child's virtual memory is capped at the bound plus ``HEADROOM_GIB`` (``RLIMIT_AS``), so a
stage that blows up fails alone; a stage whose peak passes the bound, or that fails at the cap, is
"over bound". Baseline, in the same run: a child that only holds the input mesh's arrays (numpy
imported, the vertices and faces read from .npy). Growth is the log-log slope between the two
largest sizes (1: linear in the vertex count; 0: a stage whose work does not grow, as on a working
copy of fixed size).
"""

from __future__ import annotations

import argparse
import json
import math
import pickle
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

import report
from mimetic.atomic import atomic_write
from mimetic.mesh.io import save_mesh
from mimetic.mesh.model import Mesh
from mimetic.testing import ict_landmarks, load_ict, shared_data_dir
from mimetic.testing.memory import peak_rss

LEVELS = (0, 1, 2, 3)  # midpoint subdivisions of ICT: 26.7k, 105k, 420k, 1.68M vertices
QUICK_LEVELS = (0, 1, 2)
BOUND_GIB = 8.0  # the bound for a 2M-vertex input, per stage
HEADROOM_GIB = 4.0  # address space a child may map beyond the bound (libraries, thread stacks, arenas)

_PRELUDE = """
import copyreg, pickle, time, types, warnings
from pathlib import Path
import numpy as np
warnings.simplefilter("ignore")
def _proxy(d):  # frozen objects hold read-only mappings, which pickle cannot name
    return types.MappingProxyType(d)
copyreg.pickle(types.MappingProxyType, lambda m: (_proxy, (dict(m),)))
W = Path({folder!r})
def load(name):
    return pickle.loads((W / name).read_bytes())
def dump(obj, name):
    (W / name).write_bytes(pickle.dumps(obj, protocol=5))
"""

STAGES: dict[str, str] = {
    "baseline: the mesh's arrays held": """
v, f = np.load(W / "vertices.npy"), np.load(W / "faces.npy")
t = time.perf_counter()
""",
    "1. load + validate": """
from mimetic.mesh.io import load_mesh
from mimetic.mesh.validate import validate_mesh
t = time.perf_counter()
mesh = load_mesh(W / "head.ply", units="cm")
assert not validate_mesh(mesh).errors
dump(mesh, "mesh.pkl")
""",
    "2. weld": """
from mimetic.mesh.weld import find_weld
mesh = load("mesh.pkl")
t = time.perf_counter()
weld = find_weld(mesh)  # rig_head checks the winding again only where validate_mesh found seams or flips
dump(weld, "weld.pkl")
""",
    "3. working copy (decimate, embed)": """
from mimetic.fit.working import working_copy, working_vertices_for
mesh, weld = load("mesh.pkl"), load("weld.pkl")
t = time.perf_counter()
working = working_vertices_for(mesh.n_vertices, None)
copy = None if working is None else working_copy(mesh, weld.mesh, weld.index, working)
dump(copy, "copy.pkl")
if copy is None:
    print("DIRECT")
""",
    "4. landmarks (MediaPipe)": """
from mimetic.fit.autolandmarks import auto_landmarks
mesh, copy = load("mesh.pkl"), load("copy.pkl")
t = time.perf_counter()
found = auto_landmarks(mesh if copy is None else copy.mesh)
""",
    "5. fit": """
from mimetic.fit.reference import fit_reference
from mimetic.fit.report import fit_report
from mimetic.mesh.weld import find_weld
weld, copy, landmarks = load("weld.pkl"), load("copy.pkl"), load("landmarks.pkl")
t = time.perf_counter()
fitted = weld if copy is None else find_weld(copy.mesh)
fit = fit_reference(fitted.mesh, list(landmarks.names), landmarks.positions,
                    landmark_weights=np.maximum(landmarks.confidence, 0.05))
assert not fit.flipped
fit_report(fit, "cm")
dump(fit, "fit.pkl")
dump(fitted, "fitted.pkl")
""",
    "6. transfer + skin weights": """
import dataclasses
from mimetic.fit.transfer import transfer_rig
from mimetic.rig.recipe import build_rig
from mimetic.rig.weld import unweld_rig
mesh, copy, fitted, fit = load("mesh.pkl"), load("copy.pkl"), load("fitted.pkl"), load("fit.pkl")
t = time.perf_counter()
welded = transfer_rig(build_rig(fit.head), fitted.mesh, fit.conformation.to_model,
                      openings=fit.openings, margins=fit.margins)
target = mesh if copy is None else copy.mesh
user = dataclasses.replace(target, vertices=target.vertices @ welded.source_rotation)
rig = unweld_rig(welded, fitted, user) if fitted.n_merged else welded
dump(rig, "transferred.pkl")
""",
    "7. carry to every vertex": """
import dataclasses
from mimetic.fit.working import carry_rig
mesh, copy, proxy = load("mesh.pkl"), load("copy.pkl"), load("transferred.pkl")
t = time.perf_counter()
if copy is None:
    rig = proxy
    print("DIRECT")
else:
    user = dataclasses.replace(mesh, vertices=mesh.vertices @ proxy.source_rotation)
    rig = carry_rig(proxy, copy, user)
dump(rig, "rig.pkl")
""",
    "8. save .mrig": """
from mimetic.rig.format import save_rig
rig = load("rig.pkl")
t = time.perf_counter()
save_rig(rig, W / "head.mrig")
""",
    "rig_mesh end to end (MediaPipe landmarks)": """
from mimetic.fit.pipeline import rig_mesh
t = time.perf_counter()
result = rig_mesh(W / "head.ply", units="cm")
assert result.report.accepted
""",
    "9. bake (wire engine)": """
from mimetic.engines import make_engine
from mimetic.engines.bake import bake
from mimetic.rig.format import load_rig
rig = load_rig(W / "head.mrig")
t = time.perf_counter()
basis = bake(make_engine(rig, "wire")).basis
np.save(W / "deltas.npy", basis.deltas)
""",
    "10. export GLB (morph targets)": """
from mimetic.engines.basis import Basis
from mimetic.export.gltf import export_glb, morph_targets_from_basis
from mimetic.rig.format import load_rig
rig = load_rig(W / "head.mrig")
deltas = np.load(W / "deltas.npy", mmap_mode="r")
t = time.perf_counter()
targets = morph_targets_from_basis(Basis(rig.channel_names, rig.mesh.vertices, deltas), rig)
del deltas  # the basis is gone too: the targets are what the file needs
export_glb(rig, W / "head.glb", morph_targets=targets)
""",
    "11. export USD (morph targets)": """
from mimetic.engines.basis import Basis
from mimetic.export.gltf import morph_targets_from_basis
from mimetic.export.usd import export_usd
from mimetic.rig.format import load_rig
rig = load_rig(W / "head.mrig")
deltas = np.load(W / "deltas.npy", mmap_mode="r")
t = time.perf_counter()
targets = morph_targets_from_basis(Basis(rig.channel_names, rig.mesh.vertices, deltas), rig)
del deltas  # the basis is gone too: the targets are what the file needs
export_usd(rig, W / "head.usdc", morph_targets=targets)
""",
}
"""Each stage's child code: it sets ``t`` where the timed work begins; the files it reads are
written by the stages above it (``head.ply``, ``vertices.npy``, ``faces.npy`` and ``landmarks.pkl``
by ``write_input``). A stage that prints DIRECT did not run at this size (the mesh is rigged
directly, without a working copy)."""

NEEDS = {
    "2. weld": "1. load + validate",
    "3. working copy (decimate, embed)": "2. weld",
    "4. landmarks (MediaPipe)": "3. working copy (decimate, embed)",
    "5. fit": "3. working copy (decimate, embed)",
    "6. transfer + skin weights": "5. fit",
    "7. carry to every vertex": "6. transfer + skin weights",
    "8. save .mrig": "7. carry to every vertex",
    "9. bake (wire engine)": "8. save .mrig",
    "10. export GLB (morph targets)": "9. bake (wire engine)",
    "11. export USD (morph targets)": "9. bake (wire engine)",
}
"""The stage whose output each stage reads (a stage is skipped when that one failed)."""


@dataclass(frozen=True)
class Cell:
    """One stage at one size: ``peak_gib`` the child's peak RSS, ``seconds`` the stage's work,
    ``failure`` why it did not finish ('' when it did)."""

    peak_gib: float = math.nan
    seconds: float = math.nan
    failure: str = ""
    direct: bool = False


def subdivided(mesh: Mesh, levels: int) -> Mesh:
    """``mesh`` after ``levels`` midpoint subdivisions: its first ``mesh.n_vertices`` vertices kept,
    about 4× the vertices per level."""
    vertices, faces = mesh.vertices, mesh.faces
    for _ in range(levels):
        vertices, faces = trimesh.remesh.subdivide(vertices, faces)
    return Mesh(np.ascontiguousarray(vertices), np.ascontiguousarray(faces, dtype=np.int64), units="cm")


def write_input(mesh: Mesh, landmarks, folder: Path) -> None:
    """The files the stages start from: the head as PLY and as .npy arrays, the landmarks pickled."""
    save_mesh(mesh, folder / "head.ply")
    np.save(folder / "vertices.npy", mesh.vertices)
    np.save(folder / "faces.npy", mesh.faces)
    (folder / "landmarks.pkl").write_bytes(pickle.dumps(landmarks))


def run_stage(stage: str, folder: Path, bound_gib: float) -> Cell:
    """Run ``stage`` in a fresh capped child; its peak, time, or why it failed."""
    code = (
        _PRELUDE.format(folder=str(folder)) + STAGES[stage] + "\nprint('SECONDS', time.perf_counter() - t)\n"
    )
    cap = int((bound_gib + HEADROOM_GIB) * 2**30)
    try:
        measured = peak_rss(code, max_address_space=cap, timeout_s=3600)
    except RuntimeError as error:
        text = str(error)
        if any(sign in text for sign in ("MemoryError", "bad_alloc", "Unable to allocate", "(exit -9)")):
            return Cell(failure=f"**over bound** (failed at the {bound_gib + HEADROOM_GIB:g} GiB cap)")
        last = [line for line in text.splitlines() if line.strip()][-1:]
        return Cell(failure="failed: " + (last[0][:80] if last else "no message"))
    seconds = float(
        next(line.split()[1] for line in measured.stdout.splitlines() if line.startswith("SECONDS"))
    )
    return Cell(measured.peak_gib, seconds, direct="DIRECT" in measured.stdout.split())


BAKE_STAGES = ("9. bake (wire engine)", "10. export GLB (morph targets)", "11. export USD (morph targets)")


def measure(
    levels: tuple[int, ...], bound_gib: float, keep: Path | None, bake_up_to: int | None = None
) -> tuple[list[int], dict]:
    """Every stage at every size: (vertex counts, {stage: [Cell per size]}); the bake and export
    stages only up to ``bake_up_to`` vertices when given. What is measured so far is written to
    ``out/memory.json`` after each size (``--table`` prints it)."""
    ict, meta = load_ict(shared_data_dir() / "ict-facekit")
    sizes, cells = [], {stage: [] for stage in STAGES}
    for level in levels:
        mesh = subdivided(ict, level)
        sizes.append(mesh.n_vertices)
        with tempfile.TemporaryDirectory(prefix="bench_memory_", dir=keep) as tmp:
            folder = Path(tmp)
            write_input(mesh, ict_landmarks(mesh, meta), folder)
            for stage in STAGES:
                need = NEEDS.get(stage)
                if stage in BAKE_STAGES and bake_up_to is not None and mesh.n_vertices > bake_up_to:
                    cells[stage].append(Cell(failure=f"not run (--bake-up-to {bake_up_to:,})"))
                    continue
                if need and cells[need][-1].failure:
                    cells[stage].append(Cell(failure=f"skipped ({need.split(' ', 1)[1]} failed)"))
                    continue
                cell = run_stage(stage, folder, bound_gib)
                cells[stage].append(cell)
                report.console.print(
                    f"   {mesh.n_vertices:>9,} vertices  {stage:<40} "
                    + (cell.failure or f"{cell.peak_gib:6.2f} GiB {cell.seconds:8.1f} s")
                )
        save_json(sizes, cells)
    return sizes, cells


def save_json(sizes: list[int], cells: dict) -> None:
    """The cells measured so far, as ``out/memory.json``."""
    raw = {stage: [c.__dict__ for c in row] for stage, row in cells.items()}
    report.OUT.mkdir(exist_ok=True)
    with atomic_write(report.OUT / "memory.json", "w") as handle:
        json.dump({"sizes": sizes, "cells": raw}, handle, indent=1)


def load_json() -> tuple[list[int], dict]:
    """``out/memory.json`` as (sizes, {stage: [Cell]}), sizes not measured by every stage dropped."""
    data = json.loads((report.OUT / "memory.json").read_text())
    cells = {stage: [Cell(**c) for c in row] for stage, row in data["cells"].items()}
    count = min(len(row) for row in cells.values())
    return data["sizes"][:count], {stage: row[:count] for stage, row in cells.items()}


def slope(sizes: list[int], values: list[float]) -> float:
    """The log-log slope of ``values`` between the two largest ``sizes`` (nan when either is missing)."""
    (n1, n2), (a, b) = sizes[-2:], values[-2:]
    if not (a > 0 and b > 0):
        return math.nan
    return math.log(b / a) / math.log(n2 / n1)


def cell_text(cell: Cell, bound_gib: float) -> str:
    if cell.failure:
        return cell.failure
    if cell.direct:
        return "— (rigged directly)"
    over = " **over bound**" if cell.peak_gib > bound_gib else ""
    return f"{cell.peak_gib:.2f} GiB · {cell.seconds:.1f} s{over}"


def table(sizes: list[int], cells: dict, bound_gib: float) -> tuple[tuple[str, ...], list[tuple[str, ...]]]:
    """Columns and rows: stage | one column per size | growth of peak and time | peak × baseline."""
    columns = (
        "stage",
        *(f"{n / 1e6:.2f}M vertices" if n >= 1e6 else f"{n / 1e3:.0f}k vertices" for n in sizes),
        "growth: peak, time",
        f"peak / baseline at {sizes[-1] / 1e6:.2f}M",
    )
    base = next(iter(cells.values()))[-1].peak_gib
    rows = []
    for stage, row in cells.items():
        peak = slope(sizes, [math.nan if c.direct else c.peak_gib for c in row])
        seconds = slope(sizes, [math.nan if c.direct else c.seconds for c in row])
        ratio = row[-1].peak_gib / base
        rows.append((
            stage,
            *(cell_text(c, bound_gib) for c in row),
            "—" if math.isnan(peak) else f"{peak:.2f}, {seconds:.2f}",
            "—" if math.isnan(ratio) else f"{ratio:.1f}",
        ))  # fmt: skip
    return columns, rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="up to 420k vertices (ICT subdivided twice)")
    parser.add_argument("--bound-gib", type=float, default=BOUND_GIB, help="the peak allowed per stage")
    parser.add_argument("--keep", type=Path, help="make the working folders in DIR (default: the system's)")
    parser.add_argument(
        "--bake-up-to", type=int, metavar="N", help="bake and export only meshes of at most N vertices"
    )
    parser.add_argument(
        "--table", action="store_true", help="print the table of out/memory.json, measure nothing"
    )
    args = parser.parse_args()
    if shared_data_dir() is None:
        report.console.print(
            "ICT-FaceKit not in the shared data (mimetic.testing.shared_data_dir()): nothing to do"
        )
        return
    begin = time.perf_counter()
    if args.table:
        sizes, cells = load_json()
    else:
        sizes, cells = measure(
            QUICK_LEVELS if args.quick else LEVELS, args.bound_gib, args.keep, args.bake_up_to
        )
    columns, rows = table(sizes, cells, args.bound_gib)
    markdown = report.show(
        f"Peak RSS and time of each stage, fresh child per stage (bound {args.bound_gib:g} GiB)",
        columns,
        rows,
        "growth: log-log slope between the two largest sizes (1 = linear in the vertex count)",
    )
    report.save("memory", [markdown])
    save_json(sizes, cells)
    report.console.print(f"benchmark wall time {time.perf_counter() - begin:.0f} s")


if __name__ == "__main__":
    main()
