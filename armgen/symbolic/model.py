"""The symbolic model of a robot: every derived quantity as a named ``casadi.Function``.

Inputs and outputs are named (``q``, ``xdot``, ``damping`` …) and dense. Task-space
quantities use the robot's task rows (``robot.task_rows``, all six by default), so ``m``
is the task dimension and ``n`` the number of joints.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import casadi as ca

from ..description import RobotDescription
from . import criteria, ik, steps
from .collision import COLLISION_FUNCTIONS, collision_function, require_collision
from .dynamics import DYNAMIC_FUNCTIONS, dynamic_function, require_dynamics
from .kinematics import chain, geometric_jacobian

KINEMATIC_FUNCTIONS = ("fk", "jacobian", "fk_jacobian")
CRITERION_FUNCTIONS = ("zghal", "repetitive", "joint_manipulability", "manipulability", "continuous_weights",
                       "ft_index", "wln_weights")
# The functions that depend on q only through the geometric Jacobian J (step_wgpm: through J
# and q). Each has a twin "<name>_from_jacobian" that takes J (6×n, the jacobian function's
# output) in place of q's kinematics; <name> is that twin applied to jacobian(q) — the same
# operations, so the generated <name> calls <prefix>_jacobian and the twin (one copy of each in
# flash), and a controller that already holds J calls the twin directly.
JACOBIAN_FUNCTIONS = ("manipulability", "joint_manipulability", "ft_index", "step_gpm", "step_wln", "step_fault",
                      "step_wgpm")
FROM_JACOBIAN = "_from_jacobian"
TWINS = tuple(name + FROM_JACOBIAN for name in JACOBIAN_FUNCTIONS)
STEPS = ("step_gpm", "step_wln", "step_fault", "step_wgpm")
STEP_FUNCTIONS = STEPS + tuple(name + FROM_JACOBIAN for name in STEPS)  # those that return a status
# inverse kinematics (armgen.symbolic.ik): returns OK, NOT_CONVERGED, NONFINITE or BAD_TARGET
IK_FUNCTIONS = ("ik",)
# twins first: the generated functions of J call them (and jacobian)
ALL_FUNCTIONS = KINEMATIC_FUNCTIONS + TWINS + CRITERION_FUNCTIONS + STEPS + IK_FUNCTIONS
# The rigid-body dynamics (armgen.symbolic.dynamics, DYNAMIC_FUNCTIONS) come after these, only for
# a robot with every link's inertial (robot.has_dynamics): available() lists them then, so code
# generation, `armgen verify` and the compiled backends take them like the kinematic ones.
# The collision functions (armgen.symbolic.collision, COLLISION_FUNCTIONS) come last, only for a
# robot with capsules (robot.has_collision), so the C of a robot without them is unchanged.

# One-line descriptions, used in the generated header and by `armgen show`.
DESCRIPTIONS = {
    "fk": "tool pose T (4x4 homogeneous) in the base frame",
    "jacobian": "geometric Jacobian J (6xn, rows [v; w] of the tool origin, base frame)",
    "fk_jacobian": "tool pose T and geometric Jacobian J in one call (shared trig)",
    "zghal": "Zghal joint-limit criterion H_L and its gradient (rad)",
    "repetitive": "repetitive criterion H_R = 1/2 |q - q_init|^2 and its gradient",
    "joint_manipulability": "joint manipulability omega_i = sqrt(det(J_-i J_-i^T) + delta^2), "
                            "H_M = sum a_i omega_i and its gradient",
    "manipulability": "manipulability w = sqrt(det(J J^T) + delta^2) and its gradient",
    "continuous_weights": "continuous joint-limit weights w_c (spec 35), band = damping-band fraction",
    "step_gpm": "damped gradient projection qdot = J# xdot + (I - J# J) alpha",
    "step_wln": "damped weighted least norm qdot = W^-1 J^T (J W^-1 J^T + lambda^2 I)^-1 xdot",
    "ft_index": "joint manipulability on the healthy columns (mask 1 = healthy, 0 = locked; spec 30): "
                "omega_i, H_M = sum mask_i a_i omega_i, w = sqrt(det(J_h J_h^T) + delta^2) and gradients",
    "wln_weights": "WLN weights W_i = 1 + b |dH/dq_i| / max(omega_i, omega_floor) * active_i; plain on/off "
                   "rule for v_band <= 0, smooth ramp over v_band > 0 (spec 30)",
    "step_fault": "masked weighted GPM qdot = mask*alpha + S J^T (J S J^T + lambda^2 I)^-1 (xdot - J mask*alpha), "
                  "S = mask/W, variable damping from sigma_min (tridiagonal bisection) (spec 30)",
    "step_wgpm": "multi-constraint weighted GPM (spec 35): continuous weights, repulsive field, damping from "
                 "sigma_min(J W_b) (tridiagonal bisection), oblique projector, normalised criteria, online gains",
    "ik": "inverse kinematics: q reaching the pose T_target (damped least squares from q_seed, limits clamped, "
          "deterministic restarts; self-motion toward q_rest if use_rest = 1, else away from the limits and "
          "q_seed first turned about the first joint's axis toward the target); "
          "success = 1 and OK when position/orientation errors <= tol_position/tol_orientation, else "
          "NOT_CONVERGED with the closest q reached (max_iterations <= 0: no step, iterations 0); "
          "BAD_TARGET, no step, for a T_target that is not a pose (is_pose, in the header)",
    "gravity": "gravity torques tau = g(q) (N m; N for a prismatic joint): the torques that hold the arm still at q",
    "rnea": "inverse dynamics tau = M(q) ddq + C(q, dq) dq + g(q) (recursive Newton-Euler; reflected motor "
            "inertia included)",
    "mass_matrix": "joint-space mass matrix M(q) (nxn, symmetric positive definite; composite rigid body; "
                   "reflected motor inertia on the diagonal)",
    "coriolis": "Coriolis and centrifugal torques c = C(q, dq) dq",
    "collision_distances": "signed distances d (m; negative when overlapping) of the checked capsule pairs, then of "
                           "each moving capsule to each obstacle slot (inactive slots: a large distance)",
    "collision_criterion": "collision criterion H_C = sum 1/2 ((activation - d) / (d - clearance))^2 over the "
                           "distances d below activation, continued by its tangent below clearance + 0.05 (activation "
                           "- clearance) (C1), and its gradient",
}
DESCRIPTIONS.update({twin: f"{DESCRIPTIONS[name]}; from a given Jacobian J (jacobian's output, 6xn; "
                           "its entries that are constant for this robot are not read)"
                     for name, twin in zip(JACOBIAN_FUNCTIONS, TWINS)})


def requirements(name: str) -> tuple[str, ...]:
    """The functions the generated ``name`` calls (jacobian and the twin), then ``name``."""
    return ("jacobian", name + FROM_JACOBIAN, name) if name in JACOBIAN_FUNCTIONS else (name,)


@dataclass(frozen=True)
class ModelOptions:
    """What to derive. ``functions`` None means every function the robot supports."""

    functions: tuple[str, ...] | None = None


class SymbolicModel:
    def __init__(self, robot: RobotDescription, options: ModelOptions | None = None):
        self.robot = robot
        self.options = options or ModelOptions()
        self.n = robot.n
        self.m = len(robot.task_rows)
        self.q = ca.SX.sym("q", self.n)

    # -- shared expressions -------------------------------------------------------
    @cached_property
    def ik_definition(self) -> ik.IKDefinition:
        """The IK's step, loop and functions (the ``ik`` function is its ``function``)."""
        return ik.IKDefinition(self.robot)

    @cached_property
    def _kinematics(self) -> tuple[ca.SX, ca.SX]:
        axis_frames, _, tool = chain(self.robot, self.q)
        return tool, geometric_jacobian(self.robot, axis_frames, tool)

    @property
    def tool(self) -> ca.SX:
        return self._kinematics[0]

    @property
    def jac(self) -> ca.SX:
        return self._kinematics[1]

    @property
    def task_jac(self) -> ca.SX:
        return self.jac[list(self.robot.task_rows), :]

    def task_vjp(self, jac: ca.SX, g: ca.SX) -> ca.SX:
        """∇_q Σ G ∘ J_task for a G (m×n) held constant, J = ``jac`` (criteria.jacobian_vjp)."""
        full = ca.SX(6, self.n)
        for r, row in enumerate(self.robot.task_rows):
            full[row, :] = g[r, :]
        return criteria.jacobian_vjp([j.revolute for j in self.robot.joints], jac, full)

    def available(self) -> tuple[str, ...]:
        """Every function, for any chain length (the criteria cost O(n) after the kinematics),
        then the dynamic ones when every link has an inertial."""
        return ALL_FUNCTIONS + self.dynamic_functions() + self.collision_functions()

    def selected(self) -> tuple[str, ...]:
        """The requested functions with what they call (jacobian, the twins), in ALL_FUNCTIONS order."""
        wanted = self.options.functions or self.available()
        if any(f in DYNAMIC_FUNCTIONS for f in wanted):
            require_dynamics(self.robot)  # the error names the joints without an inertial and the fix
        if any(f in COLLISION_FUNCTIONS for f in wanted):
            require_collision(self.robot)  # the error says why the robot has no capsules and the fix
        unknown = [f for f in wanted if f not in self.available()]
        if unknown:
            raise ValueError(f"functions not available for robot '{self.robot.name}': {', '.join(unknown)} "
                             f"(available: {', '.join(self.available())})")
        needed = {r for name in wanted for r in requirements(name)}
        return tuple(name for name in self.available() if name in needed)

    def dynamic_functions(self) -> tuple[str, ...]:
        """The dynamic functions (DYNAMIC_FUNCTIONS) when every link has an inertial, else none."""
        return DYNAMIC_FUNCTIONS if self.robot.has_dynamics else ()

    def collision_functions(self) -> tuple[str, ...]:
        """The collision functions (COLLISION_FUNCTIONS) when the robot has capsules, else none."""
        return COLLISION_FUNCTIONS if self.robot.has_collision else ()

    # -- the functions ---------------------------------------------------------------
    def function(self, name: str) -> ca.Function:
        if name not in self._functions:  # built on first use: a planner needs a few of them
            if name in DYNAMIC_FUNCTIONS:  # a clear error names the joints without an inertial
                self._functions[name] = dynamic_function(self.robot, name)
            elif name in COLLISION_FUNCTIONS:  # a clear error says why there are no capsules
                self._functions[name] = collision_function(self.robot, name)
            elif name not in self.available():
                raise KeyError(name)
            else:
                self._functions[name] = self._build(name)
        return self._functions[name]

    @cached_property
    def _functions(self) -> dict[str, ca.Function]:
        return {}

    def functions(self) -> dict[str, ca.Function]:
        return {name: self.function(name) for name in self.selected()}

    def _build(self, name: str) -> ca.Function:
        if name in JACOBIAN_FUNCTIONS:
            return self._through_jacobian(name)
        if name in TWINS:
            return self._twin(name[: -len(FROM_JACOBIAN)])
        q, robot = self.q, self.robot
        qmin, qmax = robot.qmin.tolist(), robot.qmax.tolist()
        dense = ca.densify
        if name == "ik":
            return self.ik_definition.function
        if name == "fk":
            return ca.Function("fk", [q], [dense(self.tool)], ["q"], ["T"])
        if name == "jacobian":
            return ca.Function("jacobian", [q], [dense(self.jac)], ["q"], ["J"])
        if name == "fk_jacobian":
            return ca.Function("fk_jacobian", [q], [dense(self.tool), dense(self.jac)], ["q"], ["T", "J"])
        if name == "zghal":
            # the floored form: equal inside the limits, finite (saturated) at and beyond them
            h = criteria.zghal_safe(q, qmin, qmax)
            return ca.Function("zghal", [q], [h, dense(criteria.zghal_safe_gradient(q, qmin, qmax))], ["q"],
                               ["H_L", "grad_H_L"])
        if name == "repetitive":
            q_init = ca.SX.sym("q_init", self.n)
            h = criteria.repetitive(q, q_init)
            return ca.Function("repetitive", [q, q_init], [h, dense(ca.gradient(h, q))],
                               ["q", "q_init"], ["H_R", "grad_H_R"])
        if name == "continuous_weights":
            band = ca.SX.sym("band")
            return ca.Function("continuous_weights", [q, band], [dense(criteria.continuous_weights(q, qmin, qmax, band))],
                               ["q", "band"], ["w_c"])
        if name == "wln_weights":
            grad, omega = ca.SX.sym("grad_H", self.n), ca.SX.sym("omega", self.n)
            qdot_prev, mask = ca.SX.sym("qdot_prev", self.n), ca.SX.sym("mask", self.n)
            b, omega_floor, v_band = ca.SX.sym("b"), ca.SX.sym("omega_floor"), ca.SX.sym("v_band")
            weights, active = criteria.wln_weights(grad, omega, qdot_prev, mask, b, omega_floor, v_band)
            return ca.Function("wln_weights", [grad, omega, qdot_prev, mask, b, omega_floor, v_band],
                               [dense(weights), dense(active)],
                               ["grad_H", "omega", "qdot_prev", "mask", "b", "omega_floor", "v_band"],
                               ["W", "active"])
        raise KeyError(name)

    def _through_jacobian(self, name: str) -> ca.Function:
        """``name`` = its twin applied to jacobian(q): the inputs of the twin with J replaced by q."""
        twin = self.function(name + FROM_JACOBIAN)
        labels = [twin.name_in(k) for k in range(1, twin.n_in())]
        symbols = {label: self.q if label == "q" else ca.SX.sym(label, twin.sparsity_in(k + 1).shape)
                   for k, label in enumerate(labels)}
        # a call node, not an inlined copy: CasADi would simplify the copy with J's shared and
        # constant entries (x − x → 0 …), which is not the twin's arithmetic; the call evaluates
        # exactly the twin's operations, as the generated <name> (jacobian, then the twin) does
        outputs = twin.call([self.jac, *[symbols[label] for label in labels]], False, True)
        names_in = ["q", *[label for label in labels if label != "q"]]
        return ca.Function(name, [self.q if label == "q" else symbols[label] for label in names_in], outputs,
                           names_in, twin.name_out())

    @cached_property
    def _jacobian_input(self) -> tuple[ca.SX, ca.SX]:
        """J as the twins see it: a symbol per entry, except the entries that are constant for this
        robot (a prismatic joint's zero angular part, the base axis …), which are those constants,
        so the twin spends no operations on them and reads only the entries that vary.
        Returns (the input symbol, J as used)."""
        symbol = ca.SX.sym("J", 6, self.n)
        jac = ca.densify(self.jac)
        out = ca.SX(6, self.n)
        for r in range(6):
            for c in range(self.n):
                entry = jac[r, c]
                out[r, c] = ca.SX(float(entry)) if entry.is_constant() else symbol[r, c]
        return symbol, out

    def _twin(self, name: str) -> ca.Function:
        """``<name>_from_jacobian``: ``name`` with the geometric Jacobian J (6×n) as its first input."""
        q, robot, n, m = self.q, self.robot, self.n, self.m
        symbol, jac = self._jacobian_input
        qmin, qmax = robot.qmin.tolist(), robot.qmax.tolist()
        dense = ca.densify
        twin = name + FROM_JACOBIAN
        task_jac = jac[list(robot.task_rows), :]
        if name == "ft_index":
            mask, a, delta = ca.SX.sym("mask", n), ca.SX.sym("a", n), ca.SX.sym("delta")
            masked = task_jac @ ca.diag(mask)
            weights = mask * a
            sens = criteria.manipulability_sensitivities(criteria.gram_qr(masked), masked, weights,
                                                         criteria.smooth_delta(delta))
            omega = ca.vertcat(*sens.omega)
            # ∂/∂J = ∂/∂(J diag(mask)) · diag(mask), then through J(q) in closed form
            return ca.Function(twin, [symbol, mask, a, delta],
                               [dense(omega), ca.dot(weights, omega),
                                dense(self.task_vjp(jac, sens.grad_h @ ca.diag(mask))),
                                sens.w, dense(self.task_vjp(jac, sens.z @ ca.diag(mask)) / sens.w)],  # ∂w/∂J = Z/w
                               ["J", "mask", "a", "delta"], ["omega", "H_M", "grad_H_M", "w", "grad_w"])
        if name == "joint_manipulability":
            # ft_index with every joint healthy: one construction for the whole family
            a, delta = ca.SX.sym("a", n), ca.SX.sym("delta")
            omega, h, grad, _, _ = self.function("ft_index" + FROM_JACOBIAN)(jac, ca.DM.ones(n), a, delta)
            return ca.Function(twin, [symbol, a, delta], [omega, h, grad], ["J", "a", "delta"],
                               ["omega", "H_M", "grad_H_M"])
        if name == "manipulability":
            delta = ca.SX.sym("delta")
            _, _, _, w, grad = self.function("ft_index" + FROM_JACOBIAN)(jac, ca.DM.ones(n), ca.DM.zeros(n), delta)
            return ca.Function(twin, [symbol, delta], [w, grad], ["J", "delta"], ["w", "grad_w"])
        if name == "step_gpm":
            xdot, alpha, damping = ca.SX.sym("xdot", m), ca.SX.sym("alpha", n), ca.SX.sym("damping")
            qdot = steps.step_gpm(task_jac, xdot, alpha, damping)
            return ca.Function(twin, [symbol, xdot, alpha, damping], [dense(qdot)],
                               ["J", "xdot", "alpha", "damping"], ["qdot"])
        if name == "step_wln":
            xdot, weights, damping = ca.SX.sym("xdot", m), ca.SX.sym("W", n), ca.SX.sym("damping")
            qdot = steps.step_wln(task_jac, xdot, weights, damping)
            return ca.Function(twin, [symbol, xdot, weights, damping], [dense(qdot)],
                               ["J", "xdot", "W", "damping"], ["qdot"])
        if name == "step_fault":
            xdot, mask = ca.SX.sym("xdot", m), ca.SX.sym("mask", n)
            weights, alpha = ca.SX.sym("W", n), ca.SX.sym("alpha", n)
            epsilon, lambda_max = ca.SX.sym("epsilon"), ca.SX.sym("lambda_max")
            qdot, lam, sigma = steps.step_fault(task_jac, xdot, mask, weights, alpha, epsilon, lambda_max)
            return ca.Function(twin, [symbol, xdot, mask, weights, alpha, epsilon, lambda_max],
                               [dense(qdot), lam, sigma],
                               ["J", "xdot", "mask", "W", "alpha", "epsilon", "lambda_max"],
                               ["qdot", "damping", "sigma_min"])
        if name == "step_wgpm":
            nc = len(steps.WGPM_CRITERIA)
            scalar_names = ("band", "t_rmax", "epsilon", "rho_max", "delta", "ramp")
            vector_names = ("H_lo", "H_hi", "k_hi", "k_lo", "u_th", "u_band")
            scalars = [ca.SX.sym(label) for label in scalar_names]
            vectors = [ca.SX.sym(label, nc) for label in vector_names]
            xdot = ca.SX.sym("xdot", m)
            out = steps.step_wgpm(task_jac, lambda g: self.task_vjp(jac, g), q, qmin, qmax, xdot, *scalars, *vectors)
            names_out = ["qdot", "w_c", "rho", "sigma_min", "gains", "H"]
            return ca.Function(twin, [symbol, q, xdot, *scalars, *vectors], [dense(out[k]) for k in names_out],
                               ["J", "q", "xdot", *scalar_names, *vector_names], names_out)
        raise KeyError(name)
