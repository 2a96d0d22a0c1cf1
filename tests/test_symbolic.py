"""The CasADi core against independent references: the spec's FK pin, closed forms,
a SymPy derivation, NumPy linear algebra and central finite differences."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from armgen.robot import load_robot, matrix_rpy
from armgen.symbolic.model import SymbolicModel
from armgen.symbolic.sympy_reference import (
    planar3_closed_form, sympy_fk_jacobian, zghal_closed_form, zghal_gradient_closed_form)

# Central differences with step 1e-6 have truncation error ~h² f''' ≈ 1e-12 and rounding
# error ~eps/h ≈ 1e-10 on O(1) values: 1e-7 leaves a margin for the larger gradients.
FD_STEP = 1e-6
FD_TOL = 1e-7
# Two derivations of the same double-precision expression differ by rounding only.
CROSS_CHECK_TOL = 1e-12
# The spec prints the modular8 pose to 3 decimals (mm) and 2 decimals (deg).
SPEC_MM_TOL = 5e-4
SPEC_DEG_TOL = 5e-3


def model(name):
    return SymbolicModel(load_robot(name))


def interior_samples(robot, count, seed, margin=0.05):
    rng = np.random.default_rng(seed)
    span = robot.qmax - robot.qmin
    return rng.uniform(robot.qmin + margin * span, robot.qmax - margin * span, size=(count, robot.n))


def central_difference(fun, q, h=FD_STEP):
    base = np.atleast_1d(np.asarray(fun(q), dtype=float)).ravel()
    out = np.zeros((base.size, q.size))
    for k in range(q.size):
        e = np.zeros_like(q)
        e[k] = h
        out[:, k] = (np.ravel(fun(q + e)) - np.ravel(fun(q - e))) / (2 * h)
    return out


def test_modular8_fk_matches_spec_pose():
    m = model("modular8")
    T = np.array(m.function("fk")(m.robot.configuration("q0")))
    np.testing.assert_allclose(T[:3, 3] * 1e3, [-510.529, 424.136, 864.082], atol=SPEC_MM_TOL)
    np.testing.assert_allclose(np.degrees(matrix_rpy(T[:3, :3])), [-88.14, 11.69, 1.56], atol=SPEC_DEG_TOL)


def test_panda_and_iiwa_zero_pose_closed_form():
    # Panda at q = 0 (outside its q4 limit, but the FK is defined): flange at
    # x = 82.5 − 82.5 + 88 mm, z = 333 + 316 + 384 − 107 mm, pointing down.
    T = np.array(model("panda").function("fk")(np.zeros(7)))
    np.testing.assert_allclose(T[:3, 3], [0.088, 0.0, 0.926], atol=1e-15)
    np.testing.assert_allclose(T[:3, 2], [0, 0, -1], atol=1e-15)
    # iiwa stretched up: 360 + 420 + 400 + 126 mm on the z axis.
    T = np.array(model("iiwa14").function("fk")(np.zeros(7)))
    np.testing.assert_allclose(T[:3, 3], [0, 0, 1.306], atol=1e-15)


def test_planar3_closed_form():
    m = model("planar3")
    lengths = tuple(j.a for j in m.robot.joints)
    for q in interior_samples(m.robot, 50, seed=3):
        T, J = (np.array(x) for x in m.function("fk_jacobian")(q))
        p, Jp = planar3_closed_form(q, lengths)
        np.testing.assert_allclose(T[:2, 3], p, atol=CROSS_CHECK_TOL)
        np.testing.assert_allclose(J[:2], Jp, atol=CROSS_CHECK_TOL)
        np.testing.assert_allclose(J[5], np.ones(3), atol=CROSS_CHECK_TOL)  # wz row
        assert math.isclose(math.atan2(T[1, 0], T[0, 0]), math.remainder(q.sum(), 2 * math.pi), abs_tol=1e-12)


@pytest.fixture(scope="module")
def sympy_models():
    return {}


@pytest.mark.parametrize("name", ["planar3", "iiwa14", "panda", "modular8"])
def test_fk_jacobian_match_sympy(name, sympy_models):
    m = model(name)
    fk_ref, jac_ref = sympy_fk_jacobian(m.robot)
    f = m.function("fk_jacobian")
    for q in interior_samples(m.robot, 20, seed=7):
        T, J = (np.array(x) for x in f(q))
        np.testing.assert_allclose(T, fk_ref(q), atol=CROSS_CHECK_TOL * 10)
        np.testing.assert_allclose(J, jac_ref(q), atol=CROSS_CHECK_TOL * 10)


@pytest.mark.parametrize("name", ["iiwa14", "panda", "modular8"])
def test_jacobian_matches_finite_differences_of_fk(name):
    m = model(name)
    fk = m.function("fk")
    jac = m.function("jacobian")
    for q in interior_samples(m.robot, 10, seed=11):
        J = np.array(jac(q))
        dp = central_difference(lambda x: np.array(fk(x))[:3, 3], q)
        np.testing.assert_allclose(J[:3], dp, atol=FD_TOL)
        R = np.array(fk(q))[:3, :3]
        for k in range(m.n):
            e = np.zeros(m.n)
            e[k] = FD_STEP
            dR = (np.array(fk(q + e))[:3, :3] - np.array(fk(q - e))[:3, :3]) / (2 * FD_STEP)
            W = dR @ R.T
            np.testing.assert_allclose(J[3:, k], [W[2, 1], W[0, 2], W[1, 0]], atol=FD_TOL)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.lists(st.floats(-2.4, 2.4), min_size=8, max_size=8), st.lists(st.floats(-1, 1), min_size=8, max_size=8))
def test_jacobian_maps_joint_rates_to_twist(q, qdot):
    """J q̇ = ẋ: the tool twist from a small joint motion equals J q̇ to first order."""
    m = model("modular8")
    q, qdot = np.array(q), np.array(qdot)
    fk = m.function("fk")
    h = 1e-6
    Tp, Tm = np.array(fk(q + h * qdot)), np.array(fk(q - h * qdot))
    v = (Tp[:3, 3] - Tm[:3, 3]) / (2 * h)
    W = (Tp[:3, :3] - Tm[:3, :3]) / (2 * h) @ np.array(fk(q))[:3, :3].T
    twist = np.concatenate([v, [W[2, 1], W[0, 2], W[1, 0]]])
    np.testing.assert_allclose(np.array(m.function("jacobian")(q)) @ qdot, twist, atol=1e-7)


def test_zghal_against_closed_form(robot):
    m = SymbolicModel(robot)
    f = m.function("zghal")
    for q in interior_samples(robot, 50, seed=5, margin=1e-4):
        h, g = f(q)
        assert float(h) == pytest.approx(zghal_closed_form(q, robot.qmin, robot.qmax), rel=1e-13)
        np.testing.assert_allclose(np.ravel(g), zghal_gradient_closed_form(q, robot.qmin, robot.qmax), rtol=1e-12)


def test_repetitive_gradient(robot):
    f = SymbolicModel(robot).function("repetitive")
    q, q0 = interior_samples(robot, 2, seed=6)
    h, g = f(q, q0)
    assert float(h) == pytest.approx(0.5 * np.sum((q - q0) ** 2), rel=1e-14)
    np.testing.assert_allclose(np.ravel(g), q - q0, rtol=1e-14)


@pytest.mark.parametrize("name", ["iiwa14", "panda", "modular8"])
def test_joint_manipulability_against_numpy(name):
    """ω_i² − δ² = det(J₋ᵢ J₋ᵢᵀ) by NumPy's LU determinant (a second implementation)."""
    m = model(name)
    f = m.function("joint_manipulability")
    fw = m.function("manipulability")
    jac = m.function("jacobian")
    delta = 1e-3
    for q in interior_samples(m.robot, 20, seed=8):
        J = np.array(jac(q))
        omega, H, _ = (np.ravel(np.array(x)) for x in f(q, np.ones(m.n), delta))
        for i in range(m.n):
            Ji = np.delete(J, i, axis=1)
            ref = np.linalg.det(Ji @ Ji.T)
            assert omega[i] ** 2 - delta ** 2 == pytest.approx(ref, abs=1e-14, rel=1e-9)
        assert H[0] == pytest.approx(omega.sum(), rel=1e-14)
        w, _ = fw(q, 0.0)
        assert float(w) == pytest.approx(math.sqrt(max(np.linalg.det(J @ J.T), 0.0)), rel=1e-9, abs=1e-12)


