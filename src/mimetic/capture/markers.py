"""Marker sets: named points on a rig's surface that correspond to captured points.

The performance-driven paper calls them virtual markers: for each real marker (or tracked
landmark), the point of the model it sits on. A ``MarkerSet`` holds them as surface points of the
rig's mesh, so they follow any deformation, plus two flags per marker:

* ``stable``: moves only with the skull (head markers on a band, the nose bridge, the inner eye
  corners); the head's rigid motion is fitted to these.
* ``sliding``: a contour point that slides along the surface (iBUG's jaw line, MediaPipe's lower
  face oval: a tracker puts it on the silhouette, not on one point of the skin); only its motion
  across the contour counts. ``tangents`` gives the contour's direction there.

Layouts (``marker_set(rig, layout)``):

* ``"paper"``: the paper's 24 markers: 16 on the moving face (brows, cheeks, nose wings, lips,
  chin) and 8 on the head (nasion, nose bridge, tragi, temples, forehead, crown).
* ``"ibug68"``: the 68 iBUG points (``ibug68_01`` … ``ibug68_68``, 1-based), from the rig's
  landmarks; the 17 jaw-line points slide.
* ``"mediapipe"``: FaceMesh's 468 face points (``mediapipe_<k>``), located on this rig by running
  FaceMesh on renders of it (extra ``[track]``); the lower face oval slides.
* a JSON file ``{"units": "cm", "markers": {"name": [x, y, z] | "landmark name", ...},
  "stable": [...], "sliding": [...], "layout": "ibug68", "placed": false}``: positions near the
  rig's neutral skin (snapped to it) or the names of rig landmarks; ``save_marker_set`` writes one
  (``placed`` true: the markers were placed on a performer and are not moved again).
"""

from __future__ import annotations

import json
import os
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp

from mimetic.atomic import atomic_write
from mimetic.capture.trajectories import CaptureError
from mimetic.head.landmarks import IBUG68
from mimetic.inputs import read_text
from mimetic.mesh.closest import closest_points
from mimetic.mesh.geometry import vertex_normals
from mimetic.mesh.model import SurfacePoint
from mimetic.mesh.units import UNIT_SCALE
from mimetic.rig.model import Rig

LAYOUTS = ("paper", "ibug68", "mediapipe")
SNAP_MAX_ANGLE_DEG = 75.0
"""A marker moved to a performer's stays on skin facing within this angle of the skin it was on."""

IBUG_STABLE = (1, 2, 3, 15, 16, 17, 28, 29, 30, 40, 43)
"""iBUG points (1-based) at the top of the jaw line (by the ears), on the nose bridge and at the inner
eye corners: candidates for the head-motion points (the solve keeps those the rig's muscles move
least, see ``capture.performance.stable_markers``)."""
IBUG_SLIDING = tuple(range(1, 18))
"""The jaw line (1-based): a tracker's contour, not a point of the skin."""

MEDIAPIPE_STABLE = (6, 8, 9, 10, 151, 168, 197, 195, 5, 4, 33, 133, 362, 263, 127, 356, 109, 338)
"""FaceMesh points on the forehead, nose bridge, eye corners and temples."""
MEDIAPIPE_SLIDING = (
    *(10, 338, 297, 332, 284, 251, 389, 356, 454, 323, 361, 288, 397, 365, 379, 378, 400, 377, 152),
    *(148, 176, 149, 150, 136, 172, 58, 132, 93, 234, 127, 162, 21, 54, 103, 67, 109),
)
"""The face's oval (``FACEMESH_FACE_OVAL``), round from the top of the forehead: the outline a tracker
sees, on skin with no features to hold it."""

PAPER_FACE = (
    "brow_inner_L",
    "brow_inner_R",
    "brow_outer_L",
    "brow_outer_R",
    "cheek_L",
    "cheek_R",
    "alare_L",
    "alare_R",
    "mouth_corner_L",
    "mouth_corner_R",
    "upper_lip_peak_L",
    "upper_lip_peak_R",
    "upper_lip_top",
    "lower_lip_mid_L",
    "lower_lip_mid_R",
    "pogonion",
)
PAPER_HEAD = (
    "nasion",
    "nose_bridge_upper",
    "tragion_L",
    "tragion_R",
    "temple_L",
    "temple_R",
    "forehead",
    "crown",
)


