"""Fault-tolerant planning (spec 30): the masked joint-manipulability index against NumPy and
finite differences, its behaviour at the kink, the index variants, the generated masked step
and WLN weights against closed forms, the planner's claims on the bundled examples, the
infeasible iiwa start, plain vs smooth weights, the sweep, the C backend, and bad input."""

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from armgen.cli.main import cli
from armgen.errors import PlanningError, TaskFileError
from armgen.planning.fault_tolerant.planner import FaultTolerantPlanner
from armgen.planning.tasks import apply_overrides, configure_task, load_task, run_task
from armgen.robot import load_robot
from armgen.symbolic.model import SymbolicModel

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
# Central differences, step 1e-6: truncation ~h²·f''' ≈ 1e-12, rounding ~eps/h ≈ 1e-10 on O(1)
# values; 1e-7 leaves a margin for the larger gradients (as in test_symbolic).
FD_STEP = 1e-6
FD_TOL = 1e-7
# det(J₋ᵢJ₋ᵢᵀ) by Cauchy–Binet vs NumPy's LU determinant: both rounding-level, the minors are
# O(1) (the same bound as test_symbolic's joint-manipulability check).
DET_ABS, DET_REL = 1e-14, 1e-9
# The generated masked step against an explicit NumPy inverse: the symbolic LDLᵀ and
# np.linalg.inv differ by rounding times the condition number (≤ (σ_max/λ)² ≈ 1e4 when damped).
STEP_TOL = 1e-10
# The bisection σ_min² is within a few eps·‖A‖ (tridiagonal reduction, 48 halvings).
SIGMA_SQ_REL = 1e-13


def model(name):
    return SymbolicModel(load_robot(name))


def interior(robot, count, seed, margin=0.05):
    rng = np.random.default_rng(seed)
    span = robot.qmax - robot.qmin
    return rng.uniform(robot.qmin + margin * span, robot.qmax - margin * span, size=(count, robot.n))


def plan(name, *overrides, backend="symbolic"):
    task, sha = load_task(EXAMPLES / f"{name}.toml")
    apply_overrides(task, list(overrides))
    return run_task(task, name, sha, backend)


def parsed(name, *overrides):
    task, _ = load_task(EXAMPLES / f"{name}.toml")
    apply_overrides(task, list(overrides))
    return configure_task(task, name).config


# -- the index ----------------------------------------------------------------------------

@pytest.mark.parametrize("name", ["iiwa14", "modular8"])
def test_masked_index_against_numpy(name):
    """ω_i² − δ² = det(J₋ᵢJ₋ᵢᵀ) of the healthy columns (locked ones deleted, NumPy LU);
    H_M = Σ_healthy a_i ω_i; w² − δ² = det(J_h J_hᵀ) (0 with fewer healthy columns than rows)."""
    m = model(name)
    f, jac = m.function("ft_index"), m.function("jacobian")
    rng = np.random.default_rng(1)
    delta = 1e-3
    for q in interior(m.robot, 10, seed=2):
        for locked in ((), (int(rng.integers(m.n)),), tuple(rng.choice(m.n, 2, replace=False))):
            mask = np.ones(m.n)
            mask[list(locked)] = 0
            a = rng.uniform(0.5, 2, m.n)
            omega, H, _, w, _ = (np.ravel(np.array(x)) for x in f(q, mask, a, delta))
            J = np.array(jac(q))
            healthy = [i for i in range(m.n) if i not in locked]
            Jh = J[:, healthy]
            for i in healthy:
                Ji = np.delete(J, list(locked) + [i], axis=1)
                ref = np.linalg.det(Ji @ Ji.T) if Ji.shape[1] >= 6 else 0.0
                assert omega[i] ** 2 - delta ** 2 == pytest.approx(ref, abs=DET_ABS, rel=DET_REL)
            assert H[0] == pytest.approx(sum(a[i] * omega[i] for i in healthy), rel=1e-14)
            ref_w = np.linalg.det(Jh @ Jh.T) if len(healthy) >= 6 else 0.0
            assert w[0] ** 2 - delta ** 2 == pytest.approx(ref_w, abs=DET_ABS, rel=DET_REL)


