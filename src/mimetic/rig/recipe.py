"""The rig recipe: ``build_rig(head)`` places the anatomy on a generated head.

Every element is defined by surface locations of the reference topology (landmark names,
region names and skin vertices nearest to canonical chart points, which are the same vertex
indices for every parameter set of a resolution), so the recipe rebuilds on any generated
or fitted copy of the reference. Widths and dropoffs are fractions of the head height
(``Rig.scale``). The muscle set follows the automated rigging thesis (26 controls, Table 4.1)
plus zygomatic minor, buccinator, levator palpebrae, platysma and the orbicularis oris and
oculi as sphincters.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from mimetic.head.model import Head, make_head
from mimetic.head.params import HeadParams
from mimetic.head.shape import skin_geometry, smoothstep
from mimetic.head.topology import build_topology
from mimetic.mesh.geometry import closest_on_polyline, smooth_field
from mimetic.mesh.model import SurfacePoint
from mimetic.rig.model import Bone, Channel, Muscle, Rig, Wire

# lengths in cm are those of the reference frame (the default head, 23 cm from crown to menton)
LID_RIGID_U, LID_FREE_U = 0.2, 0.45  # lid ring parameter u where a lid bone's weight starts / ends fading
CHIN_CORE_REL = 0.1
"""Skin this near the pogonion (× head height), below the lips and in front of the menton, rides the jaw."""
NECK_FREE_REL = 0.25
"""Skin this far below the menton (× head height) stays with the head."""
HARMONIC_LENGTH_REL = 0.15
"""Diffusion length (× head height) of the jaw weight between the jaw's and the skull's skin."""
CORNER_JAW = 0.5
"""Jaw weight of the mouth corners (the modiolus: halfway between the lips)."""
UPPER_LIP_REACH = 0.9
"""The upper lip's jaw weight falls from CORNER_JAW to 0 over this × half the mouth width."""
LOWER_LIP_REACH = 0.75
"""The lower lip's rises from CORNER_JAW to 1 over this × half the mouth width."""
EYELID_CLOSED_RAD = 0.75  # upper-lid rotation that closes the eye (larger than any head's lid opening)
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

