"""Tests for mimetic.rig.format: the .mrig file (round trip, bad files, atomic saving)."""

from __future__ import annotations

import dataclasses
import io
import json
import os
import tempfile
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mimetic import __version__
from mimetic.errors import MimeticError, RigError, RigFormatError
from mimetic.mesh.model import Mesh
from mimetic.rig import FORMAT_VERSION, load_rig, rig_differences, save_rig

MEMBERS = ("manifest.json", "rig.json", "arrays.npz")


def read_members(path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


def write_members(path: Path, members: dict[str, bytes]) -> Path:
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as archive:
        for name, data in members.items():
            archive.writestr(name, data)
    return path


def rewrite(good: Path, out: Path, *, manifest=None, doc=None, arrays=None) -> Path:
    """Copy ``good`` to ``out`` with edits: each argument is a function that edits the parsed member."""
    members = read_members(good)
    if manifest is not None:
        data = json.loads(members["manifest.json"])
        manifest(data)
        members["manifest.json"] = json.dumps(data).encode()
    if doc is not None:
        data = json.loads(members["rig.json"])
        doc(data)
        members["rig.json"] = json.dumps(data).encode()
    if arrays is not None:
        with np.load(io.BytesIO(members["arrays.npz"])) as npz:
            data = {key: npz[key] for key in npz.files}
        arrays(data)
        buffer = io.BytesIO()
        np.savez(buffer, **data)  # allows pickles, unlike mimetic
        members["arrays.npz"] = buffer.getvalue()
    return write_members(out, members)


@pytest.fixture
def good(rig, tmp_path) -> Path:
    return save_rig(rig, tmp_path / "good.mrig")


# --------------------------------------------------------------------------- round trip


def test_save_rig_then_load_rig_returns_equal_rig(rig, tmp_path):
    path = save_rig(rig, tmp_path / "head.mrig")
    assert path == tmp_path / "head.mrig"
    loaded = load_rig(path)
    assert loaded.mesh.vertices.shape == rig.mesh.vertices.shape and loaded.mesh.vertices.dtype == np.float64
    assert loaded.mesh.faces.dtype == np.int64 and loaded.mesh.colors.dtype == np.float32
    assert loaded.skin_weights.shape == rig.skin_weights.shape
    assert rig_differences(rig, loaded) == []
    assert loaded == rig
    assert loaded.channel_names == rig.channel_names
    assert list(loaded.mesh.parts) == list(rig.mesh.parts)
    assert loaded.metadata["recipe"]["params"] == (1, 2.5, None, True)


def test_save_rig_sparse_variant_round_trips(rig_builder, tmp_path):
    rig = rig_builder(5, muscle_kinds=(), n_wires=0, n_bones=1, with_colors=False, metadata={})
    rig = dataclasses.replace(
        rig, mesh=Mesh(rig.mesh.vertices, rig.mesh.faces, {}, None, None), regions={}, landmarks={}
    )
    loaded = load_rig(save_rig(rig, tmp_path / "bare.mrig"))
    assert loaded.mesh.colors is None and loaded.mesh.units is None and dict(loaded.mesh.parts) == {}
    assert rig_differences(rig, loaded) == []


def test_save_rig_special_floats_are_bit_exact(rig, tmp_path):
    vertices = rig.mesh.vertices.copy()
    vertices[0] = [-0.0, 5e-324, 1e300]  # negative zero, smallest subnormal, huge
    vertices[1, 0] = np.nextafter(vertices[1, 0], np.inf)
    mesh = rig.mesh.with_vertices(vertices)
    odd = dataclasses.replace(rig, mesh=mesh, metadata={"third": 1 / 3, "neg_zero": -0.0, "tiny": 5e-324})
    loaded = load_rig(save_rig(odd, tmp_path / "odd.mrig"))
    assert loaded.mesh.vertices.tobytes() == vertices.tobytes()
    assert loaded.metadata["third"] == 1 / 3 and str(loaded.metadata["neg_zero"]) == "-0.0"
    assert rig_differences(odd, loaded) == []


def test_save_rig_same_rig_gives_same_bytes(rig, tmp_path):
    a = save_rig(rig, tmp_path / "a.mrig").read_bytes()
    b = save_rig(rig, tmp_path / "b.mrig").read_bytes()
    assert a == b


def test_save_rig_writes_manifest_and_pickle_free_arrays(rig, good):
    with zipfile.ZipFile(good) as archive:
        assert archive.namelist() == list(MEMBERS)
        assert all(info.compress_type == zipfile.ZIP_DEFLATED for info in archive.infolist())
        manifest = json.loads(archive.read("manifest.json"))
        doc = json.loads(archive.read("rig.json"))
        npz = np.load(io.BytesIO(archive.read("arrays.npz")), allow_pickle=False)
    assert manifest == {"format": "mimetic-rig", "version": FORMAT_VERSION, "mimetic": __version__}
    assert FORMAT_VERSION == 2
    assert [m["name"] for m in doc["muscles"]] == list(rig.muscle_names)
    with npz:
        arrays = {key: npz[key] for key in npz.files}
    assert all(a.dtype != object for a in arrays.values())
    vertices = arrays[doc["mesh"]["vertices"]]
    assert vertices.shape == (162, 3) and vertices.dtype == np.float64
    assert arrays[doc["skin_weights"]["indptr"]].shape == (163,)


def test_save_rig_does_not_modify_the_rig(rig, tmp_path):
    before = rig.mesh.vertices.copy(), rig.skin_weights.data.copy()
    save_rig(rig, tmp_path / "x.mrig")
    np.testing.assert_array_equal(rig.mesh.vertices, before[0])
    np.testing.assert_array_equal(rig.skin_weights.data, before[1])


_names = st.lists(st.text(min_size=1, max_size=12), min_size=40, max_size=40, unique=True)
_json = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**60), 2**60)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.text(max_size=8),
    lambda children: (
        st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=6), children, max_size=4)
    ),
    max_leaves=12,
)
_float = st.floats(allow_nan=False, allow_infinity=False)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    seed=st.integers(0, 2**32 - 1),
    kinds=st.lists(st.sampled_from(["linear", "sphincter", "sheet"]), max_size=6),
    n_wires=st.integers(0, 3),
    n_bones=st.integers(1, 5),
    names=_names,
    metadata=st.dictionaries(st.text(max_size=8), _json, max_size=4),
    coords=st.lists(_float, min_size=3, max_size=15),
)
def test_save_rig_random_valid_rig_round_trips(
    rig_builder, seed, kinds, n_wires, n_bones, names, metadata, coords
):
    rig = rig_builder(
        seed,
        muscle_kinds=kinds,
        n_wires=n_wires,
        n_bones=n_bones,
        names=names,
        metadata=metadata,
        bone_coords=coords,
    )
    with tempfile.TemporaryDirectory() as folder:
        loaded = load_rig(save_rig(rig, Path(folder) / "r.mrig"))
    assert rig_differences(rig, loaded) == []
    assert [b.head.tobytes() for b in loaded.bones] == [b.head.tobytes() for b in rig.bones]


