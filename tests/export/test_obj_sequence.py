"""Tests for mimetic.export.obj_sequence: one OBJ per frame, in rig vertex order."""

from __future__ import annotations

import numpy as np
import pytest

from mimetic.engines import make_engine
from mimetic.engines.bake import bake
from mimetic.engines.basis import Basis, Corrective, evaluate_basis
from mimetic.errors import ActivationError
from mimetic.export import ExportError, export_obj_sequence, frame_name
from mimetic.mesh.io import load_mesh, save_mesh
from mimetic.rig.activations import Clip
from mimetic.testing import small_rig


@pytest.fixture(scope="module")
def rig():
    return small_rig()


@pytest.fixture(scope="module")
def clip(rig):
    """4 frames at 24 fps: rest, jaw open, a smile, both."""
    values = np.zeros((4, len(rig.channels)))
    values[[1, 3], rig.channel_index("jaw_open")] = 0.3
    values[[2, 3], rig.channel_index("zygomatic_major_L")] = 1.0
    return Clip(rig.channel_names, values, 24)


@pytest.fixture(scope="module")
def basis(rig):
    """The baked small rig plus one made-up corrective (jaw_open x zygomatic_major_L)."""
    baked = bake(make_engine(rig, "wire"), correctives=0, samples=1).basis
    bump = np.random.default_rng(5).normal(size=(rig.n_vertices, 3))
    extra = Corrective(("jaw_open", "zygomatic_major_L"), bump)
    return Basis(baked.channels, baked.neutral, baked.deltas, (extra,))


def test_frame_name_pads_to_four_digits_or_more():
    assert frame_name("frame_", 1, 600) == "frame_0001.obj"
    assert frame_name("f", 12345, 12345) == "f12345.obj"


def test_export_obj_sequence_engine_frames_in_rig_order(rig, clip, tmp_path):
    two = Clip(clip.channels, clip.values[[0, 3]], clip.fps)  # rest, and jaw open with a smile
    calls = []
    paths = export_obj_sequence(rig, two, tmp_path / "seq", progress=lambda d, t: calls.append((d, t)))
    assert [p.name for p in paths] == ["frame_0001.obj", "frame_0002.obj"]
    assert calls == [(1, 2), (2, 2)]
    engine = make_engine(rig, "wire")
    for path, values in zip(paths, two.values, strict=True):
        mesh = load_mesh(path)
        assert mesh.vertices.shape == (rig.n_vertices, 3) and mesh.units == rig.units
        np.testing.assert_array_equal(mesh.vertices, engine.deform(values))  # repr: exact float64
        np.testing.assert_array_equal(mesh.faces, rig.mesh.faces)
        assert list(mesh.parts) == list(rig.mesh.parts)
        np.testing.assert_array_equal(mesh.colors, rig.mesh.colors)


def test_export_obj_sequence_rest_frame_is_save_mesh_byte_for_byte(rig, basis, clip, tmp_path):
    paths = export_obj_sequence(rig, clip, tmp_path / "seq", basis=basis)
    save_mesh(rig.mesh, tmp_path / "rest.obj")
    assert paths[0].read_bytes() == (tmp_path / "rest.obj").read_bytes()


def test_export_obj_sequence_from_basis_matches_evaluate_basis(rig, basis, clip, tmp_path):
    few = clip.select(["zygomatic_major_L", "jaw_open"])  # missing channels take their defaults
    paths = export_obj_sequence(rig, few, tmp_path / "b", basis=basis, prefix="take_")
    assert paths[0].name == "take_0001.obj"
    expected = evaluate_basis(basis, few.select(basis.channels).values)
    for path, vertices in zip(paths, expected, strict=True):
        np.testing.assert_array_equal(load_mesh(path).vertices, vertices)


def test_export_obj_sequence_rejects_unknown_channels_and_bad_input(rig, basis, tmp_path):
    with pytest.raises(ActivationError, match="'smile'"):
        export_obj_sequence(rig, Clip(("smile",), np.zeros((2, 1)), 24), tmp_path / "x")
    good = Clip(("jaw_open",), np.zeros((2, 1)), 24)
    with pytest.raises(ExportError, match="prefix"):
        export_obj_sequence(rig, good, tmp_path / "x", prefix="a/b")
    with pytest.raises(ExportError, match="5 vertices but the rig has"):
        export_obj_sequence(
            rig, good, tmp_path / "x", basis=Basis(basis.channels, basis.neutral[:5], basis.deltas[:, :5])
        )
    assert not (tmp_path / "x").exists()


def test_export_obj_sequence_failed_frame_leaves_earlier_files_whole(rig, basis, clip, tmp_path, monkeypatch):
    folder = tmp_path / "seq"
    export_obj_sequence(rig, clip, folder, basis=basis)
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    import mimetic.export.obj_sequence as module

    calls = []
    real = module.atomic_write_bytes

    def flaky(path, data):
        calls.append(path)
        if len(calls) == 3:
            raise OSError("disk full")
        return real(path, data)

    monkeypatch.setattr(module, "atomic_write_bytes", flaky)
    shifted = Clip(clip.channels, clip.values[::-1], clip.fps)
    with pytest.raises(OSError, match="disk full"):
        export_obj_sequence(rig, shifted, folder, basis=basis)
    after = {p.name: p.read_bytes() for p in folder.iterdir()}
    assert sorted(after) == sorted(before)  # no temporary file left, nothing half-written
    assert after["frame_0003.obj"] == before["frame_0003.obj"]
    assert after["frame_0001.obj"] == before["frame_0004.obj"]  # frames before the failure were replaced


def test_export_obj_sequence_missing_parent_is_a_write_error(rig, clip, tmp_path):
    from mimetic.atomic import WriteError

    with pytest.raises(WriteError, match="parent folder does not exist"):
        export_obj_sequence(rig, clip, tmp_path / "no" / "seq")


def test_export_obj_sequence_writes_the_users_source_frame(rig, clip, tmp_path):
    """A rig made from a Z-up scan (face toward -Y) writes Z-up frames: rest lies on the user's mesh."""
    import dataclasses

    z_up = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])  # rig (Y up) -> source (Z up)
    turned = dataclasses.replace(rig, metadata={**rig.metadata, "source_rotation": z_up.tolist()})
    paths = export_obj_sequence(turned, clip, tmp_path / "seq")
    np.testing.assert_array_equal(load_mesh(paths[0]).vertices, rig.mesh.vertices @ z_up.T)
    posed = make_engine(rig, "wire").deform(clip.values[1])
    np.testing.assert_allclose(load_mesh(paths[1]).vertices, posed @ z_up.T, atol=1e-12)
    up = load_mesh(paths[0]).vertices
    assert np.ptp(up[:, 2]) > np.ptp(up[:, 1])  # the head is tall along +Z, as the scan was