@dataclass(frozen=True, eq=False)
class MarkerSet:
    """Virtual markers on a rig.

    Attributes
    ----------
    names : tuple of str, (m,)
    points : tuple of SurfacePoint, (m,)
        On the rig's mesh (face index + barycentric weights).
    stable : (m,) bool
        Markers that move with the skull only (used for the head motion).
    sliding : (m,) bool
        Contour markers whose motion along ``tangents`` is ignored.
    tangents : (m, 3) float64
        Unit contour direction at the neutral for sliding markers; zero for the others.
    layout : str
        "paper", "ibug68", "mediapipe" or the file it was read from.
    placed : bool
        The markers were placed on one performer's neutral (``capture.calibrate``), so a solve
        keeps them where they are.
    """

    names: tuple[str, ...]
    points: tuple[SurfacePoint, ...]
    stable: np.ndarray
    sliding: np.ndarray
    tangents: np.ndarray
    layout: str
    placed: bool = False

    def __post_init__(self) -> None:
        m = len(self.names)
        if len(self.points) != m or len(set(self.names)) != m:
            raise CaptureError(f"marker set {self.layout!r}: names must be unique, one per point")
        for name in ("stable", "sliding", "tangents"):
            array = np.array(getattr(self, name))
            array.setflags(write=False)
            object.__setattr__(self, name, array)
        if self.stable.shape != (m,) or self.sliding.shape != (m,) or self.tangents.shape != (m, 3):
            raise CaptureError(
                f"marker set {self.layout!r}: stable, sliding (m,) and tangents (m, 3) expected"
            )

    @property
    def n_markers(self) -> int:
        return len(self.names)

    def positions(self, rig: Rig, vertices: np.ndarray | None = None) -> np.ndarray:
        """Marker positions (m, 3) on the rig at rest, or on ``vertices`` (n, 3) / (f, n, 3)."""
        v = rig.mesh.vertices if vertices is None else np.asarray(vertices, dtype=np.float64)
        if v.ndim == 2:
            return self.weights(rig) @ v
        f, n, _ = v.shape
        flat = self.weights(rig) @ v.transpose(1, 0, 2).reshape(n, 3 * f)  # (m, 3f)
        return flat.reshape(-1, f, 3).transpose(1, 0, 2)

    def weights(self, rig: Rig) -> sp.csr_matrix:
        """(m, n) sparse barycentric weights on the rig's vertices: ``weights @ vertices`` (n, 3)."""
        faces = rig.mesh.faces[[p.face for p in self.points]]  # (m, 3)
        bary = np.array([p.bary for p in self.points], dtype=np.float64)  # (m, 3)
        rows = np.repeat(np.arange(self.n_markers), 3)
        return sp.csr_matrix((bary.ravel(), (rows, faces.ravel())), shape=(self.n_markers, rig.n_vertices))

    def select(self, names: Sequence[str]) -> MarkerSet:
        """The named markers, in that order."""
        index = {n: j for j, n in enumerate(self.names)}
        missing = [n for n in names if n not in index]
        if missing:
            raise CaptureError(f"marker set {self.layout!r} has no marker(s) {', '.join(missing[:5])}")
        k = [index[n] for n in names]
        return self.replace(
            names=tuple(names),
            points=tuple(self.points[j] for j in k),
            stable=self.stable[k],
            sliding=self.sliding[k],
            tangents=self.tangents[k],
        )

    def replace(self, **changes) -> MarkerSet:
        """A copy with the named attributes changed (``dataclasses.replace``)."""
        return replace(self, **changes)


# --------------------------------------------------------------------------- building


class Snapped(NamedTuple):
    """Points put on a rig's skin: ``points`` (k SurfacePoints), their ``positions`` (k, 3) and
    ``distances`` (k,) from the queries, rig units."""

    points: tuple[SurfacePoint, ...]
    positions: np.ndarray
    distances: np.ndarray


def snap_to_skin(rig: Rig, positions: np.ndarray, normals: np.ndarray | None = None) -> Snapped:
    """The points of the rig's skin (or whole mesh) closest to ``positions`` (k, 3), rig units; with
    ``normals`` (k, 3) (unit), only on skin facing within ``SNAP_MAX_ANGLE_DEG`` of them, so a point at
    the lips' contact line stays on its own lip."""
    mesh = rig.mesh
    faces = mesh.parts["skin"] if "skin" in mesh.parts else np.arange(mesh.n_faces)
    min_cos = float(np.cos(np.radians(SNAP_MAX_ANGLE_DEG)))
    hit = closest_points(mesh.vertices, mesh.faces[faces], positions, query_normals=normals, min_cos=min_cos)
    lost = hit.faces < 0  # no skin faces that way near: the closest point at all
    if lost.any():
        anywhere = closest_points(mesh.vertices, mesh.faces[faces], positions[lost])
        for name in ("points", "faces", "bary", "distance"):
            getattr(hit, name)[lost] = getattr(anywhere, name)
    points = tuple(
        SurfacePoint(int(faces[f]), (float(b[0]), float(b[1]), float(b[2])))
        for f, b in zip(hit.faces, hit.bary, strict=True)
    )
    return Snapped(points, hit.points, hit.distance)


