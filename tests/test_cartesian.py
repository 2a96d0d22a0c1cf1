"""Cartesian redundancy planner (spec 20): paths, time laws, windows, the paper's
claims on the bundled examples, backend equivalence, and bad input."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from armgen.cli.main import cli
from armgen.errors import PlanningError, TaskFileError
from armgen.planning.toolpath.paths import CirclePath, LinePath, TimeLaw
from armgen.planning.tasks import apply_overrides, configure_task, load_task, run_task
from armgen.planning.cartesian.windows import JointWindows
from armgen.robot import rpy_matrix

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
ROBOTS = Path(__file__).resolve().parent.parent / "robots"
# The spec's bars (spec 20, "What the examples must show").
DRIFT_FREE_DEG = 0.1
RETURN_EXACT_DEG = 1e-6
LIMIT_DEG = 140.0
# Undamped steps solve J q̇ = ẋ through an LDLᵀ of J Jᵀ; its residual is rounding only.
UNDAMPED_RESIDUAL = 1e-9


def plan(name, *overrides, backend="symbolic"):
    task, sha = load_task(EXAMPLES / f"{name}.toml")
    apply_overrides(task, list(overrides))
    return run_task(task, name, sha, backend)


def test_time_laws_are_rest_to_rest():
    for law in (TimeLaw("cubic"), TimeLaw("trapezoidal", 0.25), TimeLaw("constant")):
        assert law(0.0)[0] == 0.0 and law(1.0)[0] == pytest.approx(1.0, abs=1e-15)
        taus = np.linspace(0.01, 0.99, 50)
        for tau in taus:  # ds/dτ is the derivative of s
            fd = (law(tau + 1e-6)[0] - law(tau - 1e-6)[0]) / 2e-6
            assert law(tau)[1] == pytest.approx(fd, abs=1e-5)  # O(h) at the trapezoid corners
    assert TimeLaw("cubic")(0.0)[1] == 0.0 and TimeLaw("cubic")(1.0)[1] == 0.0
    with pytest.raises(TaskFileError, match="timing.law"):
        TimeLaw("sine")


def test_circle_passes_through_the_three_points_in_order():
    start, via, end = np.array([0.1, 0.2, 0.3]), np.array([0.3, 0.1, 0.5]), np.array([0.0, -0.2, 0.4])
    c = CirclePath(start, via, end, np.eye(3))
    np.testing.assert_allclose(c(0.0)[0], start, atol=1e-15)
    np.testing.assert_allclose(c(1.0)[0], start, atol=1e-14)
    a_via, a_end = c.angle_of(via), c.angle_of(end)
    assert 0 < a_via < a_end < 2 * math.pi
    np.testing.assert_allclose(c(a_via / (2 * math.pi))[0], via, atol=1e-14)
    np.testing.assert_allclose(c(a_end / (2 * math.pi))[0], end, atol=1e-14)
    s = 0.37  # dp/ds is the derivative of p
    np.testing.assert_allclose(c(s)[1], (c(s + 1e-7)[0] - c(s - 1e-7)[0]) / 2e-7, atol=1e-7)
    with pytest.raises(TaskFileError, match="collinear"):
        CirclePath(start, start + np.array([1, 1, 1.0]), start + np.array([2, 2, 2.0]), np.eye(3))


def test_line_interpolates_orientation_about_a_fixed_axis():
    r0, r1 = rpy_matrix(0.1, -0.2, 0.3), rpy_matrix(-0.5, 0.4, 1.2)
    line = LinePath(np.zeros(3), np.ones(3), r0, r1)
    np.testing.assert_allclose(line(1.0)[2], r1, atol=1e-12)
    s = 0.4  # the angular velocity per unit s: skew(ω) = dR/ds Rᵀ
    dR = (line(s + 1e-7)[2] - line(s - 1e-7)[2]) / 2e-7
    W = dR @ line(s)[2].T
    np.testing.assert_allclose(line(s)[3], [W[2, 1], W[0, 2], W[1, 0]], atol=1e-7)


def test_windows_latch_hold_and_ramp():
    w = JointWindows(1, t_smo=10.0, t_sum=20.0, shape="quadratic")
    assert w.update(0.0, np.array([False]))[0] == 0.0
    assert w.update(1.0, np.array([True]))[0] == 0.0  # opens now, ramps from 0
    assert w.update(6.0, np.array([False]))[0] == pytest.approx(0.25)  # ((6-1)/10)²; open although out of band
    assert w.update(11.0, np.array([False]))[0] == 1.0
    assert w.update(20.0, np.array([False]))[0] == 1.0  # held for T_sum − T_smo = 10 s
    assert w.update(21.0, np.array([False]))[0] == 1.0  # hold ends: ramp-down starts here
    assert w.update(26.0, np.array([False]))[0] == pytest.approx(0.75)
    v = w.update(27.0, np.array([True]))[0]  # re-entry: ramps up from the current value
    assert v == pytest.approx(1 - 0.36)
    assert w.update(32.0, np.array([True]))[0] == pytest.approx(v + (1 - v) * 0.25)
    assert w.openings[0] == 2


@pytest.fixture(scope="module")
def example_plans():
    return {name: plan(f"modular8_circle_{name}") for name in
            ("pinv", "repetitive", "zghal", "zghal_improved", "combined")}


def test_minimum_norm_drifts_and_leaves_the_limits(example_plans):
    s = example_plans["pinv"].metadata["summary"]
    assert s["max_final_deviation_deg"] > 1.0
    assert s["limit_violations"], "the paper's minimum-norm run leaves ±140°"


def test_repetitive_and_combined_are_drift_free(example_plans):
    for name in ("repetitive", "combined"):
        s = example_plans[name].metadata["summary"]
        assert max(abs(d) for d in s["final_deviation_deg"]) < DRIFT_FREE_DEG, name
    s = example_plans["combined"].metadata["summary"]
    assert max(s["max_abs_q_deg"]) <= LIMIT_DEG and not s["limit_violations"]


def test_improved_zghal_starts_and_ends_at_rest_with_less_travel(example_plans):
    plain = example_plans["zghal"].metadata["summary"]
    improved = example_plans["zghal_improved"].metadata["summary"]
    assert improved["start_joint_speed_deg_s"] == pytest.approx(0.0, abs=1e-12)
    assert improved["end_joint_speed_deg_s"] == pytest.approx(0.0, abs=1e-12)
    assert plain["start_joint_speed_deg_s"] > 1.0  # always-on gradient moves the arm at t = 0
    assert improved["total_joint_travel_deg"] < plain["total_joint_travel_deg"]
    assert not improved["limit_violations"] and not plain["limit_violations"]


def test_task_is_met_exactly_where_undamped(example_plans):
    for name, result in example_plans.items():
        undamped = result.column("damping_1") == 0
        assert undamped.mean() > 0.9
        assert np.max(result.column("task_residual_1")[undamped]) < UNDAMPED_RESIDUAL, name


@pytest.mark.slow
def test_rk4_returns_to_the_start_exactly():
    s = plan("modular8_circle_combined", "integrator.method=rk4").metadata["summary"]
    assert s["max_final_deviation_deg"] < RETURN_EXACT_DEG
    assert not s["limit_violations"]


def test_c_backend_gives_the_same_plan():
    # squeezed into 10 s the line outruns the joints' qdlim: report mode, the backends are compared
    short = ("path.type=line", "path.end=[-450, 400, 900]", "timing.duration=10", "integrator.step=0.01",
             "check.limits=report")
    a = plan("modular8_circle_combined", *short)
    b = plan("modular8_circle_combined", *short, backend="c")
    assert b.metadata["backend"] == "c"
    np.testing.assert_allclose(a.data, b.data, rtol=0, atol=1e-12)


@pytest.mark.parametrize("override, error, message", [
    ("robot=nobot", "RobotFileError", "unknown robot 'nobot'"),
    ("method.name=magic", TaskFileError, "method.name"),
    ("start=[150, 0, 0, 0, 0, 0, 0, 0]", "RobotFileError", "outside its limits"),
    ("path.via=[-3000, 424, 1080]", PlanningError, "unreachable"),
    ("path.via=[-255.2645, 424.068, 857.041]", TaskFileError, "collinear"),
    ("integrator.step=0", TaskFileError, "integrator.step"),
    ("integrator.step=-0.1", TaskFileError, "integrator.step"),
    ("timing.duration=nan", TaskFileError, "timing.duration"),
])
def test_bad_input_is_a_clear_error(override, error, message):
    from armgen import errors

    exc = getattr(errors, error) if isinstance(error, str) else error
    with pytest.raises(exc, match=message):
        plan("modular8_circle_pinv", override)


def _configured(name, *overrides, drop=()):
    """The example's typed configuration (the pipeline's configure), ``drop`` dotted keys removed."""
    task, _ = load_task(EXAMPLES / f"{name}.toml")
    apply_overrides(task, list(overrides))
    for key in drop:
        table, field = key.rsplit(".", 1)
        task[table].pop(field)
    return configure_task(task, name).config


def test_each_method_has_its_own_defaults_and_a_value_given_wins():
    """A field the file leaves out takes its method's default (combined: rho_L 1e-4, T_smo_L 20,
    T_sum_L 40; zghal_improved: rho_L 0.04; theta_s 20 deg in any unit, docs/cartesian.md); a
    value the file gives is used even where it equals the schema's default."""
    method_keys = [f"method.{k}" for k in ("rho_R", "T_smo_R", "rho_L", "theta_s", "T_smo_L", "T_sum_L",
                                           "gamma_R_ramp")]
    combined = _configured("modular8_circle_combined", drop=method_keys).method
    assert (combined.rho_L, combined.T_smo_L, combined.T_sum_L) == (1e-4, 20.0, 40.0)
    assert combined.theta_s == math.radians(20) and combined.rho_R == 2.8 and combined.gamma_R_ramp == 20.0
    improved = _configured("modular8_circle_combined", 'method.name="zghal_improved"', drop=method_keys).method
    assert (improved.rho_L, improved.T_smo_L, improved.T_sum_L) == (0.04, 40.0, 80.0)
    in_radians = _configured("modular8_circle_combined", 'units.angle="rad"', "start=[0, 0, 0, 0, 0, 0, 0, 0]",
                             drop=method_keys).method
    assert in_radians.theta_s == math.radians(20)
    given = _configured("modular8_circle_combined", "method.rho_L=0.025", "method.T_smo_L=40", "method.T_sum_L=80").method
    assert (given.rho_L, given.T_smo_L, given.T_sum_L) == (0.025, 40.0, 80.0)
    with pytest.raises(TaskFileError, match="method.T_sum_L = 10.0 must be ≥ method.T_smo_L = 20.0"):
        _configured("modular8_circle_combined", "method.T_sum_L=10", drop=["method.T_smo_L"])


