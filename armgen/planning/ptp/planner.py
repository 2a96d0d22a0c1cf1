"""Joint-space point-to-point planning through velocity-constrained waypoints (spec 40).

Every joint passes waypoints ``θ_k`` with velocities ``ω_k`` at shared knot times ``t_k``.
The methods, selected by name (:data:`~armgen.planning.ptp.families.METHODS`), are the spline
families of :mod:`~armgen.planning.ptp.families`; :mod:`~armgen.planning.ptp.config` holds the
task (SI), the time solver of :mod:`~armgen.planning.ptp.timing` finds the segment durations
and :mod:`~armgen.planning.ptp.summary` writes the metrics and the plan metadata. This module
plans: knot times, the limit checks, the sampled CSV. With a robot, the plan's joint speeds and
accelerations (the polynomials' own derivatives at the CSV's samples, as the controller's
playback evaluates them) are reported against the robot file's ``qdlim``/``qddlim`` in
``summary.joint_speed``; :func:`armgen.planning.tasks.run_task` applies the task's
``[check] limits`` policy to them (``timing.omega_max``/``eps_max`` are the task's own bounds).
"""

from __future__ import annotations

import math
from typing import Any, Sequence

import numpy as np

from ...errors import PlanningError, TaskFileError
from ..limits import speed_report
from ..result import PlanResult
from .config import PtpConfig, segment_label
from .families import segment_shape, timing_order
from .plans import PtpPlan, plan_with_times
from .segments import SegmentShape, peak_abs
from .summary import joint_metrics, plan_metadata
from .timing import GRID_RTOL, as_interval_lists, choose_duration, intersect_feasible, segment_feasible, solve_segment_time

MAX_SAMPLES = 5_000_000  # a CSV beyond this is a mistaken step, not a plan


def compute_knot_times(config: PtpConfig) -> tuple[np.ndarray, list[dict[str, Any]]]:
    """Knot times from ``ω_max`` (and ``ε_max``), shared by all joints, plus the root report.

    Each segment takes the smallest duration (on the grid, if any) feasible for every joint.
    """
    nseg = config.n_segments
    durations: list[float | None] = [None] * nseg
    report: list[dict[str, Any]] = [{} for _ in range(nseg)]
    solved: dict[tuple[int, int], SegmentShape] = {}  # (joint, segment) -> shape
    for k in timing_order(config.method, nseg):
        shapes = [segment_shape(config.method, jw, k, durations, solved.get((j, k - 1)))
                  for j, jw in enumerate(config.joints)]
        solved.update({(j, k): shape for j, shape in enumerate(shapes)})
        bounds = [(config.omega_max[j, k], None if config.eps_max is None else config.eps_max[j, k]) for j in range(len(shapes))]
        timings = [solve_segment_time(s, *b) for s, b in zip(shapes, bounds)]
        common = intersect_feasible([t.feasible for t in timings])
        chosen = choose_duration(common, config.grid,
                                 lambda T: all(segment_feasible(s, T, *b) for s, b in zip(shapes, bounds)))
        joint_reports = {jw.name: t.as_dict() for jw, t in zip(config.joints, timings)}
        if chosen is None:
            raise PlanningError(_infeasible_message(config, k, common, joint_reports, shapes))
        durations[k] = chosen
        report[k] = {"segment": segment_label(k), "T_s": float(chosen),
                     "minimal_T_s": float(common[0][0]) if common[0][0] > 0 else None,
                     "feasible_T_s": as_interval_lists(common), "joints": joint_reports}
    return np.concatenate(([0.0], np.cumsum(durations))), report


def _infeasible_message(config: PtpConfig, k: int, common: list[tuple[float, float]], joints: dict[str, Any],
                        shapes: Sequence[SegmentShape]) -> str:
    what = "|ω| ≤ timing.omega_max" + (" and |ε| ≤ timing.eps_max" if config.eps_max is not None else "")
    if common and common[0][0] == 0.0 and config.grid is None:
        return (f"{config.source}: {segment_label(k)} keeps the bounds for arbitrarily short durations (θ ends where it "
                "starts), so timing.omega_max does not fix its duration; give waypoints.t or a timing.grid")
    scale, unit = config.angle_scale, config.angle_unit
    details = []
    for (name, rep), shape in zip(joints.items(), shapes):
        start = (f", starts with ε = {shape.eps0 / scale:.6g} {unit}/s² from the segment before"
                 if shape.kind != "cubic" else "")
        details.append(f"joint '{name}': feasible T {rep['feasible_T_s'] or 'none'}, roots "
                       f"{[round(r['T_s'], 6) for r in rep['roots']]}{start}")
    grid = f" on the {config.grid:g} s grid" if config.grid is not None else ""
    return (f"{config.source}: {segment_label(k)}: no duration{grid} keeps {what} for all joints ({'; '.join(details)}); "
            "raise the bounds of this segment, limit the acceleration handed on (timing.eps_max), use a finer "
            "timing.grid, change the waypoint speeds, or give waypoints.t")