@pytest.mark.parametrize("name", ["iiwa14", "modular8"])
def test_criteria_gradients_match_finite_differences(name):
    m = model(name)
    fjm = m.function("joint_manipulability")
    fw = m.function("manipulability")
    delta = 1e-2
    a = np.linspace(1, 2, m.n)
    for q in interior_samples(m.robot, 5, seed=9):
        _, _, g = fjm(q, a, delta)
        fd = central_difference(lambda x: float(fjm(x, a, delta)[1]), q)
        np.testing.assert_allclose(np.ravel(g), fd.ravel(), atol=FD_TOL)
        _, gw = fw(q, delta)
        fd = central_difference(lambda x: float(fw(x, delta)[0]), q)
        np.testing.assert_allclose(np.ravel(gw), fd.ravel(), atol=FD_TOL)


def test_joint_manipulability_at_the_kink_is_smooth():
    """For the iiwa (spherical shoulder and wrist) locking the elbow fixes the shoulder–wrist
    distance, so det J₋₄ ≡ 0: the smooth form gives exactly δ and a zero gradient there,
    instead of the undefined derivative of |det|."""
    m = model("iiwa14")
    f = m.function("joint_manipulability")
    for delta in (1e-3, 1e-1):
        for q in interior_samples(m.robot, 5, seed=10):
            omega, _, _ = f(q, np.ones(7), delta)
            assert float(omega[3]) == pytest.approx(delta, rel=1e-9)
            e4 = np.eye(7)[3]
            _, _, g = f(q, e4, delta)  # H = ω_4 alone
            np.testing.assert_allclose(np.ravel(g), 0.0, atol=1e-9)


