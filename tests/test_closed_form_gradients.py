"""The lean criteria's closed-form derivatives (issue 12) against a second implementation.

- ``criteria.jacobian_vjp`` (the kinematic Hessian contracted in O(n)) against CasADi's
  reverse-mode AD of Σ G ∘ J(q), on revolute, prismatic and URDF-style chains;
- ``Sensitivities.combine`` (∂w/∂A, ∂H_M/∂A, ∂κ_s/∂A by adjugates and Sherman–Morrison)
  against AD of the same values, built through the Householder QR;
- the twins ``<name>_from_jacobian`` are ``<name>`` applied to ``jacobian(q)``, bit for bit.
"""

import casadi as ca
import numpy as np
import pytest

from armgen.robot import Robot, load_robot, parse_robot
from armgen.symbolic import criteria
from armgen.symbolic.model import FROM_JACOBIAN, JACOBIAN_FUNCTIONS, SymbolicModel
from armgen.verification.samples import function_inputs, joint_samples
from test_urdf import OBLIQUE_URDF

# Both sides are double evaluations of the same derivative by different operation sequences:
# they agree to rounding, relative to the gradient's norm (seen ≤ 3e-15; margin for the
# samples where the gradient is small against its terms).
DERIVATIVE_REL_TOL = 1e-11
SAMPLES = 200

# A DH chain with two prismatic joints among revolute ones (the bundled arms are all revolute).
PRISMATIC_CHAIN = """
name = "prismatic_mix"
convention = "standard"
[units]
length = "mm"
angle = "deg"
[[joints]]
name = "j1"
type = "revolute"
a = 0
d = 300
alpha = -90
qlim = [-170, 170]
[[joints]]
name = "j2"
type = "prismatic"
a = 50
d = 100
alpha = 90
theta = 30
qlim = [0, 400]
[[joints]]
name = "j3"
type = "revolute"
a = 250
d = 0
alpha = -90
qlim = [-120, 120]
[[joints]]
name = "j4"
type = "revolute"
a = 0
d = 200
alpha = 90
qlim = [-170, 170]
[[joints]]
name = "j5"
type = "prismatic"
a = 0
d = 50
alpha = -90
theta = 0
qlim = [0, 200]
[[joints]]
name = "j6"
type = "revolute"
a = 80
d = 0
alpha = 0
qlim = [-170, 170]
[[joints]]
name = "j7"
type = "revolute"
a = 60
d = 40
alpha = 90
qlim = [-170, 170]
"""


def _robot(name, tmp_path=None):
    if name == "prismatic_mix":
        return parse_robot(PRISMATIC_CHAIN, "prismatic_mix.toml")
    if name == "oblique_urdf":  # general joints: origins and oblique axes, one prismatic
        (tmp_path / "arm.urdf").write_text(OBLIQUE_URDF)
        return Robot.from_urdf(tmp_path / "arm.urdf", tip_link="flange")
    return load_robot(name)


def _outputs(result):
    return result if isinstance(result, tuple) else (result,)


def _relative(got, want):
    return float(np.max(np.abs(got - want)) / max(np.max(np.abs(want)), 1e-300))


@pytest.mark.parametrize("name", ["planar3", "modular8", "iiwa14", "prismatic_mix", "oblique_urdf"])
def test_jacobian_vjp_matches_reverse_mode_ad(name, tmp_path):
    model = SymbolicModel(_robot(name, tmp_path))
    revolute = [j.revolute for j in model.robot.joints]
    g = ca.SX.sym("G", 6, model.n)
    closed = ca.Function("closed", [model.q, g], [criteria.jacobian_vjp(revolute, model.jac, g)])
    ad = ca.Function("ad", [model.q, g], [ca.gradient(ca.sum1(ca.sum2(g * model.jac)), model.q)])
    qs, _ = joint_samples(model.robot, SAMPLES, 7)
    rng = np.random.default_rng(7)
    for q in qs:
        weights = rng.normal(size=(6, model.n))
        assert _relative(np.array(closed(q, weights)), np.array(ad(q, weights))) <= DERIVATIVE_REL_TOL


@pytest.mark.parametrize("m, n", [(3, 3), (3, 7), (6, 8), (6, 12), (6, 14)])
def test_criteria_derivatives_match_ad_through_the_qr(m, n):
    """k_w ∂w/∂A + k_h ∂H_M/∂A + k_c ∂κ_s/∂A of the closed forms against AD of
    k_w w + k_h H_M + k_c κ_s, all built from one floored Householder QR of Aᵀ."""
    a, weights, delta = ca.SX.sym("A", m, n), ca.SX.sym("a", n), ca.SX.sym("delta")
    k = ca.SX.sym("k", 3)
    sens = criteria.manipulability_sensitivities(criteria.gram_qr(a), a, weights, delta)
    value = k[0] * sens.w + k[1] * ca.dot(weights, ca.vertcat(*sens.omega)) + k[2] * sens.condition
    closed = ca.Function("closed", [a, weights, delta, k], [sens.combine(k[0], k[1], k[2])])
    ad = ca.Function("ad", [a, weights, delta, k], [ca.jacobian(value, ca.vec(a)).reshape((m, n))])
    rng = np.random.default_rng(m * 100 + n)
    for s in range(SAMPLES):
        matrix = rng.normal(size=(m, n))
        if s % 4 == 1:  # nearly rank-deficient, still regular
            u, sv, vt = np.linalg.svd(matrix, full_matrices=False)
            matrix = (u * np.r_[sv[:-1], 1e-3 * sv[-1]]) @ vt
        args = (matrix, rng.uniform(0.5, 2.0, n), 10 ** rng.uniform(-4, -1), rng.normal(size=3))
        assert _relative(np.array(closed(*args)), np.array(ad(*args))) <= DERIVATIVE_REL_TOL


@pytest.mark.parametrize("name", ["planar3", "modular8", "prismatic_mix", "oblique_urdf"])
def test_twins_are_the_functions_through_the_jacobian(name, tmp_path):
    model = SymbolicModel(_robot(name, tmp_path))
    jacobian = model.function("jacobian")
    qs, _ = joint_samples(model.robot, 50, 3)
    for index, base in enumerate(JACOBIAN_FUNCTIONS):
        func, twin = model.function(base), model.function(base + FROM_JACOBIAN)
        rng = np.random.default_rng([3, index])
        for q in qs:
            args = function_inputs(func, model.robot, q, rng)
            labels = [func.name_in(k) for k in range(func.n_in())]
            twin_args = [np.array(jacobian(q)) if label == "J" else args[labels.index(label)]
                         for label in twin.name_in()]
            for want, got in zip(_outputs(func(*args)), _outputs(twin(*twin_args))):
                assert np.array_equal(np.array(want), np.array(got)), base