# --------------------------------------------------------------------------- atomic saving


def test_save_rig_failing_writer_leaves_old_file_intact(rig, rig_builder, good, monkeypatch):
    old = good.read_bytes()
    writestr = zipfile.ZipFile.writestr

    def fail_on_arrays(self, info, data, *args, **kwargs):
        if getattr(info, "filename", info) == "arrays.npz":
            raise OSError("disk full")
        return writestr(self, info, data, *args, **kwargs)

    monkeypatch.setattr(zipfile.ZipFile, "writestr", fail_on_arrays)
    with pytest.raises(OSError, match="disk full"):
        save_rig(rig_builder(9), good)
    monkeypatch.undo()
    assert good.read_bytes() == old
    assert sorted(os.listdir(good.parent)) == ["good.mrig"]  # no temporary file left behind
    assert load_rig(good) == rig


def test_save_rig_missing_folder_raises_mimetic_error(rig, tmp_path):
    with pytest.raises(MimeticError, match="does not exist"):
        save_rig(rig, tmp_path / "nowhere" / "x.mrig")


# --------------------------------------------------------------------------- bad files


def test_load_rig_missing_file_raises_format_error(tmp_path):
    with pytest.raises(RigFormatError, match="no such file"):
        load_rig(tmp_path / "absent.mrig")


def test_load_rig_directory_raises_format_error(tmp_path):
    with pytest.raises(RigFormatError, match="is a directory"):
        load_rig(tmp_path)