def test_continuous_weights_shape():
    m = model("planar3")
    f = m.function("continuous_weights")
    lo, hi = m.robot.qmin[0], m.robot.qmax[0]
    band = 0.1
    width = band * (hi - lo)
    for q, expected in [(lo, 1.0), (lo - 0.1, 1.0), (lo + width, 0.0), (0.0, 0.0), (hi - width, 0.0), (hi, 1.0),
                        (lo + width / 2, 0.5), (hi - width / 2, 0.5)]:
        assert float(f(np.full(3, q), band)[0]) == pytest.approx(expected, abs=1e-12)
    # C¹: the slope is continuous, zero at both band edges
    for edge in (lo + width, hi - width, lo, hi):
        for side in (-1, 1):
            x = edge + side * 1e-7
            slope = (float(f(np.full(3, x + 1e-9), band)[0]) - float(f(np.full(3, x - 1e-9), band)[0])) / 2e-9
            assert abs(slope) < 1e-4


def _damped_pinv(J, lam):
    return J.T @ np.linalg.inv(J @ J.T + lam ** 2 * np.eye(J.shape[0]))


@pytest.mark.parametrize("name", ["planar3", "iiwa14", "modular8"])
def test_step_gpm_and_wln_against_numpy(name):
    m = model(name)
    rows = list(m.robot.task_rows)
    rng = np.random.default_rng(12)
    jac = m.function("jacobian")
    for q in interior_samples(m.robot, 20, seed=13):
        J = np.array(jac(q))[rows]
        xdot, alpha = rng.normal(size=m.m), rng.normal(size=m.n)
        lam = 0.05
        Jp = _damped_pinv(J, lam)
        ref = Jp @ xdot + (np.eye(m.n) - Jp @ J) @ alpha
        np.testing.assert_allclose(np.ravel(m.function("step_gpm")(q, xdot, alpha, lam)), ref, atol=1e-10)
        W = 1 + rng.uniform(0, 5, size=m.n)
        Wi = np.diag(1 / W)
        ref = Wi @ J.T @ np.linalg.solve(J @ Wi @ J.T + lam ** 2 * np.eye(m.m), xdot)
        np.testing.assert_allclose(np.ravel(m.function("step_wln")(q, xdot, W, lam)), ref, atol=1e-10)
        # undamped: the task is met exactly, whatever the null-space input
        qdot = np.ravel(m.function("step_gpm")(q, xdot, alpha, 0.0))
        np.testing.assert_allclose(J @ qdot, xdot, atol=1e-9)


