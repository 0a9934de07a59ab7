"""Contact sheets of a rig in action: every muscle at full contraction, every expression.

Both sheets use one face-framed camera per view for all their tiles (``face_camera``): it frames
the rest skin in front of the ears, between the chin and the brows, with a margin, so muscle
actions fill the frame and tiles compare like for like. A one-sided muscle's three-quarter tile
turns its own side toward the camera. ``render_pose`` draws one pose the same way (the CLI's
``mimetic pose``). ``closeup_sheet`` adds close-ups of the mouth corners and eyes of every
expression (``closeup_camera``), where tears, folds and gaps show first.

Images are (h, w, 3) uint8 arrays, as everywhere in ``mimetic.view``.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from mimetic.engines import Engine, make_engine
from mimetic.mesh.model import Mesh, surface_positions
from mimetic.render.camera import VIEWS, Camera
from mimetic.render.renderer import Renderer, default_renderer
from mimetic.rig.activations import pose
from mimetic.rig.anatomy.actions import CHANNELS as TISSUE_CHANNELS
from mimetic.rig.model import Rig
from mimetic.view.drawing import contact_sheet
from mimetic.view.look import rig_look

log = logging.getLogger(__name__)

Progress = Callable[[int, int], None]

FACE_MARGIN_REL = 0.05
"""Margin around the face box, a fraction of the head height (1.1 cm on a 22.5 cm head)."""

FACE_VIEWS = ("front", "three_quarter")
THREE_QUARTER_YAW_DEG = VIEWS["three_quarter"]


@dataclass(frozen=True)
class Action:
    """One tile pair of a muscle sheet: a label and the channel values it sets."""

    label: str
    values: Mapping[str, float]
    side: str | None = None  # "L" or "R" for one-sided actions: their side faces the 3/4 camera


def face_points(rig: Rig) -> np.ndarray:
    """Rest positions (k, 3) of the face: the skin in front of the ears, from chin to brows.

    "In front of the ears" is ``z`` at least ``0.2 * rig.scale`` ahead of the tragions, which
    drops the sides of the head; "from chin to brows" is ``y`` between the menton and the higher
    mid-brow landmark. Rigs without those landmarks give all their vertices.
    """
    v = rig.mesh.vertices
    needed = ("menton", "tragion_L", "tragion_R", "brow_mid_L", "brow_mid_R")
    if not all(n in rig.landmarks for n in needed):
        log.warning("rig lacks face landmarks (%s); framing the whole mesh", ", ".join(needed))
        return v
    lm = rig.landmark_positions(list(needed))  # (5, 3)
    skin = v
    if "skin" in rig.mesh.parts:
        skin = v[np.unique(rig.mesh.faces[rig.mesh.parts["skin"]])]
    front = lm[1:3, 2].max() + 0.2 * rig.scale
    keep = (skin[:, 1] >= lm[0, 1]) & (skin[:, 1] <= lm[3:, 1].max()) & (skin[:, 2] > front)
    return skin[keep] if keep.any() else v


def face_camera(
    rig: Rig,
    *,
    yaw_deg: float = 0.0,
    margin_rel: float = FACE_MARGIN_REL,
    fov_y_deg: float = 28.0,
    aspect: float = 1.0,
) -> Camera:
    """A camera framing the rest face (``face_points``), turned by ``yaw_deg`` toward the subject's left.

    The camera looks at the centre of the face's box from the closest distance at which every
    face point, grown by ``margin_rel * rig.scale`` in the image plane (twice that above the
    brows and below the chin, where raised brows and an open jaw go), projects inside the image.
    """
    points = face_points(rig)
    s, c = math.sin(math.radians(yaw_deg)), math.cos(math.radians(yaw_deg))
    toward_eye = np.array([-s, 0.0, c])
    up = np.array([0.0, 1.0, 0.0])
    right = np.cross(-toward_eye, up)
    centre = (points.min(axis=0) + points.max(axis=0)) / 2
    rel = points - centre  # (k, 3)
    x, y, z = rel @ right, rel @ up, rel @ toward_eye  # (k,) each, z toward the eye
    margin = margin_rel * rig.scale
    grow_x, grow_y = 1.5 * margin, 2 * margin
    tan_y = math.tan(math.radians(fov_y_deg) / 2)
    tan_x = tan_y * aspect

    def fit(tx: float, ty: float) -> float:
        # point k fits when |x_k - tx| + grow_x <= tan_x (d - z_k), and likewise in y
        half = np.maximum((np.abs(x - tx) + grow_x) / tan_x, (np.abs(y - ty) + grow_y) / tan_y)
        return float(np.max(z + half))

    tx, ty = (x.max() + x.min()) / 2, (y.max() + y.min()) / 2  # image centre, across the view
    for _ in range(6):
        # re-centre on the perspective extent: near points (the nose) spread further than far ones
        distance = fit(tx, ty)
        depth = distance - z  # (k,)
        tx += distance * (np.max((x + grow_x - tx) / depth) + np.min((x - grow_x - tx) / depth)) / 2
        ty += distance * (np.max((y + grow_y - ty) / depth) + np.min((y - grow_y - ty) / depth)) / 2
    distance = fit(tx, ty)
    target = centre + tx * right + ty * up
    return Camera(target + distance * toward_eye, target, up, fov_y_deg)


def _engine(rig: Rig, engine: Engine | str) -> Engine:
    return make_engine(rig, engine) if isinstance(engine, str) else engine


def _yaw(view: str, side: str | None) -> float:
    """Camera yaw for a view; a one-sided action's three-quarter view shows its own side."""
    if view == "three_quarter":
        return -THREE_QUARTER_YAW_DEG if side == "L" else THREE_QUARTER_YAW_DEG
    return VIEWS[view]


