"""Snake-arm tip following along a spline (spec 50): planner ``"snake"``.

Pipeline: task file (:mod:`.schema`, :mod:`.config`) → robot structure (:mod:`.arm`: rail feed + universal
joints) → path spline and rail (:mod:`.spline`) → joint-centre coordinates over time by the exact geometric solver
(:mod:`.exact`) or the paper's denoised multi-link dynamics (:mod:`.dynamics`) →
universal-joint angles (signed form) → forward kinematics on those angles → tip deviation,
chord errors, obstacle clearance (:mod:`.obstacles`), speeds, the joints' speeds against the
robot file's ``qdlim``/``qddlim`` (:func:`~armgen.planning.limits.playback_rates`) → CSV + metadata.

The task file may use mm/deg (``[units]``); everything is SI inside. See ``docs/snake.md``.
"""

from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass
from typing import Any

import numpy as np

from ...errors import PlanningError, TaskFileError
from ..common.collision import TaskCollision, clearance_report
from ..limits import PLAYBACK_RATE_RULE, playback_rates, speed_report
from ..result import PlanResult
from .arm import SnakeArm, recover_angles
from .dynamics import EXPLICIT_METHODS, BarModel, DenoisedDynamics, DynamicsRun
from .exact import joint_rates, solve_exact
from .obstacles import clearances
from .spline import HermiteSpline, Track
from .config import SnakeTask
from .schema import RAIL_TOL, mm

# Joint-angle limits are enforced up to this (rounding of atan2 of exact chords).
ANGLE_LIMIT_TOL = 1e-9  # rad
# The exact solver must meet every chord to this (1e-9 mm, the spec's bar); it reaches ~1e-16 m.
EXACT_CHORD_TOL = 1e-12  # m


@dataclass
class SnakeSolution:
    t: np.ndarray
    s: np.ndarray  # (samples, joints)
    sdot: np.ndarray
    solve_s: float  # wall time of the solver (coordinates over time)
    info: dict[str, Any]


def build_track(task: SnakeTask) -> Track:
    arm = task.arm
    spline = HermiteSpline(task.waypoints, task.start_tangent, task.end_tangent)
    arm_length = arm.n_links * arm.link
    if spline.length < arm_length:
        raise TaskFileError(
            f"{task.source}: field 'path.waypoints' gives a path of {spline.length * 1e3:.1f} mm, shorter than the arm "
            f"({arm.n_links} links × {arm.link * 1e3:g} mm = {arm_length * 1e3:g} mm); extend the path (it must hold the "
            "straight arm on the rail plus the travel)")
    return Track(spline, task.rail_start, arm.rail_dir, arm.max_feed)


def initial_coordinates(task: SnakeTask, track: Track) -> np.ndarray:
    """The arm straight on the rail, base joint at the rail's start (feed 0)."""
    return solve_exact(track, np.array([0.0]), "base", task.arm.n_links, task.arm.link)[0]


def _check_feed(task: SnakeTask, track: Track, feed: np.ndarray, t: np.ndarray) -> None:
    arm = task.arm
    over = feed > arm.max_feed
    if np.any(over):
        k = int(np.argmax(over))
        raise PlanningError(
            f"{task.source}: the base would feed {feed.max() * 1e3:.1f} mm (first beyond the rail at t = {t[k]:.2f} s), "
            f"beyond the rail's {arm.max_feed * 1e3:g} mm (robot joint '{arm.robot.joints[0].name}' limit); lower "
            "motion.v or motion.duration (travel = v·(duration − ramp))")
    if np.any(feed < arm.min_feed - RAIL_TOL):
        raise PlanningError(f"{task.source}: the base would leave the rail's start (feed {feed.min() * 1e3:.3f} mm < "
                            f"{arm.min_feed * 1e3:g} mm)")
    offset = track.rail_offset(float(feed.max()))
    if offset > RAIL_TOL:
        raise TaskFileError(
            f"{task.source}: field 'path.waypoints': the path leaves the rail line by {offset * 1e3:.4g} mm within the "
            f"base's travel ({feed.max() * 1e3:.1f} mm of feed); the path must run straight along the rail there (add "
            "collinear waypoints along the rail, or shorten the travel)")


