"""Tests for mimetic.head.model: ``make_head`` and the generated head's parts.

Heads come from ``mimetic.testing`` (2,500 requested skin vertices, cached). "Cases" are the
default head, 20 random heads (``HeadParams.random(seed)``) and every parameter at either end
of its range; properties that must hold for every valid parameter set are checked on all of them.
"""

from __future__ import annotations

from collections.abc import MutableMapping

import numpy as np
import pytest
import trimesh

from mimetic.head.model import Head
from mimetic.head.params import PARAM_RANGES, HeadParams
from mimetic.head.parts import IRIS_ANGLE, PUPIL_ANGLE, SCLERA, TOOTH, TOOTH_COLUMNS
from mimetic.head.topology import build_topology
from mimetic.mesh.geometry import boundary_loops, face_normals
from mimetic.testing import RANDOM_SEEDS, SMALL_RESOLUTION, capped_skin, head_with, range_end_params

FLIP_X = np.array([-1.0, 1.0, 1.0])
PARTS = ("skin", "eye_L", "eye_R", "teeth_upper", "teeth_lower", "tongue", "mouth", "ear_L", "ear_R")
CLOSED_PARTS = ("eye_L", "eye_R", "teeth_upper", "teeth_lower", "tongue", "ear_L", "ear_R")
INNER_PARTS = ("teeth_upper", "teeth_lower", "tongue", "mouth")
MIRROR_PART = {"eye_L": "eye_R", "eye_R": "eye_L", "ear_L": "ear_R", "ear_R": "ear_L"}

DEFAULT = {"default": None}
RANDOM = {f"seed={seed}": HeadParams.random(seed) for seed in RANDOM_SEEDS}
RANGE_ENDS = range_end_params()
ALL_CASES = {**DEFAULT, **RANDOM, **RANGE_ENDS}


def cases(*groups: dict) -> list:
    """pytest params (HeadParams or None), with the case names as ids."""
    merged = {k: v for group in groups for k, v in group.items()}
    return [pytest.param(params, id=name) for name, params in merged.items()]


def head_of(params: HeadParams | None) -> Head:
    return head_with(params, SMALL_RESOLUTION)


def part_vertices(head: Head, part: str) -> np.ndarray:
    return head.mesh.part_vertices(part)


def mouth_rim_size() -> int:
    return build_topology(SMALL_RESOLUTION).mouth.index.shape[1]


def signed_volume(vertices: np.ndarray, faces: np.ndarray) -> float:
    tri = vertices[faces]  # (m, 3, 3)
    return float(np.einsum("ij,ij->i", tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)


def assert_closed_and_consistently_wound(faces: np.ndarray, what: str) -> None:
    """Every undirected edge used by exactly two faces, every directed edge by exactly one."""
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])  # (3m, 2)
    _, directed_counts = np.unique(directed, axis=0, return_counts=True)
    _, counts = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    assert np.all(counts == 2), f"{what}: {np.sum(counts != 2)} edges are not shared by exactly two faces"
    assert np.all(directed_counts == 1), f"{what}: inconsistent winding"


# ---- structure ------------------------------------------------------------------------------------


