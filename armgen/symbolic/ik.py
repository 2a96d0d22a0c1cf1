"""Inverse kinematics: joint angles that put the tool at a pose, as one CasADi SX function.

One definition serves the Python API (:meth:`armgen.robot.Robot.ik`), the generated C
(``<p>_ik``) and ``armgen verify``: the solver is a fixed-count loop
(:mod:`armgen.symbolic.loops`) of one SX step, so the C keeps the step once inside a ``for``
loop and every caller runs the same operations in the same order (double: bit-identical).

The step (damped least squares, Levenberg–Marquardt with Sugihara's damping):

- pose error ``e`` (task rows of ``[p_t − p; θ u]``, ``θ u`` the axis-angle of ``R_t Rᵀ``,
  with θ from ``atan2`` so that small angles keep their digits);
- ``λ = DAMPING_SCALE · ½ eᵀe + DAMPING_FLOOR`` (Sugihara 2011: large far from the target,
  vanishing at it, so the last steps are Gauss–Newton steps and converge quadratically);
- ``Δq = α + Jᵀ (J Jᵀ + λ I)⁻¹ (e − J α)``: the self-motion ``α`` is a descent step of a
  criterion — the Zghal joint-limit index (``use_rest = 0``; its gradient in closed form,
  ``criteria.zghal_safe_gradient``) or ``½‖q − q_rest‖²``
  (``use_rest = 1``) — of length at most NULL_STEP · min(‖e‖, 1) (it fades with the error, so
  the damped step's residual ~ λ‖Jα‖ cannot hold the error above the tolerance);
- ``q ← clamp(q + Δq, q_min, q_max)``: every iterate is inside the limits; the joint that
  the step drives furthest past a limit stops there and the others re-solve (with its column
  of J removed, through the same factorisation: Sherman–Morrison, ``held_joint_step``) for the
  error that leaves — an active-set pass, without which an attempt stalls against a limit
  (panda: 96.5 % → 99.6 % of random poses reached). Holding only the furthest joint (the
  others are clamped after the re-solve) reached more training poses in the same steps than
  holding every joint past a limit with a second factorisation, at ~9 % fewer operations a
  step (panda, 3000 poses of seed 11, tolerance 1e-4: 98.5 against 98.2 % within 49 steps,
  99.9 against 99.6 % within 100; iiwa14, modular8 and the Gen3 within ±0.1 %).

The first attempt starts from the seed turned about the first joint's axis toward the target
(``aligned_seed``; not when ``use_rest`` = 1), and every later attempt's first step is the step
of its configuration turned the same way (``_turned_back``: the turned configuration's J and e
are this one's rotated, so no evaluation is spent on it). An attempt ends after ITERATIONS
evaluations or as soon as it stalls (a step leaves ½‖e‖² above STALL_RATIO of the previous one); the next
one moves the joints that the last step held at a limit, and their neighbours in the chain, to
the next point of a deterministic sequence (a Kronecker sequence over the joint ranges) and
steps on with the others (all move when none was held, and at every FULL_RESEED_EVERY-th
attempt), up to ATTEMPTS attempts.
The state carries the closest configuration seen (smallest ``½‖e‖²``), so a miss returns the
closest one reached. ``max_iterations`` (≤ MAX_ITERATIONS) stops earlier (≤ 0 takes no step: the
initial state is already stopped): a bound on the time
a call may take (on a Cortex-M4F, ~2.6k instructions per step of a 7-DOF arm, counting the
restart and turn code once every five steps, the most often they run: the float C lets the
compiler fuse the step's multiply–adds, ``Loop.fused_float``, and computes what only a restart
or a turn needs in the branches of its selects, ``c_emitter._branched``). Once converged
(position error ≤ ``tol_position`` and orientation error ≤ ``tol_orientation``) or out of
steps, the step is the identity: the generated C leaves its loop there (``Loop.stop``) and the
NumPy evaluation stops those samples, with the same result as running the remaining iterations.
"""

from __future__ import annotations

import hashlib
import math
from dataclasses import dataclass
from functools import cached_property

import casadi as ca
import numpy as np

from . import criteria
from .kinematics import chain, geometric_jacobian
from .loops import fixed_loop
from .replay import BatchFunction
from .steps import ldl_factor, ldl_solve, weighted_gram