def run_dynamics(task: SnakeTask, track: Track, s0: np.ndarray, t: np.ndarray) -> tuple[DynamicsRun, BarModel]:
    """The paper's multi-link model from rest at ``s0`` over ``t`` (capped at solver.max_wall_time)."""
    arm = task.arm
    driven_index = 0 if task.driven == "base" else arm.n_links
    model = BarModel(arm.link, task.link_mass, task.EA, task.h)
    off = float(s0[driven_index])
    law = task.law

    def driven_law(tt: float) -> tuple[float, float, float]:
        s, sd, sdd = law.scalar(tt)
        return off + s, sd, sdd

    dyn = DenoisedDynamics(track, model, arm.n_links, driven_index, driven_law)
    return dyn.run(s0, t, task.integrator, task.rtol, task.atol, task.max_wall_time, task.state), model


def solve(task: SnakeTask, track: Track, t: np.ndarray) -> SnakeSolution:
    """Joint coordinates over ``t`` with the task's solver (the exact one also as the reference)."""
    arm = task.arm
    s0 = initial_coordinates(task, track)
    driven_index = 0 if task.driven == "base" else arm.n_links
    rel, rel_d, _ = task.law(t)
    s_drv = s0[driven_index] + rel
    if task.driven == "base":
        _check_feed(task, track, s_drv, t)
    elif s_drv[-1] > track.spline.length:
        raise PlanningError(
            f"{task.source}: the tip would travel to path s = {s_drv[-1] * 1e3:.1f} mm, past the path's end at "
            f"{track.spline.length * 1e3:.1f} mm; extend path.waypoints or lower motion.v or motion.duration "
            "(travel = v·(duration − ramp))")
    started = time.perf_counter()
    try:
        s_exact = solve_exact(track, s_drv, task.driven, arm.n_links, arm.link)
    except PlanningError as exc:
        raise PlanningError(f"{task.source}: {exc}") from None
    exact_s = time.perf_counter() - started
    if task.driven == "tip":
        _check_feed(task, track, s_exact[:, 0], t)
    info: dict[str, Any] = {"initial_coordinates_m": s0.tolist()}
    if task.solver == "exact":
        sdot = joint_rates(track, s_exact, rel_d, task.driven)
        return SnakeSolution(t, s_exact, sdot, time.perf_counter() - started, info)
    run, model = run_dynamics(task, track, s0, t)
    info.update(integrator={"method": task.integrator, "rtol": task.rtol, "atol": task.atol, "state": task.state,
                            "h_s": task.h, "a_h": model.a_h, "b_h": model.b_h, "nfev": run.nfev, "njev": run.njev,
                            "wall_s": run.wall_s, "completed": bool(run.completed), "t_reached_s": run.t_reached,
                            "message": run.message, "explicit": task.integrator in EXPLICIT_METHODS},
                exact_reference_s=exact_s)
    if not run.completed:
        raise PlanningError(
            f"{task.source}: the {'stiff ' if task.h == 0 else ''}integration ({task.integrator}, h = {task.h} s) reached "
            f"t = {run.t_reached:.4g} s of {t[-1]:g} s ({run.message}); raise solver.max_wall_time, or use "
            "solver.h > 0 (the denoised model) with an explicit integrator")
    ds = run.s - s_exact
    info["vs_exact"] = {"max_coordinate_diff_mm": float(np.max(np.abs(ds)) * 1e3)}
    return SnakeSolution(t, run.s, run.sdot, run.wall_s, info)


def _locate(track: Track, task: SnakeTask, s: float) -> str:
    k = int(np.argmin(np.abs(track.spline.knots - s)))
    return f"path s = {s * 1e3:.1f} mm, near path.waypoints[{k}] = {mm(task.waypoints[k])} mm"