def test_make_head_has_documented_parts_shapes_and_dtypes(head):
    mesh = head.mesh
    n, m = mesh.n_vertices, mesh.n_faces
    assert mesh.vertices.shape == (n, 3) and mesh.vertices.dtype == np.float64
    assert mesh.vertices.flags.c_contiguous
    assert mesh.faces.shape == (m, 3) and mesh.faces.dtype == np.int64
    assert mesh.colors is not None and mesh.colors.shape == (n, 3) and mesh.colors.dtype == np.float32
    assert mesh.units == "cm"
    assert tuple(mesh.parts) == PARTS
    assert head.mirror.shape == (n,) and head.mirror.dtype == np.int64
    assert head.eye_centres.shape == (2, 3) and head.eye_centres.dtype == np.float64
    assert isinstance(head.eye_radius, float) and head.eye_radius > 0
    assert head.resolution == SMALL_RESOLUTION
    assert head.n_skin == build_topology(SMALL_RESOLUTION).n_vertices
    # skin first; the parts' faces tile the face array in order
    assert np.array_equal(part_vertices(head, "skin"), np.arange(head.n_skin))
    assert np.array_equal(np.concatenate(list(mesh.parts.values())), np.arange(m))
    assert np.isfinite(mesh.vertices).all() and np.all((mesh.colors >= 0) & (mesh.colors <= 1))
    # the face looks down +Z, +Y is up, the subject's left eye is at +X
    assert head.eye_centres[0, 0] > 0 > head.eye_centres[1, 0]
    assert head.vertices[head.landmarks["nose_tip"], 2] > head.eye_centres[0, 2]
    assert head.vertices[head.landmarks["menton"], 1] < head.eye_centres[0, 1]


def test_make_head_result_is_immutable(head):
    arrays = {
        "mesh.vertices": head.mesh.vertices,
        "mesh.faces": head.mesh.faces,
        "mirror": head.mirror,
        "eye_centres": head.eye_centres,
        **{f"regions[{k!r}]": v for k, v in head.regions.items()},
    }
    writeable = [name for name, array in arrays.items() if array.flags.writeable]
    assert not writeable, f"writeable arrays on a shared (cached) Head: {writeable}"
    for name in ("landmarks", "regions"):
        mapping = getattr(head, name)
        assert not isinstance(mapping, MutableMapping), f"Head.{name} is a mutable {type(mapping).__name__}"


@pytest.mark.parametrize("params", cases(RANDOM, RANGE_ENDS))
def test_make_head_parameters_keep_exact_correspondence(head, params):
    other = head_of(params)
    assert other.mesh.vertices.shape == head.mesh.vertices.shape
    assert other.n_skin == head.n_skin
    assert np.array_equal(other.mesh.faces, head.mesh.faces)
    assert list(other.mesh.parts) == list(head.mesh.parts)
    for name, faces in head.mesh.parts.items():
        assert np.array_equal(other.mesh.parts[name], faces), name
    assert np.array_equal(other.mirror, head.mirror)
    assert np.array_equal(other.mesh.colors, head.mesh.colors)
    assert not np.array_equal(other.mesh.vertices, head.mesh.vertices)


@pytest.mark.parametrize("params", cases(DEFAULT, RANDOM))
def test_make_head_is_exactly_mirror_symmetric(params):
    head = head_of(params)
    v, mirror = head.vertices, head.mirror
    assert mirror.shape == (len(v),) and mirror.dtype == np.int64
    assert np.array_equal(mirror[mirror], np.arange(len(v)))
    # exact equality (== treats -0.0 and 0.0 as equal); no tolerance
    assert np.array_equal(v[mirror], v * FLIP_X)
    assert np.all(v[mirror == np.arange(len(v)), 0] == 0.0)
    np.testing.assert_array_equal(head.eye_centres[1], head.eye_centres[0] * FLIP_X)
    for part in PARTS:
        ids = part_vertices(head, part)
        assert np.array_equal(np.sort(mirror[ids]), part_vertices(head, MIRROR_PART.get(part, part))), part


# ---- closed parts and the mouth bag -----------------------------------------------------------------


@pytest.mark.parametrize("params", cases(DEFAULT, {k: RANDOM[k] for k in list(RANDOM)[:3]}))
@pytest.mark.parametrize("part", CLOSED_PARTS)
def test_make_head_closed_part_is_watertight_and_outward(params, part):
    sub, _ = head_of(params).mesh.submesh(part)
    assert sub.faces.dtype == np.int64 and sub.vertices.dtype == np.float64
    assert_closed_and_consistently_wound(sub.faces, part)
    assert signed_volume(sub.vertices, sub.faces) > 0, f"{part} faces point inward"
    assert trimesh.Trimesh(sub.vertices, sub.faces, process=False).is_watertight


