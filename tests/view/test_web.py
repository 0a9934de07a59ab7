"""The web viewer's server without a browser: the page's callbacks, bad input, ports, the CLI.

Slider handles are driven from Python (``handle.value = x`` runs the same callback as a move in the
page); the browser itself is tested in ``test_browser.py``.
"""

from __future__ import annotations

import io
import os
import socket
import subprocess
import sys
import time
import urllib.request
from dataclasses import dataclass

import numpy as np
import pytest
from PIL import Image

from mimetic.animate.clipfiles import load_clip, save_clip
from mimetic.animate.expressions import expression_pose
from mimetic.animate.keyframes import from_poses
from mimetic.engines import make_engine
from mimetic.fit.landmarks import MIN_LANDMARKS, read_landmarks
from mimetic.mesh.io import save_mesh
from mimetic.mesh.model import Mesh
from mimetic.testing import require_extra, run_cli
from mimetic.view.session import PICK_LANDMARKS

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


@pytest.fixture(scope="module")
def web():
    require_extra("viser", "view")
    from mimetic.view import web

    return web


@pytest.fixture
def viewer(web, rig_file):
    viewer = web.start(rig_file, port=0)
    yield viewer
    viewer.server.stop()


def page(viewer) -> str:
    with urllib.request.urlopen(f"http://127.0.0.1:{viewer.server.get_port()}/", timeout=30) as response:
        assert response.status == 200
        return response.read().decode()


def test_without_the_extra_the_viewer_says_what_to_install(monkeypatch, tmp_path):
    from mimetic.errors import MissingExtraError
    from mimetic.view import web

    monkeypatch.setitem(sys.modules, "viser", None)  # import viser fails
    with pytest.raises(MissingExtraError, match=r"pip install 'mimetic\[view\]'"):
        web.start(tmp_path / "any.mrig", port=0)


def test_channel_groups_follow_the_thesis_tab(web, rig):
    groups = {name: web.channel_group(name) for name in rig.channel_names}
    assert groups["frontalis_inner_L"] == "Brows and eyes"
    assert groups["zygomatic_major_R"] == "Cheeks and nose"
    assert groups["orbicularis_oris"] == "Mouth"
    assert groups["jaw_open"] == "Jaw"
    assert groups["gaze_yaw"] == "Gaze"
    assert groups["tongue_out"] == "Tongue"
    assert groups["depressor_supercilii_L"] == "Brows and eyes" and groups["depressor_labii_L"] == "Mouth"
    assert {groups[n] for n in ("depressor_septi", "nasalis_alar_R", "nasalis_transverse_L")} == {
        "Cheeks and nose"
    }
    assert "Other" not in groups.values()


def test_display_pieces_draw_each_face_once_and_paint_the_eyes(web, rig):
    from mimetic.render.raster import ALBEDO
    from mimetic.view.look import rig_look

    look = rig_look(rig)
    pieces = {name: (faces, color) for name, faces, color in web.display_pieces(rig.mesh, look)}
    drawn = np.sort(np.concatenate([faces for faces, _ in pieces.values()]))
    np.testing.assert_array_equal(drawn, np.sort(look.faces))
    for eye in ("eye_L", "eye_R"):  # painted in flat colours: sclera, iris, pupil
        shades = sorted(sum(color) for name, (_, color) in pieces.items() if name.startswith(eye))
        assert len(shades) == 3 and shades[0] < 40 and shades[2] > 600
    skin = pieces["skin"][1]
    assert np.abs(np.array(skin) - 255 * np.array(ALBEDO)).max() < 12  # the main colour keeps the name


def test_error_text_is_shown_literally(web):
    assert web._escape("bad_file_name.mrig: <missing> *x*") == r"bad\_file\_name.mrig: \<missing\> \*x\*"


def test_a_slider_move_poses_every_part_like_the_engine(viewer, rig):
    viewer.sliders[("channels", "jaw_open")].value = 0.3
    pose = viewer.session.pose()
    assert pose[viewer.session.index["jaw_open"]] == pytest.approx(0.3)
    expected = make_engine(rig, "wire").deform(pose)
    np.testing.assert_allclose(viewer.vertices, expected, atol=1e-4)
    shown = np.zeros_like(expected)
    for used, handle in viewer.parts:
        shown[used] = handle.vertices
    np.testing.assert_allclose(shown, expected, atol=1e-4)  # what the page is sent
    assert viewer.last_update_ms > 0


def test_the_symmetry_lock_moves_the_other_sides_slider(viewer):
    viewer.session.symmetric = True
    viewer.sliders[("channels", "zygomatic_major_L")].value = 0.6
    assert viewer.sliders[("channels", "zygomatic_major_R")].value == pytest.approx(0.6)
    viewer.session.symmetric = False
    viewer.sliders[("channels", "zygomatic_major_L")].value = 0.1
    assert viewer.sliders[("channels", "zygomatic_major_R")].value == pytest.approx(0.6)