# (name, kind, origin, insertion, width_rel, falloff_start_rel, falloff_end_rel, angle_deg, region)
# origin / insertion: a landmark name or a canonical chart point (X, Y) on the left side;
# right-side muscles mirror the left. "C" muscles sit on the midline.
_MUSCLES_L = [
    ("frontalis_inner", "linear", (1.3, 7.6), "brow_inner_mid", 0.07, 0.8, 1.35, 40, "forehead"),
    ("frontalis_outer", "linear", (4.2, 7.3), "brow_outer_mid", 0.07, 0.8, 1.35, 40, "forehead"),
    ("corrugator", "linear", (0.7, 1.0), "brow_mid", 0.05, 0.85, 1.4, 35, "brow"),
    ("orbicularis_oculi_inner", "linear", (1.3, 0.3), (2.4, -2.3), 0.05, 0.85, 1.4, 40, "cheek"),
    ("orbicularis_oculi_outer", "linear", (5.6, 0.4), (4.2, -2.1), 0.06, 0.85, 1.4, 40, "cheek"),
    ("levator_labii_nasal", "linear", (1.0, -0.3), "alar_base", 0.045, 0.85, 1.4, 30, "nasolabial"),
    ("levator_labii_mid", "linear", (2.6, -1.6), "upper_lip_outer", 0.05, 0.85, 1.4, 30, "upper_lip"),
    ("zygomatic_minor", "linear", (4.0, -2.1), "upper_lip_outer", 0.045, 0.85, 1.4, 30, "upper_lip"),
    ("zygomatic_major", "linear", (6.0, -2.4), "mouth_corner", 0.06, 0.85, 1.4, 35, "cheek"),
    ("risorius", "linear", (6.4, -7.6), "mouth_corner", 0.05, 0.85, 1.4, 30, "cheek"),
    ("buccinator", "linear", (4.6, -7.3), "mouth_corner", 0.05, 0.85, 1.4, 30, "cheek"),
    ("triangularis", "linear", (3.7, -11.2), "mouth_corner", 0.05, 0.85, 1.4, 30, "jaw"),
    ("orbicularis_oris_incisivis", "linear", (0.8, -6.7), "mouth_corner", 0.04, 0.85, 1.4, 30, "upper_lip"),
    ("depressor_labii", "linear", (1.6, -10.8), "lower_lip_mid", 0.045, 0.85, 1.4, 30, "lower_lip"),
    ("levator_palpebrae", "linear", "brow_mid", "eye_upper_lid", 0.04, 0.85, 1.4, 45, "eyelid_upper"),
    ("platysma", "sheet", (5.0, -17.0), "lower_lip_outer", 0.1, 0.85, 1.4, 30, "jaw"),
]
_MUSCLES_C = [
    ("procerus", "linear", "nose_bridge_upper", "glabella", 0.04, 0.85, 1.4, 35, "forehead", False),
    ("mentalis", "linear", "pogonion", (0.0, -9.0), 0.05, 0.8, 1.3, 40, "chin", True),
]
# sphincters: (name, side, centre, semi-major end (left-side chart point, mirrored for R), semi-minor);
# a sphincter acts on everything inside its ellipse (both lips, both lids), so it has no region
_SPHINCTERS = [
    ("orbicularis_oris", "C", "upper_lip_inner", "mouth_corner_L", 0.05),
    ("orbicularis_oculi_L", "L", "pupil_L", (5.9, 0.2), 0.085),
    ("orbicularis_oculi_R", "R", "pupil_R", (5.9, 0.2), 0.085),
]
# wires of the thesis (Table 4.1): name -> (points, driving muscles (same side), dropoff_rel, regions the
# wire must not move: its deformation set is the skin within the dropoff, minus these)
_WIRES_L = {
    "forehead": (
        [(0.6, 4.8), (2.2, 5.0), (3.8, 4.7), (5.2, 4.0)],
        ["frontalis_inner", "frontalis_outer", "corrugator", "procerus"],
        0.12,
        [],
    ),
    "eyebrow": (
        ["brow_inner", "brow_inner_mid", "brow_mid", "brow_outer_mid", "brow_outer"],
        ["frontalis_inner", "frontalis_outer", "corrugator", "procerus", "orbicularis_oculi"],
        0.09,
        [],
    ),
    "nose": (
        [(0.9, -0.2), (1.3, -2.0), "alare"],
        ["orbicularis_oculi_inner", "levator_labii_nasal"],
        0.07,
        ["upper_lip", "lower_lip"],
    ),
    "cheek": (
        [(1.9, -1.6), (3.2, -2.2), (4.6, -2.0), (5.6, -1.0)],
        ["orbicularis_oculi_outer", "orbicularis_oculi"],
        0.09,
        ["upper_lip", "lower_lip"],
    ),
    "nasolabial": (
        ["alar_base", (2.5, -5.6), (3.3, -7.4)],
        ["levator_labii_nasal", "levator_labii_mid", "zygomatic_minor"],
        0.08,
        ["lower_lip"],
    ),
    "mouth_upper_corner": (
        ["upper_lip_peak", "upper_lip_outer", "mouth_corner"],
        [
            "levator_labii_nasal",
            "levator_labii_mid",
            "zygomatic_minor",
            "zygomatic_major",
            "risorius",
            "buccinator",
            "triangularis",
            "orbicularis_oris_incisivis",
            "orbicularis_oris",
        ],
        0.11,
        ["lower_lip"],
    ),
    "mouth_lower_corner": (
        ["lower_lip_mid", "lower_lip_outer", "mouth_corner"],
        [
            "zygomatic_major",
            "risorius",
            "buccinator",
            "triangularis",
            "orbicularis_oris_incisivis",
            "depressor_labii",
            "platysma",
            "orbicularis_oris",
            "mentalis",
        ],
        0.11,
        ["upper_lip"],
    ),
}
_WIRES_C = {
    "mouth_upper_center": (
        ["upper_lip_peak_R", "upper_lip_top", "upper_lip_peak_L"],
        [
            "levator_labii_nasal",
            "levator_labii_mid",
            "zygomatic_major",
            "orbicularis_oris_incisivis",
            "orbicularis_oris",
        ],
        0.08,
        ["lower_lip"],
    ),
    "mouth_lower_center": (
        ["lower_lip_mid_R", "lower_lip_bottom", "lower_lip_mid_L"],
        [
            "zygomatic_major",
            "risorius",
            "triangularis",
            "depressor_labii",
            "orbicularis_oris_incisivis",
            "orbicularis_oris",
            "mentalis",
        ],
        0.08,
        ["upper_lip"],
    ),
}


@lru_cache(maxsize=8)
def canonical_chart(resolution: int) -> np.ndarray:
    """Chart positions (n_skin, 2) of the default head's skin vertices at a resolution."""
    return skin_geometry(build_topology(resolution), HeadParams()).chart


