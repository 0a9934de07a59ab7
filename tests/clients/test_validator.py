"""The Khronos glTF validator (npm ``gltf-validator``, pinned) finds no error in exported files."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest


def validate(node: str, node_modules: Path, path: Path) -> dict:
    script = node_modules.parent / "validate.cjs"
    done = subprocess.run(
        [node, str(script), str(path)], capture_output=True, text=True, timeout=120, check=False
    )
    assert done.returncode == 0, f"the validator failed:\n{done.stderr[-3000:]}"
    return json.loads(done.stdout)


def summary(report: dict) -> str:
    issues = report["issues"]
    lines = [
        f"gltf-validator {report['validatorVersion']}: {issues['numErrors']} errors, {issues['numWarnings']} "
        f"warnings, {issues['numInfos']} infos, {issues['numHints']} hints"
    ]
    lines += [
        f"  {m['severity']} {m['code']} {m.get('pointer', '')}: {m['message']}" for m in issues["messages"]
    ]
    return "\n".join(lines)


def test_validator_finds_no_error_in_the_animated_file(node, node_modules, exported):
    report = validate(node, node_modules, exported.path)
    print(summary(report))
    assert report["issues"]["numErrors"] == 0, summary(report)
    info = report["info"]
    assert info["hasMorphTargets"] and info["hasSkins"] and info["animationCount"] == 1
    assert info["totalVertexCount"] == exported.rig.n_vertices
    assert info["maxInfluences"] == 4


@pytest.mark.parametrize("options", [{"skin": False}, {"units": "cm", "target_normals": False}])
def test_validator_finds_no_error_in_variants(node, node_modules, exported, tmp_path, options):
    from mimetic.export import export_glb

    path = export_glb(exported.rig, tmp_path / "variant.glb", morph_targets=exported.targets, **options)
    report = validate(node, node_modules, path)
    print(summary(report))
    assert report["issues"]["numErrors"] == 0, summary(report)
