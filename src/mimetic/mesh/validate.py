"""Check a mesh before rigging it: counts, topology problems, and what to do about them.

:func:`validate_mesh` never raises on a bad mesh; it returns a :class:`MeshReport` whose
``errors`` (the mesh cannot be used) and ``warnings`` (it can, but something looks wrong) each
say how to fix the problem. Everything is vectorised: a 100k-vertex head takes a few tens of
milliseconds.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from types import MappingProxyType
from typing import Any

import numpy as np

from mimetic.errors import MeshError
from mimetic.mesh.geometry import _boundary_counts, _edge_components, edges_with_counts
from mimetic.mesh.model import Mesh
from mimetic.mesh.units import PLAUSIBLE_EXTENT_M, units_for_extent
from mimetic.mesh.weld import coincident_groups, seam_vertices
from mimetic.mesh.winding import winding_flips

log = logging.getLogger(__name__)

MIN_FACES = 4
"""Fewer faces than this is an error: a closed surface needs at least four triangles."""

WHERE_CLUSTERS = 3
"""How many places a warning about seams or reversed faces names (the largest first)."""

WHERE_JOIN_REL = 0.05
"""Places a warning names are clusters of points chained within this fraction of the mesh's size."""

DEGENERATE_AREA_REL = 1e-12
"""A face is degenerate when twice its area is at most this times its longest edge squared."""


@dataclass(frozen=True)
class MeshReport:
    """What :func:`validate_mesh` found. Counts are over faces with in-range indices.

    Attributes
    ----------
    n_vertices, n_faces : int
    n_nonfinite_vertices : int
        Vertices with a NaN or infinite coordinate.
    n_out_of_range_faces : int
        Faces with a vertex index outside ``0..n_vertices-1`` (left out of all other counts).
    n_degenerate_faces : int
        Faces with a repeated vertex index or (numerically) zero area.
    n_duplicate_faces : int
        Faces beyond the first with the same set of three vertices (in any order).
    n_nonmanifold_edges : int
        Edges shared by more than two faces.
    n_boundary_loops : int
        Closed loops of boundary edges (edges with one face): 0 for a closed surface, 1 for a
        head open at the neck.
    n_boundary_chains : int
        Runs of boundary edges that do not close (only around non-manifold edges).
    n_components : int
        Connected pieces, joined through shared vertices; unused vertices are not counted.
    n_unused_vertices : int
        Vertices no face refers to.
    n_seam_vertices : int
        Vertices on unwelded seams: border edges that lie on other border edges of the same part
        (of the whole mesh, when it has no parts) without sharing their vertices, as UV seams, an
        unwelded patch or a triangle soup leave them, where the welded surface holds at least
        ``SEAM_AREA_SHARE`` of the area. Parts meeting along a border, and small pieces touching
        (eyelash cards at their roots), do not count. ``rig_head`` and the engines weld every
        coincident border (``mimetic.mesh.weld``).
    n_reversed_faces : int
        Faces wound against their neighbours (the smaller side of each piece): a patch turned
        inside out. ``rig_head`` turns them back (``mimetic.mesh.winding``).
    bbox_min, bbox_max : (3,) tuple of float, or None
        Bounding box of the finite vertices; None when there are none.
    extent : float or None
        Largest side of that box, in the mesh's units.
    units : str or None
        The mesh's declared units (``Mesh.units``).
    detected_units : str or None
        The unit that makes the mesh head-sized (see ``mimetic.mesh.units``); None if none does.
    part_faces : Mapping[str, int]
        Number of faces in each part.
    errors : tuple of str
        Problems that make the mesh unusable, each with how to fix it.
    warnings : tuple of str
        Problems worth fixing, each with how.
    """

    n_vertices: int
    n_faces: int
    n_nonfinite_vertices: int
    n_out_of_range_faces: int
    n_degenerate_faces: int
    n_duplicate_faces: int
    n_nonmanifold_edges: int
    n_boundary_loops: int
    n_boundary_chains: int
    n_components: int
    n_unused_vertices: int
    n_seam_vertices: int
    n_reversed_faces: int
    bbox_min: tuple[float, float, float] | None
    bbox_max: tuple[float, float, float] | None
    extent: float | None
    units: str | None
    detected_units: str | None
    part_faces: Mapping[str, int]
    errors: tuple[str, ...]
    warnings: tuple[str, ...]

    def __post_init__(self) -> None:
        object.__setattr__(self, "part_faces", MappingProxyType(dict(self.part_faces)))
        object.__setattr__(self, "errors", tuple(self.errors))
        object.__setattr__(self, "warnings", tuple(self.warnings))

    @property
    def ok(self) -> bool:
        """True when there are no errors (warnings allowed)."""
        return not self.errors

    def raise_for_errors(self, source: str | None = None) -> None:
        """Raise MeshError listing every error (prefixed by ``source``, e.g. a file name); else do nothing."""
        if self.errors:
            prefix = f"{source}: " if source else ""
            raise MeshError(prefix + "; ".join(self.errors))

    def as_dict(self) -> dict[str, Any]:
        """All fields as JSON-safe Python values (lists for tuples; None for missing or infinite numbers)."""

        def safe(x: float) -> float | None:
            return x if math.isfinite(x) else None

        out: dict[str, Any] = {f.name: getattr(self, f.name) for f in fields(self)}
        out["part_faces"] = dict(self.part_faces)
        for key in ("bbox_min", "bbox_max"):
            if out[key] is not None:
                out[key] = [safe(x) for x in out[key]]
        out["extent"] = None if self.extent is None else safe(self.extent)
        out["errors"], out["warnings"] = list(self.errors), list(self.warnings)
        out["ok"] = self.ok
        return out

    def lines(self) -> list[str]:
        """Human-readable summary for the CLI: one fact per line, then errors and warnings."""
        out = [
            f"vertices          {self.n_vertices:,}",
            f"faces             {self.n_faces:,}",
            f"components        {self.n_components:,} (connected pieces)",
            f"boundary loops    {self.n_boundary_loops:,}"
            + (f" (+{self.n_boundary_chains} open chains)" if self.n_boundary_chains else ""),
        ]
        if self.extent is not None and self.bbox_min is not None and self.bbox_max is not None:
            size = " x ".join(f"{hi - lo:.4g}" for lo, hi in zip(self.bbox_min, self.bbox_max, strict=True))
            out.append(f"size              {size} {self.units or '(units unknown)'}")
        out.append(f"units             {self.units or '-'} (size suggests {self.detected_units or 'none'})")
        if self.part_faces:
            out.append("parts (faces)     " + ", ".join(f"{k} {v:,}" for k, v in self.part_faces.items()))
        out += [f"error: {e}" for e in self.errors]
        out += [f"warning: {w}" for w in self.warnings]
        out.append("ok" if self.ok else f"not usable: {len(self.errors)} error(s)")
        return out


