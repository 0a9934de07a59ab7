"""Benchmark motion quality (issue 11, "Faces that move like faces"): stretch at the ICT-matched jaw drop,
lips, lids and expression fidelity, per head and engine.

    python benchmarks/bench_quality.py [--quick] [--tables abc|de] [--engines wire,vector,fem,...]

The definitions are ``mimetic.quality``'s (its module docstring); this script only builds the heads,
poses them and prints. Lengths are in cm (every head here is in cm).

Heads (all but the generated ones need the shared data, ``mimetic.testing.shared_data_dir()``;
without it they are skipped with a note):

* ``ICT file``: ICT-FaceKit's neutral rigged from its file landmarks (49 iBUG points);
* ``ICT auto``: the same mesh rigged from automatic landmarks (``auto_landmarks``, MediaPipe);
* ``ICT id s<seed> σ<sigma>``: ICT identity heads (``mimetic.testing.ict_identity``: neutral + Σ w_k
  identity_k, w ~ N(0, σ) from ``default_rng(seed)``), rigged from automatic landmarks (from the file
  landmarks, said in the name, if MediaPipe is missing). Tables a-c: seeds 1 and 2 at σ 1 and seed 1
  at σ 2 (``--quick``: seed 1 at σ 1 and at σ 2);
* ``MediaPipe``: MediaPipe's canonical mesh (468 vertices, a face-only mask whose eyes and mouth slit
  are closed by triangles), rigged from its own landmark vertices;
* ``generated default`` / ``generated s<seed>``: the built-in recipe's heads (``build_rig(make_head)``,
  10,000 skin vertices): the default head and random seeds 1 and 2 (``--quick``: 1).

Face set (the edges and triangles that count): ICT's "Face" part (vertices 0..9408) on ICT's
topology; the front skin (chart directions z > 0.3) of a generated head; MediaPipe's faces minus the
46 that close its mouth slit and eye openings.

Tables (every engine, or those named by ``--engines``):

a. Jaw: ``jaw_open`` alone at the value whose chin drop equals ICT's ``jawOpen`` shape's: on ICT's
   topology the drop of that shape at ICT's menton vertex (iBUG 8) on that head (4.05 cm), elsewhere
   4.05 cm times the head height over ICT's (``Rig.scale``), at the rig's menton. Face-edge stretch
   p99 and widest single-edge opening; baseline = ICT's own ``jawOpen`` shape on the same head (the
   head + ICT's delta), or on the ICT neutral for other topologies (marked "ICT"). Target: p99 ≤
   baseline and widest ≤ 0.3 cm.
b. Lips: triangle flips of the lip faces (face set ∩ upper/lower lip regions) in each expression of
   the library (target on every head: none; ICT's own 53 shapes flip some on ICT's topology, shown
   as the baseline), the worst face-edge stretch over the library, and the upper lip under
   ``jaw_open`` alone at the matched drop (``upper_lip_follow``; target: no more than ICT's own
   ``jawOpen`` on the same head, or on the ICT neutral for other topologies).
c. Lids: margins from ``find_lid_margins`` (MediaPipe's mask has none: skipped); gap per column at
   rest and with both upper lids at their maximum (target, both eyes: largest gap ≤ 0.1 cm, none
   below −0.01 cm); the left upper margin's roughness at rest (baseline) and in the library's
   ``wink``.
d. Fidelity: ICT's 53 expression shapes fitted on the baked rig (``bake(engine).basis``) over ICT's
   face (vertices 0..9408), ``expression_fidelity``: median and worst per head and engine. ICT auto
   (wire, vector), ICT file (wire; both engines in the full run), and identity heads (automatic
   landmarks; full: 14 heads, calibration seeds 1-5 at σ 1 and 1-3 at σ 2 and check seeds 101-106 at
   σ 1, 2, 3 in turn, both engines; --quick: s1 σ 1, s1 σ 2, s101 σ 1, s102 σ 2, wire).
   Targets: ICT auto median ≤ 30 % and every shape ≤ 60 %; identity medians within 5 points of ICT
   auto's (same engine).
e. Fidelity per shape (ICT file and auto, each engine run).
"""

from __future__ import annotations

import argparse
import os
import time
import warnings
from dataclasses import dataclass

