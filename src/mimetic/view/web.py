"""``mimetic view``: a local web app over a rig (viser; needs the ``[view]`` extra).

The page shows the rigged head (skin, eyes, teeth, tongue: one mesh per part) and, in tabs, the
thesis's animation interface (seed-000 §6): channel sliders grouped by region, descriptive, FACS
and ARKit sliders, the expression library with an intensity, a timeline with keys and playback
(clips from ``mimetic speak`` or ``mimetic capture`` play with their sound), landmark picking that
writes a landmarks file for ``mimetic rig``, and GLB / PNG / clip JSON downloads. A plain mesh
(.obj .ply .stl .glb) opens for landmark picking only. With ``capture`` (``mimetic view --capture``)
a video's (or a camera's) face plays on the rig as it arrives, solved frame by frame
(``session.LivePlayback``), under a status line; with ``speak`` (``mimetic view --speak``) a WAV
file, standing in for a microphone, is lip-synced live the same way (``session.SpeechPlayback``).

Why viser: its browser client is one bundled file that works offline, and a vertex update reaches
the browser in ~19 ms (../shared/research §D); gradio needs the network and resends whole meshes,
trame syncs JSON lists. The server binds 127.0.0.1 unless told otherwise; a port in use is an error
(viser itself would quietly take the next one).

Over 600 lines because the page is one viser app: its tabs share the rig, the session and the
client handles.
"""

from __future__ import annotations

import base64
import contextlib
import errno
import io
import os
import re
import socket
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from mimetic.errors import MimeticError, MissingExtraError

MESH_SUFFIXES = (".obj", ".ply", ".stl", ".glb", ".gltf")
GROUPS: tuple[tuple[str, tuple[str, ...]], ...] = (
    ("Brows and eyes", ("frontalis", "corrugator", "depressor_supercilii", "procerus", "orbicularis_oculi",
                        "levator_palpebrae", "eyelid")),
    ("Cheeks and nose", ("zygomatic", "levator_labii", "risorius", "buccinator", "cheek_puff", "nasalis",
                         "dilator_naris", "depressor_septi")),
    ("Mouth", ("orbicularis_oris", "triangularis", "depressor", "mentalis", "platysma", "mouth_")),
    ("Jaw", ("jaw_",)),
    ("Gaze", ("gaze_",)),
    ("Tongue", ("tongue_",)),
    ("Head", ("head_",)),
)  # fmt: skip
"""The channel tab's folders, after the thesis's muscle tab: a channel goes to the first group one
of whose name prefixes it starts with; the rest go to "Other"."""

FACINGS = {
    "+Y up, face +Z (glTF, Maya)": ((0, 1, 0), (0, 0, 1)),
    "+Z up, face -Y (Blender)": ((0, 0, 1), (0, -1, 0)),
    "+Z up, face +Y": ((0, 0, 1), (0, 1, 0)),
    "+Y up, face -Z": ((0, 1, 0), (0, 0, -1)),
}
"""How a file's head may stand (up axis, the way the face looks): the landmark picker turns the
head's frame to show it upright; the coordinates, and so the picked landmarks, stay the file's."""

COLOR_LEVELS = 16
"""Face colours are told apart at this many levels per channel."""

MAX_PAINTED_COLORS = 6
"""A part with more distinct face colours than this is textured and drawn in one colour."""

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])
"""Rec. 709 weights: which of a face's corner colours is the darkest."""

PREPARE_NOTE = {"fem": "about 10 s", "tissue": "half a minute to two minutes (it is baked)"}
"""How long an engine takes to prepare, as the page says (benchmarks/bench_view.py: fem 9 s on the
default head and 14 s on ICT; tissue 29 s and 100 s; measured again on the default head with
another job on the 2 cores: wire 0.2 s, vector 0.3 s, fem 7.6 s, tissue 116 s). Engines not
listed are ready in under a second."""

SLIDER_STEPS = 200
"""Steps across a slider's range."""

KEY_GUARD_JS = """
if (!window.mimeticKeyGuard) {
  window.mimeticKeyGuard = true;
  const cameraKeys = new Set(["KeyW", "KeyA", "KeyS", "KeyD", "KeyQ", "KeyE",
                              "ArrowUp", "ArrowDown", "ArrowLeft", "ArrowRight"]);
  document.body.addEventListener("keydown", (event) => {
    const target = event.target;
    if (cameraKeys.has(event.code) && target instanceof Element && target.closest('[role="slider"]')) {
      event.stopPropagation();
    }
  });
}
"""
"""Keeps keys pressed on a focused slider from moving the camera. viser's camera listens for the
arrow keys (and WASDQE) on ``document`` and skips text fields only, but a Mantine slider's
focusable thumb is a ``div role=slider``, so an arrow key moved the slider and turned the head.
This listener on ``body`` runs after React's (on ``#root``, inside it) has moved the slider and
stops the key before it reaches ``document``."""


class ViewError(MimeticError, RuntimeError):
    """The viewer cannot start as asked (port in use, extra missing)."""


def channel_group(name: str) -> str:
    """The folder of channel ``name`` in the channel tab (see ``GROUPS``)."""
    for group, prefixes in GROUPS:
        if name.startswith(prefixes):
            return group
    return "Other"


