"""The physical engines through a proxy (issue 31, item 2): what the proxy changes, and what it makes fit.

    python benchmarks/bench_proxy.py [--quick] [--rigs DIR] [--bound-gib 8]

1. **Proxy against full resolution**, on ICT-FaceKit's neutral head (26,719 vertices, 19,167 welded
   skin vertices, cm), where both fit: each engine (fem, tissue) prepared with ``proxy="off"`` and
   with proxies of ``PROXIES`` skin vertices, posed in ``EXPRESSIONS``. Per region of the rig (mouth:
   both lips; cheeks; nasolabial folds; brows; lids: all four; forehead; nose; chin), the largest
   difference between the proxy's vertices and the full simulation's, in cm, and its ratio to the
   baseline: the largest motion of the full simulation in that region (how far the skin moved).
2. **A 420k-vertex head** (ICT subdivided twice, ``bench_memory.subdivided``: 419,929 vertices,
   300,177 welded skin vertices), rigged by ``rig_head`` from ICT's own landmark vertices (cached in
   ``--rigs``, default a folder in the system's temporary directory), posed in joy by ``fem`` and
   ``tissue`` with the automatic proxy, each in a fresh process (``mimetic.testing.memory.peak_rss``:
   the child's ``VmHWM``, capped at the bound plus ``HEADROOM_GIB``): peak memory, the engine's
   preparation and one pose, against the bound (8 GiB) and the baseline measured in the same run: the
   same child posing with the vector engine (the rig loaded, Waters' geometric muscles, no tissue).

``--quick`` stops after part 1 with one proxy size and two expressions.
"""

from __future__ import annotations

import argparse
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

import report
from bench_memory import HEADROOM_GIB, subdivided
from mimetic.animate.expressions import compose_pose
from mimetic.engines import make_engine
from mimetic.fit.pipeline import rig_head
from mimetic.rig.format import load_rig, save_rig
from mimetic.testing import ict_landmarks, load_ict, shared_data_dir
from mimetic.testing.memory import peak_rss

TABLES: list[str] = []
PROXIES = (5_000, 10_000)
"""Proxy sizes compared with ICT's full skin (19,167): a quarter and half of it."""
EXPRESSIONS = ("joy", "surprise", "anger", "pucker")
REGIONS = {
    "mouth": ("upper_lip", "lower_lip"),
    "cheeks": ("cheek_L", "cheek_R"),
    "nasolabial": ("nasolabial_L", "nasolabial_R"),
    "brows": ("brow_L", "brow_R"),
    "lids": ("eyelid_upper_L", "eyelid_upper_R", "eyelid_lower_L", "eyelid_lower_R"),
    "forehead": ("forehead",),
    "nose": ("nose",),
    "chin": ("chin",),
}
BOUND_GIB = 8.0
DENSE_LEVEL = 2
"""ICT's midpoint subdivisions for the dense head: 419,929 vertices."""

_CHILD = """
import time, warnings
warnings.simplefilter("ignore")
from mimetic.animate.expressions import compose_pose
from mimetic.engines import make_engine
from mimetic.rig.format import load_rig
rig = load_rig({path!r})
t = time.perf_counter()
engine = make_engine(rig, {engine!r})
print("SETUP", time.perf_counter() - t, getattr(getattr(engine, "volume", None), "n_skin", 0))
t = time.perf_counter()
engine.deform(compose_pose(rig, (("joy", 1.0),)))
print("POSE", time.perf_counter() - t)
"""


def cached_rig(level: int, folder: Path):
    """ICT subdivided ``level`` times, rigged (``rig_head``, ICT's landmark vertices), from ``folder``
    when it was rigged before."""
    path = folder / f"ict_subdivided_{level}.mrig"
    if not path.exists():
        ict, meta = load_ict(shared_data_dir() / "ict-facekit")
        mesh = subdivided(ict, level)
        began = time.perf_counter()
        result = rig_head(mesh, ict_landmarks(mesh, meta), force=True)
        save_rig(result.rig, path)
        report.console.print(f"rigged {mesh.n_vertices:,} vertices in {time.perf_counter() - began:.0f} s")
    return path