import numpy as np

import report
from bench_rig import print_table, verdict  # the same tables as the fit benchmark
from mimetic.animate.expressions import expression_pose, load_library
from mimetic.engines import ENGINES as ALL_ENGINES
from mimetic.engines import make_engine
from mimetic.engines.bake import bake
from mimetic.fit.pipeline import rig_head
from mimetic.head.model import DEFAULT_RESOLUTION, make_head
from mimetic.head.params import HeadParams
from mimetic.mesh.geometry import face_normals
from mimetic.mesh.model import Mesh, SurfacePoint
from mimetic.quality import (
    ICT_JAW_DROP_REL,
    LidMargins,
    chin_drop,
    closed_lids_pose,
    edge_stretch,
    expression_fidelity,
    find_lid_margins,
    lid_gap,
    lid_roughness,
    lip_faces,
    margin_gap,
    matched_jaw_open,
    most_eyeball_seen,
    triangle_flips,
    upper_lip_follow,
)
from mimetic.rig.model import Rig
from mimetic.rig.recipe import build_rig
from mimetic.testing import (
    generated_face_faces,
    ict_expressions,
    ict_face_faces,
    ict_folder,
    ict_identity,
    ict_landmarks,
    load_ict,
    mediapipe_canonical,
    mediapipe_face_faces,
    mediapipe_landmarks,
    shared_data_dir,
)

TABLES: list[str] = []
"""The tables written to ``out/quality.md`` (``report.save``), in order."""


def titled(title: str, header: tuple[str, ...], rows: list[tuple[str, ...]], into: list[str] = TABLES) -> str:
    """``print_table``, its Markdown with the title as a paragraph above it (the titles define the
    columns and the targets) appended to ``into`` (``sweep_motion`` passes its own list) and returned."""
    table = f"{title}\n\n{print_table(title, header, rows)}"
    into.append(table)
    return table


ENGINES = tuple(ALL_ENGINES)
"""The engines measured (``--engines``); default: every engine."""
GOAL_WIDEST_CM = 0.3
GOAL_LID_GAP_CM = 0.1
CROSSING_TOL_CM = 0.01
"""A column crosses when its gap is below minus this: margins that meet at a corner at rest give ±0."""
GOAL_LIP_FOLLOW_FALLBACK = 0.10
"""Upper-lip follow target without the ICT data (ICT's own jawOpen: 0.10). With it the target is ICT's
own jawOpen value on the same head (on the ICT neutral for other topologies): a real face's upper lip
moves that much with the jaw, and more is a curtain."""
GOAL_FIDELITY_MEDIAN = 0.30
GOAL_FIDELITY_WORST = 0.60
GOAL_IDENTITY_POINTS = 5.0
ICT_MENTON_IBUG = 8  # iBUG-68 index of the menton (ICT vertex 966)
ICT_FACE = slice(0, 9409)
BAKE_SAMPLES = 2  # the basis does not depend on it; only bake's own error report does
TABLE_IDENTITIES = ((1, 1.0), (2, 1.0), (1, 2.0))
QUICK_TABLE_IDENTITIES = ((1, 1.0), (1, 2.0))
FIDELITY_IDENTITIES = (
    tuple((s, 1.0) for s in range(1, 6))
    + tuple((s, 2.0) for s in range(1, 4))
    + ((101, 1.0), (102, 2.0), (103, 3.0), (104, 1.0), (105, 2.0), (106, 3.0))
)
QUICK_FIDELITY_IDENTITIES = ((1, 1.0), (1, 2.0), (101, 1.0), (102, 2.0))
CHECK_SEEDS = range(101, 151)
"""Identities no constant was chosen on (``sweep_motion.py``'s check heads); the others (and ICT's
neutral) are calibration heads."""
GENERATED_SEEDS = (None, 1, 2)
QUICK_GENERATED_SEEDS = (None, 1)


# --------------------------------------------------------------------------- printing


def verdicts(**parts: bool) -> str:
    """``"met"`` when every part is, else the parts not met: ``"NOT met: widest, flips"``."""
    failed = [name.replace("_", " ") for name, ok in parts.items() if not ok]
    return "met" if not failed else "NOT met: " + ", ".join(failed)


def pct(x: float) -> str:
    return f"{100 * x:.1f}"


