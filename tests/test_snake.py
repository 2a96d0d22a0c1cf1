"""Snake-arm tip following (spec 50): the bundled robot and its generated C, the path spline,
the velocity law, both solvers on both bundled scenarios against the bars, angle recovery,
clearance, the CLI, and bad input."""

from __future__ import annotations

import copy
import math
import subprocess
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from armgen.codegen.generate import generate_robot
from armgen.codegen.toolchain import STRICT_FLAGS
from armgen.errors import PlanningError, TaskFileError
from armgen.planning.snake import arm as sn_arm, config as sn_config, spline as sn_spline
from armgen.planning.snake import planner as sn
from armgen.planning.result import read_plan
from armgen.planning.snake.dynamics import BarModel, DenoisedDynamics
from armgen.planning.snake.exact import joint_rates, solve_exact
from armgen.planning.snake.obstacles import Obstacle, segment_distance
from armgen.planning.snake.spline import HermiteSpline
from armgen.planning.tasks import configure_task, load_task, run_task
from armgen.robot import load_robot
from armgen.symbolic.model import ModelOptions, SymbolicModel

from conftest import require_tool

REPO_GENERATED_DIR = Path(__file__).resolve().parent.parent / "generated"  # the checked-in code

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
PLANAR, TANK = EXAMPLES / "snake_planar.toml", EXAMPLES / "snake_tank.toml"

# The bars.
EXACT_CHORD_BAR_MM = 1e-9
EXACT_TIP_BAR_MM = 1e-6
DENOISED_TIP_BAR_MM = 0.02
# Rounding level of a position of ~2 m: a few ulps (m).
ROUNDING_M = 1e-14


def spec_planar_waypoints() -> np.ndarray:
    """The planar path exactly as spec 50 describes it (mm)."""
    pts = [(x, 0.0) for x in range(-1248, 1, 52)]
    pts += [(x, 0.0) for x in range(25, 151, 25)]
    pts += [(150 + 100 * math.cos(math.radians(a)), 100 + 100 * math.sin(math.radians(a))) for a in range(-75, 1, 15)]
    pts += [(250.0, y) for y in range(125, 201, 25)]
    pts += [(350 + 100 * math.cos(math.radians(a)), 200 + 100 * math.sin(math.radians(a))) for a in range(165, 89, -15)]
    pts += [(x, 300.0) for x in range(400, 1001, 50)]
    return np.array([(x, y, 0.0) for x, y in pts])


def spec_tank_waypoints() -> np.ndarray:
    """The tank path exactly as spec 50 describes it (mm)."""
    openings = [(0, 200, 100), (300, 280, 70), (600, 360, 130), (900, 300, 90)]

    def centre(x: float) -> tuple[float, float]:
        for k, (xo, y, z) in enumerate(openings):
            if abs(x - xo) <= 20 or (k == len(openings) - 1 and x >= xo):
                return y, z
        for (xa, ya, za), (xb, yb, zb) in zip(openings, openings[1:]):
            if xa + 20 < x < xb - 20:
                u = (x - (xa + 20)) / ((xb - 20) - (xa + 20))
                w = 10 * u ** 3 - 15 * u ** 4 + 6 * u ** 5
                return ya + (yb - ya) * w, za + (zb - za) * w
        raise AssertionError(x)

    pts = [(x, 200.0, 100.0) for x in range(-1248, 1, 52)]
    pts += [(x, *centre(x)) for x in list(range(20, 1141, 20)) + [1150]]
    return np.array(pts, dtype=float)


@pytest.fixture(scope="module")
def tasks():
    return {name: load_task(path)[0] for name, path in (("planar", PLANAR), ("tank", TANK))}


def _plan(task: dict, **overrides):
    task = copy.deepcopy(task)
    for key, value in overrides.items():
        table, field = key.split("__")
        task.setdefault(table, {})[field] = value
    return run_task(task, "test.toml")


@pytest.fixture(scope="module")
def plans(tasks):
    """Both solvers on both scenarios (each plan ~0.2–0.8 s)."""
    return {(name, method): _plan(tasks[name], solver__method=method)
            for name in ("planar", "tank") for method in ("exact", "denoised")}


