"""The demo job behind ``mimetic demo`` and ``make demo``: real outputs from the built-in head.

Writes, into one folder: the default head as ``head.glb``, its rig ``default.mrig``, eight
random heads with their rigs (``heads/seed_N.glb``, ``rigs/seed_N.mrig``), the default head from
three angles (``default_views.png``) and a contact sheet of all nine heads with their muscles
drawn (``heads_muscles.png``).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from mimetic.head.model import DEFAULT_RESOLUTION, make_head
from mimetic.head.params import HeadParams
from mimetic.mesh.io import save_mesh
from mimetic.rig.format import save_rig
from mimetic.rig.recipe import build_rig
from mimetic.view.muscles import render_rig
from mimetic.view.render import Renderer
from mimetic.view.sheet import contact_sheet, save_png

Progress = Callable[[int, int], None]


@dataclass(frozen=True)
class DemoResult:
    out_dir: Path
    files: tuple[Path, ...]


def run_demo(
    out_dir: str | Path = "mimetic-demo",
    *,
    seeds: tuple[int, ...] = tuple(range(1, 9)),
    resolution: int = DEFAULT_RESOLUTION,
    size: int = 384,
    progress: Progress | None = None,
) -> DemoResult:
    """Generate the default head and ``seeds`` random heads, rig and render them into ``out_dir``."""
    out = Path(out_dir)
    (out / "heads").mkdir(parents=True, exist_ok=True)
    (out / "rigs").mkdir(parents=True, exist_ok=True)
    renderer = Renderer()
    files: list[Path] = []
    tiles = []
    jobs: list[int | None] = [None, *seeds]
    total = len(jobs) + 1
    for done, seed in enumerate(jobs):
        params = HeadParams() if seed is None else HeadParams.random(seed)
        head = make_head(params, resolution)
        rig = build_rig(head)
        if seed is None:
            files.append(save_mesh(head.mesh, out / "head.glb"))
            files.append(save_rig(rig, out / "default.mrig"))
            views = [
                (view, render_rig(rig, view, size=size, muscles=False, renderer=renderer))
                for view in ("front", "three_quarter", "profile")
            ]
            files.append(save_png(contact_sheet(views, columns=3), out / "default_views.png"))
            label = "default"
        else:
            files.append(save_mesh(head.mesh, out / "heads" / f"seed_{seed}.glb"))
            files.append(save_rig(rig, out / "rigs" / f"seed_{seed}.mrig"))
            label = f"seed {seed}"
        tiles.append((f"{label}: front", render_rig(rig, "front", size=size, renderer=renderer)))
        tiles.append(
            (f"{label}: three-quarter", render_rig(rig, "three_quarter", size=size, renderer=renderer))
        )
        if progress:
            progress(done + 1, total)
    files.append(save_png(contact_sheet(tiles, columns=6), out / "heads_muscles.png"))
    if progress:
        progress(total, total)
    return DemoResult(out, tuple(files))
