"""Keeping a program's plan within the joints' speed limits (``robot.qdlim``, ``robot.qddlim``)
and, for a robot with inertials, their torque limits (``robot.taumax``).

Two stages, in this order:

1. **Self-motion first.** After each step the planner's ``q̇`` is split into the part that
   moves the tool, ``q̇_t = J⁺J q̇`` (on the task rows and the healthy columns), and the
   self-motion ``q̇_n = q̇ − q̇_t`` (``J q̇_n = 0``). When a joint would exceed its limit,
   the self-motion is scaled by the largest ``c ∈ [0, 1]`` that keeps every joint whose
   tool part alone is within its limit inside it: the tool's twist is unchanged.
2. **Then the tool slows down.** Where the tool part alone asks for more, the path speed
   there is capped at what ``qdlim`` allows. Where a joint's acceleration exceeds ``qddlim``,
   the joint path's derivatives ``q′``, ``q″`` along s are measured from the plan and bound
   the time law everywhere (``|q′ s̈| + |q″| ṡ² ≤ qddlim``, :class:`JointAccelerationBounds`).
   Where a joint's torque exceeds ``taumax``, the torque along the path,
   ``τ = m s̈ + c ṡ² + g`` (``m = M q′``, ``c = M q″ + C(q, q′) q′``), bounds the time law the
   same way (``|m| |s̈| + |c| ṡ² ≤ taumax − |g|``, :class:`JointTorqueBounds`); a pose on the
   path where gravity alone takes (almost) all of a joint's ``taumax`` is infeasible.
   The plan is made again with the new time law until it fits. The tool never leaves the
   path; only its timing changes. A joint over its limit where the tool is at rest (which
   slowing cannot help) makes the plan infeasible.

Both are active only for programs (time comes from the program's speed); a circle or line
with a fixed ``[timing]`` duration is planned as given and its peak ``|q̇|/q̇_max`` reported.
"""

from __future__ import annotations

import math
from typing import Any, Callable, NamedTuple

import numpy as np

from ...errors import PlanningError
from ...robot import Robot
from ..limits import RATIO_TOL, acceleration_ratios, speed_ratios, speed_report
from ..torque import TORQUE_RATIO_TOL, differenced_accelerations, torque_ratios
from .accuracy import PathAccuracy, plan_accurately
from .timelaw import JointBounds, PathProfile, ProgramMotion, program_profile

# The slowed speed is this fraction of what the measured ratio allows: q̇ is sampled at the
# steps and the closed loop adds its correction, so a small margin saves a round.
SLOWDOWN_MARGIN = 0.95
# Path speeds below this fraction of the plan's fastest are too slow to measure q′ = q̇ / ṡ
# from (the closed loop's correction over a small ṡ); the cell takes the neighbouring samples'.
MEASURE_SPEED_FRACTION = 0.05
# Rounds of "plan, measure, slow down" before the plan is declared infeasible: the bundled
# examples need at most three, tests/test_acceleration_slowdown.py's programs two to four.
MAX_SLOWDOWN_ROUNDS = 8
# A plan whose tool leaves the program by more than this is infeasible (the Cartesian
# planner's bound for its circle and line: closed-loop tracking stays far below it).
MAX_PROGRAM_PATH_ERROR = 5e-3  # m
# A stretch counts as slowed where the final path speed is this fraction below the nominal one.
SLOWED_FRACTION = 1e-6
# Below this path speed (m/s) the tool is at rest: slowing it further cannot lower q̇.
REST_SPEED = 1e-9
# A joint whose gravity torque somewhere on the path leaves less than this fraction of its
# taumax for moving is refused rather than slowed: the time law's speed there goes as the
# square root of what is left, and the program would crawl (or, at none left, never arrive).
MIN_TORQUE_HEADROOM = 0.01