# -- the robot and its C ---------------------------------------------------------------------
def test_snake12_robot_file():
    robot = load_robot("snake12")
    assert robot.n == 25 and not robot.joints[0].revolute
    arm = sn_arm.snake_arm(robot, "t")  # the DH table is the universal-joint chain (checked inside)
    assert arm.n_links == 12 and arm.link == pytest.approx(0.104) and arm.max_feed == pytest.approx(1.248)
    np.testing.assert_allclose(arm.rail_dir, [1, 0, 0], atol=1e-15)
    np.testing.assert_allclose(arm.A0, np.eye(3), atol=1e-15)
    np.testing.assert_allclose(np.degrees(arm.qmax), 60.0)
    fk = SymbolicModel(robot, ModelOptions(("fk",))).function("fk")
    np.testing.assert_allclose(np.array(fk(robot.configuration("q0")))[:3, 3], [1.248, 0, 0], atol=1e-15)


def test_checked_in_snake12_code_is_fresh(tmp_path):
    """Regenerate into a temp dir: byte-identical to generated/snake12/ (update with `armgen gen snake12`)."""
    _, paths = generate_robot("snake12", tmp_path)
    assert {p.name for p in paths} == {"snake12.h", "snake12.c", "manifest.json"}
    for path in paths:
        checked_in = REPO_GENERATED_DIR / "snake12" / path.name
        assert checked_in.is_file(), f"{checked_in} missing: run `armgen gen snake12`"
        assert checked_in.read_bytes() == path.read_bytes(), f"{checked_in} is stale: run `armgen gen snake12`"


def test_snake12_code_compiles_strict_in_both_precisions(tmp_path):
    cc = require_tool("gcc")
    src = REPO_GENERATED_DIR / "snake12" / "snake12.c"

    def build(flag: int) -> subprocess.CompletedProcess:
        return subprocess.run([cc, *STRICT_FLAGS, "-O2", f"-DSNAKE12_USE_FLOAT={flag}", "-c", str(src),
                               "-o", str(tmp_path / f"s{flag}.o")], capture_output=True, text=True)

    with ThreadPoolExecutor(2) as pool:  # ~4 s each at -O2
        results = list(pool.map(build, (0, 1)))
    for flag, proc in zip((0, 1), results):
        assert proc.returncode == 0, f"USE_FLOAT={flag}:\n{proc.stderr}"
    undefined = subprocess.run(["nm", "-u", str(tmp_path / "s1.o")], capture_output=True, text=True).stdout
    assert "sqrtf" in undefined and " sqrt\n" not in undefined  # float build is single precision


# -- the spline ------------------------------------------------------------------------------
def _one_sided(spline: HermiteSpline, k: int, side: int) -> list[np.ndarray]:
    """r, r_s, r_ss at knot k from segment k−1 (side −1) or k (side +1), exactly at the knot."""
    seg = k - 1 if side < 0 else k
    tau = spline.chords[seg] if side < 0 else 0.0
    c1, c2, c3 = spline.c1[seg], spline.c2[seg], spline.c3[seg]
    return [spline.c0[seg] + tau * (c1 + tau * (c2 + tau * c3)), c1 + tau * (2 * c2 + 3 * tau * c3), 2 * c2 + 6 * tau * c3]


def _max_jumps(spline: HermiteSpline) -> np.ndarray:
    jumps = np.zeros(3)
    for k in range(1, len(spline.knots) - 1):
        left, right = _one_sided(spline, k, -1), _one_sided(spline, k, +1)
        jumps = np.maximum(jumps, [np.max(np.abs(a - b)) for a, b in zip(left, right)])
    return jumps


@pytest.mark.parametrize("waypoints", [spec_planar_waypoints, spec_tank_waypoints])
def test_spline_interpolates_and_is_c2_on_the_bundled_paths(waypoints):
    P = waypoints() * 1e-3
    spline = HermiteSpline(P, [1, 0, 0], [1, 0, 0])
    np.testing.assert_allclose(spline.position(spline.knots), P, atol=ROUNDING_M)
    r_max = np.max(np.abs(spline.evaluate(np.linspace(0, spline.length, 5000))[2]))
    jumps = _max_jumps(spline)
    assert jumps[0] < ROUNDING_M and jumps[1] < 1e-12 and jumps[2] < 1e-10 * r_max, jumps
    np.testing.assert_allclose(spline.evaluate(np.array([0.0, spline.length]))[1], [[1, 0, 0], [1, 0, 0]], atol=1e-15)


@settings(max_examples=60, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(st.floats(0.02, 0.3), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0)), min_size=2, max_size=12),
       st.booleans())