def test_the_muscle_overlay_follows_the_face_and_the_head_turn(viewer, rig):
    from mimetic.view.muscles import muscle_segments

    rest, _, ring = muscle_segments(rig)
    viewer.sliders[("channels", "head_yaw")].value = 0.5
    viewer.sliders[("channels", "zygomatic_major_L")].value = 1.0
    viewer._show_muscles(True)
    shown = np.asarray(viewer.muscle_lines.points, dtype=np.float64)
    pivot = rig.bone("head").head
    turned = np.linalg.norm(shown[~ring, 0] - rest[~ring, 0], axis=1)
    assert turned.min() > 0.01 * rig.scale  # every bony attachment turned with the head
    np.testing.assert_allclose(  # rigidly, about the head bone
        np.linalg.norm(shown[~ring, 0] - pivot, axis=1),
        np.linalg.norm(rest[~ring, 0] - pivot, axis=1),
        rtol=1e-4,
    )
    np.testing.assert_allclose(
        shown[:, 1], muscle_segments(rig, vertices=viewer.vertices)[0][:, 1], atol=1e-3
    )


def test_expression_choice_shows_the_library_pose(viewer, rig):
    viewer.expression_intensity.value = 1.0
    viewer.expression_choice.value = "surprise"
    np.testing.assert_allclose(viewer.session.pose(), expression_pose(rig, "surprise"), atol=1e-12)


def test_keys_play_back_and_export_as_a_clip(viewer, rig, tmp_path):
    viewer.time.value = 0.0
    viewer._set_key()
    viewer.time.value = 1.0  # as in Blender: go to the time, pose, key
    viewer.sliders[("channels", "jaw_open")].value = 0.25
    viewer._set_key()
    assert "Keys at 0, 1 s" in viewer.keys_text.content
    name, data = viewer._export_clip()
    path = tmp_path / name
    path.write_bytes(data)
    assert load_clip(path).evaluate(np.array([1.0]))[0][rig.channel_index("jaw_open")] == pytest.approx(0.25)
    viewer.time.value = 0.5  # scrubbing shows the clip's pose there
    jaw = viewer.session.pose()[viewer.session.index["jaw_open"]]
    assert 0.0 < jaw < 0.25


def test_play_runs_the_clip_to_its_end(viewer, rig):
    rest = viewer.session.defaults
    viewer.timeline.load(from_poses([(0.0, rest), (0.3, expression_pose(rig, "joy"))], rig))
    viewer._timeline_changed()
    viewer.time.value = 0.0
    viewer._play()
    deadline = time.monotonic() + 10
    while viewer._playing.is_set() and time.monotonic() < deadline:
        time.sleep(0.05)
    assert not viewer._playing.is_set()
    time.sleep(0.2)
    np.testing.assert_allclose(viewer.session.pose(), expression_pose(rig, "joy"), atol=1e-6)


def test_a_clip_with_sound_gets_a_player(web, rig_file, rig, tmp_path):
    clip = save_clip(from_poses([(0.0, {}), (1.0, {"jaw_open": 0.2})], rig), tmp_path / "c.json")
    sound = tmp_path / "s.wav"
    sound.write_bytes(b"RIFF0000WAVEfmt ")
    viewer = web.start(rig_file, port=0, clip=clip, audio=sound)
    try:
        assert viewer.timeline.duration_s == pytest.approx(1.0)
        assert "<audio" in viewer.player.content and "audio/wav" in viewer.player.content
        assert "autoplay" in viewer._player_html(autoplay=True, start_s=0.5)
        assert "#t=0.500" in viewer._player_html(autoplay=True, start_s=0.5)
    finally:
        viewer.server.stop()


def test_a_bad_clip_is_reported_and_the_timeline_kept(viewer):
    viewer._load_clip(b"{ not json")
    assert viewer.timeline.clip() is None


def test_png_and_glb_downloads(viewer, rig, gl_renderer):
    viewer.sliders[("channels", "jaw_open")].value = 0.3
    name, data = viewer._export_png()
    image = Image.open(io.BytesIO(data))
    assert name == "small.png" and image.format == "PNG" and image.size == (768, 768)
    assert np.asarray(image).std() > 10  # a face, not a blank frame


def test_glb_download_has_a_target_per_muscle_and_the_clip(viewer, rig, tmp_path):
    from mimetic.export.gltf import read_glb_summary

    viewer.timeline.set_key(0.0, viewer.session.pose())
    viewer.timeline.set_key(0.5, expression_pose(rig, "joy"))
    name, data = viewer._export_glb()
    path = tmp_path / name
    path.write_bytes(data)
    summary = read_glb_summary(path)
    assert summary["animations"] and len(summary["target_names"]) >= len(rig.muscles)


