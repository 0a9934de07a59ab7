"""Renders draw parts as what they are: films left out, eyeballs with an iris, lashes thin and dark,
material colours from files (``mimetic.render.appearance`` and both renderers)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from trimesh.visual.material import PBRMaterial

from mimetic.mesh.io import load_mesh
from mimetic.mesh.model import Material, Mesh
from mimetic.render import Camera, project, rasterize
from mimetic.render.appearance import CAVITY, IRIS, LASH, NOT_EYE, SCLERA, part_kind, surface
from mimetic.render.raster import ALBEDO
from mimetic.testing import load_ict, require_shared_data

EYE_CENTRE = np.array([3.0, 2.0, 9.2])
EYE_RADIUS = 1.2
GREEN = (0.05, 0.9, 0.05)


def _mesh(tm: trimesh.Trimesh) -> Mesh:
    return Mesh(np.asarray(tm.vertices, np.float64), np.asarray(tm.faces, np.int64))


def _cap(radius: float, max_angle_deg: float) -> Mesh:
    """The part of a sphere around ``EYE_CENTRE`` within ``max_angle_deg`` of +Z: an open shell."""
    ball = trimesh.creation.icosphere(subdivisions=3, radius=radius)
    angle = np.degrees(np.arccos(np.clip(ball.vertices[:, 2] / radius, -1, 1)))
    keep = (angle[ball.faces] < max_angle_deg).all(axis=1)
    used, faces = np.unique(ball.faces[keep], return_inverse=True)
    return Mesh(ball.vertices[used] + EYE_CENTRE, faces.reshape(-1, 3))


def _lash() -> Mesh:
    """A lash card: a ribbon rooted on the upper front of the eyeball, growing up and forward."""
    x = np.linspace(-0.9, 0.9, 10)
    rows = []
    for out in (0.0, 0.25, 0.5, 0.75):  # distance grown from the root
        root = np.stack([x, np.full(10, 0.75), np.full(10, 0.0)], axis=1)
        root[:, 2] = np.sqrt(EYE_RADIUS**2 - root[:, 0] ** 2 - root[:, 1] ** 2)  # on the eyeball
        rows.append(root + out * np.array([0.0, 0.8, 0.6]) + EYE_CENTRE)
    vertices = np.concatenate(rows)
    faces = []
    for r in range(3):
        for c in range(9):
            a, b = r * 10 + c, r * 10 + c + 1
            faces += [[a, b, b + 10], [a, b + 10, a + 10]]
    return Mesh(vertices, np.array(faces))


def mini_head(*, shell: Material | None = None, shell_name: str = "occlusion", named: bool = True) -> Mesh:
    """A 20-unit "head": skin sphere, an uncoloured eyeball at ``EYE_CENTRE``, a shell over the eye
    and a lash card. ``named=False`` gives the same geometry without parts."""
    pieces = {
        "skin": _mesh(trimesh.creation.icosphere(subdivisions=3, radius=10.0)),
        "eye_L": _mesh(trimesh.creation.icosphere(subdivisions=3, radius=EYE_RADIUS)),
        shell_name: _cap(1.26, 50.0),
        "lash_strip": _lash(),
    }
    pieces["eye_L"] = pieces["eye_L"].with_vertices(pieces["eye_L"].vertices + EYE_CENTRE)
    mesh = Mesh.concatenate(pieces)
    if not named:
        return Mesh(mesh.vertices, mesh.faces)
    materials = {shell_name: shell} if shell is not None else {}
    return Mesh(mesh.vertices, mesh.faces, mesh.parts, None, None, materials)


EYE_CAMERA = Camera(eye=EYE_CENTRE + np.array([0, 0, 22]), target=EYE_CENTRE, fov_y_deg=9)
SIZE = 96


def pixel(image: np.ndarray, point) -> np.ndarray:
    x, y = project(np.asarray(point, np.float64), EYE_CAMERA, SIZE).pixels
    return image[int(y), int(x)].astype(int)


def on_eye(angle_deg: float, toward=(1.0, 0.0)) -> np.ndarray:
    """The eyeball's surface point ``angle_deg`` from its front pole, toward +X (or +Y)."""
    a = np.radians(angle_deg)
    return EYE_CENTRE + EYE_RADIUS * np.array([np.sin(a) * toward[0], np.sin(a) * toward[1], np.cos(a)])