def validate_mesh(mesh: Mesh) -> MeshReport:
    """Count a mesh's problems and say how to fix them.

    Parameters
    ----------
    mesh : Mesh
        Any mesh, including one loaded with ``load_mesh(..., check=False)``: NaN coordinates,
        out-of-range face indices and empty meshes are reported, not raised.

    Returns
    -------
    report : MeshReport
    """
    v, f = mesh.vertices, mesh.faces  # (n, 3) float64, (m, 3) int64
    n, m = len(v), len(f)
    finite = np.isfinite(v).all(axis=1)  # (n,)
    all_finite = bool(finite.all())
    if m == 0 or (f.min() >= 0 and f.max() < n):  # the usual case: skip the (m, 3) mask
        in_range, fv = np.ones(m, dtype=bool), f
    else:
        in_range = ((f >= 0) & (f < n)).all(axis=1)  # (m,)
        fv = f[in_range]  # (k, 3) faces safe to index with

    # 1. Degenerate: a repeated index, or twice the area tiny against the longest edge squared.
    repeated = (fv[:, 0] == fv[:, 1]) | (fv[:, 1] == fv[:, 2]) | (fv[:, 0] == fv[:, 2])
    p0, p1, p2 = v[fv[:, 0]], v[fv[:, 1]], v[fv[:, 2]]  # (k, 3) each
    with np.errstate(invalid="ignore", over="ignore"):
        u, w = p1 - p0, p2 - p0
        double_area_sq = _norm_sq(
            np.stack(
                [
                    u[:, 1] * w[:, 2] - u[:, 2] * w[:, 1],
                    u[:, 2] * w[:, 0] - u[:, 0] * w[:, 2],
                    u[:, 0] * w[:, 1] - u[:, 1] * w[:, 0],
                ],
                axis=1,
            )
        )
        longest_sq = np.maximum(np.maximum(_norm_sq(u), _norm_sq(w)), _norm_sq(p2 - p1))
        flat = double_area_sq <= DEGENERATE_AREA_REL**2 * longest_sq**2  # False where NaN
    n_degenerate = int((repeated | flat).sum())

    # 2. Duplicates: same vertex set in any order.
    n_duplicate = len(fv) - _count_unique_rows(np.sort(fv, axis=1), n)

    # 3. Edges (computed once), boundary, components, unused vertices.
    edges, edge_counts = edges_with_counts(fv)
    n_nonmanifold = int((edge_counts > 2).sum())
    n_loops, n_chains = _boundary_counts(edges[edge_counts == 1])
    used = np.zeros(n, dtype=bool)
    used[fv.ravel()] = True
    _, labels = _edge_components(edges, n)
    n_components = int(np.bincount(labels[used], minlength=1).astype(bool).sum())

    # 4. Size and units.
    if finite.any():
        vf = v if all_finite else v[finite]
        lo, hi = vf.min(axis=0), vf.max(axis=0)
        bbox_min, bbox_max = tuple(map(float, lo)), tuple(map(float, hi))
        with np.errstate(over="ignore"):
            extent: float | None = float(np.max(hi - lo))  # = units.largest_extent(v)
    else:
        bbox_min = bbox_max = extent = None
    detected = units_for_extent(extent) if extent is not None else None
    part_faces = {name: len(ids) for name, ids in mesh.parts.items()}

    counts = dict(
        n_vertices=n,
        n_faces=m,
        n_nonfinite_vertices=int((~finite).sum()),
        n_out_of_range_faces=int((~in_range).sum()),
        n_degenerate_faces=n_degenerate,
        n_duplicate_faces=n_duplicate,
        n_nonmanifold_edges=n_nonmanifold,
        n_boundary_loops=n_loops,
        n_boundary_chains=n_chains,
        n_components=n_components,
        n_unused_vertices=int(n - used.sum()),
        n_seam_vertices=0,
        n_reversed_faces=0,
    )
    errors = _errors(mesh, counts)
    places: dict[str, str] = {}
    if not errors:  # seams and winding need finite coordinates and valid faces
        seam = seam_vertices(mesh)
        flips = winding_flips(v, f)
        counts["n_seam_vertices"] = len(seam)
        counts["n_reversed_faces"] = int(flips.sum())
        places["seam"] = _where(mesh, v[seam])
        places["reversed"] = _where(mesh, v[f[flips]].mean(axis=1), np.flatnonzero(flips))
    warnings = _warnings(mesh, counts, extent, detected, places)
    report = MeshReport(
        **counts,
        bbox_min=bbox_min,
        bbox_max=bbox_max,
        extent=extent,
        units=mesh.units,
        detected_units=detected,
        part_faces=part_faces,
        errors=tuple(errors),
        warnings=tuple(warnings),
    )
    log.debug("validated mesh: %s", counts)
    return report


