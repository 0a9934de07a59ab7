"""The project's named landmarks, known by construction, and their iBUG-68 mapping.

Every landmark is a vertex index of the generated head. Ring landmarks (eye corners and lids,
lip corners and lip points) are ring vertices at fixed angles; the others are the skin
vertices nearest to anatomical definitions evaluated on the default head of the same
resolution, so each name maps to the same vertex index for every parameter set.

Sides follow the subject: ``_L`` is the subject's left (+X), ``_R`` the right (-X).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from mimetic.head.shape import SUBNASALE_Y0, default_skin_geometry
from mimetic.head.topology import EYE_CENTRE, HeadTopology
from mimetic.mesh.geometry import vertex_normals
from mimetic.mesh.model import Mesh

# iBUG / Multi-PIE 68-point order (0-based) -> landmark name
IBUG68: tuple[str, ...] = (
    *(f"jaw_R{k}" for k in range(1, 9)),
    "menton",
    *(f"jaw_L{k}" for k in range(8, 0, -1)),
    "brow_outer_R",
    "brow_outer_mid_R",
    "brow_mid_R",
    "brow_inner_mid_R",
    "brow_inner_R",
    "brow_inner_L",
    "brow_inner_mid_L",
    "brow_mid_L",
    "brow_outer_mid_L",
    "brow_outer_L",
    "nasion",
    "nose_bridge_upper",
    "nose_bridge_lower",
    "nose_tip",
    "alar_base_R",
    "nostril_R",
    "subnasale",
    "nostril_L",
    "alar_base_L",
    "eye_outer_corner_R",
    "eye_upper_lid_outer_R",
    "eye_upper_lid_inner_R",
    "eye_inner_corner_R",
    "eye_lower_lid_inner_R",
    "eye_lower_lid_outer_R",
    "eye_inner_corner_L",
    "eye_upper_lid_inner_L",
    "eye_upper_lid_outer_L",
    "eye_outer_corner_L",
    "eye_lower_lid_outer_L",
    "eye_lower_lid_inner_L",
    "mouth_corner_R",
    "upper_lip_outer_R",
    "upper_lip_peak_R",
    "upper_lip_top",
    "upper_lip_peak_L",
    "upper_lip_outer_L",
    "mouth_corner_L",
    "lower_lip_outer_L",
    "lower_lip_mid_L",
    "lower_lip_bottom",
    "lower_lip_mid_R",
    "lower_lip_outer_R",
    "mouth_corner_R",
    "upper_lip_inner_R",
    "upper_lip_inner",
    "upper_lip_inner_L",
    "mouth_corner_L",
    "lower_lip_inner_L",
    "lower_lip_inner",
    "lower_lip_inner_R",
)

# MediaPipe FaceMesh indices of a few landmarks (for detector checks; see mediapipe-offline.md)
MEDIAPIPE: dict[str, int] = {
    "eye_outer_corner_R": 33,
    "eye_inner_corner_R": 133,
    "eye_inner_corner_L": 362,
    "eye_outer_corner_L": 263,
    "mouth_corner_R": 61,
    "mouth_corner_L": 291,
    "nose_tip": 4,
    "menton": 152,
}

# eye-ring angles (t = 0 at the lateral canthus, counter-clockwise on the left eye)
_EYE_ANGLES = {
    "eye_outer_corner": 0.0,
    "eye_upper_lid_outer": np.pi / 3,
    "eye_upper_lid": np.pi / 2,
    "eye_upper_lid_inner": 2 * np.pi / 3,
    "eye_inner_corner": np.pi,
    "eye_lower_lid_inner": 4 * np.pi / 3,
    "eye_lower_lid": 3 * np.pi / 2,
    "eye_lower_lid_outer": 5 * np.pi / 3,
}
# brow points: chart offsets from the left eye centre (medial is -X)
_BROW = {
    "brow_inner": (-1.75, 1.3),
    "brow_inner_mid": (-0.95, 1.75),
    "brow_mid": (0.0, 1.95),
    "brow_outer_mid": (0.95, 1.85),
    "brow_outer": (1.8, 1.4),
}
# lip points on the left half: (ring, xi = x / half-width, upper?)
_LIP = {
    "upper_lip_peak": ("border", 0.22, True),
    "upper_lip_outer": ("border", 0.6, True),
    "lower_lip_mid": ("border", 0.27, False),
    "lower_lip_outer": ("border", 0.62, False),
    "upper_lip_inner": ("contact", 0.45, True),
    "lower_lip_inner": ("contact", 0.45, False),
}


def _nearest_angle(t_ring: np.ndarray, t: float) -> int:
    d = np.angle(np.exp(1j * (t_ring - t)))
    return int(np.argmin(np.abs(d)))


def skin_landmarks(topo: HeadTopology, mesh: Mesh, pieces: Mapping[str, Mesh]) -> dict[str, int]:
    """Landmark name -> vertex index in the head mesh (skin first, parts after)."""
    geo = default_skin_geometry(topo)
    v, chart = geo.vertices, geo.chart
    normals = vertex_normals(v, topo.faces)
    meridian = np.nonzero(topo.mirror == np.arange(topo.n_vertices))[0]
    meridian = meridian[np.isnan(topo.ring_uv[meridian, 0])]
    front = np.nonzero((topo.directions[:, 2] > 0.3) & np.isnan(topo.ring_uv[:, 0]))[0]
    out: dict[str, int] = {}

    def nearest(candidates: np.ndarray, target: np.ndarray, space: np.ndarray) -> int:
        return int(candidates[np.argmin(np.linalg.norm(space[candidates] - target, axis=1))])

    def both_sides(name: str, left: int) -> None:
        out[f"{name}_L"] = left
        out[f"{name}_R"] = int(topo.mirror[left])

    # eyes: lid-margin ring (u = 0)
    margin = topo.eye_L.index[1]
    t_eye = topo.ring_uv[margin, 1]
    for name, t in _EYE_ANGLES.items():
        both_sides(name, int(margin[_nearest_angle(t_eye, t)]))
    start = 0
    for part, piece in pieces.items():
        if part in ("eye_L", "eye_R"):
            out[f"pupil_{part[-1]}"] = start  # the eyeball's front pole is its vertex 0
        start += piece.n_vertices

    # brows
    ec = EYE_CENTRE
    for name, off in _BROW.items():
        both_sides(name, nearest(np.concatenate([front, topo.eye_L.index[-3:].ravel()]), ec + off, chart))

    # lips: the contact ring (u = 0) and the vermilion border ring (u = 1)
    m = topo.mouth
    contact, border = m.index[1], m.index[int(np.argmin(np.abs(m.u - 1.0)))]
    t_m = topo.ring_uv[contact, 1]
    quarter = len(t_m) // 4
    both_sides("mouth_corner", int(contact[0]))
    out["upper_lip_top"] = int(border[quarter])
    out["lower_lip_bottom"] = int(border[3 * quarter])
    out["upper_lip_inner"] = int(contact[quarter])
    out["lower_lip_inner"] = int(contact[3 * quarter])
    for name, (ring, xi, upper) in _LIP.items():
        t = np.arccos(xi) * (1 if upper else -1)
        ids = border if ring == "border" else contact
        both_sides(name, int(ids[_nearest_angle(t_m, t)]))

    # nose and midline
    out["glabella"] = nearest(meridian, np.array([0.0, 1.6]), chart)
    out["nasion"] = nearest(meridian, np.array([0.0, 0.9]), chart)
    nose = meridian[(chart[meridian, 1] < -1.5) & (chart[meridian, 1] > SUBNASALE_Y0 + 0.3)]
    tip = int(nose[np.argmax(v[nose, 2])])
    out["nose_tip"] = tip
    out["nose_bridge_upper"] = nearest(meridian, np.array([0.0, 0.9 + (chart[tip, 1] - 0.9) / 3]), chart)
    out["nose_bridge_lower"] = nearest(meridian, np.array([0.0, 0.9 + 2 * (chart[tip, 1] - 0.9) / 3]), chart)
    top_of_mouth = topo.mouth.index[-1][topo.mouth.index.shape[1] // 4]  # the outer mouth ring's top
    sn = SUBNASALE_Y0  # chart Y of the subnasale on the default head
    out["subnasale"] = nearest(np.append(meridian, top_of_mouth), np.array([0.0, sn - 0.05]), chart)
    both_sides("nostril", nearest(front, np.array([0.6, sn + 0.3]), chart))
    both_sides("alar_base", nearest(front, np.array([1.25, sn + 0.15]), chart))
    both_sides("alare", nearest(front, np.array([1.85, sn + 0.6]), chart))

    # chin: pogonion = the chin's most prominent midline point seen from in front and 25° below (the
    # lower face slopes back, so the plain most anterior point sits high, at the mentolabial
    # bulge); the mouth's skin rings reach down onto the chin, so their midline column counts as
    # midline. menton = the point facing 45° down-forward on the chin's convex curve below it
    # (the concave angle where the chin meets the neck faces that way too, so points more than
    # 2.5 cm behind the pogonion are left out)
    m_skin = topo.mouth.index[topo.mouth.u > 1.0][:, 3 * topo.mouth.index.shape[1] // 4]
    midline = np.concatenate([meridian, m_skin])
    chin = midline[(v[midline, 1] < -9.0) & (v[midline, 2] > 3.0)]
    view = np.radians(25.0)
    out["pogonion"] = int(chin[np.argmax(v[chin, 2] * np.cos(view) - v[chin, 1] * np.sin(view))])
    pog = v[out["pogonion"]]
    chin = chin[(v[chin, 1] < pog[1] - 0.3) & (v[chin, 2] > pog[2] - 2.5)]
    want = np.array([0.0, -np.sqrt(0.5), np.sqrt(0.5)])
    out["menton"] = int(chin[np.argmax(normals[chin] @ want)])

    # jaw contour (iBUG 0..16): outermost skin point in the frontal view along rays from a centre
    skin_front = np.nonzero((v[:, 2] > -1.0) & (v[:, 1] < 0.0) & (v[:, 1] >= v[out["menton"], 1]))[0]
    centre = np.array([0.0, -2.0])
    rel = v[skin_front, :2] - centre
    ang = np.arctan2(rel[:, 1], rel[:, 0])  # -pi/2 = straight down
    radius = np.linalg.norm(rel, axis=1)
    for k in range(1, 9):
        a = np.pi * (-(k - 1) / 8.5) * 0.5 - 0.02  # from horizontal (left) towards down
        band = np.abs(np.angle(np.exp(1j * (ang - a)))) < 0.04
        left = int(skin_front[band][np.argmax(radius[band])])
        out[f"jaw_L{k}"] = left
        out[f"jaw_R{k}"] = int(topo.mirror[left])
    both_sides("gonion", nearest(np.arange(topo.n_vertices), np.array([5.4, -8.9, -0.6]), v))
    side = np.nonzero((v[:, 1] > -2.0) & (v[:, 1] < -0.5) & (v[:, 2] > 0.0) & (v[:, 2] < 4.0))[0]
    both_sides("zygion", int(side[np.argmax(v[side, 0])]))
    ear = np.nonzero((np.abs(v[:, 1] + 1.6) < 0.8) & (np.abs(v[:, 2] + 0.3) < 1.0))[0]
    both_sides("tragion", int(ear[np.argmax(v[ear, 0])]))
    return dict(sorted(out.items()))
