"""Case builders shared by the tests and the benchmarks (STYLE §10).

Every builder is deterministic and returns immutable objects, so the expensive ones are cached
and the same instance may be handed to many tests or benchmark cases:

* ``tetrahedron()``, ``unit_square()``: tiny meshes with known answers;
* ``small_head(seed)``, ``random_heads(n)``, ``head_with(params)``: generated heads at a low
  resolution (2,500 skin vertices, about 4,200 vertices in all), built once per process;
* ``range_end_params()``: each conformation parameter at either end of its range;
* ``small_rig(seed)``: the recipe's rig of ``small_head(seed)``;
* ``capped_skin(head)``: the head's skin with its eye and mouth openings closed, for
  inside/outside tests;
* ``unwelded_patch(mesh, centre)``, ``triangle_soup(mesh)``, ``patch_faces(mesh, centre, r)``,
  ``cheek_centre(head)``: messy versions of a clean mesh, as real exports leave them;
* ``head_landmarks(head)``: a generated head's landmarks as a user's file gives them;
* ``shared_data_dir()``, ``require_shared_data(path)``, ``load_ict(folder)``,
  ``ict_landmarks(mesh, meta)``: the real data beside the repository (``../shared/data``, or
  ``$MIMETIC_SHARED_DATA``), for tests, benchmarks and ``examples/``; ``require_extra(module,
  extra)``: an optional dependency (a test skips without it, except on CI);
* ``run_cli(*args)``: the ``mimetic`` command in this process;
* ``cluster.loopback_cluster(folder)``: a Dask scheduler and workers as processes of their own on
  127.0.0.1, as on several machines (needs the ``[batch]`` extra).

This module imports the test-free parts of mimetic only; nothing in the package (the library,
its CLI or ``mimetic demo``) imports it.
"""

from __future__ import annotations

import json
import os
from functools import lru_cache
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from mimetic.head.model import Head, make_head
from mimetic.head.params import PARAM_RANGES, HeadParams
from mimetic.mesh.geometry import boundary_loops
from mimetic.mesh.model import Mesh
from mimetic.rig.model import Rig

if TYPE_CHECKING:
    from mimetic.fit.landmarks import Landmarks

SMALL_RESOLUTION = 2_500
"""Requested skin vertex count of the small heads: about 0.25 s to build, 2,580 skin vertices."""

RANDOM_SEEDS = tuple(range(20))
"""Seeds of the random heads that the head and rig tests check (``small_head(seed)``)."""

TETRAHEDRON_VERTICES = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
TETRAHEDRON_FACES = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])  # outward, counter-clockwise

UNIT_SQUARE_VERTICES = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]])
UNIT_SQUARE_FACES = np.array([[0, 1, 2], [0, 2, 3]])  # counter-clockwise seen from +Z


def tetrahedron() -> Mesh:
    """Closed unit right-corner tetrahedron: 4 vertices, 4 outward faces, volume 1/6, no parts or units."""
    return Mesh(TETRAHEDRON_VERTICES, TETRAHEDRON_FACES)


def unit_square() -> Mesh:
    """Open unit square in z = 0: 4 vertices, 2 triangles facing +Z, one boundary loop 0-1-2-3."""
    return Mesh(UNIT_SQUARE_VERTICES, UNIT_SQUARE_FACES)


@lru_cache(maxsize=128)
def head_with(params: HeadParams | None = None, resolution: int = SMALL_RESOLUTION) -> Head:
    """``make_head(params, resolution)``, built once per process (``None``: the default head)."""
    return make_head(params, resolution=resolution)


@lru_cache(maxsize=64)
def small_head(seed: int | None = None, resolution: int = SMALL_RESOLUTION) -> Head:
    """A generated head at a low resolution, built once per process.

    Parameters
    ----------
    seed : int, optional
        None gives the default head (``HeadParams()``, not a random draw); an integer gives
        ``HeadParams.random(seed)``.
    resolution : int
        Requested skin vertex count (see ``make_head``).

    Returns
    -------
    head : Head
        Heads made at the same resolution correspond vertex by vertex.
    """
    params = None if seed is None else HeadParams.random(seed)
    return head_with(params, resolution)


def random_heads(n: int, resolution: int = SMALL_RESOLUTION) -> tuple[Head, ...]:
    """The heads of ``HeadParams.random(seed)`` for seeds ``0 .. n-1`` (cached, see ``small_head``)."""
    return tuple(small_head(seed, resolution) for seed in range(n))