def saturate_self_motion(qd: np.ndarray, jac: np.ndarray, qdlim: np.ndarray) -> tuple[np.ndarray, float]:
    """(q̇ with its self-motion scaled by c, c); ``jac`` holds the task rows, locked columns zeroed."""
    tool = np.linalg.pinv(jac) @ (jac @ qd)
    null = qd - tool
    fits = np.abs(tool) <= qdlim  # joints the tool part alone overdrives wait for the slowdown
    c = 1.0
    for i in np.flatnonzero(fits & (np.abs(null) > 0)):
        bound = (math.copysign(qdlim[i], null[i]) - tool[i]) / null[i]  # where |tool + c null| reaches the limit
        c = min(c, bound)
    c = max(c, 0.0)
    return tool + c * null, c


class SelfMotionLimiter:
    """Stage 1 inside a planner's step loop: ``limiter(q, q̇, mask)`` → the q̇ to integrate."""

    def __init__(self, robot: Robot, backend, rows: list[int]):
        self.qdlim = robot.qdlim
        self.backend, self.rows = backend, rows
        self.limited_steps = 0

    def __call__(self, q: np.ndarray, qd: np.ndarray, mask: np.ndarray | None = None) -> np.ndarray:
        """``qd`` itself when within the limits, else a new array with the self-motion scaled."""
        if np.all(np.abs(qd) <= self.qdlim):
            return qd
        _, jac = self.backend.call("fk_jacobian", q)
        jac = jac[self.rows] * (1.0 if mask is None else mask)
        out, c = saturate_self_motion(qd, jac, self.qdlim)
        if c < 1.0:
            self.limited_steps += 1
        return out


def _sample_cells(profile, s: np.ndarray, k: int) -> tuple[int, int]:
    """The grid cells (first, last) that decide the measure at sample ``k``: q̈ there is the
    difference of q̇ at samples k−1 and k, each of which depends on the speed around it, so
    the cells from sample k−2 to sample k+1."""
    last = len(profile.s) - 2
    lo = int(np.clip(np.searchsorted(profile.s, s[max(k - 2, 0)], side="right") - 1, 0, last))
    hi = int(np.clip(np.searchsorted(profile.s, s[min(k + 1, len(s) - 1)], side="left") - 1, lo, last))
    return lo, hi


def _speed_caps(profile, s: np.ndarray, ratio_v: np.ndarray) -> np.ndarray:
    """Speed caps at the grid nodes that slow the stretch of each sample over a speed limit to
    ``SLOWDOWN_MARGIN / ratio`` of its current speed (q̇ of the tool's motion scales with ṡ)."""
    cap = np.full(profile.s.size, np.inf)
    for k in np.flatnonzero(ratio_v > RATIO_TOL):
        lo, hi = _sample_cells(profile, s, k)
        cap[lo:hi + 2] = np.minimum(cap[lo:hi + 2], profile.v[lo:hi + 2] * SLOWDOWN_MARGIN / ratio_v[k])
    return cap


def _cell_max(grid: np.ndarray, at: np.ndarray, values: np.ndarray) -> np.ndarray:
    """Per grid cell, the largest of ``values`` (rows given at sorted path lengths ``at``) over
    the samples inside the cell and the nearest one either side."""
    last = at.size - 1
    lo = np.clip(np.searchsorted(at, grid[:-1], side="right") - 1, 0, last)
    hi = np.clip(np.searchsorted(at, grid[1:], side="left"), 0, last)
    return np.array([values[a:b + 1].max(axis=0) for a, b in zip(lo, hi)])


class PathDerivatives(NamedTuple):
    """A plan's joint path along the path length, measured where the tool moves fast enough:
    at the samples (sorted by ``s``) ``q`` and ``q′ = q̇ / ṡ``; between neighbouring samples
    that are not across a stop (an unrounded corner turns q′ there) nor at one ``s``, the
    midpoints ``mid_s``, ``mid_q``, ``mid_dq`` and ``q″`` (differences of q′ along s)."""

    s: np.ndarray
    q: np.ndarray
    dq: np.ndarray
    mid_s: np.ndarray
    mid_q: np.ndarray
    mid_dq: np.ndarray
    ddq: np.ndarray


