"""A CPU z-buffer rasterizer in plain numpy: the fallback when EGL is missing, and a test oracle.

It draws what the GL path in ``renderer.py`` draws (the faces and colours ``appearance.surface``
gives), with the same shading model (defined here, in ``shade``), but without antialiasing.
Triangles are grouped by the size of their pixel bounding box, so each group is one vectorised
edge-function test over a (triangles, rows, columns) grid of pixel centres. Every covered pixel
centre becomes a fragment (unless the lash cover interpolated there is under half); the nearest
fragment per pixel wins (largest interpolated 1 / depth, which is affine in screen space), and
only the winners are shaded.

Differences from GL: triangles with a vertex closer than the near plane are dropped rather
than clipped (``frame_camera`` views never have any), and pixel centres exactly on a shared
edge may go to either triangle.
"""

from __future__ import annotations

import itertools
import logging
import math
from dataclasses import dataclass

import numpy as np

from mimetic.errors import MeshError
from mimetic.mesh.model import Mesh
from mimetic.render.appearance import NOT_EYE, Surface, eye_albedo, shading_normals, surface
from mimetic.render.camera import Camera, _size, clip_planes

log = logging.getLogger(__name__)

# The shading model, shared with the GL shaders (render.py passes these as uniforms) and with the
# web viewer's lights (``view.look.page_lights``): change the look here and every picture follows.
AMBIENT = 0.18
DIFFUSE = 0.65
SPECULAR = 0.15
SHININESS = 40.0
#: Key light direction in view space (+Z toward the viewer): from the viewer's front-top-right.
LIGHT_DIR_VIEW = np.array([0.3, 0.6, 1.0]) / np.linalg.norm([0.3, 0.6, 1.0])
#: A weaker fill light from the front-bottom-left, as a studio's bounce card: without it, skin
#: facing down (under the nose and the brows) got the ambient term alone, and on a head without
#: nostrils the base of the nose read as a dark smudge, its edge following the triangles.
FILL = 0.3
FILL_DIR_VIEW = np.array([-0.2, -0.6, 1.0]) / np.linalg.norm([-0.2, -0.6, 1.0])


@dataclass(frozen=True)
class Lighting:
    """The light levels of the shading model (``shade``): ambient, key light and fill light."""

    ambient: float = AMBIENT
    diffuse: float = DIFFUSE
    fill: float = FILL


DISPLAY = Lighting()
"""The pictures' light (renders, videos, the viewer's page)."""
DETECTION = Lighting(ambient=0.25, diffuse=0.8, fill=0.0)
"""The light a face detector is shown (``fit.autolandmarks``), kept apart from the pictures' so
that restyling them never moves a fitted rig: when the fill light was added, ICT's automatic lid
and lip landmarks moved by up to 8 mm, 0.4 mm further from its landmark file on median."""

#: Back faces are lit with a flipped normal and then darkened by this factor, so the inside of
#: a mouth or an open shell reads as a darker surface rather than a hole.
BACK_FACE_SHADE = 0.55
#: Wireframe edges: the shaded colour times WIRE_DARKEN, over a line WIRE_WIDTH_PX wide.
WIRE_DARKEN = 0.4
WIRE_WIDTH_PX = 1.0
ALBEDO = (0.87, 0.68, 0.58)
BACKGROUND = (0.35, 0.35, 0.38)

_CHUNK_ELEMENTS = 1 << 21  # pixel candidates per vectorised block (~16 MB per float64 array)
_INSIDE_EPS = 1e-9  # barycentric tolerance so shared edges never leave cracks


