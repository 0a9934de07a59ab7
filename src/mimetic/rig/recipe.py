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

from mimetic.head.model import Head, make_head
from mimetic.head.params import HeadParams
from mimetic.head.shape import skin_geometry
from mimetic.head.topology import build_topology
from mimetic.mesh.geometry import closest_on_polyline
from mimetic.mesh.model import SurfacePoint
from mimetic.rig.anatomy import Anatomy
from mimetic.rig.anatomy.actions import CHANNELS as ACTION_CHANNELS
from mimetic.rig.bones import EYELID_CLOSED_RAD, bone_placement, skin_weights
from mimetic.rig.model import Channel, Muscle, Rig, Wire

CHEEK_SUCK = -0.5
"""The lower end of ``cheek_puff``: the puff's field reversed draws the cheeks in (FACS AU35)."""
JAW_SLIDE_REL = 0.045
"""``jaw_slide``'s reach to either side, × the head height (1 cm on a 22 cm head: an adult's lateral
excursion is 8-12 mm). 0.03 before 2026-12-07: ICT's captured jawLeft/jawRight were fitted at the
bound (wire, automatic landmarks: 28.3 → 26.9 % on ICT, 28.3 → 26.8 on check s101 σ 1)."""
JAW_PROTRUDE_REL = 0.05
"""``jaw_protrude``'s forward reach, × the head height (1.1 cm; protrusion is 7-11 mm). 0.04 before
2026-12-07, the bound of ICT's jawForward fit (36.8 → 35.9 % on ICT, 37.0 → 36.0 on check s101 σ 1)."""

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
    # the mentalis runs from the chin boss up toward the lower lip (1.2-1.6 cm) and lifts the whole lip
    # above it: its zone (Waters' radial falloff, the vector engine) reaches 2.5 lengths
    ("mentalis", "linear", "pogonion", (0.0, -8.4), 0.05, 0.8, 2.5, 40, "chin", True),
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

    def vertex(self, where, side: str, avoid: int = -1) -> int:
        """The vertex of a landmark name or of the front vertex nearest a chart point other than
        ``avoid`` (a muscle's other end: on a coarse head both ends can be nearest one vertex)."""
        if isinstance(where, str):
            name = where if where in self.head.landmarks else f"{where}_{side}"
            return int(self.head.landmarks[name])
        x, y = where
        target = np.array([x if side != "R" else -x, y])
        ids = self.front[self.front != avoid]
        return int(ids[np.argmin(np.linalg.norm(self.chart[ids] - target, axis=1))])

    def point(self, where, side: str, avoid: int = -1) -> SurfacePoint:
        return self.vertex_point(self.vertex(where, side, avoid))

    def ends(self, origin, insertion, side: str) -> tuple[SurfacePoint, SurfacePoint]:
        """A muscle's origin and insertion, never the same vertex."""
        first = self.vertex(origin, side)
        return self.vertex_point(first), self.point(insertion, side, avoid=first)

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
            start, end = places.ends(origin, insertion, side)
            muscles.append(
                Muscle(
                    name=f"{name}_{side}",
                    kind=kind,
                    side=side,
                    origin=start,
                    insertion=end,
                    width_rel=width,
                    falloff_start_rel=fs,
                    falloff_end_rel=fe,
                    angle_rad=float(np.radians(angle)),
                    region=reg if reg in head.regions else None,
                )
            )
    for name, kind, origin, insertion, width, fs, fe, angle, region, reversed_ in _MUSCLES_C:
        start, end = places.ends(origin, insertion, "C")
        muscles.append(
            Muscle(
                name=name,
                kind=kind,
                side="C",
                origin=start,
                insertion=end,
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


def _channels(muscles: list[Muscle]) -> list[Channel]:
    """The pivot's channels: muscles in [0, 1], the tissue actions' own channels (``cheek_puff`` down
    to CHEEK_SUCK draws the cheeks in), then jaw, eyelids (``eyelid_upper`` at its maximum,
    EYELID_CLOSED_RAD, closes the eye on every head), gaze and head, with their units.
    The jaw's translations reach a mandible's own range (JAW_SLIDE_REL, JAW_PROTRUDE_REL)."""
    channels = [Channel(m.name, 0.0, 1.0, group="muscles") for m in muscles]
    channels += [
        Channel(name, CHEEK_SUCK if name.startswith("cheek_puff") else 0.0, 1.0, group=group)
        for name, (group, _) in ACTION_CHANNELS.items()
    ]
    channels += [
        Channel("jaw_open", -0.05, 0.45, unit="rad", group="jaw"),
        Channel("jaw_slide", -JAW_SLIDE_REL, JAW_SLIDE_REL, unit="rel", group="jaw"),
        Channel("jaw_protrude", -0.02, JAW_PROTRUDE_REL, unit="rel", group="jaw"),
    ]
    for side in "LR":
        channels += [
            Channel(f"eyelid_upper_{side}", -0.3, EYELID_CLOSED_RAD, unit="rad", group="eyelids"),
            Channel(f"eyelid_lower_{side}", -0.2, 0.3, unit="rad", group="eyelids"),
        ]
    channels += [
        Channel("gaze_yaw", -0.6, 0.6, unit="rad", group="eyes"),
        Channel("gaze_pitch", -0.5, 0.5, unit="rad", group="eyes"),
        Channel("gaze_convergence", -0.4, 0.4, unit="rad", group="eyes"),
        Channel("gaze_vertical_vergence", -0.4, 0.4, unit="rad", group="eyes"),
        Channel("head_yaw", -0.9, 0.9, unit="rad", group="head"),
        Channel("head_pitch", -0.6, 0.6, unit="rad", group="head"),
        Channel("head_roll", -0.5, 0.5, unit="rad", group="head"),
    ]
    return channels


def build_rig(head: Head, *, anatomy: bool = True) -> Rig:
    """The procedural rig of a generated head: muscles, wires, bones, skin weights, channels.

    ``anatomy=False`` leaves the anatomy empty (``Anatomy.none``), for a rig that is only transferred
    (``rig_head``'s fitted reference: the transfer derives the user's anatomy on the user's mesh); its
    derivation is a third of the time of building the rig.
    """
    places = _Places(head)
    muscles = _muscles(head, places)
    scale = float(head.vertices[: head.n_skin, 1].max() - head.landmark_positions(["menton"])[0][1])
    wires = _wires(head, places, {m.name: m for m in muscles}, scale)
    bones, pivot = bone_placement(head)
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
        skin_weights=skin_weights(head, pivot),
        channels=tuple(_channels(muscles)),
        metadata={
            "generator": "mimetic.head",
            "resolution": head.resolution,
            "params": head.params.as_dict(),
        },
        anatomy=None if anatomy else Anatomy.none(head.mesh.n_vertices, len(bones)),
    )