@pytest.mark.parametrize("params", cases(DEFAULT, {k: RANDOM[k] for k in list(RANDOM)[:3]}))
def test_make_head_mouth_bag_welds_to_the_inner_lip(params):
    head = head_of(params)
    topo = build_topology(SMALL_RESOLUTION)
    inner_lip = topo.mouth.index[0]  # the mouth opening's edge
    bag = part_vertices(head, "mouth")
    rim = bag[: len(inner_lip)]
    assert rim.shape == inner_lip.shape
    assert np.array_equal(head.vertices[rim], head.vertices[inner_lip]), "the bag's rim is the inner lip"
    # identify the rim with the skin's inner-lip vertices: skin + bag is then one oriented
    # surface whose only openings are the eyes
    weld = np.arange(head.mesh.n_vertices)
    weld[rim] = inner_lip
    faces = weld[head.mesh.faces[np.concatenate([head.mesh.parts["skin"], head.mesh.parts["mouth"]])]]
    directed = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    _, directed_counts = np.unique(directed, axis=0, return_counts=True)
    _, counts = np.unique(np.sort(directed, axis=1), axis=0, return_counts=True)
    assert directed_counts.max() == 1, "the bag's winding disagrees with the skin's"
    assert set(np.unique(counts)) <= {1, 2}
    loops = boundary_loops(faces)
    eyes = (topo.eye_L.index[0], topo.eye_R.index[0])
    assert sorted((frozenset(loop.tolist()) for loop in loops), key=min) == sorted(
        (frozenset(ring.tolist()) for ring in eyes), key=min
    ), "after welding, only the two eye openings remain"


ENVELOPE_CASES = {
    **DEFAULT,
    **{k: RANDOM[k] for k in list(RANDOM)[:3]},
    **{
        k: v
        for k, v in RANGE_ENDS.items()
        if k.split("=")[0] in ("chin_height", "jaw_width", "mouth_width", "lower_lip")
    },
}


@pytest.mark.parametrize("params", cases(ENVELOPE_CASES))
def test_make_head_inner_parts_stay_inside_the_skin(params):
    head = head_of(params)
    envelope = capped_skin(head)
    shell = trimesh.Trimesh(envelope.vertices, envelope.faces, process=False)
    assert shell.is_watertight and shell.is_winding_consistent and shell.volume > 0
    outside = {}
    for part in INNER_PARTS:
        ids = part_vertices(head, part)
        if part == "mouth":
            ids = ids[mouth_rim_size() :]  # the rim lies on the skin
        inside = shell.contains(head.vertices[ids])
        assert inside.shape == (len(ids),) and inside.dtype == bool
        if not inside.all():
            outside[part] = int((~inside).sum())
    assert not outside, f"vertices outside the skin (holes capped): {outside}"


# ---- parameters ----------------------------------------------------------------------------------


def landmark(head: Head, name: str) -> np.ndarray:
    return head.vertices[head.landmarks[name]]


def distance(head: Head, a: str, b: str) -> float:
    return float(np.linalg.norm(landmark(head, a) - landmark(head, b)))


def skin(head: Head) -> np.ndarray:
    return head.vertices[: head.n_skin]