def pose_tiles(
    rig: Rig,
    engine: Engine | str,
    poses: Sequence[tuple[str, np.ndarray, str | None]],
    *,
    views: Sequence[str] = FACE_VIEWS,
    size: int = 256,
    renderer: Renderer | None = None,
    progress: Progress | None = None,
) -> list[tuple[str, np.ndarray]]:
    """Face close-ups of poses: (label, pose (c,), side) → one (label, image) tile per view, the
    mesh drawn as ``rig_look`` says.

    Tiles come pose by pose, views in order; the first view's label is the pose's, the others
    add the view (e.g. "joy 3/4"). Each image is (size, size, 3) uint8.
    """
    engine = _engine(rig, engine)
    renderer = renderer or default_renderer()
    unknown = [v for v in views if v not in VIEWS]
    if unknown:
        raise ValueError(f"unknown view(s) {unknown}; choose from {', '.join(VIEWS)}")
    cameras: dict[float, Camera] = {}
    look = rig_look(rig)
    tiles = []
    for done, (label, values, side) in enumerate(poses):
        mesh = rig.mesh.with_vertices(engine.deform(values))
        for k, view in enumerate(views):
            yaw = _yaw(view, side)
            if yaw not in cameras:
                cameras[yaw] = face_camera(rig, yaw_deg=yaw)
            image = renderer.render(mesh, cameras[yaw], size=(size, size), look=look)
            tiles.append((label if k == 0 else f"{label} {_short(view)}", image))
        if progress:
            progress(done + 1, len(poses))
    return tiles


def _short(view: str) -> str:
    return {"three_quarter": "3/4", "profile": "side"}.get(view, view)


def muscle_actions(rig: Rig) -> tuple[Action, ...]:
    """The muscle sheet's actions: rest, every muscle channel at 1, the tissue actions' own channels
    at 1 (the tongue's with the jaw half open, so it shows), then the bones.

    The bones are the jaw fully open, both upper eyelids closed, gaze to the subject's left and
    up, each at its channel's maximum.
    """
    actions = [Action("rest", {})]
    maximum = {c.name: c.maximum for c in rig.channels}
    for name in [*rig.muscle_names, *(c for c in TISSUE_CHANNELS if c in maximum)]:
        side = name[-1] if name[-2:] in ("_L", "_R") else None
        values = {name: 1.0}
        if TISSUE_CHANNELS.get(name, ("",))[0] == "tongue" and "jaw_open" in maximum:
            values["jaw_open"] = 0.5 * maximum["jaw_open"]
        actions.append(Action(name, values, side))
    extras = [
        ("jaw_open", ("jaw_open",), None),
        ("eyelids closed", ("eyelid_upper_L", "eyelid_upper_R"), None),
        ("gaze left", ("gaze_yaw",), None),
        ("gaze up", ("gaze_pitch",), None),
    ]
    for label, channels, side in extras:
        if all(c in maximum for c in channels):
            actions.append(Action(label, {c: maximum[c] for c in channels}, side))
    return tuple(actions)


