"""Performances the rig did not make: captured expression data on real and generated heads, with head
motion, as markers and as video; and the numbers that say how well a capture route reproduced them.

Used by ``benchmarks/validate_capture.py`` (the capture validation table) and the capture tests.

* ``ict_performer(seed, sigma)`` is ICT-FaceKit's neutral head, or one of its identities, that
  performs with ICT's 53 captured expression shapes (light-stage scans of a real face, not made by
  any rig); ``generated_performer(params, fit)`` carries those shapes onto a generated head through
  the reference head fitted to ICT (``RigResult.fit``). A ``Performer`` knows its vertices, the
  shapes on them, its iBUG-68 points, the vertex sets a residual is measured on, and how to be
  drawn (parts and colours: skin, lips, brows, eyes, teeth, a dark mouth).
* ``build_take(fps, seed)`` is a take: a neutral, then talking (syllables with the jaw, bilabial
  closures, rounded and spread vowels), brows, a smile, a pucker, a cheek puff, the mouth to
  either side, surprise and a frown, with blinks throughout, as weights of ICT's shapes over time;
  and a smooth random head motion (±15° yaw, ±10° pitch, ±5° roll, ±2 cm) after the neutral.
* ``marker_take`` records a performer's 68 iBUG points in millimetres with noise and dropouts;
  ``render_take`` films the performance with a perspective camera at about 60 cm, drawn by the CPU
  rasteriser (``Renderer("cpu")``, not the GL renderer the rig's own videos use).
* ``score`` compares solved (head-motion-free) vertices and head rotations with the truth.
"""

from __future__ import annotations

import itertools
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline

from mimetic.engines.skinning import rotation_x, rotation_y, rotation_z
from mimetic.head.model import Head
from mimetic.mesh.closest import closest_points
from mimetic.mesh.geometry import vertex_normals
from mimetic.mesh.model import Mesh
from mimetic.testing import ict_expressions, ict_folder, ict_identity, load_ict

IBUG_NAMES = tuple(f"ibug68_{k:02d}" for k in range(1, 69))
MOVING_MM = 2.0
"""A frame moves when some face vertex is this far from the neutral (a smaller motion is within a
capture's noise, where a relative residual says nothing)."""
CLOSED_MM = 2.0
"""The inner lips (iBUG 63 and 67, 1-based) are closed when nearer than this."""
SKIN = (0.80, 0.60, 0.50)
LIPS = (0.62, 0.32, 0.32)
BROWS = (0.30, 0.20, 0.15)
MOUTH = (0.30, 0.10, 0.10)
GUMS = (0.65, 0.30, 0.30)
TEETH = (0.92, 0.90, 0.82)
SCLERA = (0.92, 0.90, 0.87)
IRIS = (0.30, 0.20, 0.12)
LASHES = (0.10, 0.07, 0.05)
BACKGROUND = (0.35, 0.38, 0.42)


@dataclass(frozen=True, eq=False)
class Performer:
    """A head that performs with ICT-FaceKit's captured expression shapes.

    Attributes
    ----------
    name : str
    mesh : Mesh
        The neutral head, every part, in cm, with parts and colours for drawing.
    shapes : tuple of str, (k,)
        ICT's expression names (ARKit's, with _L/_R).
    deltas : (k, n, 3) float64
        Each shape's displacement of every vertex, cm.
    ibug : (68, n) scipy.sparse matrix
        The iBUG-68 points as barycentric weights: ``ibug @ vertices`` (68, 3).
    face, mouth, upper_face : (s,) int64
        The vertex sets residuals are measured on: the face (brows to chin, ear to ear, no neck or
        scalp), the mouth and chin, the eyes and brows.
    pivot : (3,) float64
        Where the head turns (the top of the neck), cm.
    """

    name: str
    mesh: Mesh
    shapes: tuple[str, ...]
    deltas: np.ndarray
    ibug: object
    face: np.ndarray
    mouth: np.ndarray
    upper_face: np.ndarray
    pivot: np.ndarray

    def vertices(self, weights: np.ndarray) -> np.ndarray:
        """(f, n, 3) the neutral plus the shapes at ``weights`` (f, k), cm, no head motion."""
        flat = weights @ self.deltas.reshape(len(self.shapes), -1)
        return self.mesh.vertices + flat.reshape(len(weights), -1, 3)


