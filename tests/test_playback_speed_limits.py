"""The snake and ptp planners against the robot file's joint speed limits (``qdlim``, ``qddlim``):
``summary.joint_speed`` and the task's ``[check] limits`` policy (exit 3 and nothing written, or
``"report"``). The references are the robot file's numbers (read here with tomllib, in the file's
units) and the joint columns of the plan's CSV, never the report itself: the snake's rates by the
controller's sampled-playback rule (forward difference of the samples, docs/firmware.md), the
ptp's by its CSV's ω and ε columns."""

from __future__ import annotations

import copy
import json
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from armgen.cli.main import cli
from armgen.errors import PlanningError
from armgen.planning.tasks import load_task, run_task

REPO = Path(__file__).resolve().parent.parent
EXAMPLES = REPO / "armgen" / "data" / "examples"
ROBOTS = REPO / "armgen" / "data" / "robots"
# The CSV holds each double's shortest round-trip text, so the test's ratios from the CSV and the
# planner's from its arrays agree to rounding of the same arithmetic.
RATIO_RTOL = 1e-12
# snake_planar's first sample whose step to the next outruns a joint: where the controller stops
# it with SPEED (docs/firmware.md, tests/test_firmware_sampled.py).
PLANAR_SPEED_STOP_S = 2.44
# The planners count a ratio up to this as within a limit (the rounding of a sample at the limit).
WITHIN_LIMIT = 1 + 1e-9


def file_limits(robot: str, key: str) -> dict[str, float]:
    """``{joint: limit}`` in SI from the robot file itself (deg → rad, mm → m); inf where absent."""
    doc = tomllib.loads((ROBOTS / f"{robot}.toml").read_text())
    angle = math.pi / 180 if doc["units"]["angle"] == "deg" else 1.0
    length = 1e-3 if doc["units"]["length"] == "mm" else 1.0
    return {j["name"]: j[key] * (angle if j["type"] == "revolute" else length) if key in j else math.inf
            for j in doc["joints"]}


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    header = path.read_text().splitlines()[0].split(",")
    return header, np.loadtxt(path, delimiter=",", skiprows=1)


def plan_cli(tmp_path: Path, example: str, *extra: str):
    out = tmp_path / f"{Path(example).stem}.csv"
    result = CliRunner().invoke(cli, ["plan", str(EXAMPLES / example), "-o", str(out), *extra])
    return result, out


def beyond(ratios: dict[str, np.ndarray], t: np.ndarray) -> dict[str, tuple[float, float]]:
    """``{joint: (worst ratio, its time)}`` for the joints above 1."""
    out = {}
    for name, r in ratios.items():
        k = int(np.argmax(r))
        if r[k] > 1:
            out[name] = (float(r[k]), float(t[k]))
    return out


# ------------------------------------------------------------------------------------------- snake


def snake_ratios(csv: Path) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """|q̇|/qdlim per snake12 joint and sample, q̇ = (row k+1 − row k)/dt of the CSV's joint
    columns (0 at the last row), qdlim from snake12.toml."""
    header, rows = read_csv(csv)
    t = rows[:, header.index("t_s")]
    dt = t[1] - t[0]
    out = {}
    for name, limit in file_limits("snake12", "qdlim").items():
        q = rows[:, header.index(f"{name}_m" if name == "feed" else f"{name}_rad")]
        qd = np.append(np.diff(q) / dt, 0.0)
        out[name] = np.abs(qd) / limit
    return t, out


@pytest.fixture(scope="module")
def planar_report(tmp_path_factory):
    """snake_planar as bundled (``[check] limits = "report"``: the paper's speed)."""
    result, out = plan_cli(tmp_path_factory.mktemp("planar"), "snake_planar.toml")
    assert result.exit_code == 0, result.output
    return out