class _Places:
    """Resolves recipe locations (landmark names, chart points) to vertices of one head."""

    def __init__(self, head: Head) -> None:
        self.head = head
        self.faces = head.mesh.faces
        self.chart = canonical_chart(head.resolution)
        self.front = np.nonzero(build_topology(head.resolution).directions[:, 2] > 0.2)[0]
        first_face = np.full(head.mesh.n_vertices, -1)
        order = np.argsort(self.faces.ravel(), kind="stable")
        flat = self.faces.ravel()[order]
        starts = np.searchsorted(flat, np.arange(head.mesh.n_vertices))
        valid = starts < len(flat)
        first_face[valid] = order[starts[valid]] // 3
        self.first_face = first_face

    def vertex(self, where, side: str) -> int:
        if isinstance(where, str):
            name = where if where in self.head.landmarks else f"{where}_{side}"
            return int(self.head.landmarks[name])
        x, y = where
        target = np.array([x if side != "R" else -x, y])
        ids = self.front
        return int(ids[np.argmin(np.linalg.norm(self.chart[ids] - target, axis=1))])

    def point(self, where, side: str) -> SurfacePoint:
        return self.vertex_point(self.vertex(where, side))

    def vertex_point(self, vertex: int) -> SurfacePoint:
        face = int(self.first_face[vertex])
        corner = int(np.nonzero(self.faces[face] == vertex)[0][0])
        bary = [0.0, 0.0, 0.0]
        bary[corner] = 1.0
        return SurfacePoint(face, (bary[0], bary[1], bary[2]))


def _muscles(head: Head, places: _Places) -> list[Muscle]:
    muscles = []
    for side in ("L", "R"):
        for name, kind, origin, insertion, width, fs, fe, angle, region in _MUSCLES_L:
            reg = region if region in head.regions else f"{region}_{side}"
            muscles.append(
                Muscle(
                    name=f"{name}_{side}",
                    kind=kind,
                    side=side,
                    origin=places.point(origin, side),
                    insertion=places.point(insertion, side),
                    width_rel=width,
                    falloff_start_rel=fs,
                    falloff_end_rel=fe,
                    angle_rad=float(np.radians(angle)),
                    region=reg if reg in head.regions else None,
                )
            )
    for name, kind, origin, insertion, width, fs, fe, angle, region, reversed_ in _MUSCLES_C:
        muscles.append(
            Muscle(
                name=name,
                kind=kind,
                side="C",
                origin=places.point(origin, "C"),
                insertion=places.point(insertion, "C"),
                width_rel=width,
                falloff_start_rel=fs,
                falloff_end_rel=fe,
                angle_rad=float(np.radians(angle)),
                reversed=reversed_,
                region=region,
            )
        )
    for name, side, centre, end, minor in _SPHINCTERS:
        muscles.append(
            Muscle(
                name=name,
                kind="sphincter",
                side=side,
                origin=places.point(centre, side),
                insertion=places.point(end, side),
                width_rel=minor,
                falloff_start_rel=0.6,
                falloff_end_rel=1.5,
                angle_rad=float(np.pi),
                origin_inset_rel=0.0,
                region=None,
            )
        )
    return muscles


@lru_cache(maxsize=8)
def _canonical_head(resolution: int) -> Head:
    return make_head(HeadParams(), resolution)


def _wires(head: Head, places: _Places, muscles: dict[str, Muscle], scale: float) -> list[Wire]:
    v, f = head.mesh.vertices, head.mesh.faces
    skin = np.unique(np.concatenate([f[head.mesh.parts[p]].ravel() for p in ("skin", "mouth")]))
    # deformation sets are vertex sets of the reference topology: found on the default head
    canonical = _canonical_head(head.resolution)
    rest = canonical.mesh.vertices
    canonical_scale = float(
        rest[: canonical.n_skin, 1].max() - canonical.landmark_positions(["menton"])[0][1]
    )
    wires = []
    specs = [(f"{n}_{s}", s, spec) for s in ("L", "R") for n, spec in _WIRES_L.items()]
    specs += [(n, "C", spec) for n, spec in _WIRES_C.items()]
    for name, side, (points, drivers, dropoff, exclude) in specs:
        pts = [places.point(p, side) for p in points]
        pos = np.array([p.position(v, f) for p in pts])
        sides = ("L", "R") if side == "C" else (side,)
        weights = {}
        for d in drivers:
            for s in sides:
                m = muscles.get(d) or muscles.get(f"{d}_{s}")
                if m is None or m.name in weights:
                    continue
                ins = m.insertion.position(v, f)
                length = np.linalg.norm(ins - m.origin.position(v, f))
                if m.kind == "sphincter":  # the ring pulls every control point inside it alike
                    near = np.linalg.norm(pos - m.origin.position(v, f), axis=1) < 1.3 * length
                    weights[m.name] = near.astype(np.float64)
                else:
                    dist = np.linalg.norm(pos - ins, axis=1)
                    reach = max(0.3 * length, 0.06 * scale)  # short muscles still reach their wire
                    weights[m.name] = np.round(1.5 * np.exp(-((dist / reach) ** 2)), 6)
        # deformation set: the skin within the dropoff, without the lip this wire must not move
        _, _, dist = closest_on_polyline(rest[skin], np.array([p.position(rest, f) for p in pts]))
        members = skin[dist < dropoff * canonical_scale]
        members = np.setdiff1d(
            members, np.concatenate([head.regions[r] for r in exclude] or [np.zeros(0, int)])
        )
        wires.append(
            Wire(
                name=name,
                side=side,
                points=tuple(pts),
                dropoff_rel=dropoff,
                vertices=members,
                muscle_weights=weights,
                rest_weight=np.ones(len(pts)),
            )
        )
    return wires


