"""The rig's bones (head, jaw, eyelids, eyes) and its skin weights, placed by anatomy on a generated head.

* **Jaw.** The pivot lies in line with the lower ear (the mandible's axis). The lower teeth and
  tongue ride it fully, the upper teeth and ears stay. The skin's jaw weight is the harmonic
  interpolation between the skin that rides the mandible (the lower lip, the chin's front) and the
  skin that stays with the skull (the upper lip, the nose and everything above the nose's base,
  behind the ear or low on the neck), screened at ``HARMONIC_LENGTH_REL`` of the head height, as
  bounded harmonic weights are: it spreads wide over the cheeks and under the chin and narrows
  toward the lips, as the jaw weights measured on captured jaw openings do. At the mouth corners
  (the modiolus, all lip skin within ``CORNER_CORE``) both lips take ``CORNER_JAW`` of the jaw's
  motion and the share ramps along each lip over ``UPPER_LIP_REACH`` / ``LOWER_LIP_REACH`` of half
  the mouth width, so the opening is a lens and the corners never tear. Last, the weight of the
  chin and the cheeks is smoothed over ``JAW_SMOOTHING_REL`` of the head height, so the chin's
  border is not a crease.
* **Eyelids.** One bone per lid rotating about the eye's centre; each column of the lid is weighted
  so that ``EYELID_CLOSED_RAD`` brings its margin to the opposite lid's. The ring topology gives the
  columns and the lid's fade into the skin; the upper lid's closing weights are then made exact from
  the head's own margins, as on any rig (``mimetic.rig.anatomy.lids.closing_weights``: skinned as
  the engines skin, the eyeball sculptor included, and smoothed along the margin).
* **Eyes.** Rigid on their eye bones.

Lengths in cm are those of the reference frame (the default head, about 22 cm from crown to menton).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from mimetic.head.model import Head
from mimetic.head.shape import smoothstep
from mimetic.head.topology import build_topology
from mimetic.mesh.geometry import smooth_field
from mimetic.mesh.openings import margin_distance
from mimetic.rig.anatomy.lids import LID_CLEARANCE_REL, LID_THICKNESS_REL, closing_weights
from mimetic.rig.model import Bone

LID_RIGID_U, LID_FREE_U = 0.2, 0.45  # lid ring parameter u where a lid bone's weight starts / ends fading
CHIN_CORE_REL = 0.1
"""Skin this near the pogonion (× head height), below the lips and in front of the menton, rides the jaw."""
NECK_FREE_REL = 0.12
"""Skin this far below the menton (× head height, 2.7 cm) stays with the head: on ICT's captured
jawOpen the skin 2.4-6.4 cm below the menton follows the jaw 0.04 (0.25 gave it 0.59); fitted on
ICT's neutral, checked on its identities (benchmarks/bench_weights.py). Neck skin nearer the chin
than ``CHIN_CORE_REL`` along the skin stays free all the same: on a head whose chin hangs low over
the neck (ICT's σ 2-3 identities) the chin's weight 1 would otherwise meet the neck's 0 within an
edge or two, and a jaw drop would tear the skin under the chin there. (A ramp of
``HARMONIC_LENGTH_REL`` mends one more check head, s102 σ2, but lets ICT's neck follow the jaw
0.11 where its captured jawOpen says 0.04.)"""
HARMONIC_LENGTH_REL = 0.15
"""Diffusion length (× head height) of the jaw weight between the jaw's and the skull's skin."""
CORNER_JAW = 0.5
"""Jaw weight of the mouth corners (the modiolus: halfway between the lips)."""
CORNER_CORE = 0.1
"""Lip skin this near a mouth corner (× half the mouth width, 2.5 mm) takes exactly CORNER_JAW: the
corner's slivers, where the lips' rows converge, move as one instead of shearing flat."""
UPPER_LIP_REACH = 0.85
"""The upper lip's jaw weight falls from CORNER_JAW to 0 over this × half the mouth width (the upper
lip's middle then follows the jaw less than ICT's own jawOpen does, on ICT's identity heads too). Its
distance from a corner counts depth only in front of the corners: the lip's inner surface behind
them keeps the weight of the lip at the same place across the face (sweep lip flips 262 → 240, s117
σ 2 5 → 1, s138 σ 2 4 → 1); counted across the face alone, its front took more of the jaw (the
upper lip followed it 0.11 against ICT's 0.10) and the skin above the corners opened 0.30-0.32 cm
on ICT (0.27-0.29), though the generated heads' widest edge fell from 0.45-0.47 to 0.33-0.36 cm."""
LOWER_LIP_REACH = 1.0
"""The lower lip's rises from CORNER_JAW to 1 over this × half the mouth width: all the way to the
mouth's middle, so no edge across the lower lip opens wide near a corner. Its distance from a corner
is taken across the face (x and y), so the lip's inner surface, running back toward the corners'
depth, keeps the weight of the lip in front of it: measured in space the weight fell going back into
the mouth, and a jaw drop folded that surface over on ICT's σ 2-3 identities (the sweep's lip flips
308 → 262, s111 σ 2 8 → 1, s121 σ 3 21 → 13; ICT's jaw weights against its jawOpen's 3.81 → 3.83 %)."""
JAW_SMOOTHING_REL = 0.03
"""The jaw weight of the chin and the cheeks is smoothed over this × the head height (6 mm) last, so
the chin's border with the cheeks is not a crease."""
EYELID_CLOSED_RAD = 0.75  # upper-lid rotation that closes the eye (taller openings: lids.closing_pivot)
BONES = (
    "head",
    "jaw",
    "eyelid_upper_L",
    "eyelid_upper_R",
    "eyelid_lower_L",
    "eyelid_lower_R",
    "eye_L",
    "eye_R",
)


def bone_placement(head: Head) -> tuple[list[Bone], np.ndarray]:
    lm = head.landmark_positions
    tragion = lm(["tragion_L"])[0]
    pogonion = lm(["pogonion"])[0]
    pivot = np.array([0.0, tragion[1] - 0.8, tragion[2] + 1.0])  # in line with the lower ear
    neck_base = np.array([0.0, head.vertices[: head.n_skin, 1].min() + 2.0, tragion[2] - 1.0])
    bones = [
        Bone("head", None, neck_base, np.array([0.0, tragion[1], tragion[2] - 1.0])),
        Bone("jaw", "head", pivot, pogonion - np.array([0.0, 0.0, 1.0])),
    ]
    r = head.eye_radius
    for i, side in enumerate("LR"):
        c = head.eye_centres[i]
        bones.append(Bone(f"eyelid_upper_{side}", "head", c, c + np.array([0.0, r, 0.0])))
        bones.append(Bone(f"eyelid_lower_{side}", "head", c, c + np.array([0.0, -r, 0.0])))
    for i, side in enumerate("LR"):
        c = head.eye_centres[i]
        bones.append(Bone(f"eye_{side}", "head", c, c + np.array([0.0, 0.0, r])))
    order = {b.name: b for b in bones}
    return [order[n] for n in BONES], pivot


def skin_weights(head: Head, jaw_pivot: np.ndarray) -> sp.csr_matrix:
    """Smooth weights (n, bones) from regions and anatomy: head, jaw taper, lids, eyeballs."""
    n = head.mesh.n_vertices
    v = head.mesh.vertices
    topo = build_topology(head.resolution)
    W = np.zeros((n, len(BONES)))
    stomion = head.landmark_positions(["upper_lip_inner"])[0]
    # the mouth cavity: below the plane through the lip contact line and the jaw pivot, tapered
    a = np.array([0.0, stomion[1] - jaw_pivot[1], stomion[2] - jaw_pivot[2]])
    normal = np.array([0.0, a[2], -a[1]]) / np.linalg.norm(a)  # points up-forward
    if normal[1] < 0:
        normal = -normal
    jaw = smoothstep(0.3, -1.3, (v - stomion) @ normal)
    # the skin: the lower lip and the chin ride the mandible, the upper lip, the nose and everything
    # above the nose's base or behind the ear stay with the skull, and the cheeks and the skin under
    # the jaw in between stretch: their weight is the harmonic interpolation of those two (bounded
    # harmonic weights), which spreads wide over the cheeks and narrows toward the lips, as the jaw
    # weights measured on captured jaw openings do. At the mouth corners (the modiolus) both lips
    # take half the jaw's motion, and the share ramps along each lip over most of the half mouth
    # width, so the opening is a lens and the corners never tear.
    corners = head.landmark_positions(["mouth_corner_L", "mouth_corner_R"])
    half_width = 0.5 * float(np.linalg.norm(corners[0] - corners[1]))
    offsets = v[:, None] - corners[None]  # (n, 2, 3) from each mouth corner
    across = np.linalg.norm(offsets[..., :2], axis=2).min(axis=1) / half_width  # (n,) half widths
    offsets[..., 2] = np.maximum(offsets[..., 2], 0.0)
    ahead = np.linalg.norm(offsets, axis=2).min(axis=1) / half_width  # depth counted in front only
    alar, pogonion, menton, tragion = head.landmark_positions(
        ["alar_base_L", "pogonion", "menton", "tragion_L"]
    )
    scale = float(v[: head.n_skin, 1].max() - menton[1])  # the head height, crown to menton
    regions = head.regions
    lower, upper = regions["lower_lip"], regions["upper_lip"]
    fixed = np.zeros(n, dtype=bool)
    value = np.zeros(n)
    still = [regions[r] for r in ("nose", "forehead", "scalp") if r in regions]
    still += [regions[f"{r}_{s}"] for r in ("eyelid_upper", "eyelid_lower", "brow") for s in "LR"]
    skin = head.mesh.part_vertices("skin")
    core = skin[
        (np.linalg.norm(v[skin] - pogonion, axis=1) < CHIN_CORE_REL * scale)
        & (v[skin, 1] < stomion[1])
        & (v[skin, 2] > menton[2])  # the chin's front, not the skin under it
    ]
    skin_faces = head.mesh.faces[head.mesh.parts["skin"]]
    ramp = CHIN_CORE_REL * scale
    near_chin = margin_distance(v, skin_faces, np.union1d(regions["chin"], core), ramp)[skin] < ramp
    neck = (v[skin, 1] < menton[1] - NECK_FREE_REL * scale) & ~near_chin
    above = skin[(v[skin, 1] > alar[1]) | (v[skin, 2] < tragion[2]) | neck]
    for ids in (*still, above, upper):
        fixed[ids] = True
    for ids in (regions["chin"], core, lower):
        fixed[ids], value[ids] = True, 1.0
    value[lower] = 1.0 - (1.0 - CORNER_JAW) * (1.0 - smoothstep(CORNER_CORE, LOWER_LIP_REACH, across[lower]))
    value[upper] = CORNER_JAW * (1.0 - smoothstep(CORNER_CORE, UPPER_LIP_REACH, ahead[upper]))
    free = np.zeros(n, dtype=bool)
    free[skin] = ~fixed[skin]
    harmonic = smooth_field(value, v, skin_faces, HARMONIC_LENGTH_REL * scale, free=free)
    unfixed = free.copy()  # and the chin, whose border with the cheeks would crease
    unfixed[regions["chin"]] = unfixed[core] = True
    unfixed[lower] = False
    harmonic = smooth_field(harmonic, v, skin_faces, JAW_SMOOTHING_REL * scale, free=unfixed)
    jaw[skin] = harmonic[skin]
    jaw[lower], jaw[upper] = value[lower], value[upper]  # the lips' loops inside the mouth too
    parts = head.mesh.parts
    for part, share in (
        ("teeth_lower", 1.0),
        ("tongue", 1.0),
        ("teeth_upper", 0.0),
        ("ear_L", 0.0),
        ("ear_R", 0.0),
    ):
        jaw[np.unique(head.mesh.faces[parts[part]])] = share
    W[:, BONES.index("jaw")] = jaw
    # eyelids: each column of the lid has the weight that makes a rotation of EYELID_CLOSED_RAD bring
    # its margin to the opposite lid's (so a blink closes the whole fissure, the canthi stay put and
    # the same channel value closes every head); the lid moves rigidly up to u = LID_RIGID_U (the
    # tarsal plate) and blends into the skin by u = LID_FREE_U, short of the brow, so the orbital skin
    # above the crease stays when the lid closes and its triangles never cut through the cornea
    for side in "LR":
        rings = topo.eye_L if side == "L" else topo.eye_R
        centre = head.eye_centres[0 if side == "L" else 1]
        margin = v[rings.index[1]] - centre  # (per_ring, 3)
        elevation = np.arctan2(margin[:, 1], margin[:, 2])  # about the x-axis
        per_ring = len(elevation)
        opposite = elevation[(per_ring - np.arange(per_ring)) % per_ring]  # the same column, other lid
        t = topo.ring_uv[rings.index[1], 1]
        share = np.clip(np.abs(elevation - opposite) / EYELID_CLOSED_RAD, 0.0, 1.0)
        up, down = np.sin(t) > 1e-9, np.sin(t) < -1e-9
        for k, u in enumerate(rings.u):
            ids = rings.index[k]
            w = (1.0 - smoothstep(LID_RIGID_U, LID_FREE_U, np.array(max(u, 0.0)))) * share
            W[ids[up], BONES.index(f"eyelid_upper_{side}")] = w[up]
            W[ids[down], BONES.index(f"eyelid_lower_{side}")] = w[down]
        eye = np.unique(head.mesh.faces[parts[f"eye_{side}"]])
        W[eye] = 0.0
        W[eye, BONES.index(f"eye_{side}")] = 1.0
    W[:, 0] = np.clip(1.0 - W[:, 1:].sum(axis=1), 0.0, None)
    # the mouth cavity's rim coincides with the inner lip: give it the same weights, or it tears
    rim = head.mesh.part_vertices("mouth")[: topo.mouth.index.shape[1]]
    W[rim] = W[topo.mouth.index[0]]
    W /= W.sum(axis=1, keepdims=True)
    # the upper lids close exactly onto the lower ones at EYELID_CLOSED_RAD, from the head's margins
    for i, side in enumerate("LR"):
        centre = head.eye_centres[i]
        W = closing_weights(
            v,
            head.mesh.faces,
            W,
            regions,
            side,
            lid=BONES.index(f"eyelid_upper_{side}"),
            head=BONES.index("head"),
            pivot=centre,
            corners=head.landmark_positions([f"eye_inner_corner_{side}", f"eye_outer_corner_{side}"]),
            centre=centre,
            radius=head.eye_radius,
            gaze=np.array([0.0, 0.0, 1.0]),
            closed_rad=EYELID_CLOSED_RAD,
            clearance=LID_CLEARANCE_REL * scale,
            thickness=LID_THICKNESS_REL * scale,
        )
    W[W < 1e-6] = 0.0
    W /= W.sum(axis=1, keepdims=True)
    return sp.csr_matrix(W)