def test_load_rig_empty_file_raises_format_error(tmp_path):
    path = tmp_path / "empty.mrig"
    path.write_bytes(b"")
    with pytest.raises(RigFormatError, match="empty"):
        load_rig(path)


def test_load_rig_not_a_zip_raises_format_error(tmp_path):
    path = tmp_path / "head.mrig"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(RigFormatError, match="not a mimetic rig: it is not a zip archive"):
        load_rig(path)


@pytest.mark.parametrize("fraction", [0.5, 0.9, 0.1])
def test_load_rig_truncated_file_raises_format_error(good, fraction):
    data = good.read_bytes()
    good.write_bytes(data[: int(len(data) * fraction)])
    with pytest.raises(RigFormatError, match="truncated") as info:
        load_rig(good)
    assert "copy it again" in str(info.value)


def test_load_rig_corrupted_member_raises_format_error(good, tmp_path):
    data = bytearray(good.read_bytes())
    with zipfile.ZipFile(good) as archive:
        info = archive.getinfo("arrays.npz")
    start = info.header_offset + 30 + len(info.filename) + len(info.extra) + 100
    data[start : start + 50] = bytes(50)  # zero 50 bytes inside the compressed arrays
    good.write_bytes(bytes(data))
    with pytest.raises(RigFormatError, match="truncated or damaged"):
        load_rig(good)


def test_load_rig_zip_without_manifest_raises_format_error(tmp_path):
    path = write_members(tmp_path / "other.mrig", {"model.obj": b"v 0 0 0\n"})
    with pytest.raises(RigFormatError, match=r"not a mimetic rig: the zip has no manifest\.json"):
        load_rig(path)


def test_load_rig_wrong_format_name_raises_format_error(good, tmp_path):
    path = rewrite(good, tmp_path / "x.mrig", manifest=lambda m: m.update(format="blender-rig"))
    with pytest.raises(RigFormatError, match=r"not a mimetic rig.*'blender-rig'"):
        load_rig(path)


def test_load_rig_newer_version_raises_format_error_with_upgrade_hint(good, tmp_path):
    newer = FORMAT_VERSION + 1
    path = rewrite(good, tmp_path / "new.mrig", manifest=lambda m: m.update(version=newer, mimetic="9.0.0"))
    with pytest.raises(RigFormatError) as info:
        load_rig(path)
    message = str(info.value)
    assert f"written by mimetic format version {newer}" in message
    assert f"versions ≤ {FORMAT_VERSION}" in message and "pip install -U mimetic" in message


def test_load_rig_bad_version_type_raises_format_error(good, tmp_path):
    path = rewrite(good, tmp_path / "v.mrig", manifest=lambda m: m.update(version="1"))
    with pytest.raises(RigFormatError, match="version should be an integer"):
        load_rig(path)


def test_load_rig_missing_member_raises_format_error(good, tmp_path):
    members = read_members(good)
    del members["arrays.npz"]
    path = write_members(tmp_path / "x.mrig", members)
    with pytest.raises(RigFormatError, match=r"incomplete: arrays\.npz is missing"):
        load_rig(path)


def test_load_rig_invalid_json_raises_format_error(good, tmp_path):
    members = read_members(good)
    members["rig.json"] = members["rig.json"][:-20]
    path = write_members(tmp_path / "x.mrig", members)
    with pytest.raises(RigFormatError, match=r"rig\.json is not valid JSON"):
        load_rig(path)