def test_unmasked_index_equals_joint_manipulability():
    m = model("modular8")
    q, a = m.robot.configuration("q0"), np.linspace(1, 2, 8)
    ft = [np.ravel(np.array(x)) for x in m.function("ft_index")(q, np.ones(8), a, 1e-3)]
    jm = [np.ravel(np.array(x)) for x in m.function("joint_manipulability")(q, a, 1e-3)]
    mw = [np.ravel(np.array(x)) for x in m.function("manipulability")(q, 1e-3)]
    for got, ref in zip(ft, jm + mw):
        np.testing.assert_allclose(got, ref, rtol=1e-13, atol=1e-16)


@pytest.mark.parametrize("name", ["iiwa14", "modular8"])
def test_masked_index_gradient_matches_finite_differences(name):
    """AD ∇H_M and ∇w on the healthy columns vs central differences, away from the kink
    (δ = 1e-2 keeps every sample's smoothing radius wide)."""
    m = model(name)
    f = m.function("ft_index")
    delta, a = 1e-2, np.linspace(1, 2, m.n)
    for k, q in enumerate(interior(m.robot, 4, seed=3)):
        mask = np.ones(m.n)
        mask[k % m.n] = 0
        _, _, g, _, gw = f(q, mask, a, delta)
        for out, grad in ((1, g), (3, gw)):
            fd = np.array([(float(f(q + e, mask, a, delta)[out]) - float(f(q - e, mask, a, delta)[out])) / (2 * FD_STEP)
                           for e in np.eye(m.n) * FD_STEP])
            np.testing.assert_allclose(np.ravel(grad), fd, atol=FD_TOL)


def test_smooth_form_at_the_kink():
    """iiwa, joint 6 locked: det(J₋₆) changes sign where q5 = 0, so |det| has a kink there.
    The smooth ω_6 = sqrt(det² + δ²) is exactly δ with zero slope at the kink, and its slope
    tends to ±|∂det/∂q5| a few δ/|∂det/∂q5| away (the documented behaviour)."""
    m = model("iiwa14")
    f, jac = m.function("ft_index"), m.function("jacobian")
    q = m.robot.configuration("q0_feasible")  # q5 = 0
    e6 = np.eye(7)[5]
    delta = 1e-4

    def det6(x):
        return np.linalg.det(np.delete(np.array(jac(x)), 5, axis=1))

    slope = (det6(q + FD_STEP * np.eye(7)[4]) - det6(q - FD_STEP * np.eye(7)[4])) / (2 * FD_STEP)
    assert abs(det6(q)) < 1e-15 and abs(slope) > 1e-3  # a genuine sign change
    omega, _, g, _, _ = (np.ravel(np.array(x)) for x in f(q, np.ones(7), e6, delta))
    assert omega[5] == pytest.approx(delta, rel=1e-9)
    assert abs(g[4]) < 1e-12
    far = 50 * delta / abs(slope)  # |det| ≈ 50 δ there: sqrt(det² + δ²) has slope 0.9998 |det|'
    e5 = FD_STEP * np.eye(7)[4]
    for side in (-1, 1):
        x = q + side * far * np.eye(7)[4]
        _, _, g, _, _ = (np.ravel(np.array(v)) for v in f(x, np.ones(7), e6, delta))
        abs_slope = (abs(det6(x + e5)) - abs(det6(x - e5))) / (2 * FD_STEP)
        assert np.sign(abs_slope) == side
        assert g[4] == pytest.approx(abs_slope, rel=1e-3)
    # δ → 0 recovers |det| away from the kink
    x = q + far * np.eye(7)[4]
    assert float(f(x, np.ones(7), e6, 1e-12)[0][5]) == pytest.approx(abs(det6(x)), rel=1e-9)