def test_spline_c2_with_uneven_knots(steps, natural):
    """Random chord lengths (ratios up to 15): interpolation, C², end conditions, derivatives."""
    points = [np.zeros(3)]
    for length, turn, climb in steps:
        d = np.array([math.cos(turn) * math.cos(climb), math.sin(turn) * math.cos(climb), math.sin(climb)])
        points.append(points[-1] + length * d)
    P = np.array(points)
    spline = HermiteSpline(P, None if natural else [1, 0, 0], None if natural else [0, 1, 0])
    np.testing.assert_allclose(spline.position(spline.knots), P, atol=1e-14)
    scale = max(1.0, np.max(np.abs(spline.evaluate(spline.knots)[2])))
    jumps = _max_jumps(spline)
    assert jumps[0] < 1e-14 and jumps[1] < 1e-11 * scale and jumps[2] < 1e-9 * scale, jumps
    ends = spline.evaluate(np.array([0.0, spline.length]))
    if natural:
        np.testing.assert_allclose(ends[2], 0.0, atol=1e-10 * scale)
    else:
        np.testing.assert_allclose(ends[1], [[1, 0, 0], [0, 1, 0]], atol=1e-14)
    # r_s and r_ss are the derivatives of r (central differences inside the segments)
    s = spline.knots[:-1] + 0.37 * spline.chords
    e = 1e-6
    r_s, r_ss = spline.evaluate(s)[1:]
    fd1 = (spline.position(s + e) - spline.position(s - e)) / (2 * e)
    fd2 = (spline.evaluate(s + e)[1] - spline.evaluate(s - e)[1]) / (2 * e)
    np.testing.assert_allclose(fd1, r_s, atol=1e-7 * scale)
    np.testing.assert_allclose(fd2, r_ss, atol=1e-5 * scale)


def test_spline_misprint_would_break_c2():
    """With the paper's printed coefficient 3 (instead of 3K²) of r_{i+1}, r'' jumps at the knots."""
    P = np.array([[0, 0, 0], [0.1, 0.02, 0], [0.35, 0.0, 0], [0.4, 0.1, 0], [0.7, 0.1, 0.05]])
    good = HermiteSpline(P, [1, 0, 0], [1, 0, 0])
    L = good.chords
    m = len(L)
    A = np.zeros((m + 1, m + 1))
    rhs = np.zeros((m + 1, 3))
    A[0, 0] = A[m, m] = 1.0
    rhs[0], rhs[m] = [1, 0, 0], [1, 0, 0]
    for i in range(1, m):
        K = L[i - 1] / L[i]
        A[i, i - 1:i + 2] = [L[i - 1], 2 * L[i - 1] * (1 + K), L[i - 1] * K]
        rhs[i] = -3 * P[i - 1] + 3 * (1 - K * K) * P[i] + 3 * P[i + 1]  # the misprint
    d = np.linalg.solve(A, rhs)
    slope = np.diff(P, axis=0) / L[:, None]
    bad = copy.copy(good)  # same knots and points, the misprinted tangents' Hermite coefficients
    bad.c1 = d[:-1]
    bad.c2 = (3 * slope - 2 * d[:-1] - d[1:]) / L[:, None]
    bad.c3 = (d[:-1] + d[1:] - 2 * slope) / (L * L)[:, None]
    assert _max_jumps(good)[2] < 1e-12
    assert _max_jumps(bad)[2] > 1.0


# -- the velocity law ------------------------------------------------------------------------
def test_velocity_law_is_the_papers():
    v = 0.12
    law = sn_config.VelocityLaw(v, 10.0, 1.0)
    t = np.linspace(0, 10, 100_001)
    _, sd, sdd = law(t)
    paper = np.where(t <= 1, 0.5 * v * (1 + np.sin((t + 1.5) * np.pi)),
                     np.where(t <= 9, v, 0.5 * v * (1 + np.sin((t - 8.5) * np.pi))))
    np.testing.assert_allclose(sd, paper, atol=1e-15)
    s, _, _ = law(np.array([10.0, 12.0]))
    assert s[0] == pytest.approx(9 * v, abs=1e-15) and law.travel == pytest.approx(1.08) and s[1] == s[0]
    mid = 0.5 * (t[1:] + t[:-1])
    np.testing.assert_allclose(np.diff(law(t)[0]) / np.diff(t), law(mid)[1], atol=1e-9)
    np.testing.assert_allclose(np.diff(sd) / np.diff(t), law(mid)[2], atol=2e-6)
    for tk in (0.3, 1.0, 5.0, 9.0, 9.7, 10.0):
        np.testing.assert_allclose(law.scalar(tk), [x.item() for x in law(np.array(tk))], atol=1e-15)


