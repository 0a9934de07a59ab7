"""Offscreen rendering of meshes with moderngl on EGL (Mesa llvmpipe works without a GPU).

``Renderer`` keeps the GL context, the shader program, the vertex buffer and one framebuffer
per (size, samples), all created on first use. When EGL is unavailable it falls back to the
numpy rasterizer in ``raster.py`` (same shading, no antialiasing) with one ``MimeticWarning``.
``MIMETIC_RENDER_BACKEND=egl|cpu`` forces a backend.

Triangles are drawn non-indexed (three corners each) so each corner can carry barycentric
coordinates for the wireframe overlay; the shading model lives in ``raster.shade``. Which faces are
drawn and in which colours (films left out, eyeballs given an iris, lashes cut to their roots) is
``appearance.surface``'s decision, which both renderers follow.
"""

from __future__ import annotations

import logging
import math
import os
import time
import warnings

import numpy as np

from mimetic.errors import MimeticWarning, RenderError
from mimetic.mesh.model import Mesh
from mimetic.render import appearance, raster
from mimetic.render.appearance import Surface, surface
from mimetic.render.camera import VIEWS, Camera, _size, clip_planes, frame_camera

log = logging.getLogger(__name__)

BACKEND_ENV = "MIMETIC_RENDER_BACKEND"
APT_HINT = "apt-get install libegl1 libegl-mesa0 libgl1 libgl1-mesa-dri libgbm1"

_VERTEX_SHADER = """
#version 330
uniform mat4 view;
uniform mat4 proj;
in vec3 in_pos;
in vec3 in_nrm;
in vec3 in_col;
in vec3 in_bary;
in vec3 in_iris;
in vec2 in_look;
out vec3 v_pos;
out vec3 v_nrm;
out vec3 v_col;
noperspective out vec3 v_bary;
out vec3 v_iris;
out vec2 v_look;
void main() {
    vec4 p = view * vec4(in_pos, 1.0);
    v_pos = p.xyz;
    v_nrm = mat3(view) * in_nrm;
    v_col = in_col;
    v_bary = in_bary;
    v_iris = in_iris;
    v_look = in_look;
    gl_Position = proj * p;
}
"""

# Mirrors raster.shade and appearance.eye_albedo (whose hard band edges it antialiases); keep them
# in step. v_look is (gaze_cos, cover).
_FRAGMENT_SHADER = """
#version 330
uniform vec3 cos_iris;      // cos of the iris, limbus and pupil angles
uniform float limbus_shade;
uniform vec3 pupil;
uniform float not_eye;
uniform vec3 light_dir;
uniform vec3 fill_dir;
uniform float fill;
uniform float ambient;
uniform float diffuse;
uniform float specular;
uniform float shininess;
uniform float back_shade;
uniform float wire_width;
uniform float wire_darken;
in vec3 v_pos;
in vec3 v_nrm;
in vec3 v_col;
noperspective in vec3 v_bary;
in vec3 v_iris;
in vec2 v_look;
out vec4 f_color;
void main() {
    if (v_look.y < 0.5) discard;
    vec3 albedo = v_col;
    if (v_look.x > 0.5 * not_eye) {
        // eye_albedo's bands, each edge blended over about a pixel (fwidth: gaze_cos's change
        // per pixel) so the iris and pupil are round, not stair-stepped (MSAA smooths only
        // triangle edges, and these edges cross triangles)
        float w = max(fwidth(v_look.x), 1e-7);
        albedo = mix(albedo, limbus_shade * v_iris, smoothstep(cos_iris.x - w, cos_iris.x + w, v_look.x));
        albedo = mix(albedo, v_iris, smoothstep(cos_iris.y - w, cos_iris.y + w, v_look.x));
        albedo = mix(albedo, pupil, smoothstep(cos_iris.z - w, cos_iris.z + w, v_look.x));
    }
    vec3 n;
    if (length(v_nrm) < 1e-12) {
        n = normalize(cross(dFdx(v_pos), dFdy(v_pos)));   // toward the eye
        if (!gl_FrontFacing) n = -n;
    } else {
        n = normalize(v_nrm);
    }
    if (!gl_FrontFacing) n = -n;
    vec3 v = normalize(-v_pos);
    vec3 h = normalize(light_dir + v);
    float ndl = max(dot(n, light_dir), 0.0);
    float spec = ndl > 0.0 ? specular * pow(max(dot(n, h), 0.0), shininess) : 0.0;
    float ndf = max(dot(n, fill_dir), 0.0);
    vec3 c = albedo * (ambient + diffuse * ndl + fill * ndf) + vec3(spec);
    if (!gl_FrontFacing) c *= back_shade;
    if (wire_width > 0.0) {
        vec3 d = v_bary / max(fwidth(v_bary), vec3(1e-12));
        float alpha = clamp(0.5 * wire_width + 0.5 - min(min(d.x, d.y), d.z), 0.0, 1.0);
        c = mix(c, c * wire_darken, alpha);
    }
    f_color = vec4(clamp(c, 0.0, 1.0), 1.0);
}
"""

