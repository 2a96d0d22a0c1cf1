"""`armgen firmware ROBOT --task TASK.toml | --plan plan.csv`: the project's demo runs the user's
task, and `armgen verify --run` accepts what it printed (issue 26)."""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from click.testing import CliRunner
from hypothesis import given, settings, strategies as st

import armgen.planning.tasks
from armgen import api
from armgen.cli.main import cli
from armgen.firmware.project import task_toml
from armgen.planning.tasks import load_task
from armgen.robot import load_robot

from conftest import require_tool

REPO = Path(__file__).resolve().parent.parent
EXAMPLES = REPO / "armgen" / "data" / "examples"
# A small circle of the tool from modular8's q0 (mm), 4 s at 20 ms: 200 ticks, inside the limits
# (the bundled pinv circle leaves them on purpose, a plan the firmware refuses).
CIRCLE_VIA_MM, CIRCLE_END_MM = [40.0, 40.0, 0.0], [80.0, 0.0, 0.0]


def _build_and_run(project: Path) -> Path:
    configure = subprocess.run(["cmake", "-S", str(project), "-B", str(project / "build")], capture_output=True,
                               text=True, timeout=300)
    assert configure.returncode == 0, configure.stdout[-3000:] + configure.stderr[-3000:]
    build = subprocess.run(["cmake", "--build", str(project / "build")], capture_output=True, text=True, timeout=600)
    assert build.returncode == 0, build.stdout[-3000:] + build.stderr[-3000:]
    demos = list((project / "build").glob("*_demo"))
    run = subprocess.run([str(demos[0])], capture_output=True, text=True, timeout=300, check=True)
    csv = project / "run.csv"
    csv.write_text(run.stdout)
    return csv


def _verify_run(project: Path, monkeypatch) -> str:
    monkeypatch.chdir(project)
    out = CliRunner().invoke(cli, ["verify", "robot.toml", "-o", "generated", "--plan", "demo/plan.csv", "--run",
                                   "run.csv", "--samples", "50", "--precision", "double"])
    assert out.exit_code == 0, out.output
    assert "== run: PASS" in out.output
    return out.output


def test_task_file_runs_in_the_project(tmp_path, monkeypatch):
    require_tool("cmake")
    robot = load_robot("modular8")
    p0 = robot.fk(robot.configuration("q0"))[:3, 3] * 1000
    task = tmp_path / "circle.toml"
    task.write_text(f'planner = "cartesian"\nrobot = "modular8"\nstart = "q0"\n[units]\nlength = "mm"\n[path]\n'
                    f'type = "circle"\nvia = {(p0 + CIRCLE_VIA_MM).tolist()}\nend = {(p0 + CIRCLE_END_MM).tolist()}\n'
                    'orientation = "hold"\n[timing]\nduration = 4\nlaw = "cubic"\n[integrator]\nmethod = "euler"\n'
                    'step = 0.02\n[method]\nname = "pinv"\n')
    out = CliRunner().invoke(cli, ["firmware", "modular8", "--task", str(task), "--out", str(tmp_path / "fw")])
    assert out.exit_code == 0, out.output
    project = tmp_path / "fw"
    header = (project / "task" / "task_params.h").read_text()
    assert "CTRL_MODE_RESOLVED_RATE" in header and "CTRL_PATH_CIRCLE" in header  # not the demo's line
    # the project's copy of the task names the project's robot file and is the user's task otherwise
    copied = tomllib.loads((project / "demo" / "demo.toml").read_text())
    original, _ = load_task(task)
    assert copied["robot"] == "../robot.toml"  # relative to demo.toml, as every task file
    assert {k: v for k, v in copied.items() if k != "robot"} == {k: v for k, v in original.items() if k != "robot"}
    _build_and_run(project)
    output = _verify_run(project, monkeypatch)
    # the double run equals the plan to 1e-9 rad to its end
    assert "run.csv (double)" in output and "DONE at 200" in output


