"""One parse, one hand-off (issue 36): a task file and its robot file are each opened once per
command, the task's robot is checked against a given robot before anything is planned, and
the plan carries the typed configuration it was made with."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path

import pytest

import armgen.api as api
from armgen.errors import RobotMismatchError
from armgen.planning import tasks
from armgen.planning.registry import PLANNER_NAMES, planner

REPO = Path(__file__).resolve().parent.parent
EXAMPLES = REPO / "examples"
ROBOTS = REPO / "robots"

# Runs the armgen CLI and prints, last, how often each watched file was opened (the audit
# event "open" is raised by open(), os.open() and every reader built on them).
COUNT_OPENS = r"""
import json, os, sys
watched = {os.path.realpath(p): 0 for p in sys.argv[1].split(os.pathsep)}
def hook(event, args):
    if event == "open" and isinstance(args[0], (str, bytes, os.PathLike)):
        path = os.path.realpath(os.fsdecode(args[0]))
        if path in watched:
            watched[path] += 1
sys.addaudithook(hook)
from armgen.cli.main import cli
try:
    cli(sys.argv[2:], standalone_mode=False)
finally:
    print("OPENS " + json.dumps(watched))
"""


def _opens(files: list[Path], *args: str, cwd: Path) -> dict[str, int]:
    run = subprocess.run([sys.executable, "-c", COUNT_OPENS, ":".join(map(str, files)), *args], cwd=cwd,
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    counts = json.loads(run.stdout.rsplit("OPENS ", 1)[1])
    return {Path(path).name: count for path, count in counts.items()}


@pytest.mark.parametrize("example", ["modular8_circle_zghal", "modular8_wgpm_demo", "modular8_ptp_two_segments",
                                     "modular8_fault_circle_gpm"])
def test_armgen_plan_opens_the_task_and_its_robot_once(tmp_path, example):
    task = EXAMPLES / f"{example}.toml"
    counts = _opens([task, ROBOTS / "modular8.toml"], "plan", str(task), "-o", str(tmp_path / "p.csv"), cwd=tmp_path)
    assert counts == {f"{example}.toml": 1, "modular8.toml": 1}


def test_a_task_for_another_robot_is_refused_before_it_is_planned(monkeypatch):
    def never(*args):
        raise AssertionError("configured a task for another robot")

    unconfigurable = dataclasses.replace(planner("cartesian"), configure=never)
    monkeypatch.setattr(tasks, "planner", lambda name, source="": unconfigurable)
    with pytest.raises(RobotMismatchError) as err:
        api.read_task(EXAMPLES / "modular8_circle_zghal.toml", for_robot=api.load_robot("panda"))
    assert "robot 'modular8'" in str(err.value) and "not 'panda'" in str(err.value)
    assert err.value.exit_code == 5


def test_the_given_robot_is_used_as_it_is():
    robot = api.load_robot("modular8")
    task = api.read_task(EXAMPLES / "modular8_circle_zghal.toml", for_robot=robot)
    assert task.config.robot is robot


def test_a_robot_override_is_a_task_field_not_the_given_robot(tmp_path):
    # `robot` is a field a task file has: as an override it changes the task (here to a file
    # that is not there), it is not the robot the task is checked against.
    from armgen.errors import RobotFileError

    with pytest.raises(RobotFileError, match="field 'robot' = .*missing.toml: robot file not found"):
        api.read_task(EXAMPLES / "modular8_circle_zghal.toml", robot=str(tmp_path / "missing.toml"))


@pytest.mark.parametrize("name", PLANNER_NAMES)
def test_every_planner_configures_a_frozen_typed_config_without_a_dict(name):
    example = {"ptp": "modular8_ptp_two_segments", "cartesian": "modular8_circle_zghal",
               "fault_tolerant": "modular8_fault_circle_gpm", "wgpm": "modular8_wgpm_demo",
               "snake": "snake_planar"}[name]
    task = api.read_task(EXAMPLES / f"{example}.toml")
    assert task.planner is planner(name)
    config = task.config
    fields = getattr(config, "__dataclass_fields__", {})
    assert fields and config.__dataclass_params__.frozen, f"{type(config).__name__} is not a frozen dataclass"
    assert not any(isinstance(getattr(config, f), dict) for f in fields), "the config holds a dict"


def test_no_json_round_trip_copies_in_the_package():
    # a json.loads(json.dumps(x)) copy was how a task dict crossed the layers to be parsed again
    hits = [f"{path.relative_to(REPO)}:{k}" for path in sorted((REPO / "armgen").rglob("*.py"))
            for k, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1)
            if "json.loads(json.dumps(" in line.replace(" ", "")]
    assert hits == []
