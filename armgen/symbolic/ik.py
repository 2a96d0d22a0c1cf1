"""Inverse kinematics: joint angles that put the tool at a pose, as one CasADi SX function.

One definition serves the Python API (:meth:`armgen.robot.Robot.ik`), the generated C
(``<p>_ik``) and ``armgen verify``: the solver is a fixed-count loop
(:mod:`armgen.symbolic.loops`) of one SX step, so the C keeps the step once inside a ``for``
loop and every caller runs the same operations in the same order (double: bit-identical).

The step (damped least squares, Levenberg–Marquardt with Sugihara's damping):

- pose error ``e`` (task rows of ``[p_t − p; θ u]``, ``θ u`` the axis-angle of ``R_t Rᵀ``,
  with θ from ``atan2`` so that small angles keep their digits);
- ``λ = ½ eᵀe + DAMPING_FLOOR`` (Sugihara 2011: large far from the target, vanishing at it, so
  the last steps are Gauss–Newton steps and converge quadratically);
- ``Δq = α + Jᵀ (J Jᵀ + λ I)⁻¹ (e − J α)``: the self-motion ``α`` is a descent step of a
  criterion — the Zghal joint-limit index (``use_rest = 0``) or ``½‖q − q_rest‖²``
  (``use_rest = 1``) — of length at most NULL_STEP;
- ``q ← clamp(q + Δq, q_min, q_max)``: every iterate is inside the limits.

An attempt has ITERATIONS evaluations; when it misses, the next attempt starts from a
deterministic seed (a Kronecker sequence over the joint ranges), up to ATTEMPTS attempts.
The state carries the closest configuration seen (smallest ``½‖e‖²``), so a miss returns
the closest one reached. Once converged (position error ≤ ``tol_position`` and orientation
error ≤ ``tol_orientation``) the step is the identity: the generated C leaves its loop there
(``Loop.stop``) and the NumPy evaluation stops the converged samples, with the same result as
running the remaining iterations.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property
import hashlib

import casadi as ca
import numpy as np

from . import criteria
from .kinematics import chain, geometric_jacobian
from .loops import fixed_loop, find_loop
from .steps import spd_solve, weighted_gram

# Evaluations per attempt and attempts (the first from the caller's seed): the worst case is
# ITERATIONS × ATTEMPTS steps. LM from a seed converges in ~5–15 steps when it converges at
# all; an attempt that has not converged by then has usually stalled at a joint limit or in a
# local minimum, where a fresh start is cheaper than more steps.
ITERATIONS = 15
ATTEMPTS = 10
# λ = ½‖e‖² + DAMPING_FLOOR: the floor (m² / rad²) keeps JJᵀ + λI regular at a singular pose;
# at 1e-9 it leaves a Gauss–Newton step near the target (the residual after a step is
# ~ λ/σ² of the error, σ² ≥ 1e-4 away from singularities).
DAMPING_FLOOR = 1e-9
DAMPING_SCALE = 0.1
# Longest self-motion step (rad): a gentle pull toward the middle of the limits (or q_rest)
# that the task correction dominates while the error is large.
NULL_STEP = 0.1
# sin θ below this is treated as 0 in θ/sin θ (the axis-angle scale): representable in float.
SIN_FLOOR = 1e-30
# The closest error so far starts here (any finite error is smaller; float-representable).
ERROR_START = 1e30
# Default convergence tolerances (the success bar): 1 µm, 1 µrad.
TOL_POSITION = 1e-6
TOL_ORIENTATION = 1e-6


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
    def done(self) -> int:
        return 2 * self.n + 6

    @property
    def size(self) -> int:
        return 2 * self.n + 7


def pose_error(tool: ca.SX, target: ca.SX) -> ca.SX:
    """``[p_t − p; θ u]`` (6): θ u the axis-angle of ``R_t Rᵀ`` (base frame), θ = atan2(‖v‖, c)
    with ``v = ½ Σ_i r_i × r_t,i`` (= sin θ u) and ``c = (tr(R_t Rᵀ) − 1)/2``."""
    r, rt = tool[:3, :3], target[:3, :3]
    v = 0.5 * (ca.cross(r[:, 0], rt[:, 0]) + ca.cross(r[:, 1], rt[:, 1]) + ca.cross(r[:, 2], rt[:, 2]))
    c = 0.5 * (ca.dot(r[:, 0], rt[:, 0]) + ca.dot(r[:, 1], rt[:, 1]) + ca.dot(r[:, 2], rt[:, 2]) - 1)
    s = ca.norm_2(v)
    theta = ca.atan2(s, c)
    return ca.vertcat(target[:3, 3] - tool[:3, 3], v * (theta / ca.fmax(s, SIN_FLOOR)))


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
        """(state, T_target, q_seed, q_rest, use_rest, tol_position, tol_orientation) → next state."""
        robot, n, lay = self.robot, self.n, self.layout
        qmin, qmax = robot.qmin, robot.qmax
        state = ca.SX.sym("state", lay.size)
        target = ca.SX.sym("T_target", 4, 4)
        q_seed, q_rest = ca.SX.sym("q_seed", n), ca.SX.sym("q_rest", n)
        use_rest, tol_p, tol_o = ca.SX.sym("use_rest"), ca.SX.sym("tol_position"), ca.SX.sym("tol_orientation")
        q = state[lay.q]
        axis_frames, _, tool = chain(robot, q)
        jac = geometric_jacobian(robot, axis_frames, tool)[self.rows, :]
        e = pose_error(tool, target)[self.rows]
        energy = 0.5 * ca.dot(e, e)
        pos, ori = self._errors(e)
        converged = ca.logic_and(pos <= tol_p, ori <= tol_o)
        closer = ca.logic_or(energy < state[lay.best_error], converged)
        # self-motion: descent on the criterion, at most NULL_STEP long
        grad = ((1 - use_rest) * ca.gradient(criteria.zghal_safe(q, qmin.tolist(), qmax.tolist()), q)
                + use_rest * (q - q_rest))
        alpha = -NULL_STEP * ca.fmin(ca.sqrt(2 * energy), 1) * grad / ca.fmax(ca.norm_2(grad), 1)
        gram = weighted_gram(jac) + (DAMPING_SCALE * energy + DAMPING_FLOOR) * ca.SX.eye(len(self.rows))
        dq = alpha + ca.mtimes(jac.T, spd_solve(gram, e - ca.mtimes(jac, alpha)))
        stepped = ca.fmin(ca.fmax(q + dq, qmin), qmax)
        # a new attempt after ITERATIONS evaluations, from the next point of the sequence
        restart = state[lay.k] >= ITERATIONS - 1
        attempt = state[lay.attempt] + 1
        frac = attempt * ca.DM(_irrational_steps(n)) + 0.5
        seed = qmin + (qmax - qmin) * (frac - ca.floor(frac))
        new = ca.vertcat(
            ca.if_else(converged, q, ca.if_else(restart, seed, stepped)),
            ca.if_else(closer, q, state[lay.best_q]),
            ca.if_else(closer, energy, state[lay.best_error]),
            ca.if_else(closer, pos, state[lay.best_position]),
            ca.if_else(closer, ori, state[lay.best_orientation]),
            ca.if_else(restart, 0, state[lay.k] + 1),
            ca.if_else(restart, attempt, state[lay.attempt]),
            state[lay.iterations] + 1,
            converged)
        nxt = ca.if_else(state[lay.done], state, new)
        return ca.Function(self._tag, [state, target, q_seed, q_rest, use_rest, tol_p, tol_o], [nxt],
                           ["state", "T_target", "q_seed", "q_rest", "use_rest", "tol_position", "tol_orientation"],
                           ["next"])

    def initial_state(self, q_seed: ca.SX) -> ca.SX:
        lay, robot = self.layout, self.robot
        q = ca.fmin(ca.fmax(q_seed, robot.qmin), robot.qmax)
        return ca.vertcat(q, q, ERROR_START, ERROR_START, ERROR_START, 0, 0, 0, 0)

    def outputs(self, state: ca.SX) -> list[ca.SX]:
        """q, position_error, orientation_error, iterations, success of a final state."""
        lay = self.layout
        return [state[lay.best_q], state[lay.best_position], state[lay.best_orientation], state[lay.iterations],
                state[lay.done]]

    @cached_property
    def finish(self) -> ca.Function:
        state = ca.SX.sym("state", self.layout.size)
        return ca.Function("ik_finish", [state], self.outputs(state), ["state"], OUTPUT_NAMES)

    @cached_property
    def start(self) -> ca.Function:
        q_seed = ca.SX.sym("q_seed", self.n)
        return ca.Function("ik_start", [q_seed], [self.initial_state(q_seed)], ["q_seed"], ["state"])

    @cached_property
    def function(self) -> ca.Function:
        """``ik``: the step ITERATIONS × ATTEMPTS times (a fixed loop) from the clamped seed."""
        step = self.step
        inputs = [ca.SX.sym(step.name_in(k), step.sparsity_in(k).shape) for k in range(1, step.n_in())]
        loop = fixed_loop(step, ITERATIONS * ATTEMPTS, stop=self.layout.done)
        final = loop(self.initial_state(inputs[1]), *inputs)
        return ca.Function("ik", inputs, [ca.densify(x) for x in self.outputs(final)], step.name_in()[1:],
                           OUTPUT_NAMES)

    def batch(self, function: ca.Function):
        """The NumPy replay of one of the functions above (cached)."""
        from .numeric import BatchFunction

        cache = self.__dict__.setdefault("_batch", {})
        if function.name() not in cache:
            cache[function.name()] = BatchFunction(function)
        return cache[function.name()]

    @property
    def loop(self):
        self.function  # noqa: B018 (registers the loop)
        return find_loop(f"{self._tag}_loop")


OUTPUT_NAMES = ["q", "position_error", "orientation_error", "iterations", "success"]
INPUT_NAMES = ["T_target", "q_seed", "q_rest", "use_rest", "tol_position", "tol_orientation"]


def definition(robot) -> IKDefinition:
    """The (cached) IK definition of a robot."""
    if "ik" not in robot._cache:
        robot._cache["ik"] = IKDefinition(robot)
    return robot._cache["ik"]


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
        Steps taken (each one FK and Jacobian), restarts included.
    """

    q: np.ndarray
    success: np.ndarray
    position_error: np.ndarray
    orientation_error: np.ndarray
    iterations: np.ndarray

    def __bool__(self) -> bool:
        return bool(np.all(self.success))