# -- the solvers against the bars ------------------------------------------------------------
@pytest.mark.parametrize("scenario", ["planar", "tank"])
def test_exact_solver_bars(plans, scenario):
    result = plans[scenario, "exact"]
    summary = result.metadata["summary"]
    assert summary["max_chord_error_mm"] <= EXACT_CHORD_BAR_MM
    assert summary["max_tip_deviation_mm"] <= EXACT_TIP_BAR_MM
    assert summary["max_tip_to_planned_point_mm"] <= EXACT_TIP_BAR_MM
    assert summary["max_joint_centre_fk_error_mm"] <= EXACT_TIP_BAR_MM
    assert summary["fk_cross_check"]["max_tip_diff_m"] < 1e-12  # generated fk == numpy chain
    assert summary["feed_range_mm"][0] == pytest.approx(0.0, abs=1e-9)
    # the driven joint follows the law: 1080 mm of travel
    driven = result.column("feed_m") if scenario == "planar" else result.column("sJ13_m")
    assert driven[-1] - driven[0] == pytest.approx(1.08, abs=1e-12)
    assert summary["solver_and_recovery_time_s"] < 2.0  # the 0.1 s bar is benchmarks/bench_snake.py's


@pytest.mark.parametrize("scenario", ["planar", "tank"])
def test_denoised_solver_bars(plans, scenario):
    summary = plans[scenario, "denoised"].metadata["summary"]
    assert summary["max_tip_deviation_mm"] <= DENOISED_TIP_BAR_MM
    assert summary["max_chord_error_mm"] <= DENOISED_TIP_BAR_MM
    assert summary["integrator"]["explicit"] and summary["integrator"]["completed"]
    # it tracks the exact solution from the same driven coordinate
    assert summary["vs_exact"]["max_coordinate_diff_mm"] <= DENOISED_TIP_BAR_MM
    exact = plans[scenario, "exact"]
    angles = [c for c in exact.columns if c[0] in "ab" and c.endswith("_rad")]
    diff = max(np.max(np.abs(plans[scenario, "denoised"].column(c) - exact.column(c))) for c in angles)
    assert math.degrees(diff) < 0.01


def test_scenario_geometry(plans):
    planar = plans["planar", "exact"].metadata["summary"]
    tank = plans["tank", "exact"].metadata["summary"]
    assert 57.0 < planar["max_abs_joint_angle_deg"] < 60.0  # the 100 mm arcs need 57.3° (limit 60°)
    assert max(tank["max_abs_beta_deg"]) > 10.0  # the tank path is spatial
    assert planar["min_clearance_mm"]["wall"] == pytest.approx(20.0, abs=0.1)  # 80 mm gap, 40 mm tube
    assert planar["min_clearance_mm"]["disc"] > 50.0
    assert min(tank["min_clearance_mm"][k] for k in tank["min_clearance_mm"] if k != "tank shell") > 25.0
    assert tank["min_clearance_mm"]["tank shell"] == pytest.approx(50.0, abs=0.01)  # z = 70 − 20 mm tube
    assert tank["max_tip_speed_mm_s"] == pytest.approx(120.0, rel=2e-3)  # the tip is driven (|r_s| ≈ 1)
    assert planar["max_base_speed_mm_s"] == pytest.approx(120.0, abs=1e-9)


def test_examples_state_the_spec_waypoints(tasks):
    for name, expected in (("planar", spec_planar_waypoints()), ("tank", spec_tank_waypoints())):
        got = np.array(tasks[name]["path"]["waypoints"], dtype=float)
        assert got.shape == expected.shape == ((60, 3) if name == "planar" else (83, 3))
        np.testing.assert_allclose(got, expected, atol=1e-9)


def test_stiff_model_needs_an_implicit_solver(tasks):
    """h = 0 with the explicit solver crawls (steps ~1e-6 s for the ~4e5 rad/s axial mode): capped."""
    task = copy.deepcopy(tasks["planar"])
    task["solver"].update(method="denoised", h=0.0, integrator="RK45", max_wall_time=0.5)
    with pytest.raises(PlanningError, match=r"stiff integration \(RK45, h = 0.0 s\) reached t = .*wall-clock cap"):
        run_task(task, "stiff.toml")