# Evaluations per attempt and attempts (the first from the caller's seed): the worst case is
# ITERATIONS × ATTEMPTS steps. LM from a seed converges in ~5–15 steps when it converges at
# all; an attempt that has not converged by then has usually stalled at a joint limit or in a
# local minimum, where a fresh start is cheaper than more steps. 30 attempts (450 steps) reach
# every one of 10 000 training poses (seed 17, not the benchmark's) of iiwa14, panda, modular8
# and the Gen3 at 1e-6; 300 steps leave 3 of panda's and 1 of the Gen3's, 150 steps 12 and 5.
# A caller bounds the time with max_iterations.
ITERATIONS = 15
ATTEMPTS = 30
# The loop's count: a caller's max_iterations below it stops earlier (a bound on the time).
MAX_ITERATIONS = ITERATIONS * ATTEMPTS
# Restart seeds keep this fraction of each joint range from either limit: an attempt that
# starts near a limit often stalls against it (the clamped joint cannot help).
SEED_MARGIN = 0.1
# λ = DAMPING_SCALE·½‖e‖² + DAMPING_FLOOR (Sugihara's E + w̄, with E scaled: 0.03 converged
# on more poses of the bundled arms than 1, 0.3 or 0.1 in the same iterations, 5000 poses).
# The floor (m² / rad²) keeps JJᵀ + λI regular at a singular pose; at 1e-9 it leaves a
# Gauss–Newton step near the target (the residual after a step is ~ λ/σ² of the error).
DAMPING_FLOOR = 1e-9
DAMPING_SCALE = 0.03
# Longest self-motion step (rad): a gentle pull toward the middle of the limits (or q_rest)
# that the task correction dominates while the error is large.
NULL_STEP = 0.1
# An attempt that has stalled restarts at once: from its STALL_AFTER-th evaluation on, a step
# that leaves ½‖e‖² above STALL_RATIO of the previous one ends it. A converging LM run shrinks
# the error by far more than that per step; a stalled one (~99 % of misses: against a joint
# limit) by less. Tuned on 2000 seeded training poses per arm (seeds 7 and 11, not the
# benchmark's) of iiwa14, panda, modular8 and the Gen3: 3–5 and 0.5–0.9 do about equally well.
STALL_AFTER = 4
STALL_RATIO = 0.8
# Every fifth attempt moves all the joints to the sequence's next point; the others move only
# the joints the last step held at a limit. A stalled attempt's free joints often lead the next
# one back into the same local minimum (the same held joints, the same error: panda's misses);
# a fresh start leaves it. Training poses (10 000 per seed, seeds 7, 11, 13 and 17, none the
# benchmark's; tolerance 1e-4), within 43 steps, every 5th / every 3rd / never: modular8
# 99.67–99.76 / 99.33–99.49 / 99.46–99.50 %, panda 97.64–97.91 / 97.00–97.17 / 97.15–97.23 %;
# iiwa14 and the Gen3 within ±0.1 %; every 4th, 6th or 7th: as every 3rd. Within 150 steps
# panda reaches 99.91 % (never: 99.45 %).
FULL_RESEED_EVERY = 5
# Floor of Sherman–Morrison's 1 − uᵀG⁻¹u (held_joint_step), which is 1/(1 + uᵀ(G − uuᵀ)⁻¹u) > 0:
# small only when the held joint's column is one the others cannot replace (the reduced system
# is near-singular). 1e-6 is above float's rounding of 1 − (a number near 1) (6e-8), so the
# float step stays finite, and then damps that step as a floored pivot would.
SHERMAN_MORRISON_FLOOR = 1e-6
# The seed is turned about the first joint's axis only when the tool point and the target each
# lie off that axis by at least this sine of their angle to it, seen from the axis's origin:
# nearer the axis the direction is set by small offsets, not by the arm's reach (iiwa14, the
# Gen3 and modular8 stand upright at the middle of their limits, sine 0, 0.02 and 0.08, and
# turning them by those offsets reached fewer training poses: the Gen3 86 → 72 % within 10
# steps; panda's seed reaches out, sine 0.66). Strict, so a point on the axis never turns.
AZIMUTH_MIN_SINE = 0.25
# sin θ below this is treated as 0 in θ/sin θ (the axis-angle scale): representable in float.
SIN_FLOOR = 1e-30
# The closest error so far starts here (any finite error is smaller; float-representable).
ERROR_START = 1e30
# Default convergence tolerances (the success bar): 1 µm, 1 µrad.
TOL_POSITION = 1e-6
TOL_ORIENTATION = 1e-6
# The tolerances of the float build (m, rad): single precision holds ~6e-8 relative per
# rounding, and a chain of ~10 products of ~1 m links leaves a few 1e-6 of noise in the pose
# error, so 1e-6 is out of reach, 1e-4 well above the noise.
FLOAT_TOL = 1e-4
# A target is a pose when its last row is [0 0 0 1] and its 3×3 part a rotation (RᵀR = I,
# det R > 0), each entry of T[3, :] − [0 0 0 1] and of RᵀR − I within these (a sheared, scaled or
# zero 3×3 part has no orientation to reach: its error's skew part can vanish, so the solver would
# report 0). Double: the default orientation tolerance (TOL_ORIENTATION), so a target that passes
# names an orientation to the accuracy the solver is asked for, far above double rounding (a
# product of 12 rotations: 4e-15). Float (the generated C's float build): 1e-6 would lie within 2×
# of a float rotation's own rounding (a product of 12 rotations in float: 6e-7), so FLOAT_TOL,
# the float IK's tolerance, ~170× above it.
POSE_TOL = TOL_ORIENTATION
FLOAT_POSE_TOL = FLOAT_TOL


