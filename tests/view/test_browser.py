"""The web viewer in a real browser: headless Chromium opens ``mimetic view``'s page and uses it.

The small generated rig is saved to a temporary .mrig and served by ``view.web.start`` on a free
port. Chromium (Debian's ``/usr/bin/chromium``, driven by Playwright; no browser is downloaded)
opens the page, waits until the face is drawn, opens the "Jaw" folder of the Channels tab and
clicks the "jaw open (rad)" slider's track with the mouse. The server must see the channel move,
and the picture must change where the jaw is and nowhere else: the mouth and chin are located on
screen by projecting the rig's landmarks with the camera the browser reports, and the screenshots
before and after are compared over the 3D canvas only (the GUI panel and notifications left out).
The other tests open a corrupt rig (the page shows the error), pick a landmark by clicking the
nose (the click's ray must hit the mesh), and hold an arrow key on a focused slider (the slider
moves, the camera does not; on the canvas the same key turns the camera).

Screenshots (before, after, difference) go to ``$MIMETIC_ARTEFACTS/viewer`` when that is set, else
to the test's temporary folder; with ``MIMETIC_UPDATE_SCREENSHOT=1`` the "after" shot also becomes
``docs/images/viewer.png``, the README's picture. Playwright, viser or Chromium missing skips the
tests, except on CI (``CI=true``), where they fail.
"""

from __future__ import annotations

import os
import re
import shutil
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from mimetic.testing import CHROMIUM, CHROMIUM_ARGS, require_extra, small_rig

ROOT = Path(__file__).resolve().parents[2]
README_SHOT = ROOT / "docs" / "images" / "viewer.png"
VIEWPORT = {"width": 1280, "height": 800}
TIMEOUT_MS = 60_000  # two cores, software WebGL, maybe another job: be patient
CHANGED = 24  # a pixel changed when a colour channel moved by more than this (of 255)
MOUTH = ("mouth_corner_L", "mouth_corner_R", "upper_lip_top", "lower_lip_bottom", "pogonion")
UPPER_FACE = ("brow_inner_L", "brow_inner_R", "brow_outer_L", "brow_outer_R", "nasion")
EYES = ("eye_outer_corner_L", "eye_outer_corner_R", "eye_upper_lid_L", "eye_upper_lid_R")


def unavailable(reason: str) -> None:
    """Skip the test locally; fail it on CI, where the browser test must run."""
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(f"{reason} (CI=true requires it)")
    pytest.skip(reason)


@pytest.fixture(scope="module")
def browser() -> Iterator[object]:
    """One headless Chromium for the module (launching it takes a few seconds)."""
    require_extra("viser", "view")
    sync_api = require_extra("playwright.sync_api", "dev")
    if not Path(CHROMIUM).exists():
        unavailable(f"{CHROMIUM} is not installed (apt-get install chromium)")
    with sync_api.sync_playwright() as playwright:
        try:
            browser = playwright.chromium.launch(executable_path=CHROMIUM, args=list(CHROMIUM_ARGS))
        except sync_api.Error as error:
            unavailable(f"cannot launch {CHROMIUM}: {error}")
        yield browser
        browser.close()


@pytest.fixture(scope="module")
def rig():
    return small_rig()


@pytest.fixture(scope="module")
def rig_path(rig, tmp_path_factory) -> Path:
    from mimetic.rig.format import save_rig

    return save_rig(rig, tmp_path_factory.mktemp("browser") / "small.mrig")


@pytest.fixture(scope="module")
def artefacts(tmp_path_factory) -> Path:
    """Where the screenshots are kept: ``$MIMETIC_ARTEFACTS/viewer``, else a temporary folder."""
    base = os.environ.get("MIMETIC_ARTEFACTS")
    folder = Path(base) / "viewer" if base else tmp_path_factory.mktemp("viewer")
    folder.mkdir(parents=True, exist_ok=True)
    return folder


@pytest.fixture
def open_page(browser) -> Iterator[Callable]:
    """``open_page(source)``: a viewer of ``source`` on a free port and a fresh page showing it."""
    from mimetic.view.web import start

    opened = []

    def open_(source: Path):
        viewer = start(source, port=0)
        page = browser.new_page(viewport=VIEWPORT, device_scale_factor=1)
        opened.append((viewer, page))
        page.set_default_timeout(TIMEOUT_MS)
        # fixedDpr (a viser URL parameter) turns off its adaptive resolution: on a slow software
        # renderer it would lower the resolution at a random moment and change every pixel a little
        page.goto(f"http://127.0.0.1:{viewer.server.get_port()}/?fixedDpr=1")
        return viewer, page

    yield open_
    for viewer, page in opened:
        page.close()
        viewer.server.stop()


# ---- the page