def _norm_sq(x: np.ndarray) -> np.ndarray:
    """Squared length (k,) of each row of ``x`` (k, 3)."""
    return x[:, 0] ** 2 + x[:, 1] ** 2 + x[:, 2] ** 2


def _count_unique_rows(rows: np.ndarray, n: int) -> int:
    """Number of distinct rows of ``rows`` (k, 3) with entries in ``0..n-1``."""
    if len(rows) == 0:
        return 0
    if n**3 < 2**62:  # pack each row into one int64, then count by sorting (see geometry._unique_counts)
        keys = np.sort((rows[:, 0] * n + rows[:, 1]) * n + rows[:, 2])
    else:
        keys = np.sort(rows.view(np.dtype((np.void, rows.dtype.itemsize * 3))).ravel())
    return int(1 + (keys[1:] != keys[:-1]).sum())


def _errors(mesh: Mesh, c: dict[str, int]) -> list[str]:
    out = []
    n, m = c["n_vertices"], c["n_faces"]
    if n == 0 or m == 0:
        out.append(
            f"the mesh is empty ({n} vertices, {m} faces); export the head as a triangle surface "
            "with its faces"
        )
    elif m < MIN_FACES:
        out.append(
            f"only {m} faces; a head mesh needs at least {MIN_FACES}. Check that this is the right file"
        )
    if c["n_nonfinite_vertices"]:
        first = int(np.argmax(~np.isfinite(mesh.vertices).all(axis=1)))
        out.append(
            f"{c['n_nonfinite_vertices']} vertices have NaN or infinite coordinates (first: vertex {first}); "
            "fix or delete them in your modelling tool"
        )
    if c["n_out_of_range_faces"]:
        out.append(
            f"{c['n_out_of_range_faces']} faces refer to vertices that do not exist (indices must be "
            f"0..{n - 1}); the file is corrupt, re-export it"
        )
    for name, ids in mesh.parts.items():
        ids = np.asarray(ids)
        if len(ids) and (ids.min() < 0 or ids.max() >= m):
            out.append(
                f"part {name!r} refers to face {int(ids.max())} but the mesh has {m} faces; rebuild the parts"
            )
    return out