def test_plan_runs_in_the_project(tmp_path, monkeypatch):
    require_tool("cmake")
    plan = tmp_path / "ptp.csv"
    out = CliRunner().invoke(cli, ["plan", str(EXAMPLES / "modular8_ptp_two_segments.toml"), "-o", str(plan)])
    assert out.exit_code == 0, out.output
    out = CliRunner().invoke(cli, ["firmware", "modular8", "--plan", str(plan), "--out", str(tmp_path / "fw")])
    assert out.exit_code == 0, out.output
    project = tmp_path / "fw"
    assert "CTRL_MODE_PLAYBACK" in (project / "task" / "task_params.h").read_text()
    _build_and_run(project)
    output = _verify_run(project, monkeypatch)
    assert "max |Δθ| [rad]" in output and "DONE at 3000" in output


@pytest.mark.parametrize("args, code, words", [
    (["iiwa14", "--task", str(EXAMPLES / "modular8_circle_pinv.toml")], 5, ("robot 'modular8'", "'iiwa14'")),
    (["modular8", "--task", str(EXAMPLES / "modular8_circle_pinv.toml"), "--plan", str(EXAMPLES / "panda_polish_contour.csv")],
     2, ("--task or --plan",)),
])
def test_refusals_write_nothing(tmp_path, args, code, words):
    out = CliRunner().invoke(cli, ["firmware", *args, "--out", str(tmp_path / "fw")])
    assert out.exit_code == code, out.output
    assert all(w in out.output for w in words), out.output
    assert not (tmp_path / "fw").exists()


def test_task_toml_round_trips_a_program():
    """The project's copy of a task: TOML that parses back (tomllib) to the task file's dict,
    nested tables and arrays of tables (a program's moves) included."""
    task, _ = load_task(EXAMPLES / "iiwa14_weld_seam_program.toml")
    text = task_toml(task, "a program")
    assert tomllib.loads(text) == task


# What a parsed TOML document holds: keys of any text, scalars, arrays and tables at any depth
# (tables inside arrays included: a program's moves).
TOML_SCALARS = st.one_of(st.booleans(), st.integers(-2 ** 63, 2 ** 63 - 1), st.floats(allow_nan=False),
                         st.text(max_size=8))
TOML_VALUES = st.recursive(TOML_SCALARS, lambda inner: st.one_of(st.lists(inner, max_size=3),
                                                                 st.dictionaries(st.text(max_size=6), inner,
                                                                                 max_size=3)),
                           max_leaves=10)


@settings(max_examples=300, deadline=None)
@given(st.dictionaries(st.text(max_size=6), TOML_VALUES, max_size=5))
def test_task_toml_round_trips_any_document(doc):
    """Any document a TOML file can hold comes back from the project's copy (tomllib), under its
    comment lines; odd keys (empty, dotted, spaces, non-ASCII) and strings (quotes, control
    characters, DEL) included."""
    text = task_toml(doc, "any")
    assert text.startswith("# any\n# Written by `armgen firmware`")
    assert tomllib.loads(text) == doc


@pytest.mark.arm
def test_task_on_an_arm_armgen_does_not_bundle(tmp_path, monkeypatch):
    """Baxter's arm (7 DOF, tests/data): a circle task → `armgen firmware --task` → CMake build →
    host run → `verify --run` (double, 1e-9 rad), and `verify --target cortex-m4` builds and runs
    the same task's firmware under QEMU (float)."""
    for tool in ("cmake", "arm-none-eabi-gcc", "qemu-system-arm"):
        require_tool(tool)
    robot_file = REPO / "tests" / "data" / "baxter_arm.toml"
    robot = load_robot(robot_file)
    p0 = robot.fk(robot.configuration("q0"))[:3, 3] * 1000  # mm: the circle starts at the tool
    via, end = p0 + [40.0, 40.0, 0.0], p0 + [80.0, 0.0, 0.0]
    task = tmp_path / "circle.toml"
    task.write_text(f'planner = "cartesian"\nrobot = "{robot_file}"\nstart = "q0"\n[units]\nlength = "mm"\n'
                    f'[path]\ntype = "circle"\nvia = {via.tolist()}\nend = {end.tolist()}\norientation = "hold"\n'
                    '[timing]\nduration = 4\nlaw = "cubic"\n[integrator]\nmethod = "euler"\nstep = 0.01\n'
                    '[method]\nname = "combined"\n')
    out = CliRunner().invoke(cli, ["firmware", str(robot_file), "--task", str(task), "--out", str(tmp_path / "fw")])
    assert out.exit_code == 0, out.output
    project = tmp_path / "fw"
    _build_and_run(project)
    output = _verify_run(project, monkeypatch)
    assert "DONE at 400" in output
    out = CliRunner().invoke(cli, ["verify", "robot.toml", "-o", "generated", "--plan", "demo/plan.csv",
                                   "--target", "cortex-m4", "--samples", "50", "--precision", "float"])
    assert out.exit_code == 0, out.output
    assert "== target: PASS" in out.output