def _check_angles(task: SnakeTask, track: Track, sol: SnakeSolution, alpha: np.ndarray, beta: np.ndarray) -> None:
    arm = task.arm
    for which, ang, col in (("α", alpha, 0), ("β", beta, 1)):
        lo, hi = arm.qmin[:, col], arm.qmax[:, col]
        bad = (ang < lo - ANGLE_LIMIT_TOL) | (ang > hi + ANGLE_LIMIT_TOL)
        if np.any(bad):
            excess = np.maximum(ang - hi, lo - ang)
            k, i = np.unravel_index(np.argmax(np.where(bad, excess, -np.inf)), ang.shape)
            joint = arm.robot.joints[1 + 2 * i + col]
            raise PlanningError(
                f"{task.source}: the path bends more than universal joint {i + 1} can: {which}{i + 1} (robot joint "
                f"'{joint.name}') would be {math.degrees(ang[k, i]):.2f}° at t = {sol.t[k]:.2f} s, outside "
                f"[{math.degrees(lo[i]):g}°, {math.degrees(hi[i]):g}°], at {_locate(track, task, float(sol.s[k, i]))}; "
                "widen that bend (larger radius: move or add waypoints) or use a robot with wider joint limits")


def plan(task: SnakeTask, backend: str = "symbolic") -> PlanResult:
    """The task's plan (``backend``: the forward kinematics cross-checked against the numpy chain)."""
    arm = task.arm
    started = time.perf_counter()
    track = build_track(task)
    n_out = int(round(task.law.duration / task.output_step))
    t = np.arange(n_out + 1) * task.output_step
    sol = solve(task, track, t)
    # joint centres, angles (the solver's output) ...
    rec_started = time.perf_counter()
    centres = track.joints(sol.s, 0)[0]
    feed, alpha, beta = recover_angles(arm, centres, task.rail_start)
    recover_s = time.perf_counter() - rec_started
    _check_angles(task, track, sol, alpha, beta)
    # ... and the checks: forward kinematics on the recovered angles
    q = arm.q_vector(feed, alpha, beta)
    place = task.rail_start - arm.base0
    fk_centres = arm.joint_centres(q)[0] + place
    tip = fk_centres[:, -1]
    fk_check = _fk_cross_check(arm, q, tip - place, backend)
    s_tip_guess = sol.s[:, -1]
    _, tip_dev = track.spline.project(tip, s_tip_guess)
    tip_to_planned = np.linalg.norm(tip - centres[:, -1], axis=1)
    chord_err = np.linalg.norm(np.diff(centres, axis=1), axis=2) - arm.link
    if task.solver == "exact" and np.max(np.abs(chord_err)) > EXACT_CHORD_TOL:
        k, i = np.unravel_index(np.argmax(np.abs(chord_err)), chord_err.shape)
        raise PlanningError(f"{task.source}: the exact solver missed link {i + 1}'s chord by {chord_err[k, i]:.3g} m "
                            f"at t = {sol.t[k]:.2f} s ({_locate(track, task, float(sol.s[k, i]))}); the path is not "
                            "smooth enough there (add waypoints)")
    _, ps = track.joints(sol.s, 1)
    speeds = np.linalg.norm(ps, axis=2) * np.abs(sol.sdot)
    clear = clearances(task.obstacles, centres, task.tube_radius) if task.obstacles else {}
    _check_collisions(task, track, sol, clear)
    result = _result(task, sol, feed, alpha, beta, tip, tip_dev, chord_err, speeds, clear)
    result.metadata = _metadata(task, track, sol, alpha, beta, feed, tip_dev, tip_to_planned, chord_err, speeds, clear,
                                fk_centres, centres, fk_check, recover_s, time.perf_counter() - started)
    result.metadata["summary"]["joint_speed"] = speed_report(arm.robot, t, playback_rates(q, task.output_step)) | {
        "enforced": False, "rate_rule": PLAYBACK_RATE_RULE}
    if arm.robot.has_collision:  # the links' capsules against each other and against the task's
        # sphere, capsule, plane and centred box obstacles at every sample (the tube's obstacles are
        # checked above); refused below [collision] clearance (0: contact) by tasks.plan_configured
        report = clearance_report(arm.robot, t, q, task.collision or TaskCollision((), None, {}))
        if report is not None:
            result.metadata["summary"]["collision"] = _named_as_in_the_file(report, task.collision_indices)
    return result


