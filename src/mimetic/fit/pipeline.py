"""``rig_head``: a user's head mesh and its landmarks in, a ``Rig`` on the user's own vertices out.

The steps: check the mesh and its units; merge its unwelded seams (coincident vertices on open
borders, ``mesh.weld``: UV seams, an unwelded patch, a triangle soup), with a warning that says how
many; fit the reference to the welded mesh (conformation and similarity from the landmarks, a
winding check (a mirrored export has its faces turned inside out: they are turned back, with a
warning), then non-rigid registration, ``fit.reference``); report the fit and gate it
(``fit.report``); rebuild the rig recipe on the fitted reference (``rig.recipe.build_rig``);
transfer it to the welded vertices (``fit.transfer``) and move it back onto the user's own vertices
(``rig.weld.unweld_rig``: every copy of a merged vertex takes the same data). A mesh over
``fit.working.WORKING_THRESHOLD`` vertices (or any, with ``working_vertices``) is fitted and
transferred on a decimated working copy instead, after its checks, weld and winding, and the copy's
rig is carried to every one of its vertices (``fit.working``).
"""

from __future__ import annotations

import dataclasses
import logging
import os
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from mimetic.errors import LandmarkError, MeshError, MimeticWarning
from mimetic.fit.landmarks import Landmarks
from mimetic.fit.reference import ReferenceFit, fit_reference
from mimetic.fit.report import FitReport, fit_report
from mimetic.fit.transfer import transfer_rig
from mimetic.fit.working import carry_rig, working_copy, working_vertices_for
from mimetic.head.model import DEFAULT_RESOLUTION
from mimetic.mesh.model import Mesh
from mimetic.mesh.units import convert_units, detect_units
from mimetic.mesh.validate import MeshReport, validate_mesh
from mimetic.mesh.weld import SEAM_AREA_SHARE, Weld, find_weld
from mimetic.mesh.winding import winding_flips
from mimetic.rig.model import Rig
from mimetic.rig.recipe import build_rig
from mimetic.rig.weld import unweld_rig

log = logging.getLogger(__name__)

MAX_VERTICES = 2_000_000

Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class RigResult:
    """What ``rig_head`` made.

    Attributes
    ----------
    rig : Rig
        On the user's vertices (same order and count), in the user's units.
    report : FitReport
    fit : ReferenceFit
        The fitted reference (reference frame), for inspection and pictures.
    flipped : bool
        True when the user's faces wound inward and were turned (the rig's faces are turned too).
    welded : int
        How many of the user's vertices lay on another one along an open border (merged for the fit;
        the rig keeps every one of them, moving together): unwelded seams, and parts that meet.
    reversed_faces : int
        Faces that wound against their neighbours and were turned in the rig.
    working_vertices : int or None
        The working copy's vertex count when the rig was made on one and carried to every vertex
        (``fit.working``); None when every vertex was fitted directly.
    """

    rig: Rig
    report: FitReport
    fit: ReferenceFit
    flipped: bool
    welded: int = 0
    reversed_faces: int = 0
    working_vertices: int | None = None


def _checked_mesh(mesh: Mesh) -> tuple[Mesh, MeshReport]:
    if mesh.n_vertices > MAX_VERTICES:
        raise MeshError(
            f"the mesh has {mesh.n_vertices:,} vertices; rig_head takes at most {MAX_VERTICES:,}. "
            "Decimate it first (e.g. Blender's Decimate modifier or trimesh's simplify_quadric_decimation)."
        )
    report = validate_mesh(mesh)
    if report.errors:
        raise MeshError("the mesh cannot be rigged: " + "; ".join(report.errors))
    if mesh.units is None:
        units = report.detected_units or detect_units(mesh.vertices)
        warnings.warn(
            f"the mesh does not say its units; its size suggests {units!r} (pass units= to load_mesh "
            "or --units to say otherwise)",
            MimeticWarning,
            stacklevel=3,
        )
        mesh = Mesh(mesh.vertices, mesh.faces, parts=mesh.parts, colors=mesh.colors, units=units)
    return mesh, report