def test_index_variants():
    """relative: ω_i/w and the quotient-rule gradient vs finite differences of H_M/w;
    sigma_min: per-joint σ_min(J₋ᵢ) vs NumPy SVD, gradient by central differences."""
    task = parsed("modular8_fault_circle_gpm")
    planner = FaultTolerantPlanner(task)
    m = model("modular8")
    f, jac = m.function("ft_index"), m.function("jacobian")
    q = task.path.q_start + 0.1
    mask = np.ones(8)
    mask[2] = 0
    rel = replace(task.method, index="relative")
    H, grad, per, w = planner.index(q, mask, rel)
    omega, hm, _, w_ref, _ = (np.ravel(np.array(x)) for x in f(q, mask, np.ones(8), rel.delta))
    assert H == pytest.approx(hm[0] / w_ref[0], rel=1e-14)
    np.testing.assert_allclose(per, omega / w_ref[0], rtol=1e-14)

    def h_rel(x):
        out = f(x, mask, np.ones(8), rel.delta)
        return float(out[1]) / float(out[3])
    fd = np.array([(h_rel(q + e) - h_rel(q - e)) / (2 * FD_STEP) for e in np.eye(8) * FD_STEP])
    np.testing.assert_allclose(grad, fd, atol=1e-6)  # H_M/w ~ 3.5: FD rounding ~3.5·eps/h
    sig = replace(task.method, index="sigma_min")
    H, grad, per, _ = planner.index(q, mask, sig)
    J = np.array(jac(q))
    for i in range(8):
        ref = 0.0 if i == 2 else np.linalg.svd(np.delete(J, [2, i], axis=1), compute_uv=False)[-1]
        assert per[i] == pytest.approx(ref, abs=1e-14)
    assert H == pytest.approx(per.sum(), rel=1e-14) and grad[2] == 0.0


# -- the generated step and weights ----------------------------------------------------------

@pytest.mark.parametrize("name", ["planar3", "iiwa14", "modular8"])
def test_step_fault_against_numpy(name):
    m = model(name)
    rows = list(m.robot.task_rows)
    f, jac = m.function("step_fault"), m.function("jacobian")
    rng = np.random.default_rng(4)
    for q in interior(m.robot, 15, seed=5):
        mask = np.ones(m.n)
        if m.n > m.m:
            mask[rng.integers(m.n)] = 0
        W = 1 + rng.uniform(0, 5, m.n)
        alpha, xdot = rng.normal(size=m.n), rng.normal(size=m.m)
        eps, lam_max = rng.uniform(0.01, 0.3), 0.05
        qd, lam, sigma = (np.ravel(np.array(x)) for x in f(q, xdot, mask, W, alpha, eps, lam_max))
        J = np.array(jac(q))[rows]
        S = np.diag(mask / W)
        A = J @ S @ J.T
        s_ref = np.linalg.svd(J @ np.sqrt(S), compute_uv=False)[m.m - 1]
        assert abs(sigma[0] ** 2 - s_ref ** 2) <= SIGMA_SQ_REL * np.linalg.norm(A, 2)
        lam2 = 0.0 if s_ref >= eps else (1 - (s_ref / eps) ** 2) * lam_max ** 2
        assert lam[0] ** 2 == pytest.approx(lam2, abs=1e-13)
        a = mask * alpha
        ref = a + S @ J.T @ np.linalg.solve(A + lam[0] ** 2 * np.eye(m.m), xdot - J @ a)
        np.testing.assert_allclose(qd, ref, atol=STEP_TOL)
        assert np.all(qd[mask == 0] == 0.0)  # a locked joint does not move, exactly
        if lam[0] == 0:
            np.testing.assert_allclose(J @ qd, xdot, atol=1e-9)


def test_wln_weights_closed_form_and_continuity():
    m = model("modular8")
    f = m.function("wln_weights")
    rng = np.random.default_rng(6)
    for _ in range(50):
        g, om, qp = rng.normal(size=8), rng.uniform(0, 0.2, 8), rng.normal(size=8)
        mask = (rng.random(8) > 0.2).astype(float)
        b, floor = rng.uniform(0, 3), 10 ** rng.uniform(-4, -2)
        penalty = mask * b * np.abs(g) / np.maximum(om, floor)
        W, act = (np.ravel(np.array(x)) for x in f(g, om, qp, mask, b, floor, 0.0))  # plain
        np.testing.assert_allclose(act, mask * (g * qp < 0), atol=0)
        np.testing.assert_allclose(W, 1 + penalty * (g * qp < 0), rtol=1e-15)
        v_band = rng.uniform(0.05, 0.5)
        W, act = (np.ravel(np.array(x)) for x in f(g, om, qp, mask, b, floor, v_band))  # smooth
        d = np.clip(-np.sign(g) * qp / v_band, 0, 1)
        np.testing.assert_allclose(W, 1 + penalty * d * d * (3 - 2 * d), rtol=1e-14)
        # continuity in the velocity: |ΔW| ≤ penalty · max g' (1.5) / v_band · |Δq̇|
        dq = 1e-6 * rng.normal(size=8)
        W2, _ = (np.ravel(np.array(x)) for x in f(g, om, qp + dq, mask, b, floor, v_band))
        assert np.all(np.abs(W2 - W) <= penalty * 1.5 / v_band * np.abs(dq) + 1e-14)