def _irrational_steps(n: int) -> list[float]:
    """Per-joint steps of the restart sequence: fractional parts of √prime (a Kronecker
    sequence, well spread over the joint box, no random state)."""
    primes, k = [], 2
    while len(primes) < n:
        if all(k % p for p in primes):
            primes.append(k)
        k += 1
    return [math.sqrt(p) % 1.0 for p in primes]


@dataclass(frozen=True)
class _Layout:
    """Where each quantity sits in the loop state."""

    n: int

    @property
    def q(self) -> slice:
        return slice(0, self.n)

    @property
    def best_q(self) -> slice:
        return slice(self.n, 2 * self.n)

    @property
    def best_error(self) -> int:
        return 2 * self.n

    @property
    def best_position(self) -> int:
        return 2 * self.n + 1

    @property
    def best_orientation(self) -> int:
        return 2 * self.n + 2

    @property
    def k(self) -> int:  # evaluations in the current attempt
        return 2 * self.n + 3

    @property
    def attempt(self) -> int:
        return 2 * self.n + 4

    @property
    def iterations(self) -> int:
        return 2 * self.n + 5

    @property
    def done(self) -> int:  # converged
        return 2 * self.n + 6

    @property
    def previous(self) -> int:  # ½‖e‖² of the previous evaluation in this attempt
        return 2 * self.n + 7

    @property
    def stopped(self) -> int:  # converged or out of iterations: the loop's stop entry
        return 2 * self.n + 8

    @property
    def size(self) -> int:
        return 2 * self.n + 9


def pose_error(tool: ca.SX, target: ca.SX) -> ca.SX:
    """``[p_t − p; θ u]`` (6): θ u the axis-angle of ``R_t Rᵀ`` (base frame), θ = atan2(‖v‖, c)
    with ``v = ½ Σ_i r_i × r_t,i`` (= sin θ u) and ``c = (tr(R_t Rᵀ) − 1)/2``."""
    r, rt = tool[:3, :3], target[:3, :3]
    v = 0.5 * (ca.cross(r[:, 0], rt[:, 0]) + ca.cross(r[:, 1], rt[:, 1]) + ca.cross(r[:, 2], rt[:, 2]))
    c = 0.5 * (ca.dot(r[:, 0], rt[:, 0]) + ca.dot(r[:, 1], rt[:, 1]) + ca.dot(r[:, 2], rt[:, 2]) - 1)
    s = ca.norm_2(v)
    theta = ca.atan2(s, c)
    return ca.vertcat(target[:3, 3] - tool[:3, 3], v * (theta / ca.fmax(s, SIN_FLOOR)))


def _turned_back(target: ca.SX, axis_frame: ca.SX, angle: ca.SX) -> ca.SX:
    """The target turned by −angle about the axis of ``axis_frame`` (its z through its origin):
    Rodrigues' rotation, applied to the target's frame and to its position about the origin."""
    axis, origin = axis_frame[:3, 2], axis_frame[:3, 3]
    cross = ca.skew(axis)
    rotation = ca.SX.eye(3) - ca.sin(angle) * cross + (1 - ca.cos(angle)) * ca.mtimes(cross, cross)
    return ca.vertcat(ca.horzcat(ca.mtimes(rotation, target[:3, :3]),
                                 origin + ca.mtimes(rotation, target[:3, 3] - origin)),
                      target[3, :])


