"""The symbolic model of a robot: every derived quantity as a named ``casadi.Function``.

Inputs and outputs are named (``q``, ``xdot``, ``damping`` …) and dense. Task-space
quantities use the robot's task rows (``robot.task_rows``, all six by default), so ``m``
is the task dimension and ``n`` the number of joints.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import casadi as ca

from ..robot import Robot
from . import criteria, steps
from .kinematics import chain, geometric_jacobian

KINEMATIC_FUNCTIONS = ("fk", "jacobian", "fk_jacobian")
CRITERION_FUNCTIONS = ("zghal", "repetitive", "joint_manipulability", "manipulability", "continuous_weights",
                       "ft_index", "wln_weights")
STEP_FUNCTIONS = ("step_gpm", "step_wln", "step_fault", "step_wgpm")
ALL_FUNCTIONS = KINEMATIC_FUNCTIONS + CRITERION_FUNCTIONS + STEP_FUNCTIONS

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
                  "S = mask/W, variable damping from sigma_min (Jacobi) (spec 30)",
    "step_wgpm": "multi-constraint weighted GPM (spec 35): continuous weights, repulsive field, damping from "
                 "sigma_min(J W_b) (Jacobi), oblique projector, normalised criteria, online gains",
}


@dataclass(frozen=True)
class ModelOptions:
    """What to derive. ``functions`` None means every function the robot supports."""

    functions: tuple[str, ...] | None = None


class SymbolicModel:
    def __init__(self, robot: Robot, options: ModelOptions | None = None):
        self.robot = robot
        self.options = options or ModelOptions()
        self.n = robot.n
        self.m = len(robot.task_rows)
        self.q = ca.SX.sym("q", self.n)

    # -- shared expressions -------------------------------------------------------
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

    def task_vjp(self, g: ca.SX) -> ca.SX:
        """∇_q Σ G ∘ J_task for a G (m×n) held constant (criteria.jacobian_vjp)."""
        full = ca.SX(6, self.n)
        for r, row in enumerate(self.robot.task_rows):
            full[row, :] = g[r, :]
        return criteria.jacobian_vjp([j.revolute for j in self.robot.joints], self.jac, full)

    def available(self) -> tuple[str, ...]:
        """Every function, for any chain length (the criteria cost O(n) after the kinematics)."""
        return ALL_FUNCTIONS

    def selected(self) -> tuple[str, ...]:
        wanted = self.options.functions or self.available()
        unknown = [f for f in wanted if f not in self.available()]
        if unknown:
            raise ValueError(f"functions not available for robot '{self.robot.name}': {', '.join(unknown)} "
                             f"(available: {', '.join(self.available())})")
        return tuple(wanted)

    # -- the functions ---------------------------------------------------------------
    def function(self, name: str) -> ca.Function:
        if name not in self._functions:  # built on first use: a planner needs a few of them
            if name not in self.available():
                raise KeyError(name)
            self._functions[name] = self._build(name)
        return self._functions[name]

    @cached_property
    def _functions(self) -> dict[str, ca.Function]:
        return {}

    def functions(self) -> dict[str, ca.Function]:
        return {name: self.function(name) for name in self.selected()}

    def _build(self, name: str) -> ca.Function:
        q, robot = self.q, self.robot
        qmin, qmax = robot.qmin.tolist(), robot.qmax.tolist()
        dense = ca.densify
        if name == "fk":
            return ca.Function("fk", [q], [dense(self.tool)], ["q"], ["T"])
        if name == "jacobian":
            return ca.Function("jacobian", [q], [dense(self.jac)], ["q"], ["J"])
        if name == "fk_jacobian":
            return ca.Function("fk_jacobian", [q], [dense(self.tool), dense(self.jac)], ["q"], ["T", "J"])
        if name == "zghal":
            # the floored form: equal inside the limits, finite (saturated) at and beyond them
            h = criteria.zghal_safe(q, qmin, qmax)
            return ca.Function("zghal", [q], [h, dense(ca.gradient(h, q))], ["q"], ["H_L", "grad_H_L"])
        if name == "repetitive":
            q_init = ca.SX.sym("q_init", self.n)
            h = criteria.repetitive(q, q_init)
            return ca.Function("repetitive", [q, q_init], [h, dense(ca.gradient(h, q))],
                               ["q", "q_init"], ["H_R", "grad_H_R"])
        if name == "joint_manipulability":
            # ft_index with every joint healthy: one construction for the whole family
            a, delta = ca.SX.sym("a", self.n), ca.SX.sym("delta")
            omega, h, grad, _, _ = self._build("ft_index")(q, ca.DM.ones(self.n), a, delta)
            return ca.Function("joint_manipulability", [q, a, delta], [omega, h, grad],
                               ["q", "a", "delta"], ["omega", "H_M", "grad_H_M"])
        if name == "manipulability":
            delta = ca.SX.sym("delta")
            _, _, _, w, grad = self._build("ft_index")(q, ca.DM.ones(self.n), ca.DM.zeros(self.n), delta)
            return ca.Function("manipulability", [q, delta], [w, grad], ["q", "delta"], ["w", "grad_w"])
        if name == "continuous_weights":
            band = ca.SX.sym("band")
            return ca.Function("continuous_weights", [q, band], [dense(criteria.continuous_weights(q, qmin, qmax, band))],
                               ["q", "band"], ["w_c"])
        if name == "step_gpm":
            xdot, alpha, damping = ca.SX.sym("xdot", self.m), ca.SX.sym("alpha", self.n), ca.SX.sym("damping")
            qdot = steps.step_gpm(self.task_jac, xdot, alpha, damping)
            return ca.Function("step_gpm", [q, xdot, alpha, damping], [dense(qdot)],
                               ["q", "xdot", "alpha", "damping"], ["qdot"])
        if name == "step_wln":
            xdot, weights, damping = ca.SX.sym("xdot", self.m), ca.SX.sym("W", self.n), ca.SX.sym("damping")
            qdot = steps.step_wln(self.task_jac, xdot, weights, damping)
            return ca.Function("step_wln", [q, xdot, weights, damping], [dense(qdot)],
                               ["q", "xdot", "W", "damping"], ["qdot"])
        if name == "ft_index":
            mask, a, delta = ca.SX.sym("mask", self.n), ca.SX.sym("a", self.n), ca.SX.sym("delta")
            masked = self.task_jac @ ca.diag(mask)
            weights = mask * a
            sens = criteria.manipulability_sensitivities(criteria.gram_qr(masked), masked, weights,
                                                         criteria.smooth_delta(delta))
            omega = ca.vertcat(*sens.omega)
            # ∂/∂J = ∂/∂(J diag(mask)) · diag(mask), then through J(q) in closed form
            return ca.Function("ft_index", [q, mask, a, delta],
                               [dense(omega), ca.dot(weights, omega), dense(self.task_vjp(sens.grad_h @ ca.diag(mask))),
                                sens.w, dense(self.task_vjp(sens.grad_w @ ca.diag(mask)))],
                               ["q", "mask", "a", "delta"], ["omega", "H_M", "grad_H_M", "w", "grad_w"])
        if name == "wln_weights":
            grad, omega = ca.SX.sym("grad_H", self.n), ca.SX.sym("omega", self.n)
            qdot_prev, mask = ca.SX.sym("qdot_prev", self.n), ca.SX.sym("mask", self.n)
            b, omega_floor, v_band = ca.SX.sym("b"), ca.SX.sym("omega_floor"), ca.SX.sym("v_band")
            weights, active = criteria.wln_weights(grad, omega, qdot_prev, mask, b, omega_floor, v_band)
            return ca.Function("wln_weights", [grad, omega, qdot_prev, mask, b, omega_floor, v_band],
                               [dense(weights), dense(active)],
                               ["grad_H", "omega", "qdot_prev", "mask", "b", "omega_floor", "v_band"],
                               ["W", "active"])
        if name == "step_fault":
            xdot, mask = ca.SX.sym("xdot", self.m), ca.SX.sym("mask", self.n)
            weights, alpha = ca.SX.sym("W", self.n), ca.SX.sym("alpha", self.n)
            epsilon, lambda_max = ca.SX.sym("epsilon"), ca.SX.sym("lambda_max")
            qdot, lam, sigma = steps.step_fault(self.task_jac, xdot, mask, weights, alpha, epsilon, lambda_max)
            return ca.Function("step_fault", [q, xdot, mask, weights, alpha, epsilon, lambda_max],
                               [dense(qdot), lam, sigma],
                               ["q", "xdot", "mask", "W", "alpha", "epsilon", "lambda_max"],
                               ["qdot", "damping", "sigma_min"])
        if name == "step_wgpm":
            nc = len(steps.WGPM_CRITERIA)
            scalar_names = ("band", "t_rmax", "epsilon", "rho_max", "delta", "ramp")
            vector_names = ("H_lo", "H_hi", "k_hi", "k_lo", "u_th", "u_band")
            scalars = [ca.SX.sym(s) for s in scalar_names]
            vectors = [ca.SX.sym(s, nc) for s in vector_names]
            xdot = ca.SX.sym("xdot", self.m)
            out = steps.step_wgpm(self.task_jac, self.task_vjp, q, qmin, qmax, xdot, *scalars, *vectors)
            names_out = ["qdot", "w_c", "rho", "sigma_min", "gains", "H"]
            inputs = [q, xdot, *scalars, *vectors]
            return ca.Function("step_wgpm", inputs, [dense(out[k]) for k in names_out],
                               ["q", "xdot", *scalar_names, *vector_names], names_out)
        raise KeyError(name)