def path_derivatives(profile: PathProfile, t: np.ndarray, q: np.ndarray, qd: np.ndarray,
                     stops: np.ndarray) -> PathDerivatives:
    """``q′`` and ``q″`` of the plan (samples at ``t``, joint values ``q``, rates ``qd``) driven
    by ``profile``."""
    s, sdot, _ = profile(t)
    fast = sdot >= max(MEASURE_SPEED_FRACTION * sdot.max(), REST_SPEED)
    s, q, dq = s[fast], q[fast], qd[fast] / sdot[fast, None]
    order = np.argsort(s, kind="stable")
    s, q, dq = s[order], q[order], dq[order]
    ds = np.diff(s)
    pairs = (ds > 0) & ~np.any((stops[None, :] > s[:-1, None]) & (stops[None, :] < s[1:, None]), axis=1)
    ddq = np.diff(dq, axis=0)[pairs] / ds[pairs, None]
    return PathDerivatives(s, q, dq, 0.5 * (s[1:] + s[:-1])[pairs], 0.5 * (q[1:] + q[:-1])[pairs],
                           0.5 * (dq[1:] + dq[:-1])[pairs], ddq)


class JointAccelerationBounds:
    """The joint accelerations along the path, ``q̈ = q′ s̈ + q″ ṡ²`` (``q′ = dq/ds``,
    ``q″ = d²q/ds²``), as bounds on the time law (:class:`timelaw.JointBounds`):
    ``|q′ s̈| + |q″| ṡ² ≤ b · qddlim`` on every joint and grid cell, with the budget ``b``
    starting at ``SLOWDOWN_MARGIN``. ``|q′|`` and ``|q″|`` are measured per cell from each
    round's plan (``q′ = q̇ / ṡ``, ``q″`` its differences along s) and kept at their largest
    over the rounds. The bound holds along the whole path, so the slowdown does not move the
    excess to the ramps beside a slowed stretch, as capping the speed there would; a cell
    whose samples still exceed a limit under the bound (the measure was coarse there) lowers
    its budget by the excess for the next round."""

    def __init__(self, grid: np.ndarray, qddlim: np.ndarray, stops: np.ndarray):
        self.grid, self.qddlim, self.stops = grid, qddlim, stops
        cells = grid.size - 1
        self.dq = np.zeros((cells, qddlim.size))
        self.ddq = np.zeros((cells, qddlim.size))
        self.budget = np.full(cells, SLOWDOWN_MARGIN)
        self.bounding = False  # whether the measured plan was made under these bounds

    def measure(self, profile: PathProfile, t: np.ndarray, q: np.ndarray, qd: np.ndarray,
                ratio_a: np.ndarray) -> None:
        if self.bounding:
            s = profile(t)[0]
            for k in np.flatnonzero(ratio_a > RATIO_TOL):
                lo, hi = _sample_cells(profile, s, k)
                self.budget[lo:hi + 1] /= ratio_a[k]
        path = path_derivatives(profile, t, q, qd, self.stops)
        self.dq = np.maximum(self.dq, _cell_max(self.grid, path.s, np.abs(path.dq)))
        if path.mid_s.size:
            self.ddq = np.maximum(self.ddq, _cell_max(self.grid, path.mid_s, np.abs(path.ddq)))

    def bounds(self) -> JointBounds:
        self.bounding = True
        return JointBounds(self.dq, self.ddq, self.budget[:, None] * self.qddlim)