def held_joint_step(jac: ca.SX, factor, q: ca.SX, trial: ca.SX, alpha: ca.SX, solved: ca.SX, qmin, qmax) -> ca.SX:
    """The step after the trial step ``trial − q = α + Jᵀ w`` (``solved`` = w = G⁻¹(e − J α),
    G = J Jᵀ + λI): the joint the trial drives furthest past a limit (relative to its range; the
    first of equals) stops at that limit, and the others re-solve for the error that leaves,
    ``Δq_F = α_F + J_Fᵀ (G − u uᵀ)⁻¹ (e − u δ − J α_F)`` (``u`` the held joint's column, ``δ``
    its move, ``J_F J_Fᵀ + λI = G − u uᵀ``). With ``s = δ − α_h`` the right-hand side is
    ``(e − J α) − u s``, so by Sherman–Morrison, with ``b = G⁻¹ u``, the solution is
    ``w + c b``, ``c = (uᵀw − s uᵀb)/(1 − uᵀb) − s``: one triangular solve pair and one Jᵀ
    product beyond the trial's, no second Gram matrix or factorisation. Joints that still leave
    their range are clamped by the caller. With no joint past a limit this is the trial step
    (u = 0, δ = α_h = 0)."""
    n = q.shape[0]
    # signed excess past the nearer limit, relative to the range (negative inside), as
    # |trial − mid| − half: few comparisons (each costs a compare, a flag transfer and a select
    # on a Cortex-M4F; fabs is one instruction)
    mid, half = ca.DM(0.5 * (qmin + qmax)), ca.DM(0.5 * (qmax - qmin))
    excess = (ca.fabs(trial - mid) - half) / ca.DM(qmax - qmin)
    worst = excess[0]
    for i in range(1, n):
        worst = ca.fmax(worst, excess[i])
    beyond = worst > 0
    held, taken = [], ca.SX(0)
    for i in range(n):
        held.append((excess[i] == worst) * (beyond - taken))
        taken = taken + held[i]
    held = ca.vertcat(*held)
    move = ca.dot(held, ca.if_else(trial > mid, ca.DM(qmax), ca.DM(qmin)) - q)  # to the limit it passed
    shift = move - ca.dot(held, alpha)
    column = ca.mtimes(jac, held)
    b = ldl_solve(factor, column)
    ub = ca.dot(column, b)
    scale = (ca.dot(column, solved) - shift * ub) / ca.fmax(1 - ub, SHERMAN_MORRISON_FLOOR) - shift
    return (1 - held) * (trial - q + scale * ca.mtimes(jac.T, b)) + held * move


