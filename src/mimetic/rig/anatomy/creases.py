"""Creases: lines of skin that sink when a muscle contracts (the automated-rigging thesis, §4.3).

Each crease is a segment on the rest skin whose vertices sink inward (against the rest tissue normal:
the skin's normal smoothed, with the lips closed, so the skin at a mouth corner sinks as one)
with a Gaussian profile across the line and a sine taper along it, by ``depth_rel`` at full
contraction of its driving channels: three forehead lines per side with the frontalis (inner and
outer halves), a vertical glabella line with the corrugator, a nasion line with the procerus,
crow's feet with the orbicularis oculi, and a deeper nasolabial fold with the zygomatic major and
the levators, which ends short of the mouth corner. Lines are placed from landmarks, in fractions
of the head height; rigs without the landmarks they need get no creases.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np
from scipy.spatial import cKDTree

FOREHEAD_LINES_REL = (0.09, 0.135, 0.18)
"""Heights of the three forehead lines above the mid-brow landmark, × the head height."""
FOREHEAD_INNER_X_REL = (0.005, 0.11)
"""The inner forehead lines' span across the face (|x| from the midline), × the head height."""
FOREHEAD_OUTER_X_REL = (0.07, 0.19)
"""The outer forehead lines' span."""
FOREHEAD_WIDTH_REL, FOREHEAD_DEPTH_REL = 0.006, 0.004
"""Gaussian half-width across, and depth at full contraction, of a forehead line."""
GLABELLA_X_REL, GLABELLA_TOP_X_REL, GLABELLA_RISE_REL = 0.025, 0.03, 0.05
"""A glabella line runs from |x| = GLABELLA_X at the nasion's height to |x| = GLABELLA_TOP_X at the
glabella's height plus GLABELLA_RISE."""
GLABELLA_WIDTH_REL, GLABELLA_DEPTH_REL = 0.006, 0.006
CROWS_FEET_FROM_REL = (0.02, 0.012, -0.01)
"""Start of a crow's-foot line from the outer eye corner: outward, up per line index, back."""
CROWS_FEET_TO_REL = (0.07, 0.035, -0.03)
"""End of a crow's-foot line from the outer eye corner: outward, up per line index, back."""
CROWS_FEET_WIDTH_REL, CROWS_FEET_DEPTH_REL = 0.005, 0.003
NASOLABIAL_END_REL = (0.035, -0.03, -0.01)
"""End of the nasolabial fold from the mouth corner: outward, down, back (it starts at the alar base)."""
NASOLABIAL_WIDTH_REL, NASOLABIAL_DEPTH_REL = 0.008, 0.007
NASOLABIAL_CLEAR_REL = 0.02
"""The nasolabial fold fades out within this × the head height (4 mm) of the lips (of the mouth
corner on a rig without lip regions): it ends at the modiolus, and the thin triangles where the
lips' rows converge at a corner must move as one."""
NASION_HALF_LENGTH_REL, NASION_WIDTH_REL, NASION_DEPTH_REL = 0.03, 0.006, 0.005
FRONT_Z_REL = 0.15
"""Skin in front of z = this × the head height is the face a crease line may be placed on."""
TAPER_MARGIN = 0.1
"""A crease fades to sin(π·TAPER_MARGIN)^½ at its ends: sin(π·(margin + (1 − 2·margin)·t))^½."""
MIN_WEIGHT = 1e-4
"""Vertices the profile moves by less than this share of the depth are left out."""


@dataclass(frozen=True, eq=False)
class Crease:
    """One crease line.

    Attributes
    ----------
    name : str
        E.g. "forehead_1_L".
    gains : Mapping[str, float]
        Channel name → how deep the crease sinks per unit of that channel (its depth at 1).
    vertices : (k,) int64
        The vertices it moves.
    offsets_rel : (k, 3) float64
        Each vertex's displacement at full depth, × the head height (inward along the rest tissue normal).
    """

    name: str
    gains: Mapping[str, float]
    vertices: np.ndarray
    offsets_rel: np.ndarray

    def __post_init__(self) -> None:
        object.__setattr__(self, "gains", MappingProxyType({str(k): float(v) for k, v in self.gains.items()}))
        for name, dtype in (("vertices", np.int64), ("offsets_rel", np.float64)):
            array = np.array(getattr(self, name), dtype=dtype, copy=True)
            array.setflags(write=False)
            object.__setattr__(self, name, array)


NEEDED = (
    *(f"{n}_{side}" for n in ("brow_mid", "eye_outer_corner", "alar_base", "mouth_corner") for side in "LR"),
    "nasion",
    "glabella",
)
"""The landmarks the crease lines are placed from."""


