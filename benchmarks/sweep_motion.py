"""Robustness sweep of motion over many heads (issue 28, "Faces that move right on every head").

    python benchmarks/sweep_motion.py [--quick] [--identities N] [--engines wire,vector,fem,tissue]

Every head is rigged automatically (``rig_head`` with automatic landmarks) and measured with the
definitions of ``mimetic.quality`` (as ``bench_quality.py`` tables a-c), in cm:

* **lids**: both upper lids at their maximum (``closed_lids_pose``); the gap between the margins
  (``find_lid_margins``) column by column, and the eyeball seen from the front (``seen_eyeball``:
  the height of eyeball a render shows per column). Goal: nothing over 0.1 cm seen and no margin
  column below −0.01 cm (crossing), on both eyes; on a head without eyeballs, the margins' largest
  gap ≤ 0.1 cm instead.
* **widest**: ``jaw_open`` at the value whose chin drop equals ICT's ``jawOpen`` shape's (ICT's
  own drop on ICT's topology; 4.05 cm × head height / ICT's elsewhere); the widest single
  face-edge opening. Goal ≤ 0.4 cm; ICT's own jawOpen on the same head is shown beside it.
* **flips**: lip triangles flipped in any expression of the library, summed. Goal 0 for wire,
  vector and fem; ≤ 20 for tissue.

Heads, in two groups. *Calibration*: the heads the lid and jaw constants were fitted on (ICT's
neutral, identities s1-s2 at σ 1, s2-s6 at σ 2 and s4 at σ 3; see docs/quality.md). *Check*:
everything else, never used to choose a constant: ICT identities (``ict_identity(seed, σ)`` over
the 20 modes, seeds 101.., σ cycling 1, 2, 3), MediaPipe's canonical mask (no lids: skipped),
generated heads (seeds 1..3), and copies of the ICT neutral in millimetres, Z-up (face toward −Y,
as Blender exports) and as a triangle soup (every face with vertices of its own). ``--quick``: 6
identities, one generated head.
"""

from __future__ import annotations

import argparse
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial

import numpy as np

import report
from bench_quality import CROSSING_TOL_CM, Case, Heads, Reference, titled
from mimetic.animate.expressions import expression_pose, load_library
from mimetic.engines import ENGINES as ALL_ENGINES
from mimetic.engines import make_engine
from mimetic.fit.autolandmarks import auto_landmarks
from mimetic.fit.pipeline import rig_head
from mimetic.mesh.model import Mesh, SurfacePoint
from mimetic.mesh.units import UNIT_SCALE
from mimetic.quality import (
    chin_drop,
    closed_lids_pose,
    edge_stretch,
    find_lid_margins,
    lid_gap,
    lip_faces,
    matched_jaw_open,
    most_eyeball_seen,
    triangle_flips,
)
from mimetic.testing import triangle_soup

TABLES: list[str] = []
"""The tables written to ``out/sweep-motion.md`` (``report.save``), in order."""
GOAL_LID_GAP_CM = 0.1
GOAL_WIDEST_CM = 0.4
GOAL_FLIPS = {"tissue": 20}
"""Flipped lip triangles allowed over the library (every other engine: 0)."""
CALIBRATION_IDENTITIES = ((1, 1.0), (2, 1.0), *((s, 2.0) for s in range(2, 7)), (4, 3.0))
"""The identities the lid, margin and jaw constants were chosen on (with ICT's neutral)."""
SIGMAS = (1.0, 2.0, 3.0)
FIRST_CHECK_SEED = 101
Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])
"""Y-up, face toward +Z → Z-up, face toward −Y (Blender's convention)."""


@dataclass(frozen=True)
class Row:
    """One head and engine: the measurements (cm) and the goals met."""

    head: str
    group: str
    engine: str
    lids: tuple[float, float] | None  # smallest, largest gap at maximum closure; None: no lids
    crossing: str
    seen: float | None  # the most eyeball seen in a column at maximum closure; None: no eyeballs
    widest: float
    ict_widest: float | None
    flips: int
    worst: str  # the expressions with flips

    def verdict(self) -> str:
        failed = []
        if self.lids is not None and not lids_met(self):
            failed.append("lids")
        if self.widest > GOAL_WIDEST_CM:
            failed.append("widest")
        if self.flips > GOAL_FLIPS.get(self.engine, 0):
            failed.append("flips")
        return "met" if not failed else "NOT met: " + ", ".join(failed)


