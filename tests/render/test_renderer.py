"""Tests for mimetic.render.renderer: the GL path, its agreement with the CPU rasterizer, backends.

GL tests use the ``gl_renderer`` fixture: they skip without EGL, and fail on CI (CI=true).
"""

from __future__ import annotations

import importlib
import warnings

import moderngl
import numpy as np
import pytest
import trimesh

from mimetic.errors import MimeticWarning, RenderError
from mimetic.mesh.model import Mesh
from mimetic.render import VIEWS, Camera, Renderer, frame_camera, project, rasterize, render

# `mimetic.render.render` is the function, so fetch the module `mimetic.render.renderer` by name.
render_module = importlib.import_module("mimetic.render.renderer")
BLACK = (0.0, 0.0, 0.0)


def covered_centroid(image: np.ndarray) -> np.ndarray:
    """Centroid (x, y) of the non-black pixels, in pixel coordinates.

    Coverage, not brightness: the key light would pull a brightness centroid toward the highlight.
    """
    weight = (image.sum(axis=2) > 0).astype(np.float64)
    ys, xs = np.mgrid[0 : image.shape[0], 0 : image.shape[1]]
    return np.array([(weight * (xs + 0.5)).sum(), (weight * (ys + 0.5)).sum()]) / weight.sum()


def box(center, extent, color=None) -> Mesh:
    tm = trimesh.creation.box(extents=extent)
    vertices = tm.vertices + center
    colors = None if color is None else np.tile(np.asarray(color, np.float32), (len(vertices), 1))
    return Mesh(vertices, tm.faces, colors=colors)


def colored_pixels(image: np.ndarray, channel: int) -> np.ndarray:
    """(k, 2) pixel centres where ``channel`` strongly dominates the other two."""
    c = image.astype(int)
    others = np.delete(c, channel, axis=2).max(axis=2)
    ys, xs = np.nonzero(c[:, :, channel] > others + 60)
    return np.stack([xs + 0.5, ys + 0.5], axis=1)


def l_shape() -> Mesh:
    """A grey block with a red block on its +X side and a green block ("nose") on its +Z side."""
    grey, red, green = (0.6, 0.6, 0.6), (0.9, 0.05, 0.05), (0.05, 0.8, 0.05)
    parts = {
        "body": box((0, 0, 0), (1.0, 1.2, 1.0), grey),
        "right": box((0.8, 0.3, 0), (0.6, 0.3, 0.3), red),
        "nose": box((0, 0, 0.65), (0.3, 0.3, 0.3), green),
    }
    return Mesh.concatenate(parts)


@pytest.mark.parametrize("size", [(96, 96), (160, 96)])
def test_render_small_sphere_centroid_matches_project(gl_renderer, size):
    point = np.array([0.35, -0.25, 0.2])
    tm = trimesh.creation.icosphere(subdivisions=4, radius=0.1)
    mesh = Mesh(tm.vertices + point, tm.faces)
    camera = Camera(eye=(0.3, 0.2, 3.0), target=(0.0, 0.0, 0.0), fov_y_deg=30)
    image = gl_renderer.render(mesh, camera, size=size, albedo=(1, 1, 1), background=BLACK)
    assert image.shape == (size[1], size[0], 3) and image.dtype == np.uint8
    expected = project(point, camera, size).pixels
    np.testing.assert_allclose(covered_centroid(image), expected, atol=0.2)  # catches half-pixel slips


def test_render_front_view_shows_plus_x_on_image_right_and_plus_z_facing_geometry(gl_renderer):
    mesh = l_shape()
    lo, hi = mesh.vertices.min(0), mesh.vertices.max(0)
    camera = frame_camera(lo, hi)
    front = gl_renderer.render(mesh, camera, size=128)
    red, green = colored_pixels(front, 0), colored_pixels(front, 1)
    body_x = project(np.zeros(3), camera, 128).pixels[0]
    assert len(red) > 50 and red[:, 0].min() > body_x + 20  # +X block on the image right
    assert len(green) > 50  # the +Z face is seen
    np.testing.assert_allclose(green.mean(axis=0), project([0, 0, 0.8], camera, 128).pixels, atol=1.5)
    back_camera = frame_camera(lo, hi, yaw_deg=180)
    back = gl_renderer.render(mesh, back_camera, size=128)
    assert len(colored_pixels(back, 1)) == 0  # hidden behind the body
    body_x = project(np.zeros(3), back_camera, 128).pixels[0]
    assert colored_pixels(back, 0)[:, 0].max() < body_x - 20  # +X now on the left
    profile_camera = frame_camera(lo, hi, yaw_deg=VIEWS["profile"])
    profile = gl_renderer.render(mesh, profile_camera, size=128)
    body_x = project(np.zeros(3), profile_camera, 128).pixels[0]
    assert colored_pixels(profile, 1)[:, 0].min() > body_x + 10  # nose points right