def test_exact_solver_is_deterministic_and_exact_on_a_random_path():
    """Chords on a winding spatial spline, both follow directions, against an independent bisection."""
    rng = np.random.default_rng(20261122)
    pts = [np.array([x, 0.0, 0.0]) for x in np.arange(0.0, 1.3, 0.05)]
    for _ in range(30):
        pts.append(pts[-1] + np.array([0.05, *rng.uniform(-0.01, 0.01, 2)]))
    P = np.array(pts)
    spline = HermiteSpline(P, [1, 0, 0], None)
    track = sn_spline.Track(spline, P[0], [1, 0, 0], 1.3)
    s = solve_exact(track, np.array([0.0, 0.2, 0.4]), "base", 12, 0.104)
    x = track.joints(s, 0)[0]
    assert np.max(np.abs(np.linalg.norm(np.diff(x, axis=1), axis=2) - 0.104)) < 1e-15
    back = solve_exact(track, s[:, -1], "tip", 12, 0.104)
    np.testing.assert_allclose(back, s, atol=1e-13)
    # independent check of one follower by plain bisection
    p0 = x[2, 5]
    lo, hi = s[2, 5] + 0.05, s[2, 5] + 0.2
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if np.linalg.norm(spline.position(mid) - p0) < 0.104 else (lo, mid)
    assert s[2, 6] == pytest.approx(lo, abs=1e-14)


# -- angle recovery --------------------------------------------------------------------------
@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.lists(st.floats(-1.0, 1.0), min_size=24, max_size=24), st.floats(0.0, 1.2))
def test_angle_recovery_round_trip(unit_angles, feed):
    """angles → FK (the robot's DH chain) → joint centres → angles, within ±60° per axis."""
    arm = sn_arm.snake_arm(load_robot("snake12"), "t")
    a = np.radians(60.0) * np.array(unit_angles)
    alpha, beta = a[0::2][None, :], a[1::2][None, :]
    q = arm.q_vector(np.array([feed]), alpha, beta)
    centres = arm.joint_centres(q)[0] + np.array([-1.248, 0.2, 0.1])
    f2, a2, b2 = sn_arm.recover_angles(arm, centres, np.array([-1.248, 0.2, 0.1]))
    assert f2[0] == pytest.approx(feed, abs=1e-12)
    np.testing.assert_allclose(a2, alpha, atol=1e-12)
    np.testing.assert_allclose(b2, beta, atol=1e-12)


def test_paper_angle_formula_loses_the_sign(plans):
    """The paper's arccos form recovers |α|: its arm leaves the planar path by decimetres."""
    result = plans["planar", "exact"]
    arm = sn_arm.snake_arm(load_robot("snake12"), "t")
    q = np.column_stack([result.column("feed_m")] + [result.column(c) for c in result.columns
                                                     if c[0] in "ab" and c.endswith("_rad")])
    rail = np.array(result.metadata["rail"]["start_m"])
    centres = arm.joint_centres(q)[0] + rail - arm.base0
    feed, alpha, beta = sn_arm.recover_angles_paper(arm, centres, rail)
    tip = arm.joint_centres(arm.q_vector(feed, alpha, beta))[0][:, -1] + rail - arm.base0
    assert np.max(np.linalg.norm(tip - centres[:, -1], axis=1)) > 0.1
    feed, alpha, beta = sn_arm.recover_angles(arm, centres, rail)
    tip = arm.joint_centres(arm.q_vector(feed, alpha, beta))[0][:, -1] + rail - arm.base0
    assert np.max(np.linalg.norm(tip - centres[:, -1], axis=1)) < 1e-14


# -- clearance -------------------------------------------------------------------------------
def test_clearance_against_dense_sampling():
    rng = np.random.default_rng(7)
    A = rng.uniform(-0.2, 0.2, (200, 3))
    B = A + rng.normal(0, 0.06, (200, 3))
    taus = np.linspace(0, 1, 20001)[:, None, None]
    pts = A[None] + taus * (B - A)[None]
    plate = Obstacle("p", "plate", np.array([0.0, 0.01, -0.02]), np.array([1.0, 0, 0]), 0.05)
    box = Obstacle("b", "box", np.array([0.0, 0.05, -1.0]), np.array([0.02, 1.0, 1.0]))
    cyl = Obstacle("c", "cylinder", np.array([0.05, 0.0, 0.0]), np.array([0.0, 0, 1.0]), 0.08)
    d = pts - plate.a
    h = d[..., 0]
    radial = np.hypot(d[..., 1], d[..., 2])
    brute = {"p": np.where(radial >= 0.05, np.abs(h), np.hypot(h, 0.05 - radial)).min(axis=0),
             "b": np.linalg.norm(np.maximum(np.maximum(box.a - pts, 0), pts - box.b), axis=-1).min(axis=0),
             "c": np.maximum(np.hypot(pts[..., 0] - 0.05, pts[..., 1]) - 0.08, 0).min(axis=0)}
    for ob in (plate, box, cyl):
        got = segment_distance(ob, A, B)
        # never above a sampled point's distance, and below it by at most half a sample spacing
        # (the brute force misses exact contact points: 20 000 samples of segments up to ~0.3 m)
        assert np.all(got <= brute[ob.name] + 1e-12)
        np.testing.assert_allclose(got, brute[ob.name], atol=1e-5 * np.linalg.norm(B - A, axis=1).max())
        far = brute[ob.name] > 1e-3  # away from contact the minimum is smooth: sampling error O(spacing²)
        np.testing.assert_allclose(got[far], brute[ob.name][far], atol=1e-9)