class JointTorqueBounds:
    """The joint torques along the path, ``τ = m s̈ + c ṡ² + g`` with ``m = M q′``,
    ``c = M q″ + C(q, q′) q′`` and ``g`` the gravity torques (``M`` with the motor inertias),
    as bounds on the time law of the same form as :class:`JointAccelerationBounds`':
    ``|m| |s̈| + |c| ṡ² ≤ b · (taumax − |g|)`` per joint with a ``taumax`` and grid cell, the
    budget ``b`` starting at ``SLOWDOWN_MARGIN``. The bound is sufficient whatever the signs
    (it never counts on the motion to help hold a load against gravity). ``m`` and ``c`` come
    from the robot's inverse dynamics at the measured ``q``, ``q′``, ``q″``
    (:func:`path_derivatives`): ``m = rnea(q, 0, q′) − g(q)`` and
    ``c = rnea(q, q′, q″) − g(q)`` at the midpoints between samples; ``|g|`` per cell from every
    sample, at rest too. All three are kept at their largest over the rounds; a cell whose
    samples still exceed ``taumax`` under the bound lowers its budget by the excess of the
    dynamic part, ``(|τ| − |g|) / (taumax − |g|)``."""

    def __init__(self, robot: Robot, grid: np.ndarray, stops: np.ndarray):
        self.robot, self.grid, self.stops = robot, grid, stops
        self.joints = np.flatnonzero(np.isfinite(robot.taumax))
        self.taumax = robot.taumax[self.joints]
        shape = (grid.size - 1, self.joints.size)
        self.inertial, self.velocity, self.gravity = np.zeros(shape), np.zeros(shape), np.zeros(shape)
        self.budget = np.full(grid.size - 1, SLOWDOWN_MARGIN)
        self.bounding = False  # whether the measured plan was made under these bounds

    def _dynamic(self, q: np.ndarray, dq: np.ndarray, ddq: np.ndarray) -> np.ndarray:
        """``|rnea(q, q′, q″) − g(q)|`` on the joints with a ``taumax``."""
        return np.abs(self.robot.rnea(q, dq, ddq) - self.robot.gravity_torques(q))[:, self.joints]

    def measure(self, profile: PathProfile, t: np.ndarray, q: np.ndarray, qd: np.ndarray, tau: np.ndarray,
                gravity: np.ndarray) -> None:
        """Measure a plan (samples at ``t``: ``q``, ``qd``, its torques ``tau`` and gravity
        torques ``gravity``, every joint) made under ``profile``."""
        s = profile(t)[0]
        tau, gravity = np.abs(tau[:, self.joints]), np.abs(gravity[:, self.joints])
        if self.bounding:
            over = tau > self.taumax * TORQUE_RATIO_TOL
            excess = np.where(over, (tau - gravity) / (self.taumax - gravity), 1.0).max(axis=1)
            for k in np.flatnonzero(excess > 1.0):
                lo, hi = _sample_cells(profile, s, k)
                self.budget[lo:hi + 1] /= excess[k]
        order = np.argsort(s, kind="stable")
        self.gravity = np.maximum(self.gravity, _cell_max(self.grid, s[order], gravity[order]))
        path = path_derivatives(profile, t, q, qd, self.stops)
        self.inertial = np.maximum(self.inertial, _cell_max(self.grid, path.s,
                                                            self._dynamic(path.q, np.zeros_like(path.dq), path.dq)))
        if path.mid_s.size:
            self.velocity = np.maximum(self.velocity, _cell_max(self.grid, path.mid_s,
                                                                self._dynamic(path.mid_q, path.mid_dq, path.ddq)))

    def bounds(self) -> JointBounds:
        self.bounding = True
        return JointBounds(self.inertial, self.velocity, self.budget[:, None] * (self.taumax - self.gravity))


def _both(first: JointBounds | None, second: JointBounds | None) -> JointBounds | None:
    """Two sets of bounds on a time law as one (their rows side by side), or the one given."""
    if first is None or second is None:
        return first if second is None else second
    return JointBounds(*(np.hstack(pair) for pair in zip(first, second)))


def _move_named(motion: ProgramMotion, result, k: int) -> str:
    move = int(motion.program.move_at(motion.profile(result.column("t_s")[k])[0])[0])
    return f"path.moves[{move}] ({motion.program.moves[move].kind})"