# --------------------------------------------------------------------------- heads


@dataclass
class Case:
    """One rigged head and what its measurements need."""

    name: str
    rig: Rig
    faces: np.ndarray  # (k, 3) the face set
    landmarks: str  # where the rig's landmarks came from
    rig_s: float
    jaw_delta: np.ndarray | None = None  # ICT's jawOpen delta (n, 3) on ICT's topology
    chin: SurfacePoint | None = None  # where the chin drop is measured (None: the rig's menton)
    shapes: tuple[tuple[str, ...], np.ndarray] | None = (
        None  # ICT's 53 shapes (names, deltas) on ICT's topology
    )


def rig_timed(mesh: Mesh, landmarks) -> tuple[Rig, float]:
    begin = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = rig_head(mesh, landmarks)
    return result.rig, time.perf_counter() - begin


def auto_or_file(mesh: Mesh, meta: dict) -> tuple[object, str]:
    """Automatic landmarks of ``mesh``, or ICT's file landmarks when MediaPipe is unavailable."""
    try:
        from mimetic.fit.autolandmarks import auto_landmarks

        return auto_landmarks(mesh), "auto"
    except Exception as error:  # MediaPipe missing, or no face found: say so and use the file's
        print(f"   auto_landmarks failed ({type(error).__name__}: {error}); using the file landmarks")
        return ict_landmarks(mesh, meta), "file"


class Heads:
    """Builds and caches the rigged heads (each at most once per run)."""

    def __init__(self) -> None:
        self.folder = ict_folder()
        self.cache: dict[str, Case] = {}
        if self.folder is not None:
            self.neutral, self.meta = load_ict(self.folder)
            self.names, self.deltas = ict_expressions(self.folder)
            self.jaw = self.deltas[self.names.index("jawOpen")]
            self.menton = int(self.meta["landmarks_68"]["vertex_indices"][ICT_MENTON_IBUG])
            self.ict_faces = ict_face_faces(self.neutral, self.meta)

    @property
    def has_ict(self) -> bool:
        return self.folder is not None

    def ict_case(self, name: str, mesh: Mesh, source: str) -> Case:
        if name not in self.cache:
            begin = time.perf_counter()
            if source == "file":
                landmarks, used = ict_landmarks(mesh, self.meta), "file"
            else:
                landmarks, used = auto_or_file(mesh, self.meta)
            rig, _ = rig_timed(mesh, landmarks)
            label = name if used == source else f"{name} (file landmarks)"
            origin = (
                f"ICT file, {len(landmarks.names)} iBUG points"
                if used == "file"
                else f"automatic (MediaPipe), {len(landmarks.names)}"
            )
            chin = SurfacePoint.at_vertex(self.menton, rig.mesh.faces)
            self.cache[name] = Case(
                label,
                rig,
                self.ict_faces,
                origin,
                time.perf_counter() - begin,
                self.jaw,
                chin,
                (self.names, self.deltas),
            )
        return self.cache[name]

    def ict_file(self) -> Case:
        return self.ict_case("ICT file", self.neutral, "file")

    def ict_auto(self) -> Case:
        return self.ict_case("ICT auto", self.neutral, "auto")

    def identity(self, seed: int, sigma: float) -> Case:
        return self.ict_case(f"ICT id s{seed} σ{sigma:g}", ict_identity(seed, sigma, self.folder), "auto")

    def mediapipe(self) -> Case | None:
        if "MediaPipe" not in self.cache:
            try:
                mesh = mediapipe_canonical()
            except FileNotFoundError:
                return None
            landmarks = mediapipe_landmarks(mesh)
            rig, t = rig_timed(mesh, landmarks)
            origin = f"its own vertices, {len(landmarks.names)}"
            self.cache["MediaPipe"] = Case("MediaPipe", rig, mediapipe_face_faces(mesh), origin, t)
        return self.cache["MediaPipe"]

    def generated(self, seed: int | None) -> Case:
        name = "generated default" if seed is None else f"generated s{seed}"
        if name not in self.cache:
            begin = time.perf_counter()
            head = make_head(None if seed is None else HeadParams.random(seed), resolution=DEFAULT_RESOLUTION)
            rig = build_rig(head)
            t = time.perf_counter() - begin
            self.cache[name] = Case(name, rig, generated_face_faces(head), "built in (recipe)", t)
        return self.cache[name]

    def jaw_reference(self) -> Reference:
        """ICT's own jawOpen on the neutral (the baseline of heads of another topology)."""
        if not self.has_ict:
            nan = float("nan")
            return Reference(nan, ICT_JAW_DROP_REL, nan, nan, GOAL_LIP_FOLLOW_FALLBACK)
        rest = self.neutral.vertices
        rig = self.ict_file().rig
        drop = float(np.linalg.norm(self.jaw[self.menton]))
        stretch = edge_stretch(rest, rest + self.jaw, self.ict_faces)
        follow = upper_lip_follow(rig, rest, rest + self.jaw, vertices=np.unique(self.ict_faces)).ratio
        return Reference(drop, drop / rig.scale, stretch.p99, stretch.widest, follow)


