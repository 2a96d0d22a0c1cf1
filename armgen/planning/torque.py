"""Joint torques of a planned motion against the joints' torque limits (issue 39), and the
policy for them.

For a robot with inertials (:attr:`~armgen.robot.Robot.has_dynamics`) every plan whose columns
give each robot joint's position and rate gets ``summary.joint_torque``: the inverse dynamics
``τ = robot.rnea(q, q̇, q̈)`` at every sample of the plan, and per joint the peak ``|τ|``, when
it occurs and its ratio to the joint's ``taumax``. ``q̇`` is the plan's rate column; ``q̈`` is
the plan's acceleration column where the planner writes one (ptp: the polynomials' second
derivative), else the central differences of ``q̇`` over ``t`` (:data:`DIFFERENCE_RULE`).

A plan that needs more than a joint's ``taumax`` follows the joints' ``[check] limits``
policy like the speed limits (:func:`armgen.planning.limits.enforce_speed_limits`): infeasible
(exit 3, nothing written) unless the task sets ``limits = "report"``. A program is slowed down
to stay within ``taumax`` (:mod:`armgen.planning.toolpath.limits`, by the same torques), and its
block says how much (``slowing``); the other planners only report. A robot without inertials
gets no block, and nothing is slowed for it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Optional

import numpy as np

from ..errors import PlanningError
from ..robot import Robot

# Column families that give one joint's position, rate and (optionally) acceleration, each
# with the unit suffixes a revolute (rad) or prismatic (m) joint's column carries.
# ``{k}`` is the joint's 1-based index, ``{name}`` its name in the robot file.
JOINT_COLUMN_FAMILIES = (
    ("q{k}", "dq{k}", "ddq{k}"),  # the resolved-rate planners (cartesian, fault_tolerant, wgpm)
    ("theta_{name}", "omega_{name}", "eps_{name}"),  # ptp
)
UNIT_SUFFIXES = (("_rad", "_rad_s", "_rad_s2"), ("_m", "_m_s", "_m_s2"))

PLAN_ACCELERATION_RULE = "the plan's own q̈ columns (the planner's closed form at the samples)"
DIFFERENCE_RULE = "central differences of the plan's q̇ columns over t (numpy.gradient; one-sided at the ends)"
SINGLE_SAMPLE_RULE = "a plan of one sample holds its pose: q̈ = 0 (no differences to take)"
NO_JOINT_COLUMNS = ("the plan's columns do not give the time t_s and every robot joint's position and rate "
                    "(q{k}_rad / dq{k}_rad_s or theta_<joint>_rad / omega_<joint>_rad_s), so no joint torques "
                    "were computed")

# A ratio up to this counts as within the limit: the rounding of the inverse dynamics' sums
# (a plan tuned to exactly taumax is feasible).
TORQUE_RATIO_TOL = 1.0 + 1e-9


@dataclass(frozen=True)
class JointColumns:
    """Where a plan's joint columns are: one index per robot joint; ``ddq`` None without them."""

    q: list[int]
    dq: list[int]
    ddq: Optional[list[int]]


def _indices(columns: list[str], stems: list[str], units: tuple[str, ...]) -> Optional[list[int]]:
    """The index of each stem's column (with the first unit suffix of ``units`` that exists),
    or None when a stem has none."""
    found = []
    for stem in stems:
        named = [stem + unit for unit in units if stem + unit in columns]
        if not named:
            return None
        found.append(columns.index(named[0]))
    return found


def joint_columns(robot: Robot, columns: list[str]) -> Optional[JointColumns]:
    """The first column family of :data:`JOINT_COLUMN_FAMILIES` that gives every joint's
    position and rate (in rad or m, whichever the column carries), or None."""
    for family in JOINT_COLUMN_FAMILIES:
        q, dq, ddq = (_indices(columns, [pattern.format(k=k, name=j.name) for k, j in enumerate(robot.joints, start=1)],
                               tuple(units[order] for units in UNIT_SUFFIXES))
                      for order, pattern in enumerate(family))
        if q is not None and dq is not None:
            return JointColumns(q, dq, ddq)
    return None


def _finite_or_none(values: np.ndarray) -> list[Optional[float]]:
    return [float(v) if math.isfinite(v) else None for v in values]


def differenced_accelerations(t: np.ndarray, dq: np.ndarray) -> tuple[np.ndarray, str]:
    """(q̈, the rule) of a plan without q̈ columns: the central differences of ``dq`` over ``t``
    (:data:`DIFFERENCE_RULE`), or 0 for a plan of one sample. A program's torque-limited slowing
    (:mod:`armgen.planning.toolpath.limits`) measures its plans by this rule too, so the plan it
    returns is within ``taumax`` by the report's own reckoning."""
    if len(t) > 1:
        return np.gradient(dq, t, axis=0), DIFFERENCE_RULE
    return np.zeros_like(dq), SINGLE_SAMPLE_RULE


