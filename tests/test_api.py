"""The public API: shapes as documented, batched results equal to per-sample results,
criteria against independent references (NumPy determinants, closed forms, finite
differences), named configurations, and plan / generate / verify round trips."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import armgen
from armgen.errors import ArmgenError, RobotFileError
from armgen.symbolic.sympy_reference import zghal_closed_form, zghal_gradient_closed_form

from conftest import KINEMATIC_ROBOTS, require_tool

SEED = 20261123
# The batch replays the same IEEE operations as CasADi's interpreter, with NumPy's instead of
# libm's sin/cos (which may differ by an ulp): entries agree to a few ulps of their magnitude.
BATCH_RTOL, BATCH_ATOL = 1e-12, 1e-14
# Central differences with h = 1e-6 rad: truncation O(h²) ≈ 1e-12 and rounding ε·w/h ≈ 1e-10.
FD_STEP, FD_TOL = 1e-6, 1e-7


def _samples(robot, shape):
    return np.random.default_rng(SEED).uniform(robot.qmin, robot.qmax, shape + (robot.n,))


def test_import_is_lazy():
    code = "import sys, armgen; print(any(m.startswith(('casadi', 'armgen.api', 'sympy')) for m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
    assert {"load_robot", "plan", "generate", "verify", "Robot"} <= set(dir(armgen))


@pytest.mark.parametrize("name", KINEMATIC_ROBOTS)
def test_shapes_as_documented(name):
    robot = armgen.load_robot(name)
    n = robot.n
    for batch in [(), (5,), (2, 3)]:
        q = _samples(robot, batch)
        assert robot.fk(q).shape == batch + (4, 4)
        assert robot.jacobian(q).shape == batch + (6, n)
        T, J = robot.fk_jacobian(q)
        assert T.shape == batch + (4, 4) and J.shape == batch + (6, n)
        assert robot.manipulability(q).shape == batch
        assert robot.manipulability_gradient(q, delta=1e-3).shape == batch + (n,)
        assert robot.joint_limit_criterion(q).shape == batch
        assert robot.joint_limit_gradient(q).shape == batch + (n,)
        assert robot.repetitive_criterion(q, robot.qmid).shape == batch
        assert robot.repetitive_gradient(q, robot.qmid).shape == batch + (n,)
        jm = robot.joint_manipulability(q)
        assert jm["omega"].shape == batch + (n,) and jm["H_M"].shape == batch and jm["grad_H_M"].shape == batch + (n,)
        assert robot.within_limits(q).shape == batch
    with pytest.raises(ValueError, match="shape"):
        robot.fk(np.zeros(n + 1))
    with pytest.raises(ValueError, match="shape"):
        robot.within_limits(np.zeros((3, n - 1)))


@pytest.mark.parametrize("name", KINEMATIC_ROBOTS)
def test_batched_equals_per_sample(name):
    robot = armgen.load_robot(name)
    q = _samples(robot, (40,))
    q_init = robot.qmid
    batched = {
        "fk": robot.fk(q), "jacobian": robot.jacobian(q), "w": robot.manipulability(q, 1e-3),
        "grad_w": robot.manipulability_gradient(q, 1e-3), "H_L": robot.joint_limit_criterion(q),
        "grad_H_L": robot.joint_limit_gradient(q), "H_R": robot.repetitive_criterion(q, q_init),
        "omega": robot.joint_manipulability(q, delta=1e-3)["omega"],
    }
    for k in range(len(q)):
        single = {
            "fk": robot.fk(q[k]), "jacobian": robot.jacobian(q[k]), "w": robot.manipulability(q[k], 1e-3),
            "grad_w": robot.manipulability_gradient(q[k], 1e-3), "H_L": robot.joint_limit_criterion(q[k]),
            "grad_H_L": robot.joint_limit_gradient(q[k]), "H_R": robot.repetitive_criterion(q[k], q_init),
            "omega": robot.joint_manipulability(q[k], delta=1e-3)["omega"],
        }
        for key, value in single.items():
            np.testing.assert_allclose(batched[key][k], value, rtol=BATCH_RTOL, atol=BATCH_ATOL, err_msg=key)


@pytest.mark.parametrize("name", ["iiwa14", "modular8"])
def test_criteria_against_independent_references(name):
    robot = armgen.load_robot(name)
    rows = list(robot.task_rows)
    q = _samples(robot, (20,))
    J = robot.jacobian(q)[:, rows, :]
    expected_w = np.sqrt(np.linalg.det(J @ np.swapaxes(J, -1, -2)))
    np.testing.assert_allclose(robot.manipulability(q), expected_w, rtol=1e-9)
    for k in range(3):
        np.testing.assert_allclose(robot.joint_limit_criterion(q[k]), zghal_closed_form(q[k], robot.qmin, robot.qmax),
                                   rtol=1e-12)
        np.testing.assert_allclose(robot.joint_limit_gradient(q[k]),
                                   zghal_gradient_closed_form(q[k], robot.qmin, robot.qmax), rtol=1e-12)
        np.testing.assert_allclose(robot.repetitive_gradient(q[k], robot.qmid), q[k] - robot.qmid, atol=1e-15)
        steps = np.eye(robot.n) * FD_STEP
        fd = np.array([(robot.manipulability(q[k] + e) - robot.manipulability(q[k] - e)) / (2 * FD_STEP) for e in steps])
        np.testing.assert_allclose(robot.manipulability_gradient(q[k]), fd, atol=FD_TOL)
        omega = robot.joint_manipulability(q[k])["omega"]
        for i in range(robot.n):
            Ji = np.delete(J[k], i, axis=1)
            # squares: a structurally singular J_-i has det ≈ 0 up to rounding, whose sqrt is noise
            assert omega[i] ** 2 == pytest.approx(np.linalg.det(Ji @ Ji.T), rel=1e-7, abs=1e-14)


def test_named_configurations_and_limits():
    robot = armgen.load_robot("panda")
    np.testing.assert_array_equal(robot.qr, robot.configuration("qr"))
    robot.qr[0] = 99.0  # a copy: the robot is unchanged
    assert robot.qr[0] == 0.0
    assert "ready" in dir(robot)
    with pytest.raises(AttributeError, match="configurations: qr, ready"):
        robot.q_unknown
    q = np.stack([robot.qr, robot.qmax + 0.1, np.full(robot.n, np.nan)])
    assert robot.within_limits(q).tolist() == [True, False, False]
    assert bool(robot.within_limits(robot.ready))


def test_load_robot_by_name_toml_and_urdf(tmp_path):
    from armgen.robot import BUNDLED_DIR

    assert armgen.load_robot(BUNDLED_DIR / "planar3.toml").sha256 == armgen.load_robot("planar3").sha256
    urdf = tmp_path / "two.urdf"
    urdf.write_text("<robot name='two'><link name='a'/><link name='b'/><link name='c'/>"
                    "<joint name='j1' type='continuous'><parent link='a'/><child link='b'/><axis xyz='0 0 1'/></joint>"
                    "<joint name='j2' type='revolute'><parent link='b'/><child link='c'/><origin xyz='1 0 0'/>"
                    "<axis xyz='0 0 1'/><limit lower='-1' upper='1'/></joint></robot>")
    robot = armgen.load_robot(urdf)
    assert robot.n == 2 and robot.convention == "urdf"
    # a planar 2R arm with links 1 and 0 (the tip is joint 2's origin): closed form
    q = np.array([0.3, -0.7])
    T = robot.fk(q)
    assert T[:3, 3] == pytest.approx([np.cos(0.3), np.sin(0.3), 0.0], abs=1e-15)
    assert T[0, 0] == pytest.approx(np.cos(-0.4), abs=1e-15)
    assert armgen.Robot.from_urdf(urdf).sha256 == robot.sha256
    with pytest.raises(RobotFileError, match="unknown robot"):
        armgen.load_robot("no_such_robot")


def test_plan_overrides_pandas_save_and_plot(tmp_path):
    from matplotlib.figure import Figure
    from PIL import Image

    task = {"planner": "cartesian", "robot": "planar3", "start": "q0", "task_rows_note": None}
    task.pop("task_rows_note")
    robot = armgen.load_robot("planar3")
    end = robot.fk(robot.q0)[:3, 3] + [0.05, 0.02, 0.0]
    task |= {"path": {"type": "line", "end": end.tolist()}, "timing": {"duration": 1.0},
             "integrator": {"method": "rk4", "step": 0.01}, "method": {"name": "pinv"}}
    plan = armgen.plan(task, **{"timing.duration": 2.0}, integrator__step=0.02)
    assert task["timing"]["duration"] == 1.0  # the caller's dict is not modified
    assert plan.metadata["task"]["timing"]["duration"] == 2.0 and plan.metadata["task"]["integrator"]["step"] == 0.02
    frame = plan.to_pandas()
    assert list(frame.columns) == plan.columns and len(frame) == 101
    assert frame["t_s"].iloc[-1] == pytest.approx(2.0)
    assert "run_time_s" in plan.summary
    csv_path, json_path = plan.save(tmp_path / "line.csv")
    assert csv_path.is_file() and json.loads(json_path.read_text())["csv"]["samples"] == 101
    figure = plan.plot()
    assert isinstance(figure, Figure) and figure.get_axes()
    gif = plan.animate(tmp_path / "line.gif", fps=4, duration=1.0)
    with Image.open(gif) as frames:
        assert frames.n_frames == 4  # fps × duration
    with pytest.raises(armgen.TaskFileError, match="planner"):
        armgen.plan({"planner": "nope"})


def test_generate_writes_c(tmp_path):
    generated = armgen.generate("planar3", out=tmp_path, functions=("fk", "jacobian"))
    assert generated.prefix == "planar3" and set(generated.flops) == {"fk", "jacobian"}
    assert {p.name for p in generated.paths} >= {"planar3.h", "planar3.c"}
    assert all(p.parent == tmp_path and p.is_file() for p in generated.paths)
    with pytest.raises(ArmgenError, match="not available"):
        armgen.generate("planar3", out=tmp_path / "x", functions=("nope",))


@pytest.mark.slow
def test_verify_returns_a_report(tmp_path):
    require_tool("gcc")
    report = armgen.verify("planar3", samples=200, precision="double", report=tmp_path / "r.json")
    assert report.passed and bool(report)
    assert [s.name for s in report.stages][:3] == ["fresh", "compile", "callbacks"]
    assert "== fresh: PASS" in str(report)
    assert report.to_dict()["passed"] and json.loads((tmp_path / "r.json").read_text())["passed"]


def test_robot_pickles_and_copies_after_use():
    import copy
    import pickle

    robot = armgen.load_robot("planar3")
    q = _samples(robot, (3,))
    expected = robot.fk(q)  # fills the evaluator cache, which holds unpicklable SX functions
    for clone in (pickle.loads(pickle.dumps(robot)), copy.deepcopy(robot)):
        np.testing.assert_array_equal(clone.fk(q), expected)