def assert_reads_as_an_eye(image: np.ndarray) -> None:
    pupil, iris, sclera = (
        pixel(image, on_eye(0)),
        pixel(image, on_eye(18)),
        pixel(image, on_eye(45)),
    )
    assert pupil.max() < 40, f"pupil {pupil}"
    assert iris[0] > iris[2] + 20 and iris.max() < 150, f"iris {iris} is not brown"
    assert sclera.min() > 150, f"sclera {sclera} is not light"


@pytest.mark.parametrize(
    ("shell", "shell_name"),
    [
        (Material("Shell", GREEN, 0.2), "occlusion"),  # transparent material
        (Material("Shell", GREEN, 0.0), "part_7"),  # transparent material, name says nothing
        (None, "Eye occlusion left"),  # named as a film, no material
        (None, "lacrimal_fluid"),
    ],
)
def test_render_transparent_or_film_shell_does_not_cover_the_eye(gl_renderer, shell, shell_name):
    mesh = mini_head(shell=shell, shell_name=shell_name)
    for image in (gl_renderer.render(mesh, EYE_CAMERA, size=SIZE), rasterize(mesh, EYE_CAMERA, size=SIZE)):
        assert_reads_as_an_eye(image)


def test_render_opaque_shell_still_covers_the_eye(gl_renderer):
    mesh = mini_head(shell=Material("Visor", GREEN, 1.0), shell_name="visor")
    image = gl_renderer.render(mesh, EYE_CAMERA, size=SIZE)
    assert pixel(image, on_eye(0))[1] > 150  # the green visor is in front: only films are left out


def test_render_unnamed_eyeball_shell_and_lash_are_recognised_by_shape(gl_renderer):
    mesh = mini_head(named=False)
    look = surface(mesh, ALBEDO)
    shell_faces = np.flatnonzero(np.isin(np.arange(mesh.n_faces), look.faces, invert=True))
    named = mini_head()
    np.testing.assert_array_equal(shell_faces, named.parts["occlusion"])  # the film, only
    image = gl_renderer.render(mesh, EYE_CAMERA, size=SIZE)
    assert_reads_as_an_eye(image)


def test_render_lash_is_dark_near_its_root_and_not_drawn_at_its_tip(gl_renderer):
    mesh = mini_head()
    lash = mesh.part_vertices("lash_strip")
    look = surface(mesh, ALBEDO)
    np.testing.assert_allclose(look.colors[lash], np.tile(LASH, (len(lash), 1)))
    root, tip = mesh.vertices[lash[4]], mesh.vertices[lash[34]]  # rows 0 and 3 at the middle
    assert look.cover[lash[4]] == pytest.approx(1.0) and look.cover[lash[34]] < 0.5
    for image in (gl_renderer.render(mesh, EYE_CAMERA, size=SIZE), rasterize(mesh, EYE_CAMERA, size=SIZE)):
        near_root = pixel(image, root + np.array([0, 0.1, 0.05]))
        assert near_root.max() < 50, f"lash root {near_root} is not dark"
        assert pixel(image, tip).max() > 60  # the tip is not drawn: skin or background shows


def test_render_eye_pattern_and_films_agree_between_gl_and_cpu(gl_renderer):
    mesh = mini_head(shell=Material("Shell", GREEN, 0.2))
    camera = Camera(eye=EYE_CENTRE + np.array([6, 3, 20]), target=EYE_CENTRE, fov_y_deg=14)
    gl = gl_renderer.render(mesh, camera, size=(160, 120), msaa=0)
    cpu = rasterize(mesh, camera, size=(160, 120))
    difference = np.abs(gl.astype(int) - cpu.astype(int))
    assert difference.mean() < 3.0, f"mean abs diff {difference.mean():.2f}/255"
    # GL blends the edges of the pupil, iris and limbal ring over a pixel; the CPU rasterizer
    # draws them hard: those edge pixels (1.3 % of this picture) may differ, nothing else
    assert (difference.max(axis=2) > 8).mean() < 0.02


def test_render_painted_eyeball_keeps_its_own_colours(gl_renderer):
    mesh = mini_head()
    colors = np.tile(np.float32(ALBEDO), (mesh.n_vertices, 1))
    eye = mesh.part_vertices("eye_L")
    colors[eye] = np.where(mesh.vertices[eye, :1] > EYE_CENTRE[0], [[0.1, 0.2, 0.9]], [[0.9, 0.9, 0.9]])
    painted = Mesh(mesh.vertices, mesh.faces, mesh.parts, colors)
    look = surface(painted, ALBEDO)
    assert (look.gaze_cos == NOT_EYE).all()  # no iris painted over the file's colours
    np.testing.assert_array_equal(look.colors[eye], colors[eye])