def torque_ratios(robot: Robot, tau: np.ndarray) -> np.ndarray:
    """|τ| / taumax per sample and joint (0 for a joint without ``taumax``)."""
    return np.abs(tau) / robot.taumax


def torque_report(robot: Robot, columns: list[str], data: np.ndarray,
                  slowing: Optional[dict[str, Any]] = None) -> Optional[dict[str, Any]]:
    """``summary.joint_torque`` of a plan (``columns``, ``data`` in SI) of ``robot``; None for a
    robot without inertials. A plan without joint columns (snake) gets a block that says so.
    ``slowing``: a program's torque-limited slowing (how much time it added, and where), kept
    in the block as ``slowing``."""
    if not robot.has_dynamics:
        return None
    found = joint_columns(robot, columns)
    if found is None or "t_s" not in columns:
        return {"computed": False, "reason": NO_JOINT_COLUMNS}
    t = data[:, columns.index("t_s")]
    q, dq = data[:, found.q], data[:, found.dq]
    if found.ddq is not None:
        ddq, rule = data[:, found.ddq], PLAN_ACCELERATION_RULE
    else:
        ddq, rule = differenced_accelerations(t, dq)
    tau = np.abs(robot.rnea(q, dq, ddq))
    taumax = robot.taumax
    peak_at = np.argmax(tau, axis=0)
    peak = tau[peak_at, np.arange(robot.n)]
    limited = np.isfinite(taumax)
    ratio = np.where(limited, peak / np.where(limited, taumax, 1.0), np.nan)
    beyond = [{"joint": j.name, "torque": float(peak[i]), "taumax": float(taumax[i]), "ratio": float(ratio[i]),
               "t_s": float(t[peak_at[i]]), "unit": "N·m" if j.revolute else "N"}
              for i, j in enumerate(robot.joints) if limited[i] and ratio[i] > TORQUE_RATIO_TOL]
    return {
        "computed": True,
        "acceleration_rule": rule,
        "peak_torque": [float(v) for v in peak],  # N·m (N for a prismatic joint)
        "peak_torque_t_s": [float(t[k]) for k in peak_at],
        "taumax": _finite_or_none(taumax),
        "peak_torque_ratio": _finite_or_none(ratio),
        "max_torque_ratio": float(ratio[limited].max()) if limited.any() else None,
        "within_torque_limits": not beyond,
        "beyond_torque_limits": beyond,  # per joint beyond taumax: its peak torque and when
        **({"slowing": slowing} if slowing is not None else {}),
    }


# Where each planner's typed config holds the robot it planned for: a ptp config's
# ``robot_model`` (its ``robot`` is the task's reference), a snake task's ``arm.robot``, the
# others' ``robot``.
ROBOT_ATTRIBUTES = (("robot_model",), ("arm", "robot"), ("robot",))


def planned_robot(config: Any) -> Optional[Robot]:
    """The robot ``config`` (a planner's typed config) planned for, or None (a ptp joint alone)."""
    for path in ROBOT_ATTRIBUTES:
        value = config
        for attribute in path:
            value = getattr(value, attribute, None)
        if isinstance(value, Robot):
            return value
    return None


# What to change when a plan asks a joint for more torque than it has, per planner.
TORQUE_LIMIT_FIXES = {
    "ptp": "Space the knot times further apart (waypoints.t), or, with computed times, lower timing.omega_max "
           "and timing.eps_max",
}
SLOWER_PATH_FIX = "Slow the motion down: lengthen timing.duration (a program: lower path.speed or its moves' speed)"


def enforce_torque_limits(report: Optional[dict[str, Any]], policy: str, source: str, planner: str = "") -> None:
    """Raise the infeasible-plan error for a plan that asks a joint for more than its ``taumax``
    unless ``policy`` is ``"report"``; the joint named is the one whose peak comes first."""
    if not report or policy == "report" or not report.get("beyond_torque_limits"):
        return
    first = min(report["beyond_torque_limits"], key=lambda v: v["t_s"])
    raise PlanningError(
        f"{source}: the plan asks joint '{first['joint']}' for {first['torque']:.4g} {first['unit']} at "
        f"t = {first['t_s']:.3f} s, {first['ratio']:.2f} times its torque limit of {first['taumax']:.4g} "
        f"{first['unit']} (taumax in the robot file, effort in a URDF); nothing was written. "
        f"{TORQUE_LIMIT_FIXES.get(planner, SLOWER_PATH_FIX)}, move the motion where gravity loads the joint less, "
        "or raise taumax if the drive gives more; or, to write the plan and inspect it, set [check] limits = "
        "\"report\" in the task (or --set check.limits=report)")