def range_end_params() -> dict[str, HeadParams]:
    """Each conformation parameter at its minimum and at its maximum, the others at their defaults.

    Returns
    -------
    cases : dict
        ``"nose_length=0.85"`` → ``HeadParams(nose_length=0.85)``, two entries per parameter, in
        the order of ``PARAM_RANGES``.
    """
    cases = {}
    for name, (low, high, _) in PARAM_RANGES.items():
        for value in (low, high):
            cases[f"{name}={value:g}"] = HeadParams().with_values(**{name: value})
    return cases


@lru_cache(maxsize=16)
def small_rig(seed: int | None = None, resolution: int = SMALL_RESOLUTION) -> Rig:
    """``build_rig(small_head(seed, resolution))``, built once per process."""
    from mimetic.rig.recipe import build_rig

    return build_rig(small_head(seed, resolution))


def capped_skin(head: Head) -> Mesh:
    """The skin of ``head`` as a closed surface: each boundary loop capped by a fan to its centroid.

    The generated skin has three openings (the eyes and the mouth). Each becomes a fan of
    triangles around one new vertex at the centroid of its boundary loop, oriented like the
    skin, so the result is watertight with outward normals (positive signed volume).

    Returns
    -------
    mesh : Mesh
        Vertices ``(n_skin + loops, 3)`` float64: the skin's, then one centroid per loop; faces
        ``(m, 3)`` int64: the skin's, then the caps. No parts, colours or units.
    """
    skin, _ = head.mesh.submesh("skin")
    vertices, faces = [skin.vertices], [skin.faces]
    n = skin.n_vertices
    for loop in boundary_loops(skin.faces):  # loop follows its faces' edges
        vertices.append(skin.vertices[loop].mean(axis=0, keepdims=True))
        # the cap walks each boundary edge (a, b) backwards: triangle (b, a, centre)
        faces.append(np.column_stack([np.roll(loop, -1), loop, np.full(len(loop), n)]))
        n += 1
    return Mesh(np.concatenate(vertices), np.concatenate(faces))


def head_landmarks(
    head: Head, units: str = "cm", scale: float = 1.0, turn: np.ndarray | None = None
) -> Landmarks:
    """The landmarks a user would click on a generated head (no pupils, jaw contour or menton), as a
    ``Landmarks`` file would give them: positions times ``scale``, turned by ``turn`` (3, 3)."""
    from mimetic.fit.landmarks import Landmarks

    names = tuple(n for n in head.landmarks if not n.startswith(("pupil", "jaw_")) and n != "menton")
    points = scale * head.landmark_positions(list(names))
    if turn is not None:
        points = points @ np.asarray(turn).T
    return Landmarks(names, points, np.ones(len(names)), units, "generated head")


def cheek_centre(head: Head) -> np.ndarray:
    """The centre (3,) of the head's left cheek region, in its units: where the messy-mesh cases cut."""
    return head.mesh.vertices[head.regions["cheek_L"]].mean(axis=0)


def patch_faces(mesh: Mesh, centre: np.ndarray, radius: float) -> np.ndarray:
    """Sorted skin faces (k,) whose centroids lie within ``radius`` of ``centre`` (3,)."""
    faces = mesh.parts["skin"] if "skin" in mesh.parts else np.arange(mesh.n_faces)
    centroids = mesh.vertices[mesh.faces[faces]].mean(axis=1)
    return np.sort(faces[np.linalg.norm(centroids - centre, axis=1) < radius])


def unwelded_patch(mesh: Mesh, centre: np.ndarray, radius: float = 2.0) -> Mesh:
    """``mesh`` with a patch of skin around ``centre`` cut loose: the patch's faces take their own copies
    of the vertices on its border (appended after the mesh's vertices), so the border is an unwelded
    seam, as an export that splits a UV island leaves it. Vertex order before the copies is kept."""
    patch = patch_faces(mesh, centre, radius)
    inside = np.zeros(mesh.n_faces, dtype=bool)
    inside[patch] = True
    border = np.intersect1d(np.unique(mesh.faces[patch]), np.unique(mesh.faces[~inside]))
    copy = np.full(mesh.n_vertices, -1)
    copy[border] = mesh.n_vertices + np.arange(len(border))
    faces = mesh.faces.copy()
    cut = faces[patch]
    faces[patch] = np.where(copy[cut] >= 0, copy[cut], cut)
    colors = None if mesh.colors is None else np.concatenate([mesh.colors, mesh.colors[border]])
    vertices = np.concatenate([mesh.vertices, mesh.vertices[border]])
    return Mesh(vertices, faces, mesh.parts, colors, mesh.units)


