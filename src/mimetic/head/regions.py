"""Named regions of the skin, as vertex sets known by construction.

Regions are defined on the default head of a resolution (ring structure, chart position and
height), so each region holds the same vertex indices for every parameter set. Paired regions
are exact mirror images. The lips, eyelids, brows, nose, cheeks, nasolabial folds and chin are
pairwise disjoint; the mouth corners belong to neither lip.
"""

from __future__ import annotations

import numpy as np

from mimetic.head.params import HeadParams
from mimetic.head.shape import Layout, default_skin_geometry
from mimetic.head.topology import EYE_CENTRE, HeadTopology

REGION_NAMES = (
    "upper_lip",
    "lower_lip",
    "eyelid_upper_L",
    "eyelid_upper_R",
    "eyelid_lower_L",
    "eyelid_lower_R",
    "brow_L",
    "brow_R",
    "forehead",
    "nose",
    "cheek_L",
    "cheek_R",
    "nasolabial_L",
    "nasolabial_R",
    "chin",
    "jaw_L",
    "jaw_R",
    "neck",
    "scalp",
)


def skin_regions(topo: HeadTopology) -> dict[str, np.ndarray]:
    """Region name -> sorted skin vertex indices (k,) int64."""
    params = HeadParams()
    L = Layout.of(params)
    geo = default_skin_geometry(topo)
    v, (X, Y) = geo.vertices, geo.chart.T
    n = topo.n_vertices
    u, t = topo.ring_uv[:, 0], topo.ring_uv[:, 1]
    front = topo.directions[:, 2] > 0.3
    is_mouth = np.zeros(n, bool)
    is_mouth[topo.mouth.index.ravel()] = True
    is_eye = np.zeros(n, bool)
    is_eye[topo.eye_L.index.ravel()] = True
    is_eye[topo.eye_R.index.ravel()] = True
    up = np.sin(t) > 1e-9
    down = np.sin(t) < -1e-9
    left = v[:, 0] > 1e-9
    masks: dict[str, np.ndarray] = {}

    masks["upper_lip"] = is_mouth & up & (u <= 1.5)
    masks["lower_lip"] = is_mouth & down & (u <= 1.5)
    lid = is_eye & (u <= 0.45)
    masks["eyelid_upper_L"] = lid & up & left
    masks["eyelid_lower_L"] = lid & down & left
    ex, ey = EYE_CENTRE
    brow = front & ((((np.abs(X) - ex) / 2.4) ** 2 + ((Y - ey - 1.8) / 0.7) ** 2) < 1) & ~lid
    masks["brow_L"] = brow & left
    masks["forehead"] = front & (Y > ey + 2.5) & (v[:, 1] < 9.0) & (np.abs(X) < 6.0)
    nose_w = np.interp(
        Y, [L.subnasale_y, L.tip_y, 0.9], [L.alar_half_width + 0.45, L.alar_half_width + 0.3, 0.9]
    )
    nose = front & (np.abs(X) < nose_w) & (Y > L.subnasale_y - 0.1) & (Y < 1.2) & ~is_mouth & ~is_eye
    masks["nose"] = nose
    # nasolabial band: within 0.8 of the fold line from the alar base to beside the mouth corner
    a = np.array([L.alar_half_width + 0.05, L.subnasale_y + 0.2])
    b = np.array([2.5 * L.mouth_scale[0] + 1.3, L.mouth_centre[1] - 1.4])
    d = b - a
    p = np.column_stack([np.abs(X), Y])
    s = np.clip((p - a) @ d / (d @ d), 0, 1)
    dist = np.linalg.norm(p - (a + s[:, None] * d), axis=1)
    lips = masks["upper_lip"] | masks["lower_lip"] | (is_mouth & (u <= 1.5))
    fold = front & (dist < 0.8) & ~lips & ~nose & ~is_eye
    masks["nasolabial_L"] = fold & left
    cheek = (
        front
        & (np.abs(X) < 6.5)
        & (Y < -1.3)
        & (Y > L.mouth_centre[1] + 0.5)
        & ~is_mouth
        & ~nose
        & ~fold
        & ~is_eye
    )
    cheek &= ~((np.abs(X) < a[0]) & (Y > a[1]))
    masks["cheek_L"] = cheek & left
    # the mouth's outer skin rings reach down onto the chin: they belong to it, not to the lips
    chin = front & (Y < L.mouth_centre[1] - 1.5) & (np.abs(X) < 2.6) & (v[:, 1] > -12.3) & ~lips & ~fold
    masks["chin"] = chin
    jaw = (v[:, 1] > -12.3) & (v[:, 1] < -4.0) & (v[:, 2] > -3.0) & ~front | (
        front & (Y < L.mouth_centre[1] + 0.5) & ~chin & ~is_mouth & ~fold & ~cheek & (v[:, 1] > -12.3)
    )
    masks["jaw_L"] = jaw & left & ~chin
    masks["neck"] = (v[:, 1] <= -12.3) & ~chin
    masks["scalp"] = ((v[:, 1] > 9.0) | ((v[:, 2] < -3.0) & (v[:, 1] > -6.0))) & ~masks["forehead"]

    out: dict[str, np.ndarray] = {}
    for name in REGION_NAMES:
        if name.endswith("_R"):
            ids = topo.mirror[np.nonzero(masks[name[:-2] + "_L"])[0]]
        else:
            ids = np.nonzero(masks[name])[0]
        ids = np.sort(ids).astype(np.int64)
        ids.setflags(write=False)
        out[name] = ids
    return out