def solve(robot, targets: np.ndarray, seeds: np.ndarray, q_rest: np.ndarray, use_rest: float,
          tol_position: float, tol_orientation: float) -> list[np.ndarray]:
    """Run the IK of ``targets`` (B, 4, 4) from ``seeds`` (B, n), ``q_rest`` (B, n): the outputs
    (OUTPUT_NAMES), each (B, …). The same operations as the ``ik`` function: its step, repeated
    until every sample has finished or the cap is reached (finished samples are not stepped
    again, the step being the identity for them). One pose goes through CasADi's evaluator
    (fast for one sample), a batch through the NumPy replay of the same SX step."""
    ik = definition(robot)
    lay, batch = ik.layout, targets.shape[0]
    count = ITERATIONS * ATTEMPTS
    constants = [targets.transpose(0, 2, 1).reshape(batch, 16).T, seeds.T, q_rest.T,
                 np.full((1, batch), float(use_rest)), np.full((1, batch), float(tol_position)),
                 np.full((1, batch), float(tol_orientation))]
    if batch == 1:
        step = ik.step
        state = ik.start(seeds[0]).full()
        args = [targets[0], seeds[0], q_rest[0], use_rest, tol_position, tol_orientation]
        for _ in range(count):
            if state[lay.done, 0] != 0:
                break
            state = step(state, *args).full()
    else:
        step = ik.batch(ik.step)
        state = ik.batch(ik.start)([np.ascontiguousarray(seeds.T)], batch)[0]
        active = np.arange(batch)
        for _ in range(count):
            active = active[state[lay.done, active] == 0]
            if active.size == 0:
                break
            state[:, active] = step([state[:, active], *[np.ascontiguousarray(c[:, active]) for c in constants]],
                                    active.size)[0]
    finish = ik.finish
    if batch == 1:
        return [np.asarray(x.full()).reshape(-1, 1) for x in finish(state)]
    return ik.batch(finish)([state], batch)