def test_clearance_through_the_opening_centre():
    plate = Obstacle("p", "plate", np.array([0.3, 0.28, 0.07]), np.array([1.0, 0, 0]), 0.05)
    A, B = np.array([[0.25, 0.28, 0.07]]), np.array([[0.354, 0.28, 0.07]])
    assert segment_distance(plate, A, B)[0] == pytest.approx(0.05, abs=1e-12)
    tank = Obstacle("t", "tank", np.zeros(3), np.array([1.2, 0.8, 0.2]), faces=("z-", "y+"))
    # outside the tank (on the rail) nothing counts; inside, the part past x = 0 counts (z: 0.05 → 0.03)
    assert segment_distance(tank, np.array([[-0.5, 0.2, 0.01]]), np.array([[-0.4, 0.2, 0.01]]))[0] == np.inf
    assert segment_distance(tank, np.array([[-0.05, 0.2, 0.07]]), np.array([[0.05, 0.2, 0.03]]))[0] == pytest.approx(0.03)


# -- the command line ------------------------------------------------------------------------
def test_cli_plan_and_plot(tmp_path):
    from click.testing import CliRunner

    from armgen.cli.main import cli

    runner = CliRunner()
    csv = tmp_path / "tank.csv"
    out = runner.invoke(cli, ["plan", str(TANK), "-o", str(csv), "--units", "deg"])
    assert out.exit_code == 0, out.output
    plan = read_plan(csv)
    assert plan.data.shape[0] == 1001 and plan.column("t_s")[-1] == pytest.approx(10.0)
    for col in ("feed_m", "a1_rad", "b12_rad", "sJ1_m", "sJ13_m", "tip_x_m", "tip_dev_m", "chord_err_max_m",
                "clearance_min_m", "base_speed_m_s", "tip_speed_m_s"):
        assert col in plan.columns
    assert plan.metadata["planner"] == "snake" and plan.metadata["path"]["waypoints"] == 83
    png = tmp_path / "tank.png"
    out = runner.invoke(cli, ["plot", str(csv), "-o", str(png)])
    assert out.exit_code == 0, out.output
    assert png.stat().st_size > 50_000


def test_c_backend_fk_cross_check(tasks):
    """FK on the recovered angles through the compiled generated C (double)."""
    require_tool("gcc")
    result = run_task(copy.deepcopy(tasks["planar"]), "planar.toml", backend="c")
    check = result.metadata["summary"]["fk_cross_check"]
    assert check["backend"] == "c" and check["max_tip_diff_m"] < 1e-12


# -- bad input -------------------------------------------------------------------------------
def _with_waypoints(task: dict, waypoints) -> dict:
    task = copy.deepcopy(task)
    task["path"]["waypoints"] = [list(map(float, p)) for p in waypoints]
    return task


def test_duplicate_and_too_close_waypoints(tasks):
    wp = spec_planar_waypoints()
    dup = np.insert(wp, 40, wp[39], axis=0)
    with pytest.raises(TaskFileError, match=r"'path.waypoints\[40\]' = .* duplicates path.waypoints\[39\]"):
        run_task(_with_waypoints(tasks["planar"], dup), "t.toml")
    close = np.insert(wp, 40, wp[39] + [0.0, 0.5, 0.0], axis=0)
    with pytest.raises(TaskFileError, match=r"waypoints\[40\]' .* is only 0.5 mm from .* at least 1 mm apart"):
        run_task(_with_waypoints(tasks["planar"], close), "t.toml")
    loop = np.vstack([wp, wp[45:46] + [0.0, 0.0, 0.0]])  # a path returning onto an earlier waypoint
    with pytest.raises(TaskFileError, match=r"waypoints\[60\]' .* duplicates path.waypoints\[45\]"):
        run_task(_with_waypoints(tasks["planar"], loop), "t.toml")


def test_path_shorter_than_the_arm(tasks):
    wp = [[-1248 + 100 * k, 0, 0] for k in range(12)]  # 1100 mm
    with pytest.raises(TaskFileError, match=r"path of 1100.0 mm, shorter than the arm \(12 links × 104 mm = 1248 mm\)"):
        run_task(_with_waypoints(tasks["planar"], wp), "t.toml")


