"""Torque limits in planning (issue 39): a plan of a robot with inertials reports its joint
torques (``summary.joint_torque``) against ``taumax``, checked against an independent inverse
dynamics (Pinocchio on the same arm built by hand, and gravity in closed form), and a plan that
needs more than ``taumax`` follows the ``[check] limits`` policy; a robot without inertials
gets no block."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import tomli_w
from click.testing import CliRunner

from armgen.cli.main import cli
from armgen.errors import PlanningError
from armgen.planning.plan_schema import JointTorque
from armgen.planning.tasks import configure_task, load_task, run_task
from armgen.planning.torque import (DIFFERENCE_RULE, PLAN_ACCELERATION_RULE, SINGLE_SAMPLE_RULE, planned_robot,
                                   torque_report)
from armgen.robot import load_robot, parse_robot

pin = pytest.importorskip("pinocchio")

REPO = Path(__file__).resolve().parent.parent
EXAMPLES = REPO / "armgen" / "data" / "examples"

# Pinocchio and armgen's RNEA agree to ~1e-15 relative in double (tests/test_dynamics.py); the
# peaks are compared at the same samples, so only that rounding separates them.
PEAK_RTOL = 1e-9
# A 100 s line: q̈ ~ 1e-5 rad/s² and q̇ ~ 1e-3 rad/s against ~0.5 kg·m² give ~1e-5 N·m beside
# gravity's ~10 N·m, so the peak is the closed-form gravity torque to this relative bound.
QUASI_STATIC_RTOL = 1e-5

# A planar 3R arm in a vertical plane (gravity along -y of the base), standard DH: each link's
# centre of mass and tensor are given in DH frame i, at the link's far end.
LINKS = (  # a (m), mass (kg), com (m, frame i), inertia [ixx, iyy, izz, ixy, ixz, iyz] (kg·m²)
    (0.5, 3.0, (-0.25, 0.01, 0.02), (0.01, 0.07, 0.065, 0.001, -0.002, 0.0005)),
    (0.4, 2.0, (-0.2, -0.01, 0.0), (0.004, 0.03, 0.028, 0.0, 0.001, 0.0)),
    (0.3, 1.0, (-0.15, 0.0, 0.01), (0.001, 0.008, 0.0075, 0.0, 0.0, 0.0002)),
)
GRAVITY = (0.0, -9.81, 0.0)
TAUMAX = (40.0, 15.0, 5.0)  # N·m, above what the test motions need


def robot_text(taumax: tuple[float, ...] = TAUMAX) -> str:
    lines = ['name = "vertical3"', 'convention = "standard"', 'task_rows = ["vx", "vy", "wz"]',
             f"gravity = {list(GRAVITY)}", "[units]", 'length = "m"', 'angle = "deg"', 'mass = "kg"']
    for k, ((a, mass, com, inertia), limit) in enumerate(zip(LINKS, taumax), start=1):
        lines += ["[[joints]]", f'name = "j{k}"', 'type = "revolute"', f"a = {a}", "d = 0", "alpha = 0",
                  "qlim = [-170, 170]", f"mass = {mass}", f"com = {list(com)}", f"inertia = {list(inertia)}",
                  *([f"taumax = {limit}"] if math.isfinite(limit) else [])]
    lines += ["[configurations]", "q0 = [30, -45, 60]"]
    return "\n".join(lines) + "\n"


def pinocchio_arm() -> tuple:
    """The same arm built joint by joint in Pinocchio: joint i turns about z at the end of link
    i - 1; DH frame i is joint i's frame shifted by a_i along x, so each body sits there."""
    model = pin.Model()
    parent, placement = 0, pin.SE3.Identity()
    for k, (a, mass, com, (ixx, iyy, izz, ixy, ixz, iyz)) in enumerate(LINKS, start=1):
        joint = model.addJoint(parent, pin.JointModelRZ(), placement, f"j{k}")
        tensor = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        shift = pin.SE3(np.eye(3), np.array([a, 0.0, 0.0]))
        model.appendBodyToJoint(joint, pin.Inertia(mass, np.array(com), tensor), shift)
        parent, placement = joint, shift
    model.gravity.linear = np.array(GRAVITY)
    return model, model.createData()