def display_pieces(mesh, look) -> list[tuple[str, np.ndarray, tuple[int, int, int]]]:
    """The meshes the page draws, each one colour: (name, face indices (k,), sRGB 0–255).

    One piece per part and colour (faces no part names form "surface"), keeping only the faces
    ``look`` (a ``render.appearance.Surface``) draws, so eye films and lash tips stay hidden. A part
    painted in a few flat colours (an eyeball's sclera, iris and pupil; the skin with its lips) is
    split by face colour, a face across a colour edge taking its darkest corner's colour: the edge
    then runs along a loop of vertices (a round iris, the lips' border), where a majority of
    corners zigzags from one face to the next. A textured part takes its median colour. An eyeball
    the look paints by the angle from its gaze axis is split into sclera, iris and pupil pieces by
    that angle. The pieces ride on the mesh's vertices, so an iris turns with its eye.
    """
    from mimetic.render.appearance import IRIS_ANGLE_RAD, NOT_EYE, PUPIL, PUPIL_ANGLE_RAD

    def rgb(color) -> tuple[int, int, int]:
        return tuple(round(255 * min(max(float(c), 0.0), 1.0)) for c in color)

    drawn = np.zeros(mesh.n_faces, bool)
    drawn[look.faces] = True
    parts = dict(mesh.parts)
    covered = np.zeros(mesh.n_faces, bool)
    for faces in parts.values():
        covered[faces] = True
    if not covered.all():
        parts["surface"] = np.flatnonzero(~covered)
    pieces = []
    for name, face_ids in parts.items():
        face_ids = face_ids[drawn[face_ids]]
        if len(face_ids) == 0:
            continue
        corners = mesh.faces[face_ids]
        gaze = look.gaze_cos[corners].mean(axis=1)
        if (look.gaze_cos[corners] == NOT_EYE).any():
            corner_levels = np.round(look.colors[corners] * COLOR_LEVELS)  # (k, 3 corners, rgb)
            darkest = (corner_levels @ LUMINANCE).argmin(axis=1)  # (k,)
            levels = corner_levels[np.arange(len(face_ids)), darkest]  # (k, rgb)
            distinct, which = np.unique(levels, axis=0, return_inverse=True)
            if len(distinct) > MAX_PAINTED_COLORS:  # a texture
                pieces.append((name, face_ids, rgb(np.median(look.colors[np.unique(corners)], axis=0))))
                continue
            counts = np.bincount(which.ravel())
            order = np.argsort(-counts)  # the part's main colour keeps its name
            for rank, k in enumerate(order):
                piece = name if rank == 0 else f"{name}_{rank}"
                pieces.append((piece, face_ids[which.ravel() == k], rgb(distinct[k] / COLOR_LEVELS)))
            continue
        pupil, iris = gaze >= np.cos(PUPIL_ANGLE_RAD), gaze >= np.cos(IRIS_ANGLE_RAD)
        sclera = np.median(look.colors[np.unique(corners[~iris])], axis=0) if (~iris).any() else None
        for piece, mask, color in (
            (name, ~iris, sclera),
            (f"{name}_iris", iris & ~pupil, look.iris_colors[np.unique(corners[iris])].mean(axis=0)),
            (f"{name}_pupil", pupil, PUPIL),
        ):
            if mask.any():
                pieces.append((piece, face_ids[mask], rgb(color)))
    return _welded(mesh.faces, pieces)


def _welded(
    faces: np.ndarray, pieces: list[tuple[str, np.ndarray, tuple[int, int, int]]]
) -> list[tuple[str, np.ndarray, tuple[int, int, int]]]:
    """``pieces`` with those of one colour that share a vertex joined (under the first one's name).

    The browser computes each piece's normals from its own faces, so a border between two pieces
    is a shading seam: between parts of one colour that meet (ICT's face and head-and-neck parts,
    across the forehead) it had no reason to be there.
    """
    groups: list[list[int]] = []
    vertices: list[np.ndarray] = []
    for k, (_, face_ids, color) in enumerate(pieces):
        used = np.unique(faces[face_ids])
        for g, group in enumerate(groups):
            if pieces[group[0]][2] == color and np.isin(used, vertices[g]).any():
                group.append(k)
                vertices[g] = np.union1d(vertices[g], used)
                break
        else:
            groups.append([k])
            vertices.append(used)
    return [
        (pieces[g[0]][0], np.sort(np.concatenate([pieces[k][1] for k in g])), pieces[g[0]][2]) for g in groups
    ]


def prepare_text(name: str, done: int, total: int, elapsed_s: float) -> str:
    """The progress of engine ``name``'s preparation as the page shows it, e.g. "preparing tissue:
    12/40, 31 s" (its stages, then its bake's poses, each counted by ``Deformers.prepare``)."""
    return f"preparing {name}: {done}/{total}, {elapsed_s:.0f} s"


def check_port(host: str, port: int) -> None:
    """ViewError unless ``port`` on ``host`` is free (a second viewer on the same port)."""
    with socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_STREAM) as probe:
        try:
            probe.bind((host, port))
        except OSError as error:
            if error.errno == errno.EADDRINUSE:
                raise ViewError(
                    f"port {port} on {host} is already in use (another `mimetic view`?). Stop that "
                    f"viewer, or pass --port {port + 1}."
                ) from None
            raise ViewError(f"cannot listen on {host}:{port}: {error.strerror or error}") from None


def check_capture(source: Path, capture: str | os.PathLike[str]) -> None:
    """Fail before serving when ``capture`` cannot play on ``source``: a mesh rather than a rig, or
    ``session.check_live_source``'s reasons (mediapipe missing, no such file or device, not a video)."""
    from mimetic.view.session import check_live_source

    if Path(source).suffix.lower() in MESH_SUFFIXES:
        raise ViewError(f"--capture plays on a rig, and {Path(source).name} is a mesh; pass a .mrig rig")
    check_live_source(capture)