def test_path_too_short_for_the_travel(tasks):
    wp = spec_planar_waypoints()[:55]  # ends at x = 750 mm: 2212 mm of path, the tip needs ~2340 mm
    with pytest.raises(PlanningError, match=r"t.toml: joint 1\d has no place on the path at sample \d+: no point of the "
                                            r"path beyond the path's end .* too short for the arm plus its travel"):
        run_task(_with_waypoints(tasks["planar"], wp), "t.toml")


@pytest.mark.parametrize("scenario", ["planar", "tank"])
def test_feed_beyond_the_rail(tasks, scenario):
    task = copy.deepcopy(tasks[scenario])
    task["motion"]["v"] = 150  # travel 1350 mm > 1248 mm
    if scenario == "tank":  # the tip must stay on the path: extend it beyond the tank
        task["path"]["waypoints"] += [[x, 300.0, 90.0] for x in range(1200, 1601, 50)]
    with pytest.raises(PlanningError, match=r"the base would feed 13\d\d.\d mm .* beyond the rail's 1248 mm .* "
                                            r"lower motion.v or motion.duration"):
        run_task(task, "t.toml")


def test_tip_past_the_path_end(tasks):
    task = copy.deepcopy(tasks["tank"])
    task["motion"]["v"] = 150
    with pytest.raises(PlanningError, match=r"the tip would travel to path s = 2598.0 mm, past the path's end"):
        run_task(task, "t.toml")


def _one_bend_path(radius: float) -> np.ndarray:
    """Rail, straight to x = 150, a left 90° arc of ``radius``, then straight up (mm)."""
    pts = [(x, 0.0) for x in range(-1248, 1, 52)] + [(x, 0.0) for x in range(25, 151, 25)]
    pts += [(150 + radius * math.cos(math.radians(a)), radius + radius * math.sin(math.radians(a)))
            for a in range(-75, 1, 15)]
    pts += [(150 + radius, radius + 25.0 * k) for k in range(1, 45)]
    return np.array([(x, y, 0.0) for x, y in pts])


def test_bend_beyond_the_universal_joints(tasks):
    """A 70 mm radius bend: a 104 mm chord turns by 2 asin(52/70) = 96° there (limit ±60°);
    the same path with a 100 mm radius passes."""
    run_task(_with_waypoints(tasks["planar"], _one_bend_path(100.0)), "t.toml")
    with pytest.raises(PlanningError, match=r"bends more than universal joint \d+ can: α\d+ .* outside \[-60°, 60°\], "
                                            r"at path s = .* near path.waypoints\[\d+\] .* widen that bend"):
        run_task(_with_waypoints(tasks["planar"], _one_bend_path(70.0)), "t.toml")


def test_rail_and_field_errors(tasks):
    task = copy.deepcopy(tasks["planar"])
    task["rail"]["start"] = [-1200, 0, 0]
    with pytest.raises(TaskFileError, match=r"'path.waypoints\[0\]' .* is not the rail start"):
        run_task(task, "t.toml")
    wp = spec_planar_waypoints()
    bent = wp.copy()
    bent[10:25, 1] = np.linspace(0, 30, 15)  # the path leaves the rail line within the base's travel
    with pytest.raises(TaskFileError, match=r"leaves the rail line by .* mm within the base's travel"):
        run_task(_with_waypoints(tasks["planar"], bent), "t.toml")
    for edit, message in (
            (("solver", "method", "magic"), r"'solver.method' = 'magic' is not one of exact, denoised"),
            (("motion", "driven", "middle"), r"'motion.driven' = 'middle' is not one of base, tip"),
            (("motion", "v", -5), r"'motion.v' = -5 must be > 0"),
            (("motion", "output_step", 0.003), r"'motion.output_step' = 0.003 s must divide"),
            (("motion", "ramp", 6), r"two ramps do not fit"),
            (("solver", "integrator", "Euler"), r"'solver.integrator' = 'Euler' is not one of"),
            (("path", "color", "red"), r"'path' has unknown field\(s\) color")):
        bad = copy.deepcopy(tasks["planar"])
        bad[edit[0]][edit[1]] = edit[2]
        with pytest.raises(TaskFileError, match=message):
            run_task(bad, "t.toml")
    bad = copy.deepcopy(tasks["planar"])
    bad["robot"] = "modular8"
    with pytest.raises(TaskFileError, match=r"'robot' = 'modular8' is not a snake arm"):
        run_task(bad, "t.toml")