def test_load_rig_duplicate_json_key_raises_format_error(good, tmp_path):
    members = read_members(good)
    members["rig.json"] = members["rig.json"].replace(b'"units"', b'"scale": 1.0, "units"', 1)
    path = write_members(tmp_path / "x.mrig", members)
    with pytest.raises(RigFormatError, match="duplicate key 'scale'"):
        load_rig(path)


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (lambda d: d["muscles"][2].pop("kind"), "rig.json: muscles[2].kind is missing"),
        (lambda d: d.pop("bones"), "rig.json: bones is missing"),
        (lambda d: d["mesh"].pop("faces"), "rig.json: mesh.faces is missing"),
        (lambda d: d["wires"][1]["points"][0].pop("bary"), "rig.json: wires[1].points[0].bary is missing"),
        (
            lambda d: d["muscles"][0].update(width_rel="wide"),
            'muscles[0].width_rel should be a number; got "wide"',
        ),
        (lambda d: d["muscles"][1].update(reversed=1), "muscles[1].reversed should be a boolean"),
        (lambda d: d["channels"][0].update(minimum=True), "channels[0].minimum should be a number"),
        (lambda d: d["bones"][0].update(head=[1, 2]), "bones[0].head should be a list of 3 numbers"),
        (lambda d: d["muscles"][0]["origin"].update(face=1.5), "muscles[0].origin.face should be an integer"),
        (lambda d: d.update(muscles={}), "rig.json: muscles should be a list; got {} (object)"),
        (lambda d: d.update(scale=None), "rig.json: scale should be a number"),
        (
            lambda d: d["skin_weights"].update(shape=[162]),
            "skin_weights.shape should be 2 non-negative integers",
        ),
        (lambda d: d["regions"].update({next(iter(d["regions"])): 3}), "regions.region_"),
        (
            lambda d: d["mesh"].update(vertices="nope"),
            "no array 'nope' (referenced by rig.json: mesh.vertices)",
        ),
    ],
)
def test_load_rig_missing_or_mistyped_field_raises_format_error_naming_path(good, tmp_path, edit, expected):
    path = rewrite(good, tmp_path / "x.mrig", doc=edit)
    with pytest.raises(RigFormatError) as info:
        load_rig(path)
    assert expected in str(info.value)
    assert str(info.value).startswith("x.mrig: ")


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (
            lambda a: a.update({"mesh.vertices": a["mesh.vertices"].astype(np.float32)}),
            "'mesh.vertices' (rig.json: mesh.vertices) has dtype float32; expected float64",
        ),
        (
            lambda a: a.update({"mesh.faces": np.zeros((320, 4), np.int64)}),
            "'mesh.faces' (rig.json: mesh.faces) has shape (320, 4); expected (?, 3)",
        ),
        (
            lambda a: a.update({"wires.0.rest_weight": np.ones(99)}),
            "'wires.0.rest_weight' (rig.json: wires[0].rest_weight) has shape (99,); expected (",
        ),
        (
            lambda a: a.update({"skin_weights.indptr": a["skin_weights.indptr"].astype(np.int32)}),
            "has dtype int32; expected int64",
        ),
        (
            lambda a: a.update({"skin_weights.indptr": a["skin_weights.indptr"][::-1].copy()}),
            "skin_weights CSR arrays are inconsistent",
        ),
        (lambda a: a.pop("regions.0"), "no array 'regions.0' (referenced by rig.json: regions."),
    ],
)
def test_load_rig_wrong_array_raises_format_error_naming_key(good, tmp_path, edit, expected):
    path = rewrite(good, tmp_path / "x.mrig", arrays=edit)
    with pytest.raises(RigFormatError) as info:
        load_rig(path)
    assert expected in str(info.value)


def test_load_rig_object_array_raises_format_error_mentioning_pickle(good, tmp_path):
    def add_pickle(arrays):
        arrays["regions.0"] = np.array([{"evil": 1}, None], dtype=object)

    path = rewrite(good, tmp_path / "x.mrig", arrays=add_pickle)
    with pytest.raises(RigFormatError, match=r"'regions\.0' holds Python objects \(a pickle\)"):
        load_rig(path)


def test_load_rig_npz_member_not_an_archive_raises_format_error(good, tmp_path):
    members = read_members(good)
    members["arrays.npz"] = b"hello"
    path = write_members(tmp_path / "x.mrig", members)
    with pytest.raises(RigFormatError, match=r"arrays\.npz"):
        load_rig(path)


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (lambda d: d["muscles"][1]["origin"].update(face=99999), ".origin.face=99999 is out of range"),
        (lambda d: d["muscles"][0].update(kind="ring"), "muscle 'linear_"),
        (lambda d: d.update(units="furlong"), "units='furlong'"),
        (lambda d: d["bones"][1].update(parent="ghost"), ".parent='ghost' is not a bone"),
        (lambda d: d["skin_weights"].update(shape=[162, 9]), "skin_weights has shape (162, 9)"),
    ],
)
def test_load_rig_inconsistent_contents_raise_rig_error(good, tmp_path, edit, expected):
    path = rewrite(good, tmp_path / "x.mrig", doc=edit)
    with pytest.raises(RigError) as info:
        load_rig(path)
    assert not isinstance(info.value, RigFormatError)
    assert str(info.value).startswith("x.mrig: ")
    assert expected in str(info.value)


