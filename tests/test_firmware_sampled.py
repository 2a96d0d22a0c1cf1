"""Snake plans on the controller: sampled playback (CTRL_MODE_SAMPLED) of the plan's joint table
(issue 26). The reference is the plan CSV the snake planner wrote and the robot file's limits:
the command of tick k is sample k exactly, q̇ the forward difference to sample k+1 over the
output step, and the run stops where a sample leaves the limits or a step outruns a joint."""

from __future__ import annotations

import dataclasses
import math
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

import armgen.firmware as fw
from armgen.cli.main import cli
from armgen.firmware.errors import FirmwareError
from armgen.planning.result import PlanResult, read_plan
from armgen.planning.tasks import load_task, run_task
from armgen.verification import firmware_compare as fwcmp

from conftest import require_tool
from test_firmware_task_project import _build_and_run

REPO = Path(__file__).resolve().parent.parent
EXAMPLES = REPO / "armgen" / "data" / "examples"
HOST_SAN = fw.Variant("host", "double", sanitize=True, opt="-O1")
# robots/snake12.toml, read by hand: the feed (rail) first, then a1, b1, …, a12, b12;
# qdlim 250 mm/s on the feed and 60 deg/s on every universal-joint axis; qlim ±60 deg.
SNAKE12_COLUMNS = ["feed_m"] + [f"{ab}{i}_rad" for i in range(1, 13) for ab in "ab"]
SNAKE12_QDLIM = np.array([0.25] + [math.radians(60)] * 24)
SNAKE12_QMAX_RAD = math.radians(60)
# The Cortex-M4F table holds each sample rounded once to float: ≤ 2⁻²⁴ × 1.25 m (the largest
# |q| on the rail) ≈ 7.5e-8. The bar is 1e-4 rad; this checks the stated rounding.
FLOAT_TABLE_ROUNDING = 1e-7


def plan_q(plan: PlanResult) -> np.ndarray:
    return np.column_stack([plan.column(c) for c in SNAKE12_COLUMNS])


def forward_difference(q: np.ndarray, dt: float) -> np.ndarray:
    qd = np.zeros_like(q)
    qd[:-1] = (q[1:] - q[:-1]) / dt
    return qd


def ticks(run: fw.FirmwareRun) -> np.ndarray:
    """The first row of each tick (the runners print the held command again after the end)."""
    return np.array([row for _, row in sorted(run.by_tick().items())])


def with_q(plan: PlanResult, q: np.ndarray) -> PlanResult:
    data = plan.data.copy()
    for j, c in enumerate(SNAKE12_COLUMNS):
        data[:, plan.columns.index(c)] = q[:, j]
    return PlanResult(list(plan.columns), data, plan.metadata, plan.config)


@pytest.fixture(scope="module")
def plans():
    out = {}
    for name in ("snake_tank", "snake_planar"):
        task, _ = load_task(EXAMPLES / f"{name}.toml")
        out[name] = run_task(task, name)
    return out


@pytest.fixture(scope="module")
def builder(tmp_path_factory):
    require_tool("gcc")
    return fw.FirmwareBuilder("snake12", tmp_path_factory.mktemp("firmware_snake12"))


def run_plan(builder, plan: PlanResult, name: str, header=None) -> tuple[fw.FirmwareTask, fw.FirmwareRun]:
    task = fw.task_from_plan(plan, name)
    if header is not None:
        task = dataclasses.replace(task, header=header(task.header))
    return task, fw.run_host(builder.executable(HOST_SAN, task, name))


def test_tank_plan_plays_back_exactly(builder, plans):
    """snake_tank stays within every limit: each command is the plan's sample bit for bit, q̇
    the forward difference (0 at the end), and the run ends DONE at the last sample."""
    plan = plans["snake_tank"]
    task, run = run_plan(builder, plan, "tank")
    q, dt = plan_q(plan), plan.metadata["motion"]["output_step_s"]
    assert (run.state, run.fault, task.n_ticks) == ("DONE", "NONE", len(q) - 1)
    rows = ticks(run)
    assert np.array_equal(rows[:, 2:27], q)
    assert np.array_equal(rows[:, 27:52], forward_difference(q, dt))
    assert np.all(rows[-1, 27:52] == 0.0)
    assert fwcmp.compare_with_plan(plan, run, task, "double", "tank").passed
    assert "100100 B in float, 200200 B in double" in task.header  # 1001 rows x 25 joints x 4 / 8 B