def lids_met(row: Row) -> bool:
    """The lids meet: as seen where the head has eyeballs, by the margins' gap where it has not."""
    gap = row.lids[1] if row.lids is not None and row.seen is None else row.seen
    return row.lids is not None and gap <= GOAL_LID_GAP_CM and not row.crossing


def margins_met(row: Row) -> bool:
    """The lids meet by the margins' gap alone (the measure before the seen one)."""
    return row.lids is not None and row.lids[1] <= GOAL_LID_GAP_CM and not row.crossing


def to_cm(case: Case) -> float:
    units = case.rig.mesh.units or "cm"
    return UNIT_SCALE[units] / UNIT_SCALE["cm"]


def measure(case: Case, group: str, engine_name: str, reference: Reference) -> Row:
    rig = case.rig
    cm = to_cm(case)
    engine = make_engine(rig, engine_name)
    rest = engine.deform(np.array([c.default for c in rig.channels], dtype=np.float64))
    ict_widest = None
    if case.jaw_delta is not None:
        shape = rig.mesh.vertices + case.jaw_delta / cm
        target = chin_drop(rig, rig.mesh.vertices, shape, chin=case.chin)
        ict_widest = edge_stretch(rig.mesh.vertices, shape, case.faces).widest * cm
    else:
        target = reference.drop_rel * rig.scale
    match = matched_jaw_open(engine, target, chin=case.chin)
    widest = edge_stretch(rest, match.vertices, case.faces).widest * cm
    lips = lip_faces(rig, case.faces)
    library = load_library()
    flips = {}
    for name in library.names:
        count = int(triangle_flips(rest, engine.deform(expression_pose(rig, name)), lips).sum())
        if count:
            flips[name] = count
    worst = ", ".join(f"{n} {c}" for n, c in sorted(flips.items(), key=lambda kv: -kv[1])[:3])
    margins = [find_lid_margins(rig, side) for side in ("L", "R")]
    lids, crossing, seen = None, "", None
    if all(m.usable for m in margins):
        closed = engine.deform(closed_lids_pose(rig))
        shown = most_eyeball_seen(rig, closed)
        seen = None if shown is None else shown * cm
        gaps = [lid_gap(m, closed, tolerance=CROSSING_TOL_CM / cm) for m in margins]
        lids = (min(g.smallest for g in gaps) * cm, max(g.largest for g in gaps) * cm)
        crossing = ", ".join(g.side for g in gaps if g.crossing)
    elif not any(m.bridged for m in margins):  # a head with lids whose margins were not found
        lids, crossing = (float("nan"), float("inf")), "margins not found"
    return Row(
        case.name, group, engine_name, lids, crossing, seen, widest, ict_widest, sum(flips.values()), worst
    )