@dataclass(frozen=True)
class Reference:
    """ICT's jawOpen shape on the ICT neutral: chin drop (cm) and that drop over the head height of the
    file-landmark rig; face-edge stretch p99 and widest opening (cm); upper-lip follow."""

    drop: float
    drop_rel: float
    p99: float
    widest: float
    follow: float


# --------------------------------------------------------------------------- tables a-c


@dataclass
class Rows:
    jaw: list
    lips: list
    lids: list


def measure(case: Case, engine_name: str, reference: Reference, rows: Rows) -> None:
    """Tables a-c for one head and engine: appends one row to each."""
    rig = case.rig
    engine = make_engine(rig, engine_name)
    defaults = np.array([c.default for c in rig.channels], dtype=np.float64)
    rest = engine.deform(defaults)
    mesh_rest = rig.mesh.vertices
    face_vertices = np.unique(case.faces)
    # a. jaw at the ICT-matched drop
    if case.jaw_delta is not None:
        shape = mesh_rest + case.jaw_delta
        target = chin_drop(rig, mesh_rest, shape, chin=case.chin)
        baseline = edge_stretch(mesh_rest, shape, case.faces)
        base_p99, base_widest, marker = baseline.p99, baseline.widest, ""
        base_follow = upper_lip_follow(rig, mesh_rest, shape, vertices=face_vertices)
    else:
        target = reference.drop_rel * rig.scale
        base_p99, base_widest, marker, base_follow = reference.p99, reference.widest, " ICT", None
    match = matched_jaw_open(engine, target, chin=case.chin)
    stretch = edge_stretch(rest, match.vertices, case.faces)
    reach = "" if match.reached else " (max; unreached)"
    rows.jaw.append(
        (
            case.name,
            engine_name,
            f"{match.value:.3f}{reach}",
            f"{match.drop:.2f} / {target:.2f}",
            f"{stretch.p99:.2f}",
            f"{base_p99:.2f}{marker}",
            f"{stretch.p99 / base_p99:.2f}",
            f"{stretch.widest:.2f}",
            f"{base_widest:.2f}{marker}",
            verdicts(p99=stretch.p99 <= base_p99, widest=stretch.widest <= GOAL_WIDEST_CM),
        )
    )

    # b. lips: flips and stretch over the library; the upper lip under jaw_open alone
    lips = lip_faces(rig, case.faces)
    library = load_library()
    lip_area = np.linalg.norm(face_normals(rest, lips, unit=False), axis=1) / 2  # (k,)
    flips, worst_p99, worst_widest, worst_area = {}, (0.0, ""), (0.0, ""), (0.0, "")
    for name in library.names:
        posed = engine.deform(expression_pose(rig, name))
        flipped = triangle_flips(rest, posed, lips)
        if flipped.any():
            flips[name] = int(flipped.sum())
            worst_area = max(worst_area, (float(lip_area[flipped].sum() / lip_area.sum()), name))
        s = edge_stretch(rest, posed, case.faces)
        worst_p99 = max(worst_p99, (s.p99, name))
        worst_widest = max(worst_widest, (s.widest, name))
    follow = upper_lip_follow(rig, rest, match.vertices, vertices=face_vertices)
    follow_goal = reference.follow if base_follow is None else base_follow.ratio
    if case.shapes is not None:
        ict_names, ict_deltas = case.shapes
        own = [int(triangle_flips(mesh_rest, mesh_rest + d, lips).sum()) for d in ict_deltas]
        k = int(np.argmax(own))
        flip_base = f"jawOpen {own[ict_names.index('jawOpen')]}, max {own[k]} ({ict_names[k]})"
        follow_base = f"{base_follow.ratio:.2f} ({base_follow.upper_p99:.2f} cm)"
    else:
        flip_base = ""
        follow_base = f"{reference.follow:.2f} ICT"
    shown = ", ".join(f"{n} {c}" for n, c in sorted(flips.items(), key=lambda kv: -kv[1])[:4])
    more = f" +{len(flips) - 4} more" if len(flips) > 4 else ""
    rows.lips.append(
        (
            case.name,
            engine_name,
            str(len(lips)),
            str(sum(flips.values())),
            f"{len(flips)} of {len(library)}" + (f": {shown}{more}" if flips else ""),
            f"{100 * worst_area[0]:.2f} ({worst_area[1]})" if flips else "0",
            flip_base,
            f"{worst_p99[0]:.2f} ({worst_p99[1]})",
            f"{worst_widest[0]:.2f} ({worst_widest[1]})",
            f"{follow.ratio:.2f} ({follow.upper_p99:.2f} cm)",
            follow_base,
            verdicts(flips=not flips, follow=follow.ratio <= follow_goal),
        )
    )

    # c. lids
    margins = [find_lid_margins(rig, side) for side in ("L", "R")]
    unusable = [m for m in margins if not m.usable]
    if unusable:
        rows.lids.append((case.name, engine_name, f"skipped: {unusable[0].reason}", *[""] * 7))
        return
    closed = engine.deform(closed_lids_pose(rig))
    wink = engine.deform(expression_pose(rig, "wink"))
    rest_gaps = np.concatenate([column_gaps(m, rest) for m in margins])
    gaps = [lid_gap(m, closed, tolerance=CROSSING_TOL_CM) for m in margins]
    smallest = min(g.smallest for g in gaps)
    largest = max(g.largest for g in gaps)
    crossing = [g.side for g in gaps if g.crossing]
    left = margins[0]
    rough_rest, rough_wink = lid_roughness(left, rest), lid_roughness(left, wink)
    wink_gap = lid_gap(left, wink, tolerance=CROSSING_TOL_CM)
    shown = most_eyeball_seen(rig, closed)
    rows.lids.append(
        (
            case.name,
            engine_name,
            f"{len(left.upper)} / {len(left.lower)}",
            f"{rest_gaps.min():.2f} .. {rest_gaps.max():.2f}",
            f"{smallest:+.2f} .. {largest:+.2f}",
            ", ".join(crossing) if crossing else "no",
            f"{wink_gap.smallest:+.2f} .. {wink_gap.largest:+.2f}",
            f"{100 * rough_wink:.2f} % / {100 * rough_rest:.2f} %",
            "" if shown is None else f"{shown:.2f}",
            verdicts(gap=(largest if shown is None else shown) <= GOAL_LID_GAP_CM, crossing=not crossing),
        )
    )


