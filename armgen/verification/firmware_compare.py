"""A firmware run compared with the plan it reproduces, sample by sample (spec 60, stages
replay, target and run), with the bounds of each precision and why."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ..firmware.configuration import (DEFAULT_POS_ERR_MAX, PLAYBACK_SPEED_RTOL, RESOLVED_MODES, FirmwareTask,
                                     speed_guard)
from ..firmware.output import FAULT_STATE, FirmwareRun
from ..planning.common.collision import plan_distances
from ..planning.limits import playback_rates
from ..planning.result import PlanResult

# --- replay bounds -------------------------------------------------------------------------
# Double: the controller evaluates the planner's formulas in the planner's order through the
# same generated C; what differs is libm (glibc vs CPython/numpy: ≤ 1 ulp per call), BLAS
# summation order in numpy's 3-vector norms and products, and tau**3 vs tau*tau*tau: a few
# ulp (≈ 1e-16 relative) per step. 12 500 open-loop Euler steps integrate these at most
# linearly (≈ 1e4 × 2e-16 × |q| ≈ 1e-12 rad), and the null-space operators only contract
# them. 1e-9 rad (as the C-backend replay) leaves three orders of margin and still catches
# any real divergence (one wrong operation gives ≥ 1e-6 rad). Task error: 1e-9 m likewise.
FW_DOUBLE_BOUND_RAD = 1e-9
FW_DOUBLE_BOUND_M = 1e-9
# Float (Cortex-M4F; the same code built with -D<P>_USE_FLOAT=1): every tick evaluates ~1000
# float operations of relative error ε = 6e-8, and the solve through J Jᵀ amplifies them by
# its condition number (κ ≈ 200 at q0 of spec 20), so q̇ is off by ≲ κ ε |q̇| per tick.
# Compensated (Kahan) summation keeps the integrator from adding one rounding of q (ulp(2.4
# rad) = 2.4e-7) per tick, so over N ticks the q error is at most the sum of the q̇ errors,
# N h κ ε |q̇|max = 12 500 × 0.02 s × 200 × 6e-8 × 0.13 rad/s ≈ 4e-4 rad on the combined plan
# (rounding errors of random sign give ≈ √N times less). Measured there: 3.1e-5 rad (QEMU) and
# 3.2e-5 rad (host float). Bound 1e-3 rad (0.057°): above the worst-case estimate, 30× the
# measurement. The task error the controller reports (|p_d − p| in float; its task-space
# drift is ≲ N h κ ε |ẋ|max ≈ 3e-5 m, FK rounding ≈ 1e-7 m; measured 5e-7 m) gets 1e-4 m.
# With CLIK the task-space part is corrected every tick, so both bounds are conservative there.
FW_FLOAT_BOUND_RAD = 1e-3
FW_FLOAT_BOUND_M = 1e-4
# Playback (PTP): the polynomial is evaluated afresh each tick (no integration), so the error
# is that of one float evaluation of Σ a_j τ^j by Horner's rule, ≈ ε Σ |a_j| τ^j: a few
# ε × |θ|max (≈ 6e-8 × 4.4 rad on spec 40's worked example; measured 4.4e-7 rad there).
# Bound 1e-5 rad and 1e-5 rad/s: 20× the measurement, still 1000× below a wrong coefficient.
FW_FLOAT_PLAYBACK_BOUND_RAD = 1e-5
FW_FLOAT_PLAYBACK_BOUND_RAD_S = 1e-5
# Sampled playback: the command is the table's row, so in double it is the plan's sample
# exactly (the table holds each double by repr) and q̇ = (q_k+1 − q_k)/dt the same IEEE
# operations as numpy's: both 0, under the double bound above. In float each sample is
# rounded once: ≤ 2⁻²⁴ |q| ≤ 3.7e-7 rad for |q| ≤ 2π (snake12: ≤ 1.25 m, 1.05 rad). Bound
# 1e-6 rad (m for a prismatic joint); q̇ then differs by at most twice that over dt (plus one
# rounding of the quotient), so its bound is 2 × 1e-6 / dt — e.g. 2e-4 rad/s at 10 ms.
FW_FLOAT_SAMPLED_BOUND_RAD = 1e-6


@dataclass
class Comparison:
    rows: list[list[Any]]  # [run, quantity, value, bound, ok]
    passed: bool
    max_dq: float = float("nan")
    max_dtask: float = float("nan")
    fault_tick: int | None = None


def bounds_for(precision: str, mode: str, dt: float | None = None) -> tuple[float, float]:
    """The bounds of (q or θ, the second quantity) for a run; sampled playback's velocity bound
    depends on the tick period ``dt`` (NaN without it: a NaN bound passes nothing)."""
    if precision == "double":
        return FW_DOUBLE_BOUND_RAD, FW_DOUBLE_BOUND_M
    if mode == "playback":
        return FW_FLOAT_PLAYBACK_BOUND_RAD, FW_FLOAT_PLAYBACK_BOUND_RAD_S
    if mode == "sampled":
        return FW_FLOAT_SAMPLED_BOUND_RAD, 2.0 * FW_FLOAT_SAMPLED_BOUND_RAD / dt if dt else float("nan")
    return FW_FLOAT_BOUND_RAD, FW_FLOAT_BOUND_M


def _sampled(plan: PlanResult, task: FirmwareTask) -> tuple[np.ndarray, np.ndarray]:
    """A sampled plan's q (robot joint order) and the controller's q̇ rule on it: the forward
    difference (q_k+1 − q_k)/dt, 0 at the last sample."""
    q = np.column_stack([plan.column(task.joints[i]) for i in range(task.robot.n)])
    return q, playback_rates(q, task.dt)




def _expected_fault_ticks(plan: PlanResult, task: FirmwareTask,
                          plan_ticks: np.ndarray) -> tuple[int, int, str] | None:
    """Where a guarded controller must stop, and with which fault: at the plan's first sample
    outside the joint limits (JOINT_LIMIT; the planners do not enforce them) or, in the
    resolved-rate modes, farther than the tracking guard from the path (TRACKING: e.g. a lock
    that leaves the arm unable to follow), or in sampled playback at the first sample whose
    step to the next is faster than the joint's speed limit (SPEED: its q̇ is that step / dt)
    — or, when the plan keeps only every k-th sample, anywhere after the last good sample and
    up to that one."""
    robot = task.robot
    if task.mode == "sampled":
        q, qd = _sampled(plan, task)
        bad_q = ((q > robot.qmax) | (q < robot.qmin)).any(axis=1)
        bad_s = (np.abs(qd) > speed_guard(robot) * (1 + PLAYBACK_SPEED_RTOL)).any(axis=1)
        rows = np.flatnonzero(bad_q | bad_s)
        if not rows.size:
            return None
        r = int(rows[0])  # the limit check comes first on a tick
        return r, r, "JOINT_LIMIT" if bad_q[r] else "SPEED"
    if task.mode in RESOLVED_MODES:
        idx = list(range(robot.n))
        q = np.column_stack([plan.column(f"q{i + 1}_rad") for i in idx])
    else:
        idx = sorted(task.joints)
        q = np.column_stack([plan.column(f"theta_{task.joints[i]}_rad") for i in idx])
    bad_q = ((q > robot.qmax[idx]) | (q < robot.qmin[idx])).any(axis=1)
    bad_e = plan.column("pos_err_m") > DEFAULT_POS_ERR_MAX if task.mode in RESOLVED_MODES else np.zeros_like(bad_q)
    bad_c = _below_clearance(task, q, idx)
    rows = np.flatnonzero(bad_q | bad_e | bad_c)
    if not rows.size:
        return None
    r = int(rows[0])
    hi = int(plan_ticks[r])
    lo = int(plan_ticks[r - 1]) + 1 if r > 0 else hi
    # a tick checks the limits, then the tracking guard, then the command's clearance (controller.c)
    return lo, hi, "JOINT_LIMIT" if bad_q[r] else "TRACKING" if bad_e[r] else "COLLISION"


def _below_clearance(task: FirmwareTask, q: np.ndarray, idx: list[int]) -> np.ndarray:
    """Per plan sample: closer than the task's [collision] clearance, which the controller checks
    every command against (COLLISION); all False without the check, or for a playback plan that
    moves only some of the joints (the others' held values are not in the plan)."""
    if task.collision is None or len(idx) != task.robot.n:
        return np.zeros(len(q), dtype=bool)
    least = plan_distances(task.robot, q, task.collision.obstacles).min(axis=1)
    return least < task.collision.settings.clearance


def compare_with_plan(plan: PlanResult, run: FirmwareRun, task: FirmwareTask, precision: str, label: str,
                      tick_slack: int | None = None) -> Comparison:
    """Sample-by-sample comparison of a firmware run with the plan it reproduces.

    Resolved rate: max |Δq| and max |Δ task error| (|p_d − p|) over the plan's samples;
    playback: max |Δθ| and |Δω|; sampled playback: max |Δq| and |Δq̇| (q̇ by the controller's
    forward-difference rule on the plan's samples). A plan that leaves the joint limits must
    make the controller stop there with CTRL_FAULT_JOINT_LIMIT at that sample (± ``tick_slack``:
    0 in double, 1 in float; likewise TRACKING and sampled playback's SPEED, see
    :func:`_expected_fault_ticks`), holding a finite command inside the limits; otherwise the
    run must end DONE.
    """
    bound_q, bound_2 = bounds_for(precision, task.mode, task.dt)
    slack = tick_slack if tick_slack is not None else (0 if precision == "double" else 1)
    plan_ticks = _plan_ticks(plan, task)
    fw = run.by_tick()
    expected = _expected_fault_ticks(plan, task, plan_ticks)
    fault_ticks = [k for k, row in fw.items() if int(row[-2]) == FAULT_STATE]
    fault_tick = min(fault_ticks) if fault_ticks else None
    stop = fault_tick if fault_tick is not None else task.n_ticks + 1
    use = [(r, k) for r, k in enumerate(plan_ticks) if k < stop]
    missing = [k for _, k in use if k not in fw]
    if missing:
        return Comparison([[label, "samples", f"{len(missing)} plan samples have no firmware tick (first {missing[0]})",
                            "all", False]], False)
    fw_rows = np.array([fw[k] for _, k in use]) if use else np.zeros((0, len(run.columns)))
    (what_q, dq), (what_2, de) = _deviations(plan, run, task, fw_rows, [r for r, _ in use])
    rows = [[label, what, value, bound, bool(np.isfinite(value) and value <= bound)]
            for what, value, bound in ((what_q, dq, bound_q), (what_2, de, bound_2))]
    if expected is None:
        rows.append(_end_row(run, task, fault_tick, label))
    else:
        rows.append(_fault_row(run, task, fw, expected, fault_tick, slack, label))
    held_ok = bool(np.all(np.isfinite(run.data[:, 2:2 + 2 * task.robot.n])))
    rows.append([label, "commands finite", "yes" if held_ok else "NO", "yes", held_ok])
    return Comparison(rows, all(row[-1] for row in rows), dq, de, fault_tick)


def _plan_ticks(plan: PlanResult, task: FirmwareTask) -> np.ndarray:
    """The controller tick of each plan sample: its time over the tick period in the resolved
    modes, one sample a tick in playback."""
    t_plan = plan.column("t_s")
    if task.mode in RESOLVED_MODES:
        return np.rint(t_plan / task.dt).astype(int)
    return np.arange(len(t_plan))


def _deviations(plan: PlanResult, run: FirmwareRun, task: FirmwareTask, fw_rows: np.ndarray,
                plan_rows: list[int]) -> tuple[tuple[str, float], tuple[str, float]]:
    """(what, largest deviation) of the run's ``fw_rows`` from the plan's ``plan_rows``: the
    joint values and the mode's second quantity (task error, q̇ or ω); 0 for no samples."""
    n = task.robot.n
    if task.mode in RESOLVED_MODES:
        q_plan = np.column_stack([plan.column(f"q{i + 1}_rad")[plan_rows] for i in range(n)])
        dq = float(np.max(np.abs(fw_rows[:, 2:2 + n] - q_plan))) if plan_rows else 0.0
        e_plan = plan.column("pos_err_m")[plan_rows]
        de = float(np.max(np.abs(fw_rows[:, run.columns.index("pos_err_m")] - e_plan))) if plan_rows else 0.0
        return ("max |Δq| [rad]", dq), ("max |Δ task error| [m]", de)
    if task.mode == "sampled":
        q_plan, qd_plan = _sampled(plan, task)
        dq = float(np.max(np.abs(fw_rows[:, 2:2 + n] - q_plan[plan_rows]))) if plan_rows else 0.0
        de = float(np.max(np.abs(fw_rows[:, 2 + n:2 + 2 * n] - qd_plan[plan_rows]))) if plan_rows else 0.0
        return ("max |Δq| [rad, m]", dq), ("max |Δq̇| [rad/s, m/s]", de)
    idx = sorted(task.joints)
    th = np.column_stack([plan.column(f"theta_{task.joints[i]}_rad")[plan_rows] for i in idx])
    om = np.column_stack([plan.column(f"omega_{task.joints[i]}_rad_s")[plan_rows] for i in idx])
    dq = float(np.max(np.abs(fw_rows[:, [2 + i for i in idx]] - th))) if plan_rows else 0.0
    de = float(np.max(np.abs(fw_rows[:, [2 + n + i for i in idx]] - om))) if plan_rows else 0.0
    return ("max |Δθ| [rad]", dq), ("max |Δω| [rad/s]", de)


def _end_row(run: FirmwareRun, task: FirmwareTask, fault_tick: int | None, label: str) -> list[Any]:
    """How a run whose plan stays feasible ended: DONE after all its ticks, no fault."""
    last = run.data[-1]
    ok = run.state == "DONE" and run.fault == "NONE" and fault_tick is None
    return [label, "end", f"{run.state}/{run.fault} after {int(last[0])} ticks", f"DONE at {task.n_ticks}",
            ok and int(last[0]) == task.n_ticks]


def _fault_row(run: FirmwareRun, task: FirmwareTask, fw: dict[int, np.ndarray], expected: tuple[int, int, str],
               fault_tick: int | None, slack: int, label: str) -> list[Any]:
    """How a run whose plan leaves the limits (or the tracking guard, or the speed limits)
    ended: the expected fault within ``slack`` ticks of the expected span, holding the last
    command, inside the limits."""
    robot = task.robot
    lo, hi, expected_fault = expected
    ok = run.fault == expected_fault and fault_tick is not None and lo - slack <= fault_tick <= hi + slack
    if ok and fault_tick in fw and fault_tick - 1 in fw:
        held = fw[fault_tick][2:2 + robot.n]
        prev = fw[fault_tick - 1][2:2 + robot.n]
        ok = bool(np.array_equal(held, prev) and np.all(held <= robot.qmax) and np.all(held >= robot.qmin))
    where = f"tick {fault_tick}" if fault_tick is not None else "none"
    span = f"tick {hi}" if lo == hi else f"ticks {lo}..{hi}"
    why = {"JOINT_LIMIT": "limits", "SPEED": "speed limits", "COLLISION": "clearance"}.get(expected_fault,
                                                                                       "tracking guard")
    return [label, f"end (plan leaves the {why})", f"{run.state}/{run.fault} at {where}",
            f"{expected_fault} at {span} (t = {hi * task.dt:.4g} s)", ok]