def pinocchio_torques(q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
    model, data = pinocchio_arm()
    return np.array([pin.rnea(model, data, *row).copy() for row in zip(q, dq, ddq)])


def closed_form_gravity(q: np.ndarray) -> np.ndarray:
    """τ_g of the planar arm: joint i holds the weight of links i..3 at their centres of mass,
    τ_i = Σ_k m_k g (x_com,k − x_joint,i) with gravity along −y."""
    g = -GRAVITY[1]
    angles = np.cumsum(q)
    ends = np.cumsum([[a * math.cos(th), a * math.sin(th)] for (a, *_), th in zip(LINKS, angles)], axis=0)
    joints_x = np.concatenate([[0.0], ends[:-1, 0]])
    com_x = [ends[k, 0] + math.cos(angles[k]) * com[0] - math.sin(angles[k]) * com[1]
             for k, (_, _, com, _) in enumerate(LINKS)]
    return np.array([sum(LINKS[k][1] * g * (com_x[k] - joints_x[i]) for k in range(i, 3)) for i in range(3)])


@pytest.fixture
def arm_file(tmp_path):
    def write(taumax: tuple[float, ...] = TAUMAX) -> Path:
        path = tmp_path / "vertical3.toml"
        path.write_text(robot_text(taumax))
        return path
    return write


def line_task(robot: Path, duration: float, **check: str) -> dict:
    """A cartesian line of the vertical arm from q0, 50 mm along x and 20 mm along y."""
    arm = parse_robot(robot.read_text(), str(robot))
    end = arm.fk(arm.q0)[:3, 3] + [0.05, 0.02, 0.0]
    task = {"planner": "cartesian", "robot": str(robot), "start": "q0", "units": {"length": "m", "angle": "deg"},
            "path": {"type": "line", "end": end.tolist()}, "timing": {"duration": duration, "law": "cubic"},
            "integrator": {"method": "rk4", "step": duration / 100}}
    if check:
        task["check"] = check
    return task


def columns(result, stems: str) -> np.ndarray:
    return np.column_stack([result.column(stems.format(k=k)) for k in (1, 2, 3)])


def test_cartesian_peak_torques_equal_pinocchio(arm_file):
    result = run_task(line_task(arm_file(), 1.0), "line.toml")
    report = result.metadata["summary"]["joint_torque"]
    t = result.column("t_s")
    q, dq = columns(result, "q{k}_rad"), columns(result, "dq{k}_rad_s")
    # the documented rule for q̈ (no q̈ columns in a cartesian plan), then Pinocchio's inverse dynamics
    tau = np.abs(pinocchio_torques(q, dq, np.gradient(dq, t, axis=0)))
    assert report["computed"] and report["acceleration_rule"] == DIFFERENCE_RULE
    assert report["peak_torque"] == pytest.approx(tau.max(axis=0), rel=PEAK_RTOL)
    assert report["peak_torque_t_s"] == pytest.approx(t[tau.argmax(axis=0)].tolist(), abs=0)
    assert report["taumax"] == list(TAUMAX)
    assert report["peak_torque_ratio"] == pytest.approx(tau.max(axis=0) / TAUMAX, rel=PEAK_RTOL)
    assert report["max_torque_ratio"] == pytest.approx(max(tau.max(axis=0) / TAUMAX), rel=PEAK_RTOL)
    assert report["within_torque_limits"] and report["beyond_torque_limits"] == []
    assert isinstance(result.summary.joint_torque, JointTorque)


def test_slow_line_peak_torques_are_closed_form_gravity(arm_file):
    result = run_task(line_task(arm_file(), 100.0), "line.toml")
    report = result.metadata["summary"]["joint_torque"]
    q = columns(result, "q{k}_rad")
    gravity = np.abs(np.array([closed_form_gravity(row) for row in q]))
    assert report["peak_torque"] == pytest.approx(gravity.max(axis=0), rel=QUASI_STATIC_RTOL)


PTP_TASK = {"planner": "ptp", "method": "3-4", "step": 0.005, "units": {"angle": "deg"},
            "waypoints": {"t": [0, 1.5, 3.0],
                          "theta": {"j1": [30, 60, 90], "j2": [-45, -20, 0], "j3": [60, 30, 10]},
                          "omega": {"j1": [0, 20, 0], "j2": [0, 15, 0], "j3": [0, -15, 0]}}}


def test_ptp_peak_torques_use_the_plans_accelerations(arm_file):
    result = run_task(PTP_TASK | {"robot": str(arm_file())}, "ptp.toml")
    report = result.metadata["summary"]["joint_torque"]
    names = ("theta_j{k}_rad", "omega_j{k}_rad_s", "eps_j{k}_rad_s2")
    tau = np.abs(pinocchio_torques(*(columns(result, stems) for stems in names)))
    assert report["acceleration_rule"] == PLAN_ACCELERATION_RULE
    assert report["peak_torque"] == pytest.approx(tau.max(axis=0), rel=PEAK_RTOL)


def test_a_plan_beyond_taumax_is_infeasible_and_writes_nothing(arm_file, tmp_path):
    task = tmp_path / "line.toml"
    task.write_text(tomli_w.dumps(line_task(arm_file((20.0, 15.0, 5.0)), 1.0)))
    out = tmp_path / "plan.csv"
    run = CliRunner().invoke(cli, ["plan", str(task), "-o", str(out)])
    assert run.exit_code == 3, run.output
    reference = run_task(line_task(arm_file(), 1.0), "line.toml").metadata["summary"]["joint_torque"]
    peak, when = reference["peak_torque"][0], reference["peak_torque_t_s"][0]
    text = " ".join(run.output.split())
    named = (f"asks joint 'j1' for {peak:.4g} N·m at t = {when:.3f} s, {peak / 20:.2f} times its torque limit "
             "of 20 N·m")
    assert named in text, text
    assert "taumax" in text and 'limits = "report"' in text
    assert not out.exists() and not out.with_suffix(".json").exists()


def test_report_policy_writes_the_plan_and_lists_the_joints_beyond(arm_file, tmp_path):
    with pytest.raises(PlanningError, match="joint 'j1'"):
        run_task(line_task(arm_file((20.0, 15.0, 5.0)), 1.0), "line.toml")
    task = tmp_path / "line.toml"
    task.write_text(tomli_w.dumps(line_task(arm_file((20.0, 15.0, 5.0)), 1.0, limits="report")))
    out = tmp_path / "plan.csv"
    run = CliRunner().invoke(cli, ["plan", str(task), "-o", str(out)])
    assert run.exit_code == 0, run.output
    report = json.loads(out.with_suffix(".json").read_text())["summary"]["joint_torque"]
    (beyond,) = report["beyond_torque_limits"]
    assert beyond["joint"] == "j1" and beyond["taumax"] == 20.0 and beyond["ratio"] > 1
    assert beyond["torque"] == report["peak_torque"][0] and beyond["t_s"] == report["peak_torque_t_s"][0]
    assert not report["within_torque_limits"] and report["max_torque_ratio"] == beyond["ratio"]


def test_joints_without_taumax_have_no_ratio(arm_file):
    result = run_task(line_task(arm_file((math.inf, 15.0, 5.0)), 1.0), "line.toml")
    report = result.metadata["summary"]["joint_torque"]
    assert report["taumax"][0] is None and report["peak_torque_ratio"][0] is None
    assert report["peak_torque"][0] > 0 and report["max_torque_ratio"] == max(report["peak_torque_ratio"][1:])


def test_a_plan_without_joint_columns_says_so(arm_file):
    robot = load_robot(arm_file())
    report = torque_report(robot, ["t_s", "feed_m", "a1_rad"], np.zeros((3, 3)))
    assert report is not None and report["computed"] is False and "no joint torques" in report["reason"]
    assert JointTorque.model_validate(report).beyond_torque_limits == []



def test_a_plan_of_one_sample_needs_the_gravity_torques(arm_file):
    robot = load_robot(arm_file())
    q = np.radians([20.0, -30.0, 50.0])
    report = torque_report(robot, ["t_s", "q1_rad", "q2_rad", "q3_rad", "dq1_rad_s", "dq2_rad_s", "dq3_rad_s"],
                           np.concatenate([[0.0], q, np.zeros(3)])[None, :])
    assert report["acceleration_rule"] == SINGLE_SAMPLE_RULE
    assert report["peak_torque"] == pytest.approx(np.abs(closed_form_gravity(q)), rel=PEAK_RTOL)

def test_robots_without_inertials_get_no_torque_block():
    result = run_task(line_task(Path(load_robot("planar3").path), 1.0), "line.toml")
    assert "joint_torque" not in result.metadata["summary"]
    assert result.summary.joint_torque is None
    example = EXAMPLES / "modular8_ptp_two_segments.toml"
    document, sha = load_task(example)
    assert "joint_torque" not in run_task(document, str(example), sha).metadata["summary"]



@pytest.mark.parametrize("example, robot", [
    ("modular8_ptp_two_segments", "modular8"), ("ptp_single_joint", None), ("modular8_circle_pinv", "modular8"),
    ("modular8_fault_circle_gpm", "modular8"), ("modular8_wgpm_demo", "modular8"), ("snake_planar", "snake12")])
def test_every_planners_config_names_its_robot(example, robot):
    path = EXAMPLES / f"{example}.toml"
    document, sha = load_task(path)
    found = planned_robot(configure_task(document, str(path), sha).config)
    assert (found and found.name) == robot


def test_the_summary_table_gives_torques_in_newton_metres():
    from armgen.cli.summary import summary_table

    block = {"computed": True, "peak_torque": [30.36, 8.915, 1.059], "peak_torque_ratio": [1.518, None, 0.1],
             "taumax": [20.0, None, 10.0], "within_torque_limits": False,
             "beyond_torque_limits": [{"joint": "j1", "t_s": 0.0}]}
    table = summary_table({"planner": "ptp", "summary": {"joint_torque": block}})
    assert "peak joint torque" in table and "[30.36, 8.915, 1.059]" in table and "N·m" in table
    assert "152% (joint 1)" in table and "within torque limits" in table
