"""The PTP plan's summary: per-joint metrics, waypoint errors, bound checks, the method
comparison and the plan metadata written beside the CSV."""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .config import PtpConfig, segment_label
from .plans import PtpPlan, plan_with_times
from .segments import derivative_at, extremes, peak_abs, total_variation
from .timing import FEAS_RTOL


def joint_metrics(plan: PtpPlan, j: int) -> dict[str, Any]:
    """Peak velocity, peak |acceleration|, ε jumps at inner knots, ∫|ε| dt (velocity TV), θ range (SI)."""
    durations = np.diff(plan.knots)
    rows = list(zip(plan.coeffs[j], durations))
    jumps = [abs(derivative_at(rows[k][0], 0.0, 2) - derivative_at(*rows[k - 1], 2))
             for k in range(1, len(rows))]
    theta_range = [extremes(c, d, 0) for c, d in rows]
    return {
        "peak_velocity_rad_s": max(peak_abs(c, d, 1) for c, d in rows),
        "peak_abs_acceleration_rad_s2": max(peak_abs(c, d, 2) for c, d in rows),
        "acceleration_jumps_rad_s2": jumps,
        "max_acceleration_jump_rad_s2": max(jumps, default=0.0),
        "velocity_total_variation_rad_s": sum(total_variation(c, d, 1) for c, d in rows),
        "theta_min_rad": min(lo for lo, _ in theta_range),
        "theta_max_rad": max(hi for _, hi in theta_range),
    }


def waypoint_errors(config: PtpConfig, plan: PtpPlan) -> dict[str, float]:
    """Max |θ − θ_k| and |ω − ω_k| at the knots, from both adjacent segments (SI)."""
    durations = np.diff(plan.knots)
    err_theta = err_omega = 0.0
    for j, jw in enumerate(config.joints):
        for k, (c, d) in enumerate(zip(plan.coeffs[j], durations)):
            for tau, i in ((0.0, k), (d, k + 1)):
                err_theta = max(err_theta, abs(derivative_at(c, tau, 0) - jw.theta[i]))
                err_omega = max(err_omega, abs(derivative_at(c, tau, 1) - jw.omega[i]))
    return {"theta_rad": float(err_theta), "omega_rad_s": float(err_omega)}


def compare_methods(config: PtpConfig, knots: np.ndarray,
                    methods: Sequence[str] = ("cubic", "3-4", "3-5-3")) -> list[dict[str, Any]]:
    """The comparison table: one row per method and joint on the same knots (SI units)."""
    return _comparison_rows([plan_with_times(config, m, knots) for m in methods])


def _comparison_rows(plans: Sequence[PtpPlan]) -> list[dict[str, Any]]:
    rows = []
    for p in plans:
        for j, name in enumerate(p.joint_names):
            metrics = joint_metrics(p, j)
            rows.append({"method": p.method, "joint": name,
                         **{k: v for k, v in metrics.items() if not k.startswith("theta_")}})
    return rows


def bound_check(config: PtpConfig, plan: PtpPlan) -> list[dict[str, Any]]:
    """Per segment and joint: peak |ω| (|ε|) against the timing bounds, when bounds are given."""
    if config.omega_max is None:
        return []
    out = []
    for j, name in enumerate(plan.joint_names):
        for k, (c, d) in enumerate(zip(plan.coeffs[j], np.diff(plan.knots))):
            row = {"segment": segment_label(k), "joint": name, "peak_omega_rad_s": peak_abs(c, d, 1),
                   "omega_max_rad_s": float(config.omega_max[j, k])}
            ok = row["peak_omega_rad_s"] <= row["omega_max_rad_s"] * (1 + FEAS_RTOL)
            if config.eps_max is not None:
                row.update(peak_eps_rad_s2=peak_abs(c, d, 2), eps_max_rad_s2=float(config.eps_max[j, k]))
                ok = ok and row["peak_eps_rad_s2"] <= row["eps_max_rad_s2"] * (1 + FEAS_RTOL)
            row["within_bounds"] = bool(ok)
            out.append(row)
    return out


def plan_metadata(config: PtpConfig, result: PtpPlan, report: list[dict[str, Any]]) -> dict[str, Any]:
    per_joint = {name: joint_metrics(result, j) for j, name in enumerate(result.joint_names)}
    checks = bound_check(config, result)
    # one entry per metric, each {joint: value}: `armgen plan` prints one line per entry
    summary: dict[str, Any] = {"duration_s": float(result.knots[-1] - result.knots[0])}
    for key in per_joint[result.joint_names[0]]:
        summary[key] = {name: metrics[key] for name, metrics in per_joint.items()}
    summary["waypoint_error"] = waypoint_errors(config, result)
    summary["bound_violations"] = sum(not c["within_bounds"] for c in checks)
    meta: dict[str, Any] = {
        "method": config.method,
        "units": {"angle": "rad", "time": "s", "task_angle_unit": config.angle_unit},
        "parameters": {
            "step_s": config.step,
            "times": "given" if config.times is not None else "computed from timing.omega_max",
            "grid_s": config.grid,
            "omega_max_rad_s": None if config.omega_max is None else config.omega_max.tolist(),
            "eps_max_rad_s2": None if config.eps_max is None else config.eps_max.tolist(),
            "robot": config.robot,
        },
        "knot_times_s": result.knots.tolist(),
        "joints": list(result.joint_names),
        "segments": {
            "kinds": list(result.kinds),
            "coefficient_order": "a0..a5 of theta(tau) = sum a_j tau^j, tau = t - knot_times_s[k], rad and s",
            "coefficients": {name: result.coeffs[j].tolist() for j, name in enumerate(result.joint_names)},
        },
        "timing": {"segments": report, "bound_check": checks},
        "summary": summary,
    }
    if config.solved_poses is not None:
        meta["ik"] = {"note": "waypoints given as tool poses, solved each from the previous one (rad)",
                      **config.solved_poses.record()}
    if config.compare:
        plans = {m: plan_with_times(config, m, result.knots) for m in config.compare}
        meta["comparison"] = {
            "methods": list(config.compare),
            "rows": _comparison_rows(list(plans.values())),
            "segments": {m: {"kinds": list(p.kinds),
                             "coefficients": {name: p.coeffs[j].tolist() for j, name in enumerate(p.joint_names)}}
                         for m, p in plans.items()},
        }
    return meta
