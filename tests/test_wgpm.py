"""Multi-constraint weighted GPM (spec 35): the generated ``step_wgpm`` against an independent
NumPy implementation (finite-difference gradients, SVD, explicit inverses), the projector
properties on random configurations inside the damping bands (hypothesis), the bisection σ_min
estimate against NumPy, continuity of weights, gains and damping, the demo comparison, the
survey, the C backend and bad input."""

import math
from dataclasses import replace
from pathlib import Path

import casadi as ca
import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import given, settings
from hypothesis import strategies as st

from armgen.cli.main import cli
from armgen.errors import TaskFileError
from armgen.planning.tasks import apply_overrides, configure_task, load_task, run_task
from armgen.planning.wgpm.planner import WgpmPlanner
from armgen.robot import load_robot
from armgen.symbolic import criteria
from armgen.symbolic.model import SymbolicModel
from armgen.symbolic.steps import WGPM_SENSE, min_eigenvalue

# The survey of docs/wgpm.md: a random start in the free band (|q| ≤ 98°: Ω = 0.15 of ±140°) and
# a random circle through it (via and end relative to the start, within ±250 mm).
SURVEY_SET = ["--set", "path.relative=true", "--set", "path.turns=1", "--set", "check.limits=report"]
SURVEY_RANGES = ["--range", "start=" + str([-98] * 8) + ":" + str([98] * 8),
                 "--range", "path.via=[-250, -250, -250]:[250, 250, 250]",
                 "--range", "path.end=[-250, -250, -250]:[250, 250, 250]"]
EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
# Spec 35: with ρ = 0 and J_wb of full row rank the projector identities hold to rounding,
# "1e-12 in double". Rounding of N_wb = I − W_b J_wb^# J is ~eps ‖J‖² ‖J_wb^#‖ ≤ eps · 4 / ε, so
# the property tests draw ε ≥ 0.05 (‖J_wb^#‖ ≤ 20 when undamped): ~2e-14, well inside 1e-12.
PROJECTOR_TOL = 1e-12
# The generated step against the NumPy reference whose criterion gradients are central
# differences (h = 1e-6, error ~1e-9 relative on the gradients, times gains ≤ 1 / span).
REFERENCE_TOL = 1e-7
# λ_min by tridiagonal bisection: a few eps · ‖A‖ (seen ≤ 1.3e-15 ‖A‖ over 6000 matrices).
EIGEN_REL = 1e-13

ROBOTS = {name: SymbolicModel(load_robot(name)) for name in ("planar3", "iiwa14", "modular8")}


def g(d):
    return d * d * (3 - 2 * d)


def numpy_wgpm(m, jac_fn, q, xdot, band, t_rmax, eps, rho_max, delta, ramp, lo, hi, khi, klo, uth, ub):
    """Spec 35 written out with NumPy: closed-form weights, determinants by LU, criterion
    gradients by central differences, σ_min by SVD, N_wb and J_wb^# as explicit matrices."""
    r = m.robot
    rows = list(r.task_rows)
    qmin, qmax = r.qmin, r.qmax
    span = qmax - qmin
    d_lo = np.clip((qmin + band * span - q) / (band * span), 0, 1)
    d_hi = np.clip((q - (qmax - band * span)) / (band * span), 0, 1)
    wc = g(d_lo) + g(d_hi)
    wb = 1 - wc
    tr = t_rmax * (g(d_lo) - g(d_hi))

    def crit(x):
        J = np.array(jac_fn(x))[rows]
        A = J @ J.T
        mm = J.shape[0]
        det = max(np.linalg.det(A), 0.0)
        hm = 0.0
        for i in range(len(x)):
            Ji = np.delete(J, i, axis=1)
            hm += math.sqrt((max(np.linalg.det(Ji @ Ji.T), 0.0) if Ji.shape[1] >= mm else 0.0) + delta ** 2)
        hl = np.sum(span ** 2 / ((qmax - x) * (x - qmin)))
        return np.array([math.sqrt(det + delta ** 2), hm, hl, np.trace(A) / (mm * (det + delta ** 2) ** (1 / mm))])

    H = crit(q)
    G = np.array([(crit(q + e) - crit(q - e)) / 2e-6 for e in np.eye(len(q)) * 1e-6]).T
    sense = np.array(WGPM_SENSE)
    spans = hi - lo
    hn = np.clip((H - lo) / spans, 0, 1)
    u = np.where(sense > 0, hn, 1 - hn)
    k = sense * (khi - (khi - klo) * g(np.clip((u - uth) / ub, 0, 1)))
    z = ramp * (tr + wb * ((k / spans) @ G))
    J = np.array(jac_fn(q))[rows]
    Jwb = J @ np.diag(wb)
    sigma = np.linalg.svd(Jwb, compute_uv=False)[J.shape[0] - 1]
    rho2 = 0.0 if sigma >= eps else (1 - (sigma / eps) ** 2) * rho_max ** 2
    Jsharp = Jwb.T @ np.linalg.inv(Jwb @ Jwb.T + rho2 * np.eye(J.shape[0]))
    N = np.eye(len(q)) - np.diag(wb) @ Jsharp @ J
    return {"qdot": np.diag(wb) @ Jsharp @ xdot + N @ z, "w_c": wc, "rho": math.sqrt(rho2), "sigma_min": sigma,
            "gains": k, "H": H, "N": N, "J": J, "Jsharp": Jsharp, "wb": wb}