def column_gaps(margins: LidMargins, vertices: np.ndarray) -> np.ndarray:
    """The margin gaps (s,) of ``margins`` at ``vertices``."""
    return margin_gap(margins.project(vertices, margins.upper), margins.project(vertices, margins.lower))[1]


def tables_abc(cases: list[Case], reference: Reference) -> None:
    rows = Rows([], [], [])
    begin = time.perf_counter()
    for case in cases:
        for engine_name in ENGINES:
            measure(case, engine_name, reference, rows)
    t = time.perf_counter() - begin
    ref = reference
    titled(
        f"a. jaw_open alone at the ICT-matched chin drop (ICT's jawOpen: {ref.drop:.2f} cm on ICT, "
        f"{100 * ref.drop_rel:.1f} % of the head height elsewhere); face-edge stretch p99 and widest "
        f"single-edge opening (cm); baseline = ICT's jawOpen on the same head ('ICT': on the neutral, "
        f"p99 {ref.p99:.2f}, widest {ref.widest:.2f} cm); target p99 ≤ baseline and widest ≤ "
        f"{GOAL_WIDEST_CM} cm",
        (
            "head",
            "engine",
            "jaw_open rad",
            "chin drop / target cm",
            "p99",
            "baseline p99",
            "ratio",
            "widest cm",
            "baseline widest",
            "verdict",
        ),
        rows.jaw,
    )
    titled(
        f"b. lips: flipped lip triangles (normal turned > 90°) summed over the {len(load_library())} "
        "library expressions and the largest flipped share of the lip area in one expression (baseline: "
        "ICT's own 53 shapes on the same head), the worst face-edge "
        "stretch over the library, and upper-lip follow under jaw_open alone at the matched drop (mean "
        "upper-lip / lower-lip displacement away from the corners; in brackets the upper lip's p99 "
        "displacement); targets: no flips, follow ≤ ICT's jawOpen follow",
        (
            "head",
            "engine",
            "lip faces",
            "flips",
            "expressions with flips",
            "flipped area % (expr)",
            "ICT's own flips",
            "worst p99 (expr)",
            "worst widest cm (expr)",
            "upper-lip follow",
            "ICT jawOpen follow",
            "verdict",
        ),
        rows.lips,
    )
    titled(
        "c. lids: gap per margin column, v(upper) − v(lower) along the eye's up axis (cm, negative = "
        "crossed), both eyes; closed = both upper lids at their maximum; wink = the library's 'wink' "
        "(left eye); roughness = RMS deviation of the left upper margin from a smooth curve, % of the "
        f"lid width, in the wink / at rest; seen = the most eyeball a front view shows in a column, "
        f"closed (quality.seen_eyeball); target closed: seen (the margins' gap without eyeballs) ≤ "
        f"{GOAL_LID_GAP_CM} cm, no margin below −{CROSSING_TOL_CM} cm",
        (
            "head",
            "engine",
            "columns up/low",
            "rest gap cm",
            "closed gap min .. max",
            "crossed",
            "wink gap (L)",
            "roughness wink / rest",
            "seen closed",
            "verdict",
        ),
        rows.lids,
    )
    print(f"   tables a-c: {t:.0f} s for {len(cases)} heads × {len(ENGINES)} engines")


