"""An eyeball as the lids meet it: its own surface over the directions in front of its centre.

A closing lid slides over the eyeball, and the engines' sculptor keeps it outside (``Eyeball.sculpt``;
compiled for the engines as ``mimetic.engines.kernels.sculpt_lids``). An eyeball is a sphere with a
cornea bulging out of it in front, but not by one amount nor about the eye bone's axis: ICT's
corneas rise 9 % above the sclera's sphere (the built-in head's 5 %), their axis up to 7° off the
bone's. Held off the generic profile only, a closing lid's skin kept its thickness over a cornea
too low and passed through the real one: pupils showed through the middle of closed lids (ICT
identity s145 σ 3: 0.46-0.55 cm of eyeball seen from the front). So each eye's surface is read off
its own mesh where it stands out of the generic profile: its radius along each direction within
``REACH_RAD`` of the gaze, on a grid over the plane of ``θ (cos φ, sin φ)`` (θ the angle from the
gaze, φ about it), by the first hits of rays cast down onto the eye's faces mapped there with their
distance from the centre as height (``mimetic.mesh.openings.front_depth``).

The sculptor pushes a lid point radially out of the generic eyeball, as it always has, then forward
along the gaze out of the eye's own surface: a radial push over a cornea below the eye's equator
also lowers the point, which landed closed margins 0.01 cm past the lower lid on s118 σ 3 and, in
the closing weights solved with it, folded the lid's skin on s144 σ 2; forward, a lid rides out
over the cornea at the height it had in the eye's frame, and the closing weights, solved on the
generic eyeball (``mimetic.rig.anatomy.lids.closing_weights``), still land its margin.

Lengths are in rig units.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import map_coordinates

from mimetic.head.parts import eyeball_profile
from mimetic.mesh.openings import front_depth

__all__ = ["GRID_STEP_RAD", "MAX_REL", "REACH_RAD", "SAME_REL", "Eyeball"]

GRID_STEP_RAD = np.radians(2.5)
"""The grid's spacing in θ (rad): 0.07 cm on a 1.5 cm eyeball, finer than the cornea's rise."""
REACH_RAD = np.radians(45.0)
"""The eye's own surface is read this far from the gaze, the generic sphere beyond: the cornea (30°
across on ICT's eyes, its axis up to 7° off the eye bone's) lies within it; the corners' caruncle
and conjunctiva, which the eye part may hold, lie beyond (50-75° on ICT's)."""
FORWARD_STEPS = 3
"""Pushes forward out of the eye's own surface (``Eyeball.sculpt``): each lands on the surface in the
direction the last one left; three leave a point within a thousandth of the radius of it."""
FORWARD_TOL_REL = 1e-4
"""... and a point short of it by less than this × the radius (1.5 µm on a 1.5 cm eye) is left."""
SAME_REL = 1e-3
"""An eye standing out of the generic profile by no more than this × its radius anywhere is taken for
the generic one (the built-in head's, its facets cut under the profile it is sampled on)."""
MAX_REL = 1.25
"""Faces of the eye part with a vertex farther than this × the sphere's radius from the centre are
not eyeball (the part keeps pieces within ``mimetic.fit.parts.EYE_REACH``, 1.5); ICT's corneas reach
1.09-1.12."""


@dataclass(frozen=True, eq=False)
class Eyeball:
    """An eye's surface at rest, as radii over the directions in front of its centre.

    ``centre`` (3,); ``axes`` (3, 3) rows: side, up and gaze, unit; ``radius`` the sphere's (the eye
    bone's length); ``radii`` (k, k) the surface's distance from the centre × ``radius`` at
    ``θ (cos φ, sin φ)`` = (``grid[j]``, ``grid[i]``) for ``radii[i, j]``, ``grid`` (k,) rad, read
    within ``REACH_RAD`` of the gaze (the generic profile beyond), never below the generic profile;
    None: the generic profile everywhere (an eye without a mesh of its own); ``excess`` the most it
    stands out of the generic profile, × ``radius``.
    """

    centre: np.ndarray
    axes: np.ndarray
    radius: float
    grid: np.ndarray
    radii: np.ndarray | None
    excess: float = 0.0

    @classmethod
    def of(
        cls,
        centre: np.ndarray,
        gaze: np.ndarray,
        radius: float,
        vertices: np.ndarray | None = None,
        faces: np.ndarray | None = None,
    ) -> Eyeball:
        """The eyeball about ``centre`` (3,) looking along ``gaze`` (3,) with the sphere's ``radius``:
        the surface of ``faces`` (e, 3) of ``vertices`` (n, 3) where it stands out of the generic
        profile (``mimetic.head.parts.eyeball_profile``), that profile elsewhere and without them."""
        centre = np.asarray(centre, dtype=np.float64)
        gaze = np.asarray(gaze, dtype=np.float64) / np.linalg.norm(gaze)
        side = np.cross([0.0, 1.0, 0.0], gaze)
        if np.linalg.norm(side) < 1e-6:  # looking straight up or down
            side = np.cross(gaze, [0.0, 0.0, 1.0])
        side /= np.linalg.norm(side)
        axes = np.stack([side, np.cross(gaze, side), gaze])
        half = int(np.ceil(REACH_RAD / GRID_STEP_RAD)) + 1
        grid = GRID_STEP_RAD * np.arange(-half, half + 1)
        if faces is None or not len(faces):
            return cls(centre, axes, float(radius), grid, None)
        gx, gy = np.meshgrid(grid, grid)
        ids = np.unique(faces)
        mapped = np.zeros((len(vertices), 3))
        mapped[ids] = _plane(np.asarray(vertices, dtype=np.float64)[ids] - centre, axes) / [1.0, 1.0, radius]
        within = (mapped[faces, 2] <= MAX_REL).all(axis=1)
        # a face across the back pole would spread over the plane: only faces in front of it
        within &= (np.hypot(mapped[faces, 0], mapped[faces, 1]) < 0.9 * np.pi).all(axis=1)
        low, high = np.array([grid[0], grid[0]]), np.array([grid[-1], grid[-1]])
        seen = front_depth(mapped, faces[within], low, high, GRID_STEP_RAD).z[: len(grid), : len(grid)]
        generic = eyeball_profile(np.hypot(gx, gy))
        radii = np.fmax(generic, seen)  # NaN where no ray hits: the profile
        excess = float((radii - generic).max())
        if excess <= SAME_REL:
            return cls(centre, axes, float(radius), grid, None)
        return cls(centre, axes, float(radius), grid, radii, excess)

    def surface(
        self, points: np.ndarray, transform: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """Distances (k,) of ``points`` (k, 3) from the centre and the surface's distance (k,) in their
        directions, with the eye moved by ``transform`` (4, 4) (its bone's; None: at rest)."""
        dist, own, _ = self._surfaces(points, transform)
        return dist, own

    def rest_clearance(self, points: np.ndarray, clearance: float, thickness: float) -> np.ndarray:
        """How far (k, 2) the sculptor keeps each of the lid vertices ``points`` (k, 3) outside the
        generic eyeball (``mimetic.head.parts.eyeball_profile`` on the sphere) and outside the eye's
        own surface: its height over each at rest, up to ``thickness`` (a closing lid keeps its
        thickness over the cornea: over ICT's, its skin 2 mm above came down through a generic one),
        ``clearance`` added; over its own surface no more than at rest where it lies below it (a
        margin resting on the cornea a hair inside the eye's facets). Both -inf (left alone) for a
        vertex inside the sphere (``clearance`` added) at rest: a skirt tucked inside, or a lid sunk
        into the sphere, which the closing weights and the lid contact look after."""
        dist, own, sphere = self._surfaces(points)
        out = clearance + np.minimum(np.column_stack([dist - sphere, dist - own]) - clearance, thickness)
        out[dist < sphere + clearance] = -np.inf
        return out

    def sculpt(
        self, points: np.ndarray, clearance: float | np.ndarray, transform: np.ndarray | None = None
    ) -> np.ndarray:
        """The engines' eyelid sculptor: ``points`` (k, 3) pushed out of the eyeball (moved by
        ``transform``, as ``surface``) to ``clearance`` outside it, a float or (k, 2) as
        ``rest_clearance`` gives (-inf: left alone). Radially out of the generic eyeball first, then
        forward, along the gaze, out of the eye's own surface: a lid sliding over a cornea that stands
        out of the generic one rides out over it, neither higher nor lower in the eye's frame, so the
        closing weights, solved on the generic eyeball, still land its margin on the lower lid."""
        clearance = np.broadcast_to(np.asarray(clearance, dtype=np.float64), (len(points), 2))
        centre, turn = self._placed(transform)
        out = np.array(points, dtype=np.float64, copy=True)
        gaze = turn @ self.axes[2]
        d = out - centre
        dist = np.sqrt(np.einsum("ij,ij->i", d, d))
        theta = np.arccos(np.clip(d @ gaze / np.maximum(dist, 1e-300), -1.0, 1.0))
        sphere = self.radius * eyeball_profile(theta)
        limit = sphere + clearance[:, 0]
        inside = dist < limit
        scale = limit[inside] / np.maximum(dist[inside], 1e-300)
        out[inside] = centre + d[inside] * scale[:, None]
        if self.radii is None:
            return out
        # forward only where the eye's own surface could still hold a point: within its reach of the
        # gaze, nearer than the sphere's profile and the most the eye stands out of it
        dist = np.maximum(dist, limit)  # each point's direction is as it was
        reach = sphere + self.excess * self.radius + clearance[:, 1]
        ids = np.flatnonzero((theta <= REACH_RAD) & (dist < reach))
        for _ in range(FORWARD_STEPS):  # the limit depends on the direction, which the push turns
            plane = _plane((out[ids] - centre) @ turn, self.axes)
            limit = self.radius * self._own(plane) + clearance[ids, 1]
            short = plane[:, 2] < limit - FORWARD_TOL_REL * self.radius
            ids, limit, dist = ids[short], limit[short], plane[short, 2]
            if not len(ids):
                break
            along = (out[ids] - centre) @ gaze
            out[ids] += (-along + np.sqrt(np.maximum(along**2 - dist**2 + limit**2, 0.0)))[:, None] * gaze
        return out

    def _placed(self, transform: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
        """The centre (3,) and the rotation (3, 3) of the eye moved by ``transform`` (4, 4) or at rest."""
        if transform is None:
            return self.centre, np.eye(3)
        return transform[:3, :3] @ self.centre + transform[:3, 3], transform[:3, :3]

    def _surfaces(
        self, points: np.ndarray, transform: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Distances (k,) of ``points`` (k, 3) from the centre, the eye's own surface's and the generic
        eyeball's in their directions (k,), the eye moved by ``transform`` (4, 4) or at rest."""
        centre, turn = self._placed(transform)
        plane = _plane((points - centre) @ turn, self.axes)
        sphere = eyeball_profile(np.hypot(plane[:, 0], plane[:, 1]))
        return plane[:, 2], self.radius * self._own(plane), self.radius * sphere

    def _own(self, plane: np.ndarray) -> np.ndarray:
        """The eye's own surface × the radius (k,) at ``plane`` (k, 2+) (``_plane``'s first columns)."""
        theta = np.hypot(plane[:, 0], plane[:, 1])
        own = eyeball_profile(theta)
        near = theta <= REACH_RAD
        if self.radii is not None and near.any():
            index = (plane[near, :2][:, ::-1] - self.grid[0]) / GRID_STEP_RAD  # (row, column)
            own[near] = map_coordinates(self.radii, index.T, order=1, mode="nearest")
        return own


def _plane(offsets: np.ndarray, axes: np.ndarray) -> np.ndarray:
    """``offsets`` (k, 3) from an eye's centre in the plane of ``θ (cos φ, sin φ)`` (rad) with their
    length: (k, 3)."""
    local = offsets @ axes.T  # side, up, gaze
    dist = np.linalg.norm(local, axis=1)
    theta = np.arccos(np.clip(local[:, 2] / np.maximum(dist, 1e-300), -1.0, 1.0))
    across = np.hypot(local[:, 0], local[:, 1])
    scale = np.where(across > 1e-12, theta / np.maximum(across, 1e-300), 0.0)
    return np.column_stack([local[:, 0] * scale, local[:, 1] * scale, dist])