def marker_normals(markers: MarkerSet, rig: Rig) -> np.ndarray:
    """(m, 3) the rig's unit skin normal at each marker, at rest."""
    normals = markers.weights(rig) @ vertex_normals(rig.mesh.vertices, rig.mesh.faces)
    return normals / np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-300)


def _contour_chain(names: Sequence[str], sliding: np.ndarray) -> list[int]:
    """The sliding markers' indices in contour order: iBUG's jaw line by number, MediaPipe's face
    oval in ``MEDIAPIPE_SLIDING``'s order, otherwise the order of the set."""
    order = {f"ibug68_{k:02d}": i for i, k in enumerate(IBUG_SLIDING)}
    order.update({f"mediapipe_{k}": i for i, k in enumerate(MEDIAPIPE_SLIDING)})
    chain = [j for j in range(len(names)) if sliding[j]]
    if all(names[j] in order for j in chain):
        chain.sort(key=lambda j: order[names[j]])
    return chain


def with_tangents(markers: MarkerSet, rig: Rig) -> MarkerSet:
    """``markers`` with the contour tangents of its sliding markers at their positions on ``rig``
    (unit (m, 3); each the direction from the contour's previous marker to its next)."""
    positions = markers.positions(rig)
    chain = _contour_chain(markers.names, markers.sliding)
    tangents = np.zeros_like(positions)
    for k, j in enumerate(chain):
        direction = positions[chain[min(k + 1, len(chain) - 1)]] - positions[chain[max(k - 1, 0)]]
        tangents[j] = direction / max(np.linalg.norm(direction), 1e-300)
    return markers.replace(tangents=tangents)


def _paper(rig: Rig) -> MarkerSet:
    lm = {n: rig.landmark_positions([n])[0] for n in rig.landmarks}
    height = rig.scale
    up = np.array([0.0, 1.0, 0.0])
    derived = {}
    for side in "LR":
        derived[f"cheek_{side}"] = (lm[f"zygion_{side}"] + lm[f"mouth_corner_{side}"]) / 2
        derived[f"temple_{side}"] = (
            lm[f"tragion_{side}"] + lm[f"brow_outer_{side}"]
        ) / 2 + 0.08 * height * up
    derived["forehead"] = lm["nasion"] + 0.22 * height * up
    top = rig.mesh.vertices[int(np.argmax(rig.mesh.vertices[:, 1]))]
    derived["crown"] = top
    names = PAPER_FACE + PAPER_HEAD
    points = []
    for name in names:
        if name in derived:
            points.append(snap_to_skin(rig, derived[name][None]).points[0])
        else:
            points.append(rig.landmarks[name])
    m = len(names)
    stable = np.array([n in PAPER_HEAD for n in names])
    return MarkerSet(names, tuple(points), stable, np.zeros(m, bool), np.zeros((m, 3)), "paper")


def _ibug(rig: Rig) -> MarkerSet:
    names = tuple(f"ibug68_{k:02d}" for k in range(1, 69))
    missing = sorted({n for n in IBUG68 if n not in rig.landmarks})
    if missing:
        raise CaptureError(
            f"the rig lacks landmark(s) {', '.join(missing[:5])} of the iBUG-68 layout; rig it again "
            "with `mimetic rig` (which places them) or give a marker file"
        )
    points = tuple(rig.landmarks[n] for n in IBUG68)
    number = np.arange(1, 69)
    stable = np.isin(number, IBUG_STABLE)
    sliding = np.isin(number, IBUG_SLIDING)
    return with_tangents(MarkerSet(names, points, stable, sliding, np.zeros((68, 3)), "ibug68"), rig)


def _mediapipe(rig: Rig) -> MarkerSet:
    from mimetic.capture.video import mediapipe_markers

    names, points = mediapipe_markers(rig)
    number = np.array([int(n.split("_")[1]) for n in names])
    stable = np.isin(number, MEDIAPIPE_STABLE)
    sliding = np.isin(number, MEDIAPIPE_SLIDING)
    return with_tangents(
        MarkerSet(names, points, stable, sliding, np.zeros((len(names), 3)), "mediapipe"), rig
    )