def shade(
    normals: np.ndarray,
    positions: np.ndarray,
    colors: np.ndarray,
    front: np.ndarray,
    lighting: Lighting = DISPLAY,
) -> np.ndarray:
    """Lambert + Blinn-Phong colour of surface samples, lit from ``LIGHT_DIR_VIEW`` (and a diffuse
    fill from ``FILL_DIR_VIEW``).

    ``c = albedo (AMBIENT + DIFFUSE max(n·l, 0) + FILL max(n·f, 0)) + SPECULAR max(n·h, 0)^SHININESS``, with
    ``h = normalize(l + v)`` and ``v`` toward the eye; for back faces ``n`` is flipped and ``c``
    is multiplied by ``BACK_FACE_SHADE``. The specular term is zero where ``n·l <= 0``.

    Parameters
    ----------
    normals : (k, 3) float
        Interpolated view-space normals of the front side (need not be unit length; they must
        not be zero).
    positions : (k, 3) float
        View-space positions (the eye is at the origin, looking down -Z).
    colors : (k, 3) float
        Albedo in [0, 1].
    front : (k,) bool
        Whether each sample is on a front-facing triangle.

    Returns
    -------
    (k, 3) float64 colour, not clamped.
    """
    n = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    n = np.where(front[:, None], n, -n)
    v = -positions / np.linalg.norm(positions, axis=1, keepdims=True)
    h = LIGHT_DIR_VIEW + v
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    ndl = np.maximum(n @ LIGHT_DIR_VIEW, 0.0)  # (k,)
    ndh = np.maximum(np.einsum("kd,kd->k", n, h), 0.0)  # (k,)
    spec = np.where(ndl > 0, SPECULAR * ndh**SHININESS, 0.0)
    ndf = np.maximum(n @ FILL_DIR_VIEW, 0.0)  # (k,)
    c = colors * (lighting.ambient + lighting.diffuse * ndl + lighting.fill * ndf)[:, None] + spec[:, None]
    return np.where(front[:, None], c, c * BACK_FACE_SHADE)


def to_uint8(colors: np.ndarray) -> np.ndarray:
    """Float colours in [0, 1] → uint8, rounding to nearest as GL does for an 8-bit target."""
    return np.floor(np.clip(colors, 0.0, 1.0) * 255.0 + 0.5).astype(np.uint8)


def _rgb(value, name: str) -> np.ndarray:
    rgb = np.asarray(value, dtype=np.float64).reshape(-1)
    if rgb.shape != (3,):
        raise ValueError(f"{name} must be an (r, g, b) triple in [0, 1]; got {value!r}")
    return rgb


def check_mesh(mesh: Mesh) -> None:
    """Raise ``MeshError`` when ``mesh`` cannot be drawn (non-finite vertices, bad indices)."""
    if not np.all(np.isfinite(mesh.vertices)):
        bad = np.flatnonzero(~np.isfinite(mesh.vertices).all(axis=1))
        raise MeshError(f"cannot render: {len(bad)} vertices are NaN or infinite (first: {bad[0]})")
    if mesh.n_faces and (mesh.faces.min() < 0 or mesh.faces.max() >= mesh.n_vertices):
        raise MeshError(
            f"cannot render: face indices span [{mesh.faces.min()}, {mesh.faces.max()}] "
            f"but the mesh has {mesh.n_vertices} vertices"
        )