def sample_times(knots: np.ndarray, step: float) -> np.ndarray:
    """``t_0 + k·step`` up to the last knot, which is appended when the grid misses it."""
    span = knots[-1] - knots[0]
    count = int(math.floor(span / step + GRID_RTOL))
    if count + 1 > MAX_SAMPLES:
        raise TaskFileError(f"field 'step' = {step:g} s gives {count + 1} samples over {span:g} s (limit {MAX_SAMPLES}); "
                            "use a larger step")
    t = knots[0] + step * np.arange(count + 1)
    if knots[-1] - t[-1] > GRID_RTOL * step:
        t = np.append(t, knots[-1])
    return t


# --------------------------------------------------------------------------- entry point

# Given knot times are checked, not obeyed (the spec-40 example rounds a segment to 5 s and
# exceeds its bound by 4 %); knot times that exceed a segment's bound by more than this
# factor are a mistake, not a rounding, and refused.
MAX_BOUND_OVERSHOOT = 2.0
# Whatever the bounds, a planned joint speed beyond this (about 160 turns per second, 100 times
# the fastest arm joints) comes from knot times too close together, with or without a robot.
MAX_PLANNED_SPEED_RAD_S = 1e3


def _check_given_times(config: PtpConfig, plan: PtpPlan) -> None:
    """Refuse given knot times whose plan is absurdly fast or far beyond the task's own bounds."""
    scale, unit = config.angle_scale, config.angle_unit
    for j, name in enumerate(plan.joint_names):
        for k, (c, d) in enumerate(zip(plan.coeffs[j], np.diff(plan.knots))):
            peak = peak_abs(c, d, 1)
            bound = None if config.omega_max is None else float(config.omega_max[j, k])
            if peak > MAX_PLANNED_SPEED_RAD_S or (bound is not None and peak > MAX_BOUND_OVERSHOOT * bound):
                what = (f"beyond {MAX_PLANNED_SPEED_RAD_S:g} rad/s" if peak > MAX_PLANNED_SPEED_RAD_S else
                        f"over {MAX_BOUND_OVERSHOOT:g} times its timing.omega_max of {bound / scale:.6g} {unit}/s")
                raise PlanningError(
                    f"{config.source}: {segment_label(k)}, joint '{name}': the knot times given in waypoints.t "
                    f"({d:.6g} s for the segment) make the planned speed {peak / scale:.6g} {unit}/s, {what}; "
                    "space the knot times further apart, or remove waypoints.t to compute them from timing.omega_max")


def plan_splines(config: PtpConfig) -> tuple[PtpPlan, list[dict[str, Any]]]:
    """The task's plan (knots given or computed) and the time solver's report (empty if given)."""
    if config.times is not None:
        knots, report = np.asarray(config.times, dtype=float), []
    else:
        knots, report = compute_knot_times(config)
    result = plan_with_times(config, config.method, knots)
    if config.times is not None:
        _check_given_times(config, result)
    for j, jw in enumerate(config.joints):
        if jw.qlim is None:
            continue
        m = joint_metrics(result, j)
        for value, limit, side in ((m["theta_min_rad"], jw.qlim[0], "below"), (m["theta_max_rad"], jw.qlim[1], "above")):
            if (side == "below" and value < limit) or (side == "above" and value > limit):
                scale = config.angle_scale
                raise PlanningError(
                    f"{config.source}: joint '{jw.name}' reaches {value / scale:.6g} {config.angle_unit} between waypoints "
                    f"with method '{config.method}', {side} its limit {limit / scale:.6g} {config.angle_unit}; "
                    "move the waypoints away from the limit, lower the waypoint speeds, or add a waypoint")
    return result, report


def plan(config: PtpConfig, backend: str = "symbolic") -> PlanResult:
    """``armgen plan`` entry: plan, sample θ, ω, ε, jerk at ``step`` (``backend`` unused)."""
    del backend  # the polynomials are evaluated the same way by both backends
    result, report = plan_splines(config)
    t = sample_times(result.knots, config.step)
    columns = ["t_s"]
    blocks = [t[:, None]]
    values = [result.evaluate(t, order) for order in range(4)]
    for j, name in enumerate(result.joint_names):
        columns += [f"theta_{name}_rad", f"omega_{name}_rad_s", f"eps_{name}_rad_s2", f"jerk_{name}_rad_s3"]
        blocks.append(np.column_stack([v[:, j] for v in values]))
    meta = plan_metadata(config, result, report)
    if config.robot_model is not None:
        meta["summary"]["joint_speed"] = speed_report(config.robot_model, t, values[1], values[2]) | {
            "enforced": False, "rate_rule": "the polynomials' derivatives at the samples"}
    return PlanResult(columns, np.hstack(blocks), meta, config=config)