def rig_head(
    mesh: Mesh,
    landmarks: Landmarks,
    *,
    resolution: int = DEFAULT_RESOLUTION,
    force: bool = False,
    progress: Progress | None = None,
    metadata: dict | None = None,
    working_vertices: int | str | None = None,
) -> RigResult:
    """Rig ``mesh`` by fitting the reference head to it and transferring the reference's rig.

    Parameters
    ----------
    mesh : Mesh
        The user's head: any vertex count up to ``MAX_VERTICES``, any units (known or detected),
        any axis-aligned orientation, with or without eyeballs, teeth and a mouth cavity.
    landmarks : Landmarks
        At least 8 project landmarks on ``mesh`` (from ``read_landmarks`` or ``auto_landmarks``).
    resolution : int
        Skin vertex count of the reference head.
    force : bool
        Return the rig even when the report's gate rejects the mesh.
    progress : callable(step, done, total), optional
    metadata : dict, optional
        Extra provenance for ``Rig.metadata`` (e.g. the source file).
    working_vertices : int, "full" or None
        Rig a decimated copy of about this many vertices and carry the rig to every vertex
        (``fit.working``); None: ``WORKING_VERTICES`` for meshes over ``WORKING_THRESHOLD``
        vertices, every vertex directly otherwise; "full": every vertex directly.

    Raises
    ------
    MeshError
        The mesh is broken or too large, or (without ``force``) the fit says it is not a head.
    LandmarkError
        Too few, unknown or degenerate landmarks.
    """
    return _rig(mesh, landmarks, resolution, force, progress, metadata, working_vertices)


def _rig(
    mesh: Mesh,
    landmarks: Landmarks | None,
    resolution: int,
    force: bool,
    progress: Progress | None,
    metadata: dict | None,
    working_vertices: int | str | None,
) -> RigResult:
    """``rig_head``, with ``landmarks`` None found by MediaPipe on the mesh that is fitted (the
    working copy when there is one)."""
    mesh, checked = _checked_mesh(mesh)
    working = working_vertices_for(mesh.n_vertices, working_vertices)
    if landmarks is not None and len(landmarks.names) < 8:
        raise LandmarkError(f"got {len(landmarks.names)} landmarks; rigging needs at least 8")
    weld = find_weld(mesh)
    seams = checked.n_seam_vertices if weld.n_merged else 0
    if seams:
        warnings.warn(
            f"{seams:,} vertices lie on unwelded seams (UV seams, an unwelded patch or a triangle soup); "
            "they are welded for the fit and move together in every pose. Your vertex order and count "
            "are kept.",
            MimeticWarning,
            stacklevel=2,
        )
    faces = mesh.faces.copy()  # the user's faces as the rig will have them
    if weld.n_merged or checked.n_reversed_faces:
        reversed_faces = winding_flips(weld.mesh.vertices, weld.mesh.faces, min_share=SEAM_AREA_SHARE)
    else:  # validate_mesh found every piece consistent (with min_share 0, which turns more)
        reversed_faces = np.zeros(weld.mesh.n_faces, dtype=bool)
    if reversed_faces.any():
        warnings.warn(
            f"{int(reversed_faces.sum()):,} faces wind against their neighbours (a patch turned inside out, "
            "dark in renders); the rig uses them turned back",
            MimeticWarning,
            stacklevel=2,
        )
        weld = _turned(weld, reversed_faces)
        faces[weld.faces[reversed_faces]] = faces[weld.faces[reversed_faces], ::-1]
    if working is not None:
        return _rig_working(
            mesh, landmarks, weld, faces, reversed_faces, working, resolution, force, progress, metadata
        )
    if landmarks is None:
        landmarks = _found_landmarks(mesh, progress)
    points = landmarks.positions
    if landmarks.units is not None and landmarks.units != mesh.units:
        points = convert_units(points, landmarks.units, mesh.units)
    fit = fit_reference(
        weld.mesh,
        list(landmarks.names),
        points,
        landmark_weights=np.maximum(landmarks.confidence, 0.05),
        resolution=resolution,
        progress=progress,
    )
    flipped = fit.flipped
    if flipped:
        warnings.warn(
            "the mesh's faces wind clockwise seen from outside (normals point into the head, as after "
            "a mirroring export); the rig uses them turned the right way round",
            MimeticWarning,
            stacklevel=2,
        )
        weld = _turned(weld, np.ones(weld.mesh.n_faces, dtype=bool))
        faces = faces[:, ::-1]
    report = fit_report(fit, mesh.units)
    if not report.accepted and not force:
        raise MeshError(
            "this does not look like a head the reference can fit: "
            + "; ".join(report.reasons)
            + ". If you are sure, rig it anyway with force=True (CLI: --force)."
        )
    if progress is not None:
        progress("rig", 0, 1)
    reference_rig = build_rig(fit.head, anatomy=False)  # the transfer derives the user's own
    welded_rig = transfer_rig(
        reference_rig,
        weld.mesh,
        fit.conformation.to_model,
        openings=fit.openings,
        margins=fit.margins,
        metadata={
            "landmarks": landmarks.source,
            "fit": {
                "mean_pct": report.mean_pct,
                "max_pct": report.max_pct,
                "coverage": report.coverage,
                "accepted": report.accepted,
            },
            "params": report.params,
            "resolution": resolution,
            "flipped_winding": flipped,
            "welded_vertices": weld.n_merged,
            "reversed_faces": int(reversed_faces.sum()),
            **(metadata or {}),
        },
    )
    turn = welded_rig.source_rotation.T  # user frame -> rig frame, as transfer_rig turned the vertices
    user = dataclasses.replace(mesh, vertices=mesh.vertices @ turn.T, faces=faces)
    rig = unweld_rig(welded_rig, weld, user) if weld.n_merged else welded_rig
    if progress is not None:
        progress("rig", 1, 1)
    return RigResult(rig, report, fit, flipped, weld.n_merged, int(reversed_faces.sum()))