# --------------------------------------------------------------------------- fidelity


def fidelity(heads: Heads, case: Case, engine_name: str):
    begin = time.perf_counter()
    basis = bake(make_engine(case.rig, engine_name), samples=BAKE_SAMPLES).basis
    result = expression_fidelity(basis, heads.deltas, names=heads.names, channels=case.rig, vertices=ICT_FACE)
    return result, time.perf_counter() - begin


def tables_de(heads: Heads, quick: bool) -> None:
    runs = [(heads.ict_auto(), e) for e in ENGINES]
    runs += [(heads.ict_file(), e) for e in (ENGINES[:1] if quick else ENGINES)]
    identities = QUICK_FIDELITY_IDENTITIES if quick else FIDELITY_IDENTITIES
    identity_engines = ENGINES[:1] if quick else ENGINES
    runs += [(heads.identity(seed, sigma), e) for seed, sigma in identities for e in identity_engines]
    begin = time.perf_counter()
    results = {}
    for case, engine_name in runs:
        results[case.name, engine_name] = fidelity(heads, case, engine_name)
    t = time.perf_counter() - begin
    auto_name = heads.ict_auto().name
    rows = []
    for (name, engine_name), (result, seconds) in results.items():
        over = int(np.sum(result.residual > GOAL_FIDELITY_WORST))
        reference = results.get((auto_name, engine_name))
        if name == auto_name:
            ok = result.median <= GOAL_FIDELITY_MEDIAN and result.worst <= GOAL_FIDELITY_WORST
            base, diff = f"goal ≤ {pct(GOAL_FIDELITY_MEDIAN)}", ""
        elif name.startswith("ICT id") and reference is not None:
            points = 100 * (result.median - reference[0].median)
            ok = abs(points) <= GOAL_IDENTITY_POINTS
            base, diff = f"ICT auto {pct(reference[0].median)}", f"{points:+.1f}"
        else:
            ok, base, diff = None, "", ""
        group = "check" if any(name.startswith(f"ICT id s{seed} ") for seed in CHECK_SEEDS) else "calibration"
        rows.append(
            (
                name,
                group,
                engine_name,
                pct(result.median),
                f"{pct(result.worst)} ({result.worst_name})",
                str(over),
                base,
                diff,
                "yes" if result.success else "no (30 steps)",
                f"{seconds:.0f} s",
                "" if ok is None else verdict(ok),
            )
        )
    titled(
        f"d. expression fidelity: ICT's {len(heads.names)} shapes fitted on each baked rig over ICT's face "
        "(vertices 0..9408), residual = ‖fit − target‖ / ‖target‖ in %; targets: ICT auto median ≤ "
        f"{pct(GOAL_FIDELITY_MEDIAN)} % and every shape ≤ {pct(GOAL_FIDELITY_WORST)} %; identity heads "
        f"(automatic landmarks) within {GOAL_IDENTITY_POINTS:g} points of ICT auto's median",
        (
            "head",
            "group",
            "engine",
            "median %",
            "worst % (shape)",
            f"shapes > {pct(GOAL_FIDELITY_WORST)} %",
            "baseline",
            "Δ points",
            "solve converged",
            "bake + fit",
            "verdict",
        ),
        rows,
    )
    identity = [r.median for (n, _), (r, _) in results.items() if n.startswith("ICT id")]
    if identity:
        print(
            f"   identity heads: median of medians {pct(float(np.median(identity)))} %, range "
            f"{pct(min(identity))} .. {pct(max(identity))} % over {len(identity)} heads"
        )
    columns = [(n, e) for (n, e) in results if not n.startswith("ICT id")]
    shape_rows = []
    for k, shape in enumerate(heads.names):
        shape_rows.append((shape, *(pct(results[c][0].residual[k]) for c in columns)))
    titled(
        "e. fidelity per shape, residual %",
        ("shape", *(f"{n} {e}" for n, e in columns)),
        shape_rows,
    )
    print(f"   tables d-e: {t:.0f} s ({len(runs)} bakes and fits)")


