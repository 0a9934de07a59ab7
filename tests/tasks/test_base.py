"""Tests for the task layer's declarations: every option declared once, read by every front end."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import typer

from mimetic.batch.items import FORMAT, batch_options
from mimetic.cli import app
from mimetic.tasks import BATCH_TASKS, TASKS, OutputError, TaskError, specs
from mimetic.tasks.animate import AnimateOptions
from mimetic.tasks.base import check_output
from mimetic.tasks.capture import CaptureSolveOptions
from mimetic.testing import run_cli


def _command(name: str):
    """The click command of ``mimetic NAME`` ("capture solve" walks into the group)."""
    command = typer.main.get_command(app)
    for part in name.split():
        command = command.commands[part]
    return command


@pytest.mark.parametrize("name", sorted(TASKS))
def test_the_command_line_reads_every_default_from_the_task(name):
    """Each option of the task is an option of its command (unless positional), with the same
    default: declared once, in the options dataclass."""
    task = TASKS[name]
    params = {param.name: param for param in _command(name).params}
    for spec in specs(task.options).values():
        assert spec.name in params, f"mimetic {name} lacks {spec.flag}"
        param = params[spec.name]
        if param.param_type_name == "argument":
            continue
        if isinstance(param.default, (list, tuple)):  # a repeatable option: none given by default
            assert tuple(param.default) == tuple(spec.default or ()), spec.name
        else:
            assert param.default == spec.default, spec.name


@pytest.mark.parametrize("kind", sorted(BATCH_TASKS))
def test_a_batch_takes_its_tasks_shared_options_and_a_format(kind):
    task = BATCH_TASKS[kind]
    options = batch_options(kind)
    shared = {name for name, spec in specs(task.options).items() if spec.batch}
    assert set(options) - {FORMAT} == shared
    assert (FORMAT in options) == (len(task.outputs) > 1)
    params = {param.name for param in _command(f"batch {kind}").params}
    assert shared - {"rig"} <= params  # capture's rig is its first argument


def test_options_are_checked_against_their_declarations_naming_the_option():
    assert AnimateOptions(fps=60).fps == 60.0
    assert AnimateOptions(clip="a.json").clip == Path("a.json")  # paths given as text become Paths
    with pytest.raises(TaskError, match=r"fps=0 is below its minimum 0\.001"):
        AnimateOptions(fps=0)
    with pytest.raises(TaskError, match=r"engine='wir': choose one of wire, vector, fem, tissue"):
        AnimateOptions(engine="wir")
    with pytest.raises(TaskError, match=r"size=1\.5 must be a whole number"):
        AnimateOptions(size=1.5)
    with pytest.raises(dataclasses.FrozenInstanceError):
        AnimateOptions().fps = 24  # type: ignore[misc]
    assert CaptureSolveOptions(rig="a.mrig", cutoff=4.0).changed() == {"rig": Path("a.mrig"), "cutoff": 4.0}


def test_a_misused_option_is_a_usage_error_and_a_missing_folder_a_problem_with_the_input(tmp_path):
    with pytest.raises(TaskError, match=r"x\.txt: cannot write a \.txt marker file; use \.json"):
        check_output(tmp_path / "x.txt", (".json",), "marker file")
    with pytest.raises(OutputError, match="does not exist; create it first"):
        check_output(tmp_path / "nowhere" / "x.json", (".json",))
    assert issubclass(TaskError, ValueError) and not issubclass(OutputError, TaskError)
    result = run_cli("head", "-o", tmp_path / "nowhere" / "head.glb")
    assert result.exit_code == 1 and "does not exist" in result.output
    wrong = run_cli("head", "-o", tmp_path / "head.glb", "--resolution", "10")  # below its declared minimum
    assert wrong.exit_code == 2 and "--resolution" in wrong.output