def _fk_cross_check(arm: SnakeArm, q: np.ndarray, tip_base: np.ndarray, backend: str) -> dict[str, Any]:
    """The robot's generated ``fk`` (CasADi interpreter or compiled C) against the numpy chain."""
    if backend == "symbolic":  # the CasADi interpreter, without importing the code generator
        from ...symbolic.model import ModelOptions, SymbolicModel

        fk = SymbolicModel(arm.robot, ModelOptions(("fk",))).function("fk")
    else:
        from ..backends import make_backend

        fk = make_backend(arm.robot, backend, ("fk",)).functions["fk"]
    try:
        T = np.array(fk.map(q.shape[0])(q.T)).reshape(4, q.shape[0], 4)[:3, :, 3].T
    except Exception:  # a Callback without map support: evaluate sample by sample
        T = np.array([np.array(fk(qk))[:3, 3] for qk in q])
    return {"backend": backend, "max_tip_diff_m": float(np.max(np.abs(T - tip_base)))}


def _named_as_in_the_file(report: dict[str, Any], indices: tuple[int, ...]) -> dict[str, Any]:
    """The report with its ``obstacles[j]`` (j among the collision-vocabulary obstacles) renamed by
    the obstacle's index among the task's [[obstacles]], where the tube's obstacles count too."""
    def rename(text: str) -> str:
        return re.sub(r"obstacles\[(\d+)\]", lambda m: f"obstacles[{indices[int(m.group(1))]}]", text)

    return {key: rename(value) if isinstance(value, str) else value for key, value in report.items()}


def _check_collisions(task: SnakeTask, track: Track, sol: SnakeSolution, clear: dict[str, np.ndarray]) -> None:
    for name, c in clear.items():
        if np.min(c) < 0:
            k, i = np.unravel_index(np.argmin(c), c.shape)
            raise PlanningError(
                f"{task.source}: link {i + 1} touches obstacle '{name}' at t = {sol.t[k]:.2f} s (clearance "
                f"{c[k, i] * 1e3:.2f} mm, tube radius {task.tube_radius * 1e3:g} mm), at "
                f"{_locate(track, task, float(sol.s[k, i]))}; move the waypoints away from it")


def _columns(n_links: int, n_joints: int) -> list[str]:
    cols = ["t_s", "feed_m"]
    for i in range(n_links):
        cols += [f"a{i + 1}_rad", f"b{i + 1}_rad"]
    cols += [f"sJ{j + 1}_m" for j in range(n_joints)]
    cols += ["base_speed_m_s", "tip_speed_m_s", "tip_x_m", "tip_y_m", "tip_z_m", "tip_dev_m", "chord_err_max_m",
             "clearance_min_m"]
    return cols


def _result(task, sol, feed, alpha, beta, tip, tip_dev, chord_err, speeds, clear) -> PlanResult:
    n = task.arm.n_links
    angles = np.empty((feed.size, 2 * n))
    angles[:, 0::2], angles[:, 1::2] = alpha, beta
    cmin = np.min(np.stack([c.min(axis=1) for c in clear.values()]), axis=0) if clear else np.full(feed.size, np.inf)
    data = np.column_stack([sol.t, feed, angles, sol.s, speeds[:, 0], speeds[:, -1], tip, tip_dev,
                            np.max(np.abs(chord_err), axis=1), cmin])
    return PlanResult(_columns(n, n + 1), data, {}, config=task)