def default_params(m, rng):
    n = m.n
    return dict(band=rng.uniform(0.05, 0.3), t_rmax=0.3, eps=rng.uniform(0.02, 0.1), rho_max=0.05, delta=1e-3,
                ramp=rng.uniform(0, 1), lo=np.array([0.0, 0.0, 4.0 * n, 1.0]),
                hi=np.array([0.2, 1.0, 40.0 * n, 50.0]), khi=rng.uniform(0.2, 1, 4), klo=rng.uniform(0, 0.2, 4),
                uth=rng.uniform(0, 0.5, 4), ub=rng.uniform(0.1, 0.5, 4))


def call(m, q, xdot, p):
    f = m.function("step_wgpm")
    out = f(q, xdot, p["band"], p["t_rmax"], p["eps"], p["rho_max"], p["delta"], p["ramp"], p["lo"], p["hi"],
            p["khi"], p["klo"], p["uth"], p["ub"])
    return dict(zip(f.name_out(), (np.ravel(np.array(o)) for o in out)))


@pytest.mark.parametrize("name", ["planar3", "iiwa14", "modular8"])
def test_step_matches_the_numpy_reference(name):
    m = ROBOTS[name]
    jac = m.function("jacobian")
    rng = np.random.default_rng(7)
    span = m.robot.qmax - m.robot.qmin
    for _ in range(8):
        q = rng.uniform(m.robot.qmin + 0.02 * span, m.robot.qmax - 0.02 * span)
        xdot = rng.normal(size=m.m)
        p = default_params(m, rng)
        got = call(m, q, xdot, p)
        ref = numpy_wgpm(m, jac, q, xdot, **p)
        for key in ("w_c", "rho", "sigma_min", "gains", "H"):
            np.testing.assert_allclose(got[key], ref[key], rtol=1e-9, atol=1e-12, err_msg=key)
        np.testing.assert_allclose(got["qdot"], ref["qdot"], atol=REFERENCE_TOL * max(1, np.abs(ref["qdot"]).max()))


@st.composite
def band_configuration(draw, robot, band):
    """Each joint in the free band or in a damping band (half of the joints on average)."""
    q = []
    for lo, hi in zip(robot.qmin, robot.qmax):
        width = band * (hi - lo)
        where = draw(st.sampled_from(("free", "free", "low", "high")))
        x = draw(st.floats(0.001, 0.999))
        q.append({"free": lo + width + x * (hi - lo - 2 * width), "low": lo + x * width,
                  "high": hi - x * width}[where])
    return np.array(q)