def rasterize(
    mesh: Mesh,
    camera: Camera,
    *,
    size: int | tuple[int, int] = (512, 512),
    wireframe: bool = False,
    albedo: tuple[float, float, float] = ALBEDO,
    background: tuple[float, float, float] = BACKGROUND,
    look: Surface | None = None,
    lighting: Lighting = DISPLAY,
) -> np.ndarray:
    """Render ``mesh`` seen by ``camera`` on the CPU, like ``Renderer.render`` with ``msaa=0``.

    Parameters
    ----------
    mesh : Mesh
        Smooth-shaded with area-weighted vertex normals; drawn and coloured as ``look`` says.
    size : int or (width, height)
    wireframe : bool
        Darken a one-pixel line along every triangle edge.
    look : Surface, optional
        What to draw: ``appearance.surface(mesh, albedo)`` when omitted (``mesh.colors`` when
        present, else ``albedo`` and the parts' material colours; see-through films left out;
        eyeballs, lashes and teeth drawn as such). Pass one made at a rest pose to draw a deformed
        mesh the same way.

    Returns
    -------
    image : (h, w, 3) uint8, row 0 at the top.
    """
    w, h = _size(size)
    albedo_rgb, background_rgb = _rgb(albedo, "albedo"), _rgb(background, "background")
    check_mesh(mesh)
    image = np.empty((h * w, 3), np.uint8)
    image[:] = to_uint8(background_rgb)
    if mesh.n_faces == 0:
        return image.reshape(h, w, 3)
    look = look if look is not None else surface(mesh, albedo_rgb)
    look.check(mesh)
    faces = mesh.faces[look.faces]  # (m', 3) the faces drawn

    # 1. Vertices to view space, then to pixel coordinates (x right, y down).
    view = camera.view_matrix()
    rotation = view[:3, :3]
    p_view = mesh.vertices @ rotation.T + view[:3, 3]  # (n, 3)
    n_view = shading_normals(mesh.vertices, faces, look.weld) @ rotation.T  # (n, 3)
    depth = -p_view[:, 2]  # (n,)
    near, _ = clip_planes(camera, mesh.vertices)
    f = 1.0 / math.tan(math.radians(camera.fov_y_deg) / 2)
    with np.errstate(divide="ignore", invalid="ignore"):
        sx = (f * h / w * p_view[:, 0] / depth + 1) * (w / 2)  # (n,)
        sy = (1 - f * p_view[:, 1] / depth) * (h / 2)  # (n,)
        inv_depth = 1.0 / depth  # (n,)

    # 2. Triangles in front of the near plane with a non-empty pixel bounding box.
    tri = np.flatnonzero((depth[faces] >= near).all(axis=1))  # (m',)
    X, Y = sx[faces[tri]], sy[faces[tri]]  # (m', 3)
    area = (X[:, 1] - X[:, 0]) * (Y[:, 2] - Y[:, 0]) - (X[:, 2] - X[:, 0]) * (Y[:, 1] - Y[:, 0])
    x0 = np.maximum(np.ceil(X.min(axis=1) - 0.5), 0).astype(np.int64)
    x1 = np.minimum(np.floor(X.max(axis=1) - 0.5), w - 1).astype(np.int64)
    y0 = np.maximum(np.ceil(Y.min(axis=1) - 0.5), 0).astype(np.int64)
    y1 = np.minimum(np.floor(Y.max(axis=1) - 0.5), h - 1).astype(np.int64)
    ok = (area != 0) & (x1 >= x0) & (y1 >= y0)
    tri, X, Y, area, x0, x1, y0, y1 = (a[ok] for a in (tri, X, Y, area, x0, x1, y0, y1))
    log.debug("rasterize: %d of %d triangles on screen", len(tri), len(faces))

    # 3. Fragments: every pixel centre inside a triangle, grouped by power-of-two box size.
    box_w = 1 << np.ceil(np.log2(x1 - x0 + 1)).astype(np.int64)
    box_h = 1 << np.ceil(np.log2(y1 - y0 + 1)).astype(np.int64)
    order = np.lexsort((box_h, box_w))
    frag_tri, frag_pix, frag_b = [], [], []
    bounds = np.flatnonzero(np.diff(box_w[order]) | np.diff(box_h[order])) + 1
    for group in np.split(order, bounds):
        if len(group) == 0:
            continue
        bw, bh = int(box_w[group[0]]), int(box_h[group[0]])
        step = max(1, _CHUNK_ELEMENTS // (bw * bh))  # triangles per block
        band = min(bh, max(1, _CHUNK_ELEMENTS // bw))  # box rows per block (< bh for huge boxes)
        for start, row in itertools.product(range(0, len(group), step), range(0, bh, band)):
            t = group[start : start + step]  # (T,)
            px = x0[t, None, None] + np.arange(bw)  # (T, 1, bw) int
            py = y0[t, None, None] + np.arange(row, min(row + band, bh))[:, None]  # (T, rows, 1) int
            cx, cy = px + 0.5, py + 0.5
            Xt, Yt = X[t, :, None, None], Y[t, :, None, None]  # (T, 3, 1, 1)
            inv_a = 1.0 / area[t, None, None]
            # b_i = edge function of the opposite edge (j, k) / signed area, (i, j, k) cyclic
            b0 = ((Xt[:, 1] - cx) * (Yt[:, 2] - cy) - (Xt[:, 2] - cx) * (Yt[:, 1] - cy)) * inv_a
            b1 = ((Xt[:, 2] - cx) * (Yt[:, 0] - cy) - (Xt[:, 0] - cx) * (Yt[:, 2] - cy)) * inv_a
            b2 = ((Xt[:, 0] - cx) * (Yt[:, 1] - cy) - (Xt[:, 1] - cx) * (Yt[:, 0] - cy)) * inv_a
            inside = (b0 >= -_INSIDE_EPS) & (b1 >= -_INSIDE_EPS) & (b2 >= -_INSIDE_EPS)
            inside &= (px <= x1[t, None, None]) & (py <= y1[t, None, None])  # (T, rows, bw)
            k, r, c = np.nonzero(inside)
            frag_tri.append(t[k])
            frag_pix.append((y0[t[k]] + row + r) * w + x0[t[k]] + c)
            frag_b.append(np.stack([b0[k, r, c], b1[k, r, c], b2[k, r, c]], axis=1))
    if not frag_tri:
        return image.reshape(h, w, 3)
    ftri, fpix, fb = np.concatenate(frag_tri), np.concatenate(frag_pix), np.concatenate(frag_b)
    corners = faces[tri[ftri]]  # (F, 3)
    if (look.cover < 1).any():  # fragments under half cover are not drawn (lash tips)
        q = fb * inv_depth[corners]
        cover = np.einsum("fi,fi->f", q, look.cover[corners]) / q.sum(axis=1)  # (F,)
        keep = cover >= 0.5
        ftri, fpix, fb, corners = ftri[keep], fpix[keep], fb[keep], corners[keep]

    # 4. Depth test: the largest screen-linear 1/depth per pixel wins.
    finv = np.einsum("fi,fi->f", fb, inv_depth[corners])  # (F,)
    zbuf = np.full(h * w, -np.inf)
    np.maximum.at(zbuf, fpix, finv)
    owner = np.full(h * w, -1)
    won = np.flatnonzero(finv == zbuf[fpix])
    owner[fpix[won]] = won
    pixels = np.flatnonzero(owner >= 0)  # (k,)
    win = owner[pixels]  # (k,)
    log.debug("rasterize: %d fragments, %d pixels covered", len(ftri), len(pixels))

    # 5. Perspective-correct interpolation and shading of the winners.
    wt, wb, wc = ftri[win], fb[win], corners[win]  # (k,), (k, 3), (k, 3)
    q = wb * inv_depth[wc]
    q /= q.sum(axis=1, keepdims=True)  # (k, 3)
    normals = np.einsum("ki,kid->kd", q, n_view[wc])
    positions = np.einsum("ki,kid->kd", q, p_view[wc])
    colors = np.einsum("ki,kid->kd", q, look.colors[wc])
    gaze = np.einsum("ki,ki->k", q, look.gaze_cos[wc])  # (k,)
    eye = gaze > NOT_EYE / 2
    if eye.any():
        iris = np.einsum("ki,kid->kd", q[eye], look.iris_colors[wc[eye]])
        colors[eye] = eye_albedo(gaze[eye], colors[eye], iris)
    front = area[wt] < 0  # counter-clockwise with y up is clockwise with y down
    flat = np.linalg.norm(normals, axis=1) < 1e-12
    if flat.any():  # normals cancelled: use the face normal, toward the eye
        pv = p_view[wc[flat]]  # (j, 3, 3)
        fn = np.cross(pv[:, 1] - pv[:, 0], pv[:, 2] - pv[:, 0])
        fn *= np.where(np.einsum("jd,jd->j", fn, pv[:, 0]) > 0, -1.0, 1.0)[:, None]
        normals[flat] = np.where(front[flat, None], fn, -fn)
    rgb = shade(normals, positions, colors, front, lighting)
    if wireframe:
        # Pixel distance to the nearest edge: b_i / fwidth(b_i), as the GL shader computes it.
        # With (i, j, k) cyclic, |A| fwidth(b_i) = |y_j - y_k| + |x_k - x_j|.
        Xw, Yw = X[wt], Y[wt]  # (k, 3)
        Xj, Xk, Yj, Yk = np.roll(Xw, -1, 1), np.roll(Xw, -2, 1), np.roll(Yw, -1, 1), np.roll(Yw, -2, 1)
        grad = np.abs(Yj - Yk) + np.abs(Xk - Xj)  # (k, 3)
        distance = (wb * np.abs(area[wt])[:, None] / np.maximum(grad, 1e-12)).min(axis=1)
        alpha = np.clip(WIRE_WIDTH_PX / 2 + 0.5 - distance, 0.0, 1.0)[:, None]
        rgb = rgb * (1 - alpha) + rgb * WIRE_DARKEN * alpha
    image[pixels] = to_uint8(rgb)
    return image.reshape(h, w, 3)