def test_start_and_path_errors_name_the_field():
    """Joint values of the wrong count name the field 'start' (not 'task.start') and the robot's
    joint count; the path's own rules are the schema's, naming the field (a circle without via,
    a missing end_rpy, an interpolating circle, turns on a line); a duration that is no whole
    number of steps names the file."""
    with pytest.raises(TaskFileError, match="field 'start' has 3 joint values but robot 'modular8' has 8 joints"):
        _configured("modular8_circle_pinv", "start=[0, 0, 0]")
    with pytest.raises(TaskFileError, match=r"missing field 'path.via'; add 'via = <value>'"):
        _configured("modular8_circle_pinv", drop=["path.via"])
    with pytest.raises(TaskFileError, match=r"missing field 'path.end_rpy'"):
        _configured("modular8_circle_pinv", "path.type=line", "path.orientation=interpolate")
    with pytest.raises(TaskFileError, match=r"field 'path.orientation' = 'interpolate': .* along a line only"):
        _configured("modular8_circle_pinv", "path.orientation=interpolate", "path.end_rpy=[0, 0, 0]")
    with pytest.raises(TaskFileError, match=r"field 'path.turns' = 2: turns are for circles only"):
        _configured("modular8_fault_circle_gpm", "path.type=line")
    # refused when configured, naming the file (the planner's loop found it, unnamed)
    with pytest.raises(TaskFileError, match="modular8_circle_pinv: timing.duration = 250.01 s is not a multiple of "
                                            "integrator.step = 0.02 s"):
        _configured("modular8_circle_pinv", "timing.duration=250.01")