class IKDefinition:
    """The IK step, its loop and the ``ik`` function of one robot (built on first use)."""

    def __init__(self, robot):
        self.robot = robot
        self.n = robot.n
        self.layout = _Layout(robot.n)
        rows = list(robot.task_rows)
        self.rows = rows
        self.position_rows = [k for k, row in enumerate(rows) if row < 3]
        self.orientation_rows = [k for k, row in enumerate(rows) if row >= 3]

    def _errors(self, e: ca.SX) -> tuple[ca.SX, ca.SX]:
        def norm(idx):
            return ca.norm_2(e[idx]) if idx else ca.SX(0)
        return norm(self.position_rows), norm(self.orientation_rows)

    @property
    def _tag(self) -> str:
        # loops are registered by name: one per robot kinematics (its file and task rows; the
        # limits and the chain come from the file), short enough for a C identifier
        robot = self.robot
        key = repr((robot.convention, robot.joints, robot.base.tolist(), robot.tool.tolist(), robot.task_rows))
        return f"ik_step_{hashlib.sha256(key.encode()).hexdigest()[:8]}"

    @cached_property
    def step(self) -> ca.Function:
        """(state, T_target, q_rest, use_rest, tol_position, tol_orientation, max_iterations) → next state."""
        robot, n, lay = self.robot, self.n, self.layout
        state = ca.SX.sym("state", lay.size)
        target = ca.SX.sym("T_target", 4, 4)
        q_rest = ca.SX.sym("q_rest", n)
        use_rest, tol_p, tol_o = ca.SX.sym("use_rest"), ca.SX.sym("tol_position"), ca.SX.sym("tol_orientation")
        max_iterations = ca.SX.sym("max_iterations")
        q = state[lay.q]
        axis_frames, _, tool = chain(robot, q)
        jac = geometric_jacobian(robot, axis_frames, tool)[self.rows, :]
        e = pose_error(tool, target)[self.rows]
        energy = 0.5 * ca.dot(e, e)
        pos, ori = self._errors(e)
        converged = ca.logic_and(pos <= tol_p, ori <= tol_o)
        closer = ca.logic_or(energy < state[lay.best_error], converged)
        turning = ca.logic_and(ca.logic_and(state[lay.k] == 0, state[lay.attempt] > 0), use_rest == 0)
        base, e_step = self._step_start(q, axis_frames, tool, target, e, turning)
        energy_step = 0.5 * ca.dot(e_step, e_step)
        alpha = self._self_motion(q, q_rest, use_rest, energy_step)
        stepped, free = self._limited_step(jac, base, e_step, alpha, energy_step)
        restart, reseeded, sequence = self._restart(state, energy, free)
        # one select per joint: a converged step's q is never read again (the state stops there
        # and the answer is best_q, which takes this q); counters by arithmetic, exact on integers
        new = ca.vertcat(
            ca.if_else(reseeded, sequence, stepped),
            ca.if_else(closer, q, state[lay.best_q]),
            ca.if_else(closer, energy, state[lay.best_error]),
            ca.if_else(closer, pos, state[lay.best_position]),
            ca.if_else(closer, ori, state[lay.best_orientation]),
            (state[lay.k] + 1) * (1 - restart),
            state[lay.attempt] + restart,
            state[lay.iterations] + 1,
            converged,
            ca.if_else(restart, ERROR_START, energy),
            ca.logic_or(converged, state[lay.iterations] + 1 >= max_iterations))
        nxt = ca.if_else(state[lay.stopped], state, new)
        return ca.Function(self._tag, [state, target, q_rest, use_rest, tol_p, tol_o, max_iterations], [nxt],
                           ["state", *STEP_CONSTANTS], ["next"])

    def _step_start(self, q: ca.SX, axis_frames, tool: ca.SX, target: ca.SX, e: ca.SX,
                    turning: ca.SX) -> tuple[ca.SX, ca.SX]:
        """(the configuration the step starts from, its pose error). The first evaluation of a
        restarted attempt (``turning``) steps from its configuration turned about the first axis
        toward the target (as the seed, aligned_seed), without an evaluation of its own: the
        turned configuration's J and e are this one's rotated by the turn, so its step is this
        one's toward the target turned back; the C computes the turn only then (a branch of the
        selects on ``turning``)."""
        if not self.robot.joints[0].revolute:
            return q, e
        first, turn = self._turned_first(q, axis_frames, tool, target)
        first = ca.if_else(turn, first, q[0])  # near the axis: no turn (e_turned is then e)
        e_turned = pose_error(tool, _turned_back(target, axis_frames[0], first - q[0]))[self.rows]
        e_step = ca.if_else(turning, e_turned, e)
        return ca.vertcat(ca.if_else(turning, first, q[0]), q[1:]), e_step

    def _self_motion(self, q: ca.SX, q_rest: ca.SX, use_rest: ca.SX, energy_step: ca.SX) -> ca.SX:
        """α: descent on the criterion (Zghal's index, or ½‖q − q_rest‖² with ``use_rest``), at
        most NULL_STEP long, fading with the error."""
        qmin, qmax = self.robot.qmin, self.robot.qmax
        grad = ((1 - use_rest) * criteria.zghal_safe_gradient(q, qmin.tolist(), qmax.tolist())
                + use_rest * (q - q_rest))
        return -NULL_STEP * ca.fmin(ca.sqrt(2 * energy_step), 1) * grad / ca.fmax(ca.norm_2(grad), 1)

    def _limited_step(self, jac: ca.SX, base: ca.SX, e_step: ca.SX, alpha: ca.SX,
                      energy_step: ca.SX) -> tuple[ca.SX, ca.SX]:
        """(the damped step from ``base`` with the joint furthest past a limit held there and the
        rest clamped to the limits; which joints the trial step, before any limit, leaves inside them)."""
        qmin, qmax = self.robot.qmin, self.robot.qmax
        damping = DAMPING_SCALE * energy_step + DAMPING_FLOOR
        factor = ldl_factor(weighted_gram(jac) + damping * ca.SX.eye(len(self.rows)))
        solved = ldl_solve(factor, e_step - ca.mtimes(jac, alpha))
        trial = base + alpha + ca.mtimes(jac.T, solved)
        free = ca.logic_and(trial >= qmin, trial <= qmax)
        stepped = ca.fmin(ca.fmax(base + held_joint_step(jac, factor, base, trial, alpha, solved, qmin, qmax), qmin), qmax)
        return stepped, free

    def _restart(self, state: ca.SX, energy: ca.SX, free: ca.SX) -> tuple[ca.SX, ca.SX, ca.SX]:
        """(whether a new attempt starts, which joints it reseeds, the sequence point they move to).

        A new attempt as soon as this one stalls, or after ITERATIONS evaluations: the joints the
        step held at a limit move to the next point of the sequence and the others step on (a
        stalled attempt is mostly right but for the joints a limit holds: with STALL_AFTER 3,
        reseeding every joint reached 95.1 % of panda's training poses within 45 steps, this
        97.7 %); with none held, all of them move there."""
        lay = self.layout
        qmin, qmax = self.robot.qmin, self.robot.qmax
        capped = state[lay.k] >= ITERATIONS - 1
        restart = ca.logic_or(capped, ca.logic_and(state[lay.k] >= STALL_AFTER,
                                                   energy > STALL_RATIO * state[lay.previous]))
        attempt = state[lay.attempt] + 1
        frac = attempt * ca.DM(_irrational_steps(self.n)) + 0.5
        sequence = qmin + (qmax - qmin) * (SEED_MARGIN + (1 - 2 * SEED_MARGIN) * (frac - ca.floor(frac)))
        held = 1 - free
        # every FULL_RESEED_EVERY-th attempt starts afresh: moving only the held joints can send
        # the others back to the same local minimum, attempt after attempt (attempt/5 is exact
        # for a multiple of 5 and rounds below the next integer otherwise, float included)
        afresh = ca.logic_or(attempt == FULL_RESEED_EVERY * ca.floor(attempt / FULL_RESEED_EVERY),
                             ca.logic_and(capped, ca.sum1(held) == 0))
        # a held joint's neighbours in the chain move with it: they carry the compensation that
        # keeps the attempt on the branch the limit blocks (panda, 3000 training poses each of
        # seeds 7, 11 and 13 at 1e-4: +0.24 to +0.33 % within 49 steps; the other arms ±0.1 %)
        moved = held + ca.vertcat(held[1:], 0) + ca.vertcat(0, held[:-1])  # nonzero: held or beside one
        # which joints to reseed is a select on ``restart`` (not a product), so that the C works
        # it out only at a restart (a branch)
        reseeded = ca.if_else(restart, ca.logic_or(moved, afresh), 0)
        return restart, reseeded, sequence

    def aligned_seed(self, q_seed: ca.SX, target: ca.SX, use_rest: ca.SX) -> ca.SX:
        """The seed turned about the first joint's axis (a revolute one) so that the tool point
        lies in the target's half-plane about that axis, then clamped to the limits: the base
        rotation is the largest and least linear move toward a target beside or behind the arm,
        where a damped least-squares run from the seed often stalls (panda, 3000 training poses
        each of seeds 7 and 11: 69 → 78 % reached within 10 steps, 98.75 → 99.0 % within 49).
        Not with ``use_rest`` = 1: the caller asks for an answer near q_rest, and its seed (by
        default q_rest, e.g. the previous waypoint's solution) is kept as given; nor when the
        tool point or the target lies near the axis (AZIMUTH_MIN_SINE)."""
        robot = self.robot
        q = ca.fmin(ca.fmax(q_seed, robot.qmin), robot.qmax)
        if not robot.joints[0].revolute:
            return q
        axis_frames, _, tool = chain(robot, q)
        first, turn = self._turned_first(q, axis_frames, tool, target)
        return ca.vertcat(ca.if_else(ca.logic_and(turn, use_rest == 0), first, q[0]), q[1:])

    def _turned_first(self, q: ca.SX, axis_frames, tool: ca.SX, target: ca.SX) -> tuple[ca.SX, ca.SX]:
        """(the first joint turned so that the tool point lies in the target's half-plane about
        its axis, then wrapped by a revolution or clamped into its range; whether to turn: both
        points off the axis, AZIMUTH_MIN_SINE)."""
        robot = self.robot
        axis, origin = axis_frames[0][:3, 2], axis_frames[0][:3, 3]
        reach, goal = tool[:3, 3] - origin, target[:3, 3] - origin
        a, b = reach - axis * ca.dot(axis, reach), goal - axis * ca.dot(axis, goal)  # off the axis
        sine, cosine = ca.dot(axis, ca.cross(a, b)), ca.dot(a, b)  # |a||b| (sin, cos) of the turn
        off_axis = ca.logic_and(ca.dot(a, a) > AZIMUTH_MIN_SINE ** 2 * ca.dot(reach, reach),
                                ca.dot(b, b) > AZIMUTH_MIN_SINE ** 2 * ca.dot(goal, goal))
        lo, hi = robot.qmin[0], robot.qmax[0]
        first = q[0] + ca.atan2(sine, cosine)
        # the same turn a revolution the other way when that lands inside the range
        down = ca.logic_and(first > hi, first - 2 * math.pi >= lo)
        up = ca.logic_and(first < lo, first + 2 * math.pi <= hi)
        first = first - 2 * math.pi * down + 2 * math.pi * up
        return ca.fmin(ca.fmax(first, lo), hi), off_axis

    def initial_state(self, q: ca.SX, max_iterations: ca.SX) -> ca.SX:
        """The state before the first step: stopped already unless max_iterations ≥ 1 (≤ 0 or
        NaN takes no step: the outputs are q, errors ERROR_START, 0 iterations, no success)."""
        stopped = ca.logic_not(max_iterations >= 1)
        return ca.vertcat(q, q, ERROR_START, ERROR_START, ERROR_START, 0, 0, 0, 0, ERROR_START, stopped)

    def outputs(self, state: ca.SX) -> list[ca.SX]:
        """q, position_error, orientation_error, iterations, success of a final state."""
        lay = self.layout
        return [state[lay.best_q], state[lay.best_position], state[lay.best_orientation], state[lay.iterations],
                state[lay.done]]

    @cached_property
    def function(self) -> ca.Function:
        """``ik``: the step ITERATIONS × ATTEMPTS times (a fixed loop) from the seed, turned
        toward the target (aligned_seed) and clamped."""
        step = self.step
        constants = [ca.SX.sym(step.name_in(k), step.sparsity_in(k).shape) for k in range(1, step.n_in())]
        q_seed = ca.SX.sym("q_seed", self.n)
        loop = fixed_loop(step, MAX_ITERATIONS, stop=self.layout.stopped, fused_float=True)
        start = self.initial_state(self.aligned_seed(q_seed, constants[0], constants[2]), constants[-1])
        final = loop(start, *constants)
        return ca.Function("ik", [constants[0], q_seed, *constants[1:]], [ca.densify(x) for x in self.outputs(final)],
                           INPUT_NAMES, OUTPUT_NAMES)

    @cached_property
    def errors(self) -> ca.Function:
        """(q, T_target) → (position_error, orientation_error): the solver's own measure of how
        far the tool at q is from the target (task rows), for checking a solution from elsewhere
        (the float C) in double."""
        q, target = ca.SX.sym("q", self.n), ca.SX.sym("T_target", 4, 4)
        axis_frames, _, tool = chain(self.robot, q)
        pos, ori = self._errors(pose_error(tool, target)[self.rows])
        return ca.Function("ik_errors", [q, target], [pos, ori], ["q", "T_target"],
                           ["position_error", "orientation_error"])

    @cached_property
    def batch(self) -> BatchFunction:
        """The NumPy replay of ``function`` (:mod:`armgen.symbolic.replay`)."""
        return BatchFunction(self.function)