@dataclass(frozen=True, eq=False)
class Take:
    """A performance: shape weights and head motion over time.

    Attributes
    ----------
    weights : (f, k) float64
        Per frame, each of ``shapes``' weight in [0, 1].
    angles : (f, 3) float64
        Head yaw, pitch, roll (radians) as the rig composes them, R = R_y(yaw) R_x(pitch) R_z(−roll).
    shift : (f, 3) float64
        Head translation, cm.
    fps : float
    segments : dict
        Name → (start, end) in seconds.
    closures : (e,) int64
        Frames at the middle of each bilabial closure.
    """

    shapes: tuple[str, ...]
    weights: np.ndarray
    angles: np.ndarray
    shift: np.ndarray
    fps: float
    segments: dict = field(default_factory=dict)
    closures: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))

    @property
    def n_frames(self) -> int:
        return len(self.weights)

    def rotations(self) -> np.ndarray:
        """(f, 3, 3) the head's rotation per frame."""
        return np.array([rotation_y(y) @ rotation_x(p) @ rotation_z(-r) for y, p, r in self.angles])

    def still(self) -> Take:
        """The same performance without head motion."""
        return Take(
            self.shapes, self.weights, 0 * self.angles, 0 * self.shift, self.fps, self.segments, self.closures
        )


# --------------------------------------------------------------------------- performers


def _ict_parts(folder: Path, meta: dict) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """ICT's triangles by part (its polygon ranges), and the vertex colours that draw it."""
    face_to_quad = np.load(folder / "neutral.npz")["face_to_quad"]
    ranges = {p["name"]: p for p in meta["parts"]}

    def faces(*names: str) -> np.ndarray:
        return np.concatenate(
            [np.flatnonzero((face_to_quad >= r[0]) & (face_to_quad <= r[1])) for r in
             (ranges[n]["polygon_range"] for n in names)]
        )  # fmt: skip

    def vertices(name: str) -> slice:
        first, last = ranges[name]["vertex_range"]
        return slice(first, last + 1)

    parts = {
        "skin": faces("Face", "Head and Neck", "Eye socket left", "Eye socket right"),
        "mouth": faces("Mouth socket", "Gums and tongue"),
        "teeth": faces("Teeth"),
        "eye_L": faces("Eyeball left"),
        "eye_R": faces("Eyeball right"),
        "lashes": faces("Eyelashes left", "Eyelashes right"),
        "eye occlusion": faces(*(f"{kind} {side}" for kind in ("Lacrimal fluid", "Eye blend", "Eye occlusion")
                                 for side in ("left", "right"))),
    }  # fmt: skip
    n = meta["parts"][0]["n_vertices"]
    colors = np.tile(np.array(SKIN, np.float32), (n, 1))
    colors[vertices("Mouth socket")] = MOUTH
    colors[vertices("Gums and tongue")] = GUMS
    colors[vertices("Teeth")] = TEETH
    colors[vertices("Eyelashes left")] = colors[vertices("Eyelashes right")] = LASHES
    for part in meta["eyeball_details"]:
        first, last = part["vertex_range"]
        colors[first : last + 1] = IRIS if part["name"].startswith("Iris") else SCLERA
    return parts, colors


def _paint_features(vertices: np.ndarray, colors: np.ndarray, face: np.ndarray, ibug: np.ndarray) -> None:
    """Lips and brows on the face's colours, in place: a soft blend by distance (in the image plane)
    to the outer lip contour and to the brow lines (``ibug`` (68, 3), cm)."""
    xy = vertices[face, :2]
    front = vertices[face, 2] > np.median(vertices[face, 2])
    lips = ibug[48:60, :2]
    inside = np.zeros(len(face), bool)
    for a, b in zip(lips, np.roll(lips, -1, axis=0), strict=True):  # even-odd rule
        crosses = (a[1] > xy[:, 1]) != (b[1] > xy[:, 1])
        x_at = a[0] + (xy[:, 1] - a[1]) * (b[0] - a[0]) / np.where(b[1] == a[1], 1e-30, b[1] - a[1])
        inside ^= crosses & (xy[:, 0] < x_at)
    colors[face[inside & front]] = LIPS
    for start, stop in ((17, 22), (22, 27)):
        line = ibug[start:stop, :2]
        t = np.linspace(0.0, 1.0, 40)[:, None]
        dense = np.concatenate([a + t * (b - a) for a, b in itertools.pairwise(line)])
        distance = np.min(np.linalg.norm(xy[:, None] - dense[None], axis=2), axis=1)
        amount = np.clip(1.0 - (distance - 0.25) / 0.25, 0.0, 1.0)[:, None] * front[:, None]
        colors[face] = (1.0 - amount) * colors[face] + amount * np.array(BROWS, np.float32)