def test_fbx_download_is_a_binary_fbx_of_the_same_scene(viewer, rig):
    from mimetic.blender import find_blender

    if find_blender() is None:
        pytest.skip("no Blender (bpy) here yet: `mimetic setup fbx` installs it (tests/clients check FBX)")
    viewer.timeline.set_key(0.0, viewer.session.pose())
    viewer.timeline.set_key(0.5, expression_pose(rig, "joy"))
    name, data = viewer._export_fbx()
    assert name == "small.fbx"
    assert data.startswith(b"Kaydara FBX Binary  \x00") and len(data) > 100_000


# ---- landmark picking


@dataclass(frozen=True)
class Click:
    ray_origin: tuple[float, float, float]
    ray_direction: tuple[float, float, float]


def click_on(viewer, point: np.ndarray) -> None:
    """A click whose ray comes from in front of the face (+Z of the display) through ``point``."""
    viewer._clicked(Click(tuple(point + np.array([0.0, 0.0, 100.0])), (0.0, 0.0, -1.0)))


def test_picked_landmarks_are_written_in_the_meshs_own_frame_and_units(web, rig, tmp_path):
    # A scan exported from Blender: Z up, face toward -Y, millimetres. The picker stands it upright
    # for the display; clicks come in display coordinates; the file gets the scan's own frame.
    turn = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # +Y up, +Z face → Blender
    scan = Mesh(10.0 * rig.mesh.vertices @ turn.T, rig.mesh.faces, units="mm")
    mesh_file = save_mesh(scan, tmp_path / "scan.obj")
    out = tmp_path / "picked.json"
    viewer = web.start(mesh_file, port=0, landmarks_out=out)
    try:
        assert viewer.session is None and viewer.picking.value
        viewer._face("+Z up, face -Y (Blender)")
        np.testing.assert_allclose(viewer.turn @ turn, np.eye(3), atol=1e-12)  # upright again
        truth = {}
        for name in PICK_LANDMARKS[:MIN_LANDMARKS]:
            truth[name] = 10.0 * turn @ rig.landmark_positions([name])[0]
            click_on(viewer, viewer.turn @ truth[name])  # the camera looks down -Z of the display
        assert list(viewer.picks.points) == list(PICK_LANDMARKS[:MIN_LANDMARKS])
        viewer._save_landmarks()
        read = read_landmarks(out)
        assert read.units == "mm"
        for name, position in zip(read.names, read.positions, strict=True):
            np.testing.assert_allclose(position, truth[name], atol=0.5)  # the front surface, in mm
    finally:
        viewer.server.stop()


def test_too_few_landmarks_write_nothing(viewer, tmp_path):
    viewer.landmarks_out = tmp_path / "lm.json"
    viewer.landmarks_out.write_text("keep me")
    viewer.picking.value = True
    click_on(viewer, viewer.rig.landmark_positions(["nose_tip"])[0])
    assert len(viewer.picks.points) == 1
    viewer._save_landmarks()
    assert viewer.landmarks_out.read_text() == "keep me"


def test_a_click_that_misses_picks_nothing(viewer):
    viewer.picking.value = True
    click_on(viewer, np.array([1e4, 1e4, 0.0]))
    assert viewer.picks.points == {}


# ---- bad input and ports


def test_a_corrupt_rig_is_explained_in_the_page(web, tmp_path):
    bad = tmp_path / "broken.mrig"
    bad.write_bytes(os.urandom(2048))
    viewer = web.start(bad, port=0)
    try:
        assert viewer.error and "broken.mrig" in viewer.error
        assert viewer.session is None
        assert "<html" in page(viewer).lower()  # the server still serves the page with the message
    finally:
        viewer.server.stop()


def test_a_missing_rig_is_explained(web, tmp_path):
    viewer = web.start(tmp_path / "nowhere.mrig", port=0)
    try:
        assert "no such file" in viewer.error.lower() or "not found" in viewer.error.lower()
    finally:
        viewer.server.stop()


def test_a_second_viewer_on_the_same_port_is_refused(web, viewer, rig_file):
    port = viewer.server.get_port()
    with pytest.raises(web.ViewError, match=f"port {port} .* already in use.*--port {port + 1}"):
        web.start(rig_file, port=port)
    assert "<html" in page(viewer).lower()  # the first one still serves


def listening_addresses(port: int) -> set[str]:
    """The IPv4 addresses a local socket listens on at ``port`` (Linux ``/proc/net/tcp``)."""
    found = set()
    for line in open("/proc/net/tcp").read().splitlines()[1:]:
        local, state = line.split()[1], line.split()[3]
        address, hex_port = local.split(":")
        if state == "0A" and int(hex_port, 16) == port:  # 0A: LISTEN
            found.add(socket.inet_ntoa(bytes.fromhex(address)[::-1]))
    return found


