"""Skin weights against the weights ICT-FaceKit's captured shapes imply (issue 28, "weights from
anatomy").

    python benchmarks/bench_weights.py [--quick]

ICT's ``jawOpen`` and ``eyeBlink_L/R`` shapes are captured, not rigged, but each is close to one
bone's rotation: how far a vertex follows that rotation is the weight an artist would paint there.

* **jaw**: the lower teeth move rigidly in ``jawOpen`` (the teeth vertices that move more than half
  the most); their rotation and translation (Kabsch) give each vertex's jaw motion r_i, and the
  implied weight is the share of it the captured delta d_i takes, ``clip(d_i · r_i / |r_i|², 0, 1)``.
* **upper lids**: ``eyeBlink_<side>`` turns the upper lid about the eyeball's centre (the rig's
  ``eye_<side>`` bone) by the median angle of the lid margin's vertices about the left-right axis
  (``mimetic.mesh.openings``'s margins); the implied weight likewise. The rig's lid weights are
  scaled by its closed lid's angle over that one, so both say how far a vertex turns with the lid
  as the eye closes.

Compared over ICT's face (vertices 0..9408; a lid's within ``EYE_REACH`` eye widths of the eye's
centre): mean |rig − implied| in percent (the Maskle paper's metric, 2.63 % mean on its rigs), with
two baselines measured the same way: no weight at all (every vertex on the head bone) and weight 1
everywhere. Also the
jaw's mean excess over the implied weight, in points, on three places an anatomical jaw weight has
none: the face above the upper lip's line (iBUG 51) in front of the jaw joint, behind the joint, and
the mouth cavity (ICT's mouth socket) above halfway from the upper lip to the nose tip.

Heads: ICT's neutral with automatic landmarks and with its file's (the *calibration* heads of the
lid band ``LID_BAND_REL`` and the jaw constants), and identity heads (*check*: never used to choose
a constant; ICT's shapes applied to them as deltas, which keeps the implied weights meaningful
since the identities share the topology). ``--quick``: two identities.
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import report
from bench_quality import Case, Heads
from bench_rig import print_table
from mimetic.engines.skinning import bone_transforms
from mimetic.mesh.openings import eye_opening, eyeball, margin_seeds, skin_faces
from mimetic.quality import closed_lids_pose, implied_weights, rigid_motion
from mimetic.testing import shared_data_dir

FACE = slice(0, 9409)
TEETH = (17039, 21451)
IBUG = {"upper_lip_top": 51, "nose_tip": 30, "eye_L": (42, 45), "eye_R": (39, 36)}
EYE_REACH = 1.0
"""A lid's weights are compared within this × the eye's width (corner to corner) of the eye's centre."""
IDENTITIES = ((101, 1.0), (102, 2.0), (103, 3.0), (104, 1.0), (105, 2.0))
QUICK_IDENTITIES = ((101, 1.0), (102, 2.0))


def jaw_motion(vertices: np.ndarray, delta: np.ndarray) -> np.ndarray:
    teeth = np.arange(*TEETH)
    lower = teeth[np.linalg.norm(delta[teeth], axis=1) > 0.5 * np.linalg.norm(delta[teeth], axis=1).max()]
    rotation, shift = rigid_motion(vertices[lower], vertices[lower] + delta[lower])
    return vertices @ rotation.T + shift - vertices


def lid_motion(
    vertices: np.ndarray, faces: np.ndarray, delta: np.ndarray, corners, centre
) -> tuple[np.ndarray, float] | None:
    """The upper lid's rotation motion (n, 3) in a captured blink ``delta`` and its angle (rad), or
    None when the eye's opening is not found on the head."""
    skin = skin_faces(vertices, faces)
    opening = eye_opening(vertices, skin, corners, eyeball(vertices, faces, corners))
    if opening is None:
        return None
    upper, _ = margin_seeds(vertices, skin, opening, 0.03 * opening.width)
    p, q = vertices[upper] - centre, vertices[upper] + delta[upper] - centre
    theta = float(np.median(np.arctan2(q[:, 1], q[:, 2]) - np.arctan2(p[:, 1], p[:, 2])))
    c, s = np.cos(theta), np.sin(theta)
    rotation = np.array([[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]])  # turns atan2(y, z) by theta
    return (vertices - centre) @ rotation.T + centre - vertices, abs(theta)


def closed_angle(rig, bone: str) -> float:
    """The rotation (rad) of ``bone`` with the upper lids at their channel maximum."""
    turn = bone_transforms(rig, closed_lids_pose(rig))[rig.bone_index(bone), :3, :3]
    return float(np.arccos(np.clip((np.trace(turn) - 1) / 2, -1.0, 1.0)))


