"""three.js's GLTFLoader, in headless Chromium, reads the exported .glb.

``page.html`` loads the file with three.js (npm, pinned in package.json), plays the first clip to
a given time and writes what three.js made of it into the page as JSON; Chromium's
``--dump-dom`` prints the page once its virtual time budget has run out. The page and the file
are served by python's http.server on 127.0.0.1 (module scripts do not run from file:// URLs).
"""

from __future__ import annotations

import functools
import html
import http.server
import json
import re
import shutil
import subprocess
import threading

import numpy as np
import pytest

CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",  # CI runs as root
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
    "--virtual-time-budget=30000",
    "--dump-dom",
]


class QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args) -> None:
        pass


@pytest.fixture(scope="module")
def site(exported, node_modules, tmp_path_factory):
    """A folder with the page, the node modules (a link) and the file, served on 127.0.0.1."""
    root = tmp_path_factory.mktemp("site")
    page = node_modules.parent / "page.html"
    shutil.copy(page, root / "page.html")
    (root / "node_modules").symlink_to(node_modules, target_is_directory=True)
    shutil.copy(exported.path, root / "face.glb")
    handler = functools.partial(QuietHandler, directory=str(root))
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


@pytest.fixture(scope="module")
def three(chromium, site, exported, tmp_path_factory):
    """What three.js reports for the file at ``exported.seconds``."""
    profile = tmp_path_factory.mktemp("chromium-profile")
    url = f"{site}/page.html?glb=face.glb&t={exported.seconds}"
    command = [chromium, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", url]
    done = subprocess.run(command, capture_output=True, text=True, timeout=180, check=False)
    match = re.search(r'<pre id="out">(.*?)</pre>', done.stdout, re.S)
    assert done.returncode == 0 and match, f"chromium failed ({done.returncode}):\n{done.stderr[-3000:]}"
    report = json.loads(html.unescape(match.group(1)))
    assert "error" not in report, report.get("error")
    shown = {k: v for k, v in report.items() if k not in ("positions", "meshes")}
    shown["meshes"] = [
        (m["name"], m["vertices"], len(m["morphTargetDictionary"] or {})) for m in report["meshes"]
    ]
    print("three.js:", json.dumps(shown))
    return report


def test_threejs_morph_target_dictionary_has_every_target(three, exported):
    expected = {name: k for k, name in enumerate(exported.targets)}
    meshes = three["meshes"]
    assert [m["material"] for m in meshes] == list(exported.rig.mesh.parts)
    assert sum(m["vertices"] for m in meshes) == exported.rig.n_vertices
    for mesh in meshes:
        assert mesh["skinned"]
        assert mesh["morphTargetDictionary"] == expected


def test_threejs_exposes_the_clip_and_skeleton(three, exported):
    assert three["bones"] == list(exported.rig.bone_names)
    (clip,) = three["animations"]
    assert clip["name"] == "clip"
    assert clip["duration"] == pytest.approx((exported.clip.n_frames - 1) / exported.clip.fps, rel=1e-6)
    tracks = clip["tracks"]
    parts = len(exported.rig.mesh.parts)
    assert sum(t.endswith(".morphTargetInfluences") for t in tracks) == parts  # one per primitive
    bones = sorted(t for t in tracks if not t.endswith(".morphTargetInfluences"))
    anim = exported.summary["animations"][0]
    assert len(bones) == anim["rotation_channels"] + anim["translation_channels"]
    assert {"head.quaternion", "jaw.quaternion", "jaw.position", "eye_L.quaternion"} <= set(bones)


def test_threejs_pose_matches_gltf_vertices(three, exported):
    positions = np.array(three["positions"], dtype=np.float64).reshape(-1, 3)
    assert positions.shape == exported.posed.shape
    np.testing.assert_allclose(positions, exported.posed, atol=1e-6)


def test_threejs_shows_the_head_upright_facing_the_viewer(three, exported):
    """three.js's world is +Y up with the default camera looking down -Z: the posed head's chin is below
    its brow and its face looks toward +Z, though the rig was made from a Z-up scan."""
    shown = np.array(three["positions"], dtype=np.float64).reshape(-1, 3)
    up = exported.landmark(shown, "glabella") - exported.landmark(shown, "subnasale")
    assert up[1] > 0.9 * np.linalg.norm(up)
    forward = exported.landmark(shown, "nose_tip") - 0.5 * (
        exported.landmark(shown, "tragion_L") + exported.landmark(shown, "tragion_R")
    )
    assert forward[2] > 0.8 * np.linalg.norm(forward)  # the ears are above the nose tip