@dataclass(frozen=True)
class Box:
    """A screen rectangle in CSS pixels: x0 ≤ x < x1, y0 ≤ y < y1 (rounded outwards)."""

    x0: int
    y0: int
    x1: int
    y1: int

    @classmethod
    def around(cls, points: np.ndarray) -> Box:
        """The box around ``points`` (k, 2)."""
        low, high = points.min(axis=0), points.max(axis=0)
        return cls(int(np.floor(low[0])), int(np.floor(low[1])), int(np.ceil(high[0])), int(np.ceil(high[1])))

    @classmethod
    def of(cls, rect: dict) -> Box:
        """The box of a Playwright bounding box (``x``, ``y``, ``width``, ``height``)."""
        return cls.around(
            np.array([[rect["x"], rect["y"]], [rect["x"] + rect["width"], rect["y"] + rect["height"]]])
        )

    def mask(self, shape: tuple[int, int]) -> np.ndarray:
        """A boolean (height, width) image, True inside the box."""
        mask = np.zeros(shape, bool)
        mask[max(self.y0, 0) : max(self.y1, 0), max(self.x0, 0) : max(self.x1, 0)] = True
        return mask


def screenshot(page) -> np.ndarray:
    """The page as an (height, width, 3) uint8 image in CSS pixels (whatever devicePixelRatio is)."""
    import io

    return np.asarray(Image.open(io.BytesIO(page.screenshot(scale="css"))).convert("RGB"))


def settled(
    page, *, differs_from: np.ndarray | None = None, where: np.ndarray | None = None, timeout_s: float = 60.0
) -> np.ndarray:
    """A screenshot once the page stops changing: two shots 0.3 s apart agree (and, when
    ``differs_from`` is given, differ from it, so a frame still to come is waited for). ``where``
    (height, width) bool limits the comparisons, e.g. to the canvas without the GUI panel."""

    def same(a: np.ndarray, b: np.ndarray) -> bool:
        return np.array_equal(a, b) if where is None else np.array_equal(a[where], b[where])

    deadline = time.monotonic() + timeout_s
    last = screenshot(page)
    while time.monotonic() < deadline:
        time.sleep(0.3)
        shot = screenshot(page)
        if same(shot, last) and (differs_from is None or not same(shot, differs_from)):
            return shot
        last = shot
    new = " on a new picture" if differs_from is not None else ""
    pytest.fail(f"the page did not settle{new} in {timeout_s:.0f} s")


def canvas_box(page) -> Box:
    """The 3D canvas (three.js's WebGL canvas, not viser's 2D overlay)."""
    return Box.of(page.locator("canvas[data-engine]").bounding_box())


def face_drawn(page) -> np.ndarray:
    """Wait until the canvas shows the face (skin-coloured pixels) and the page has settled; close
    viser's "Software WebGL rendering detected" notification first (it covers the top left)."""
    canvas = canvas_box(page)  # waits for the canvas
    deadline = time.monotonic() + TIMEOUT_MS / 1e3
    while time.monotonic() < deadline:
        shot = screenshot(page)[canvas.y0 : canvas.y1, canvas.x0 : canvas.x1].astype(int)
        # the skin is reddish on white: ~9 % of the canvas when drawn (the notification's bar: 0.1 %)
        skin = (shot[..., 0] - shot[..., 2] > 30).mean()
        if skin > 0.02:
            break
        time.sleep(0.3)
    else:
        pytest.fail("the face was not drawn in the canvas")
    note = page.locator(".mantine-Notification-root", has_text="Software WebGL rendering detected")
    if note.count():
        note.locator(".mantine-Notification-closeButton").click()
        note.wait_for(state="detached")
    return settled(page)


def slider(page, label: str):
    """The Mantine slider labelled ``label``. viser writes ``<label for=ID>`` beside ``<div
    id=ID class=mantine-Slider-root>``; a label names no div for accessibility, so
    ``get_by_label`` finds nothing and the label's ``for`` is followed by hand."""
    exact = re.compile(f"^{re.escape(label)}$")
    target = page.locator("label").filter(has_text=exact).get_attribute("for")
    return page.locator(f'[id="{target}"].mantine-Slider-root')


def open_folder(page, title: str) -> None:
    """Click a GUI folder's header (``title``) to expand it."""
    page.get_by_test_id("floating-panel").get_by_text(title, exact=True).click()


def click_track(page, label: str, fraction: float) -> None:
    """Click slider ``label``'s track at ``fraction`` of its width, as a user would."""
    track = slider(page, label).locator(".mantine-Slider-track")
    track.scroll_into_view_if_needed()
    box = track.bounding_box()
    page.mouse.click(box["x"] + fraction * box["width"], box["y"] + box["height"] / 2)