def measure(case: Case, heads: Heads, cavity_ids: np.ndarray) -> list[tuple[str, ...]]:
    rig = case.rig
    V, F = rig.mesh.vertices, heads.neutral.faces
    names, deltas = heads.names, heads.deltas
    landmarks = np.asarray(heads.meta["landmarks_68"]["vertex_indices"])
    rows = []
    face = np.zeros(len(V), dtype=bool)
    face[FACE] = True
    bones = [("jaw", "jawOpen", jaw_motion(V, deltas[names.index("jawOpen")]), face, 1.0)]
    for side in ("L", "R"):
        corners = V[landmarks[list(IBUG[f"eye_{side}"])]]
        delta = deltas[names.index(f"eyeBlink_{side}")]
        centre = np.asarray(rig.bone(f"eye_{side}").head, dtype=np.float64)
        near = face & (np.linalg.norm(V - centre, axis=1) < EYE_REACH * np.linalg.norm(np.subtract(*corners)))
        found = lid_motion(V, F, delta, corners, centre)
        bone = f"eyelid_upper_{side}"
        if found is None:
            rows.append((case.name, bone, "eye opening not found", *[""] * 5))
            continue
        motion, theta = found
        bones.append((bone, f"eyeBlink_{side}", motion, near, closed_angle(rig, bone) / theta))
    for bone, shape, motion, counts, scale in bones:
        truth = implied_weights(deltas[names.index(shape)], motion)
        got = scale * rig.skin_weights[:, rig.bone_index(bone)].toarray().ravel()
        err = 100 * np.abs(got - truth)[counts].mean()
        zero = 100 * truth[counts].mean()
        one = 100 * (1 - truth[counts]).mean()
        extra = ""
        if bone == "jaw":
            lip_y = V[landmarks[IBUG["upper_lip_top"]], 1]
            nose = V[landmarks[IBUG["nose_tip"]]]
            joint = np.asarray(rig.bone("jaw").head, dtype=np.float64)
            above = face & (V[:, 1] > lip_y) & (V[:, 2] > joint[2])
            behind = face & (V[:, 2] < joint[2]) & (V[:, 1] > joint[1] - 0.5 * (joint[1] - lip_y))
            cavity = np.zeros(len(V), dtype=bool)
            cavity[cavity_ids] = True
            cavity &= V[:, 1] > nose[1] - 0.5 * (nose[1] - lip_y)
            extra = " / ".join(
                f"{100 * np.clip(got - truth, 0, None)[m].mean():.1f}" if m.any() else "-"
                for m in (above, behind, cavity)
            )
        rows.append(
            (
                case.name,
                bone,
                str(int(counts.sum())),
                f"{err:.2f}",
                f"{zero:.2f}",
                f"{one:.2f}",
                f"{err / zero:.2f}",
                extra,
            )
        )
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="two identities")
    args = parser.parse_args()
    warnings.simplefilter("ignore")
    begin = time.perf_counter()
    heads = Heads()
    if not heads.has_ict:
        print(f"ICT-FaceKit not in the shared data ({shared_data_dir()}): nothing to compare with")
        return
    mouth = next(p["vertex_range"] for p in heads.meta["parts"] if p["name"] == "Mouth socket")
    cavity = np.arange(mouth[0], mouth[1] + 1)
    groups = [("calibration", heads.ict_auto()), ("calibration", heads.ict_file())]
    ids = QUICK_IDENTITIES if args.quick else IDENTITIES
    groups += [("check", heads.identity(seed, sigma)) for seed, sigma in ids]
    rows = [(group, *row) for group, case in groups for row in measure(case, heads, cavity)]
    weights = print_table(
        "skin weights vs the weights ICT's captured jawOpen / eyeBlink imply "
        "(mean |difference| %, where the bone moves; the Maskle paper: 2.63 % mean)",
        (
            "group",
            "head",
            "bone",
            "vertices",
            "rig",
            "no weight",
            "weight 1",
            "rig / no weight",
            "jaw excess: above lip / behind joint / cavity",
        ),
        rows,
    )
    means = []
    for group in ("calibration", "check"):
        sel = [float(r[4]) for r in rows if r[0] == group and r[4]]
        base = [float(r[5]) for r in rows if r[0] == group and r[5]]
        means.append(
            f"{group}: rig {np.mean(sel):.2f} % mean over bones and heads (no weight {np.mean(base):.2f} %)"
        )
        print(means[-1])
    report.save("weights", [weights, "; ".join(means) + "."])
    print(f"\nbenchmark wall time {time.perf_counter() - begin:.0f} s")


if __name__ == "__main__":
    main()