def test_planar_plan_stops_where_a_joint_would_outrun_its_limit(builder, plans):
    """snake_planar's 100 mm arcs turn the middle joints faster than snake12's 60 deg/s: the
    controller stops with SPEED at the first sample whose step to the next exceeds qdlim · dt,
    holding the sample before it."""
    plan = plans["snake_planar"]
    q, dt = plan_q(plan), plan.metadata["motion"]["output_step_s"]
    first = int(np.flatnonzero((np.abs(np.diff(q, axis=0)) > SNAKE12_QDLIM * dt).any(axis=1))[0])
    task, run = run_plan(builder, plan, "planar")
    rows = ticks(run)
    assert (run.state, run.fault) == ("FAULT", "SPEED")
    assert len(rows) == first + 1 and rows[first, -2] == 3  # state FAULT from that tick
    assert np.array_equal(rows[:first, 2:27], q[:first])
    assert np.array_equal(rows[first, 2:27], q[first - 1])  # held, velocity 0
    assert np.all(rows[first, 27:52] == 0.0)
    assert fwcmp.compare_with_plan(plan, run, task, "double", "planar").passed


def test_sample_outside_the_limits_stops_there(builder, plans):
    """a1 drifted at 0.5 rad/s (within its speed limit) from 2 s on leaves +60 deg: JOINT_LIMIT
    at the first such sample, the previous one held."""
    plan = plans["snake_tank"]
    q = plan_q(plan)
    t = plan.column("t_s")
    q[:, 1] += 0.5 * np.maximum(t - 2.0, 0.0)
    first = int(np.flatnonzero(q[:, 1] > SNAKE12_QMAX_RAD)[0])
    task, run = run_plan(builder, with_q(plan, q), "limit")
    rows = ticks(run)
    assert run.fault == "JOINT_LIMIT" and len(rows) == first + 1 and rows[first, -2] == 3
    assert np.array_equal(rows[first, 2:27], q[first - 1])
    assert fwcmp.compare_with_plan(with_q(plan, q), run, task, "double", "limit").passed