def project(viewer, page, points: np.ndarray) -> np.ndarray:
    """Screen positions (k, 2) in CSS pixels of ``points`` (k, 3), seen by the page's camera.

    The camera is the one the browser reports to the server (position, look-at, up and vertical
    field of view); the picture fills the canvas."""
    clients = list(viewer.server.get_clients().values())
    assert len(clients) == 1, f"expected one browser connected, found {len(clients)}"
    camera = clients[0].camera
    eye, target, up = (np.asarray(v, np.float64) for v in (camera.position, camera.look_at, camera.up))
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, up)
    right /= np.linalg.norm(right)
    true_up = np.cross(right, forward)
    canvas = canvas_box(page)
    width, height = canvas.x1 - canvas.x0, canvas.y1 - canvas.y0
    offset = np.asarray(points, np.float64) - eye
    depth = offset @ forward
    assert (depth > 0).all(), "a projected point is behind the camera"
    focal = height / 2 / np.tan(camera.fov / 2)  # pixels
    x = canvas.x0 + width / 2 + focal * (offset @ right) / depth
    y = canvas.y0 + height / 2 - focal * (offset @ true_up) / depth
    return np.column_stack([x, y])


def landmarks_on(rig, vertices: np.ndarray, names: tuple[str, ...]) -> np.ndarray:
    """Positions (k, 3) of the rig's landmarks ``names`` on ``vertices`` (n, 3) in rig order."""
    points = [rig.landmarks[n] for n in names]
    corners = vertices[rig.mesh.faces[[p.face for p in points]]]  # (k, 3, 3)
    return np.einsum("kj,kjd->kd", np.array([p.bary for p in points]), corners)