def check_speak(source: Path, speak: str | os.PathLike[str]) -> None:
    """Fail before serving when ``speak`` cannot be lip-synced live on ``source``: a mesh rather than a
    rig, or ``session.check_speech_source``'s reasons (pocketsphinx missing, not a PCM WAV file)."""
    from mimetic.view.session import check_speech_source

    if Path(source).suffix.lower() in MESH_SUFFIXES:
        raise ViewError(f"--speak plays on a rig, and {Path(source).name} is a mesh; pass a .mrig rig")
    check_speech_source(speak)


def _viser():
    try:
        import viser
    except ImportError as error:
        raise MissingExtraError(f"the viewer needs viser ({error}); pip install 'mimetic[view]'") from None
    return viser


def run_javascript(server, source: str) -> None:
    """Run ``source`` in every page of ``server``, now and on every page opened later (viser's
    message for it is kept in the buffer each new client replays; viser has no public call)."""
    from viser._messages import RunJavascriptMessage

    server._websock_server.queue_message(RunJavascriptMessage(source=source))


def _escape(text: str) -> str:
    """``text`` shown literally in markdown (a file name with underscores, a ``<`` in a message)."""
    return re.sub(r"([\\`*_{}\[\]<>#|])", r"\\\1", text)


def _label(name: str) -> str:
    return name.replace("_", " ")


def _step(lo: float, hi: float) -> float:
    return float(f"{(hi - lo) / SLIDER_STEPS:.2g}")


