"""Pieces every engine shares: the deformation chain after the muscles, and muscle geometry.

The chain follows the automated rigging thesis (§4.3.2): muscles -> skull -> creases ->
skinning -> eyelid sculptors, then the accessories riveted to the skin (``attach``). The muscle
stage is engine-specific; the rest is here.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.interpolate import LinearNDInterpolator

from mimetic.engines.attach import find_attachments, ride
from mimetic.engines.skinning import bone_transforms, linear_blend_skinning
from mimetic.head.parts import eyeball_profile
from mimetic.mesh.geometry import vertex_normals
from mimetic.rig.model import Rig

SKIN_PARTS = ("skin", "mouth")  # the deformable surface; other parts only follow bones
SKULL_CLEARANCE_REL = 0.0  # the skull surface lies on the rest forehead (as the thesis lofts it)
LID_RIGID_WEIGHT = 0.35  # eyelid bone weight from which muscles leave a vertex to the lid
SCULPTOR_MARGIN_REL = 0.0002  # lids stay this far outside the eyeball (0.005 cm on a 23 cm head)


@dataclass(frozen=True)
class MuscleFrame:
    """Where a muscle pulls from and to, in rig units."""

    attachment: np.ndarray  # (3,) bony origin (linear, sheet) or centre (sphincter)
    insertion: np.ndarray  # (3,)
    length: float


def muscle_frame(rig: Rig, name: str) -> MuscleFrame:
    m = rig.muscle(name)
    v, f = rig.mesh.vertices, rig.mesh.faces
    insertion = m.insertion.position(v, f)
    attachment = m.origin.position(v, f) if m.kind == "sphincter" else rig.muscle_attachment(name)
    return MuscleFrame(attachment, insertion, float(np.linalg.norm(insertion - attachment)))


def deformable_vertices(rig: Rig) -> np.ndarray:
    """Sorted indices of the vertices muscles may move: the skin and the mouth cavity."""
    parts = [p for p in SKIN_PARTS if p in rig.mesh.parts]
    if not parts:
        return np.arange(rig.n_vertices)
    return np.unique(np.concatenate([rig.mesh.faces[rig.mesh.parts[p]].ravel() for p in parts]))


def muscle_mask(rig: Rig) -> np.ndarray:
    """How much (n,) of each vertex's motion the muscles may drive, from its eyelid bone weight.

    The lids are bones (as in the thesis): skin bound to a lid bone by LID_RIGID_WEIGHT or more
    follows the lid only, and the lid's blend into the surrounding skin blends the two, so nothing
    tears at the lid border and no muscle drags a closed lid into the eyeball.
    """
    lids = [rig.bone_index(b) for b in rig.bone_names if b.startswith("eyelid_")]
    if not lids:
        return np.ones(rig.n_vertices)
    lid = np.asarray(rig.skin_weights[:, lids].sum(axis=1)).ravel()
    return np.clip(1.0 - lid / LID_RIGID_WEIGHT, 0.0, 1.0)


def lip_contact_pairs(rig: Rig) -> np.ndarray:
    """Pairs (k, 2) of (upper lip, lower lip) vertices that coincide at rest: the lips' contact line."""
    upper, lower = rig.regions.get("upper_lip"), rig.regions.get("lower_lip")
    if upper is None or lower is None or not len(upper) or not len(lower):
        return np.zeros((0, 2), np.int64)
    from scipy.spatial import cKDTree

    v = rig.mesh.vertices
    dist, nearest = cKDTree(v[lower]).query(v[upper])
    touching = dist < 1e-9 * rig.scale
    return np.column_stack([upper[touching], lower[nearest[touching]]]).astype(np.int64)