def _torques(robot: Robot, t: np.ndarray, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(τ, |τ|/taumax per sample: its largest over the joints) of a plan, with q̈ by the torque
    report's rule (:func:`armgen.planning.torque.differenced_accelerations`); no torques
    (zeros) for a robot without inertials or without any ``taumax``."""
    if not robot.has_dynamics or not np.isfinite(robot.taumax).any():
        return np.zeros_like(qd), np.zeros(t.size)
    tau = robot.rnea(q, qd, differenced_accelerations(t, qd)[0])
    return tau, torque_ratios(robot, tau).max(axis=1)


def _unit(robot: Robot, joint: int) -> str:
    return "N·m" if robot.joints[joint].revolute else "N"


def check_gravity_headroom(robot: Robot, motion: ProgramMotion, t: np.ndarray, gravity: np.ndarray,
                           source: str) -> None:
    """Refuse a program that passes a pose where gravity alone takes more than
    ``1 − MIN_TORQUE_HEADROOM`` of a joint's ``taumax`` (no speed makes it feasible), naming the
    first such sample's joint, time, move and torques."""
    share = np.abs(gravity) / robot.taumax
    beyond = share > 1.0 - MIN_TORQUE_HEADROOM
    if not beyond.any():
        return
    k = int(np.argmax(beyond.any(axis=1)))
    joint = int(np.argmax(share[k]))
    move = int(motion.program.move_at(motion.profile(t[k])[0])[0])
    unit, limit = _unit(robot, joint), robot.taumax[joint]
    raise PlanningError(
        f"{source}: joint '{robot.joints[joint].name}' needs {abs(gravity[k, joint]):.4g} {unit} against gravity alone "
        f"at t = {t[k]:.3f} s (path.moves[{move}], {motion.program.moves[move].kind}), {share[k, joint]:.2f} times its "
        f"torque limit of {limit:.4g} {unit} (taumax in the robot file, effort in a URDF): "
        + ("the joint cannot hold that pose" if share[k, joint] > 1.0 else
           f"it leaves less than {MIN_TORQUE_HEADROOM:.0%} of taumax to move with")
        + ", so slowing cannot make the program feasible; nothing was written. Move the program where gravity loads "
        "the joint less (closer to the base, lower), start from another configuration, lighten the tool, or raise "
        "taumax if the drive gives more")


def plan_within_limits(plan: Callable[[ProgramMotion, float], Any], motion: ProgramMotion,
                       angular_speed: float | None, robot: Robot, source: str,
                       samples: Callable[[Any], tuple[np.ndarray, np.ndarray, np.ndarray]], accuracy: PathAccuracy):
    """Stage 2: plan (``plan(motion, step)`` → result, within the path tolerance), measure
    (``samples(result)`` → (t, q, q̇)), slow the tool where a joint exceeds a limit (speed,
    acceleration, torque), plan again. Returns (result, final motion, limits report, torque
    slowing report (None for a robot without inertials or ``taumax``), accuracy report)."""
    nominal = motion
    program = motion.program
    grid = motion.profile.s
    cap = np.full(grid.shape, np.inf)
    joint_acc = JointAccelerationBounds(grid, robot.qddlim, program.stops)
    joint_torque = JointTorqueBounds(robot, grid, program.stops) if robot.has_dynamics else None
    bounds = None  # no joint acceleration bounds until a joint exceeds its qddlim
    torque_bounds = None  # nor torque bounds until one exceeds its taumax
    step = None  # the step the tolerance asked for: a slower time law needs no coarser one
    for _ in range(MAX_SLOWDOWN_ROUNDS):
        current = motion
        result, step, accurate = plan_accurately(
            lambda h: plan(current, h), accuracy, current.duration, source,
            lambda r, k: _move_named(current, r, k), lambda r: check_on_path(r, current, source), step)
        t, q, qd = samples(result)
        ratio_v = speed_ratios(robot, qd).max(axis=1)
        ratio_a = acceleration_ratios(robot, t, qd).max(axis=1)
        tau, ratio_t = _torques(robot, t, q, qd)
        if ratio_v.max() <= RATIO_TOL and ratio_a.max() <= RATIO_TOL and ratio_t.max() <= TORQUE_RATIO_TOL:
            torque = None if joint_torque is None or not joint_torque.joints.size else _torque_slowing(
                program, angular_speed, cap, bounds, torque_bounds, nominal, motion)
            return result, motion, _report(robot, t, qd, nominal, motion), torque, accurate
        s, sdot, _ = motion.profile(t)
        at_rest = (sdot < REST_SPEED) & (ratio_v > RATIO_TOL)
        if at_rest.any():
            k = int(np.argmax(at_rest))
            joint = int(np.argmax(speed_ratios(robot, qd[k])))
            raise PlanningError(
                f"{source}: joint {robot.joints[joint].name} needs {ratio_v[k]:.2f}× its speed limit at t = {t[k]:.2f} s "
                f"while the tool is at rest (move {int(program.move_at(s[k])[0])}): slowing the tool cannot help; "
                "lower the method's gains or the closed-loop gain")
        cap = np.minimum(cap, _speed_caps(motion.profile, s, ratio_v))
        if ratio_a.max() > RATIO_TOL:
            joint_acc.measure(motion.profile, t, q, qd, ratio_a)
            bounds = joint_acc.bounds()
        if ratio_t.max() > TORQUE_RATIO_TOL:
            gravity = robot.gravity_torques(q)
            check_gravity_headroom(robot, motion, t, gravity, source)
            joint_torque.measure(motion.profile, t, q, qd, tau, gravity)
            torque_bounds = joint_torque.bounds()
        motion = ProgramMotion(program, program_profile(program, angular_speed, cap, _both(bounds, torque_bounds)))
    if ratio_t.max() > TORQUE_RATIO_TOL:
        k = int(np.argmax(ratio_t))
        joint = int(np.argmax(torque_ratios(robot, tau[k])))
        unit = _unit(robot, joint)
        raise PlanningError(
            f"{source}: the plan still asks joint '{robot.joints[joint].name}' for {abs(tau[k, joint]):.4g} {unit} at "
            f"t = {t[k]:.3f} s, {ratio_t[k]:.2f} times its torque limit of {robot.taumax[joint]:.4g} {unit}, after "
            f"{MAX_SLOWDOWN_ROUNDS} rounds of slowing the tool (its joint path changes with the timing there: the "
            "method's self-motion or the closed loop); lower path.speed / path.acceleration, lower the method's gains, "
            "or raise taumax if the drive gives more")
    worst = int(np.argmax(np.maximum(ratio_v, ratio_a)))
    raise PlanningError(f"{source}: the plan still exceeds a joint limit ({max(ratio_v.max(), ratio_a.max()):.2f}× "
                        f"at t = {t[worst]:.2f} s) after {MAX_SLOWDOWN_ROUNDS} rounds of slowing the tool; lower "
                        "path.speed / path.acceleration, or start from a configuration further from singularities")


def check_on_path(result, motion: ProgramMotion, source: str) -> None:
    """Refuse a plan whose tool left the program (an unreachable pose or a singularity on the
    way; slowing cannot help), naming the move where it first did."""
    error = result.column("pos_err_m")
    if error.max() <= MAX_PROGRAM_PATH_ERROR:
        return
    k = int(np.argmax(error > MAX_PROGRAM_PATH_ERROR))
    t = result.column("t_s")[k]
    move = int(motion.program.move_at(motion.profile(t)[0])[0])
    raise PlanningError(
        f"{source}: path.moves[{move}] ({motion.program.moves[move].kind}) is not reachable from this start: the tool "
        f"left the program by {error[k] * 1e3:.1f} mm (> {MAX_PROGRAM_PATH_ERROR * 1e3:g} mm) at t = {t:.2f} s; move "
        "its target (position or orientation) into the arm's workspace, or start from another configuration")


def _slowed_zones(program, reference: PathProfile, final: PathProfile) -> list[dict[str, Any]]:
    """The stretches where ``final``'s path speed is below ``reference``'s (same grid): moves,
    path lengths, times (in ``final``) and the slowest fraction of the reference speed."""
    v0, v1 = reference.v, final.v
    slowed = v1 < v0 * (1 - SLOWED_FRACTION)
    zones = []
    edges = np.flatnonzero(np.diff(np.concatenate([[0], slowed.astype(int), [0]])))
    for a, b in zip(edges[::2], edges[1::2] - 1):
        s0, s1 = final.s[a], final.s[b]
        zones.append({"moves": sorted({int(m) for m in program.move_at(final.s[a:b + 1])}),
                      "s_from_mm": s0 * 1e3, "s_to_mm": s1 * 1e3,
                      "t_from_s": float(final.t[a]), "t_to_s": float(final.t[b]),
                      "slowest_speed_fraction": float(np.min(v1[a:b + 1] / v0[a:b + 1]))})
    return zones


def _report(robot: Robot, t: np.ndarray, qd: np.ndarray, nominal: ProgramMotion, final: ProgramMotion) -> dict[str, Any]:
    """The speed report plus the time added by slowing down and where: the stretches where the
    final path speed is below the nominal one (moves, path lengths, times, slowest fraction)."""
    return speed_report(robot, t, qd) | {
        "nominal_duration_s": nominal.duration, "duration_s": final.duration,
        "time_added_s": final.duration - nominal.duration,
        "slowed": _slowed_zones(final.program, nominal.profile, final.profile)}


def _torque_slowing(program, angular_speed: float | None, cap: np.ndarray, bounds: JointBounds | None,
                    torque_bounds: JointBounds | None, nominal: ProgramMotion, final: ProgramMotion) -> dict[str, Any]:
    """``summary.joint_torque.slowing``: the time the torque bounds added, the final time law's
    duration against the one under the speed and acceleration slowing alone (the same caps and
    bounds without the torque rows), and the stretches they slowed."""
    without = final.profile if torque_bounds is None else program_profile(program, angular_speed, cap, bounds)
    return {"enforced": True, "nominal_duration_s": nominal.duration, "duration_without_torque_s": without.duration,
            "duration_s": final.duration, "time_added_s": final.duration - without.duration,
            "slowdown_factor": final.duration / without.duration,
            "slowed": _slowed_zones(program, without, final.profile)}


def plan_samples(result, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(t, q, q̇) of a resolved-rate plan (its ``t_s``, ``q<i>_rad`` and ``dq<i>_rad_s`` columns)."""
    return (result.column("t_s"), np.column_stack([result.column(f"q{i + 1}_rad") for i in range(n)]),
            np.column_stack([result.column(f"dq{i + 1}_rad_s") for i in range(n)]))


def plan_with_speed_limits(run: Callable[[ProgramMotion | None, float], Any], motion: ProgramMotion | None,
                           angular_speed: float | None, robot: Robot, source: str, accuracy: PathAccuracy,
                           duration: float, check_path: Callable[[Any], None] = lambda result: None) -> tuple[Any, float]:
    """``run(motion, step)`` → (PlanResult, the step it used) within the path tolerance
    (``accuracy``; the step is halved as needed), for a program within the joint limits (stage
    2: speed, acceleration and, for a robot with inertials, torque), with ``summary.joint_speed``:
    the report, the time added and where, and whether it was enforced (programs) or only
    measured (a fixed-duration circle or line of ``duration`` s: ``run(None, step)``,
    ``check_path`` refusing a plan whose tool left it); ``summary.path_accuracy``: the
    tolerance, the deviation and the step used; and for a program on a robot with inertials and
    ``taumax``, ``summary.joint_torque.slowing`` (the rest of that block is the torque report
    every plan gets, :func:`armgen.planning.torque.torque_report`)."""
    summary_torque = None
    if motion is None:
        result, _, accurate = plan_accurately(lambda h: run(None, h), accuracy, duration, source,
                                              lambda r, k: "the path", check_path)
        t, _, qd = plan_samples(result, robot.n)
        report = speed_report(robot, t, qd) | {"enforced": False}
    else:
        result, final, report, summary_torque, accurate = plan_within_limits(
            run, motion, angular_speed, robot, source, lambda r: plan_samples(r, robot.n), accuracy)
        report |= {"enforced": True}
        result.metadata.setdefault("path", {}).update(program_metadata(final))
        result.motion = final
    summary = result.metadata.setdefault("summary", {})
    summary["joint_speed"] = report
    summary["path_accuracy"] = accurate
    if summary_torque is not None:
        summary["joint_torque"] = {"slowing": summary_torque}
    return result, accurate["step_s"]


def program_metadata(motion: ProgramMotion) -> dict[str, Any]:
    program = motion.program
    return {"type": "program", "length_mm": program.length * 1e3, "moves": len(program.moves),
            "program_duration_s": motion.duration, "law": "trapezoidal",
            "stops_mm": (program.stops * 1e3).tolist(),
            "blend_zones_mm": [[a * 1e3, b * 1e3] for a, b, _, _ in program.blend_zones()],
            # corners whose blend turned back too sharply to round: the tool stops there
            "unrounded_corners": [{"move": k, "turn_deg": math.degrees(angle)} for k, angle in program.unrounded]}