STEP_CONSTANTS = ["T_target", "q_rest", "use_rest", "tol_position", "tol_orientation", "max_iterations"]
OUTPUT_NAMES = ["q", "position_error", "orientation_error", "iterations", "success"]
INPUT_NAMES = ["T_target", "q_seed", "q_rest", "use_rest", "tol_position", "tol_orientation", "max_iterations"]


@dataclass(frozen=True)
class IKResult:
    """What :meth:`armgen.robot.Robot.ik` returns (arrays with the batch shape in front for a batch).

    Attributes
    ----------
    q
        The solution, or the closest configuration reached when ``success`` is False; always
        inside the joint limits. Shape ``(n,)`` or ``(..., n)``.
    success
        Position error ≤ ``tol_position`` and orientation error ≤ ``tol_orientation``.
    position_error, orientation_error
        ‖p_target − p(q)‖ (m) and the rotation angle between the target and reached
        orientations (rad), over the robot's task rows.
    iterations
        Steps taken (each one FK and Jacobian), restarts included, and those of the search for a
        collision-free configuration.
    clearance
        The least distance (m; negative when overlapping) at ``q`` over the checked pairs: the
        arm's self pairs and its capsules against the obstacles given. None when nothing was
        checked (a robot without capsules, or ``collision_free=False``).
    colliding
        True where the pose was reached but every configuration found comes closer than the
        clearance asked for (``q`` is then the one that comes least close); ``success`` is False
        there. None when nothing was checked.
    """

    q: np.ndarray
    success: np.ndarray
    position_error: np.ndarray
    orientation_error: np.ndarray
    iterations: np.ndarray
    clearance: np.ndarray | None = None
    colliding: np.ndarray | None = None

    def __bool__(self) -> bool:
        return bool(np.all(self.success))

    @property
    def reason(self) -> str | np.ndarray:
        """Why a pose was not solved ("" where it was): not reached within the tolerances, or no
        collision-free configuration found. A str for one pose, an array of str for a batch."""
        colliding = np.zeros_like(self.success) if self.colliding is None else self.colliding
        clearance = np.full(np.shape(self.success), np.nan) if self.clearance is None else self.clearance
        reasons = np.vectorize(_reason, otypes=[object])(self.success, colliding, self.position_error,
                                                        self.orientation_error, clearance)
        return str(reasons) if reasons.ndim == 0 else reasons.astype(str)