def _bones(head: Head) -> tuple[list[Bone], np.ndarray]:
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


def _skin_weights(head: Head, jaw_pivot: np.ndarray) -> sp.csr_matrix:
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
    reach = np.linalg.norm(v[:, None] - corners[None], axis=2).min(axis=1) / half_width
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
    above = skin[
        (v[skin, 1] > alar[1]) | (v[skin, 2] < tragion[2]) | (v[skin, 1] < menton[1] - NECK_FREE_REL * scale)
    ]
    for ids in (*still, above, upper):
        fixed[ids] = True
    core = skin[
        (np.linalg.norm(v[skin] - pogonion, axis=1) < CHIN_CORE_REL * scale)
        & (v[skin, 1] < stomion[1])
        & (v[skin, 2] > menton[2])  # the chin's front, not the skin under it
    ]
    for ids in (regions["chin"], core, lower):
        fixed[ids], value[ids] = True, 1.0
    value[lower] = 1.0 - (1.0 - CORNER_JAW) * (1.0 - smoothstep(0.0, LOWER_LIP_REACH, reach[lower]))
    value[upper] = CORNER_JAW * (1.0 - smoothstep(0.0, UPPER_LIP_REACH, reach[upper]))
    skin_faces = head.mesh.faces[head.mesh.parts["skin"]]
    free = np.zeros(n, dtype=bool)
    free[skin] = ~fixed[skin]
    harmonic = smooth_field(value, v, skin_faces, HARMONIC_LENGTH_REL * scale, free=free)
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
    W[W < 1e-6] = 0.0
    W /= W.sum(axis=1, keepdims=True)
    return sp.csr_matrix(W)


def _channels(muscles: list[Muscle]) -> list[Channel]:
    """The pivot's channels: muscles in [0, 1], then jaw, eyelids (``eyelid_upper`` at its maximum,
    EYELID_CLOSED_RAD, closes the eye on every head), gaze and head, with their units."""
    channels = [Channel(m.name, 0.0, 1.0, group="muscles") for m in muscles]
    channels += [
        Channel("jaw_open", -0.05, 0.45, unit="rad", group="jaw"),
        Channel("jaw_slide", -0.03, 0.03, unit="rel", group="jaw"),
        Channel("jaw_protrude", -0.02, 0.04, unit="rel", group="jaw"),
    ]
    for side in "LR":
        channels += [
            Channel(f"eyelid_upper_{side}", -0.3, EYELID_CLOSED_RAD, unit="rad", group="eyelids"),
            Channel(f"eyelid_lower_{side}", -0.2, 0.3, unit="rad", group="eyelids"),
        ]
    channels += [
        Channel("gaze_yaw", -0.6, 0.6, unit="rad", group="eyes"),
        Channel("gaze_pitch", -0.5, 0.5, unit="rad", group="eyes"),
        Channel("gaze_convergence", -0.2, 0.4, unit="rad", group="eyes"),
        Channel("head_yaw", -0.9, 0.9, unit="rad", group="head"),
        Channel("head_pitch", -0.6, 0.6, unit="rad", group="head"),
        Channel("head_roll", -0.5, 0.5, unit="rad", group="head"),
    ]
    return channels


def build_rig(head: Head) -> Rig:
    """The procedural rig of a generated head: muscles, wires, bones, skin weights, channels."""
    places = _Places(head)
    muscles = _muscles(head, places)
    scale = float(head.vertices[: head.n_skin, 1].max() - head.landmark_positions(["menton"])[0][1])
    wires = _wires(head, places, {m.name: m for m in muscles}, scale)
    bones, pivot = _bones(head)
    landmarks = {name: places.vertex_point(v) for name, v in head.landmarks.items()}
    return Rig(
        mesh=head.mesh,
        units="cm",
        scale=scale,
        landmarks=landmarks,
        regions=dict(head.regions),
        muscles=tuple(muscles),
        wires=tuple(wires),
        bones=tuple(bones),
        skin_weights=_skin_weights(head, pivot),
        channels=tuple(_channels(muscles)),
        metadata={
            "generator": "mimetic.head",
            "resolution": head.resolution,
            "params": head.params.as_dict(),
        },
    )