def triangle_soup(mesh: Mesh) -> Mesh:
    """Every face of ``mesh`` with three vertices of its own (3m vertices, face k uses 3k..3k+2), as some
    exporters write STL; parts kept by face."""
    vertices = mesh.vertices[mesh.faces.ravel()]
    colors = None if mesh.colors is None else mesh.colors[mesh.faces.ravel()]
    return Mesh(vertices, np.arange(len(vertices)).reshape(-1, 3), mesh.parts, colors, mesh.units)


def ibug_outline(head: Head, samples: int = 17, seed: int = 0) -> np.ndarray:
    """An iBUG-like outline (samples, 3) on ``head``'s skin: its frontal silhouette from eye level on
    the subject's right, round the chin, to eye level on the left, at equal arc length (outermost of
    300,000 surface samples along rays from the centre at eye level), as a 68-point detector's jaw
    points lie. (The head's own jaw_* points lie on the same silhouette, at fixed angles from a lower
    centre.)"""
    import trimesh

    skin = trimesh.Trimesh(head.mesh.vertices, head.mesh.faces[head.mesh.parts["skin"]], process=False)
    dense, _ = trimesh.sample.sample_surface(skin, 300_000, seed=seed)
    eye_y = head.landmark_positions(["eye_outer_corner_L"])[0, 1]
    chin_y = head.landmark_positions(["menton"])[0, 1]
    front = dense[(dense[:, 2] > -1.0) & (dense[:, 1] <= eye_y) & (dense[:, 1] >= chin_y)]
    rel = front[:, :2] - [0.0, eye_y]
    angle, radius = np.arctan2(rel[:, 1], rel[:, 0]), np.linalg.norm(rel, axis=1)
    silhouette = []
    for a in np.linspace(-np.pi, 0.0, 361):  # outermost sample along each ray, right to left
        band = np.abs(np.angle(np.exp(1j * (angle - a)))) < 0.005
        silhouette.append(front[band][np.argmax(radius[band])])
    silhouette = np.array(silhouette)
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(silhouette[:, :2], axis=0), axis=1))])
    return silhouette[np.searchsorted(arc, np.linspace(0.0, arc[-1], samples)).clip(0, len(silhouette) - 1)]


SHARED_DATA_ENV = "MIMETIC_SHARED_DATA"
ICT_IBUG_USED = tuple(i for i in range(17, 68) if i not in (60, 64))
"""The iBUG-68 landmarks of ICT-FaceKit's file that fits use: no jaw contour (0-16, which a mesh
shows only in profile), and not the inner mouth corners 60/64, which name the same project
landmarks as the outer 48/54."""


def shared_data_dir() -> Path | None:
    """The shared data folder (it holds a ``README.md``), or None when absent."""
    env = os.environ.get(SHARED_DATA_ENV)
    candidates = [Path(env)] if env else []
    candidates.append(Path(__file__).resolve().parents[4] / "shared" / "data")
    return next((c for c in candidates if (c / "README.md").is_file()), None)


def load_ict(folder: Path) -> tuple[Mesh, dict]:
    """ICT-FaceKit's neutral head (cm, all its parts) and its ``meta.json``, from ``folder`` (the
    shared data's ``ict-facekit``)."""
    data = np.load(folder / "neutral.npz")
    meta = json.loads((folder / "meta.json").read_text())
    mesh = Mesh(data["vertices"].astype(np.float64), data["faces"].astype(np.int64), units="cm")
    return mesh, meta


def ict_landmarks(mesh: Mesh, meta: dict) -> Landmarks:
    """The 49 landmarks of ``ICT_IBUG_USED`` at ICT's own landmark vertices of ``mesh`` (the neutral,
    or any mesh that keeps its first vertices, as without the eye shells), under project names."""
    from mimetic.fit.landmarks import Landmarks
    from mimetic.head.landmarks import IBUG68

    ids = np.asarray(meta["landmarks_68"]["vertex_indices"])[list(ICT_IBUG_USED)]
    names = tuple(IBUG68[i] for i in ICT_IBUG_USED)
    return Landmarks(names, mesh.vertices[ids], np.ones(len(ids)), "cm", "ict-facekit landmarks_68")