@pytest.mark.parametrize("index, edit, message", [
    (0, {"diameter": 3}, r"'obstacles\[0\].diameter' is not a field of a box \(it takes min, max\); remove it"),
    (0, {"min": None}, r"'obstacles\[0\].min' is missing; a box takes min and max"),
    (0, {"min": [60, 40, -1000]}, r"'obstacles\[0\]' needs min < max in every coordinate"),
    (2, {"axis": [0, 0, 0]}, r"'obstacles\[2\].axis' is the zero vector; give a direction such as \[1, 0, 0\]$"),
    (2, {"normal": [1, 0, 0]}, r"'obstacles\[2\].normal' is not a field of a cylinder"),
])
def test_obstacle_fields_follow_their_type(tasks, index, edit, message):
    """Each obstacle type takes its own fields (docs/snake.md): a missing one, one of another type
    (which the old reader ignored), a zero axis or an empty box is bad input naming the field."""
    task = copy.deepcopy(tasks["planar"])
    for key, value in edit.items():
        if value is None:
            task["obstacles"][index].pop(key)
        else:
            task["obstacles"][index][key] = value
    with pytest.raises(TaskFileError, match=message):
        configure_task(task, "t.toml")


def test_configure_makes_the_typed_si_task_the_plan_carries(tasks, plans):
    """The validated file and the robot become a frozen SnakeTask in SI (no task dict in it); the
    tube's default diameter and wall are 40 mm and 2 mm whatever the file's length unit; the plan
    carries the task it was made from."""
    task = copy.deepcopy(tasks["planar"])  # mm
    del task["links"], task["path"]["start_tangent"]  # the start tangent defaults to the rail's direction, +x
    task["path"]["end_tangent"] = "natural"
    config = configure_task(task, "t.toml").config
    assert isinstance(config, sn_config.SnakeTask)
    with pytest.raises(AttributeError):
        config.h = 0.0
    assert (config.outer_diameter, config.wall, config.tube_radius) == (0.040, 0.002, 0.020)
    # the paper's tube: ρ π/4 (OD² − ID²) L with L = 104 mm, computed independently
    assert config.link_mass == pytest.approx(2700.0 * math.pi / 4 * (0.040 ** 2 - 0.036 ** 2) * 0.104, rel=1e-12)
    np.testing.assert_allclose(config.waypoints, np.array(tasks["planar"]["path"]["waypoints"]) * 1e-3, rtol=0, atol=0)
    assert config.start_tangent.tolist() == [1.0, 0.0, 0.0] and config.end_tangent is None
    assert config.integrator == "RK45" and isinstance(config.obstacles, tuple)
    assert not any(isinstance(getattr(config, f), dict) for f in config.__dataclass_fields__)
    assert isinstance(plans[("planar", "exact")].config, sn_config.SnakeTask)


def test_collision_is_reported(tasks):
    task = copy.deepcopy(tasks["planar"])
    task["obstacles"].append({"name": "post", "type": "cylinder", "centre": [250, 150, 0], "diameter": 20})
    with pytest.raises(PlanningError, match=r"link \d+ touches obstacle 'post' at t = .* move the waypoints away"):
        run_task(task, "t.toml")


def test_dynamics_right_hand_side_on_an_exact_state():
    """On an exact state (chords exact, rates consistent) the elastic force vanishes, M is symmetric
    positive definite on the free coordinates, and both state forms give the same accelerations."""
    task = configure_task(load_task(PLANAR)[0], "t").config
    track = sn.build_track(task)
    t = 4.2
    s_c, v_c, _ = task.law.scalar(t)
    s = solve_exact(track, np.array([s_c]), "base", 12, 0.104)[0]
    sdot = joint_rates(track, s[None], np.array([v_c]), "base")[0]
    dyn = DenoisedDynamics(track, BarModel(0.104, task.link_mass, 1e9, 0.1), 12, 0, task.law.scalar)
    M, C, F = dyn.accelerations(t, s, sdot)
    elastic = 1e9 * np.max(np.abs(np.linalg.norm(np.diff(track.joints(s, 0)[0], axis=0), axis=1) - 0.104)) / 0.104
    assert elastic < 1e-4  # N: chords exact to ~1e-16 m
    assert np.allclose(M, M.T) and np.all(np.linalg.eigvalsh(M[1:, 1:]) > 0)
    dyn.state = "link"
    y_link = dyn.rhs(t, dyn.to_state(s, sdot))
    dyn.state = "absolute"
    y_abs = dyn.rhs(t, dyn.to_state(s, sdot))
    full = np.concatenate([[task.law.scalar(t)[2]], y_abs[12:]])
    np.testing.assert_allclose(y_link[12:], np.diff(full), rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(y_link[:12], np.diff(sdot), atol=1e-15)
