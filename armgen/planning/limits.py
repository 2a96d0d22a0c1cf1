"""Joint-limit violations of a planned motion, and the policy for them.

The resolved-rate planners (``cartesian``, ``fault_tolerant``, ``wgpm``) follow the path
whatever the joints do, so a plan may leave a joint's limits. By default such a plan is
infeasible (exit 3, nothing written): ``armgen plan … && armgen firmware …`` must not ship
it. A task that studies a method which leaves the limits on purpose (the papers'
pseudo-inverse baselines) sets ``[check] limits = "report"``: the plan is written and the
violations are listed in the summary's ``limit_violations``. (The ``ptp`` and ``snake``
planners never leave the position limits: they refuse such a plan themselves.)

The joints' speed limits (``qdlim``, ``qddlim``) follow the same policy in every planner: a plan
that asks a joint for more is infeasible unless the task sets ``[check] limits = "report"``.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..errors import PlanningError
from ..robot import Robot


def limit_report(robot: Robot, t: np.ndarray, q: np.ndarray) -> tuple[list[dict[str, Any]], float]:
    """(one entry per joint that leaves its limits, smallest margin to a limit over the plan
    in rad; < 0 = beyond). An entry names the joint, when it first and last is beyond, and its
    farthest excursion (``worst_deg`` at ``worst_t_s`` past ``limit_deg``)."""
    violations = []
    for i, j in enumerate(robot.joints):
        beyond = np.maximum(q[:, i] - j.qlim[1], j.qlim[0] - q[:, i])  # > 0 outside
        bad = beyond > 0
        if bad.any():
            k = int(np.argmax(beyond))
            limit = j.qlim[1] if q[k, i] > j.qlim[1] else j.qlim[0]
            violations.append({"joint": j.name, "first_t_s": float(t[np.argmax(bad)]),
                               "last_t_s": float(t[len(bad) - 1 - np.argmax(bad[::-1])]),
                               "worst_t_s": float(t[k]), "worst_deg": math.degrees(q[k, i]),
                               "limit_deg": math.degrees(limit),
                               "max_abs_deg": float(np.degrees(np.max(np.abs(q[:, i]))))})
    margin = np.minimum(q - robot.qmin, robot.qmax - q)
    return violations, float(np.min(margin))


def check_start_off_limits(robot: Robot, q_start: np.ndarray, criterion: str, source: str) -> None:
    """A joint-limit criterion (Zghal's H_L) is infinite on a limit, so a start exactly there
    sends the arm off the path at once; name the joint instead."""
    for j, value in zip(robot.joints, q_start):
        if value <= j.qlim[0] or value >= j.qlim[1]:
            side, limit = ("lower", j.qlim[0]) if value <= j.qlim[0] else ("upper", j.qlim[1])
            shown = f"{math.degrees(limit):.3f} deg" if j.revolute else f"{limit * 1e3:.3f} mm"
            raise PlanningError(
                f"{source}: the start has joint '{j.name}' sitting on its {side} limit ({shown}), where the "
                f"joint-limit criterion of {criterion} is infinite: start the joint inside its limits (e.g. a degree away), "
                "widen its limits in the robot file, or use a method without a joint-limit criterion")


def enforce_limits(violations: list[dict[str, Any]], policy: str, source: str) -> None:
    """Raise the infeasible-plan error for ``violations`` unless ``policy`` is ``"report"``."""
    if not violations or policy == "report":
        return
    first = min(violations, key=lambda v: v["first_t_s"])
    others = [v["joint"] for v in violations if v is not first]
    raise PlanningError(
        f"{source}: the plan leaves the joint limits: joint '{first['joint']}' passes its limit "
        f"{first['limit_deg']:.2f} deg at t = {first['first_t_s']:.3f} s and reaches {first['worst_deg']:.2f} deg "
        f"at t = {first['worst_t_s']:.3f} s" + (f" (also beyond: {', '.join(others)})" if others else "")
        + "; nothing was written. Change the start, the path or the method; or, to write the plan and inspect "
        "it (a baseline that leaves the limits on purpose), set [check] limits = \"report\" in the task "
        "(or --set check.limits=report)")


PLAYBACK_RATE_RULE = "forward difference of the samples, (q[k+1] - q[k]) / output_step; 0 at the last sample"


def playback_rates(q: np.ndarray, dt: float) -> np.ndarray:
    """The joint rates the controller's sampled playback commands (and its speed guard checks) at
    each sample of a plan sampled every ``dt``: the forward difference to the next sample, the
    rate that reaches it in one tick (docs/firmware.md, "Sampled playback"); 0 at the last
    sample, where the plan ends at rest. A plan within the limits by this rule is one the
    controller plays back without a speed fault."""
    qd = np.zeros_like(q)
    qd[:-1] = np.diff(q, axis=0) / dt
    return qd


# What to change when a plan asks a joint for more than its speed limits, per planner (the
# resolved-rate planners' fixed-duration circle or line otherwise).
SPEED_LIMIT_FIXES = {
    "snake": "The joints turn in proportion to the driven end's speed and the path's curvature: lower motion.v "
             "(raise motion.duration to keep the travel v·(duration − ramp)), lengthen motion.ramp, or widen the "
             "bends (move or add waypoints)",
    "ptp": "Space the knot times further apart (waypoints.t), or, with computed times, lower timing.omega_max "
           "(timing.eps_max) to at most the robot's qdlim (qddlim)",
}
FIXED_DURATION_FIX = ("A fixed-duration path is not slowed down: lengthen timing.duration, or give the path as a program "
                      "(path.type = \"program\"), which is slowed to stay within the limits")


def enforce_speed_limits(report: dict[str, Any] | None, policy: str, source: str, planner: str = "") -> None:
    """Raise the infeasible-plan error for a plan that asks a joint for more than its velocity or
    acceleration limit, unless ``policy`` is ``"report"``: a fixed-duration path (a circle or line
    with ``[timing]``), a snake plan, a ptp plan on a robot. A program is slowed down to stay within
    them instead (its report is ``enforced``), so it never gets here beyond them."""
    if not report or report.get("enforced") or policy == "report" or not report.get("beyond_speed_limits"):
        return
    first = min(report["beyond_speed_limits"], key=lambda v: v["t_s"])
    raise PlanningError(
        f"{source}: the plan asks joint '{first['joint']}' for {first['ratio']:.2f} times its {first['limit']} limit "
        f"(the robot file's {'qdlim' if first['limit'] == 'velocity' else 'qddlim'}) at t = {first['t_s']:.3f} s; "
        f"nothing was written. {SPEED_LIMIT_FIXES.get(planner, FIXED_DURATION_FIX)}; or, to write the plan "
        "and inspect it, set [check] limits = \"report\" in the task (or --set check.limits=report)")


# A ratio up to this counts as within the limit (the rounding of q̇ = J⁺ẋ at the limit).
RATIO_TOL = 1.0 + 1e-9


def speed_ratios(robot: Robot, qd: np.ndarray) -> np.ndarray:
    """|q̇| / q̇_max per sample and joint (0 for an unlimited joint)."""
    return np.abs(qd) / robot.qdlim


def acceleration_ratios(robot: Robot, t: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """|q̈| / q̈_max per sample (differences of q̇ between samples, given at the later one)."""
    qdd = np.zeros_like(qd)
    qdd[1:] = np.diff(qd, axis=0) / np.diff(t)[:, None]
    return np.abs(qdd) / robot.qddlim


def _finite_or_none(values: np.ndarray) -> list[float | None]:
    return [float(v) if math.isfinite(v) else None for v in values]


def speed_report(robot: Robot, t: np.ndarray, qd: np.ndarray, qdd: np.ndarray | None = None) -> dict[str, Any]:
    """Peak |q̇|/q̇_max (and |q̈|/q̈_max) per joint; None for a joint without that limit. q̈ is
    ``qdd`` where the plan has it in closed form (ptp's polynomials), else the differences of q̇."""
    per_sample_v = speed_ratios(robot, qd)
    per_sample_a = acceleration_ratios(robot, t, qd) if qdd is None else np.abs(qdd) / robot.qddlim
    ratio_v, ratio_a = per_sample_v.max(axis=0), per_sample_a.max(axis=0)
    limited_v, limited_a = np.isfinite(robot.qdlim), np.isfinite(robot.qddlim)
    beyond = [{"joint": j.name, "limit": kind, "ratio": float(ratios[k, i]), "t_s": float(t[k])}
              for kind, ratios in (("velocity", per_sample_v), ("acceleration", per_sample_a))
              for i, j in enumerate(robot.joints)
              for k in [int(np.argmax(ratios[:, i]))] if ratios[k, i] > RATIO_TOL]
    return {
        "qdlim": _finite_or_none(robot.qdlim),
        "peak_speed_ratio": [float(r) if ok else None for r, ok in zip(ratio_v, limited_v)],
        "max_speed_ratio": float(ratio_v[limited_v].max()) if limited_v.any() else None,
        "qddlim": _finite_or_none(robot.qddlim),
        "peak_acceleration_ratio": [float(r) if ok else None for r, ok in zip(ratio_a, limited_a)],
        "within_speed_limits": not beyond,
        "beyond_speed_limits": beyond,  # per joint and limit: the worst ratio and when
    }