def require_shared_data(relative: str = "") -> Path:
    """The path ``relative`` inside the shared data folder; skips the test when it is absent.

    On CI (``CI=true``) a missing folder fails the test instead, so CI always runs the tests on
    real data.
    """
    root = shared_data_dir()
    path = None if root is None else root / relative
    if path is None or not path.exists():
        _missing(
            f"shared test data {relative or 'folder'!r} not found (looked in ${SHARED_DATA_ENV} and "
            "../shared/data beside the repository)"
        )
    return path


CHROMIUM = "/usr/bin/chromium"
"""Debian's Chromium (``apt-get install chromium``; ``.ci/run`` installs it): browser tests and
benchmarks drive it with Playwright (``executable_path``), never a downloaded browser."""
CHROMIUM_ARGS = (
    "--no-sandbox",  # CI runs as root
    "--disable-gpu",
    "--disable-background-networking",  # the machine's closed network refuses Chromium's own calls
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
)


def require_extra(module: str, extra: str):
    """``module``, from mimetic's optional ``extra`` (e.g. "pocketsphinx", "speech"); skips the test
    when it is not installed, fails it on CI (``CI=true``), where every extra is."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as error:
        _missing(f"needs {module}, in the extra [{extra}] (pip install 'mimetic[{extra}]'): {error}")


def _missing(reason: str) -> None:
    """Skip the running test for ``reason``; on CI (``CI=true``) fail it instead."""
    import pytest

    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(f"{reason}; CI=true requires it")
    pytest.skip(reason)


def run_cli(*args: object):
    """``mimetic`` on the command line, in this process: each argument passed as ``str``; returns
    typer's ``Result`` (``exit_code``, ``output``) and lets exceptions through."""
    from typer.testing import CliRunner

    from mimetic.cli import app

    return CliRunner().invoke(app, [str(a) for a in args], catch_exceptions=False)


# --------------------------------------------------------------------------- motion-quality cases
# (benchmarks/bench_quality.py, tests/test_quality.py)

ICT_IDENTITY_MODES = 20
FRONT_COS = 0.3
"""A generated head's skin vertex is on the face when its chart direction has z above this."""
MEDIAPIPE_INNER_LIPS = (
    *(78, 191, 80, 81, 82, 13, 312, 311, 310, 415, 308),  # upper, right corner to left
    *(324, 318, 402, 317, 14, 87, 178, 88, 95),  # lower, left to right
)
"""MediaPipe FaceMesh's inner lip contour (``face_mesh_connections.FACEMESH_LIPS``, inner ring)."""
MEDIAPIPE_EYES = (
    (263, 249, 390, 373, 374, 380, 381, 382, 362, 398, 384, 385, 386, 387, 388, 466),
    (33, 7, 163, 144, 145, 153, 154, 155, 133, 173, 157, 158, 159, 160, 161, 246),
)
"""MediaPipe FaceMesh's eye contours, the subject's left (+X) then right
(``FACEMESH_LEFT_EYE``, ``FACEMESH_RIGHT_EYE``)."""


def ict_folder() -> Path | None:
    """The shared ICT-FaceKit folder, or None when the shared data is absent."""
    root = shared_data_dir()
    return None if root is None or not (root / "ict-facekit").is_dir() else root / "ict-facekit"


def _ict_folder_or_raise(folder: Path | None) -> Path:
    folder = folder or ict_folder()
    if folder is None:
        raise FileNotFoundError(
            f"ICT-FaceKit data not found: put the shared data beside the repository or set ${SHARED_DATA_ENV}"
        )
    return Path(folder)


@lru_cache(maxsize=4)
def ict_expressions(folder: Path | None = None) -> tuple[tuple[str, ...], np.ndarray]:
    """ICT-FaceKit's 53 expression shapes with ARKit names (not the 4 extras), sorted by name.

    Returns
    -------
    names : tuple of str, (53,)
    deltas : (53, 26719, 3) float64, read-only
        Each shape minus the neutral, cm.
    """
    folder = _ict_folder_or_raise(folder)
    meta = json.loads((folder / "meta.json").read_text())
    names = tuple(sorted(meta["expressions"]["names_vertex_indices_json"]))
    shapes = np.load(folder / "expressions.npz")
    deltas = np.stack([shapes[name].astype(np.float64) for name in names])
    deltas.setflags(write=False)
    return names, deltas