@pytest.mark.parametrize("name", ["iiwa14", "modular8"])
def test_projector_properties_on_band_configurations(name):
    m = ROBOTS[name]
    jac = m.function("jacobian")
    rows = list(m.robot.task_rows)
    stats = {"undamped": 0, "damped": 0}

    @settings(max_examples=80, deadline=None, derandomize=True)
    @given(st.floats(0.05, 0.3), st.data(), st.floats(0.05, 0.2),
           st.lists(st.floats(-1, 1), min_size=m.m, max_size=m.m))
    def check(band, data, eps, xdot):
        q = data.draw(band_configuration(m.robot, band))
        xdot = np.array(xdot)
        rng = np.random.default_rng(len(stats) + int(1e6 * band))
        p = dict(default_params(m, rng), band=band, eps=eps, ramp=1.0)
        out = call(m, q, xdot, p)
        J = np.array(jac(q))[rows]
        wb = 1 - out["w_c"]
        Jwb = J * wb
        rho2 = out["rho"] ** 2
        Jsharp = Jwb.T @ np.linalg.inv(Jwb @ Jwb.T + rho2 * np.eye(m.m))
        N = np.eye(m.n) - np.diag(wb) @ Jsharp @ J
        # the primary part is linear in ẋ: q̇(ẋ) − q̇(0) = W_b J_wb^# ẋ (also when damped)
        out0 = call(m, q, np.zeros(m.m), p)
        np.testing.assert_allclose(out["qdot"] - out0["qdot"], wb * (Jsharp @ xdot), atol=1e-10)
        if out["rho"] == 0:
            stats["undamped"] += 1
            assert np.abs(J @ N).max() <= PROJECTOR_TOL
            assert np.abs(N @ N - N).max() <= PROJECTOR_TOL
            assert np.linalg.norm(J @ out["qdot"] - xdot) <= PROJECTOR_TOL * max(1.0, np.linalg.norm(xdot))
            # the secondary part lies in the range of N_wb and does not move the tool
            np.testing.assert_allclose(N @ out0["qdot"], out0["qdot"], atol=PROJECTOR_TOL * max(1, np.abs(out0["qdot"]).max()))
            assert np.linalg.norm(J @ out0["qdot"]) <= PROJECTOR_TOL * max(1, np.abs(out0["qdot"]).max())
        else:
            stats["damped"] += 1
            assert out["sigma_min"] < eps

    check()
    # Both branches were exercised. The mix is not fixed even with derandomize: Hypothesis seeds
    # its draws with constants from the local modules loaded so far, so it moves with the test
    # order and the package's module layout (18 to 32 of 80 undamped seen); 5 of each is a bar
    # far below that spread that still shows each branch was checked several times.
    assert stats["undamped"] >= 5 and stats["damped"] >= 5


def test_the_tempting_projector_is_not_a_null_space_projector():
    """I − J_wb⁺ J_wb is a projector but does not annihilate J when a joint is in a band."""
    m = ROBOTS["modular8"]
    q = m.robot.configuration("q0").copy()
    q[5] = m.robot.qmax[5] - 0.02 * (m.robot.qmax[5] - m.robot.qmin[5])  # j6 deep in its upper band
    out = call(m, q, np.zeros(6), dict(default_params(m, np.random.default_rng(0)), band=0.1))
    J = np.array(m.function("jacobian")(q))
    wb = 1 - out["w_c"]
    assert 0 < wb[5] < 1
    Jwb = J * wb
    tempting = np.eye(8) - np.linalg.pinv(Jwb) @ Jwb
    assert np.abs(J @ tempting).max() > 1e-3


@pytest.mark.parametrize("size", [3, 6])
def test_min_eigenvalue_against_numpy(size):
    a = ca.SX.sym("a", size, size)
    f = ca.Function("f", [a], [min_eigenvalue((a + a.T) / 2)])
    rng = np.random.default_rng(8)
    for k in range(400):
        B = rng.normal(size=(size, 8))
        if k % 4 == 1:  # one dominant direction: tiny λ_min
            B[:, 1:] *= 1e-3
        elif k % 4 == 2:  # nearly rank-deficient
            U, _ = np.linalg.qr(rng.normal(size=(size, size)))
            B = U @ np.diag(np.r_[np.ones(size - 1), rng.uniform(0, 1e-4)]) @ rng.normal(size=(size, 8))
        elif k % 4 == 3:  # clustered spectrum
            B = np.repeat(B[:, :1], 8, axis=1) + 1e-6 * B
        A = B @ B.T
        assert abs(float(f(A)) - np.linalg.eigvalsh(A)[0]) <= EIGEN_REL * np.linalg.norm(A, 2)