def test_snake_plan_beyond_the_speed_limits_is_infeasible(tmp_path, planar_report):
    result, out = plan_cli(tmp_path, "snake_planar.toml", "--set", "check.limits=error")
    assert result.exit_code == 3, result.output
    assert not out.exists() and not out.with_suffix(".json").exists()
    t, ratios = snake_ratios(planar_report)
    expected = beyond(ratios, t)
    name, (ratio, at) = min(expected.items(), key=lambda item: item[1][1])  # the joint whose worst comes first
    text = " ".join(result.output.split())
    assert (f"asks joint '{name}' for {ratio:.2f} times its velocity limit (the robot file's qdlim) at t = {at:.3f} s"
            in text), text
    assert "lower motion.v" in text and 'set [check] limits = "report"' in text


def test_snake_report_mode_lists_the_joints_beyond(planar_report):
    meta = json.loads(planar_report.with_suffix(".json").read_text())
    speed = meta["summary"]["joint_speed"]
    t, ratios = snake_ratios(planar_report)
    expected = beyond(ratios, t)
    reported = {v["joint"]: (v["ratio"], v["t_s"]) for v in speed["beyond_speed_limits"]}
    assert expected and reported.keys() == expected.keys()
    for name, (ratio, at) in expected.items():
        assert reported[name][0] == pytest.approx(ratio, rel=RATIO_RTOL)
        assert reported[name][1] == pytest.approx(at, abs=1e-9)
    assert {v["limit"] for v in speed["beyond_speed_limits"]} == {"velocity"}  # snake12 has no qddlim
    assert speed["peak_acceleration_ratio"] == [None] * 25 and not speed["within_speed_limits"]
    # the first sample beyond a limit is the one the controller stops at
    first = int(np.flatnonzero(np.any(np.stack(list(ratios.values())) > 1, axis=0))[0])
    assert t[first] == pytest.approx(PLANAR_SPEED_STOP_S, abs=1e-9)
    # the paper's 77 deg/s against snake12's 60 deg/s (docs/snake.md)
    assert max(r for r, _ in expected.values()) * 60 == pytest.approx(77.4, abs=0.05)


def test_snake_plan_within_the_limits_passes_in_error_mode(tmp_path):
    result, out = plan_cli(tmp_path, "snake_tank.toml")  # no [check]: error mode
    assert result.exit_code == 0, result.output
    speed = json.loads(out.with_suffix(".json").read_text())["summary"]["joint_speed"]
    _, ratios = snake_ratios(out)
    worst = max(float(r.max()) for r in ratios.values())
    assert 0 < worst <= 1
    assert speed["within_speed_limits"] and speed["beyond_speed_limits"] == []
    assert speed["max_speed_ratio"] == pytest.approx(worst, rel=RATIO_RTOL)


@pytest.mark.parametrize("example", ["snake_tank.toml", "modular8_ptp_two_segments.toml"])
def test_bad_check_value_is_bad_input(tmp_path, example):
    result, out = plan_cli(tmp_path, example, "--set", "check.limits=warn")
    assert result.exit_code == 2, result.output
    assert "check.limits" in result.output and not out.exists()


# --------------------------------------------------------------------------------------------- ptp

PTP_EXAMPLE = "modular8_ptp_two_segments.toml"  # 3 s; knot times [0, 1.5, 3]


def ptp_ratios(header: list[str], rows: np.ndarray, robot: str = "modular8") -> dict[tuple[str, str], np.ndarray]:
    """``{(joint, "velocity"|"acceleration"): |ω|/qdlim or |ε|/qddlim}`` from the CSV's columns."""
    out = {}
    for kind, key, column in (("velocity", "qdlim", "omega_{}_rad_s"), ("acceleration", "qddlim", "eps_{}_rad_s2")):
        for name, limit in file_limits(robot, key).items():
            out[(name, kind)] = np.abs(rows[:, header.index(column.format(name))]) / limit
    return out


def test_bundled_ptp_example_is_within_the_limits(tmp_path):
    result, out = plan_cli(tmp_path, PTP_EXAMPLE)
    assert result.exit_code == 0, result.output
    speed = json.loads(out.with_suffix(".json").read_text())["summary"]["joint_speed"]
    ratios = ptp_ratios(*read_csv(out))
    assert max(float(r.max()) for r in ratios.values()) < 1
    assert speed["max_speed_ratio"] == pytest.approx(max(float(r.max()) for (_, k), r in ratios.items()
                                                         if k == "velocity"), rel=RATIO_RTOL)