@lru_cache(maxsize=32)
def ict_identity(seed: int, sigma: float = 1.0, folder: Path | None = None) -> Mesh:
    """An ICT-FaceKit identity head: ``neutral + Σ_k w_k · identity_k`` over the 20 modes.

    ``w = np.random.default_rng(seed).normal(0, sigma, 20)``: ``sigma`` 1 gives the plausible heads
    ICT's modes are scaled for, 2 stronger ones. Same topology and vertex order as the neutral
    (every part, cm); deterministic.
    """
    folder = _ict_folder_or_raise(folder)
    neutral, _ = load_ict(folder)
    modes = np.load(folder / "identities.npz")
    weights = np.random.default_rng(seed).normal(0.0, sigma, ICT_IDENTITY_MODES)
    vertices = neutral.vertices.copy()
    for k, w in enumerate(weights):
        vertices += w * modes[f"identity{k:03d}"].astype(np.float64)
    return Mesh(vertices, neutral.faces, units="cm")


def ict_face_faces(mesh: Mesh, meta: dict) -> np.ndarray:
    """The faces (k, 3) of ``mesh`` (ICT's topology) whose vertices all lie in ICT's "Face" part
    (vertices 0..9408, ``meta["parts"]``): the face the issue's edge-stretch numbers are over."""
    first, last = next(p["vertex_range"] for p in meta["parts"] if p["name"] == "Face")
    faces = mesh.faces
    return faces[((faces >= first) & (faces <= last)).all(axis=1)]


def generated_face_faces(head: Head) -> np.ndarray:
    """The skin faces (k, 3) of a generated head whose three vertices are on the face: chart
    directions with z > ``FRONT_COS`` (as ``benchmarks/bench_rig.py`` counts the face)."""
    from mimetic.head.topology import build_topology

    front = np.zeros(head.mesh.n_vertices, dtype=bool)
    front[: head.n_skin] = build_topology(head.resolution).directions[:, 2] > FRONT_COS
    faces = head.mesh.faces[head.mesh.parts["skin"]]
    return faces[front[faces].all(axis=1)]


def mediapipe_canonical(folder: Path | None = None) -> Mesh:
    """MediaPipe's canonical face mesh: 468 vertices, 898 triangles, cm, a face-only mask whose eye
    openings and mouth slit are closed by triangles."""
    root = shared_data_dir() if folder is None else None
    folder = folder or (None if root is None else root / "mediapipe")
    if folder is None or not (Path(folder) / "canonical.npz").is_file():
        raise FileNotFoundError(f"MediaPipe canonical mesh not found (set ${SHARED_DATA_ENV})")
    data = np.load(Path(folder) / "canonical.npz")
    return Mesh(data["vertices"].astype(np.float64), data["faces"].astype(np.int64), units="cm")


def mediapipe_landmarks(mesh: Mesh) -> Landmarks:
    """The project landmarks at their MediaPipe vertices (``MEDIAPIPE_LANDMARKS``) of the canonical
    mesh ``mesh`` (no pupils: they are iris points 468+)."""
    from mimetic.fit.autolandmarks import MEDIAPIPE_LANDMARKS
    from mimetic.fit.landmarks import Landmarks

    names = tuple(n for n, i in MEDIAPIPE_LANDMARKS.items() if i < mesh.n_vertices)
    ids = [MEDIAPIPE_LANDMARKS[n] for n in names]
    return Landmarks(names, mesh.vertices[ids], np.ones(len(names)), "cm", "mediapipe canonical vertices")


def mediapipe_face_faces(mesh: Mesh) -> np.ndarray:
    """The canonical mesh's faces (k, 3) without those that close the mouth slit or an eye opening
    (all three vertices on the inner lip contour, or on one eye's contour): those must stretch or
    fold when the mouth opens or the lids close, so they are not the face's skin."""
    faces = mesh.faces
    closing = np.zeros(len(faces), dtype=bool)
    for contour in (MEDIAPIPE_INNER_LIPS, *MEDIAPIPE_EYES):
        closing |= np.isin(faces, contour).all(axis=1)
    return faces[~closing]
