"""The deformation chain every engine runs after its muscles (``Chain``), with the lids' contact.

The chain follows the automated rigging thesis (§4.3.2): muscles -> skull -> creases and tissue
actions -> skinning -> lip and lid contacts -> eyelid sculptors, then the accessories riveted to the skin
(``attach``). The muscle stage is engine-specific; the rest is here. What the chain acts on (the
skull, the creases, the tissue actions, the lip and lid contacts, the accessories) is the rig's
anatomy (``Rig.anatomy``): the engines only read it. Creases and tissue actions are offsets linear
in their channels, added before skinning (so they ride the jaw and bake exactly).

**Lid contact** (``mimetic.rig.anatomy.lids``): the upper lid's contact vertices never pass below
the lower lid's margin, measured along the eye frame's up axis at each vertex's own position along
the lid (the frame turns with the head). Where a visible contact vertex would, its column of the
upper lid is opened back: each upper-lid vertex is skinned as if its lid bone had turned less by
``Δ(u)``, the largest over the crossing contacts of ``Δ_i`` fading linearly to 0 at
``LID_COLUMN_REACH`` margin steps along ``u``, where ``Δ_i`` (bisection) puts contact ``i`` on the
lower margin. The rigid lid plate thus stops as one piece, the skin above it follows by its
weight, and the lower lid stays where its own bone put it (the upper lid yields, as in a blink onto
a raised lower lid). After the sculptor, any contact vertex still below (a tucked skirt inside the
eyeball, a vertex the column missed) is turned about the lid's axis onto the margin by itself,
which keeps its distance from the eye's centre. A contact vertex that lies below the margin at
rest may stay that far below, so the rest pose is exact.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.interpolate import LinearNDInterpolator

from mimetic.engines.attach import ride
from mimetic.engines.kernels import (
    blend_skinning,
    bridged_margin,
    channel_offsets,
    least_opening,
    sculpt_lids,
    triangle_heights,
)
from mimetic.engines.muscles import LID_RIGID_WEIGHT
from mimetic.engines.skinning import IDENTITY, bone_transforms
from mimetic.head.parts import CORNEA_BULGE, IRIS_ANGLE
from mimetic.rig.anatomy.eyeball import FORWARD_STEPS, FORWARD_TOL_REL, GRID_STEP_RAD, REACH_RAD, Eyeball
from mimetic.rig.anatomy.lids import (
    LID_BRIDGE_REL,
    LID_CLEARANCE_REL,
    LID_COLUMN_REL,
    LID_CONTACT_GAP_REL,
    LID_THICKNESS_REL,
    eye_frame,
)
from mimetic.rig.model import Rig

SCULPTOR_MARGIN_REL = LID_CLEARANCE_REL  # lids stay this far outside the eyeball (0.005 cm on a 23 cm head)
LID_SCULPTED_WEIGHT = 0.05
"""Vertices a lid bone weights this much or more are sculpted with the lid regions."""
LID_COLUMN_REACH = 2.0
"""How far along the lid (in median steps of the lower margin) a contact opens the upper lid's column."""
LID_MAX_OPENING_RAD = 1.5
"""The most a contact turns the upper lid back (rad)."""
LID_SOLVE_STEPS = 8
"""Steps of the Illinois false-position search for a contact's opening angle (``_least_opening``)."""


@dataclass(frozen=True)
class EyeContact:
    """One eye's lid contact, prepared for the chain (rest values; see the module docstring)."""

    lid: int  # the upper-lid bone's index
    head: int  # the head bone's index (the eye frame turns with it)
    pivot: np.ndarray  # (3,) its head: the lid turns about it
    origin: np.ndarray  # (3,) the eye frame at rest (``mimetic.rig.anatomy.lids.eye_frame``)
    axes: np.ndarray  # (3, 3) rows u, v, w
    layers: tuple  # of (upper (k,), lower (j,), tucked, floor (k,) rig units, rest u (k,))
    followers: np.ndarray  # (f,) int64 vertices with an upper-lid weight
    follower_weight: np.ndarray  # (f,) their upper-lid weight
    follower_u: np.ndarray  # (f,) their rest u
    reach: float  # rig units along u: how far a contact opens the column
    bridge: float  # rig units along u: the widest dip of the lower margin the upper lid bridges
    column: float  # rig units along u: the widest chord it rests on whatever the margin's shape