# --------------------------------------------------------------------------- main


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="fewer heads (for CI and every change)")
    parser.add_argument(
        "--tables",
        default="abcde",
        help="which tables to print: 'abc' (jaw, lips, lids; fast) and/or 'de' (fidelity; slow); default all",
    )
    parser.add_argument(
        "--engines",
        default=",".join(ALL_ENGINES),
        help=f"comma-separated engines to measure (default: all, {','.join(ALL_ENGINES)})",
    )
    args = parser.parse_args()
    global ENGINES
    ENGINES = tuple(e for e in args.engines.split(",") if e)
    unknown = set(ENGINES) - set(ALL_ENGINES)
    if unknown:
        parser.error(f"unknown engines {sorted(unknown)}; choose from {', '.join(ALL_ENGINES)}")
    begin = time.perf_counter()
    print(
        f"load average {os.getloadavg()[0]:.2f} at start; "
        f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}"
    )
    heads = Heads()
    cases: list[Case] = []
    if heads.has_ict:
        cases += [heads.ict_file(), heads.ict_auto()]
        table_ids = QUICK_TABLE_IDENTITIES if args.quick else TABLE_IDENTITIES
        cases += [heads.identity(seed, sigma) for seed, sigma in table_ids]
    else:
        print(f"ICT-FaceKit not in the shared data ({shared_data_dir()}): ICT heads and fidelity skipped")
    mediapipe = heads.mediapipe()
    if mediapipe is not None:
        cases.append(mediapipe)
    cases += [heads.generated(seed) for seed in (QUICK_GENERATED_SEEDS if args.quick else GENERATED_SEEDS)]
    titled(
        "Heads",
        ("head", "landmarks", "vertices", "face-set faces", "head height cm", "rig time"),
        [
            (
                c.name,
                c.landmarks,
                f"{c.rig.n_vertices:,}",
                f"{len(c.faces):,}",
                f"{c.rig.scale:.2f}",
                f"{c.rig_s:.1f} s",
            )
            for c in cases
        ],
    )
    if set("abc") & set(args.tables):
        tables_abc(cases, heads.jaw_reference())
    if heads.has_ict and set("de") & set(args.tables):
        tables_de(heads, args.quick)
    print(f"\nbenchmark wall time {time.perf_counter() - begin:.0f} s")
    report.save("quality", TABLES)


if __name__ == "__main__":
    main()