def test_online_gain_is_the_cubic_with_flat_ends():
    u, k_hi, k_lo, u_th, lam = (ca.SX.sym(s) for s in ("u", "k_hi", "k_lo", "u_th", "lam"))
    f = ca.Function("f", [u, k_hi, k_lo, u_th, lam], [criteria.online_gain(u, k_hi, k_lo, u_th, lam)])
    kh, kl, th, lb = 1.3, 0.2, 0.25, 0.4
    # a u³ + b u² + c u + d through (u_th, k_hi), (u_th + λ, k_lo) with zero slope at both
    M = np.array([[th ** 3, th ** 2, th, 1], [(th + lb) ** 3, (th + lb) ** 2, th + lb, 1],
                  [3 * th ** 2, 2 * th, 1, 0], [3 * (th + lb) ** 2, 2 * (th + lb), 1, 0]])
    coef = np.linalg.solve(M, [kh, kl, 0, 0])
    for x in np.linspace(0, 1, 41):
        ref = kh if x <= th else kl if x >= th + lb else np.polyval(coef, x)
        assert float(f(x, kh, kl, th, lb)) == pytest.approx(ref, abs=1e-12)
    for edge in (th, th + lb):
        slope = (float(f(edge + 1e-7, kh, kl, th, lb)) - float(f(edge - 1e-7, kh, kl, th, lb))) / 2e-7
        assert abs(slope) < 1e-5


@settings(max_examples=80, deadline=None, derandomize=True)
@given(st.floats(-0.2, 1.2), st.floats(-1e-4, 1e-4), st.floats(0, 2), st.floats(0, 1), st.floats(0, 0.8),
       st.floats(0.05, 0.5))
def test_gains_and_weights_are_continuous(u, du, k_hi, frac, u_th, lam):
    """|Δk| ≤ 1.5 (k_hi − k_lo)/λ |Δu| (max slope of g is 1.5); |Δw_c| ≤ 1.5/(Ω·range) |Δq|."""
    k_lo = frac * k_hi
    a, b = (float(criteria.online_gain(ca.DM(x), k_hi, k_lo, u_th, lam)) for x in (u, u + du))
    assert abs(a - b) <= 1.5 * (k_hi - k_lo) / lam * abs(du) + 1e-13
    m = ROBOTS["planar3"]
    f = m.function("continuous_weights")
    band = 0.1
    q = m.robot.qmin + (m.robot.qmax - m.robot.qmin) * (u + 0.2) / 1.4
    w0, w1 = (np.ravel(np.array(f(x, band))) for x in (q, q + du))
    assert np.all(np.abs(w1 - w0) <= 1.5 / (band * (m.robot.qmax - m.robot.qmin)) * abs(du) + 1e-13)


def test_damping_is_continuous_in_sigma():
    """ρ² = ρ_max² (1 − σ²/ε²)₊: 0 at σ = ε from both sides, ρ_max at σ = 0."""
    m = ROBOTS["modular8"]
    q = m.robot.configuration("q0")
    p = dict(default_params(m, np.random.default_rng(2)), band=0.05, ramp=0.0)
    sigma = call(m, q, np.zeros(6), p)["sigma_min"][0]
    for eps, expected in ((sigma * (1 - 1e-9), 0.0), (sigma * (1 + 1e-9), 0.0), (1e6, p["rho_max"])):
        rho = call(m, q, np.zeros(6), dict(p, eps=eps))["rho"][0]
        assert rho == pytest.approx(expected, abs=p["rho_max"] * 1e-4)


# -- the planner ---------------------------------------------------------------------------

def parsed(name, *overrides):
    task, _ = load_task(EXAMPLES / f"{name}.toml")
    apply_overrides(task, list(overrides))
    return configure_task(task, name).config