def _turn_parts(d: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The angle-free parts (along, across, cross), each (k, 3), of Rodrigues' formula for vectors ``d``
    (k, 3) turned about the unit ``axis`` (3,): d turned by θ is along + across cos θ + cross sin θ."""
    along = np.outer(d @ axis, axis)
    across = d - along
    x, y, z = axis
    cross = np.column_stack([y * d[:, 2] - z * d[:, 1], z * d[:, 0] - x * d[:, 2], x * d[:, 1] - y * d[:, 0]])
    return along, across, cross


def _turner(d: np.ndarray, axis: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """``angle (k,) -> d turned by angle``: vectors ``d`` (k, 3) turned about the unit ``axis`` (3,) by
    Rodrigues' formula, its angle-free parts computed once (``_turn_parts``)."""
    along, across, cross = _turn_parts(d, axis)
    return lambda angle: along + across * np.cos(angle)[:, None] + cross * np.sin(angle)[:, None]


def _lower_line(points: np.ndarray, span: float, column: float) -> tuple[np.ndarray, np.ndarray, float]:
    """(u, v, step) of the line the upper lid closes onto (``mimetic.rig.anatomy.lids.lower_line``,
    compiled: ``kernels.bridged_margin``) for the lower margin (j, 3 in the eye frame). ``step`` is
    the median spacing along u (0 for fewer than two points)."""
    order = np.argsort(points[:, 0], kind="stable")
    u, v = points[order, 0], points[order, 1]
    step = _median(np.diff(u)) if len(u) > 1 else 0.0
    if len(u) < 3:
        return u, v, step
    # v_i = max(v_i, v_a + (u_i - u_a) (v_b - v_a) / (u_b - u_a)) over a < i < b with u_b - u_a <= column,
    # or <= span where v_i <= min(v_a, v_b)
    line = bridged_margin(u, v, span, column)
    # each end stands as high as the margin within a column of it: a canthus' wall (a stack of rim
    # vertices at one u) holds the lid's corner at its top, not beside its foot
    line[0] = max(line[0], v[: np.searchsorted(u, u[0] + column, side="right")].max())
    line[-1] = max(line[-1], v[np.searchsorted(u, u[-1] - column, side="left") :].max())
    return u, line, step


def _median(x: np.ndarray) -> float:
    """``float(np.median(x))`` for a non-empty (k,) array without NaN, without np.median's overhead
    (80 µs a call, a quarter of the lid contact's time)."""
    x = np.sort(x)
    middle = len(x) // 2
    return float(x[middle] if len(x) % 2 else (x[middle - 1] + x[middle]) / 2)


def _clearance(
    uvw: np.ndarray, line: tuple[np.ndarray, np.ndarray, float], *, beyond: bool = True
) -> np.ndarray:
    """How far each point (k, 3 in the eye frame) lies above the margin ``line`` (``_lower_line``) at
    its u. With ``beyond``, the line runs on level for one of its median steps past either end;
    farther out (or past the ends without ``beyond``) the clearance is +inf."""
    u, v, step = line
    step = step if beyond else 0.0
    within = (uvw[:, 0] >= u[0] - step) & (uvw[:, 0] <= u[-1] + step)
    return np.where(within, uvw[:, 1] - np.interp(uvw[:, 0], u, v), np.inf)


def prepare_lid_contacts(rig: Rig, weights: sp.csc_matrix | None = None) -> list[EyeContact]:
    """The rig's lid contacts (``Rig.anatomy.lids``), per eye, with what the chain needs at rest.

    ``weights``: the rig's skin weights as CSC, when the caller has them (converted otherwise)."""
    out = []
    v = rig.mesh.vertices
    weights = rig.skin_weights.tocsc() if weights is None else weights
    for side in ("L", "R"):
        layers_of = [c for c in rig.anatomy.lids if c.side == side]
        needed = ["head", f"eye_{side}", f"eyelid_upper_{side}"]
        corners = [f"eye_inner_corner_{side}", f"eye_outer_corner_{side}"]
        if (
            not layers_of
            or any(b not in rig.bone_names for b in needed)
            or any(c not in rig.landmarks for c in corners)
        ):
            continue
        eye = rig.bone(f"eye_{side}")
        inner, outer = rig.landmark_positions(corners)
        origin, axes, width = eye_frame(inner, outer, eye.tail - eye.head)
        lid = rig.bone_index(f"eyelid_upper_{side}")
        layers, steps = [], []
        for contact in layers_of:
            rest_upper = (v[contact.upper] - origin) @ axes.T
            line = _lower_line(
                (v[contact.lower] - origin) @ axes.T, LID_BRIDGE_REL * width, LID_COLUMN_REL * width
            )
            floor = np.minimum(_clearance(rest_upper, line), LID_CONTACT_GAP_REL * rig.scale)
            layers.append((contact.upper, contact.lower, contact.tucked, floor, rest_upper[:, 0]))
            if not contact.tucked and len(line[0]) > 1:
                steps.append(line[2])
        column = weights[:, lid].tocoo()
        order = np.argsort(column.row, kind="stable")
        rows, data = column.row[order].astype(np.int64), column.data[order]
        followers, follower_weight = rows[data > 0], data[data > 0]
        out.append(
            EyeContact(
                lid,
                rig.bone_index("head"),
                np.asarray(rig.bone(f"eyelid_upper_{side}").head, dtype=np.float64),
                origin,
                axes,
                tuple(layers),
                followers,
                follower_weight,
                (v[followers] - origin) @ axes[0],
                LID_COLUMN_REACH * (max(steps) if steps else 0.0),
                LID_BRIDGE_REL * width,
                LID_COLUMN_REL * width,
            )
        )
    return out


def keep_lids_apart(
    eye: EyeContact,
    skinned: np.ndarray,
    before: np.ndarray,
    transforms: np.ndarray,
    *,
    columns: bool,
) -> np.ndarray:
    """``skinned`` (n, 3) with eye's upper lid kept on or above its lower margin (module docstring).

    ``columns``: open the upper lid's columns (skinning with a smaller lid angle, from the pre-skinning
    positions ``before`` (n, 3)); otherwise turn each crossing contact vertex by itself.
    Returns a new array, or ``skinned`` itself when nothing crosses.
    """
    m, mh = transforms[eye.lid], transforms[eye.head]
    turn = m[:3, :3]
    axis = turn[:, 0]  # the lid's hinge: its bone turns about its own x axis
    pivot = m[:3, :3] @ eye.pivot + m[:3, 3]
    origin = mh[:3, :3] @ eye.origin + mh[:3, 3]
    axes = eye.axes @ mh[:3, :3].T  # the eye frame turns with the head

    def frame(points: np.ndarray) -> np.ndarray:
        return (points - origin) @ axes.T

    out = skinned
    opening = []  # per visible layer: (rest u of crossing contacts, their Δ)
    for upper, lower, tucked, least, rest_u in eye.layers:
        if tucked and columns:  # a skirt inside the eyeball does not hold the lid open
            continue
        if len(lower) < 2:
            continue
        low, high = frame(out[lower]), frame(out[upper])
        # the margin line never rises above its highest point (bridging takes chords between its points):
        # contacts that clear that point by their floor cannot cross, so an open eye builds no line
        if np.all(high[:, 1] - low[:, 1].max() > least + 1e-6 * eye.bridge):
            continue
        line = _lower_line(low, eye.bridge, eye.column)
        crossing = _clearance(high, line, beyond=not columns) < least
        if not crossing.any():
            continue
        ids = upper[crossing]
        floor = least[crossing]
        if columns:
            w = _upper_weight(eye, ids)
            rigid = w >= LID_RIGID_WEIGHT  # a contact the lid bone hardly moves cannot open its column
            ids, floor, at_u, w = ids[rigid], floor[rigid], rest_u[crossing][rigid], w[rigid]
            if len(ids) == 0:
                continue
            # turned back by δ, a contact sits at base - w R q + w (R q turned by -δ)
            arm = (before[ids] - eye.pivot) @ turn.T  # R q: the lid's full swing of each vertex
            parts = _turn_parts(arm, axis)
            start, scale = out[ids] - w[:, None] * arm, w
        else:  # turned back by δ, a contact sits at pivot + (p - pivot turned by -δ)
            parts = _turn_parts(out[ids] - pivot, axis)
            start, scale = np.tile(pivot, (len(ids), 1)), np.ones(len(ids))
        # the smallest δ that puts each contact on the margin (``_least_opening``), compiled
        reach = line[2] if not columns else 0.0
        hi = least_opening(
            start, scale, *parts, origin, axes, *line[:2], reach, floor, LID_MAX_OPENING_RAD, LID_SOLVE_STEPS
        )
        if columns:
            opening.append((at_u, hi))
        else:
            along, across, cross = parts
            out = out.copy() if out is skinned else out
            out[ids] = pivot + (along + across * np.cos(-hi)[:, None] + cross * np.sin(-hi)[:, None])
    if columns and opening:
        u = np.concatenate([o[0] for o in opening])
        delta = np.concatenate([o[1] for o in opening])
        reach = max(eye.reach, 1e-300)
        fade = np.clip(1.0 - np.abs(eye.follower_u[:, None] - u[None]) / reach, 0.0, None)  # (f, c)
        field = (fade * delta[None]).max(axis=1)
        moving = field > 0
        ids = eye.followers[moving]
        arm = (before[ids] - eye.pivot) @ turn.T
        out = out.copy()
        out[ids] += eye.follower_weight[moving, None] * (_turner(arm, axis)(-field[moving]) - arm)
    return out


def _least_opening(above: Callable[[np.ndarray], np.ndarray], k: int) -> np.ndarray:
    """The smallest turns δ (k,) in [0, LID_MAX_OPENING_RAD] rad with ``above(δ) >= 0``, from above
    (the reference for ``kernels.least_opening``, which ``keep_lids_apart`` calls).

    ``above`` (k,) -> (k,) rises with δ and is < 0 at 0 (+inf where a turned vertex leaves the margin's
    span). Illinois false position (the kept end's value halved when one end moves twice in a row),
    with a bisection step wherever an end is infinite: superlinear on the smooth clearance, so
    LID_SOLVE_STEPS steps land within about 1e-6 rad where 30 bisection steps did. Returns the upper
    end of each bracket, where ``above`` >= 0 (or LID_MAX_OPENING_RAD where it never is).
    """
    lo, hi = np.zeros(k), np.full(k, LID_MAX_OPENING_RAD)
    g_lo, g_hi = above(lo), above(hi)
    last = np.zeros(k, dtype=np.int8)  # +1: the upper end moved last, -1: the lower end
    for _ in range(LID_SOLVE_STEPS):
        finite = np.isfinite(g_lo) & np.isfinite(g_hi) & (g_hi > g_lo)
        with np.errstate(invalid="ignore", divide="ignore"):
            falsi = (lo * g_hi - hi * g_lo) / (g_hi - g_lo)
        x = np.where(finite, np.clip(falsi, lo, hi), 0.5 * (lo + hi))
        g = above(x)
        up = g >= 0
        g_lo = np.where(up & (last == 1), 0.5 * g_lo, g_lo)
        g_hi = np.where(~up & (last == -1), 0.5 * g_hi, g_hi)
        hi, g_hi = np.where(up, x, hi), np.where(up, g, g_hi)
        lo, g_lo = np.where(up, lo, x), np.where(up, g_lo, g)
        last = np.where(up, 1, -1).astype(np.int8)
    return hi


def _upper_weight(eye: EyeContact, ids: np.ndarray) -> np.ndarray:
    """The upper-lid weights (k,) of vertices ``ids`` (0 for vertices the lid bone does not move)."""
    at = np.searchsorted(eye.followers, ids)
    at = np.clip(at, 0, max(len(eye.followers) - 1, 0))
    found = len(eye.followers) > 0
    hit = found & (eye.followers[at] == ids) if found else np.zeros(len(ids), dtype=bool)
    return np.where(hit, eye.follower_weight[at] if found else 0.0, 0.0)


def _triangle_grid(tri) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A uniform grid over a 2-D triangulation's points (about one triangle a cell): per cell, the
    triangles whose bounding box meets it (``kernels.triangle_heights``): (cell_first (G + 1,),
    cell_triangles, (x0, y0, cell size, columns, rows))."""
    corners = tri.points[tri.simplices]  # (S, 3, 2)
    low, high = tri.points.min(axis=0), tri.points.max(axis=0)
    size = max(float(np.max(high - low)) / max(np.sqrt(len(tri.simplices)), 1.0), 1e-300)
    nx, ny = (np.floor((high - low) / size).astype(np.int64) + 1).tolist()
    first = np.floor((corners.min(axis=1) - low) / size).astype(np.int64)  # (S, 2)
    last = np.floor((corners.max(axis=1) - low) / size).astype(np.int64)
    cells, owners = [], []
    for s, ((i0, j0), (i1, j1)) in enumerate(zip(first, last, strict=True)):
        i, j = np.meshgrid(np.arange(i0, i1 + 1), np.arange(j0, j1 + 1))
        cells.append((j * nx + i).ravel())
        owners.append(np.full(i.size, s))
    cells, owners = np.concatenate(cells), np.concatenate(owners)
    order = np.lexsort((owners, cells))  # by cell, then triangle
    cell_first = np.searchsorted(cells[order], np.arange(nx * ny + 1))
    return cell_first, owners[order].astype(np.int64), np.array([*low, size, nx, ny], np.float64)


class Chain:
    """The stages after the muscles: skull push, creases, skinning, eyelid sculptors, accessories
    riveted to the skin (prepared once)."""

    def __init__(self, rig: Rig, *, skull: bool = True) -> None:
        self.rig = rig
        anatomy = rig.anatomy
        folds = anatomy.creases + anatomy.actions  # both are per-channel offsets
        rows, cols, vals = [], [], []
        for crease in folds:  # one row per channel: the summed crease and action offsets it drives
            offsets = (crease.offsets_rel * rig.scale).ravel()
            columns = (3 * crease.vertices[:, None] + np.arange(3)).ravel()
            for channel, gain in crease.gains.items():
                rows.append(np.full(len(columns), rig.channel_index(channel)))
                cols.append(columns)
                vals.append(gain * offsets)
        self.creases = sp.csr_matrix(
            (np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))) if vals else ([], ([], [])),
            shape=(len(rig.channels), 3 * rig.n_vertices),
        )
        self.weights = rig.skin_weights.tocsc()
        self.lip_pairs = anatomy.lip_contact
        self.skull_ids = anatomy.skull.vertices
        self.skull = None
        if skull and len(anatomy.skull):
            surface = anatomy.skull.surface
            self.skull = LinearNDInterpolator(surface[:, :2], surface[:, 2])
            self.skull_cells = _triangle_grid(self.skull.tri)
        v = rig.mesh.vertices
        self.lids = []
        for side in ("L", "R"):
            if f"eye_{side}" not in rig.bone_names:
                continue
            ids = [
                rig.regions.get(f"eyelid_{lid}_{side}", np.zeros(0, np.int64)) for lid in ("upper", "lower")
            ]
            for lid in ("upper", "lower"):  # and whatever the lid bones move (skin the lid stretches)
                if f"eyelid_{lid}_{side}" in rig.bone_names:
                    column = self.weights[:, rig.bone_index(f"eyelid_{lid}_{side}")]
                    ids.append(column.indices[column.data >= LID_SCULPTED_WEIGHT])
            ids = np.unique(np.concatenate(ids)).astype(np.int64)
            bone = rig.bone(f"eye_{side}")
            part = rig.mesh.parts.get(f"eye_{side}", np.zeros(0, np.int64))
            radius = float(np.linalg.norm(bone.tail - bone.head))
            eye = Eyeball.of(bone.head, bone.tail - bone.head, radius, v, rig.mesh.faces[part])
            # each lid vertex keeps its rest height over the eyeball, up to LID_THICKNESS_REL (the
            # conjunctiva skirt tucked inside is left alone)
            keep = eye.rest_clearance(v[ids], SCULPTOR_MARGIN_REL * rig.scale, LID_THICKNESS_REL * rig.scale)
            sculpted = np.isfinite(keep[:, 0])
            radii = np.zeros((0, 0)) if eye.radii is None else eye.radii
            index = rig.bone_index(f"eye_{side}")
            self.lids.append((ids[sculpted], index, eye, np.ascontiguousarray(keep[sculpted]), radii))
        self.accessories = anatomy.accessories
        self.lid_contacts = prepare_lid_contacts(rig, self.weights)

    def _skull_height(self, points: np.ndarray) -> np.ndarray:
        """The skull surface's height (k,) under ``points`` (k, 3), NaN outside it: the interpolator's
        value, found through a grid of its triangles (``kernels.triangle_heights``: its search walked
        the triangulation point by point, 63 of its 90 us); points no triangle of their cell holds
        (outside, or on an edge within rounding) go to the interpolator itself."""
        tri = self.skull.tri
        first, triangles, grid = self.skull_cells
        xy = np.ascontiguousarray(points[:, :2])
        z = triangle_heights(
            xy, tri.transform, tri.simplices, self.skull.values[:, 0], first, triangles, grid
        )
        missed = np.isnan(z)
        if missed.any():
            z[missed] = self.skull(xy[missed])
        return z

    def apply(self, deformed: np.ndarray, values: np.ndarray) -> np.ndarray:
        """Skull push (+Z onto the rest forehead), creases and tissue actions, skinning, lip contact,
        lid contact, lid sculptors, then the accessories (eyelashes and the like) placed on the skin
        they ride. The lips' contact comes after skinning, on the positions a viewer sees: a pair the
        muscles left one behind the other moves apart in height too as the jaw turns it, so a pair
        pressed together before skinning could still cross after it.

        ``deformed`` (n, 3) is the rest skin moved by the muscles; returns (n, 3).
        """
        v = deformed.copy()
        if self.skull is not None:
            p = v[self.skull_ids]
            z = self._skull_height(p)
            behind = np.isfinite(z) & (p[:, 2] < z - 1e-9 * self.rig.scale)
            v[self.skull_ids[behind], 2] = z[behind]
        if self.creases.nnz:  # creases.T @ values, over the channels that are not 0
            c = self.creases
            v += channel_offsets(c.indptr, c.indices, c.data, values, c.shape[1]).reshape(-1, 3)
        transforms = bone_transforms(self.rig, values)
        before = v
        # linear_blend_skinning, compiled
        moving = np.flatnonzero((transforms != IDENTITY).any(axis=(1, 2)))  # bones that are not at rest
        w = self.weights
        v = blend_skinning(v, w.indptr, w.indices, w.data, transforms, moving)
        if len(self.lip_pairs):  # lips meet but never cross: a crossed pair is pressed together
            upper, lower = v[self.lip_pairs[:, 0]], v[self.lip_pairs[:, 1]]
            crossed = upper[:, 1] < lower[:, 1]
            mid = 0.5 * (upper[crossed, 1] + lower[crossed, 1])
            v[self.lip_pairs[crossed, 0], 1] = mid
            v[self.lip_pairs[crossed, 1], 1] = mid
        for eye in self.lid_contacts:  # the upper lid's columns stop on the lower margin
            v = keep_lids_apart(eye, v, before, transforms, columns=True)
        for ids, bone, eye, keep, radii in self.lids:
            # sculptor: lids never inside the eyeball (its own surface, the cornea included), and no
            # thinner over it than at rest (skinning's blend shortens a turning lid's radius);
            # ``Eyeball.sculpt``, compiled
            m = transforms[bone]
            turn = np.ascontiguousarray(m[:3, :3])
            centre = turn @ eye.centre + m[:3, 3]
            sculpt_lids(
                v, ids, centre, turn, eye.axes, eye.radius, keep, radii, eye.grid[0], GRID_STEP_RAD,
                REACH_RAD, eye.excess, IRIS_ANGLE, CORNEA_BULGE, FORWARD_STEPS, FORWARD_TOL_REL,
            )  # fmt: skip
        for eye in self.lid_contacts:  # then every contact vertex by itself (and the tucked skirt)
            v = keep_lids_apart(eye, v, before, transforms, columns=False)
        return ride(self.accessories, self.rig.mesh.vertices, v, transforms) if len(self.accessories) else v
