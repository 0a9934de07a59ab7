"""Stress the tissue engine's dynamics (issue 12, item 7): long clips of random extreme activations.

    python benchmarks/stress_physics.py [--quick] [--steps N] [--budget S] [--resolution R] [--heads H,...]

For each head (the default head, a random head, a fitted ICT head when the shared data is there, and
the default head in millimetres) the tissue engine takes ``--steps`` BDF2 steps (default 10,000;
``--quick`` 500) of a clip at 30 fps whose muscle channels jump between 0 and 1 in random subsets
every few frames (now and then all of them at once) while ``jaw_open`` jumps between its minimum and
maximum. The kernel's ``step`` is driven directly with the engine's calibrated ``forces``, as
``TissueEngine.simulate`` does inside (simulate always starts at rest, so a long clip in chunks would
restart), ramping each frame's activations as simulate does; the shared chain (jaw, lids) runs on the
last frame of every chunk. After the clip all activations are released for one second.

One table: steps done (of those asked; ``--budget`` seconds of stepping per head stop a head early,
0 for no limit), nodes, seconds, steps/s, NaN, the largest skin displacement over the head height
(blow-up: must stay under ``BLOW_UP``), the largest kinetic energy, inverted elements (negative
signed volume at the simulated nodes: the volume's tetrahedra, all positive at rest, and the model's
prisms, not needles, whose signed volume changed sign from rest) as the most
in one step and the number of steps with any, the displacement left one second after the release
(over the head height), and a verdict.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import time
import warnings

import numpy as np

from mimetic.engines.tissue import HEAD_HEIGHT_M, TissueEngine, TissueState, prism_volumes, step
from mimetic.engines.volume import tet_volumes
from mimetic.head.model import DEFAULT_RESOLUTION, make_head
from mimetic.head.params import HeadParams
from mimetic.mesh.model import Mesh
from mimetic.rig.recipe import build_rig
from mimetic.testing import ict_folder, ict_landmarks, load_ict

FPS = 30.0
CHUNK = 100
"""Frames generated and stepped at a time (memory stays bounded whatever ``--steps``)."""
BLOW_UP = 0.5
"""Largest skin displacement allowed, as a fraction of the head height."""
NEEDLE = 1e-3
"""Prisms whose rest volume is under this fraction of the median are needles (the mouth's corners):
their sign flips with any motion, so they are not counted as inverted."""
RELEASE_S = 1.0
"""Seconds of all-zero activations after the clip."""
PROGRESS = 1000
"""Steps between progress lines (a 10,000-step run takes the better part of an hour per head)."""


def millimetre_head(head):
    """``head`` ×10 in millimetres (a generated head is in centimetres)."""
    m = head.mesh
    return dataclasses.replace(
        head,
        mesh=Mesh(m.vertices * 10.0, m.faces, m.parts, m.colors, "cm"),  # build_rig labels its rig cm
        eye_centres=head.eye_centres * 10.0,
        eye_radius=head.eye_radius * 10.0,
    )


def millimetre_rig(head):
    """The rig of ``head`` built ×10 and labelled millimetres (its ``scale`` is then about 220)."""
    rig = build_rig(millimetre_head(head))
    m = rig.mesh
    return dataclasses.replace(rig, mesh=Mesh(m.vertices, m.faces, m.parts, m.colors, "mm"), units="mm")


HEADS = ("default", "random", "ict", "mm")
"""The heads ``--heads`` chooses from: the default head, a random head, a fitted ICT head, the default
head in millimetres."""


def heads(resolution: int, chosen: tuple[str, ...] = HEADS):
    """(label, rig or None, note) for each head ``chosen``; None when it cannot be built here."""
    if "default" in chosen:
        yield "default head", build_rig(make_head(resolution=resolution)), ""
    if "random" in chosen:
        yield "random head (seed 7)", build_rig(make_head(HeadParams.random(7), resolution=resolution)), ""
    folder = ict_folder()
    if "ict" not in chosen:
        pass
    elif folder is None:
        yield "ICT-FaceKit (fitted)", None, "skipped: ICT-FaceKit not in the shared data"
    else:
        from mimetic.fit.pipeline import rig_head

        neutral, meta = load_ict(folder)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield "ICT-FaceKit (fitted)", rig_head(neutral, ict_landmarks(neutral, meta)).rig, ""
    if "mm" in chosen:
        yield "default head, mm", millimetre_rig(make_head(resolution=resolution)), ""


class ExtremeClip:
    """Random extreme activations (frames, c), a chunk at a time: every 1-6 frames a random subset of
    the muscle channels (each with probability 0.3) jumps to 0 or 1; one change in 20 sets all of them
    to 1, one in 20 all to 0; ``jaw_open`` jumps between its minimum and maximum."""

    def __init__(self, rig, seed: int) -> None:
        self.rng = np.random.default_rng(seed)
        self.muscles = np.array([i for i, c in enumerate(rig.channels) if c.unit == "activation"])
        self.jaw = rig.channel_index("jaw_open") if "jaw_open" in rig.channel_names else None
        self.jaw_range = (
            (rig.channels[self.jaw].minimum, rig.channels[self.jaw].maximum) if self.jaw is not None else None
        )
        self.now = np.array([c.default for c in rig.channels], dtype=np.float64)
        self.hold = 0

    def chunk(self, frames: int) -> np.ndarray:
        out = np.empty((frames, len(self.now)))
        rng = self.rng
        for f in range(frames):
            if self.hold == 0:
                draw = rng.random()
                if draw < 0.05:
                    self.now[self.muscles] = 1.0
                elif draw < 0.10:
                    self.now[self.muscles] = 0.0
                else:
                    subset = self.muscles[rng.random(len(self.muscles)) < 0.3]
                    self.now[subset] = rng.integers(0, 2, len(subset))
                if self.jaw is not None and rng.random() < 0.5:
                    self.now[self.jaw] = self.jaw_range[rng.integers(0, 2)]
                self.hold = int(rng.integers(1, 7))
            self.hold -= 1
            out[f] = self.now
        return out


@dataclasses.dataclass
class Stress:
    steps: int = 0
    seconds: float = 0.0
    nan: bool = False
    displacement: float = 0.0  # largest skin displacement / head height
    kinetic: float = 0.0  # J
    inverted_tets: int = 0  # most in one step
    inverted_prisms: int = 0
    steps_inverted: int = 0  # steps with any inverted tet or prism
    settled: float = float("nan")  # skin displacement / head height after the release
    settled_kinetic: float = float("nan")


def run(engine: TissueEngine, steps: int, budget: float, seed: int = 0) -> Stress:
    model, volume = engine.model, engine.volume
    k = volume.n_skin
    out = Stress()
    mass = model.mass[:, None]
    n_sub = engine.steps_per_frame(FPS)
    h = 1.0 / (FPS * n_sub)
    clip = ExtremeClip(engine.rig, seed)
    state = TissueState.at_rest(model)
    previous = np.zeros(len(engine.muscles))
    last_values = clip.now.copy()
    rest_volumes = prism_volumes(model.rest, model.prisms)
    rest_sign = np.sign(rest_volumes)  # a few needle prisms start negative
    solid = np.abs(rest_volumes) >= NEEDLE * np.median(np.abs(rest_volumes))

    def advance(target: np.ndarray) -> bool:
        nonlocal state, previous
        for i in range(1, n_sub + 1):
            now = previous + (target - previous) * (i / n_sub)
            state = step(model, state, (engine.forces @ now).reshape(-1, 3), h)
            x = state.x
            if not np.isfinite(x).all() or not np.isfinite(state.v).all():
                out.nan = True
                return False
            d = x[:k] - model.rest[:k]
            out.displacement = max(
                out.displacement, float(np.sqrt(np.einsum("ni,ni->n", d, d).max())) / HEAD_HEIGHT_M
            )
            out.kinetic = max(out.kinetic, float(0.5 * np.sum(mass * state.v**2)))
            tets = int(np.count_nonzero(tet_volumes(x, volume.tets) < 0))
            prisms = int(np.count_nonzero((np.sign(prism_volumes(x, model.prisms)) != rest_sign) & solid))
            out.inverted_tets = max(out.inverted_tets, tets)
            out.inverted_prisms = max(out.inverted_prisms, prisms)
            out.steps_inverted += bool(tets or prisms)
            out.steps += 1
            if out.steps % PROGRESS == 0:
                print(f"    {out.steps} steps, {time.perf_counter() - start:.0f} s", flush=True)
        previous = target
        return True

    start = time.perf_counter()
    alive = True
    while alive and out.steps < steps and not (budget and time.perf_counter() - start > budget):
        values = clip.chunk(min(CHUNK, -(-(steps - out.steps) // n_sub)))
        for frame in values:
            alive = advance(frame[engine.muscles])
            if not alive or out.steps >= steps or (budget and time.perf_counter() - start > budget):
                break
            last_values = frame
        if alive:  # the chain (jaw, lids) on the chunk's last frame
            skin = engine.chain.apply(engine._skin(state.x), last_values)
            alive = bool(np.isfinite(skin).all())
            out.nan |= not alive
    out.seconds = time.perf_counter() - start
    if alive:  # release: all activations off for RELEASE_S
        zero = np.zeros(len(engine.muscles))
        for _ in range(round(RELEASE_S * FPS)):
            for i in range(1, n_sub + 1):
                now = previous * (1.0 - i / n_sub)
                state = step(model, state, (engine.forces @ now).reshape(-1, 3), h)
            previous = zero
        d = state.x[:k] - model.rest[:k]
        out.settled = float(np.sqrt(np.einsum("ni,ni->n", d, d).max())) / HEAD_HEIGHT_M
        out.settled_kinetic = float(0.5 * np.sum(mass * state.v**2))
        out.nan |= not np.isfinite(state.x).all()
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="500 steps, 60 s per head, small heads")
    parser.add_argument("--steps", type=int, default=None, help="steps per head (default 10,000)")
    parser.add_argument(
        "--budget", type=float, default=None, help="seconds of stepping per head (0: no limit)"
    )
    parser.add_argument("--resolution", type=int, default=None, help="skin vertices of the generated heads")
    parser.add_argument(
        "--heads", default=",".join(HEADS), help=f"comma-separated, of {', '.join(HEADS)} (default: all)"
    )
    args = parser.parse_args()
    chosen = tuple(h.strip() for h in args.heads.split(",") if h.strip())
    unknown = sorted(set(chosen) - set(HEADS))
    if unknown:
        parser.error(f"unknown head(s) {', '.join(unknown)}; choose from {', '.join(HEADS)}")
    steps = args.steps or (500 if args.quick else 10_000)
    budget = args.budget if args.budget is not None else (60.0 if args.quick else 150.0)
    resolution = args.resolution or (2_500 if args.quick else DEFAULT_RESOLUTION)
    print(
        f"tissue stress: {steps} steps at {FPS:g} fps per head, budget {budget:g} s per head, "
        f"generated heads at resolution {resolution}; load average {os.getloadavg()[0]:.2f}"
    )
    header = (
        "head",
        "steps",
        "nodes",
        "setup s",
        "s",
        "steps/s",
        "NaN",
        "max disp/H",
        "max KE J",
        "inv tets",
        "inv prisms",
        "steps inv",
        "rest err/H",
        "KE 1s after",
        "verdict",
    )
    rows = []
    total = time.perf_counter()
    for label, rig, note in heads(resolution, chosen):
        if rig is None:
            print(note)
            rows.append((label, "-", *["-"] * 12, note))
            continue
        setup = time.perf_counter()
        engine = TissueEngine(rig)
        setup = time.perf_counter() - setup
        s = run(engine, steps, budget)
        ok = not s.nan and s.displacement < BLOW_UP
        verdict = "ok" if ok else ("NaN" if s.nan else "BLOW-UP")
        if s.steps < steps and ok:
            verdict += f" (budget: {s.steps} of {steps})"
        rows.append(
            (
                label,
                f"{s.steps}/{steps}",
                f"{engine.model.n_nodes:,}",
                f"{setup:.1f}",
                f"{s.seconds:.0f}",
                f"{s.steps / max(s.seconds, 1e-9):.2f}",
                "yes" if s.nan else "none",
                f"{s.displacement:.3f}",
                f"{s.kinetic:.2e}",
                str(s.inverted_tets),
                str(s.inverted_prisms),
                str(s.steps_inverted),
                f"{s.settled:.4f}",
                f"{s.settled_kinetic:.1e}",
                verdict,
            )
        )
        print(f"  {label}: done in {time.perf_counter() - total:.0f} s so far: {rows[-1]}", flush=True)
    widths = [max(len(str(r[i])) for r in (header, *rows)) for i in range(len(header))]
    for r in (header, tuple("-" * w for w in widths), *rows):
        print(" | ".join(str(c).ljust(w) for c, w in zip(r, widths, strict=True)))
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    cores = len(os.sched_getaffinity(0))
    print(f"total {time.perf_counter() - total:.0f} s; load average {load}; {cores} cores")


if __name__ == "__main__":
    main()