def _metadata(task, track, sol, alpha, beta, feed, tip_dev, tip_to_planned, chord_err, speeds, clear, fk_centres,
              centres, fk_check, recover_s, total_s) -> dict[str, Any]:
    arm = task.arm
    deg = np.degrees
    summary: dict[str, Any] = {
        "solver": task.solver,
        "driven": task.driven,
        "max_tip_deviation_mm": float(np.max(tip_dev) * 1e3),
        "max_tip_to_planned_point_mm": float(np.max(tip_to_planned) * 1e3),
        "max_chord_error_mm": float(np.max(np.abs(chord_err)) * 1e3),
        "max_chord_error_per_link_mm": (np.max(np.abs(chord_err), axis=0) * 1e3).tolist(),
        "max_joint_centre_fk_error_mm": float(np.max(np.linalg.norm(fk_centres - centres, axis=2)) * 1e3),
        "fk_cross_check": fk_check,
        "max_abs_alpha_deg": deg(np.max(np.abs(alpha), axis=0)).tolist(),
        "max_abs_beta_deg": deg(np.max(np.abs(beta), axis=0)).tolist(),
        "max_abs_joint_angle_deg": float(deg(max(np.max(np.abs(alpha)), np.max(np.abs(beta))))),
        "joint_limit_deg": [float(deg(arm.qmin.min())), float(deg(arm.qmax.max()))],
        "feed_range_mm": [float(feed.min() * 1e3), float(feed.max() * 1e3)],
        "max_base_speed_mm_s": float(np.max(speeds[:, 0]) * 1e3),
        "max_tip_speed_mm_s": float(np.max(speeds[:, -1]) * 1e3),
        "final_tip_mm": mm(fk_centres[-1, -1]),
        "solve_time_s": sol.solve_s,
        "angle_recovery_time_s": recover_s,
        "solver_and_recovery_time_s": sol.solve_s + recover_s,
        "plan_time_s": total_s,
    }
    if clear:
        summary["min_clearance_mm"] = {name: float(np.min(c) * 1e3) for name, c in clear.items()}
        summary["min_clearance_per_link_mm"] = {name: (np.min(c, axis=0) * 1e3).tolist() for name, c in clear.items()}
    summary.update({k: v for k, v in sol.info.items() if k in ("integrator", "vs_exact", "exact_reference_s")})
    spline = track.spline
    return {
        "method": task.solver,
        "robot": {"name": arm.robot.name, "file": arm.robot.source, "sha256": arm.robot.sha256,
                  "qlim_rad": [list(j.qlim) for j in arm.robot.joints], "links": arm.n_links, "link_m": arm.link},
        "path": {"waypoints": len(task.waypoints), "waypoints_m": task.waypoints.tolist(), "length_m": spline.length,
                 "start_tangent": None if task.start_tangent is None else task.start_tangent.tolist(),
                 "end_tangent": None if task.end_tangent is None else task.end_tangent.tolist(),
                 "max_param_speed": spline.max_speed(),
                 "rail_offset_mm": track.rail_offset(float(feed.max())) * 1e3,
                 "knots_m": spline.knots.tolist()},
        "rail": {"start_m": task.rail_start.tolist(), "direction": arm.rail_dir.tolist(), "max_feed_m": arm.max_feed},
        "motion": {"driven": task.driven, "v_m_s": task.law.v, "duration_s": task.law.duration,
                   "ramp_s": task.law.ramp, "travel_m": task.law.travel, "output_step_s": task.output_step},
        "parameters": {"solver": task.solver, "h_s": task.h, "integrator": task.integrator, "rtol": task.rtol,
                       "atol": task.atol, "state": task.state, "max_wall_time_s": task.max_wall_time},
        "links": task.link_props,
        "obstacles": [o.describe() for o in task.obstacles],
        "summary": summary,
    }