@pytest.mark.skipif(not os.path.exists("/proc/net/tcp"), reason="reads Linux's /proc/net/tcp")
def test_the_server_binds_localhost_unless_told(web, rig_file):
    for host, expected in (("127.0.0.1", {"127.0.0.1"}), ("0.0.0.0", {"0.0.0.0"})):
        viewer = web.start(rig_file, host=host, port=0)
        try:
            assert listening_addresses(viewer.server.get_port()) == expected
        finally:
            viewer.server.stop()


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


def test_cli_refuses_a_missing_rig_at_once_without_serving(tmp_path):
    """Nothing to show: one line and exit code 1 before any server starts (a corrupt rig, below, is
    served so that the page can explain it)."""
    result = run_cli("view", tmp_path / "nowhere.mrig", "--port", str(free_port()))
    assert result.exit_code == 1
    (line,) = result.output.strip().splitlines()
    assert "nowhere.mrig: no such file" in line and "http://" not in result.output


def test_cli_reports_a_corrupt_rig_in_the_terminal_and_a_busy_port(web, tmp_path):
    bad = tmp_path / "broken.mrig"
    bad.write_bytes(b"not a rig at all")
    port = free_port()
    command = [
        sys.executable,
        "-c",
        "from mimetic.cli import app; app()",
        "view",
        str(bad),
        "--port",
        str(port),
    ]
    first = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        line = ""
        while "mimetic view: http://localhost" not in line and time.monotonic() < deadline:
            line = first.stdout.readline()
        assert f"localhost:{port}" in line
        second = subprocess.run(command, capture_output=True, text=True, timeout=120)
        assert second.returncode == 1
        assert f"port {port} on 127.0.0.1 is already in use" in " ".join(second.stderr.split())
    finally:
        first.terminate()
        _, err = first.communicate(timeout=30)
    assert "broken.mrig" in err and "error" in err


def test_display_pieces_draw_the_lips_in_their_own_colour_along_their_border(web, rig):
    from mimetic.head.model import LIP
    from mimetic.view.look import rig_look

    look = rig_look(rig)
    pieces = web.display_pieces(rig.mesh, look)
    lips = [(faces, color) for name, faces, color in pieces if name.startswith("skin_")]
    faces, color = min(lips, key=lambda piece: np.abs(np.array(piece[1]) - 255 * np.array(LIP)).max())
    assert np.abs(np.array(color) - 255 * np.array(LIP)).max() < 12, color
    lip_coloured = np.abs(rig.mesh.colors - LIP).max(axis=1) < 1e-3  # (n,)
    corners = lip_coloured[rig.mesh.faces[faces]]  # (k, 3)
    assert corners.any(axis=1).all()  # every face of the piece touches the lips ...
    # ... and the lips' faces are all in it: the piece covers them, not a zigzag of their majority
    inside = np.flatnonzero(lip_coloured[rig.mesh.faces].all(axis=1))
    assert np.isin(inside, faces).all()


def test_switching_to_a_slow_engine_shows_its_progress_in_the_status_line(viewer):
    prepare = viewer.deformers.prepare
    seen = []

    def watched(name, progress=None):
        assert progress is not None, "the page passed no progress callback"
        progress(1, 3)
        seen.append(viewer.status.content)
        prepare(name, progress)

    viewer.deformers.prepare = watched
    viewer._switch_engine("fem")
    deadline = time.monotonic() + 120
    while "engine fem" not in viewer.status.content and time.monotonic() < deadline:
        time.sleep(0.1)  # the status line is written last, once the face is posed with fem
    assert viewer.engine == "fem"
    assert len(seen) == 1 and "preparing fem: 1/3" in seen[0], seen
    assert "preparing" not in viewer.status.content and "engine fem" in viewer.status.content


def test_display_pieces_join_parts_of_one_colour_that_meet(web, sphere):
    from mimetic.render.appearance import surface
    from mimetic.render.raster import ALBEDO

    top = sphere.vertices[sphere.faces].mean(axis=1)[:, 1] > 0  # (m,) faces above the equator
    parts = {"face": np.flatnonzero(top), "head_and_neck": np.flatnonzero(~top)}
    mesh = Mesh(sphere.vertices, sphere.faces, parts)
    assert np.isin(sphere.faces[top], sphere.faces[~top]).any()  # the parts share their border
    pieces = web.display_pieces(mesh, surface(mesh, ALBEDO))
    assert [name for name, _, _ in pieces] == ["face"]  # one mesh: one set of normals, no seam
    np.testing.assert_array_equal(pieces[0][1], np.arange(sphere.n_faces))
    apart = Mesh.concatenate({"a": sphere, "b": sphere.with_vertices(sphere.vertices + 3.0)})
    assert len(web.display_pieces(apart, surface(apart, ALBEDO))) == 2  # no shared vertex: kept apart