def muscle_sheet(
    rig: Rig,
    engine: Engine | str = "wire",
    *,
    size: int = 256,
    views: Sequence[str] = FACE_VIEWS,
    columns: int | None = None,
    renderer: Renderer | None = None,
    progress: Progress | None = None,
) -> np.ndarray:
    """Every muscle at full contraction (and the jaw, eyelids and gaze), face close-ups, labelled.

    Tiles: ``muscle_actions(rig)`` (rest first) × ``views``, each (size, size); ``columns``
    defaults to 4 actions per row. Returns the sheet (h, w, 3) uint8.
    """
    poses = [(a.label, pose(rig, a.values), a.side) for a in muscle_actions(rig)]
    tiles = pose_tiles(rig, engine, poses, views=views, size=size, renderer=renderer, progress=progress)
    return contact_sheet(tiles, columns=columns or 4 * len(views))


def expression_sheet(
    rig: Rig,
    engine: Engine | str = "wire",
    library=None,
    *,
    size: int = 256,
    views: Sequence[str] = FACE_VIEWS,
    columns: int | None = None,
    renderer: Renderer | None = None,
    progress: Progress | None = None,
) -> np.ndarray:
    """Every expression of ``library`` (default: the built-in one), plus rest, face close-ups.

    Tiles: rest then each expression at weight 1 × ``views``, each (size, size); ``columns``
    defaults to 4 expressions per row. Returns the sheet (h, w, 3) uint8.
    """
    from mimetic.animate.expressions import expression_pose, load_library

    library = library if library is not None else load_library()
    poses = [("rest", pose(rig), None)]
    poses += [(name, expression_pose(rig, library[name]), None) for name in library.names]
    tiles = pose_tiles(rig, engine, poses, views=views, size=size, renderer=renderer, progress=progress)
    return contact_sheet(tiles, columns=columns or 4 * len(views))


def posed_mesh(rig: Rig, engine: Engine | str, values: np.ndarray) -> Mesh:
    """The rig's mesh (all parts, same vertex order) deformed by ``engine`` for a pose (c,)."""
    return rig.mesh.with_vertices(_engine(rig, engine).deform(values))


def render_pose(
    rig: Rig,
    engine: Engine | str,
    values: np.ndarray,
    *,
    view: str = "front",
    size: int = 512,
    renderer: Renderer | None = None,
) -> np.ndarray:
    """A face close-up (size, size, 3) uint8 of a pose (c,); ``view="all"`` gives a labelled sheet
    of the front, three-quarter and profile views side by side."""
    vertices = posed_mesh(rig, engine, values).vertices
    return render_posed(rig, vertices, view=view, size=size, renderer=renderer)


def render_posed(
    rig: Rig, vertices: np.ndarray, *, view: str = "front", size: int = 512, renderer: Renderer | None = None
) -> np.ndarray:
    """``render_pose`` of the rig's mesh already posed: ``vertices`` (n, 3) in rig units."""
    views = list(VIEWS) if view == "all" else [view]
    if any(v not in VIEWS for v in views):
        raise ValueError(f"unknown view {view!r}; choose all or one of {', '.join(VIEWS)}")
    renderer = renderer or default_renderer()
    mesh = rig.mesh.with_vertices(np.asarray(vertices, dtype=np.float64))
    look = rig_look(rig)
    tiles = [
        (
            v.replace("_", " "),
            renderer.render(mesh, face_camera(rig, yaw_deg=VIEWS[v]), size=(size, size), look=look),
        )
        for v in views
    ]
    return tiles[0][1] if len(tiles) == 1 else contact_sheet(tiles, columns=len(tiles))