def test_render_iris_takes_the_colour_of_a_flat_dark_iris_part(gl_renderer):
    base = mini_head()
    inner = trimesh.creation.icosphere(subdivisions=2, radius=1.1)
    mesh = Mesh.concatenate(
        {"base": base, "IrisLeft": _mesh(inner).with_vertices(inner.vertices + EYE_CENTRE)}
    )
    parts = {**{k: v for k, v in base.parts.items()}, "IrisLeft": mesh.parts["IrisLeft"]}
    blue = (0.15, 0.3, 0.7)
    mesh = Mesh(mesh.vertices, mesh.faces, parts, None, None, {"IrisLeft": Material("M_IrisLeft", blue)})
    image = gl_renderer.render(mesh, EYE_CAMERA, size=SIZE)
    iris = pixel(image, on_eye(18))
    assert iris[2] > iris[0] + 30, f"iris {iris} is not the file's blue"


def test_surface_of_the_generated_head_changes_nothing(small_head_mesh):
    look = surface(small_head_mesh, ALBEDO)
    np.testing.assert_array_equal(look.faces, np.arange(small_head_mesh.n_faces))
    np.testing.assert_array_equal(look.colors, small_head_mesh.colors)
    assert (look.gaze_cos == NOT_EYE).all() and (look.cover == 1.0).all()


@pytest.fixture(scope="module")
def small_head_mesh() -> Mesh:
    from mimetic.testing import small_head

    return small_head().mesh


def test_render_rejects_a_surface_made_for_another_mesh(gl_renderer, sphere):
    look = surface(mini_head(), ALBEDO)
    with pytest.raises(ValueError, match="another mesh"):
        gl_renderer.render(sphere, EYE_CAMERA, size=32, look=look)


@pytest.mark.parametrize(
    ("name", "material", "kind"),
    [
        ("Eyeball left", None, "eye"),
        ("part3", "M_ScleraLeft", "eye"),
        ("M_EyeLashes", None, "lash"),
        ("Eye occlusion right", None, "film"),
        ("x", "M_EyeBlend", "film"),
        ("Eye socket left", None, None),
        ("eyebrow_L", None, None),
        ("teeth_upper", None, "teeth"),
        ("Mouth socket", None, "cavity"),
        ("x", "M_MouthCavity", "cavity"),
        ("mouth_corner_L", None, None),
        ("skin", None, None),
    ],
)
def test_part_kind_reads_names(name, material, kind):
    assert part_kind(name, material) == kind


# --- material colours from files reach the render -------------------------------------------------


def _two_boxes_obj(folder: Path, mtl: str) -> Path:
    left = trimesh.creation.box(extents=(1, 1, 1))
    lines = ["mtllib boxes.mtl"]
    lines += [f"v {x - 1.2} {y} {z}" for x, y, z in left.vertices.tolist()]
    lines += [f"v {x + 1.2} {y} {z}" for x, y, z in left.vertices.tolist()]
    lines.append("usemtl LeftMat")
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in left.faces.tolist()]
    lines.append("usemtl RightMat")
    lines += [f"f {a + 9} {b + 9} {c + 9}" for a, b, c in left.faces.tolist()]
    (folder / "boxes.mtl").write_text(mtl)
    path = folder / "boxes.obj"
    path.write_text("\n".join(lines) + "\n")
    return path


BOXES_CAMERA = Camera(eye=(0, 2, 9), target=(0, 0, 0), fov_y_deg=30)