@pytest.mark.parametrize("example, extra", [("modular8_circle_pinv", ()),
                                            ("modular8_fault_circle_gpm", ("path.turns=1",))])
def test_an_unreachable_line_names_the_field_to_move(example, extra):
    """The reach check every circle or line shares (planning.common): a line ends beyond the
    arm's reach (5 m, relative or not) → infeasible, naming path.end alone (a circle: via and end)."""
    with pytest.raises(PlanningError, match=r"unreachable: .* move path\.end closer"):
        plan(example, "path.type=line", "path.end=[5000, 0, 0]", "check.limits=report", *extra)


def test_cli_failure_writes_nothing(tmp_path):
    out = tmp_path / "plan.csv"
    result = CliRunner().invoke(cli, ["plan", str(EXAMPLES / "modular8_circle_pinv.toml"), "-o", str(out),
                                      "--set", "path.via=[-3000, 424, 1080]"])
    assert result.exit_code == 3 and "unreachable" in result.output
    assert list(tmp_path.iterdir()) == []


def test_leaving_the_joint_limits_is_exit_3_unless_the_task_reports_it(tmp_path):
    """The minimum-norm circle takes j6 past +140° (spec 20). By default that plan is infeasible
    (exit 3, the joint, time and value named, nothing written); its example file asks to report."""
    example = EXAMPLES / "modular8_circle_pinv.toml"
    reported = tmp_path / "reported.csv"
    ok = CliRunner().invoke(cli, ["plan", str(example), "-o", str(reported)])
    assert ok.exit_code == 0, ok.output
    data = np.genfromtxt(reported, delimiter=",", names=True)
    beyond = np.abs(data["q6_rad"]) > math.radians(LIMIT_DEG)  # the CSV read back: where j6 is outside
    first_t, worst = data["t_s"][np.argmax(beyond)], math.degrees(np.max(np.abs(data["q6_rad"])))

    out = tmp_path / "failed" / "plan.csv"
    failed = CliRunner().invoke(cli, ["plan", str(example), "-o", str(out), "--set", "check.limits=error"])
    assert failed.exit_code == 3, failed.output
    assert f"joint 'j6' passes its limit {LIMIT_DEG:.2f} deg at t = {first_t:.3f} s" in failed.output
    assert f"reaches {worst:.2f} deg" in failed.output and "also beyond: j8" in failed.output
    assert 'limits = "report"' in failed.output
    assert not out.parent.exists()
    with pytest.raises(TaskFileError, match="check.limits"):
        plan("modular8_circle_pinv", "check.limits=ignore")