@pytest.mark.parametrize("msaa", [0, 4])
@pytest.mark.parametrize("wireframe", [False, True])
@pytest.mark.parametrize("name", ["sphere", "torus"])
def test_render_gl_matches_cpu_rasterizer(gl_renderer, request, name, wireframe, msaa):
    mesh = request.getfixturevalue(name)
    camera = frame_camera(mesh.vertices.min(0), mesh.vertices.max(0), yaw_deg=25, pitch_deg=20)
    gl = gl_renderer.render(mesh, camera, size=(200, 160), wireframe=wireframe, msaa=msaa)
    cpu = rasterize(mesh, camera, size=(200, 160), wireframe=wireframe)
    assert gl.shape == cpu.shape == (160, 200, 3) and gl.dtype == cpu.dtype == np.uint8
    difference = np.abs(gl.astype(int) - cpu.astype(int))
    assert difference.mean() < 3.0, f"mean abs diff {difference.mean():.2f}/255"
    if msaa == 0 and not wireframe:
        assert (difference.max(axis=2) > 8).mean() < 0.002


def test_render_vertex_colors_show(gl_renderer, sphere):
    red, skin = [[0.9, 0.05, 0.05]], [[0.87, 0.68, 0.58]]
    colors = np.where(sphere.vertices[:, :1] > 0, red, skin).astype(np.float32)
    mesh = Mesh(sphere.vertices, sphere.faces, colors=colors)
    image = gl_renderer.render(mesh, frame_camera(mesh.vertices.min(0), mesh.vertices.max(0)), size=96)
    red = colored_pixels(image, 0)
    assert len(red) > 500
    assert red[:, 0].min() > 44  # the +X half only
    plain = gl_renderer.render(sphere, frame_camera(sphere.vertices.min(0), sphere.vertices.max(0)), size=96)
    assert len(colored_pixels(plain, 0)) == 0


def test_render_wireframe_darkens_edges_not_face_centres(gl_renderer):
    tm = trimesh.creation.icosphere(subdivisions=1)
    mesh = Mesh(tm.vertices, tm.faces)
    camera = frame_camera(mesh.vertices.min(0), mesh.vertices.max(0))
    plain = gl_renderer.render(mesh, camera, size=256).astype(int)
    wire = gl_renderer.render(mesh, camera, size=256, wireframe=True).astype(int)
    _, _, forward = camera.basis()
    tri = mesh.vertices[mesh.faces]  # (m, 3, 3)
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    facing = tri[(normals @ -forward) > 0.5 * np.linalg.norm(normals, axis=1)]  # clearly visible
    centres = project(facing.mean(axis=1), camera, 256).pixels.astype(int)
    edge_midpoints = (facing + np.roll(facing, 1, axis=1)).reshape(-1, 3) / 2
    midpoints = project(edge_midpoints, camera, 256).pixels.astype(int)
    at = lambda image, p: image[p[:, 1], p[:, 0]].sum(axis=1)  # noqa: E731
    np.testing.assert_array_equal(at(wire, centres), at(plain, centres))
    assert (at(wire, midpoints) < at(plain, midpoints) - 30).mean() > 0.9


def test_render_back_faces_are_lit_but_darker(gl_renderer):
    tm = trimesh.creation.icosphere(subdivisions=3)
    faces = tm.faces[tm.vertices[tm.faces].mean(axis=1)[:, 2] > 0]  # open front shell
    mesh = Mesh(tm.vertices, faces)
    lo, hi = tm.vertices.min(0), tm.vertices.max(0)
    outside = gl_renderer.render(mesh, frame_camera(lo, hi), size=96, background=BLACK)
    inside = gl_renderer.render(mesh, frame_camera(lo, hi, yaw_deg=180), size=96, background=BLACK)
    lit_out, lit_in = outside[outside.sum(2) > 0], inside[inside.sum(2) > 0]
    assert len(lit_in) > 0.8 * len(lit_out)  # no holes
    assert 40 < lit_in.mean() < lit_out.mean()