def _box_pixels(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    left = project(np.array([-1.2, 0.0, 0.5]), BOXES_CAMERA, 128).pixels
    right = project(np.array([1.2, 0.0, 0.5]), BOXES_CAMERA, 128).pixels
    return image[int(left[1]), int(left[0])].astype(int), image[int(right[1]), int(right[0])].astype(int)


def test_render_obj_mtl_colours_show_on_their_parts(gl_renderer, tmp_path):
    path = _two_boxes_obj(tmp_path, "newmtl LeftMat\nKd 0.9 0.1 0.1\nnewmtl RightMat\nKd 0.1 0.2 0.9\n")
    mesh = load_mesh(path, units="m", check=False)
    left, right = _box_pixels(gl_renderer.render(mesh, BOXES_CAMERA, size=128))
    assert left[0] > left[1] + 80 and left[0] > left[2] + 80, f"left box {left} is not red"
    assert right[2] > right[0] + 80, f"right box {right} is not blue"


def test_render_partial_mtl_colours_show_over_the_skin_tone(gl_renderer, tmp_path):
    path = _two_boxes_obj(tmp_path, "newmtl LeftMat\nKd 0.1 0.2 0.9\nnewmtl RightMat\nd 1\n")
    mesh = load_mesh(path, units="m", check=False)
    assert mesh.colors is None  # only one part is coloured: the colour stays on its material
    left, right = _box_pixels(gl_renderer.render(mesh, BOXES_CAMERA, size=128))
    assert left[2] > left[0] + 80, f"left box {left} is not blue"
    assert right[0] > right[2] + 40, f"right box {right} is not skin-toned"


def test_render_gltf_base_colours_show_on_their_parts(gl_renderer, tmp_path):
    scene = trimesh.Scene()
    for name, color, shift in (("left", [230, 20, 20, 255], -1.2), ("right", [20, 40, 230, 255], 1.2)):
        box = trimesh.creation.box(extents=(1, 1, 1))
        box.apply_translation((shift, 0, 0))
        box.visual = trimesh.visual.TextureVisuals(
            material=PBRMaterial(name=f"{name}Mat", baseColorFactor=color)
        )
        scene.add_geometry(box, node_name=name, geom_name=name)
    files = scene.export(file_type="gltf", embed_buffers=True)
    header = json.loads(next(iter(files.values())))
    assert [m["name"] for m in header["materials"]] == ["leftMat", "rightMat"]
    path = tmp_path / "boxes.gltf"
    path.write_bytes(next(iter(files.values())))
    mesh = load_mesh(path, units="m", check=False)
    left, right = _box_pixels(gl_renderer.render(mesh, BOXES_CAMERA, size=128))
    assert left[0] > left[2] + 80, f"left box {left} is not red"
    assert right[2] > right[0] + 80, f"right box {right} is not blue"


# --- ICT-FaceKit, as shipped ----------------------------------------------------------------------

ICT_SHELLS = ("Lacrimal fluid", "Eye blend", "Eye occlusion")
ICT_MTL = {
    "M_Face": "Kd 0.80 0.60 0.50",
    "M_BackHead": "Kd 0.80 0.60 0.50",
    "M_GumsTongue": "Kd 0.75 0.35 0.35",
    "M_Teeth": "Kd 0.92 0.90 0.82",
    "M_ScleraLeft": "Kd 0.95 0.95 0.93",
    "M_ScleraRight": "Kd 0.95 0.95 0.93",
    "M_IrisLeft": "Kd 0.15 0.30 0.60",
    "M_IrisRight": "Kd 0.15 0.30 0.60",
    "M_LacrimalFluid": "Kd 0.9 0.9 0.9\nd 0.1",
    "M_EyeBlend": "Kd 0.5 0.4 0.4\nd 0",
    "M_EyeOcclusion": "Kd 0.1 0.1 0.1\nd 0.3",
    "M_EyeLashes": "Kd 0.05 0.04 0.03",
}


def write_ict_obj(folder: Path, mesh: Mesh, meta: dict) -> Path:
    """ICT's neutral as an OBJ of its own quads with one ``usemtl`` per material and an .mtl beside it."""
    data = np.load(require_shared_data("ict-facekit") / "neutral.npz")
    names = [m["name"] for m in meta["materials"]]
    (folder / "ict.mtl").write_text("".join(f"newmtl {n}\n{ICT_MTL[n]}\n" for n in names))
    lines = ["mtllib ict.mtl", "# units: cm"] + [f"v {x!r} {y!r} {z!r}" for x, y, z in mesh.vertices.tolist()]
    current = None
    for quad, material in zip((data["quads"] + 1).tolist(), data["quad_material"].tolist(), strict=True):
        if material != current:
            lines.append(f"usemtl {names[material]}")
            current = material
        lines.append("f " + " ".join(str(i) for i in quad if i > 0))  # -1 + 1: a triangle
    path = folder / "ict.obj"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture(scope="module")
def ict() -> tuple[Mesh, dict]:
    return load_ict(require_shared_data("ict-facekit"))


def _ict_eyes(mesh: Mesh, meta: dict) -> list[tuple[np.ndarray, float]]:
    """(centre (3,), radius) of ICT's two outer eyeballs (its sclera vertex ranges)."""
    out = []
    for part in meta["eyeball_details"]:
        if part["name"].startswith("Sclera"):
            lo, hi = part["vertex_range"]
            points = mesh.vertices[lo : hi + 1]
            a = np.column_stack([2 * points, np.ones(len(points))])
            c = np.linalg.lstsq(a, (points**2).sum(axis=1), rcond=None)[0][:3]
            out.append((c, float(np.percentile(np.linalg.norm(points - c, axis=1), 95))))
    return out


def _ict_shell_faces(meta: dict) -> np.ndarray:
    data = np.load(require_shared_data("ict-facekit") / "neutral.npz")
    quads = [p["polygon_range"] for p in meta["parts"] if p["name"].startswith(ICT_SHELLS)]
    shell_quads = np.concatenate([np.arange(lo, hi + 1) for lo, hi in quads])
    return np.flatnonzero(np.isin(data["face_to_quad"], shell_quads))


def _assert_ict_eyes_read_as_eyes(
    image: np.ndarray, camera: Camera, eyes, size: int, iris_blue: bool
) -> None:
    for centre, radius in eyes:
        front = centre + np.array([0, 0, radius])
        side = centre + radius * np.array([np.sin(0.6) * np.sign(centre[0]), 0, np.cos(0.6)])  # outer white
        ring = centre + radius * np.array([np.sin(0.33), 0, np.cos(0.33)])
        (px, py), (sx, sy), (rx, ry) = project(np.stack([front, side, ring]), camera, size).pixels.astype(int)
        pupil, sclera, iris = image[py, px].astype(int), image[sy, sx].astype(int), image[ry, rx].astype(int)
        assert pupil.max() < 45, f"pupil {pupil}"
        assert sclera.min() > 120 and np.ptp(sclera) < 25, f"sclera {sclera} is not a light grey-white"
        if iris_blue:
            assert iris[2] > iris[0] + 25, f"iris {iris} is not the .mtl's blue"
        else:
            assert iris[0] > iris[2] + 15 and iris.max() < 160, f"iris {iris} is not brown"


ICT_CAMERA = Camera(eye=(0.0, 3.6, 40.0), target=(0.0, 3.6, 8.0), fov_y_deg=18)


def test_render_ict_as_shipped_shows_its_eyes_not_its_shells(gl_renderer, ict):
    mesh, meta = ict
    look = surface(mesh, ALBEDO)
    hidden = np.setdiff1d(np.arange(mesh.n_faces), look.faces)
    np.testing.assert_array_equal(hidden, _ict_shell_faces(meta))  # exactly the three shells
    lashes = next(p for p in meta["parts"] if p["name"] == "Eyelashes left")["vertex_range"]
    lash = np.arange(lashes[0], lashes[1] + 1)
    np.testing.assert_allclose(look.colors[lash], np.tile(LASH, (len(lash), 1)))
    assert 0.3 < (look.cover[lash] >= 0.5).mean() < 0.8  # the cards drawn only near their roots
    size = 384
    for image in (gl_renderer.render(mesh, ICT_CAMERA, size=size), rasterize(mesh, ICT_CAMERA, size=size)):
        _assert_ict_eyes_read_as_eyes(image, ICT_CAMERA, _ict_eyes(mesh, meta), size, iris_blue=False)


def test_render_ict_obj_with_materials_uses_them(gl_renderer, ict, tmp_path):
    shipped, meta = ict
    mesh = load_mesh(write_ict_obj(tmp_path, shipped, meta))
    np.testing.assert_array_equal(mesh.vertices, shipped.vertices)  # order and count as written
    assert mesh.materials["M_EyeOcclusion"].transparent and mesh.materials["M_LacrimalFluid"].transparent
    np.testing.assert_allclose(mesh.colors[0], [0.8, 0.6, 0.5], atol=1e-6)  # Kd of the face
    look = surface(mesh, ALBEDO)
    hidden = set(np.setdiff1d(np.arange(mesh.n_faces), look.faces).tolist())
    shells = {name: mesh.parts[name] for name in ("M_LacrimalFluid", "M_EyeBlend", "M_EyeOcclusion")}
    assert hidden == set(np.concatenate(list(shells.values())).tolist())
    size = 384
    image = gl_renderer.render(mesh, ICT_CAMERA, size=size)
    _assert_ict_eyes_read_as_eyes(image, ICT_CAMERA, _ict_eyes(mesh, meta), size, iris_blue=True)
    sclera = look.colors[mesh.part_vertices("M_ScleraLeft")]
    np.testing.assert_allclose(sclera, np.tile([0.95, 0.95, 0.93], (len(sclera), 1)), atol=1e-6)
    assert not np.allclose(SCLERA, (0.95, 0.95, 0.93)) and not np.allclose(IRIS, (0.15, 0.3, 0.6))


def test_render_painted_iris_edges_are_antialiased_not_stair_stepped(gl_renderer):
    """Along a row from the pupil's centre to the sclera, each edge (pupil, limbus, sclera) passes
    through an in-between shade: no one-pixel step makes most of the change across its edge (a
    hard edge does: 0.97 to 1 of it, measured before the shader blended the bands)."""
    mesh = mini_head()
    size = 192
    image = gl_renderer.render(mesh, EYE_CAMERA, size=size, msaa=4).astype(float)
    assert image.shape == (size, size, 3)
    x, y = project(np.stack([on_eye(0.0), on_eye(50.0)]), EYE_CAMERA, size).pixels.T
    row = image[int(y[0]), int(x[0]) : int(x[1]) + 1].mean(axis=1)  # (k,) pupil centre → sclera
    steps = np.diff(row)
    edges = np.flatnonzero(np.abs(steps) > 10)
    edges = edges[(edges >= 2) & (edges < len(steps) - 2)]
    assert len(edges) >= 3, f"the row {row.round()} does not cross a pupil, an iris and a sclera"
    for i in edges:
        across = row[i + 3] - row[i - 2]  # the change across the edge, two pixels either side
        share = steps[i] / across
        assert share < 0.8, f"a {steps[i]:.0f} step of {across:.0f} at pixel {i} of {row.round()}"


def test_surface_colours_an_uncoloured_mouth_socket_dark_and_keeps_a_coloured_one(sphere):
    faces = np.arange(sphere.n_faces)
    half = {"skin": faces[: len(faces) // 2], "Mouth socket": faces[len(faces) // 2 :]}
    bare = Mesh(sphere.vertices, sphere.faces, half)
    look = surface(bare, ALBEDO)
    socket = np.unique(sphere.faces[half["Mouth socket"]])
    skin_only = np.setdiff1d(np.unique(sphere.faces[half["skin"]]), socket)
    np.testing.assert_allclose(look.colors[socket], np.tile(CAVITY, (len(socket), 1)))
    np.testing.assert_allclose(look.colors[skin_only], np.tile(ALBEDO, (len(skin_only), 1)))
    painted = Mesh(sphere.vertices, sphere.faces, half, np.full((sphere.n_vertices, 3), 0.5))
    np.testing.assert_array_equal(surface(painted, ALBEDO).colors, painted.colors)  # the file's colours stay


def test_render_a_sphere_split_at_a_seam_shades_like_the_whole_one(gl_renderer, sphere):
    """A glTF file splits a mesh at its UV seams; the split copy must not show the seam."""
    v, f = sphere.vertices, sphere.faces
    east = v[f].mean(axis=1)[:, 0] > 0  # (m,) faces on the +X half
    seam = np.unique(f[east])
    copy = np.full(len(v), -1)
    copy[seam] = len(v) + np.arange(len(seam))  # the +X half gets its own copies of its vertices
    split = Mesh(np.concatenate([v, v[seam]]), np.where(east[:, None], copy[f], f))
    assert split.n_vertices > sphere.n_vertices
    look = surface(split, ALBEDO)
    assert look.weld.shape == (split.n_vertices,) and look.weld.dtype == np.int64
    border = np.intersect1d(f[east], f[~east])  # on the seam: used by both halves
    np.testing.assert_array_equal(look.weld[copy[border]], border)  # a copy takes its original's normal
    camera = Camera(eye=(0, 0, 4), target=(0, 0, 0), fov_y_deg=40)
    for render in (gl_renderer.render, rasterize):
        whole, cut = (render(m, camera, size=96).astype(int) for m in (sphere, split))
        difference = np.abs(cut - whole).max(axis=2)
        assert difference.max() <= 2, f"{render.__name__}: the seam shows ({difference.max()} levels)"
