"""Rig renders show the rig's eyes: eyeballs around their eye bones, films left out, lashes dark."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from mimetic.fit.pipeline import rig_head
from mimetic.mesh.model import Mesh
from mimetic.render import Camera, project
from mimetic.render.appearance import LASH, NOT_EYE, PUPIL_ANGLE_RAD
from mimetic.rig.activations import pose
from mimetic.rig.model import Rig
from mimetic.testing import ict_landmarks, load_ict, require_shared_data, small_rig
from mimetic.view.look import eye_frames, rig_look
from mimetic.view.muscles import render_rig
from mimetic.view.sheets import face_camera, posed_mesh, render_pose

SIZE = 256


@pytest.fixture(scope="module")
def rig() -> Rig:
    return small_rig()


@pytest.fixture(scope="module")
def bare_rig(rig: Rig) -> Rig:
    """The generated rig with its colours dropped: eyeballs that say nothing about their iris."""
    m = rig.mesh
    return dataclasses.replace(rig, mesh=Mesh(m.vertices, m.faces, m.parts, None, m.units))


def _eye_points(rig: Rig, part: str, vertices: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The front pole and a point 50° off the gaze, toward the outer side, of an eyeball part."""
    centre, axis = eye_frames(rig)[part]
    axis = axis / np.linalg.norm(axis)
    ids = rig.mesh.part_vertices(part)
    radius = np.percentile(np.linalg.norm(rig.mesh.vertices[ids] - centre, axis=1), 95)
    outward = np.array([np.sign(centre[0]), 0.0, 0.0])
    a = math.radians(35)
    return centre + radius * axis, centre + radius * (math.cos(a) * axis + math.sin(a) * outward)


def _pixel(image: np.ndarray, point: np.ndarray, camera: Camera) -> np.ndarray:
    x, y = project(point, camera, image.shape[0]).pixels
    return image[int(y), int(x)].astype(int)


def test_rig_look_of_the_generated_rig_changes_nothing(rig):
    look = rig_look(rig)
    np.testing.assert_array_equal(look.faces, np.arange(rig.mesh.n_faces))
    np.testing.assert_array_equal(look.colors, rig.mesh.colors)
    assert (look.gaze_cos == NOT_EYE).all() and (look.cover == 1.0).all()
    # its lips touch at rest and its mouth bag's rim lies on them: neither is welded (streaks)
    v = rig.mesh.vertices
    assert len(np.unique(v, axis=0)) < len(v)  # there are vertices at one position ...
    np.testing.assert_array_equal(look.weld, np.arange(len(v)))  # ... each keeps its own normal


def test_render_rig_without_colours_shows_dark_pupils_and_light_sclera(bare_rig):
    camera = face_camera(bare_rig)
    image = render_rig(bare_rig, camera, size=SIZE, muscles=False)
    for part in ("eye_L", "eye_R"):
        front, side = _eye_points(bare_rig, part)
        pupil, sclera = _pixel(image, front, camera), _pixel(image, side, camera)
        assert pupil.max() < 50, f"{part} pupil {pupil}"
        assert sclera.min() > 110 and np.ptp(sclera) < 30, f"{part} sclera {sclera} is not white"


def test_render_pose_iris_turns_with_the_gaze(bare_rig):
    look = rig_look(bare_rig)
    pupil = np.flatnonzero(look.gaze_cos >= math.cos(PUPIL_ANGLE_RAD))  # both pupils' vertices
    gaze = pose(bare_rig, {"gaze_yaw": bare_rig.channel("gaze_yaw").maximum})
    posed = posed_mesh(bare_rig, "wire", gaze)
    camera = face_camera(bare_rig)
    image = render_pose(bare_rig, "wire", gaze, size=SIZE)
    for part in ("eye_L", "eye_R"):
        ids = np.intersect1d(pupil, bare_rig.mesh.part_vertices(part))
        rest_px = project(bare_rig.mesh.vertices[ids].mean(axis=0), camera, SIZE).pixels
        turned = posed.vertices[ids].mean(axis=0)
        turned_px = project(turned, camera, SIZE).pixels
        assert np.linalg.norm(turned_px - rest_px) > 2.0  # the pupil moved with the eye
        assert _pixel(image, turned, camera).max() < 50  # and is drawn where it went
        assert _pixel(image, bare_rig.mesh.vertices[ids].mean(axis=0), camera).max() > 60  # not left behind


# --- ICT-FaceKit rigged, with its shells and lashes -----------------------------------------------

ICT_SHELLS = ("Lacrimal fluid", "Eye blend", "Eye occlusion")


@pytest.fixture(scope="module")
def ict_rig() -> tuple[Rig, dict]:
    mesh, meta = load_ict(require_shared_data("ict-facekit"))
    return rig_head(mesh, ict_landmarks(mesh, meta)).rig, meta


def test_render_rigged_ict_shows_eyes_not_shells_and_dark_lashes(ict_rig):
    rig, meta = ict_rig
    look = rig_look(rig)
    shell = np.concatenate(
        [
            np.arange(lo, hi + 1)
            for p in meta["parts"]
            if p["name"].startswith(ICT_SHELLS)
            for lo, hi in [p["vertex_range"]]
        ]
    )
    hidden = np.setdiff1d(np.arange(rig.mesh.n_faces), look.faces)
    np.testing.assert_array_equal(np.unique(rig.mesh.faces[hidden]), shell)  # the shells, all of them, only
    lo, hi = next(p["vertex_range"] for p in meta["parts"] if p["name"] == "Eyelashes right")
    np.testing.assert_allclose(look.colors[lo : hi + 1], np.tile(LASH, (hi + 1 - lo, 1)))
    camera = face_camera(rig)
    for view_camera in (camera, face_camera(rig, yaw_deg=35.0)):
        image = render_rig(rig, view_camera, size=384, muscles=False)
        for part in ("eye_L", "eye_R"):
            front, side = _eye_points(rig, part)
            pupil = _pixel(image, front, view_camera)
            assert pupil.max() < 50, f"{part} pupil {pupil}"
    image = render_rig(rig, camera, size=384, muscles=False)
    for part in ("eye_L", "eye_R"):
        _, side = _eye_points(rig, part)
        sclera = _pixel(image, side, camera)
        assert sclera.min() > 110 and np.ptp(sclera) < 30, f"{part} sclera {sclera} is not white"