def test_render_reuses_context_across_sizes_deterministically(gl_renderer, sphere):
    camera = frame_camera(sphere.vertices.min(0), sphere.vertices.max(0))
    vertices_before = sphere.vertices.copy()
    a = gl_renderer.render(sphere, camera, size=64)
    b = gl_renderer.render(sphere, camera, size=(80, 48))
    c = gl_renderer.render(sphere, camera, size=64)
    assert b.shape == (48, 80, 3)
    np.testing.assert_array_equal(a, c)
    np.testing.assert_array_equal(sphere.vertices, vertices_before)


def test_render_convenience_uses_named_views(gl_renderer, monkeypatch, sphere):
    monkeypatch.setenv("MIMETIC_RENDER_BACKEND", "egl")
    image = render(sphere, "three_quarter", size=(64, 48))
    assert image.shape == (48, 64, 3) and image.dtype == np.uint8
    assert render_module.default_renderer().backend == "egl"
    with pytest.raises(ValueError, match="unknown view"):
        render(sphere, "top")


def test_render_backend_env_cpu_uses_rasterizer(monkeypatch, sphere):
    monkeypatch.setenv("MIMETIC_RENDER_BACKEND", "cpu")
    image = render(sphere, "front", size=64)
    camera = frame_camera(sphere.vertices.min(0), sphere.vertices.max(0))
    np.testing.assert_array_equal(image, rasterize(sphere, camera, size=64))
    assert render_module.default_renderer().backend == "cpu"


def _no_egl(*args, **kwargs):
    raise Exception("libEGL.so.1 not loaded")


def test_renderer_falls_back_to_cpu_once_with_apt_hint_when_egl_missing(monkeypatch, sphere):
    monkeypatch.setattr(moderngl, "create_standalone_context", _no_egl)
    monkeypatch.setattr(render_module, "_warned_fallback", False)
    monkeypatch.delenv("MIMETIC_RENDER_BACKEND", raising=False)
    camera = frame_camera(sphere.vertices.min(0), sphere.vertices.max(0))
    with pytest.warns(MimeticWarning, match="apt-get install libegl1 libegl-mesa0"):
        image = Renderer("auto").render(sphere, camera, size=48)
    np.testing.assert_array_equal(image, rasterize(sphere, camera, size=48))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        renderer = Renderer()
        renderer.render(sphere, camera, size=48)  # warned once per process
    assert renderer.backend == "cpu"


def test_renderer_forced_egl_unavailable_raises_render_error(monkeypatch, sphere):
    monkeypatch.setattr(moderngl, "create_standalone_context", _no_egl)
    monkeypatch.setenv("MIMETIC_RENDER_BACKEND", "egl")
    camera = frame_camera(sphere.vertices.min(0), sphere.vertices.max(0))
    with pytest.raises(RenderError, match=r"apt-get install libegl1 libegl-mesa0 .*libgl1-mesa-dri libgbm1"):
        Renderer().render(sphere, camera, size=48)


def test_renderer_rejects_unknown_backend_and_bad_msaa(monkeypatch, sphere):
    monkeypatch.setenv("MIMETIC_RENDER_BACKEND", "vulkan")
    with pytest.raises(RenderError, match="vulkan"):
        Renderer()
    camera = frame_camera(sphere.vertices.min(0), sphere.vertices.max(0))
    with pytest.raises(ValueError, match="msaa"):
        Renderer("cpu").render(sphere, camera, msaa=3)


def test_renderer_keeps_working_after_another_renderer_is_released(gl_renderer, sphere):
    camera = frame_camera(sphere.vertices.min(0), sphere.vertices.max(0))
    before = gl_renderer.render(sphere, camera, size=48)
    other = Renderer("egl")
    other.render(sphere, camera, size=(32, 24))  # makes its own context current
    other.release()
    np.testing.assert_array_equal(gl_renderer.render(sphere, camera, size=48), before)