def accuracy(rig, proxies: tuple[int, ...], expressions: tuple[str, ...]) -> None:
    """Part 1: per region, the proxy's largest difference from the full simulation (module docstring)."""
    rows, timing = [], []
    poses = {name: compose_pose(rig, ((name, 1.0),)) for name in expressions}
    for engine_name in ("fem", "tissue"):
        shapes = {}
        for proxy in ("off", *proxies):
            began = time.perf_counter()
            engine = make_engine(rig, engine_name, proxy=proxy)
            setup = time.perf_counter() - began
            began = time.perf_counter()
            shapes[proxy] = {name: engine.deform(values) for name, values in poses.items()}
            posed = (time.perf_counter() - began) / len(poses)
            timing.append(
                (engine_name, str(proxy), f"{engine.volume.n_skin:,}", f"{setup:.1f} s", f"{posed:.2f} s")
            )
            del engine
        for proxy in proxies:
            for name in expressions:
                full = shapes["off"][name]
                gap = np.linalg.norm(shapes[proxy][name] - full, axis=1)
                motion = np.linalg.norm(full - rig.mesh.vertices, axis=1)
                cells = []
                for parts in REGIONS.values():
                    ids = np.unique(np.concatenate([rig.regions[p] for p in parts]))
                    moved = motion[ids].max()
                    ratio = f" ({gap[ids].max() / moved:.0%})" if moved > 0.05 else ""
                    cells.append(f"{gap[ids].max():.2f}{ratio}")
                rms = np.sqrt(np.mean(gap**2))
                rows.append((engine_name, f"{proxy:,}", name, *cells, f"{gap.max():.2f}", f"{rms:.3f}"))
    TABLES.append(
        report.show(
            "Proxy against full resolution: ICT-FaceKit (19,167 skin vertices)",
            ("engine", "proxy", "expression", *REGIONS, "all: max", "all: rms"),
            rows,
            "Largest difference (cm) between the proxy's and the full simulation's vertices per region; in "
            "brackets its ratio to the baseline, the full simulation's largest motion in the region (left "
            "out where the skin moved less than 0.05 cm). The head is 22.1 cm tall.",
        )
    )
    TABLES.append(
        report.show(
            "Preparation and pose, ICT-FaceKit",
            ("engine", "proxy", "skin nodes", "prepare", "pose (mean)"),
            timing,
            "One engine at a time, in this process; pose: the static solve of one expression and the chain.",
        )
    )


def dense(path: Path, bound_gib: float) -> None:
    """Part 2: the 420k head posed by each engine in a fresh capped process (module docstring)."""
    rows, baseline = [], None
    cap = int((bound_gib + HEADROOM_GIB) * 2**30)
    for engine_name in ("vector", "fem", "tissue"):
        try:
            measured = peak_rss(_CHILD.format(path=str(path), engine=engine_name), max_address_space=cap)
        except RuntimeError as error:
            last = [line for line in str(error).splitlines() if line.strip()][-1:]
            rows.append((engine_name, "failed: " + (last[0][:80] if last else ""), "", "", "", "", ""))
            continue
        values = {line.split()[0]: line.split()[1:] for line in measured.stdout.splitlines() if line.strip()}
        peak = measured.peak_gib
        baseline = baseline or peak
        skin = int(values["SETUP"][1])
        rows.append(
            (
                engine_name,
                f"{skin:,}" if skin else "",
                f"{peak:.2f}",
                "yes" if peak <= bound_gib else "**no**",
                f"{float(values['SETUP'][0]):.0f} s",
                f"{float(values['POSE'][0]):.2f} s",
                f"{peak / baseline:.2f}",
            )
        )
        report.console.print(f"   {engine_name}: {peak:.2f} GiB")
    TABLES.append(
        report.show(
            "A 420k-vertex head (ICT subdivided twice) posed in joy",
            (
                "engine",
                "proxy skin nodes",
                "peak GiB",
                f"within {bound_gib:g} GiB",
                "prepare",
                "pose",
                "ratio",
            ),
            rows,
            "Each engine in a fresh process: the rig loaded, the engine prepared (the automatic proxy: "
            "300,177 welded skin vertices decimated to about 20,000), one pose. Ratio: peak over the "
            "baseline's, the vector engine in the same child.",
        )
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="part 1 only, one proxy, two expressions")
    parser.add_argument("--rigs", type=Path, default=Path(tempfile.gettempdir()) / "mimetic-bench-proxy")
    parser.add_argument("--bound-gib", type=float, default=BOUND_GIB)
    args = parser.parse_args()
    if shared_data_dir() is None:
        raise SystemExit("bench_proxy needs the shared data folder (ICT-FaceKit); set MIMETIC_SHARED_DATA")
    args.rigs.mkdir(parents=True, exist_ok=True)
    warnings.simplefilter("ignore")
    begin = time.perf_counter()
    rig = load_rig(cached_rig(0, args.rigs))
    if args.quick:
        accuracy(rig, PROXIES[:1], EXPRESSIONS[:2])
    else:
        accuracy(rig, PROXIES, EXPRESSIONS)
        dense(cached_rig(DENSE_LEVEL, args.rigs), args.bound_gib)
    print(f"\nbenchmark wall time {time.perf_counter() - begin:.0f} s")
    report.save("proxy", TABLES)


if __name__ == "__main__":
    main()