def load_marker_set(path: str | os.PathLike[str], rig: Rig) -> MarkerSet:
    """A marker set from a JSON file (see the module docstring), placed on ``rig``."""
    path = Path(path)
    try:
        document = json.loads(read_text(path, CaptureError, "marker"))
    except json.JSONDecodeError as error:
        raise CaptureError(f"{path}: not a JSON marker file ({error})") from None
    if not isinstance(document, dict) or not isinstance(document.get("markers"), dict):
        raise CaptureError(f'{path}: expected {{"units": "cm", "markers": {{"name": [x, y, z], ...}}}}')
    factor = 1.0
    units = document.get("units")
    if units is not None:
        if units not in UNIT_SCALE or rig.units not in UNIT_SCALE:
            raise CaptureError(f"{path}: units {units!r} cannot be converted to the rig's {rig.units!r}")
        factor = UNIT_SCALE[units] / UNIT_SCALE[rig.units]
    names, points = [], []
    for name, value in document["markers"].items():
        if isinstance(value, str):
            if value not in rig.landmarks:
                raise CaptureError(f"{path}: marker {name!r} names landmark {value!r}, which the rig lacks")
            points.append(rig.landmarks[value])
        else:
            position = np.asarray(value, dtype=np.float64) * factor
            if position.shape != (3,) or not np.isfinite(position).all():
                raise CaptureError(
                    f"{path}: marker {name!r} must be [x, y, z] or a landmark name; got {value}"
                )
            points.append(snap_to_skin(rig, position[None]).points[0])
        names.append(str(name))
    flags = {}
    for key in ("stable", "sliding"):
        listed = document.get(key, [])
        unknown = [n for n in listed if n not in names]
        if unknown:
            raise CaptureError(f"{path}: {key} lists unknown marker(s) {', '.join(unknown[:5])}")
        flags[key] = np.isin(names, listed)
    marker_set = MarkerSet(
        tuple(names),
        tuple(points),
        flags["stable"],
        flags["sliding"],
        np.zeros((len(names), 3)),
        str(document.get("layout", path)),
        bool(document.get("placed", False)),
    )
    return with_tangents(marker_set, rig)


def save_marker_set(markers: MarkerSet, rig: Rig, path: str | os.PathLike[str], *, note: str = "") -> Path:
    """Write ``markers`` as a marker file (the JSON ``load_marker_set`` reads): each marker's position
    on ``rig`` at rest, in the rig's units, its flags, its layout, whether it was placed on a
    performer, and ``note`` (e.g. the take it was calibrated on). Written atomically."""
    positions = markers.positions(rig).round(6).tolist()
    document = {
        "units": rig.units,
        "layout": markers.layout,
        "placed": markers.placed,
        "note": note,
        "markers": dict(zip(markers.names, positions, strict=True)),
        "stable": [n for n, s in zip(markers.names, markers.stable, strict=True) if s],
        "sliding": [n for n, s in zip(markers.names, markers.sliding, strict=True) if s],
    }
    path = Path(path)
    with atomic_write(path, "w") as handle:
        handle.write(json.dumps(document, indent=1) + "\n")
    return path


def marker_set(rig: Rig, layout: str | os.PathLike[str]) -> MarkerSet:
    """The marker layout ``layout`` ("paper", "ibug68", "mediapipe" or a JSON file) on ``rig``."""
    if layout == "paper":
        return _paper(rig)
    if layout == "ibug68":
        return _ibug(rig)
    if layout == "mediapipe":
        return _mediapipe(rig)
    if Path(layout).suffix.lower() == ".json":
        return load_marker_set(layout, rig)
    raise CaptureError(f"unknown marker layout {layout!r}; use one of {', '.join(LAYOUTS)} or a .json file")


def layout_for(names: Sequence[str]) -> str:
    """The built-in layout whose names the captured points use ("ibug68", "mediapipe" or "paper")."""
    if all(n.startswith("ibug68_") for n in names):
        return "ibug68"
    if all(n.startswith("mediapipe_") for n in names):
        return "mediapipe"
    if set(names) & set(PAPER_FACE + PAPER_HEAD):
        return "paper"
    raise CaptureError(
        f"cannot tell which marker layout the points {', '.join(list(names)[:4])}, … follow; pass "
        "markers= (paper, ibug68, mediapipe or a JSON marker file naming each point on the rig)"
    )