def test_ptp_plan_beyond_the_limits_exits_3_and_report_mode_lists_it(tmp_path):
    squeeze = ("--set", "waypoints.t=[0, 0.25, 0.5]")  # six times faster
    result, out = plan_cli(tmp_path, PTP_EXAMPLE, *squeeze)
    assert result.exit_code == 3, result.output
    assert not out.exists() and not out.with_suffix(".json").exists()
    text = " ".join(result.output.split())
    assert "Space the knot times further apart" in text
    result, out = plan_cli(tmp_path, PTP_EXAMPLE, *squeeze, "--set", "check.limits=report")
    assert result.exit_code == 0, result.output
    header, rows = read_csv(out)
    t = rows[:, header.index("t_s")]
    ratios = ptp_ratios(header, rows)
    expected = {}
    for (name, kind), r in ratios.items():
        k = int(np.argmax(r))
        if r[k] > 1:
            expected[(name, kind)] = (float(r[k]), float(t[k]))
    reported = {(v["joint"], v["limit"]): (v["ratio"], v["t_s"]) for v in
                json.loads(out.with_suffix(".json").read_text())["summary"]["joint_speed"]["beyond_speed_limits"]}
    assert {kind for _, kind in expected} == {"velocity", "acceleration"}  # both limits are crossed
    assert reported.keys() == expected.keys()
    for key, (ratio, at) in expected.items():
        assert reported[key][0] == pytest.approx(ratio, rel=RATIO_RTOL) and reported[key][1] == pytest.approx(at)
    name, kind = min(expected, key=lambda key: expected[key][1])
    assert f"asks joint '{name}' for {expected[(name, kind)][0]:.2f} times its {kind} limit" in text


def test_ptp_computed_times_above_the_robots_qdlim_are_refused():
    """``timing.omega_max`` is the task's bound; above the robot file's qdlim (planar3: 180 deg/s)
    the plan it times is refused all the same, and at the qdlim it plans within it."""
    qdlim = file_limits("planar3", "qdlim")
    task = {"planner": "ptp", "robot": "planar3", "method": "3-4", "units": {"angle": "deg"},
            "waypoints": {"theta": {"j1": [0, 90, 120], "j2": [0, -30, 0], "j3": [0, 0, 0]},
                          "omega": {"j1": [0, 20, 0], "j2": [0, 0, 0], "j3": [0, 0, 0]}},
            "timing": {"omega_max": 360}}
    with pytest.raises(PlanningError, match=r"joint 'j1' for 2\.00 times its velocity limit.*lower timing\.omega_max"):
        run_task(copy.deepcopy(task), "fast.toml")
    task["timing"] = {"omega_max": 180}
    plan = run_task(task, "at_limit.toml")
    worst = max(float(np.abs(plan.column(f"omega_{name}_rad_s")).max() / limit) for name, limit in qdlim.items())
    assert 0.99 < worst <= WITHIN_LIMIT  # the time solver runs j1 up to its bound, here the qdlim


def test_ptp_without_a_robot_has_no_joint_speed():
    task, _ = load_task(EXAMPLES / "ptp_single_joint.toml")
    assert "joint_speed" not in run_task(task, "single.toml").metadata["summary"]


@settings(max_examples=15, deadline=None, derandomize=True, database=None)
@given(st.floats(0.05, 1.0))
def test_ptp_refused_exactly_when_the_csv_exceeds_a_limit(scale):
    """Knot times scaled by ``scale``: error mode refuses the plan iff one of its CSV's ω or ε
    samples is beyond the robot file's qdlim or qddlim."""
    task, _ = load_task(EXAMPLES / PTP_EXAMPLE)
    task["waypoints"]["t"] = [x * scale for x in task["waypoints"]["t"]]
    reported = run_task({**copy.deepcopy(task), "check": {"limits": "report"}}, "scaled.toml")
    worst = max(float(r.max()) for r in ptp_ratios(reported.columns, reported.data).values())
    try:
        run_task(task, "scaled.toml")
        refused = False
    except PlanningError:
        refused = True
    assert refused == (worst > WITHIN_LIMIT)