def _reason(success: bool, colliding: bool, position_error: float, orientation_error: float,
            clearance: float) -> str:
    if success:
        return ""
    if colliding:
        return (f"no collision-free configuration was found: every one that reaches the pose comes closer than "
                f"the clearance asked for (the best: least distance {clearance * 1e3:.1f} mm)")
    return (f"not reached within the tolerances: the closest configuration found is {position_error:.3g} m / "
            f"{orientation_error:.3g} rad from the pose")


def sequence_point(qmin: np.ndarray, qmax: np.ndarray, attempt: int) -> np.ndarray:
    """The point of the restart sequence for attempt ``attempt`` (the configuration
    ``IKDefinition._restart`` moves the joints to), in NumPy: a deterministic start spread over
    the middle of the joint ranges, for a caller's own restarts beyond the solver's."""
    frac = attempt * np.array(_irrational_steps(len(qmin))) + 0.5
    return qmin + (qmax - qmin) * (SEED_MARGIN + (1 - 2 * SEED_MARGIN) * (frac - np.floor(frac)))


def check_targets(targets: np.ndarray) -> None:
    """Raise ValueError unless every target of ``targets`` (B, 4, 4) is a pose: finite, last row
    [0 0 0 1] and a rotation for its 3×3 part, within POSE_TOL (the checks and order of the
    generated ``<p>_is_pose``, whose ``<p>_ik`` returns ``<P>_BAD_TARGET`` for such a target)."""
    def where(k: int) -> str:
        return f"pose {k} of the batch" if len(targets) > 1 else "pose"

    finite = np.isfinite(targets).all(axis=(1, 2))
    if not finite.all():
        raise ValueError(f"{where(int(np.argmin(finite)))} holds NaN or inf; give a finite 4x4 homogeneous transform")
    row = np.abs(targets[:, 3, :] - [0.0, 0.0, 0.0, 1.0]).max(axis=1)
    rot = targets[:, :3, :3]
    gram = np.abs(np.einsum("bki,bkj->bij", rot, rot) - np.eye(3)).max(axis=(1, 2))
    det = np.einsum("bi,bi->b", rot[:, :, 0], np.cross(rot[:, :, 1], rot[:, :, 2]))
    for k in range(len(targets)):
        if not row[k] <= POSE_TOL:
            raise ValueError(f"{where(k)}: the last row of a homogeneous transform must be [0, 0, 0, 1] "
                             f"(within {POSE_TOL:g}), got {targets[k, 3].tolist()}")
        if not (gram[k] <= POSE_TOL and det[k] > 0):
            raise ValueError(f"{where(k)}: the 3x3 rotation part is not a rotation (R^T R = I within {POSE_TOL:g}, "
                             "det R = +1); build it e.g. with scipy.spatial.transform.Rotation")