def _sets(
    vertices: np.ndarray, face: np.ndarray, ibug: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The face (front of the head from above the brows to below the chin, ear to ear), the mouth and
    chin, and the eyes and brows, as vertex indices, from the iBUG points (68, 3)."""
    eye_distance = np.linalg.norm(ibug[36] - ibug[45])
    top = ibug[17:27, 1].max() + 0.35 * eye_distance
    bottom = ibug[8, 1] - 0.1 * eye_distance
    p = vertices[face]
    front = (p[:, 1] < top) & (p[:, 1] > bottom) & (np.abs(p[:, 0]) < np.abs(ibug[[0, 16], 0]).max())
    front &= p[:, 2] > ibug[[0, 16], 2].min()
    in_face = face[front]
    q = vertices[in_face]
    mouth_centre = ibug[48:68].mean(axis=0)
    mouth = in_face[
        (q[:, 1] < ibug[33, 1]) & (np.linalg.norm(q[:, :2] - mouth_centre[:2], axis=1) < 0.9 * eye_distance)
    ]
    upper = in_face[q[:, 1] > ibug[[39, 42], 1].mean() - 0.3 * eye_distance]
    return in_face, mouth, upper


def ict_performer(seed: int | None = None, sigma: float = 1.0, folder: Path | None = None) -> Performer:
    """ICT-FaceKit's neutral (``seed`` None) or identity ``ict_identity(seed, sigma)``, performing with
    its 53 captured shapes (the shapes were scanned on the neutral; as in ICT's own model they add
    to any identity)."""
    import scipy.sparse as sp

    folder = folder or ict_folder()
    neutral, meta = load_ict(folder)
    mesh = neutral if seed is None else ict_identity(seed, sigma, folder)
    shapes, deltas = ict_expressions(folder)
    parts, colors = _ict_parts(folder, meta)
    landmarks = np.asarray(meta["landmarks_68"]["vertex_indices"])
    ibug = sp.csr_matrix((np.ones(68), (np.arange(68), landmarks)), shape=(68, mesh.n_vertices))
    face_part = np.arange(meta["parts"][1]["n_vertices"])  # "Face": vertices 0..9408
    points = ibug @ mesh.vertices
    _paint_features(mesh.vertices, colors, face_part, points)
    face, mouth, upper = _sets(mesh.vertices, face_part, points)
    name = "ICT neutral" if seed is None else f"ICT id {seed} σ{sigma:g}"
    drawn = Mesh(mesh.vertices, mesh.faces, parts, colors, "cm")
    pivot = np.array([0.0, points[8, 1], points[[0, 16], 2].mean()])  # below the ears, at the chin's height
    return Performer(name, drawn, shapes, deltas, ibug, face, mouth, upper, pivot)


def generated_performer(head: Head, ict: Performer, fit) -> Performer:
    """A generated head performing ICT's shapes, carried over through the reference head fitted to
    ICT (``fit``: ``rig_head(ict.mesh, ...).fit``, a ``ReferenceFit``): each skin vertex of ``head``
    (of the fit's resolution, so vertex for vertex the reference) takes the shapes' motion at the
    point of ICT's surface nearest to its fitted reference vertex (normals within 60°, so an upper lip
    does not take the lower lip's motion), turned and scaled into the reference frame. The eyes,
    teeth and tongue keep still (a blink is skin)."""
    import scipy.sparse as sp

    from mimetic.head.landmarks import IBUG68

    fitted = fit.head.mesh.vertices[: head.n_skin]  # reference frame
    skin_faces = fit.head.mesh.faces[fit.head.mesh.parts["skin"]]
    target = fit.target  # ICT in the reference frame
    target_faces = target.faces[ict.mesh.parts["skin"]]
    hit = closest_points(
        target.vertices,
        target_faces,
        fitted,
        query_normals=vertex_normals(fit.head.mesh.vertices, skin_faces)[: head.n_skin],
        min_cos=0.5,
    )
    corners = target_faces[hit.faces]  # (s, 3)
    to_model = fit.conformation.to_model
    linear = to_model.scale * to_model.rotation  # ICT's frame → the reference frame (no translation)
    moved = np.einsum("sc,kscd->ksd", hit.bary, ict.deltas[:, corners]) @ linear.T
    deltas = np.zeros((len(ict.shapes), head.mesh.n_vertices, 3))
    deltas[:, : head.n_skin] = moved
    mesh = head.mesh
    names = list(IBUG68)
    vertices = [int(head.landmarks[n]) for n in names]  # a generated head's landmarks are vertices
    ibug = sp.csr_matrix((np.ones(68), (np.arange(68), vertices)), shape=(68, mesh.n_vertices))
    positions = ibug @ mesh.vertices
    skin_vertices = np.arange(head.n_skin)
    colors = np.tile(np.array(SKIN, np.float32), (mesh.n_vertices, 1))
    if mesh.colors is not None:
        colors[head.n_skin :] = mesh.colors[head.n_skin :]
    _paint_features(mesh.vertices, colors, skin_vertices, positions)
    face, mouth, upper = _sets(mesh.vertices, skin_vertices, positions)
    drawn = Mesh(mesh.vertices, mesh.faces, mesh.parts, colors, mesh.units)
    pivot = np.array([0.0, positions[8, 1], positions[[0, 16], 2].mean()])
    return Performer("generated", drawn, ict.shapes, deltas, ibug, face, mouth, upper, pivot)


# --------------------------------------------------------------------------- takes


def _smoothstep(x: np.ndarray) -> np.ndarray:
    x = np.clip(x, 0.0, 1.0)
    return x * x * (3.0 - 2.0 * x)


def _bump(t: np.ndarray, start: float, length: float, rise: float = 0.2) -> np.ndarray:
    """0 before ``start``, up over ``rise`` of ``length``, held, down by ``start + length``."""
    r = rise * length
    return _smoothstep((t - start) / r) * (1.0 - _smoothstep((t - (start + length - r)) / r))


SEGMENTS = (
    ("talk", 2.5), ("brows", 1.2), ("smile", 1.2), ("pucker", 1.0), ("puff", 1.0),
    ("left", 0.8), ("right", 0.8), ("surprise", 1.2), ("frown", 1.0),
)  # fmt: skip
"""The take's acts after the neutral, and their lengths in seconds."""
NEUTRAL_S = 0.6
HEAD_DEG = (15.0, 10.0, 5.0)
HEAD_CM = 2.0


def build_take(shapes: tuple[str, ...], fps: float, seed: int = 0, *, head_motion: bool = True) -> Take:
    """The take of the module docstring at ``fps``; ``seed`` draws the syllables, blinks and head motion."""
    rng = np.random.default_rng(seed)
    total = NEUTRAL_S + sum(length for _, length in SEGMENTS) + 0.4
    f = round(total * fps)
    t = np.arange(f) / fps
    weights = np.zeros((f, len(shapes)))
    closures = []

    def add(name: str, curve: np.ndarray) -> None:
        weights[:, shapes.index(name)] += curve

    def both(name: str, curve: np.ndarray) -> None:
        add(f"{name}_L", curve)
        add(f"{name}_R", curve)

    start, segments = NEUTRAL_S, {}
    for name, length in SEGMENTS:
        segments[name] = (start, start + length)
        b = _bump(t, start, length)
        if name == "talk":
            k = start + 0.1
            while k < start + length - 0.25:
                d = rng.uniform(0.18, 0.3)
                kind = rng.choice(["open", "open", "bilabial", "round", "spread"])
                amp = rng.uniform(0.15, 0.45)
                s = _bump(t, k, d, 0.4)
                if kind == "bilabial":
                    add("jawOpen", 0.12 * s)
                    add("mouthClose", 0.12 * s)
                    both("mouthPress", 0.3 * s)
                    closures.append(round((k + d / 2) * fps))
                elif kind == "round":
                    add("jawOpen", 0.5 * amp * s)
                    add("mouthFunnel", 0.6 * s)
                    add("mouthPucker", 0.3 * s)
                elif kind == "spread":
                    add("jawOpen", 0.6 * amp * s)
                    both("mouthStretch", 0.4 * s)
                else:
                    add("jawOpen", amp * s)
                    both("mouthLowerDown", 0.3 * s)
                    both("mouthUpperUp", 0.2 * s)
                k += d * rng.uniform(0.8, 1.0)
        elif name == "brows":
            both("browInnerUp", 0.9 * b)
            both("browOuterUp", 0.8 * b)
        elif name == "smile":
            both("mouthSmile", 0.9 * b)
            both("cheekSquint", 0.5 * b)
            both("eyeSquint", 0.3 * b)
        elif name == "pucker":
            add("mouthPucker", 0.95 * b)
        elif name == "puff":
            both("cheekPuff", 0.9 * b)
        elif name in ("left", "right"):
            add(f"mouth{name.title()}", 0.9 * b)
        elif name == "surprise":
            both("browInnerUp", 0.9 * b)
            both("browOuterUp", 0.9 * b)
            both("eyeWide", 0.7 * b)
            add("jawOpen", 0.45 * b)
        elif name == "frown":
            both("browDown", 0.9 * b)
            both("mouthFrown", 0.5 * b)
            both("noseSneer", 0.4 * b)
        start += length
    blink = 1.0 + rng.uniform(0.0, 0.5)
    while blink < total - 0.3:
        both("eyeBlink", _bump(t, blink, 0.18, 0.45))
        blink += rng.uniform(1.3, 2.1)
    weights = np.clip(weights, 0.0, 1.0)

    def spline(amplitude: float) -> np.ndarray:
        knots = np.arange(-0.9, t[-1] + 1.8, 0.9)
        return CubicSpline(knots, rng.uniform(-amplitude, amplitude, len(knots)))(t)

    envelope = _smoothstep((t - NEUTRAL_S / 2) / NEUTRAL_S)[:, None] * head_motion
    angles = np.stack([spline(np.radians(a)) for a in HEAD_DEG], axis=1) * envelope
    shift = np.stack([spline(HEAD_CM) for _ in range(3)], axis=1) * envelope
    return Take(shapes, weights, angles, shift, float(fps), segments, np.array(closures, np.int64))


def moved(points: np.ndarray, take: Take, pivot: np.ndarray) -> np.ndarray:
    """``points`` (f, k, 3) (cm, no head motion) turned and shifted by the take's head motion."""
    return np.einsum("fij,fkj->fki", take.rotations(), points - pivot) + pivot + take.shift[:, None]


def marker_take(
    performer: Performer, take: Take, *, noise_mm: float = 1.0, drop: float = 0.05, seed: int = 0
):
    """The performer's 68 iBUG points through the take, in millimetres with Gaussian noise of
    ``noise_mm`` RMS (3D) and a fraction ``drop`` of the samples missing (NaN): a ``Trajectories``
    of markers at 60 fps or the take's rate."""
    from mimetic.capture import Trajectories

    rng = np.random.default_rng(seed)
    points = np.stack([performer.ibug @ v for v in performer.vertices(take.weights)])  # (f, 68, 3) cm
    millimetres = 10.0 * moved(points, take, performer.pivot)
    millimetres += rng.normal(0.0, noise_mm / np.sqrt(3), millimetres.shape)
    millimetres[rng.random(millimetres.shape[:2]) < drop] = np.nan
    return Trajectories(IBUG_NAMES, millimetres, take.fps, "mm", source=f"{performer.name} markers")


def take_camera(performer: Performer, *, distance_cm: float = 60.0, fov_y_deg: float = 40.0):
    """A camera ``distance_cm`` in front of the performer's face, looking at it (+Y up)."""
    from mimetic.render.camera import Camera

    centre = (performer.ibug @ performer.mesh.vertices)[[27, 33, 8]].mean(axis=0) * np.array([0.0, 1.0, 1.0])
    return Camera(centre + np.array([0.0, 0.0, distance_cm]), centre, (0.0, 1.0, 0.0), fov_y_deg)


def render_take(
    performer: Performer,
    take: Take,
    path: Path,
    *,
    size: tuple[int, int] = (1280, 720),
    distance_cm: float = 60.0,
    fov_y_deg: float = 40.0,
    progress: Callable[[int, int], None] | None = None,
) -> Path:
    """Film the performance (H.264 MP4 at the take's rate) with ``take_camera``, drawn by the CPU
    rasteriser on a grey-blue background."""
    from mimetic.render.renderer import Renderer
    from mimetic.view.video import write_mp4

    renderer = Renderer("cpu")
    camera = take_camera(performer, distance_cm=distance_cm, fov_y_deg=fov_y_deg)
    mesh = performer.mesh

    def frames():
        for start in range(0, take.n_frames, 32):
            chunk = slice(start, start + 32)
            part = Take(take.shapes, take.weights[chunk], take.angles[chunk], take.shift[chunk], take.fps)
            for k, vertices in enumerate(moved(performer.vertices(part.weights), part, performer.pivot)):
                yield renderer.render(mesh.with_vertices(vertices), camera, size=size, background=BACKGROUND)
                if progress is not None:
                    progress(start + k + 1, take.n_frames)

    return write_mp4(frames(), path, fps=take.fps, size=size)


# --------------------------------------------------------------------------- scores


def _relative(solved: np.ndarray, truth: np.ndarray, neutral: np.ndarray) -> np.ndarray:
    """(f,) ‖solved − truth‖ / ‖truth − neutral‖ over the vertices given (f, s, 3)."""
    error = np.linalg.norm((solved - truth).reshape(len(truth), -1), axis=1)
    motion = np.linalg.norm((truth - neutral).reshape(len(truth), -1), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        return error / motion


def score(
    performer: Performer,
    take: Take,
    solved: np.ndarray,
    *,
    rotations: np.ndarray | None = None,
    jaw: np.ndarray | None = None,
) -> dict:
    """How well a route reproduced the take.

    Parameters
    ----------
    solved : (f, n, 3) float64
        The solved face without head motion, on the performer's vertices, cm.
    rotations : (f, 3, 3) float64, optional
        The solved head rotation per frame (relative to the first frame).
    jaw : (f,) float64, optional
        The solved ``jaw_open``, for its correlation with ICT's ``jawOpen`` weight.

    Returns
    -------
    dict with, over the moving frames (``MOVING_MM``): ``face``, ``mouth``, ``upper_face`` (the
    median of ‖solved − true‖ / ‖true − neutral‖, %), ``worse_than_rest`` (% of moving frames whose
    face residual exceeds 100 %), ``jaw_r``, ``closures_hit`` (bilabial closures at which the solved
    inner lips are within ``CLOSED_MM``, of those the truth closes), ``head_deg`` (RMS angle between
    the true and solved head rotations), ``moving_frames``, and the per-act medians ``acts``.
    """
    truth = performer.vertices(take.weights)
    neutral = performer.mesh.vertices
    motion = np.linalg.norm(truth[:, performer.face] - neutral[performer.face], axis=2).max(axis=1)
    moving = motion * 10.0 > MOVING_MM
    out = {"moving_frames": int(moving.sum())}
    for name in ("face", "mouth", "upper_face"):
        index = getattr(performer, name)
        relative = _relative(solved[:, index], truth[:, index], neutral[index])
        out[name] = float(100.0 * np.nanmedian(relative[moving & np.isfinite(relative)]))
        if name == "face":
            face = relative
    out["worse_than_rest"] = float(100.0 * np.mean(face[moving] > 1.0))
    out["acts"] = {
        act: float(100.0 * np.nanmedian(face[moving & (np.arange(len(face)) / take.fps >= a)
                                              & (np.arange(len(face)) / take.fps < b)]))
        for act, (a, b) in take.segments.items()
    }  # fmt: skip
    if jaw is not None:
        out["jaw_r"] = float(np.corrcoef(take.weights[:, take.shapes.index("jawOpen")], jaw)[0, 1])
    lips = performer.ibug[[62, 66]]  # inner lip middles
    gap_true = np.array([np.linalg.norm(np.diff(lips @ v, axis=0)) for v in truth[take.closures]]) * 10.0
    gap_solved = np.array([np.linalg.norm(np.diff(lips @ v, axis=0)) for v in solved[take.closures]]) * 10.0
    closed = gap_true < CLOSED_MM
    out["closures"] = int(closed.sum())
    out["closures_hit"] = int((closed & (gap_solved < CLOSED_MM)).sum())
    if rotations is not None:
        relative = np.einsum("fji,fjk->fik", rotations, take.rotations())
        cos = np.clip((np.trace(relative, axis1=1, axis2=2) - 1.0) / 2.0, -1.0, 1.0)
        out["head_deg"] = float(np.degrees(np.sqrt(np.mean(np.arccos(cos) ** 2))))
    return out


def write_json(data: dict, path: Path) -> Path:
    """``data`` as JSON (numpy numbers as Python's, nan as null)."""

    def plain(value):
        if isinstance(value, dict):
            return {str(k): plain(v) for k, v in value.items()}
        if isinstance(value, list | tuple):
            return [plain(v) for v in value]
        if isinstance(value, np.integer | np.bool_):
            return value.item()
        if isinstance(value, float | np.floating):
            return float(value) if np.isfinite(value) else None
        return value

    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(plain(data), indent=1))
    return path