class Viewer:
    """The page for one rig (or mesh) on a running ``viser.ViserServer``.

    ``server`` is the viser server; ``source`` the .mrig rig (or a mesh, for picking); ``engine``
    the engine shown first; ``clip``/``audio`` a clip JSON (and its sound) loaded on the timeline;
    ``landmarks_out`` where picked landmarks are written (default: beside ``source``); ``capture`` a
    video file or camera device played live on the rig (``session.LivePlayback``, given
    ``capture_options``). ``stop()`` ends the capture, then the server.
    """

    def __init__(
        self,
        server,
        source: Path,
        *,
        engine: str = "wire",
        clip: Path | None = None,
        audio: Path | None = None,
        landmarks_out: Path | None = None,
        capture: str | os.PathLike[str] | None = None,
        capture_options: dict | None = None,
        speak: str | os.PathLike[str] | None = None,
    ) -> None:
        self.server = server
        self.source = Path(source)
        self.landmarks_out = landmarks_out or self.source.with_name(f"{self.source.stem}.landmarks.json")
        self.error: str | None = None
        self.session = None
        self.timeline = None
        self.engine = engine
        self.preparing: str | None = None  # the progress of an engine being prepared
        self.facing = next(iter(FACINGS))
        self.turn = np.eye(3)
        self.parts: list[tuple[np.ndarray, object]] = []
        self.sliders: dict[tuple[str, str], object] = {}
        self._syncing = False
        self._lock = threading.RLock()
        self._playing = threading.Event()
        self.last_update_ms = 0.0
        self.vertices: np.ndarray | None = None
        self.pose: np.ndarray | None = None
        self.audio: tuple[bytes, str] | None = None  # the timeline's sound and its MIME type
        if capture is not None and speak is not None:
            raise ViewError("give --capture or --speak, not both: each drives the face live")
        self.capture = None if capture is None else str(capture)
        self.speak = speak is not None  # ``capture`` is then a WAV file lip-synced live
        if speak is not None:
            self.capture = str(speak)
        self.live = None  # the session.LivePlayback of ``capture``
        self.live_text = None
        self._live_posed = False  # a live frame has posed the face
        try:
            self._load()
        except MimeticError as error:
            self.error = str(error)
            self._error_page()
            return
        self._build()
        if clip is not None:
            self._load_clip(Path(clip).read_bytes(), audio)
        if self.capture is not None:
            self._start_live(capture_options or {})

    def stop(self) -> None:
        """End the live capture (its thread and ffmpeg), then the server."""
        if self.live is not None:
            self.live.stop()
        self.server.stop()

    # ---- loading

    def _load(self) -> None:
        from mimetic.mesh.io import load_mesh
        from mimetic.tasks.prepared import prepared_rig
        from mimetic.view.session import Deformers, Picks, Session, Timeline

        if self.source.suffix.lower() in MESH_SUFFIXES:
            self.rig = None
            self.mesh = load_mesh(self.source)
        else:
            prepared = prepared_rig(self.source)  # the rig the downloads' tasks load: one bake each
            self.rig = prepared.rig
            self.mesh = self.rig.mesh
            self.session = Session(self.rig)
            self.timeline = Timeline(self.session)
            self.deformers = Deformers(prepared)
            if self.engine not in self.deformers.engines:
                raise MimeticError(f"unknown engine {self.engine!r}; choose one of {self.deformers.engines}")
            self.deformers.prepare(self.engine)
            self.pose = self.session.pose()
        self.picks = Picks(self.mesh.faces)
        self.vertices = self.mesh.vertices.astype(np.float32)

    def _error_page(self) -> None:
        self.server.gui.add_markdown(
            f"### Cannot open `{self.source.name}`\n\n{_escape(self.error)}\n\n"
            "Start `mimetic view` again with a `.mrig` rig (from `mimetic head --rig` or `mimetic rig`) "
            "or a mesh file."
        )

    # ---- the page

    def _build(self) -> None:
        gui, scene = self.server.gui, self.server.scene
        scene.set_up_direction("+y")
        run_javascript(self.server, KEY_GUARD_JS)
        self._add_lights()
        self.head = scene.add_frame("/head", show_axes=False)
        self._add_meshes()
        self.server.on_client_connect(self._frame_camera)
        self.status = gui.add_markdown(self._status_text())
        if self.capture is not None:
            self.live_text = gui.add_markdown(self._live_line("starting"))
        if self.session is not None:
            self._view_controls()
        tabs = gui.add_tab_group()
        if self.session is not None:
            with tabs.add_tab("Channels"):
                self._channel_tab()
            with tabs.add_tab("Expressions"):
                self._expression_tab()
            with tabs.add_tab("Descriptive"):
                self._descriptive_tab()
            with tabs.add_tab("FACS"):
                self._table_tab("facs")
            with tabs.add_tab("ARKit"):
                self._table_tab("arkit")
            with tabs.add_tab("Timeline"):
                self._timeline_tab()
        with tabs.add_tab("Landmarks"):
            self._landmark_tab()
        if self.session is not None:
            with tabs.add_tab("Export"):
                self._export_tab()

    def _add_lights(self) -> None:
        """The renderers' lights (``look.page_lights``) in place of viser's own and its
        environment map, so the page looks like its PNG export."""
        from mimetic.view.look import page_lights

        scene = self.server.scene
        scene.configure_default_lights(False)
        scene.configure_environment_map(None)
        lights = page_lights()
        scene.add_light_ambient("/lights/ambient", intensity=lights.ambient)
        size = float(np.ptp(self.mesh.vertices, axis=0).max())
        for k, (direction, intensity) in enumerate(lights.directional):
            position = tuple(float(x) for x in 10 * size * direction)  # shines toward the origin
            scene.add_light_directional(
                f"/lights/directional_{k}", intensity=intensity, position=position, cast_shadow=False
            )

    def _status_text(self) -> str:
        what = self.source.name
        n = self.mesh.n_vertices
        if self.session is None:
            return f"**{what}**: {n:,} vertices, {self.mesh.units or 'unknown units'}; pick landmarks"
        text = f"**{what}**: {n:,} vertices · engine {self.engine} · pose {self.last_update_ms:.1f} ms"
        return text if self.preparing is None else f"{text} · {self.preparing}"

    def _add_meshes(self) -> None:
        from mimetic.render.appearance import surface
        from mimetic.render.raster import ALBEDO
        from mimetic.view.look import rig_look

        scene, mesh = self.server.scene, self.mesh
        look = rig_look(self.rig) if self.rig is not None else surface(mesh, ALBEDO)
        for name, face_ids, color in display_pieces(mesh, look):
            used, local = np.unique(mesh.faces[face_ids], return_inverse=True)
            handle = scene.add_mesh_simple(
                f"/head/part/{name}", self.vertices[used], local.reshape(-1, 3), color=color, side="double"
            )
            self.parts.append((used, handle))
        self.wireframe = scene.add_mesh_simple(
            "/head/overlay/wireframe",
            self.vertices,
            mesh.faces,
            color=(40, 40, 40),
            wireframe=True,
            visible=False,
        )
        self.muscle_lines = None
        self._rest_muscles: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None
        self.landmark_points = None
        scene.on_click()(self._clicked)

    def _frame_camera(self, client) -> None:
        """Put ``client``'s camera in front of the face, +Y up (the display frame)."""
        shown = self.mesh.vertices @ self.turn.T
        low, high = shown.min(axis=0), shown.max(axis=0)
        centre, size = (low + high) / 2, float((high - low).max())
        with client.atomic():  # position first: setting it moves look_at along
            client.camera.position = centre + np.array([0.0, 0.0, high[2] - centre[2] + 0.55 * size])
            client.camera.look_at = centre
            client.camera.up = (0.0, 1.0, 0.0)

    def _face(self, facing: str) -> None:
        """Stand a mesh whose file has another convention (``FACINGS``) +Y up, facing +Z, for the
        display only: the head's frame turns; the coordinates, and picked landmarks, are the file's."""
        from scipy.spatial.transform import Rotation

        up, forward = (np.array(axis, dtype=np.float64) for axis in FACINGS[facing])
        self.facing = facing
        self.turn = np.stack([np.cross(up, forward), up, forward])  # rows: file axes → display x, y, z
        self.head.wxyz = Rotation.from_matrix(self.turn).as_quat(scalar_first=True)
        for client in self.server.get_clients().values():
            self._frame_camera(client)

    def _notify(self, title: str, body: str, *, loading: bool = False, color: str | None = None):
        return [
            client.add_notification(
                title, body, loading=loading, color=color, auto_close_seconds=None if loading else 6.0
            )
            for client in self.server.get_clients().values()
        ]

    def _view_controls(self) -> None:
        from mimetic.engines import ENGINES

        gui = self.server.gui
        engine = gui.add_dropdown("Engine", ENGINES, initial_value=self.engine)
        engine.on_update(lambda event: self._switch_engine(event.target.value))
        symmetric = gui.add_checkbox(
            "Symmetry lock", False, hint="Moving a left control moves the right too."
        )
        symmetric.on_update(lambda event: setattr(self.session, "symmetric", event.target.value))
        wire = gui.add_checkbox("Wireframe", False)
        wire.on_update(lambda event: setattr(self.wireframe, "visible", event.target.value))
        muscles = gui.add_checkbox("Muscles", False, hint="The muscles as lines, origin to insertion.")
        muscles.on_update(lambda event: self._show_muscles(event.target.value))
        reset = gui.add_button("Reset pose")
        reset.on_click(lambda _: self._show_pose(self.session.defaults))

    # ---- tabs

    def _slider(self, layer: str, key: str, label: str, lo: float, hi: float, value: float, hint: str = ""):
        slider = self.server.gui.add_slider(label, lo, hi, _step(lo, hi), value, hint=hint or None)
        self.sliders[(layer, key)] = slider

        def moved(event) -> None:
            if self._syncing:
                return
            with self._lock:
                if layer == "channels":
                    changed = self.session.set_channel(key, event.target.value)
                else:
                    changed = self.session.set_layer(layer, key, event.target.value)
                self._sync(layer, [k for k in changed if k != key])
                self._refresh()

        slider.on_update(moved)
        return slider

    def _channel_tab(self) -> None:
        gui = self.server.gui
        grouped: dict[str, list] = {}
        for channel in self.rig.channels:
            grouped.setdefault(channel_group(channel.name), []).append(channel)
        order = [g for g, _ in GROUPS] + ["Other"]
        for group in order:
            if group not in grouped:
                continue
            with gui.add_folder(group, expand_by_default=group == "Mouth"):
                for c in grouped[group]:
                    unit = "" if c.unit == "activation" else f" ({c.unit})"
                    self._slider("channels", c.name, _label(c.name) + unit, c.minimum, c.maximum, c.default)

    def _expression_tab(self) -> None:
        gui = self.server.gui
        names = ("(none)", *self.session.library.names)
        choice = gui.add_dropdown("Expression", names, initial_value="(none)")
        intensity = gui.add_slider("Intensity", 0.0, 1.5, 0.01, 1.0)

        def changed(_) -> None:
            with self._lock:
                name = None if choice.value == "(none)" else choice.value
                self.session.set_expression(name, intensity.value)
                self._refresh()

        choice.on_update(changed)
        intensity.on_update(changed)
        self.expression_choice, self.expression_intensity = choice, intensity
        gui.add_markdown("Expressions add to the other tabs' sliders; *Reset pose* clears them all.")

    def _descriptive_tab(self) -> None:
        from mimetic.animate.controls import descriptive_controls

        gui = self.server.gui
        gui.add_markdown(
            "The thesis's descriptive sliders; in pairs the left slider moves the face's right side."
        )
        for control in descriptive_controls():
            if not all(c in self.session.index for c in control.channels):
                continue
            sides = ("left", "right") if control.paired else ("",)
            for side, channel in zip(sides, control.channels, strict=True):
                label = f"{control.name} ({side})" if side else control.name
                channel_range = self.rig.channel(channel)
                self._slider(
                    "descriptive", channel, label, 0.0, channel_range.maximum, 0.0, control.description
                )

    def _table_tab(self, layer: str) -> None:
        from mimetic.animate.arkit import arkit_table
        from mimetic.animate.facs import action_units, parse_key
        from mimetic.view.session import arkit_keys, facs_keys

        if layer == "facs":
            units = action_units()
            for key in facs_keys():
                unit = units[parse_key(key)[0]]
                self._slider("facs", key, f"{key} {unit.name}", 0.0, 1.0, 0.0, unit.muscles)
        else:
            table = arkit_table()
            for key in arkit_keys():
                self._slider("arkit", key, key, 0.0, 1.0, 0.0, table[key].description)

    def _timeline_tab(self) -> None:
        gui = self.server.gui
        self.time = gui.add_slider("Time (s)", 0.0, 2.0, 1.0 / 30.0, 0.0)
        self.time.on_update(self._scrubbed)
        key = gui.add_button("Set key", hint="Key the face as it is now at this time.")
        key.on_click(lambda _: self._set_key())
        delete = gui.add_button("Delete key")
        delete.on_click(lambda _: self._delete_key())
        play = gui.add_button("Play")
        play.on_click(lambda _: self._play())
        stop = gui.add_button("Stop")
        stop.on_click(lambda _: self._stop())
        self.loop = gui.add_checkbox("Loop", False)
        upload = gui.add_upload_button("Load clip (JSON)", mime_type="application/json")
        upload.on_upload(lambda event: self._load_clip(event.target.value.content))
        sound = gui.add_upload_button("Load sound (WAV)", mime_type="audio/*")
        sound.on_upload(lambda event: self._set_audio(event.target.value.content, event.target.value.name))
        clear = gui.add_button("Clear timeline")
        clear.on_click(lambda _: self._clear_timeline())
        self.keys_text = gui.add_markdown("No keys yet.")
        self.player = gui.add_html("")

    def _landmark_tab(self) -> None:
        from mimetic.fit.landmarks import PROJECT_LANDMARKS
        from mimetic.view.session import PICK_LANDMARKS

        gui = self.server.gui
        gui.add_markdown(
            "Turn on *Pick*, choose a landmark and click it on the face; the next one is chosen for you. "
            "*Save* writes a landmarks file for `mimetic rig --landmarks`."
        )
        self.picking = gui.add_checkbox("Pick", self.session is None)
        names = PICK_LANDMARKS + tuple(n for n in PROJECT_LANDMARKS if n not in PICK_LANDMARKS)
        self.landmark_choice = gui.add_dropdown("Landmark", names, initial_value=names[0])
        remove = gui.add_button("Remove this landmark")
        remove.on_click(lambda _: self._remove_landmark())
        facing = gui.add_dropdown("File convention", tuple(FACINGS), initial_value=self.facing)
        facing.on_update(lambda event: self._face(event.target.value))
        save = gui.add_button("Save landmarks")
        save.on_click(lambda _: self._save_landmarks())
        self.picks_text = gui.add_markdown("Nothing picked yet.")

    def _export_tab(self) -> None:
        gui = self.server.gui
        gui.add_markdown("Downloads of what the viewer shows, with the current engine.")
        for label, action in (
            ("GLB (morph targets, timeline clip)", self._export_glb),
            ("FBX (the same, through Blender)", self._export_fbx),
            ("PNG (front view)", self._export_png),
            ("Clip JSON", self._export_clip),
        ):
            button = gui.add_button(label)
            button.on_click(lambda _, action=action: self._guarded(action))

    # ---- updating the face

    def _sync(self, layer: str, keys: list[str]) -> None:
        """Show the session's values on ``keys``' sliders without re-running their callbacks."""
        self._syncing = True
        try:
            values = self.session.channels if layer == "channels" else getattr(self.session, layer)
            for key in keys:
                slider = self.sliders.get((layer, key))
                if slider is not None:
                    value = values[self.session.index[key]] if layer == "channels" else values.get(key, 0.0)
                    slider.value = float(value)
        finally:
            self._syncing = False

    def _sync_all(self) -> None:
        self._syncing = True
        try:
            for (layer, key), slider in self.sliders.items():
                if layer == "channels":
                    slider.value = float(self.session.channels[self.session.index[key]])
                else:
                    slider.value = float(getattr(self.session, layer).get(key, 0.0))
            self.expression_choice.value = self.session.expression or "(none)"
            self.expression_intensity.value = self.session.intensity
        finally:
            self._syncing = False

    def _refresh(self, pose: np.ndarray | None = None) -> None:
        """Pose the face (``pose`` (c,), default the session's) and send the new vertices."""
        start = time.perf_counter()
        pose = self.session.pose() if pose is None else pose
        self.pose = pose
        self.vertices = self.deformers.vertices(self.engine, pose)
        self._send_vertices()
        self.server.flush()  # send now, not at viser's next 1/60 s window (12–16 ms sooner)
        self.last_update_ms = 1e3 * (time.perf_counter() - start)
        self.status.content = self._status_text()

    def _send_vertices(self) -> None:
        with self.server.atomic():
            for used, handle in self.parts:
                handle.vertices = self.vertices[used]
            if self.wireframe.visible:
                self.wireframe.vertices = self.vertices
            if self.muscle_lines is not None and self.muscle_lines.visible:
                self.muscle_lines.points = self._muscle_points()
            self._draw_picks()

    def _show_pose(self, pose: np.ndarray) -> None:
        with self._lock:
            self.session.show(pose)
            self._sync_all()
            self._refresh()

    def _switch_engine(self, name: str) -> None:
        if self.deformers.ready(name):
            self.engine = name
            self._refresh()
            return
        wait = PREPARE_NOTE.get(name, "under a second")
        notes = self._notify(f"Preparing the {name} engine", f"This takes {wait}, once.", loading=True)
        started = time.perf_counter()

        def progress(done: int, total: int) -> None:
            """The preparation's stages, then its bake's poses: in the notes and the status line."""
            self.preparing = prepare_text(name, done, total, time.perf_counter() - started)
            for note in notes:
                note.body = f"This takes {wait}, once. {self.preparing}"
            self.status.content = self._status_text()

        def work() -> None:
            try:
                self.deformers.prepare(name, progress)
            except MimeticError as error:
                self._notify(f"The {name} engine failed", str(error), color="red")
                return
            finally:
                self.preparing = None
                self.status.content = self._status_text()
                for note in notes:
                    note.remove()
            with self._lock:
                self.engine = name
                self._refresh()

        threading.Thread(target=work, daemon=True).start()

    def _muscle_points(self) -> np.ndarray:
        """The muscle overlay's segments (k, 2, 3) on the face as shown: insertions and sphincter
        rings on the posed skin, bony attachments carried by the head bone."""
        from mimetic.engines.skinning import bone_transforms
        from mimetic.view.muscles import muscle_segments

        segments, _, ring = muscle_segments(self.rig, vertices=self.vertices)
        if self._rest_muscles is None:
            self._rest_muscles = muscle_segments(self.rig)
        rest = self._rest_muscles[0]
        head = bone_transforms(self.rig, self.pose)[self.rig.bone_index("head")]
        segments[~ring, 0] = rest[~ring, 0] @ head[:3, :3].T + head[:3, 3]
        return segments.astype(np.float32)

    def _show_muscles(self, visible: bool) -> None:
        if self.muscle_lines is None:
            points = self._muscle_points()
            colors = self._rest_muscles[1]
            rgb = (np.repeat(colors[:, None, :], 2, axis=1) * 255).astype(np.uint8)
            self.muscle_lines = self.server.scene.add_line_segments(
                "/head/overlay/muscles", points, rgb, line_width=2.5
            )
        else:
            self.muscle_lines.points = self._muscle_points()
        self.muscle_lines.visible = visible

    # ---- live capture

    def _live_line(self, text: str) -> str:
        what = "Live lip sync" if self.speak else "Live capture"
        return f"**{what}** of `{Path(self.capture).name}`: {_escape(text)}"

    def _start_live(self, options: dict) -> None:
        """Play ``self.capture`` on the rig as it arrives (``session.LivePlayback``)."""
        from mimetic.view.session import LivePlayback, SpeechPlayback

        if self.session is None:
            self.live_text.content = self._live_line(
                f"error: {self.source.name} is a mesh; live capture plays on a .mrig rig"
            )
            return
        self._playing.clear()  # the timeline stops: the capture drives the face
        self.live = (SpeechPlayback if self.speak else LivePlayback)(
            self.rig, self.capture, show=self._show_live, report=self._live_reported, **options
        )
        self.live.start()

    def _show_live(self, time_s: float, values: np.ndarray) -> None:
        """Pose the face with a live frame's values (c,) (sliders are synced when the capture ends)."""
        with self._lock:
            self._refresh(np.clip(values, self.session.lower, self.session.upper))
            self._live_posed = True

    def _live_reported(self, status) -> None:
        """Show a ``session.LiveStatus``; at the end, the sliders take the last pose shown."""
        self.live_text.content = self._live_line(status.text())
        if status.state == "failed":
            self._notify("Live capture failed", status.error, color="red")
        if status.done and self._live_posed:
            self._show_pose(self.pose)

    # ---- timeline

    def _set_key(self) -> None:
        with self._lock:
            self.timeline.set_key(self.time.value, self.session.pose())
            self._timeline_changed()

    def _delete_key(self) -> None:
        with self._lock:
            if not self.timeline.delete_key(self.time.value):
                self._notify("No key here", f"No key within half a frame of {self.time.value:.3f} s.")
            self._timeline_changed()

    def _clear_timeline(self) -> None:
        with self._lock:
            self._playing.clear()
            self.timeline.clear()
            self.audio = None
            self.player.content = ""
            self._timeline_changed()

    def _timeline_changed(self) -> None:
        timeline = self.timeline
        if timeline.loaded is not None:
            clip = timeline.loaded
            text = f"Clip: {clip.duration_s:.2f} s, {len(clip.channels)} channels, layers " + ", ".join(
                layer.name for layer in clip.layers
            )
        elif timeline.keys:
            text = "Keys at " + ", ".join(f"{t:g}" for t in sorted(timeline.keys)) + " s"
        else:
            text = "No keys yet."
        self.keys_text.content = text
        self.time.max = max(2.0, timeline.duration_s + 1.0)

    def _load_clip(self, data: bytes, audio: Path | None = None) -> None:
        import tempfile

        from mimetic.animate.clipfiles import load_clip

        with tempfile.TemporaryDirectory() as folder:
            path = Path(folder) / "clip.json"
            path.write_bytes(data)
            try:
                clip = load_clip(path)
                with self._lock:
                    self.timeline.load(clip)
            except (MimeticError, KeyError) as error:
                self._notify("Cannot load the clip", str(error), color="red")
                print(f"error: cannot load the clip: {error}")
                return
        if audio is not None:
            self._set_audio(Path(audio).read_bytes(), Path(audio).name)
        self._timeline_changed()

    def _set_audio(self, data: bytes, name: str) -> None:
        self.audio = (data, "audio/wav" if name.lower().endswith(".wav") else "audio/mpeg")
        self.player.content = self._player_html(autoplay=False)

    def _player_html(self, *, autoplay: bool, start_s: float = 0.0) -> str:
        data, kind = self.audio
        source = f"data:{kind};base64,{base64.b64encode(data).decode()}#t={start_s:.3f}"
        seek = f'onloadedmetadata="this.currentTime={start_s:.3f}"'  # where #t= is not honoured
        return f'<audio controls {"autoplay" if autoplay else ""} {seek} src="{source}"></audio>'

    def _stop(self) -> None:
        """Stop playback and its sound (the player is replaced by a paused one)."""
        self._playing.clear()
        if self.audio is not None:
            self.player.content = self._player_html(autoplay=False)

    def _scrubbed(self, event) -> None:
        if self._syncing or self._playing.is_set():
            return
        pose = self.timeline.pose_at(event.target.value)
        if pose is not None:
            self._show_pose(pose)

    def _play(self) -> None:
        """Play the timeline from the time slider (from the start when it is at the end), sampled
        once at ``FPS``; frames are dropped, not slowed, when posing falls behind."""
        from mimetic.view.session import FPS

        if self.timeline.clip() is None or self._playing.is_set():
            return
        frames = self.timeline.frames(FPS)
        first = round(self.time.value * FPS)
        first = first if first < len(frames) - 1 else 0
        self._playing.set()
        if self.audio is not None:
            self.player.content = self._player_html(autoplay=True, start_s=first / FPS)

        def run() -> None:
            began = time.perf_counter() - first / FPS
            frame = first
            while self._playing.is_set():
                frame = int((time.perf_counter() - began) * FPS)
                if frame >= len(frames):
                    if not self.loop.value:
                        frame = len(frames) - 1
                        break
                    began, frame = time.perf_counter(), 0
                with self._lock:
                    self._refresh(frames[frame])
                    self._syncing = True
                    self.time.value = frame / FPS
                    self._syncing = False
                time.sleep(max(0.0, (frame + 1) / FPS - (time.perf_counter() - began)))
            self._playing.clear()
            with self._lock:
                self._syncing = True
                self.time.value = frame / FPS
                self._syncing = False
                self._show_pose(frames[frame])

        threading.Thread(target=run, daemon=True).start()

    # ---- landmarks

    def _clicked(self, event) -> None:
        from mimetic.view.session import PICK_LANDMARKS, pick

        if not self.picking.value:
            return
        origin, direction = (self.turn.T @ np.array(v) for v in (event.ray_origin, event.ray_direction))
        hit = pick(self.vertices, self.mesh.faces, origin, direction)  # in the file's frame
        if hit is None:
            return
        face, bary, _ = hit
        with self._lock:
            self.picks.add(self.landmark_choice.value, face, bary)
            following = self.picks.next_name(PICK_LANDMARKS)
            if following is not None:
                self.landmark_choice.value = following
            self._draw_picks()
            self._picks_changed()

    def _remove_landmark(self) -> None:
        self.picks.remove(self.landmark_choice.value)
        self._draw_picks()
        self._picks_changed()

    def _draw_picks(self) -> None:
        if self.landmark_points is not None:
            self.landmark_points.remove()
            self.landmark_points = None
        if not self.picks.points:
            return
        positions = self.picks.positions(self.vertices)
        points = np.array(list(positions.values()), np.float32).reshape(-1, 3)
        size = float(np.ptp(self.mesh.vertices, axis=0).max())
        self.landmark_points = self.server.scene.add_point_cloud(
            "/head/overlay/landmarks", points, (30, 200, 90), point_size=0.012 * size, point_shape="circle"
        )

    def _picks_changed(self) -> None:
        from mimetic.fit.landmarks import MIN_LANDMARKS

        names = list(self.picks.points)
        more = max(0, MIN_LANDMARKS - len(names))
        self.picks_text.content = (
            f"{len(names)} picked: {', '.join(names)}" + (f" ({more} more needed)" if more else "")
            if names
            else "Nothing picked yet."
        )

    def landmarks(self):
        """The picked landmarks in the source file's own frame and units (``fit.Landmarks``)."""
        from mimetic.fit.landmarks import Landmarks

        vertices = self.mesh.vertices if self.rig is None else self.rig.source_mesh().vertices
        positions = self.picks.positions(vertices)
        units = self.mesh.units
        names = tuple(positions)
        return Landmarks(
            names,
            np.array([positions[n] for n in names]).reshape(-1, 3),
            np.ones(len(names)),
            units,
            f"picked:{self.source.name}",
        )

    def _save_landmarks(self) -> None:
        from mimetic.fit.landmarks import MIN_LANDMARKS, write_landmarks

        if len(self.picks.points) < MIN_LANDMARKS:
            self._notify(
                "Not enough landmarks", f"Pick at least {MIN_LANDMARKS} before saving.", color="yellow"
            )
            return
        path = write_landmarks(self.landmarks(), self.landmarks_out)
        self._notify("Landmarks saved", f"{path}")
        print(f"wrote {path}")

    # ---- exports

    def _guarded(self, action: Callable[[], tuple[str, bytes]]) -> None:
        notes = self._notify("Exporting", "", loading=True)
        try:
            name, data = action()
        except (MimeticError, ValueError) as error:
            self._notify("Export failed", str(error), color="red")
            return
        finally:
            for note in notes:
                note.remove()
        self.server.send_file_download(name, data, save_immediately=True)

    def _export_glb(self) -> tuple[str, bytes]:
        from mimetic.view.exports import scene_bytes

        return f"{self.source.stem}.glb", scene_bytes(self.source, self.engine, self.timeline.clip())

    def _export_fbx(self) -> tuple[str, bytes]:
        from mimetic.view.exports import scene_bytes

        return f"{self.source.stem}.fbx", scene_bytes(self.source, self.engine, self.timeline.clip(), ".fbx")

    def _export_png(self) -> tuple[str, bytes]:
        from mimetic.view.exports import png_bytes

        data = png_bytes(
            self.source,
            self.engine,
            self.pose,
            self.rig.channel_names,
            lambda pose: self.deformers.vertices(self.engine, pose),
        )
        return f"{self.source.stem}.png", data

    def _export_clip(self) -> tuple[str, bytes]:
        return f"{self.source.stem}.clip.json", self.timeline.clip_json()