_CORNER_FLOATS = 17  # position, normal, colour, barycentric, iris colour, (gaze_cos, cover)

_warned_fallback = False


def _backend_choice(backend: str | None) -> str:
    choice = (backend if backend is not None else os.environ.get(BACKEND_ENV, "")).strip().lower() or "auto"
    if choice not in ("auto", "egl", "cpu"):
        raise RenderError(
            f"unknown render backend {choice!r} (from {BACKEND_ENV} or backend=); use auto, egl, cpu"
        )
    return choice


class Renderer:
    """Renders meshes to uint8 images, reusing one GL context across calls.

    Parameters
    ----------
    backend : "auto", "egl", "cpu" or None
        None reads ``MIMETIC_RENDER_BACKEND`` (default "auto": EGL, else the CPU rasterizer with a
        warning). "egl" raises ``RenderError`` when EGL is unavailable.

    Nothing is created until the first ``render``; ``backend`` then tells which one is in use.
    """

    def __init__(self, backend: str | None = None) -> None:
        self._choice = _backend_choice(backend)
        self._ctx = None
        self._prog = None
        self._vbo = None
        self._vao = None
        self._capacity = 0  # corners the vertex buffer holds
        self._framebuffers: dict[tuple[int, int, int], tuple] = {}
        self._backend: str | None = "cpu" if self._choice == "cpu" else None

    @property
    def backend(self) -> str | None:
        """The backend in use, "egl" or "cpu", once decided by the first render; else None."""
        return self._backend

    def _ensure_backend(self, stacklevel: int = 3) -> str:
        """Decide the backend on first use; ``stacklevel`` points the fallback warning at the caller."""
        if self._backend is None:
            try:
                self._create_context()
                self._backend = "egl"
            except Exception as error:
                reason = f"EGL offscreen rendering is unavailable ({type(error).__name__}: {error})"
                if self._choice == "egl":
                    raise RenderError(
                        f"{reason}. Install the system libraries: {APT_HINT}, "
                        f"or set {BACKEND_ENV}=cpu to use the slower CPU rasterizer."
                    ) from error
                global _warned_fallback
                if not _warned_fallback:
                    _warned_fallback = True
                    warnings.warn(
                        f"{reason}; falling back to the slower CPU rasterizer. For GL rendering: {APT_HINT}. "
                        f"Set {BACKEND_ENV}=cpu to silence this warning.",
                        MimeticWarning,
                        stacklevel=stacklevel,
                    )
                self._backend = "cpu"
        return self._backend

    def _create_context(self) -> None:
        import moderngl

        start = time.perf_counter()
        ctx = moderngl.create_standalone_context(backend="egl")
        try:
            with ctx:
                prog = ctx.program(vertex_shader=_VERTEX_SHADER, fragment_shader=_FRAGMENT_SHADER)
                prog["light_dir"].value = tuple(raster.LIGHT_DIR_VIEW)
                prog["fill_dir"].value = tuple(raster.FILL_DIR_VIEW)
                prog["specular"].value = raster.SPECULAR
                prog["shininess"].value = raster.SHININESS
                prog["back_shade"].value = raster.BACK_FACE_SHADE
                prog["wire_darken"].value = raster.WIRE_DARKEN
                prog["cos_iris"].value = tuple(
                    math.cos(a)
                    for a in (
                        appearance.IRIS_ANGLE_RAD,
                        appearance.LIMBUS_ANGLE_RAD,
                        appearance.PUPIL_ANGLE_RAD,
                    )
                )
                prog["limbus_shade"].value = appearance.LIMBUS_SHADE
                prog["pupil"].value = appearance.PUPIL
                prog["not_eye"].value = appearance.NOT_EYE
        except Exception:
            ctx.release()
            raise
        self._ctx, self._prog = ctx, prog
        log.debug(
            "EGL context (%s, %s) in %.3f s",
            ctx.info["GL_RENDERER"],
            ctx.info["GL_VERSION"],
            time.perf_counter() - start,
        )

    def _framebuffer(self, w: int, h: int, samples: int):
        key = (w, h, samples)
        if key not in self._framebuffers:
            ctx = self._ctx
            draw = ctx.framebuffer(
                color_attachments=[ctx.renderbuffer((w, h), samples=samples)],
                depth_attachment=ctx.depth_renderbuffer((w, h), samples=samples),
            )
            resolve = ctx.framebuffer(color_attachments=[ctx.renderbuffer((w, h))]) if samples else draw
            self._framebuffers[key] = (draw, resolve)
        return self._framebuffers[key]

    def _upload(self, corners: np.ndarray) -> None:
        """Write (3m, 14) float32 corner data, growing the buffer (and its VAO) when needed."""
        if len(corners) > self._capacity:
            for obj in (self._vao, self._vbo):
                if obj is not None:
                    obj.release()
            self._capacity = max(len(corners), 2 * self._capacity)
            self._vbo = self._ctx.buffer(reserve=self._capacity * _CORNER_FLOATS * 4, dynamic=True)
            self._vao = self._ctx.vertex_array(
                self._prog,
                [
                    (
                        self._vbo,
                        "3f 3f 3f 3f 3f 2f",
                        "in_pos",
                        "in_nrm",
                        "in_col",
                        "in_bary",
                        "in_iris",
                        "in_look",
                    )
                ],
            )
        self._vbo.write(corners)

    def render(
        self,
        mesh: Mesh,
        camera: Camera,
        *,
        size: int | tuple[int, int] = (512, 512),
        wireframe: bool = False,
        albedo: tuple[float, float, float] = raster.ALBEDO,
        background: tuple[float, float, float] = raster.BACKGROUND,
        msaa: int = 4,
        look: Surface | None = None,
        lighting: raster.Lighting = raster.DISPLAY,
    ) -> np.ndarray:
        """Render ``mesh`` seen by ``camera``.

        Parameters
        ----------
        mesh : Mesh
            Smooth-shaded with area-weighted vertex normals (shared by vertices at one rest position,
            ``Surface.weld``), both sides lit (back faces darker);
            drawn and coloured as ``look`` says.
        size : int or (width, height)
        wireframe : bool
            Darken a one-pixel line along every triangle edge.
        albedo, background : (r, g, b) float in [0, 1]
        msaa : int
            Samples per pixel for antialiasing (0 = off); ignored by the CPU backend.
        look : Surface, optional
            What to draw: ``appearance.surface(mesh, albedo)`` when omitted, which gives
            ``mesh.colors`` (n, 3) when present, else ``albedo`` and the parts' material colours;
            leaves out see-through films (transparent materials, eye occlusion shells, tear lines);
            gives eyeballs of one flat colour a pupil, iris and sclera, and draws lashes dark and
            thin and teeth ivory. Pass one made at a rest pose to draw a deformed mesh the same way.

        lighting : raster.Lighting
            The light levels (``raster.DISPLAY`` for pictures, ``raster.DETECTION`` for a face detector).

        Returns
        -------
        image : (h, w, 3) uint8, row 0 at the top; pixel centres project as in ``camera.project``.
        """
        w, h = _size(size)
        if msaa < 0 or (msaa & (msaa - 1)):
            raise ValueError(f"msaa={msaa} must be 0 or a power of two")
        if self._ensure_backend() == "cpu":
            return raster.rasterize(
                mesh,
                camera,
                size=(w, h),
                wireframe=wireframe,
                albedo=albedo,
                background=background,
                look=look,
                lighting=lighting,
            )
        albedo_rgb = raster._rgb(albedo, "albedo")
        background_rgb = raster._rgb(background, "background")
        raster.check_mesh(mesh)
        look = look if look is not None else surface(mesh, albedo_rgb)
        look.check(mesh)
        drawn = mesh.faces[look.faces]  # (m', 3)
        faces = drawn.ravel()  # (3m',) corner → vertex
        corners = np.empty((len(faces), _CORNER_FLOATS), np.float32)
        corners[:, 0:3] = mesh.vertices[faces]
        corners[:, 3:6] = appearance.shading_normals(mesh.vertices, drawn, look.weld)[faces]
        corners[:, 6:9] = look.colors[faces]
        corners[:, 9:12] = np.tile(np.eye(3, dtype=np.float32), (len(drawn), 1))
        corners[:, 12:15] = look.iris_colors[faces]
        corners[:, 15] = look.gaze_cos[faces]
        corners[:, 16] = look.cover[faces]
        near, far = clip_planes(camera, mesh.vertices)
        # numpy is row-major and GL column-major: the bytes of M.T are M in GL's order.
        view = camera.view_matrix().T.astype(np.float32).tobytes()
        proj = camera.projection_matrix(w / h, near, far).T.astype(np.float32).tobytes()

        import moderngl

        with self._ctx:  # make our context current: another Renderer may have switched it
            samples = min(msaa, self._ctx.max_samples) if msaa > 1 else 0
            draw, resolve = self._framebuffer(w, h, samples)
            self._prog["view"].write(view)
            self._prog["proj"].write(proj)
            self._prog["wire_width"].value = raster.WIRE_WIDTH_PX if wireframe else 0.0
            self._prog["ambient"].value = lighting.ambient
            self._prog["diffuse"].value = lighting.diffuse
            self._prog["fill"].value = lighting.fill
            draw.use()
            draw.clear(*(raster.to_uint8(background_rgb) / 255.0), 1.0, depth=1.0)
            if len(corners):
                self._upload(corners)
                self._ctx.enable(moderngl.DEPTH_TEST)
                self._ctx.disable(moderngl.CULL_FACE)
                self._vao.render(moderngl.TRIANGLES, vertices=len(corners))
            if samples:
                self._ctx.copy_framebuffer(resolve, draw)
            data = resolve.read(components=3, alignment=1)
        return np.frombuffer(data, np.uint8).reshape(h, w, 3)[::-1].copy()

    def release(self) -> None:
        """Free the GL context and its buffers; the next ``render`` creates them again."""
        if self._ctx is not None:
            with self._ctx:
                for draw, resolve in self._framebuffers.values():
                    for fbo in {id(draw): draw, id(resolve): resolve}.values():
                        for attachment in (*fbo.color_attachments, fbo.depth_attachment):
                            if attachment is not None:
                                attachment.release()
                        fbo.release()
                for obj in (self._vao, self._vbo, self._prog):
                    if obj is not None:
                        obj.release()
            self._ctx.release()
        self._framebuffers.clear()
        self._ctx = self._prog = self._vbo = self._vao = None
        self._capacity = 0
        if self._backend == "egl":
            self._backend = None