# parameter -> (what grows with it, how to measure it)
EFFECTS = {
    "head_width": ("x extent of the skin", lambda h: np.ptp(skin(h)[:, 0])),
    "head_height": ("y extent of the skin", lambda h: np.ptp(skin(h)[:, 1])),
    "head_depth": ("z extent of the skin", lambda h: np.ptp(skin(h)[:, 2])),
    "jaw_width": ("gonion distance", lambda h: distance(h, "gonion_L", "gonion_R")),
    "chin_height": (
        "lower lip to menton height",
        lambda h: landmark(h, "lower_lip_bottom")[1] - landmark(h, "menton")[1],
    ),
    "nose_length": (
        "nasion to subnasale height",
        lambda h: landmark(h, "nasion")[1] - landmark(h, "subnasale")[1],
    ),
    "nose_width": ("alae fullness: the alare comes forward", lambda h: landmark(h, "alare_L")[2]),
    "nose_projection": ("nose tip forward", lambda h: landmark(h, "nose_tip")[2]),
    "upper_lip": (
        "upper vermilion height",
        lambda h: landmark(h, "upper_lip_top")[1] - landmark(h, "upper_lip_inner")[1],
    ),
    "lower_lip": (
        "lower vermilion height",
        lambda h: landmark(h, "lower_lip_inner")[1] - landmark(h, "lower_lip_bottom")[1],
    ),
    "mouth_width": ("mouth corner distance", lambda h: distance(h, "mouth_corner_L", "mouth_corner_R")),
    "eye_spacing": ("pupil distance", lambda h: distance(h, "pupil_L", "pupil_R")),
    "eye_size": (
        "palpebral fissure width",
        lambda h: distance(h, "eye_outer_corner_L", "eye_inner_corner_L"),
    ),
    "brow_ridge": ("brows forward", lambda h: h.vertices[h.regions["brow_L"], 2].mean()),
    "cheekbones": ("cheeks forward", lambda h: h.vertices[h.regions["cheek_L"], 2].mean()),
}


def test_make_head_effects_table_covers_every_parameter():
    assert set(EFFECTS) == set(PARAM_RANGES)


@pytest.mark.parametrize("name", list(PARAM_RANGES))
def test_make_head_parameter_acts_as_documented(name):
    low, high, _ = PARAM_RANGES[name]
    what, measure = EFFECTS[name]
    values = [measure(head_of(HeadParams().with_values(**{name: x}))) for x in (low, 1.0, high)]
    assert values[0] < values[1] < values[2], f"{name}: {what} should grow: {values}"