def _clusters(points: np.ndarray, join: float) -> np.ndarray:
    """Cluster labels (k,) int64 of ``points`` (k, 3): points chained within about ``join`` of each
    other share one.

    The points are first pooled into cubic cells of side ``join / 2`` (one centroid per occupied
    cell), and the centroids are chained within ``join``: memory grows with the occupied cells, not
    with the pairs of points (156,000 seam points of a triangle soup make tens of millions of pairs
    within 5 % of a head, a few thousand cells).
    """
    if len(points) == 0:
        return np.zeros(0, dtype=np.int64)
    cells = np.floor((points - points.min(axis=0)) / (0.5 * join)).astype(np.int64)  # (k, 3)
    _, cell_of, members = np.unique(cells, axis=0, return_inverse=True, return_counts=True)
    cell_of = cell_of.ravel()
    centres = np.zeros((len(members), 3))
    np.add.at(centres, cell_of, points)
    centres /= members[:, None]  # (c, 3)
    return coincident_groups(centres, np.arange(len(centres)), join)[cell_of]


def _where(mesh: Mesh, points: np.ndarray, faces: np.ndarray | None = None) -> str:
    """Where ``points`` (k, 3) are: the centres of their largest clusters (chained within
    ``WHERE_JOIN_REL`` of the mesh's size) with their counts, and the parts of ``faces`` (k,) when
    given and named."""
    if len(points) == 0:
        return ""
    size = float(np.linalg.norm(np.ptp(mesh.vertices, axis=0)))
    label = _clusters(points, WHERE_JOIN_REL * size)
    names, counts = np.unique(label, return_counts=True)
    places = []
    for k in np.argsort(-counts, kind="stable")[:WHERE_CLUSTERS]:
        centre = points[label == names[k]].mean(axis=0)
        centre = np.round(centre / (1e-3 * size)) * (1e-3 * size) + 0.0  # no -0, no 1e-15 noise
        places.append(f"{counts[k]:,} around ({', '.join(f'{x:.4g}' for x in centre)})")
    text = "; ".join(places) + ("; …" if len(names) > WHERE_CLUSTERS else "")
    if faces is not None and mesh.parts:
        inside = [name for name, ids in mesh.parts.items() if np.isin(faces, ids).any()]
        text += f" [{', '.join(inside)}]"
    return text


def _warnings(
    mesh: Mesh, c: dict[str, int], extent: float | None, detected: str | None, places: dict[str, str]
) -> list[str]:
    out = []
    if c["n_degenerate_faces"]:
        out.append(
            f"{c['n_degenerate_faces']} degenerate faces (zero area or a repeated vertex) have no normal and "
            "can upset fitting; delete them (Blender: Mesh > Clean Up > Degenerate Dissolve)"
        )
    if c["n_duplicate_faces"]:
        out.append(
            f"{c['n_duplicate_faces']} duplicate faces (same three vertices as another face); delete the "
            "copies (Blender: Select > Select All by Trait > Interior Faces, or Merge by Distance)"
        )
    if c["n_nonmanifold_edges"]:
        out.append(
            f"{c['n_nonmanifold_edges']} non-manifold edges (shared by more than two faces) confuse "
            "normals and boundaries; split or delete the extra faces (Blender: Select > Select All by Trait "
            "> Non Manifold)"
        )
    if c["n_boundary_chains"]:
        out.append(
            f"{c['n_boundary_chains']} boundary chains do not close into loops (around non-manifold edges); "
            "fix the non-manifold edges"
        )
    if c["n_seam_vertices"]:
        out.append(
            f"{c['n_seam_vertices']:,} vertices lie on unwelded seams (open borders on top of each other, as "
            f"UV seams, an unwelded patch or a triangle soup leave them): {places['seam']}. mimetic welds "
            "them for fitting and deformation and keeps your vertex order and count; to weld them in the "
            "file: Blender Mesh > Clean Up > Merge by Distance"
        )
    if c["n_reversed_faces"]:
        out.append(
            f"{c['n_reversed_faces']:,} faces wind against their neighbours (a patch turned inside out, "
            f"dark in renders): {places['reversed']}. mimetic rig turns them back; to fix the file: "
            "Blender Mesh > Normals > Recalculate Outside"
        )
    if c["n_unused_vertices"]:
        out.append(
            f"{c['n_unused_vertices']} vertices are used by no face and will not move with the rig; delete "
            "loose vertices (Blender: Mesh > Clean Up > Delete Loose)"
        )
    if extent is not None and detected is None:
        low, high = PLAUSIBLE_EXTENT_M
        out.append(
            f"the largest extent is {extent:.3g}, not a head size ({low * 100:.0f}-{high * 100:.0f} cm) "
            'in any unit; check the file, and give its units explicitly (units="cm", CLI --units cm)'
        )
    elif mesh.units is not None and detected is not None and detected != mesh.units:
        out.append(
            f"the mesh says its units are {mesh.units} but its size ({extent:.3g}) suggests {detected}; "
            f'if the size is right, load it with units="{detected}"'
        )
    return out