_default_renderers: dict[str, Renderer] = {}


def default_renderer() -> Renderer:
    """The shared ``Renderer`` for the backend ``MIMETIC_RENDER_BACKEND`` asks for, created once."""
    choice = _backend_choice(None)
    if choice not in _default_renderers:
        _default_renderers[choice] = Renderer(choice)
    return _default_renderers[choice]


def render(
    mesh: Mesh,
    view: str | Camera = "front",
    *,
    size: int | tuple[int, int] = 512,
    wireframe: bool = False,
    albedo: tuple[float, float, float] = raster.ALBEDO,
    background: tuple[float, float, float] = raster.BACKGROUND,
    msaa: int = 4,
    fill: float = 0.8,
    look: Surface | None = None,
) -> np.ndarray:
    """Render ``mesh`` from a named view (see ``VIEWS``) or a ``Camera``, with the shared renderer.

    A named view frames the mesh's bounding box with ``frame_camera(..., fill=fill)``; ``look`` is
    as in ``Renderer.render``.

    Returns
    -------
    image : (h, w, 3) uint8, as ``Renderer.render``.
    """
    w, h = _size(size)
    if isinstance(view, str):
        if view not in VIEWS:
            raise ValueError(f"unknown view {view!r}; use one of {', '.join(VIEWS)} or a Camera")
        if mesh.n_vertices == 0:
            raise ValueError("cannot frame a named view on a mesh without vertices; pass a Camera")
        camera = frame_camera(
            mesh.vertices.min(axis=0), mesh.vertices.max(axis=0), yaw_deg=VIEWS[view], fill=fill, aspect=w / h
        )
    else:
        camera = view
    renderer = default_renderer()
    renderer._ensure_backend(stacklevel=3)
    return renderer.render(
        mesh,
        camera,
        size=(w, h),
        wireframe=wireframe,
        albedo=albedo,
        background=background,
        msaa=msaa,
        look=look,
    )