def _segment_distance(points: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance (m,) from points (m, 3) to the segment a-b (3,), and the parameter t (m,) in [0, 1]."""
    ab = b - a
    t = np.clip((points - a) @ ab / max(ab @ ab, 1e-30), 0.0, 1.0)
    return np.linalg.norm(points - (a + t[:, None] * ab), axis=1), t


def find_creases(
    vertices: np.ndarray,
    normals: np.ndarray,
    skin: np.ndarray,
    landmark: Callable[[str], np.ndarray],
    landmark_names: set[str],
    channel_names: set[str],
    scale: float,
    lips: np.ndarray | None = None,
) -> tuple[Crease, ...]:
    """The crease lines of a rest mesh (see the module docstring).

    Parameters
    ----------
    vertices, normals : (n, 3) float64
        The rest mesh (rig units) and its unit tissue normals (``anatomy.tissue_normals``).
    skin : (s,) int64
        The vertices a crease may move.
    landmark : callable(name) -> (3,)
        A landmark's rest position.
    landmark_names, channel_names : set of str
        The rig's landmarks and channels: creases whose landmarks or channels are missing are left out.
    scale : float
        The head height, rig units.
    lips : (l,) int64, optional
        The lips' vertices, which the nasolabial fold stays clear of.
    """
    if not set(NEEDED) <= landmark_names:
        return ()
    s = scale
    front = skin[vertices[skin, 2] > FRONT_Z_REL * s]
    out: list[Crease] = []

    def on_surface(x: float, y: float) -> np.ndarray:
        """The rest front-skin vertex nearest to (x, y) seen from the front."""
        return vertices[front[np.argmin((vertices[front, 0] - x) ** 2 + (vertices[front, 1] - y) ** 2)]]

    def add(
        name: str,
        gains: dict[str, float],
        a: np.ndarray,
        b: np.ndarray,
        width: float,
        depth: float,
        clear: np.ndarray | None = None,
    ):
        """One crease from ``a`` to ``b`` (3,); faded out near the points ``clear`` (k, 3)."""
        gains = {c: g for c, g in gains.items() if c in channel_names}
        if not gains:
            return
        reach = width * s * np.sqrt(-np.log(MIN_WEIGHT))  # the Gaussian is below MIN_WEIGHT beyond it
        near = skin[np.all(np.abs(vertices[skin] - 0.5 * (a + b)) <= 0.5 * np.abs(b - a) + reach, axis=1)]
        dist, t = _segment_distance(vertices[near], a, b)
        w = (
            np.exp(-((dist / (width * s)) ** 2))
            * np.sin(np.pi * (TAPER_MARGIN + (1 - 2 * TAPER_MARGIN) * t)) ** 0.5
        )
        if clear is not None:  # (1 − (1 − d/r)²)² within r of the nearest of the points
            d, _ = cKDTree(clear).query(vertices[near])
            x = np.clip(d / (NASOLABIAL_CLEAR_REL * s), 0.0, 1.0)
            w = w * (1.0 - (1.0 - x) ** 2) ** 2
        keep = w > MIN_WEIGHT
        ids = near[keep]
        out.append(Crease(name, gains, ids, -(depth * w[keep])[:, None] * normals[ids]))

    for side, sx in (("L", 1.0), ("R", -1.0)):
        brow = landmark(f"brow_mid_{side}")
        for k, height in enumerate(FOREHEAD_LINES_REL, 1):
            y = brow[1] + height * s
            for half, span in (("inner", FOREHEAD_INNER_X_REL), ("outer", FOREHEAD_OUTER_X_REL)):
                ends = [on_surface(sx * x * s, y) for x in span]
                add(
                    f"forehead_{half}_{k}_{side}",
                    {f"frontalis_{half}_{side}": 1.0},
                    *ends,
                    FOREHEAD_WIDTH_REL,
                    FOREHEAD_DEPTH_REL,
                )
        top = on_surface(sx * GLABELLA_TOP_X_REL * s, landmark("glabella")[1] + GLABELLA_RISE_REL * s)
        bottom = on_surface(sx * GLABELLA_X_REL * s, landmark("nasion")[1])
        add(
            f"glabella_{side}",
            {f"corrugator_{side}": 1.0},
            bottom,
            top,
            GLABELLA_WIDTH_REL,
            GLABELLA_DEPTH_REL,
        )
        corner = landmark(f"eye_outer_corner_{side}")
        for k in (-1, 0, 1):
            a = corner + s * np.array(
                [sx * CROWS_FEET_FROM_REL[0], k * CROWS_FEET_FROM_REL[1], CROWS_FEET_FROM_REL[2]]
            )
            b = corner + s * np.array(
                [sx * CROWS_FEET_TO_REL[0], k * CROWS_FEET_TO_REL[1], CROWS_FEET_TO_REL[2]]
            )
            gains = {f"orbicularis_oculi_outer_{side}": 1.0, f"orbicularis_oculi_{side}": 1.0}
            add(f"crows_feet_{k + 2}_{side}", gains, a, b, CROWS_FEET_WIDTH_REL, CROWS_FEET_DEPTH_REL)
        mouth_corner = landmark(f"mouth_corner_{side}")
        end = mouth_corner + s * np.array([sx * NASOLABIAL_END_REL[0], *NASOLABIAL_END_REL[1:]])
        gains = {f"{m}_{side}": 1.0 for m in ("zygomatic_major", "levator_labii_mid", "levator_labii_nasal")}
        add(
            f"nasolabial_{side}",
            gains,
            landmark(f"alar_base_{side}"),
            end,
            NASOLABIAL_WIDTH_REL,
            NASOLABIAL_DEPTH_REL,
            clear=vertices[lips] if lips is not None and len(lips) else mouth_corner[None],
        )
    nasion = landmark("nasion")
    half = np.array([NASION_HALF_LENGTH_REL * s, 0.0, 0.0])
    add("nasion", {"procerus": 1.0}, nasion - half, nasion + half, NASION_WIDTH_REL, NASION_DEPTH_REL)
    return tuple(out)
