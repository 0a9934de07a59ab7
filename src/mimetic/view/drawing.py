"""2D drawing over rendered images (lines, points, projected 3D segments), contact sheets, PNGs.

Images are (h, w, 3) uint8 arrays with row 0 at the top. Coordinates are the pixel coordinates
of ``camera.project``: x right, y down, pixel ``(i, j)`` centred at ``(i + 0.5, j + 0.5)``.
Colours are (r, g, b) floats in [0, 1], one triple for all items or one per item (k, 3).
Every function returns a new image and leaves its input alone.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from mimetic.atomic import atomic_write
from mimetic.render.camera import Camera, project


def _rgb8(image: np.ndarray) -> np.ndarray:
    image = np.asarray(image)
    if image.dtype != np.uint8:
        raise ValueError(f"images must be uint8; got {image.dtype}")
    if image.ndim == 2:
        image = np.repeat(image[:, :, None], 3, axis=2)
    if image.ndim != 3 or image.shape[2] not in (3, 4):
        raise ValueError(f"images must have shape (h, w, 3), (h, w, 4) or (h, w); got {image.shape}")
    return np.ascontiguousarray(image[:, :, :3])


def _colors8(colors, k: int) -> list[tuple[int, int, int]]:
    c = np.asarray(colors, dtype=np.float64)
    if c.shape == (3,):
        c = np.broadcast_to(c, (k, 3))
    if c.shape != (k, 3):
        raise ValueError(f"colors must be (3,) or ({k}, 3) floats in [0, 1]; got shape {c.shape}")
    c8 = np.floor(np.clip(c, 0.0, 1.0) * 255 + 0.5).astype(int)
    return [tuple(int(v) for v in row) for row in c8]


def _clip(a: np.ndarray, b: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple | None:
    """Segment a→b (2,) cut to the box [lo, hi] (Liang–Barsky), or None when it misses the box."""
    d = b - a
    t0, t1 = 0.0, 1.0
    for axis in range(2):
        for p, q in ((-d[axis], a[axis] - lo[axis]), (d[axis], hi[axis] - a[axis])):
            if p == 0:
                if q < 0:
                    return None
            elif p < 0:
                t0 = max(t0, q / p)
            else:
                t1 = min(t1, q / p)
    return (a + t0 * d, a + t1 * d) if t0 <= t1 else None


def _pixel(point: np.ndarray) -> tuple[int, int]:
    """The pixel (column, row) containing ``point``; Pillow addresses pixels by index."""
    return int(np.floor(point[0])), int(np.floor(point[1]))


def _font(size: int) -> ImageFont.ImageFont | ImageFont.FreeTypeFont:
    return ImageFont.load_default(size=max(int(size), 6))


def draw_lines(
    image: np.ndarray, segments_2d: np.ndarray, colors=(1.0, 0.85, 0.2), width: int = 2
) -> np.ndarray:
    """Draw straight segments (k, 2, 2) — (start, end) × (x, y) — over a copy of ``image``.

    Segments with a NaN coordinate (e.g. behind the camera) are skipped.
    """
    out = Image.fromarray(_rgb8(image))
    seg = np.asarray(segments_2d, dtype=np.float64).reshape(-1, 2, 2)
    draw = ImageDraw.Draw(out)
    margin = np.array([width + 2.0, width + 2.0])
    lo, hi = -margin, np.array(out.size, float) + margin
    for (a, b), color in zip(seg, _colors8(colors, len(seg)), strict=True):
        clipped = _clip(a, b, lo, hi) if np.all(np.isfinite([a, b])) else None
        if clipped is not None:
            draw.line([_pixel(clipped[0]), _pixel(clipped[1])], fill=color, width=int(width))
    return np.asarray(out)


def draw_points(
    image: np.ndarray, points_2d: np.ndarray, colors=(1.0, 0.85, 0.2), radius: float = 3.0
) -> np.ndarray:
    """Draw filled discs of ``radius`` pixels at points (k, 2) over a copy of ``image``; skip NaN points."""
    out = Image.fromarray(_rgb8(image))
    pts = np.asarray(points_2d, dtype=np.float64).reshape(-1, 2)
    draw = ImageDraw.Draw(out)
    for point, color in zip(pts, _colors8(colors, len(pts)), strict=True):
        if np.all(np.isfinite(point)):
            x, y = _pixel(point)
            draw.ellipse([x - radius, y - radius, x + radius, y + radius], fill=color)
    return np.asarray(out)


def overlay_segments(
    image: np.ndarray,
    camera: Camera,
    segments_3d: np.ndarray,
    colors=(1.0, 0.85, 0.2),
    labels: list[str] | None = None,
    *,
    width: int = 2,
    font_size: int = 11,
) -> np.ndarray:
    """Draw 3D segments (k, 2, 3), e.g. muscles from origin to insertion, over a rendered image.

    The image must have been rendered with ``camera``. Each segment gets a line and a dot at its
    end (the insertion), and its label beside the end; segments with an end behind the camera are
    skipped. Nothing is hidden by the surface: muscles lie under the skin and show through.
    """
    rgb = _rgb8(image)
    h, w = rgb.shape[:2]
    seg = np.asarray(segments_3d, dtype=np.float64).reshape(-1, 2, 3)
    if labels is not None and len(labels) != len(seg):
        raise ValueError(f"got {len(labels)} labels for {len(seg)} segments")
    pixels, _ = project(seg.reshape(-1, 3), camera, (w, h))
    seg_2d = pixels.reshape(-1, 2, 2)  # NaN behind the camera
    seg_2d[~np.isfinite(seg_2d).all(axis=(1, 2))] = np.nan
    out = draw_lines(rgb, seg_2d, colors, width)
    out = draw_points(out, seg_2d[:, 1], colors, radius=max(width, 2))
    if labels:
        pil = Image.fromarray(out)
        draw = ImageDraw.Draw(pil)
        font = _font(font_size)
        for (x, y), label, color in zip(seg_2d[:, 1], labels, _colors8(colors, len(seg)), strict=True):
            if np.isfinite(x) and np.isfinite(y):
                draw.text((x + width + 3, y), label, fill=color, font=font, anchor="lm")
        out = np.asarray(pil)
    return out


def contact_sheet(
    tiles: list[tuple[str, np.ndarray]],
    columns: int,
    label_height: int = 24,
    background=(0.12, 0.12, 0.13),
    label_color=(0.92, 0.92, 0.92),
) -> np.ndarray:
    """Lay labelled images out in a grid, each label centred in a strip under its tile.

    Every cell is as large as the largest tile plus the label strip; smaller tiles are centred
    in their cell. The sheet is (rows · (tile_h + label_height), columns · tile_w, 3) uint8 with
    ``rows = ceil(len(tiles) / columns)`` (``columns`` is capped at the number of tiles).
    """
    if not tiles:
        raise ValueError("contact_sheet needs at least one (label, image) tile")
    if columns < 1:
        raise ValueError(f"columns={columns} must be at least 1")
    images = [_rgb8(image) for _, image in tiles]
    columns = min(columns, len(tiles))
    rows = -(-len(tiles) // columns)
    tile_h = max(i.shape[0] for i in images)
    tile_w = max(i.shape[1] for i in images)
    cell_h = tile_h + label_height
    bg, fg = _colors8(background, 1)[0], _colors8(label_color, 1)[0]
    sheet = Image.new("RGB", (columns * tile_w, rows * cell_h), bg)
    draw = ImageDraw.Draw(sheet)
    font = _font(round(label_height * 0.6))
    for k, ((label, _), image) in enumerate(zip(tiles, images, strict=True)):
        r, c = divmod(k, columns)
        left, top = c * tile_w, r * cell_h
        sheet.paste(
            Image.fromarray(image),
            (left + (tile_w - image.shape[1]) // 2, top + (tile_h - image.shape[0]) // 2),
        )
        if label_height > 0 and label:
            draw.text(
                (left + tile_w / 2, top + tile_h + label_height / 2), label, fill=fg, font=font, anchor="mm"
            )
    return np.asarray(sheet)


IMAGE_FORMATS = {".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG", ".webp": "WEBP"}
"""Image file suffixes ``save_image`` writes, and the format each names."""


def save_image(image: np.ndarray, path: str | os.PathLike) -> Path:
    """Write ``image`` (h, w, 3|4) or (h, w) uint8 to ``path`` atomically, in the format its suffix
    names (``IMAGE_FORMATS``: PNG, JPEG at quality 95 without alpha, WebP); returns the path."""
    path = Path(path)
    kind = IMAGE_FORMATS.get(path.suffix.lower())
    if kind is None:
        raise ValueError(f"{path.name}: write images as {', '.join(IMAGE_FORMATS)}")
    array = np.asarray(image)
    shape_ok = array.ndim == 2 or (array.ndim == 3 and array.shape[2] in (3, 4))
    if array.dtype != np.uint8 or not shape_ok:
        raise ValueError(
            f"save_image needs an (h, w), (h, w, 3) or (h, w, 4) uint8 image; got {array.shape} {array.dtype}"
        )
    picture = Image.fromarray(np.ascontiguousarray(array))
    options = {}
    if kind == "JPEG":
        picture = picture.convert("RGB")
        options["quality"] = 95
    with atomic_write(path, "wb") as handle:
        picture.save(handle, format=kind, **options)
    return path


def save_png(image: np.ndarray, path: str | os.PathLike) -> Path:
    """Write ``image`` (h, w, 3|4) or (h, w) uint8 to ``path`` as a PNG, atomically; returns the path."""
    path = Path(path)
    if path.suffix.lower() != ".png":
        raise ValueError(f"{path.name}: save_png writes .png files; use save_image for other formats")
    return save_image(image, path)
