"""Image landmarks (2D) lifted to 3D with the rig's depth, so the 3D solve can use them.

Per frame, a scaled orthographic camera ``x = s Π R X + t`` (Π keeps x and y) is fitted to the
seen landmarks against the rig's virtual markers at rest: the affine camera by linear least
squares, its 2 × 3 part projected to the nearest scaled pair of orthonormal rows (SVD). Each
landmark then gets the depth its rig marker has under that camera, ``s (R X)_z``. Images store +y
down; the lifted points are (x, −y, z), right-handed with +Y up and +Z toward the camera, in pixels.

Motion along the camera's axis is not observed: the lifted depth is the neutral rig's, so the
solve sees expressions only through their image-plane motion (a pucker's forward push is lost).
"""

from __future__ import annotations

import numpy as np

from mimetic.capture.trajectories import CaptureError, Trajectories

MIN_POINTS = 6
"""Landmarks a frame needs for its camera."""


def lift_landmarks(trajectories: Trajectories, rig_points: np.ndarray) -> Trajectories:
    """3D points (f, m, 3) in pixels for 2D ``trajectories`` whose points correspond, in order, to
    ``rig_points`` (m, 3) (the rig's virtual markers at rest, rig units). Frames with fewer than
    ``MIN_POINTS`` landmarks stay missing."""
    if trajectories.dims != 2:
        raise CaptureError(f"{trajectories.source}: lift_landmarks takes 2D landmarks; these are 3D")
    image = trajectories.positions * np.array([1.0, -1.0])  # (f, m, 2), +y up
    f, m, _ = image.shape
    seen = np.isfinite(image).all(axis=2)
    lifted = np.full((f, m, 3), np.nan)
    X = np.concatenate([rig_points, np.ones((m, 1))], axis=1)  # (m, 4)
    for t in np.flatnonzero(seen.sum(axis=1) >= MIN_POINTS):
        k = seen[t]
        affine, *_ = np.linalg.lstsq(X[k], image[t, k], rcond=None)  # (4, 2): x = X affine
        A = affine[:3].T  # (2, 3)
        u, sigma, vt = np.linalg.svd(A, full_matrices=False)
        scale = sigma.mean()
        rows = u @ vt  # (2, 3) orthonormal rows
        third = np.cross(rows[0], rows[1])
        depth = scale * rig_points @ third  # (m,)
        lifted[t, k, :2] = image[t, k]
        lifted[t, k, 2] = depth[k] - depth.mean()
    return Trajectories(
        trajectories.names, lifted, trajectories.fps, "px", trajectories.confidence, trajectories.source
    )