def test_steps_finite_at_a_singular_pose():
    """Stretched iiwa (q = 0) is singular; with zero damping the pivot floor keeps the
    step finite; with damping it is the damped least-squares solution."""
    m = model("iiwa14")
    q = np.zeros(7)
    xdot = np.array([0.0, 0.0, 0.1, 0.0, 0.0, 0.0])  # along the stretched arm: unreachable
    for lam in (0.0, 1e-2):
        qdot = np.ravel(m.function("step_gpm")(q, xdot, np.zeros(7), lam))
        assert np.all(np.isfinite(qdot))
        qdot = np.ravel(m.function("step_wln")(q, xdot, np.ones(7), lam))
        assert np.all(np.isfinite(qdot))


def test_loop_calls_found_in_order_and_replayed():
    """Two fixed loops called in one function, the second on the first's result: calls_in_order
    names them in the algorithm's order (from each call instruction's own SX node), and the
    NumPy replay agrees with CasADi's own evaluation of the function, bit for bit."""
    import casadi as ca

    from armgen.symbolic.loops import calls_in_order, fixed_loop
    from armgen.symbolic.replay import BatchFunction

    state, c = ca.SX.sym("state", 2), ca.SX.sym("c")
    halving = fixed_loop(ca.Function("test_halving_step", [state, c], [ca.vertcat(0.5 * state[0] + c, state[1] * state[0])],
                                     ["state", "c"], ["next"]), 7)
    rotating = fixed_loop(ca.Function("test_rotating_step", [state, c], [ca.vertcat(ca.cos(c) * state[0] - ca.sin(c) * state[1],
                                                                                  ca.sin(c) * state[0] + ca.cos(c) * state[1])],
                                      ["state", "c"], ["next"]), 5)
    x = ca.SX.sym("x", 2)
    y = x[0]
    for k in range(200):  # a long prefix before the calls
        y = ca.sin(y) * x[1] + 1e-3 * k
    first = halving(ca.vertcat(y, x[1]), x[0])
    second = rotating(first, x[1])
    func = ca.Function("two_loops", [x], [ca.cos(second[0]) + second[1]])
    assert [f.name() for f in calls_in_order(func)] == ["test_halving_step_loop", "test_rotating_step_loop"]
    inputs = np.random.default_rng(3).uniform(-1, 1, (2, 5))
    replay = BatchFunction(func)([inputs], 5)[0]
    reference = np.array([float(func(inputs[:, j])) for j in range(5)])
    np.testing.assert_array_equal(replay[0], reference)


@pytest.mark.parametrize("name", ["panda", "iiwa14"])
def test_zghal_gradient_closed_form_equals_reverse_mode_ad(name):
    """criteria.zghal_safe_gradient (the closed form every step uses) against CasADi's AD of
    zghal_safe, inside the limits, within a hair of them and beyond them (floored: zero)."""
    import casadi as ca

    from armgen.symbolic import criteria
    robot = load_robot(name)
    q = ca.SX.sym("q", robot.n)
    lo, hi = robot.qmin.tolist(), robot.qmax.tolist()
    both = ca.Function("g", [q], [criteria.zghal_safe_gradient(q, lo, hi), ca.gradient(criteria.zghal_safe(q, lo, hi), q)])
    rng = np.random.default_rng(11)
    span = robot.qmax - robot.qmin
    samples = [robot.qmin + span * rng.uniform(0, 1, robot.n) for _ in range(40)]
    samples += [robot.qmin + span * rng.choice([1e-4, 1 - 1e-4, -0.1, 1.1], robot.n) for _ in range(20)]
    for sample in samples:
        closed, ad = (np.asarray(x).ravel() for x in both(sample))
        np.testing.assert_allclose(closed, ad, rtol=1e-12, atol=0)
    outside = robot.qmax + 0.1
    assert not np.any(np.asarray(both(outside)[0]))
