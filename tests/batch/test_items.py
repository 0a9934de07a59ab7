"""Tests of ``mimetic.batch.items``: inputs, globs and manifest files → items (no workers run here)."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from mimetic.batch.items import BatchError, collect_items, expand_inputs


@pytest.fixture
def inputs(tmp_path, monkeypatch):
    """Three empty "meshes" and two landmark files in ``tmp_path/in``; the current folder is tmp_path."""
    monkeypatch.chdir(tmp_path)
    folder = tmp_path / "in"
    folder.mkdir()
    for name in ("b.obj", "a.obj", "c.ply", "a.json", "b.json"):
        (folder / name).write_text("x")
    return folder


def test_expand_inputs_sorts_glob_matches_and_keeps_missing_paths(inputs):
    found = expand_inputs(["in/*.obj", "in/missing.obj", "in/c.ply"])
    assert found == [Path("in/a.obj"), Path("in/b.obj"), Path("in/missing.obj"), Path("in/c.ply")]


def test_expand_inputs_refuses_a_glob_that_matches_nothing(inputs):
    with pytest.raises(BatchError, match=r"no file matches 'in/\*\.stl'"):
        expand_inputs(["in/*.stl"])


def test_collect_items_names_outputs_after_inputs_with_absolute_paths(inputs, tmp_path):
    items = collect_items("rig", ["in/*.obj"], "out", options={"landmarks": "{dir}/{stem}.json"})
    assert [i.name for i in items] == ["a", "b"]
    a = items[0]
    assert a.input == str(inputs / "a.obj") and a.out_dir == str(tmp_path / "out")
    assert a.outputs == tuple(str(tmp_path / "out" / f) for f in ("a.mrig", "a.fit.json", "a.fit.png"))
    assert a.options["landmarks"] == str(inputs / "a.json")  # the template, filled per head
    assert a.options["resolution"] == 10_000 and a.options["picture"] is True  # the defaults
    assert a.record == tmp_path / "out" / ".mimetic-batch" / "a.json"
    assert all(os.path.isabs(p) for p in (a.input, *a.outputs))


def test_collect_items_reads_csv_and_json_manifests(inputs, tmp_path):
    rows = tmp_path / "lists" / "rows.csv"
    rows.parent.mkdir()
    rows.write_text("input,output,units,picture\n../in/a.obj,scans/alice.mrig,mm,false\n../in/b.obj,,,\n")
    items = collect_items("rig", [], "out", manifest=rows, options={"units": "cm"})
    alice, b = items
    assert alice.name == "scans/alice" and alice.row == 1 and alice.input == str(inputs / "a.obj")
    assert alice.outputs == (
        str(tmp_path / "out/scans/alice.mrig"),
        str(tmp_path / "out/scans/alice.fit.json"),
    )
    assert alice.options["units"] == "mm" and alice.options["picture"] is False  # the row's, typed
    assert b.name == "b" and b.options["units"] == "cm"  # empty cells leave the batch's options
    assert alice.record.name == "scans%alice.json"

    clips = tmp_path / "clips.json"
    clips.write_text(
        json.dumps(
            [
                {"input": "in/a.obj", "options": {"clip": "in/a.json"}},
                {"input": "in/b.obj", "output": "b.mp4", "clip": "in/b.json", "fps": "24"},
            ]
        )
    )
    a, b = collect_items("animate", [], "anims", manifest=clips)
    assert a.outputs == (str(tmp_path / "anims/a.glb"),) and a.options["clip"] == str(inputs / "a.json")
    assert b.options["format"] == "mp4" and b.options["fps"] == 24.0  # the output's suffix picks it


@pytest.mark.parametrize(
    ("kind", "paths", "options", "message"),
    [
        ("rig", ["in/a.obj", "in/a.obj"], {}, r"a\.mrig would be written by 2 items"),
        ("render", ["in/a.obj", "in/a.json"], {}, r"a\.png would be written by 2 items"),
        ("rig", ["in/a.obj"], {"colour": "red"}, r"unknown option\(s\) colour; batch rig takes landmarks"),
        ("rig", ["in/a.obj"], {"units": "furlong"}, r"units='furlong'; use one of mm, cm"),
        ("rig", ["in/a.obj"], {"resolution": "lots"}, r"resolution='lots' is not a whole number"),
        ("animate", ["in/a.obj"], {}, r"a\.obj: batch animate needs 'clip'"),
        ("speak", ["in/a.obj"], {}, r"needs 'text' or 'text_file' or 'timings'"),
        ("rig", [], {}, r"nothing to do"),
        ("rig", ["in/a.obj"], {"landmarks": "x.json", "auto_landmarks": True}, r"not both"),
    ],
)
def test_collect_items_refuses_a_batch_that_cannot_start(inputs, kind, paths, options, message):
    with pytest.raises(BatchError, match=message):
        collect_items(kind, paths, "out", options=options)


def test_collect_items_refuses_an_output_over_the_manifest_or_outside_the_folder(inputs, tmp_path):
    (inputs / "batch-capture.trc").write_text("x")
    with pytest.raises(BatchError, match=r"batch-capture\.json is the batch's manifest"):
        collect_items("capture", ["in/batch-capture.trc"], "out", options={"rig": "r.mrig"})
    rows = tmp_path / "rows.json"
    rows.write_text(json.dumps([{"input": "in/a.obj", "output": "../elsewhere.mrig"}]))
    with pytest.raises(BatchError, match=r"row 1: output '\.\./elsewhere\.mrig' is outside"):
        collect_items("rig", [], "out", manifest=rows)
    rows.write_text(json.dumps([{"input": "in/a.obj", "output": "a.obj"}]))
    with pytest.raises(BatchError, match=r"batch rig writes \.mrig"):
        collect_items("rig", [], "out", manifest=rows)


def test_item_key_changes_with_the_input_and_options_but_not_the_folder(inputs, tmp_path):
    def key(out="out", **options):
        return collect_items("rig", ["in/a.obj"], out, options=options)[0].key

    first = key()
    assert key() == first
    assert key(out="moved") == first  # outputs are keyed relative to OUTDIR, so it may move
    assert key(units="mm") != first
    (inputs / "a.obj").write_text("a changed mesh")
    assert key() != first