def start(
    source: Path,
    *,
    host: str = "127.0.0.1",
    port: int = 8080,
    engine: str = "wire",
    clip: Path | None = None,
    audio: Path | None = None,
    landmarks_out: Path | None = None,
    capture: str | os.PathLike[str] | None = None,
    capture_options: dict | None = None,
    speak: str | os.PathLike[str] | None = None,
) -> Viewer:
    """Start the viewer's server (in background threads) and build the page; ``viewer.stop()`` ends it
    (and ``capture``'s thread). ViewError when the port is taken; a rig that cannot be read shows its
    error in the page (``viewer.error``), and so does a capture that fails (``viewer.live.status``)."""
    viser = _viser()
    if port:
        check_port(host, port)
    with contextlib.redirect_stdout(io.StringIO()):  # viser's own banner; the CLI prints the address
        server = viser.ViserServer(host=host, port=port, label="mimetic", verbose=False)
    if port and server.get_port() != port:
        server.stop()
        raise ViewError(f"port {port} on {host} was taken while the viewer started; pass --port {port + 1}")
    try:
        return Viewer(
            server,
            source,
            engine=engine,
            clip=clip,
            audio=audio,
            landmarks_out=landmarks_out,
            capture=capture,
            capture_options=capture_options,
            speak=speak,
        )
    except BaseException:
        server.stop()
        raise