# The spec's comparison, as docs/wgpm.md gives it: one `armgen sweep` over the method.
COMPARE = ["--grid", 'method.name=["pinv", "clamp", "wgpm"]', "--set", "check.limits=report"]


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    import pandas as pd

    out = tmp_path_factory.mktemp("compare") / "compare.csv"
    result = CliRunner().invoke(cli, ["sweep", str(EXAMPLES / "modular8_wgpm_demo.toml"), *COMPARE, "--workers", "1",
                                      "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = pd.read_csv(out, keep_default_na=False)
    assert list(table["status"]) == ["ok"] * 3, table["message"]
    return {row["method.name"]: row for _, row in table.iterrows()}


def test_demo_comparison(demo):
    pinv, clamp, wgpm = demo["pinv"], demo["clamp"], demo["wgpm"]
    assert not pinv["within_limits"] and pinv["max_abs_q_overall_deg"] > 180  # j6, j8 far beyond ±140°
    assert clamp["within_limits"] and clamp["min_limit_margin_deg"] >= 0
    assert wgpm["within_limits"] and wgpm["tracks"] and wgpm["min_limit_margin_deg"] > 5
    assert wgpm["damped_steps"] == 0 and wgpm["max_pos_error_mm"] < 1.0
    assert clamp["peak_ddq_deg_s2"] > 20 * wgpm["peak_ddq_deg_s2"]  # the clamp's velocity jumps
    assert wgpm["start_joint_speed_deg_s"] == 0.0  # the ramp: at rest at t = 0
    assert wgpm["end_joint_speed_deg_s"] < 0.1


def test_wgpm_velocities_are_continuous():
    """Halving h halves wgpm's largest per-step velocity change (q̇ continuous in t); the binary
    clamp's velocity jumps where it freezes a joint do not shrink (q̇ discontinuous)."""
    jumps = {}
    for step in (0.02, 0.01):
        task = parsed("modular8_wgpm_demo", f"integrator.step={step}")
        planner = WgpmPlanner(task)
        for name in ("wgpm", "clamp"):
            r = planner.run(replace(task.method, name=name))
            qd = np.column_stack([r.column(f"dq{i + 1}_rad_s") for i in range(8)])
            dq = np.degrees(np.abs(np.diff(qd, axis=0)).max(axis=1))
            if name == "wgpm":
                jumps[name, step] = dq.max()
            else:
                wc = np.column_stack([r.column(f"wc{i + 1}_1") for i in range(8)])
                first = np.flatnonzero(np.any(np.diff(wc, axis=0) != 0, axis=1))[0]
                jumps[name, step] = dq[first]
    assert jumps["wgpm", 0.01] < 0.65 * jumps["wgpm", 0.02]
    assert jumps["clamp", 0.01] > 0.8 * jumps["clamp", 0.02] > 1.0  # deg/s in one step, whatever h


def test_survey_is_a_sweep(tmp_path):
    """The survey as `armgen sweep`: every method on the same seeded random tasks, one row each;
    the draws lie in their ranges and a row is the plan of its drawn task."""
    import json

    import pandas as pd

    out = tmp_path / "survey.csv"
    result = CliRunner().invoke(cli, ["sweep", str(EXAMPLES / "modular8_wgpm_demo.toml"), *SURVEY_SET,
                                      "--set", "timing.duration=6", "--grid", "method.name=['pinv', 'wgpm']",
                                      "--random", "2", "--seed", "3", *SURVEY_RANGES, "--workers", "1", "-o", str(out)])
    assert result.exit_code == 0, result.output
    table = pd.read_csv(out, keep_default_na=False)
    assert list(table["method.name"]) == ["pinv", "pinv", "wgpm", "wgpm"]
    assert list(table["start"][:2]) == list(table["start"][2:])  # the same tasks for every method
    starts = np.array([json.loads(s) for s in table["start"]])
    assert np.all(np.abs(starts) <= 98)
    ok = table[table["status"] == "ok"]
    assert len(ok) >= 2 and set(ok["within_limits"]) <= {True, False}
    row = ok.iloc[-1]
    task, sha = load_task(EXAMPLES / "modular8_wgpm_demo.toml")
    apply_overrides(task, [*SURVEY_SET[1::2], "timing.duration=6"])
    for key, value in json.loads(row["overrides"]).items():
        apply_overrides(task, [f"{key}={json.dumps(value)}"])
    single = run_task(task, "demo", sha).metadata["summary"]
    assert row["max_pos_error_mm"] == pytest.approx(single["max_pos_error_mm"], rel=1e-15)
    assert row["peak_ddq_deg_s2"] == pytest.approx(single["peak_ddq_deg_s2"], rel=1e-15)


def test_c_backend_gives_the_same_plan():
    task, sha = load_task(EXAMPLES / "modular8_wgpm_demo.toml")
    # squeezed into 4 s the demo outruns the joints' qdlim: report mode, the backends are compared
    apply_overrides(task, ["timing.duration=4", "method.ramp_time=1", "check.limits=report"])
    a = run_task(dict(task), "demo", sha)
    b = run_task(dict(task), "demo", sha, backend="c")
    np.testing.assert_allclose(a.data, b.data, rtol=0, atol=1e-12)


def test_cli_plan_and_plot(tmp_path):
    out = tmp_path / "plan.csv"
    result = CliRunner().invoke(cli, ["plan", str(EXAMPLES / "modular8_wgpm_demo.toml"), "-o", str(out),
                                      "--set", "timing.duration=6", "--set", "check.limits=report",  # squeezed
                                      "--units", "deg"])
    assert result.exit_code == 0, result.output
    header = out.read_text().splitlines()[0].split(",")
    for col in ("t_s", "q1_deg", "dq1_deg_s", "pos_err_m", "ori_err_deg", "H_L_1", "k_L_1", "wc1_1", "damping_1"):
        assert col in header
    result = CliRunner().invoke(cli, ["plot", str(out), "-o", str(tmp_path / "plan.png")])
    assert result.exit_code == 0, result.output
    assert (tmp_path / "plan.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize("override, message", [
    ("method.criteria.zghal.k_hi=-1", r"zghal.k_hi' = -1 must be ≥ 0"),
    ("method.criteria.joint_manipulability.k_lo=-0.1", r"k_lo' = -0.1 must be ≥ 0"),
    ("method.criteria.zghal.k_lo=2", "exceeds k_hi"),
    ("method.criteria.zghal.H_hi=10", "must exceed H_lo"),
    ("method.criteria.volume.k_hi=1", r"unknown field\(s\) volume"),
    ("method.band=0.5", "method.band"),
    ("method.band=0", "method.band"),
    ("method.t_rmax=-5", "method.t_rmax"),
    ("method.name=magic", "method.name"),
    ("method.ramp_time=30", "ramp_time"),
    ("damping.epsilon=0", "damping.epsilon"),
    ("tracking.pos_tol=-1", "tracking.pos_tol"),
])
def test_bad_input_is_a_clear_error(override, message):
    task, _ = load_task(EXAMPLES / "modular8_wgpm_demo.toml")
    apply_overrides(task, [override])
    with pytest.raises(TaskFileError, match=message):
        configure_task(task, "demo")


def test_configure_gives_si_values_and_defaults_whatever_the_units():
    """The demo's deg and mm converted (1 deg = π/180 rad, 1 mm = 1e-3 m), a criterion the file
    leaves out is off, and the unit-dependent defaults are SI: t_rmax 10 deg/s, tracking 1 mm and
    1 deg, not 10 and 1 in the file's units; the task is configured on the robot given."""
    robot = load_robot("modular8")
    task, _ = load_task(EXAMPLES / "modular8_wgpm_demo.toml")
    config = configure_task(task, "demo", robot=robot).config
    assert config.robot is robot
    assert config.method.t_rmax == pytest.approx(20 * math.pi / 180, rel=1e-15)
    zghal, manipulability = config.method.criteria[2], config.method.criteria[0]  # WGPM_CRITERIA's order
    assert (zghal.k_hi, zghal.k_lo, zghal.H_lo, zghal.H_hi) == (0.5, 0.05, 32.0, 100.0)
    assert manipulability.k_hi == manipulability.k_lo == 0.0
    del task["method"]["t_rmax"], task["tracking"]
    config = configure_task(task, "demo", robot=robot).config
    assert config.method.t_rmax == pytest.approx(10 * math.pi / 180, rel=1e-15)
    assert config.pos_tol == pytest.approx(1e-3, rel=1e-15) and config.ori_tol == pytest.approx(math.pi / 180, rel=1e-15)


def test_plan_carries_the_method_it_ran():
    task = parsed("modular8_wgpm_demo", "timing.duration=6", "method.ramp_time=1")
    result = WgpmPlanner(task).run(replace(task.method, name="pinv"))
    assert result.config.method.name == "pinv" and result.config.path.step == task.path.step
    assert result.metadata["method"] == "pinv"