# -- the planner ----------------------------------------------------------------------------

def test_task_twist_is_the_papers():
    """ẋ = [0, πR sin πt, −πR cos πt, 0, 0, 0], R = 50 mm."""
    planner = FaultTolerantPlanner(parsed("iiwa14_fault_circle_gpm"))
    R = 0.05
    for t in np.linspace(0, 4, 17):
        _, _, xdot = planner.path(t)
        ref = [0, math.pi * R * math.sin(math.pi * t), -math.pi * R * math.cos(math.pi * t), 0, 0, 0]
        np.testing.assert_allclose(xdot, ref, atol=1e-12)


def test_published_start_is_infeasible_on_the_iiwa():
    with pytest.raises(PlanningError, match=r"start 'q0' is infeasible.*820\.0 mm.*q0_feasible"):
        plan("iiwa14_fault_circle_gpm", "start=q0")
    # planned anyway: the elbow passes through full stretch and the task fails
    # (report mode for the joint limits too: through full stretch the elbow outruns its qdlim)
    r = plan("iiwa14_fault_circle_gpm", "start=q0", "check.reach=report", "check.limits=report", "fault.joints=[]")
    s = r.metadata["summary"]
    assert "infeasible" in s["infeasible_start"] and not s["task_completed"]
    assert r.metadata["reach_check"]["needed_distance_range_mm"][1] > 820.0
    q4 = r.column("q4_rad")
    assert q4.min() < 0 < q4.max()  # the elbow went through straight
    assert s["damped_steps"] > 0
    # the shipped start stays inside the elbow's range
    ok = plan("iiwa14_fault_circle_gpm", "fault.joints=[]").metadata
    assert ok["reach_check"]["feasible"] and ok["summary"]["task_completed"]


def test_locked_joint_stops_and_the_examples_verdicts():
    r = plan("iiwa14_fault_circle_wln")
    t = r.column("t_s")
    after = t >= 2.0
    assert np.all(r.column("dq5_rad_s")[after] == 0.0)
    assert np.ptp(r.column("q5_rad")[after]) == 0.0
    assert np.all(r.column("lock5_1")[after] == 1) and np.all(r.column("lock5_1")[~after] == 0)
    v = r.metadata["verdict"]
    assert v["completed"] and v["max_pos_err_after_lock_mm"] < 1.0
    assert r.metadata["integrator"]["clik"] and r.metadata["integrator"]["clik_gain"] == 10.0
    # the iiwa's locked elbow fixes the shoulder–wrist distance: the circle cannot be finished
    v = plan("iiwa14_fault_circle_gpm").metadata["verdict"]
    assert not v["completed"] and v["w_min_after_lock"] < 1e-3
    # the 8-DOF arm keeps one redundancy after the lock and GPM keeps raising H_M
    v = plan("modular8_fault_circle_gpm").metadata["verdict"]
    assert v["completed"] and v["H_M_end"] > v["H_M_min_after_lock"]


def test_gpm_raises_the_index_before_the_lock():
    base = parsed("modular8_fault_circle_gpm")
    planner = FaultTolerantPlanner(base)
    h = [planner.run_locks(replace(base.method, K=k), [(3,)])[0].metadata["verdict"]["H_M_before_lock"]
         for k in (0.0, 2.0)]
    assert h[1] > h[0] * 1.05


def test_open_loop_is_recorded():
    meta = plan("modular8_fault_circle_gpm", "integrator.clik=false").metadata
    assert meta["integrator"]["open_loop"] and meta["integrator"]["clik_gain"] == 0.0