@pytest.mark.parametrize(("name", "axis"), [("head_width", 0), ("head_height", 1), ("head_depth", 2)])
@pytest.mark.parametrize("factor", ["low", "high"])
def test_make_head_head_size_parameters_scale_the_whole_head(head, name, axis, factor):
    low, high, _ = PARAM_RANGES[name]
    value = low if factor == "low" else high
    scaled = head_of(HeadParams().with_values(**{name: value}))
    scale = np.ones(3)
    scale[axis] = value
    assert scaled.vertices.shape == head.vertices.shape
    eyes = np.concatenate([head.mesh.part_vertices("eye_L"), head.mesh.part_vertices("eye_R")])
    rest = np.setdiff1d(np.arange(head.mesh.n_vertices), eyes)
    np.testing.assert_allclose(scaled.vertices[rest], head.vertices[rest] * scale, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(scaled.eye_centres, head.eye_centres * scale, rtol=1e-12, atol=1e-12)
    # the eyeballs stay spheres, scaled by the smallest factor about their moved centres
    k = min(1.0, value)
    assert scaled.eye_radius == pytest.approx(head.eye_radius * k, rel=1e-12)
    for i, part in enumerate(("eye_L", "eye_R")):
        ids = head.mesh.part_vertices(part)
        expected = scaled.eye_centres[i] + (head.vertices[ids] - head.eye_centres[i]) * k
        np.testing.assert_allclose(scaled.vertices[ids], expected, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("params", cases(RANDOM, RANGE_ENDS))
def test_make_head_folds_no_skin_triangle(head, params):
    """No triangle turns over: neither against the default head (normals more than 120° apart) nor
    against its neighbours (an edge whose two faces point apart by more than 120° where they agree
    on the default head). Near-vertical triangles under the nose and at the mouth corners may
    legitimately turn a little past 90° when the nose gets shorter or the lips fuller."""
    other = head_of(params)
    faces = head.mesh.faces[head.mesh.parts["skin"]]
    reference = face_normals(head.vertices, faces)  # (m, 3) unit
    normals = face_normals(other.vertices, faces)
    assert normals.shape == reference.shape == (len(faces), 3) and normals.dtype == np.float64
    dot = np.einsum("ij,ij->i", normals, reference)
    flipped = np.nonzero(dot < -0.5)[0]
    where = np.round(head.vertices[faces[flipped[:2]]].mean(axis=1), 2).tolist()  # default-head centroids
    assert len(flipped) == 0, (
        f"{len(flipped)} skin triangles turn over (normal · default normal < -0.5; min {dot.min():.3f}); "
        f"first faces {flipped[:4].tolist()} at {where}"
    )
    edges = np.sort(faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    order = np.lexsort((edges[:, 1], edges[:, 0]))
    shared = np.nonzero(np.all(edges[order][1:] == edges[order][:-1], axis=1))[0]  # manifold: pairs
    f0, f1 = order[shared] // 3, order[shared + 1] // 3
    new = np.einsum("ij,ij->i", normals[f0], normals[f1])
    old = np.einsum("ij,ij->i", reference[f0], reference[f1])
    folds = np.nonzero((new < -0.5) & (old > 0.0))[0]
    assert len(folds) == 0, f"{len(folds)} edges fold over (neighbour normals {new[folds[:4]]})"


# ---- eyes --------------------------------------------------------------------------------------------


def lid_vertices(side: str) -> np.ndarray:
    """The eye-ring vertices from the lid margin outward (u ≥ 0); the skirt (u < 0) is tucked in."""
    rings = getattr(build_topology(SMALL_RESOLUTION), f"eye_{side}")
    return rings.index[rings.u >= 0].ravel()


@pytest.mark.parametrize("params", cases(ALL_CASES))
def test_make_head_eyelids_stay_outside_the_eyeball(params):
    head = head_of(params)
    for i, side in enumerate("LR"):
        lids = lid_vertices(side)
        gap = np.linalg.norm(head.vertices[lids] - head.eye_centres[i], axis=1) - head.eye_radius
        assert gap.shape == (len(lids),)
        assert gap.min() >= 0.0, f"eye_{side}: a lid vertex is {-gap.min():.3f} cm inside the eye radius"


@pytest.mark.parametrize("params", cases(ALL_CASES))
def test_make_head_eyelids_stay_outside_the_eyeball_mesh(params):
    head = head_of(params)
    for side in "LR":
        sub, _ = head.mesh.submesh(f"eye_{side}")
        eyeball = trimesh.Trimesh(sub.vertices, sub.faces, process=False)
        inside = eyeball.contains(head.vertices[lid_vertices(side)])
        assert not inside.any(), f"eye_{side}: {inside.sum()} lid vertices inside the eyeball mesh"


@pytest.mark.parametrize(
    "params", cases(DEFAULT, {k: v for k, v in RANGE_ENDS.items() if k.startswith(("head_", "eye_size"))})
)
def test_make_head_eyeballs_are_spheres_of_eye_radius(params):
    head = head_of(params)
    for i, side in enumerate("LR"):
        ball = head.vertices[part_vertices(head, f"eye_{side}")] - head.eye_centres[i]  # (k, 3)
        polar = np.arccos(np.clip(ball[:, 2] / np.linalg.norm(ball, axis=1), -1, 1))
        sclera = ball[polar > IRIS_ANGLE + 1e-6]  # behind the cornea bulge
        radius = np.linalg.norm(sclera, axis=1)
        np.testing.assert_allclose(
            radius,
            head.eye_radius,
            rtol=1e-9,
            err_msg=f"eye_{side}: sclera radius {radius.min():.4f}..{radius.max():.4f}, eye_radius "
            f"{head.eye_radius:.4f}",
        )


def test_make_head_eyeball_iris_and_pupil_colours_differ_from_the_sclera(head):
    colors = head.mesh.colors
    for i, side in enumerate("LR"):
        ids = part_vertices(head, f"eye_{side}")
        ball = head.vertices[ids] - head.eye_centres[i]
        polar = np.arccos(np.clip(ball[:, 2] / np.linalg.norm(ball, axis=1), -1, 1))  # 0 = looking +Z
        pupil = colors[ids[polar <= PUPIL_ANGLE * 0.9]]
        iris = colors[ids[(polar > PUPIL_ANGLE * 1.1) & (polar < IRIS_ANGLE * 0.9)]]
        sclera = colors[ids[polar > IRIS_ANGLE * 1.1]]
        assert len(pupil) and len(iris) and len(sclera)
        np.testing.assert_allclose(sclera, np.tile(SCLERA, (len(sclera), 1)), atol=1e-6)
        assert np.all(np.abs(iris - SCLERA).max(axis=1) > 0.2), f"eye_{side}: iris looks like sclera"
        assert np.all(np.abs(pupil - SCLERA).max(axis=1) > 0.2), f"eye_{side}: pupil looks like sclera"
        assert pupil.mean() < iris.mean() < sclera.mean(), "pupil darker than iris darker than sclera"
        assert head.landmarks[f"pupil_{side}"] in ids
        assert colors[head.landmarks[f"pupil_{side}"]].max() < 0.1


def test_make_head_teeth_are_shaded_apart_and_the_mouth_cavity_is_dark(head):
    colors = head.mesh.colors
    assert colors.shape == (head.mesh.n_vertices, 3) and colors.dtype == np.float32
    luminance = colors.astype(np.float64) @ (0.2126, 0.7152, 0.0722)  # (n,)
    for part in ("teeth_upper", "teeth_lower"):
        ids = part_vertices(head, part)
        columns = luminance[ids].reshape(-1, 4)  # (n, 4): the arch's columns, 4 corners each
        edge = columns[:, 1]  # the biting edge, along the arch
        assert edge.max() == pytest.approx(np.dot(TOOTH, (0.2126, 0.7152, 0.0722)), abs=0.02)
        assert edge.min() < 0.6 * edge.max(), f"{part}: no dark gaps between the teeth"
        dark = edge < 0.8 * edge.max()  # (n,) columns at a gap between teeth
        gaps = int(dark[0]) + int((dark[1:] & ~dark[:-1]).sum())  # runs of dark columns
        assert gaps >= len(edge) / TOOTH_COLUMNS - 1, f"{part}: {gaps} gaps along {len(edge)} columns"
        np.testing.assert_allclose(columns, columns[::-1], atol=1e-6)  # mirror symmetric
        assert (columns[:, 0] <= columns[:, 1]).all(), f"{part}: the root end is not darker"
    cavity = part_vertices(head, "mouth")
    mouth = luminance[cavity]
    lips = luminance[np.setdiff1d(head.regions["upper_lip"], cavity)]  # the region holds the bag's rim
    assert mouth.max() < 0.1 < lips.min(), "the mouth cavity is not dark beside the lips"


def test_make_head_draws_brows_along_the_brow_line_and_nowhere_else(head):
    """A face tracker follows brows by their hair; a bare head leaves it guessing."""
    from mimetic.head.model import BROW, BROW_LINE, SKIN

    colors = head.mesh.colors
    is_brow = np.all(colors == BROW, axis=1)
    for side in "LR":
        line = [head.landmarks[f"{name}_{side}"] for name in BROW_LINE]
        assert is_brow[line].all()
        above = head.landmarks[f"brow_mid_{side}"]
        forehead = np.flatnonzero(head.vertices[: head.n_skin, 1] > head.vertices[above, 1] + 1.5)
        assert not is_brow[forehead].any() and np.all(colors[forehead] == SKIN)
    assert is_brow.sum() < 0.05 * head.n_skin
    mirrored = head.mirror[np.flatnonzero(is_brow)]
    assert is_brow[mirrored].all()  # the same brows on both sides