CLOSEUPS = (
    ("eye R", ("eye_outer_corner_R", "eye_inner_corner_R"), "R"),
    ("eye L", ("eye_outer_corner_L", "eye_inner_corner_L"), "L"),
    ("corner R", ("mouth_corner_R",), "R"),
    ("corner L", ("mouth_corner_L",), "L"),
)
"""The close-ups of ``closeup_sheet``: label, the landmarks whose mean the camera aims at, and the
side it is turned toward (the subject's right side is the image left, so R comes first)."""

CLOSEUP_HALF_REL = {"eye": 0.09, "corner": 0.06}
"""Half the height a close-up shows at its target, a fraction of the head height (2 cm around
an eye, 1.35 cm around a mouth corner on a 22.5 cm head)."""

CLOSEUP_YAW_DEG = 20.0
"""A close-up turns the face this far toward the camera's side, so the corner's depth shows."""


def closeup_camera(
    rig: Rig,
    landmarks: Sequence[str],
    *,
    vertices: np.ndarray | None = None,
    half_rel: float = CLOSEUP_HALF_REL["corner"],
    yaw_deg: float = 0.0,
    fov_y_deg: float = 28.0,
) -> Camera:
    """A camera aimed at the mean of ``landmarks`` on ``vertices`` (n, 3) (a posed mesh; default
    the rest mesh), from the front turned by ``yaw_deg`` toward the subject's left (negative: right),
    at the distance where the image height at the target is ``2 * half_rel * rig.scale``.

    The target projects to the image centre; lengths scale with the head, so the framing is the
    same on any head and in any units.
    """
    missing = [n for n in landmarks if n not in rig.landmarks]
    if missing or not landmarks:
        raise KeyError(f"no landmark(s) {missing or landmarks}; the rig has {len(rig.landmarks)} landmarks")
    v = rig.mesh.vertices if vertices is None else np.asarray(vertices, dtype=np.float64)
    target = surface_positions([rig.landmarks[n] for n in landmarks], v, rig.mesh.faces).mean(axis=0)
    s, c = math.sin(math.radians(yaw_deg)), math.cos(math.radians(yaw_deg))
    distance = half_rel * rig.scale / math.tan(math.radians(fov_y_deg) / 2)
    return Camera(target + distance * np.array([-s, 0.0, c]), target, (0.0, 1.0, 0.0), fov_y_deg)


def closeup_sheet(
    rig: Rig,
    engine: Engine | str = "wire",
    library=None,
    *,
    size: int = 256,
    renderer: Renderer | None = None,
    progress: Progress | None = None,
) -> np.ndarray:
    """Rest and every expression of ``library`` (default: the built-in one), one row each: the
    front face, then close-ups (``CLOSEUPS``) of the right and left eye and the right and left
    mouth corner, each following its landmarks on the posed mesh.

    Tiles are (size, size), labelled "NAME", "NAME eye R", ..., "NAME corner L"; the sheet is
    (rows · (size + 24), 5 · size, 3) uint8 with one row per pose (``contact_sheet``). Rigs
    without the eye or mouth corner landmarks raise ``KeyError`` naming them.
    """
    from mimetic.animate.expressions import expression_pose, load_library

    library = library if library is not None else load_library()
    engine = _engine(rig, engine)
    renderer = renderer or default_renderer()
    look = rig_look(rig)
    face = face_camera(rig)
    poses = [("rest", pose(rig))] + [(n, expression_pose(rig, library[n])) for n in library.names]
    tiles = []
    for done, (name, values) in enumerate(poses):
        vertices = engine.deform(values)  # (n, 3)
        mesh = rig.mesh.with_vertices(vertices)
        tiles.append((name, renderer.render(mesh, face, size=(size, size), look=look)))
        for label, names, side in CLOSEUPS:
            camera = closeup_camera(
                rig,
                names,
                vertices=vertices,
                half_rel=CLOSEUP_HALF_REL[label.split()[0]],
                yaw_deg=CLOSEUP_YAW_DEG if side == "L" else -CLOSEUP_YAW_DEG,
            )
            tiles.append((f"{name} {label}", renderer.render(mesh, camera, size=(size, size), look=look)))
        if progress:
            progress(done + 1, len(poses))
    return contact_sheet(tiles, columns=1 + len(CLOSEUPS))