@settings(max_examples=12, deadline=None, derandomize=True, database=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(joint=st.integers(1, 24), scale=st.floats(0.5, 3.0), offset=st.floats(-0.9, 0.9))
@example(joint=9, scale=1.0, offset=0.0)  # DONE (the plan as it is)
@example(joint=9, scale=3.0, offset=0.0)  # SPEED (three times as fast)
@example(joint=9, scale=1.0, offset=0.9)  # JOINT_LIMIT (row 0 of the tank plan is 0: 0.9 rad is inside)
def test_stop_is_where_the_plan_first_breaks_a_limit(builder, plans, joint, scale, offset):
    """One universal joint of snake_tank stretched about its start (its speeds × scale) and
    shifted (its start stays inside the limits: the plan's row 0 is 0 on every joint): the run equals the samples exactly up to the first sample outside the limits
    (JOINT_LIMIT) or whose step to the next outruns the joint (SPEED), as the robot file's
    limits say, and stops there — or ends DONE when there is none."""
    plan = plans["snake_tank"]
    q = plan_q(plan)
    q[:, joint] = q[0, joint] + scale * (q[:, joint] - q[0, joint]) + offset
    dt = plan.metadata["motion"]["output_step_s"]
    outside = (np.abs(q[:, 1:]) > SNAKE12_QMAX_RAD).any(axis=1) | (q[:, 0] < 0.0) | (q[:, 0] > 1.248)
    too_fast = np.append((np.abs(np.diff(q, axis=0)) > SNAKE12_QDLIM * dt).any(axis=1), False)
    bad = np.flatnonzero(outside | too_fast)
    _, run = run_plan(builder, with_q(plan, q), "stretched")
    rows = ticks(run)
    if not bad.size:
        assert (run.state, len(rows)) == ("DONE", len(q))
        assert np.array_equal(rows[:, 2:27], q)
        return
    first = int(bad[0])
    assert run.fault == ("JOINT_LIMIT" if outside[first] else "SPEED"), (first, run.fault)
    assert len(rows) == first + 1 and rows[first, -2] == 3
    assert np.array_equal(rows[:first, 2:27], q[:first])
    if first > 0:
        assert np.array_equal(rows[first, 2:27], q[first - 1])


def _table_row(header: str, row: int, value: str) -> str:
    """The header with the first value of table row ``row`` replaced."""
    lines = header.splitlines()
    start = next(i for i, line in enumerate(lines) if line.startswith("static const ctrl_real fw_task_samples"))
    literal = r"CTRL_LIT\([^)]*\)|\(\(ctrl_real\)[^)]*\)"  # armgen.firmware.literals.c_real's two forms
    lines[start + 1 + row] = re.sub(literal, value, lines[start + 1 + row], count=1)
    return "\n".join(lines)


@pytest.mark.parametrize("name, edit", [
    ("nan", lambda h: _table_row(h, 500, "(ctrl_real)NAN")),
    ("inf", lambda h: _table_row(h, 1000, "(ctrl_real)-INFINITY")),
    ("start", lambda h: _table_row(h, 0, "(ctrl_real)0.001")),  # the rail 1 mm from q_start
    ("null", lambda h: h.replace(".table = &fw_task_samples[0][0],", ".table = 0,")),  # a null pointer
    ("one_row", lambda h: h.replace(".n_samples = FW_TASK_SAMPLES,", ".n_samples = 1,")),
    ("too_many", lambda h: h.replace(".n_samples = FW_TASK_SAMPLES,", ".n_samples = CTRL_MAX_SAMPLES + 1,")),
])
def test_bad_table_is_refused_at_init(builder, plans, name, edit):
    """ctrl_init checks the table once (present, 2 .. CTRL_MAX_SAMPLES rows, every value
    finite, row 0 at q_start): BAD_CONFIG, holding q_start, nothing moves (under ASan: a
    row count beyond the table is refused before any row is read)."""
    plan = plans["snake_tank"]
    _, run = run_plan(builder, plan, f"bad_{name}", edit)
    assert (run.summary["init"], run.state, run.fault) == ("BAD_CONFIG", "FAULT", "BAD_CONFIG")
    assert np.all(np.isfinite(run.data))
    assert np.array_equal(run.data[:, 2:27], np.tile(plan_q(plan)[0], (len(run.data), 1)))


def test_plan_the_controller_cannot_take_is_refused(plans):
    plan = plans["snake_tank"]
    data = plan.data.copy()
    data[10, plan.columns.index("t_s")] += 1e-4  # not on the output step's grid
    with pytest.raises(FirmwareError, match="t_s is not t_0"):
        fw.task_from_plan(PlanResult(list(plan.columns), data, plan.metadata, plan.config), "uneven.csv")
    keep = [i for i, c in enumerate(plan.columns) if c != "b12_rad"]
    with pytest.raises(FirmwareError, match="no column b12_rad"):
        short = PlanResult([plan.columns[i] for i in keep], plan.data[:, keep], plan.metadata, plan.config)
        fw.task_from_plan(short, "short.csv")


def test_snake_plan_for_another_robot_is_refused(tmp_path):
    plan = tmp_path / "planar.csv"
    assert CliRunner().invoke(cli, ["plan", str(EXAMPLES / "snake_planar.toml"), "-o", str(plan)]).exit_code == 0
    out = CliRunner().invoke(cli, ["firmware", "modular8", "--plan", str(plan), "--out", str(tmp_path / "fw")])
    assert out.exit_code == 5, out.output  # its task names another robot: refused before it is planned again
    assert "robot 'snake12'" in out.output and "'modular8'" in out.output
    assert not (tmp_path / "fw").exists()


def test_snake_plan_runs_in_the_project(tmp_path, monkeypatch):
    """plan snake_tank → `armgen firmware snake12 --plan` → CMake host build → run →
    `armgen verify --run`: every command the plan's sample, exactly, to DONE."""
    require_tool("cmake")
    plan_path = tmp_path / "tank.csv"
    assert CliRunner().invoke(cli, ["plan", str(EXAMPLES / "snake_tank.toml"), "-o", str(plan_path)]).exit_code == 0
    out = CliRunner().invoke(cli, ["firmware", "snake12", "--plan", str(plan_path), "--out", str(tmp_path / "fw")])
    assert out.exit_code == 0, out.output
    project = tmp_path / "fw"
    assert "CTRL_MODE_SAMPLED" in (project / "task" / "task_params.h").read_text()
    run_csv = _build_and_run(project)
    q = plan_q(read_plan(plan_path))
    assert np.array_equal(ticks(fw.parse_output(run_csv.read_text()))[:, 2:27], q)
    monkeypatch.chdir(project)
    out = CliRunner().invoke(cli, ["verify", "robot.toml", "-o", "generated", "--plan", "demo/plan.csv", "--run",
                                   "run.csv", "--samples", "20", "--precision", "double"])
    assert out.exit_code == 0, out.output
    assert "== run: PASS" in out.output and f"DONE at {len(q) - 1}" in out.output


def test_snake_plan_beyond_the_speed_limits_is_not_shipped(tmp_path):
    """snake_planar asks a12 for 1.29 times its qdlim and says limits = "report" (the paper's
    speed, written to be inspected): `armgen firmware` refuses it (exit 3), nothing written."""
    plan_path = tmp_path / "planar.csv"
    assert CliRunner().invoke(cli, ["plan", str(EXAMPLES / "snake_planar.toml"), "-o", str(plan_path)]).exit_code == 0
    out = CliRunner().invoke(cli, ["firmware", "snake12", "--plan", str(plan_path), "--out", str(tmp_path / "fw")])
    assert out.exit_code == 3, out.output
    assert "'a12'" in out.output and "velocity limit" in out.output and "never to run it" in out.output
    assert not (tmp_path / "fw").exists()


@pytest.mark.arm
def test_snake_task_on_the_m4(tmp_path, monkeypatch):
    """snake_tank → `armgen firmware snake12 --task` → the Cortex-M4F image under QEMU (float):
    every command within one float rounding of the plan's sample, DONE at the last one, and
    `armgen verify --run` accepts the run."""
    for tool in ("cmake", "arm-none-eabi-gcc", "qemu-system-arm"):
        require_tool(tool)
    out = CliRunner().invoke(cli, ["firmware", "snake12", "--task", str(EXAMPLES / "snake_tank.toml"),
                                   "--out", str(tmp_path / "fw")])
    assert out.exit_code == 0, out.output
    project = tmp_path / "fw"
    for args in (["-S", str(project), "-B", str(project / "build-m4"),
                  f"-DCMAKE_TOOLCHAIN_FILE={project / 'cmake' / 'arm-none-eabi-cortex-m4.cmake'}"],
                 ["--build", str(project / "build-m4")], ["--build", str(project / "build-m4"), "--target", "qemu"]):
        done = subprocess.run(["cmake", *args], capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    run = fw.parse_output((project / "build-m4" / "run-m4.csv").read_text())
    q = plan_q(read_plan(project / "demo" / "plan.csv"))
    assert (run.state, run.fault, run.summary["real_bytes"]) == ("DONE", "NONE", "4")
    assert np.max(np.abs(ticks(run)[:, 2:27] - q)) <= FLOAT_TABLE_ROUNDING
    monkeypatch.chdir(project)
    out = CliRunner().invoke(cli, ["verify", "robot.toml", "-o", "generated", "--plan", "demo/plan.csv", "--run",
                                   "build-m4/run-m4.csv", "--samples", "20", "--precision", "float"])
    assert out.exit_code == 0, out.output
    assert "== run: PASS" in out.output and "DONE at 1000" in out.output