def test_a_robot_file_in_a_task_is_found_beside_the_task_file(tmp_path, monkeypatch):
    """`robot = "my_arm.toml"` is relative to the task file, not to the current folder."""
    tasks = tmp_path / "tasks"
    tasks.mkdir()
    (tasks / "my_arm.toml").write_bytes((ROBOTS / "modular8.toml").read_bytes())
    text = (EXAMPLES / "modular8_circle_combined.toml").read_text().replace('robot = "modular8"',
                                                                            'robot = "my_arm.toml"')
    (tasks / "job.toml").write_text(text)
    monkeypatch.chdir(tmp_path)  # the parent folder: no my_arm.toml here
    short = ["--set", "path.type=line", "--set", "path.end=[-450, 400, 900]", "--set", "timing.duration=2"]
    result = CliRunner().invoke(cli, ["plan", "tasks/job.toml", "-o", "job.csv", *short])
    assert result.exit_code == 0, result.output
    assert json.loads(Path("job.json").read_text())["robot"]["file"] == str(Path("tasks") / "my_arm.toml")
    # a bundled name stays a name, and a value given with --set is relative to the current folder
    assert load_task(tasks / "job.toml")[0]["robot"] == str(Path(tasks) / "my_arm.toml")
    assert load_task(EXAMPLES / "modular8_circle_combined.toml")[0]["robot"] == "modular8"
    result = CliRunner().invoke(cli, ["plan", "tasks/job.toml", "-o", "job.csv", *short, "--set", "robot=my_arm.toml"])
    assert result.exit_code == 2 and "my_arm.toml: robot file not found" in result.output


@pytest.mark.parametrize("start, joint, side", [("[-57, -45, 71, -45, 32, 140, 34, -28]", "j6", "upper"),
                                               ("[-140, -45, 71, -45, 32, 80, 34, -28]", "j1", "lower")])
def test_a_start_on_a_limit_with_a_joint_limit_criterion_names_the_joint(start, joint, side):
    """H_L is infinite on a limit: the error names the joint instead of "the tool left the path"."""
    for name in ("zghal", "zghal_improved", "combined"):
        with pytest.raises(PlanningError, match=f"joint '{joint}' sitting on its {side} limit"):
            plan("modular8_circle_combined", f"start={start}", f'method.name="{name}"')
    with pytest.raises(PlanningError, match=f"joint '{joint}' sitting on its {side} limit") as info:
        run_task(load_task(EXAMPLES / "modular8_wgpm_demo.toml")[0] | {"start": json.loads(start)}, "wgpm")
    assert "method.criteria.zghal" in str(info.value)
    # without a joint-limit criterion the start is legal (inside the closed range): not this error
    short = ("path.type=line", "path.end=[-450, 400, 900]", "timing.duration=2", "check.limits=report")
    try:
        plan("modular8_circle_combined", f"start={start}", 'method.name="pinv"', *short)
    except PlanningError as exc:
        assert "sitting on" not in str(exc)


def test_cli_plan_and_plot(tmp_path):
    out = tmp_path / "plan.csv"
    result = CliRunner().invoke(cli, ["plan", str(EXAMPLES / "modular8_circle_repetitive.toml"), "-o", str(out),
                                      "--set", "path.type=line", "--set", "path.end=[-450, 400, 900]",
                                      "--set", "timing.duration=10", "--units", "deg"])
    assert result.exit_code == 0, result.output
    header = out.read_text().splitlines()[0].split(",")
    assert header[:3] == ["t_s", "q1_deg", "q2_deg"] and "dq1_deg_s" in header
    assert (tmp_path / "plan.json").is_file()
    result = CliRunner().invoke(cli, ["plot", str(out), "-o", str(tmp_path / "plan.png")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "plan.png").read_bytes()[:4] == b"\x89PNG"