OPEN_COUNTER = """
import json, os, sys
watch = {os.path.realpath(p): 0 for p in sys.argv[1:3]}
def hook(event, args):
    if event == "open" and args and isinstance(args[0], (str, bytes, os.PathLike)):
        path = os.path.realpath(os.fsdecode(args[0]))
        if path in watch:
            watch[path] += 1
sys.addaudithook(hook)
import armgen.api
armgen.api.firmware_project(sys.argv[1], sys.argv[3], task=sys.argv[2])
print(json.dumps(list(watch.values())))
"""


def test_firmware_project_reads_the_robot_and_the_task_once(tmp_path):
    """`armgen firmware ROBOT --task TASK`: the robot file and the task file are each opened once
    (counted by an audit hook on every open of the process; it was 4 and 1), the task's robot
    being the same file."""
    robot = tmp_path / "arm.toml"
    robot.write_bytes((REPO / "armgen" / "data" / "robots" / "modular8.toml").read_bytes())
    task = tmp_path / "ptp.toml"
    text = (EXAMPLES / "modular8_ptp_two_segments.toml").read_text()
    task.write_text(text.replace('robot = "modular8"', 'robot = "arm.toml"'))
    assert 'robot = "arm.toml"' in task.read_text()
    done = subprocess.run([sys.executable, "-c", OPEN_COUNTER, str(robot), str(task), str(tmp_path / "fw")],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr[-3000:]
    assert json.loads(done.stdout.splitlines()[-1]) == [1, 1]


def test_a_task_for_another_robot_is_refused_before_it_is_planned(tmp_path, monkeypatch):
    """The task names modular8, the project is iiwa14's: refused (exit 5, nothing written)
    before any planning (the old code planned the whole circle first)."""
    def never(*args, **kwargs):
        raise AssertionError("planned a task for another robot")

    monkeypatch.setattr(armgen.planning.tasks, "plan_configured", never)
    out = CliRunner().invoke(cli, ["firmware", "iiwa14", "--task", str(EXAMPLES / "modular8_circle_pinv.toml"),
                                   "--out", str(tmp_path / "fw")])
    assert out.exit_code == 5, out.output
    assert "robot 'modular8'" in out.output and "'iiwa14'" in out.output
    assert not (tmp_path / "fw").exists()


def test_api_firmware_project_takes_overrides_and_refuses_what_does_not_fit(tmp_path):
    """armgen.api.firmware_project: --set values change the task the demo runs (here the PTP
    step: 3 s at 20 ms, 150 ticks); both a task and a plan, or overrides without a task, are
    an OptionError (exit 2) before anything is read."""
    robot, paths = api.firmware_project("modular8", tmp_path / "fw", task=EXAMPLES / "modular8_ptp_two_segments.toml",
                                        overrides=["step=0.02"])
    assert robot.name == "modular8" and tmp_path / "fw" / "task" / "task_params.h" in paths
    header = (tmp_path / "fw" / "task" / "task_params.h").read_text()
    assert ".dt = CTRL_LIT(0.02)," in header and ".n_ticks = 150," in header
    with pytest.raises(api.OptionError, match="--task or --plan"):
        api.firmware_project("modular8", tmp_path / "x", task="t.toml", plan="p.csv")
    with pytest.raises(api.OptionError, match="--set changes a task file"):
        api.firmware_project("modular8", tmp_path / "x", overrides=["step=0.02"])
    assert not (tmp_path / "x").exists()