def test_smooth_weights_do_not_chatter_where_plain_ones_do():
    """Plain on/off weights jump: their velocity steps do not shrink with h, so peak |q̈| grows
    like 1/h; the smooth rule's weights are continuous in t and peak |q̈| stays put."""
    peaks = {}
    for rule in ("plain", "smooth"):
        for step in (0.02, 0.005):
            task = parsed("modular8_fault_circle_wln", f"method.weight_rule={rule}", "method.b=0.25",
                          f"integrator.step={step}", "fault.joints=[4]")
            v = FaultTolerantPlanner(task).run().metadata["verdict"]
            peaks[rule, step] = (v["peak_ddq_deg_s2"], v["max_weight_step"], v["completed"])
    assert peaks["plain", 0.005][0] > 2.5 * peaks["plain", 0.02][0]
    assert peaks["smooth", 0.005][0] < 1.2 * peaks["smooth", 0.02][0]
    assert peaks["smooth", 0.005][0] < 0.3 * peaks["plain", 0.005][0]
    assert peaks["smooth", 0.02][1] < 0.6 * peaks["plain", 0.02][1]
    assert all(c for _, _, c in peaks.values())


def test_sweep_over_gain_and_locked_joint(tmp_path):
    """`armgen sweep` over K × the locked joint: one row per plan; locking the modular arm's j4
    completes the task (spec 30's verdict), and a row's summary is that plan's."""
    import pandas as pd

    out = tmp_path / "sweep.csv"
    result = CliRunner().invoke(cli, ["sweep", str(EXAMPLES / "modular8_fault_circle_gpm.toml"), "--grid", "method.K=[0, 2]",
                                      "--grid", "fault.joints=[[1], [4]]", "--workers", "1", "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = pd.read_csv(out)
    assert list(zip(table["method.K"], table["fault.joints"])) == [(0, "[1]"), (0, "[4]"), (2, "[1]"), (2, "[4]")]
    assert list(table["task_completed"]) == [False, True, False, True]
    single = plan("modular8_fault_circle_gpm", "method.K=2", "fault.joints=[4]").metadata["summary"]
    for key in ("H_M_before_lock", "peak_ddq_deg_s2", "w_min_after_lock_mm3", "max_pos_error_after_lock_mm"):
        assert table.iloc[3][key] == pytest.approx(single[key], rel=1e-15), key


def test_c_backend_gives_the_same_plan():
    short = ("timing.duration=1", "fault.time=0.5", "method.name=wln")
    a = plan("modular8_fault_circle_wln", *short)
    b = plan("modular8_fault_circle_wln", *short, backend="c")
    np.testing.assert_allclose(a.data, b.data, rtol=0, atol=1e-12)


def test_cli_plan_and_plot(tmp_path):
    out = tmp_path / "plan.csv"
    result = CliRunner().invoke(cli, ["plan", str(EXAMPLES / "iiwa14_fault_circle_wln.toml"), "-o", str(out)])
    assert result.exit_code == 0, result.output
    header = out.read_text().splitlines()[0].split(",")
    for col in ("t_s", "q1_rad", "dq1_rad_s", "pos_err_m", "ori_err_rad", "H_M_1", "omega1_1", "lock1_1", "W1_1"):
        assert col in header
    result = CliRunner().invoke(cli, ["plot", str(out), "-o", str(tmp_path / "plan.png")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "plan.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("override, message", [
    ("fault.joints=[9]", r"fault.joints'\[0\] = 9 is not a joint of robot 'iiwa14'.*1\.\.7"),
    ("fault.joints=['elbow']", r"'elbow' is not a joint"),
    ("fault.joints=[4, 4]", "twice"),
    ("fault.joints=[1, 2, 3, 4, 5, 6, 7]", "locks all 7 joints"),
    ("fault.time=5", r"fault.time = 5.* outside the plan \[0, 4\]"),
    ("fault.time=-0.1", "outside the plan"),
    ("method.K=-1", r"method.K' = -1 must be ≥ 0"),
    ("method.b=-0.5", r"method.b' = -0.5 must be ≥ 0"),
    ("sweep.K=[1, -2]", r"sweep.K'\[1\] = -2 must be ≥ 0"),
    ("method.name=magic", "method.name"),
    ("method.index=volume", "method.index"),
    ("method.delta=0", "method.delta"),
    ("fault.when=2", "fault.when"),
    ("integrator.method=rk4", "explicit Euler only"),
])
def test_bad_input_is_a_clear_error(override, message):
    with pytest.raises(TaskFileError, match=message):
        plan("iiwa14_fault_circle_gpm", override)


def test_sweep_reports_an_infeasible_start_per_row(tmp_path):
    """From the paper's start the reach check fails: with check.reach = "error" every run is an
    exit-3 row; with "report" the runs plan and the rows carry the infeasibility; a bad field is
    an exit-2 row."""
    import pandas as pd

    out = tmp_path / "sweep.csv"
    args = ["sweep", str(EXAMPLES / "iiwa14_fault_circle_gpm.toml"), "--set", "start=q0", "--set", "check.limits=report",
            "--workers", "1", "-o", str(out)]
    result = CliRunner().invoke(cli, [*args, "--grid", "check.reach=['error', 'report']", "--grid", "fault.time=[2, 9]"])
    assert result.exit_code == 0, result.output
    table = pd.read_csv(out, keep_default_na=False)
    assert list(table["exit_code"]) == [3, 2, 0, 2]
    assert "infeasible" in table.iloc[0]["message"] and "fault.time" in table.iloc[1]["message"]
    assert "infeasible" in table.iloc[2]["infeasible_start"] and table.iloc[2]["status"] == "ok"


# -- configuration (issue 36: the validated task and the loaded robot → the typed SI task) --

def test_configure_resolves_the_task_on_the_given_robot():
    """The task is configured on the robot given (not a second copy of its file): joints by name
    or number → 0-based indices, the fault at half the duration by default, the file's mm and
    deg converted (1 mm = 1e-3 m, 1 deg = π/180 rad) and the unit-dependent defaults in SI
    whatever the file's units."""
    robot = load_robot("iiwa14")
    task, _ = load_task(EXAMPLES / "iiwa14_fault_circle_wln.toml")  # mm, deg; v_band = 11.46 deg/s
    del task["fault"]["time"]
    apply_overrides(task, ["fault.joints=['a6', 2]", "sweep.joints=[7, 'a1']", "completion.pos_tol=0.5"])
    config = configure_task(task, "wln", robot=robot).config
    assert config.robot is robot
    assert config.fault.joints == (1, 5) and config.sweep.joints == (0, 6)
    assert config.fault.time == 2.0  # timing.duration = 4 s
    assert config.method.v_band == pytest.approx(11.46 * math.pi / 180, rel=1e-15)
    assert config.completion.pos_tol == pytest.approx(0.5e-3, rel=1e-15)
    assert config.completion.ori_tol == pytest.approx(math.pi / 180, rel=1e-15)  # default 1 deg
    assert config.completion.max_joint_speed == pytest.approx(120 * math.pi / 180, rel=1e-15)
    del task["method"]["v_band"]
    assert configure_task(task, "wln", robot=robot).config.method.v_band == 0.2  # rad/s, not 0.2 deg/s


def test_plan_carries_the_config_it_was_made_with():
    """A stated path tolerance halves the integrator step (no lock: with a4 locked the tool
    leaves the path on purpose); the plan's config is the task at the step used, and planning
    that config again gives the same samples with no halving."""
    from armgen.planning.fault_tolerant import PLANNER

    result = plan("iiwa14_fault_circle_gpm", "fault.joints=[]", "check.path_tolerance=0.05")
    accuracy = result.metadata["summary"]["path_accuracy"]
    assert accuracy["step_halvings"] > 0
    config = result.config
    assert config.path.step == accuracy["step_s"] == pytest.approx(0.02 / 2 ** accuracy["step_halvings"])
    assert np.diff(result.column("t_s")) == pytest.approx(config.path.step)
    assert config.fault.joints == () and config.method.K == 4.0
    again = PLANNER.plan(config)
    assert again.metadata["summary"]["path_accuracy"]["step_halvings"] == 0
    np.testing.assert_array_equal(again.data, result.data)


def test_fault_time_beyond_a_program_names_the_programs_duration():
    """A program has no [timing]: a fault after its end is refused naming its duration."""
    import tomllib

    from test_programs import bar_task

    task = tomllib.loads(bar_task("fault_tolerant") + "\n[fault]\njoints = [2]\ntime = 100.0\n")
    with pytest.raises(TaskFileError, match=r"fault.time = 100.0 s is outside the plan \[0, [\d.]+\] s; choose a time "
                                            "within the program's duration"):
        configure_task(task, "bar")