def rig_mesh(
    mesh: Mesh | str | os.PathLike[str],
    landmarks: Landmarks | str | os.PathLike[str] | None = None,
    *,
    units: str | None = None,
    resolution: int = DEFAULT_RESOLUTION,
    force: bool = False,
    progress: Progress | None = None,
    working_vertices: int | str | None = None,
) -> RigResult:
    """Rig a head in one call (what ``mimetic rig`` does): load, find or read landmarks, ``rig_head``.

    Parameters
    ----------
    mesh : Mesh or path
        The head, or a mesh file (.obj .ply .stl .glb .gltf .fbx) read with ``load_mesh(path, units=units)``.
    landmarks : Landmarks, path or None
        Landmarks; a landmark file (JSON or CSV, see ``read_landmarks``); or None to find them with
        MediaPipe on renders of the mesh, or of its working copy (``auto_landmarks``, the ``[track]``
        extra).
    units : {"mm", "cm", "dm", "m", "in"}, optional
        The file's units when it does not say (else guessed from its size, with a warning).
    resolution, force, progress, working_vertices
        As for ``rig_head``.

    Returns
    -------
    RigResult
        ``result.rig`` on the user's vertices; save it with ``mimetic.save_rig``.
    """
    from mimetic.fit.landmarks import read_landmarks
    from mimetic.mesh.io import load_mesh

    source = {}
    if not isinstance(mesh, Mesh):
        source = {"source": Path(mesh).name}
        mesh = load_mesh(mesh, units=units)
    if landmarks is not None and not isinstance(landmarks, Landmarks):
        landmarks = read_landmarks(landmarks, mesh_units=mesh.units)
    return _rig(mesh, landmarks, resolution, force, progress, source, working_vertices)


def _found_landmarks(mesh: Mesh, progress: Progress | None) -> Landmarks:
    """Landmarks found by MediaPipe on renders of ``mesh``."""
    from mimetic.fit.autolandmarks import auto_landmarks

    if progress is not None:
        progress("landmarks (MediaPipe)", 0, 1)
    landmarks = auto_landmarks(mesh)
    if progress is not None:
        progress("landmarks (MediaPipe)", 1, 1)
    return landmarks


def _rig_working(
    mesh: Mesh,
    landmarks: Landmarks | None,
    weld: Weld,
    faces: np.ndarray,
    reversed_faces: np.ndarray,
    working: int,
    resolution: int,
    force: bool,
    progress: Progress | None,
    metadata: dict | None,
) -> RigResult:
    """``rig_head`` through a working copy of about ``working`` vertices (``fit.working``): ``weld``
    merges ``mesh``'s seams (its faces already turned where ``reversed_faces``), ``faces`` are the
    user's faces as the rig will have them."""
    if progress is not None:
        progress(f"working copy ({working:,} vertices)", 0, 1)
    copy = working_copy(mesh, weld.mesh, weld.index, working)
    log.info("working copy: %d of %d vertices", copy.mesh.n_vertices, mesh.n_vertices)
    if progress is not None:
        progress(f"working copy ({working:,} vertices)", 1, 1)
    if landmarks is None:
        landmarks = _found_landmarks(copy.mesh, progress)
    proxy = _rig(copy.mesh, landmarks, resolution, force, progress, metadata, "full")
    if proxy.flipped:
        faces = faces[:, ::-1]
    turn = proxy.rig.source_rotation.T  # user frame -> rig frame
    user = dataclasses.replace(mesh, vertices=mesh.vertices @ turn.T, faces=faces)
    if progress is not None:
        progress("carry to every vertex", 0, 1)
    extra = {
        "working_vertices": copy.mesh.n_vertices,
        "welded_vertices": weld.n_merged,
        "reversed_faces": int(reversed_faces.sum()),
    }
    rig = carry_rig(proxy.rig, copy, user, metadata=extra)
    if progress is not None:
        progress("carry to every vertex", 1, 1)
    return RigResult(
        rig,
        proxy.report,
        proxy.fit,
        proxy.flipped,
        weld.n_merged,
        int(reversed_faces.sum()),
        copy.mesh.n_vertices,
    )


def _turned(weld: Weld, mask: np.ndarray) -> Weld:
    """``weld`` with the welded faces of ``mask`` (f,) bool wound the other way."""
    faces = weld.mesh.faces.copy()
    faces[mask] = faces[mask, ::-1]
    return dataclasses.replace(weld, mesh=dataclasses.replace(weld.mesh, faces=faces))