def copy(heads: Heads, name: str) -> Case:
    """The ICT neutral rigged in millimetres ("ICT in mm"), Z-up ("ICT Z-up") or as a triangle soup
    ("ICT soup"), from automatic landmarks."""
    neutral, faces = heads.neutral, heads.ict_faces
    chin = SurfacePoint.at_vertex(heads.menton, neutral.faces)
    if name == "ICT in mm":
        mesh = Mesh(neutral.vertices * 10.0, neutral.faces, units="mm")
    elif name == "ICT Z-up":
        mesh = Mesh(neutral.vertices @ Z_UP.T, neutral.faces, units="cm")
    else:
        mesh = triangle_soup(Mesh(neutral.vertices, neutral.faces, units="cm"))
        # face k of the soup is face k of the neutral: the face set keeps its faces' indices
        faces, chin = mesh.faces[np.flatnonzero(np.isin(neutral.faces, faces).all(axis=1))], None
    begin = time.perf_counter()
    rig = rig_head(mesh, auto_landmarks(mesh)).rig
    delta = heads.jaw if chin is not None else None  # cm: ``measure`` converts it
    return Case(name, rig, faces, "automatic", time.perf_counter() - begin, delta, chin)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="6 identities and one generated head")
    parser.add_argument("--identities", type=int, default=50, help="check identities (default 50)")
    parser.add_argument("--engines", default="wire", help="comma-separated engines (default wire)")
    args = parser.parse_args()
    engines = tuple(e for e in args.engines.split(",") if e)
    if set(engines) - set(ALL_ENGINES):
        parser.error(f"unknown engines; choose from {', '.join(ALL_ENGINES)}")
    warnings.simplefilter("ignore")  # the rigs' own warnings are not what this measures
    begin = time.perf_counter()
    heads = Heads()
    reference = heads.jaw_reference()
    n_ids = 6 if args.quick else args.identities
    # (group, build): each head is rigged when measured and dropped after, so 60 rigs never share memory
    groups: list[tuple[str, Callable[[], Case | None]]] = []
    if heads.has_ict:
        groups += [("calibration", heads.ict_auto)]
        groups += [("calibration", partial(heads.identity, s, sigma)) for s, sigma in CALIBRATION_IDENTITIES]
        checks = [(FIRST_CHECK_SEED + k, SIGMAS[k % len(SIGMAS)]) for k in range(n_ids)]
        groups += [("check", partial(heads.identity, s, sigma)) for s, sigma in checks]
        groups += [("check", partial(copy, heads, name)) for name in ("ICT in mm", "ICT Z-up", "ICT soup")]
    groups.append(("check", heads.mediapipe))
    groups += [("check", partial(heads.generated, seed)) for seed in ((1,) if args.quick else (1, 2, 3))]
    rows = []
    for k, (group, build) in enumerate(groups, 1):
        case = build()
        if case is None:  # MediaPipe's mesh missing
            continue
        for e in engines:
            rows.append(measure(case, group, e, reference))
            r = rows[-1]
            lids = "no lids" if r.lids is None else f"lids {r.lids[1]:+.2f}"
            print(
                f"[{k}/{len(groups)}] {r.head} {e}: widest {r.widest:.2f}, flips {r.flips}, {lids}",
                r.crossing,
            )
        heads.cache.clear()
        del case
    titled(
        "motion on every head (cm; goals: lids ≤ 0.1 no crossing, widest ≤ 0.4, flips 0 (tissue ≤ 20))",
        (
            "head",
            "group",
            "engine",
            "lids at max",
            "crossing",
            "eyeball seen",
            "widest",
            "ICT jawOpen",
            "flips",
            "verdict",
        ),
        [
            (
                r.head,
                r.group,
                r.engine,
                "no lids" if r.lids is None else f"{r.lids[0]:+.2f} .. {r.lids[1]:+.2f}",
                r.crossing or "no",
                "" if r.seen is None else f"{r.seen:.2f}",
                f"{r.widest:.2f}",
                "" if r.ict_widest is None else f"{r.ict_widest:.2f}",
                f"{r.flips}" + (f" ({r.worst})" if r.worst else ""),
                r.verdict(),
            )
            for r in rows
        ],
        TABLES,
    )
    summary = []
    for group in ("calibration", "check"):
        for e in engines:
            sel = [r for r in rows if r.group == group and r.engine == e]
            if not sel:
                continue
            with_lids = [r for r in sel if r.lids is not None]
            summary.append(
                (
                    group,
                    e,
                    str(len(sel)),
                    f"{sum(margins_met(r) for r in with_lids)} of {len(with_lids)}",
                    f"{sum(lids_met(r) for r in with_lids)} of {len(with_lids)}",
                    f"{sum(r.widest <= GOAL_WIDEST_CM for r in sel)} of {len(sel)}",
                    f"{sum(r.flips <= GOAL_FLIPS.get(e, 0) for r in sel)} of {len(sel)}",
                    f"{np.median([r.widest for r in sel]):.2f} / {max(r.widest for r in sel):.2f}",
                    f"{sum(r.verdict() == 'met' for r in sel)} of {len(sel)}",
                )
            )
    titled(
        "summary: heads meeting each goal",
        (
            "group",
            "engine",
            "heads",
            "lids (margins)",
            "lids (seen)",
            "widest",
            "flips",
            "widest median / max",
            "all goals",
        ),
        summary,
        TABLES,
    )
    print(f"\nsweep wall time {time.perf_counter() - begin:.0f} s")
    report.save("sweep-motion", TABLES)


if __name__ == "__main__":
    main()