def lip_mask(rig: Rig, insertion_vertex_point) -> np.ndarray:
    """Vertices a muscle inserting at a point may move: not the opposite lip (n,) bool."""
    n = rig.n_vertices
    mask = np.ones(n, dtype=bool)
    upper, lower = rig.regions.get("upper_lip"), rig.regions.get("lower_lip")
    if upper is None or lower is None:
        return mask
    face = rig.mesh.faces[insertion_vertex_point.face]
    corner = face[int(np.argmax(insertion_vertex_point.bary))]
    if np.isin(corner, upper):
        mask[lower] = False
    elif np.isin(corner, lower):
        mask[upper] = False
    return mask


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance (m,) from points (m, 3) to the segment a-b (3,), and the parameter t (m,) in [0, 1]."""
    ab = b - a
    t = np.clip((points - a) @ ab / max(ab @ ab, 1e-30), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * ab), axis=1), t


def crease_deltas(rig: Rig) -> dict[str, np.ndarray]:
    """Crease clusters (thesis §4.3.2): channel name -> displacement (n, 3) per unit activation.

    Each crease is a line on the rest skin whose vertices sink inward (against the normal) with a
    Gaussian profile across the line, driven linearly by a muscle: forehead lines (frontalis),
    vertical glabella lines (corrugator), a nasion line (procerus), crow's feet (orbicularis oculi)
    and a deeper nasolabial fold (zygomatic major and the levators). Rigs without the needed
    landmarks get no creases.
    """
    need = [
        f"{n}_{side}" for n in ("brow_mid", "eye_outer_corner", "alar_base", "mouth_corner") for side in "LR"
    ]
    if not all(n in rig.landmarks for n in [*need, "nasion", "glabella"]):
        return {}
    s = rig.scale
    v = rig.mesh.vertices
    normals = surface_normals(rig)
    skin = rig.mesh.part_vertices("skin") if "skin" in rig.mesh.parts else deformable_vertices(rig)

    def lm(name: str) -> np.ndarray:
        return rig.landmark_positions([name])[0]

    def on_surface(x: float, y: float, near: np.ndarray) -> np.ndarray:
        """The rest vertex nearest to (x, y) seen from the front, among ``near``."""
        return v[near[np.argmin((v[near, 0] - x) ** 2 + (v[near, 1] - y) ** 2)]]

    front = skin[v[skin, 2] > 0.15 * s]
    out: dict[str, np.ndarray] = {}

    def add(channel: str, a: np.ndarray, b: np.ndarray, width: float, depth: float) -> None:
        if channel not in rig.channel_names:
            return
        dist, t = _segment_distance(v[skin], a, b)
        w = np.exp(-((dist / width) ** 2)) * np.sin(np.pi * (0.1 + 0.8 * t)) ** 0.5
        delta = out.setdefault(channel, np.zeros_like(v))
        delta[skin] -= (depth * w)[:, None] * normals[skin]

    for side, sx in (("L", 1.0), ("R", -1.0)):
        brow = lm(f"brow_mid_{side}")
        for k in range(3):
            y = brow[1] + (0.09 + 0.045 * k) * s
            inner = [on_surface(sx * x * s, y, front) for x in (0.005, 0.11)]
            outer = [on_surface(sx * x * s, y, front) for x in (0.07, 0.19)]
            add(f"frontalis_inner_{side}", *inner, 0.006 * s, 0.004 * s)
            add(f"frontalis_outer_{side}", *outer, 0.006 * s, 0.004 * s)
        top = on_surface(sx * 0.03 * s, lm("glabella")[1] + 0.05 * s, front)
        add(
            f"corrugator_{side}",
            on_surface(sx * 0.025 * s, lm("nasion")[1], front),
            top,
            0.006 * s,
            0.006 * s,
        )
        corner = lm(f"eye_outer_corner_{side}")
        for k in (-1, 0, 1):
            a = corner + np.array([sx * 0.02 * s, 0.012 * k * s, -0.01 * s])
            b = corner + np.array([sx * 0.07 * s, 0.035 * k * s, -0.03 * s])
            for muscle in ("orbicularis_oculi_outer", "orbicularis_oculi"):
                add(f"{muscle}_{side}", a, b, 0.005 * s, 0.003 * s)
        fold_end = lm(f"mouth_corner_{side}") + np.array([sx * 0.035 * s, -0.03 * s, -0.01 * s])
        for muscle in ("zygomatic_major", "levator_labii_mid", "levator_labii_nasal"):
            add(f"{muscle}_{side}", lm(f"alar_base_{side}"), fold_end, 0.008 * s, 0.007 * s)
    nasion = lm("nasion")
    add(
        "procerus",
        nasion + np.array([-0.03 * s, 0.0, 0.0]),
        nasion + np.array([0.03 * s, 0.0, 0.0]),
        0.006 * s,
        0.005 * s,
    )
    return out


class Chain:
    """The stages after the muscles: skull push, creases, skinning, eyelid sculptors, accessories
    riveted to the skin (prepared once)."""

    def __init__(self, rig: Rig, *, skull: bool = True, creases: bool = True) -> None:
        self.rig = rig
        v = rig.mesh.vertices
        folds = crease_deltas(rig) if creases else {}
        self.crease_channels = np.array([rig.channel_index(c) for c in folds], dtype=np.int64)
        self.creases = sp.csr_matrix(np.array([d.ravel() for d in folds.values()]).reshape(len(folds), -1))
        self.weights = rig.skin_weights.tocsc()
        self.lip_pairs = lip_contact_pairs(rig)
        self.skull_ids = np.asarray(rig.regions.get("forehead", np.zeros(0, np.int64)))
        self.skull = None
        if skull and len(self.skull_ids) > 10:
            pts = v[self.skull_ids]
            self.skull = LinearNDInterpolator(pts[:, :2], pts[:, 2] - SKULL_CLEARANCE_REL * rig.scale)
        self.lids = []
        for side in ("L", "R"):
            if f"eye_{side}" not in rig.bone_names:
                continue
            ids = np.concatenate(
                [rig.regions.get(f"eyelid_{lid}_{side}", np.zeros(0, np.int64)) for lid in ("upper", "lower")]
            )
            bone = rig.bone(f"eye_{side}")
            # only lid vertices clear of the eyeball at rest (the conjunctiva skirt is tucked inside)
            dist, limit = self._eyeball_clearance(v[ids], bone.head, bone.tail - bone.head)
            outside = dist >= limit
            self.lids.append(
                (ids[outside].astype(np.int64), rig.bone_index(f"eye_{side}"), bone.head, bone.tail)
            )
        self.attachments = find_attachments(rig.mesh, rig.scale, rig.skin_weights)

    def _eyeball_clearance(self, points: np.ndarray, centre: np.ndarray, gaze: np.ndarray) -> tuple:
        """Distances (k,) of points from the eye centre and the sculptor's limit (k,) for each."""
        radius = np.linalg.norm(gaze)
        d = points - centre
        dist = np.linalg.norm(d, axis=1)
        angle = np.arccos(np.clip(d @ gaze / np.maximum(dist * radius, 1e-30), -1.0, 1.0))
        limit = radius * eyeball_profile(angle) + SCULPTOR_MARGIN_REL * self.rig.scale
        return dist, limit

    def apply(self, deformed: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Lip contact, skull push (+Z onto the rest forehead), creases, skinning, lid sculptors,
        then the accessories (eyelashes and the like) placed on the skin they ride.

        ``deformed`` (n, 3) is the rest skin moved by the muscles; returns (n, 3).
        """
        v = deformed.copy()
        if len(self.lip_pairs):  # lips meet but never cross: a crossed pair is pressed together
            upper, lower = v[self.lip_pairs[:, 0]], v[self.lip_pairs[:, 1]]
            crossed = upper[:, 1] < lower[:, 1]
            mid = 0.5 * (upper[crossed, 1] + lower[crossed, 1])
            v[self.lip_pairs[crossed, 0], 1] = mid
            v[self.lip_pairs[crossed, 1], 1] = mid
        if self.skull is not None:
            p = v[self.skull_ids]
            z = self.skull(p[:, 0], p[:, 1])
            behind = np.isfinite(z) & (p[:, 2] < z - 1e-9 * self.rig.scale)
            v[self.skull_ids[behind], 2] = z[behind]
        if len(self.crease_channels):
            v += (self.creases.T @ values[self.crease_channels]).reshape(-1, 3)
        transforms = bone_transforms(self.rig, values)
        v = linear_blend_skinning(v, self.weights, transforms)
        for ids, bone, rest_centre, rest_tip in self.lids:
            # sculptor: lids never inside the eyeball (its profile, the cornea included)
            m = transforms[bone]
            centre = m[:3, :3] @ rest_centre + m[:3, 3]
            dist, limit = self._eyeball_clearance(v[ids], centre, m[:3, :3] @ (rest_tip - rest_centre))
            inside = dist < limit
            d = v[ids[inside]] - centre
            v[ids[inside]] = centre + d * (limit[inside] / dist[inside])[:, None]
        return ride(self.attachments, self.rig.mesh.vertices, v, transforms) if len(self.attachments) else v


def surface_normals(rig: Rig) -> np.ndarray:
    """Rest vertex normals (n, 3)."""
    return vertex_normals(rig.mesh.vertices, rig.mesh.faces)
