"""Synthetic rigs for the rig tests: an icosphere head with every kind of rig element.

``make_rig`` builds a small, valid ``Rig`` from a seeded generator; its keyword arguments let
property tests vary the counts, names, metadata and raw float values. Rigs are immutable, so
the fixtures are session-scoped.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import numpy as np
import pytest
import scipy.sparse as sp
import trimesh

from mimetic.engines import make_engine
from mimetic.mesh.model import Mesh, SurfacePoint
from mimetic.rig.activations import pose
from mimetic.rig.model import Bone, Channel, Muscle, Rig, Wire
from mimetic.testing import small_rig

HEAD_RADIUS_MM = 100.0


def icosphere_mesh(*, with_colors: bool = True, units: str | None = "mm") -> Mesh:
    """A 162-vertex, 320-face icosphere of radius 100 mm with parts "skin" (upper) and "neck"."""
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=HEAD_RADIUS_MM)
    vertices = np.asarray(sphere.vertices, dtype=np.float64)
    faces = np.asarray(sphere.faces, dtype=np.int64)
    lower = vertices[faces].mean(axis=1)[:, 1] < -0.6 * HEAD_RADIUS_MM  # (m,)
    parts = {"skin": np.flatnonzero(~lower), "neck": np.flatnonzero(lower)}
    colors = None
    if with_colors:
        colors = np.random.default_rng(7).random((len(vertices), 3)).astype(np.float32)
    return Mesh(vertices, faces, parts, colors, units)


def random_point(rng: np.random.Generator, n_faces: int) -> SurfacePoint:
    bary = rng.dirichlet([1.0, 1.0, 1.0])
    return SurfacePoint(int(rng.integers(n_faces)), (float(bary[0]), float(bary[1]), float(bary[2])))


def random_skin_weights(rng: np.random.Generator, n_vertices: int, n_bones: int) -> sp.csr_matrix:
    """(n_vertices, n_bones) CSR weights with 1..4 distinct bones per row, each row summing to 1."""
    rows, cols, vals = [], [], []
    for v in range(n_vertices):
        k = int(rng.integers(1, min(4, n_bones) + 1))
        bones = rng.choice(n_bones, size=k, replace=False)
        w = rng.random(k) + 0.05
        rows += [v] * k
        cols += bones.tolist()
        vals += (w / w.sum()).tolist()
    return sp.csr_matrix((vals, (rows, cols)), shape=(n_vertices, n_bones))


def make_rig(
    seed: int = 0,
    *,
    muscle_kinds: Sequence[str] = ("linear", "linear", "sphincter", "sheet"),
    n_wires: int = 2,
    n_bones: int = 4,
    names: Sequence[str] | None = None,
    metadata: dict[str, Any] | None = None,
    bone_coords: Sequence[float] | None = None,
    with_colors: bool = True,
) -> Rig:
    """A valid rig on ``icosphere_mesh()``.

    ``names`` (unique strings) name the muscles, wires, bones, extra channels, landmarks and
    regions in turn when given; ``bone_coords`` supplies raw floats for bone heads (cycled).
    """
    rng = np.random.default_rng(seed)
    mesh = icosphere_mesh(with_colors=with_colors)
    n, m = mesh.n_vertices, mesh.n_faces
    pool: Iterator[str] = iter(names) if names is not None else iter(())
    counter = iter(range(10_000))

    def name(default: str) -> str:
        return next(pool, f"{default}_{next(counter)}")

    regions = {
        name("region"): np.unique(rng.choice(n, size=20, replace=False)),
        name("region"): np.unique(rng.choice(n, size=35, replace=False)),
    }
    region_names = list(regions)
    landmarks = {name("landmark"): random_point(rng, m) for _ in range(5)}
    sides = ("L", "R", "C")
    muscles = []
    for i, kind in enumerate(muscle_kinds):
        start = float(rng.uniform(0.0, 0.9))
        muscles.append(
            Muscle(
                name=name(f"{kind}"),
                kind=kind,
                side=sides[i % 3],
                origin=random_point(rng, m),
                insertion=random_point(rng, m),
                width_rel=float(rng.uniform(0.01, 0.2)),
                falloff_start_rel=start,
                falloff_end_rel=start + float(rng.uniform(0.05, 1.0)),
                angle_rad=float(rng.uniform(0.1, np.pi)),
                origin_inset_rel=float(rng.uniform(0.0, 0.2)),
                reversed=bool(i % 2),
                region=region_names[i % 2] if i % 3 else None,
            )
        )
    wires = []
    for i in range(n_wires):
        p = int(rng.integers(2, 6))
        affecting = [mu.name for mu in muscles[: int(rng.integers(0, len(muscles) + 1))]]
        wires.append(
            Wire(
                name=name("wire"),
                side=sides[i % 3],
                points=tuple(random_point(rng, m) for _ in range(p)),
                dropoff_rel=float(rng.uniform(0.02, 0.3)),
                vertices=np.unique(rng.choice(n, size=int(rng.integers(0, 40)), replace=False)),
                muscle_weights={mu: rng.random(p) for mu in affecting},
                rest_weight=rng.random(p) + 0.1,
            )
        )
    bones = []
    coords = iter(np.resize(np.asarray(bone_coords, dtype=np.float64), 3 * n_bones)) if bone_coords else None
    for i in range(n_bones):
        head = np.array([next(coords) for _ in range(3)]) if coords is not None else rng.normal(size=3) * 50
        tail = head.copy()
        tail[1] = head[1] + 10.0 if abs(head[1]) < 1e15 else head[1] / 2
        parent = None if i == 0 else bones[int(rng.integers(0, i))].name
        bones.append(Bone(name("bone"), parent, head, tail))
    channels = [Channel(mu.name, 0.0, 1.0) for mu in muscles]
    channels += [
        Channel(name("jaw_open"), -0.1, 0.5, 0.0, "rad", "jaw"),
        Channel(name("jaw_slide"), -0.05, 0.05, 0.0, "rel", "jaw"),
    ]
    order = rng.permutation(len(channels))  # channel order is independent of muscle order
    return Rig(
        mesh=mesh,
        units="mm",
        scale=2 * HEAD_RADIUS_MM,
        landmarks=landmarks,
        regions=regions,
        muscles=tuple(muscles),
        wires=tuple(wires),
        bones=tuple(bones),
        skin_weights=random_skin_weights(rng, n, n_bones),
        channels=tuple(channels[i] for i in order),
        metadata={"source": "icosphere", "recipe": {"version": 1, "params": [1, 2.5, None, True]}}
        if metadata is None
        else metadata,
    )


@pytest.fixture(scope="session")
def rig() -> Rig:
    """A small valid rig: 162 vertices, 4 muscles (2 linear, a sphincter, a sheet), 2 wires, 4 bones."""
    return make_rig(0)


@pytest.fixture(scope="session")
def rig_builder():
    """``make_rig`` itself, for tests that vary its arguments."""
    return make_rig


MOVING_HEADS = (None, 1, 2)
"""The default generated head and two random ones (``HeadParams.random(seed)``)."""


@pytest.fixture(scope="module", params=MOVING_HEADS, ids=lambda s: "default" if s is None else f"random{s}")
def case(request):
    """(rig, rest vertices, motion(values) -> (n, 3)) for one generated head, through the wire engine:
    ``motion({channel: value})`` is the displacement from rest at that pose."""
    rig = small_rig(request.param)
    engine = make_engine(rig, "wire")
    rest = engine.deform(pose(rig))
    return rig, rest, lambda values: engine.deform(pose(rig, values)) - rest