def solve(ik: IKDefinition, targets: np.ndarray, seeds: np.ndarray, q_rest: np.ndarray, use_rest: float,
          tol_position: float, tol_orientation: float, max_iterations: int = MAX_ITERATIONS) -> list[np.ndarray]:
    """Evaluate ``ik`` for ``targets`` (B, 4, 4) from ``seeds`` (B, n) with ``q_rest`` (B, n):
    the outputs (OUTPUT_NAMES), each (rows, B). One pose goes through CasADi's evaluator, a
    batch through the NumPy replay of the same SX (which stops stepping finished samples).
    A target that is not a pose raises ValueError (check_targets). The caller holds ``ik``
    (a robot's is ``robot.symbolic.ik_definition``), so its functions are built once."""
    check_targets(targets)
    batch = targets.shape[0]
    scalars = [float(use_rest), float(tol_position), float(tol_orientation), float(max_iterations)]
    if batch == 1:
        return [np.asarray(x.full()).reshape(-1, 1) for x in ik.function(targets[0], seeds[0], q_rest[0], *scalars)]
    inputs = [targets.transpose(0, 2, 1).reshape(batch, 16).T, seeds.T, q_rest.T,
              *[np.full((1, batch), x) for x in scalars]]
    return ik.batch([np.ascontiguousarray(x) for x in inputs], batch)