def wait_for(condition: Callable[[], object], timeout_s: float = 10.0) -> bool:
    """Poll ``condition`` until it holds (True) or ``timeout_s`` passes (False)."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.1)
    return True


def save(image: np.ndarray, path: Path) -> Path:
    Image.fromarray(image).save(path)
    return path


# ---- tests


def test_view_jaw_slider_changes_mouth_only(open_page, rig, rig_path, artefacts):
    saved = rig_path.read_bytes()
    viewer, page = open_page(rig_path)
    assert viewer.error is None, viewer.error
    before = face_drawn(page)
    rest = viewer.vertices.copy()
    jaw = viewer.session.index["jaw_open"]
    assert viewer.session.pose()[jaw] == pytest.approx(0.0)

    open_folder(page, "Jaw")
    click_track(page, "jaw open (rad)", 0.85)
    posed = wait_for(lambda: viewer.session.pose()[jaw] > 0.2 and not np.array_equal(viewer.vertices, rest))
    value = viewer.session.pose()[jaw]
    assert value > 0.2, f"jaw_open is {value:.3f} after clicking its slider at 85 % (range -0.05..0.45)"
    assert posed, "the server did not pose the face"
    canvas = canvas_box(page)
    panel = Box.of(page.get_by_test_id("floating-panel").bounding_box())
    shape = before.shape[:2]
    compared = canvas.mask(shape) & ~panel.mask(shape)  # the 3D view, not the GUI over it
    for note in page.locator(".mantine-Notification-root").all():
        compared &= ~Box.of(note.bounding_box()).mask(shape)
    after = settled(page, differs_from=before, where=compared)
    changed = (np.abs(after.astype(int) - before.astype(int)).max(axis=2) > CHANGED) & compared

    mouth_rest = project(viewer, page, landmarks_on(rig, rest, MOUTH))
    mouth_open = project(viewer, page, landmarks_on(rig, viewer.vertices, MOUTH))
    mouth = Box.around(np.concatenate([mouth_rest, mouth_open]))
    upper = project(viewer, page, landmarks_on(rig, rest, UPPER_FACE + EYES))
    eye_line = project(viewer, page, landmarks_on(rig, rest, EYES))[:, 1].min()
    brow = Box.around(upper)
    forehead = Box(brow.x0, brow.y0 - (brow.y1 - brow.y0), brow.x1, int(eye_line))
    above_eyes = Box(canvas.x0, canvas.y0, canvas.x1, int(eye_line))

    diff = np.where(compared[..., None], before // 2 + 128, 96).astype(np.uint8)  # grey: not compared
    diff[changed] = (255, 0, 0)
    for box, colour in ((mouth, (0, 160, 0)), (forehead, (0, 0, 255))):
        edge = box.mask(shape) & ~Box(box.x0 + 2, box.y0 + 2, box.x1 - 2, box.y1 - 2).mask(shape)
        diff[edge] = colour
    save(before, artefacts / "before.png")
    save(after, artefacts / "after.png")
    save(diff, artefacts / "diff.png")
    if os.environ.get("MIMETIC_UPDATE_SCREENSHOT") == "1":
        README_SHOT.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(artefacts / "after.png", README_SHOT)

    def fraction(box: Box) -> float:
        inside = box.mask(shape) & compared
        assert inside.sum() > 400, f"{box} has only {inside.sum()} pixels on the canvas"
        return float(changed[inside].mean())

    in_mouth, in_forehead = fraction(mouth), fraction(forehead)
    above = int(changed[above_eyes.mask(shape)].sum())
    print(
        f"jaw_open {value:.3f}: changed {in_mouth:.1%} of the mouth box {mouth}, {in_forehead:.2%} of the "
        f"forehead box {forehead}, {above} pixels above the eyes (y < {eye_line:.0f}); "
        f"{changed.sum()} changed in all; screenshots in {artefacts}"
    )
    assert in_mouth > 0.15, f"only {in_mouth:.1%} of the mouth box changed (see {artefacts / 'diff.png'})"
    assert in_forehead < 0.002, (
        f"{in_forehead:.2%} of the forehead box changed (see {artefacts / 'diff.png'})"
    )
    assert above < 50, f"{above} pixels above the eyes changed (see {artefacts / 'diff.png'})"
    assert rig_path.read_bytes() == saved, "the viewer modified the rig file"


def test_view_corrupt_rig_shows_error(open_page, tmp_path):
    path = tmp_path / "x.mrig"
    path.write_bytes(np.random.default_rng(0).bytes(4096))
    viewer, page = open_page(path)
    assert viewer.error, "a corrupt rig loaded without an error"
    page.get_by_text("Cannot open").wait_for()
    text = " ".join(page.locator("body").inner_text().split())
    print(f"the page shows the error: {viewer.error}")
    assert "Cannot open x.mrig" in text
    assert " ".join(viewer.error.split()) in text, f"{viewer.error!r} is not on the page"


def test_view_click_on_nose_picks_landmark(open_page, rig, rig_path):
    viewer, page = open_page(rig_path)
    face_drawn(page)
    page.get_by_role("tab", name="Landmarks").click()
    pick = page.get_by_role("checkbox", name="Pick")
    if not pick.is_checked():
        pick.click()
    assert wait_for(lambda: viewer.picking.value), "ticking Pick did not reach the server"
    assert viewer.picks.points == {}

    nose = landmarks_on(rig, viewer.vertices, ("nose_tip",))
    x, y = project(viewer, page, nose)[0]
    page.mouse.click(x, y)
    # the server's click handler adds the pick, then moves the picker on: wait for both
    wait_for(lambda: viewer.picks.points and viewer.landmark_choice.value != "eye_outer_corner_R")
    assert list(viewer.picks.points) == ["eye_outer_corner_R"], viewer.picks.points
    assert viewer.landmark_choice.value == "eye_inner_corner_R", "the picker did not move on"
    picked = viewer.picks.positions(viewer.vertices)["eye_outer_corner_R"]
    size = float(np.ptp(rig.mesh.vertices, axis=0).max())
    distance = float(np.linalg.norm(picked - nose[0]))
    print(f"clicked the nose tip at ({x:.0f}, {y:.0f}); picked {distance:.3g} from it (head {size:.3g})")
    assert distance < 0.03 * size, f"the pick landed {distance:.3g} from the nose tip"


def test_view_arrow_keys_on_a_slider_move_the_slider_not_the_camera(open_page, rig_path):
    viewer, page = open_page(rig_path)
    face_drawn(page)
    client = next(iter(viewer.server.get_clients().values()))
    jaw = viewer.session.index["jaw_open"]

    def camera() -> np.ndarray:
        return np.array([*client.camera.position, *client.camera.look_at], np.float64)

    def hold(key: str) -> None:
        page.keyboard.down(key)
        time.sleep(0.6)  # viser moves the camera every frame while a key is held
        page.keyboard.up(key)

    # on the canvas the arrow key turns the camera (the check below can fail)
    canvas = canvas_box(page)
    page.mouse.click(canvas.x0 + 5, canvas.y1 - 5)  # the background near a corner: no pick, no GUI
    start = camera()
    hold("ArrowRight")
    assert wait_for(lambda: not np.allclose(camera(), start, atol=1e-6)), "ArrowRight did not turn the camera"

    open_folder(page, "Jaw")
    thumb = slider(page, "jaw open (rad)").locator(".mantine-Slider-thumb")
    thumb.focus()
    time.sleep(1.0)  # the camera's last updates arrive
    start, value = camera(), viewer.session.pose()[jaw]
    hold("ArrowRight")
    assert wait_for(lambda: viewer.session.pose()[jaw] > value), "ArrowRight on the slider did not move it"
    time.sleep(1.0)
    moved = float(np.abs(camera() - start).max())
    print(f"jaw_open {value:.3f} → {viewer.session.pose()[jaw]:.3f}; the camera moved by {moved:.2g}")
    assert moved < 1e-6, f"ArrowRight on the focused slider also moved the camera (by {moved:.3g})"