# --------------------------------------------------------------------------- the anatomy (format 2)


def test_load_rig_of_format_1_derives_the_anatomy(good, tmp_path, rig):
    """A file written before the anatomy was stored still loads, with the anatomy derived by the rules."""

    def to_version_1(data):
        data["version"] = 1

    path = rewrite(good, tmp_path / "v1.mrig", manifest=to_version_1, doc=lambda d: d.pop("anatomy"))
    loaded = load_rig(path)
    assert rig_differences(loaded, rig) == []


def test_save_rig_stores_the_anatomy_and_loads_it_back(tmp_path):
    from mimetic.testing import small_rig

    rig = small_rig()
    assert len(rig.anatomy.creases) > 10 and len(rig.anatomy.lip_contact) > 5
    path = save_rig(rig, tmp_path / "a.mrig")
    doc = json.loads(read_members(path)["rig.json"])
    assert {"creases", "skull", "lip_contact", "accessories", "thickness_rel"} <= set(doc["anatomy"])
    assert rig_differences(load_rig(path), rig) == []


def test_load_rig_written_before_tissue_actions_derives_them(tmp_path):
    """A version-2 file from before ``anatomy.actions`` existed loads with the actions derived."""
    from mimetic.testing import small_rig

    rig = small_rig()
    assert {a.name for a in rig.anatomy.actions} >= {"cheek_puff_L", "lip_roll_upper", "tongue_out"}
    good = save_rig(rig, tmp_path / "a.mrig")
    assert len(json.loads(read_members(good)["rig.json"])["anatomy"]["actions"]) == len(rig.anatomy.actions)
    old = rewrite(good, tmp_path / "old.mrig", doc=lambda d: d["anatomy"].pop("actions"))
    assert rig_differences(load_rig(old), rig) == []


def test_load_rig_written_before_the_local_channels_loads_and_runs(tmp_path):
    """A file from before the feature-local channels (depressor supercilii, septi, the nasalis parts)
    loads with the channels it stored and runs; a control that needs a new channel (AU4) names it."""
    from mimetic.animate.facs import FacsError, facs_pose
    from mimetic.engines import make_engine
    from mimetic.rig.activations import pose
    from mimetic.rig.anatomy.local import CHANNELS as LOCAL
    from mimetic.testing import small_rig

    rig = small_rig()
    good = save_rig(rig, tmp_path / "a.mrig")

    def drop(doc):
        doc["channels"] = [c for c in doc["channels"] if c["name"] not in LOCAL]
        doc["anatomy"]["actions"] = [a for a in doc["anatomy"]["actions"] if not set(a["gains"]) & set(LOCAL)]

    old = load_rig(rewrite(good, tmp_path / "old.mrig", doc=drop))
    assert len(old.channels) == len(rig.channels) - len(LOCAL) and not set(LOCAL) & set(old.channel_names)
    moved = make_engine(old, "wire").deform(pose(old, {"dilator_naris_L": 1.0})) - old.mesh.vertices
    assert np.linalg.norm(moved, axis=1).max() > 0.05
    assert facs_pose(old, {"AU12": 1.0}).shape == (len(old.channels),)
    with pytest.raises(FacsError, match="depressor_supercilii_L"):
        facs_pose(old, {"AU4": 1.0})


@pytest.mark.parametrize(
    ("edit", "expected"),
    [
        (lambda d: d["anatomy"].pop("skull"), "anatomy.skull is missing"),
        (lambda d: d["anatomy"]["actions"][0].update(gains={"ghost": 1.0}), "channels the rig lacks"),
        (lambda d: d["anatomy"]["creases"][0].update(gains={"ghost": 1.0}), "channels the rig lacks"),
        (
            lambda d: d["anatomy"]["creases"][0].update(gains={"frontalis_inner_L": "deep"}),
            "should be a number",
        ),
    ],
)
def test_load_rig_bad_anatomy_names_the_field(tmp_path, edit, expected):
    from mimetic.testing import small_rig

    good = save_rig(small_rig(), tmp_path / "a.mrig")
    with pytest.raises((RigFormatError, RigError), match=expected):
        load_rig(rewrite(good, tmp_path / "x.mrig", doc=edit))
