"""A task or a plan turned into the controller's C configuration: the text of ``task_params.h``,
which defines ``const ctrl_config fw_task`` (a few parameters for the resolved-rate modes;
knots and coefficients for playback). It is compiled in, so the host and the Cortex-M4F builds
run the identical task.

- :func:`task_from_plan` / :func:`task_from_dict` turn a plan (its ``plan.json``) or a task
  file into a :class:`FirmwareTask`; a program path (``path.type = "program"``) becomes the
  program table of :mod:`.program_table` (geometry and the plan's final time law, after any
  slowing down for the joints' speed limits) beside ``fw_task``; a snake plan becomes a
  sampled joint table (:func:`sampled_task`, ``CTRL_MODE_SAMPLED``);
- :func:`write_task_files` writes ``task_params.h``, the PTP evaluator ``fw_ptp.{h,c}`` and
  ``robot_fw.c`` (the generated functions the controller calls) for the stub's Makefile
  (``armgen firmware-task``).
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..codegen.generate import GENERATED_DIR
from ..codegen.ptp_c import generate_ptp_evaluator
from ..errors import RobotFileError, excerpt
from ..fileio import write_text_atomic
from ..planning.result import PlanResult, read_plan
from ..planning.tasks import apply_overrides, load_task, run_task
from ..planning.toolpath.timelaw import ProgramMotion
from ..robot import Robot, load_robot
from .errors import FirmwareError
from .literals import c_real, c_reals
from .program_table import program_table_c
from .sources import PTP_PREFIX, extract_functions, firmware_functions, robot_prefix

MAX_SEGMENTS = 16  # CTRL_MAX_SEGMENTS default; plans with more segments get a -D
MAX_SAMPLES = 65536  # CTRL_MAX_SAMPLES default (controller.h): the most rows of a sampled table
# s: a sampled plan's times must be t_0 + k·step (the controller ticks at the plan's output
# step); the planners write k·step in double, so 1e-9 s only rejects a grid that is not uniform.
SAMPLE_TIME_TOL_S = 1e-9

# Controller guards written into every task (see controller.h and docs/firmware.md).
# rad/s: the speed guard of a joint whose robot file gives no qdlim (also the singular-pose
# guard), far above the bundled plans (< 0.5 rad/s); a joint with a qdlim is guarded by it.
DEFAULT_QDOT_MAX = 3.0
# rad/s²: MOVE_TO's acceleration of a joint whose robot file gives no qddlim (a moderate
# industrial-arm figure: 0 → 3 rad/s in 0.3 s).
DEFAULT_QDDOT_MAX = 10.0
# ctrl_init's bounds of the limits (controller.c, same names): a joint's speed and acceleration
# limits at most these, and a MOVE_TO over its whole range (profile accelerating over
# MOVE_TO_BLEND of the time at the limits times 1 - MOVE_TO_MARGIN) within 2^24 ticks.
QDOT_MAX_LIMIT = 1.0e3
QDDOT_MAX_LIMIT = 1.0e4
MOVE_TO_BLEND = 0.25
MOVE_TO_MARGIN = 1e-3
MOVE_TO_MAX_TICKS = 2.0 ** 24
# The playback guards' slack (controller.c PLAYBACK_STEP_RTOL): a joint's speed may reach its
# guard times (1 + this) before SPEED.
PLAYBACK_SPEED_RTOL = 1e-3
# A program plan read from disk is planned again; its samples must come back to this (the
# CSV holds the doubles exactly; a plan made with another backend differs by ~1e-12, far
# below the double controller's 1e-9 replay bound, while another path or time law differs
# by far more).
REPLANNED_SAMPLE_TOL = 1e-9
DEFAULT_RESIDUAL_REL = 1e-3  # |J q̇ − ẋ|∞ ≤ 1e-3 |ẋ|∞ + 1e-6: float rounding stays below 1e-5
DEFAULT_RESIDUAL_ABS = 1e-6
DEFAULT_POS_ERR_MAX = 5e-3  # m: the planner's own MAX_PATH_ERROR

# Controller modes that integrate a Cartesian task on board (compared by q and task error).
RESOLVED_MODES = ("resolved_rate", "fault_tolerant", "weighted_gpm")
METHOD_IDS = {"pinv": "CTRL_METHOD_PINV", "repetitive": "CTRL_METHOD_REPETITIVE", "zghal": "CTRL_METHOD_ZGHAL",
              "zghal_improved": "CTRL_METHOD_ZGHAL_IMPROVED", "combined": "CTRL_METHOD_COMBINED"}
LAW_IDS = {"cubic": "CTRL_LAW_CUBIC", "trapezoidal": "CTRL_LAW_TRAPEZOIDAL", "constant": "CTRL_LAW_CONSTANT"}


@dataclass
class FirmwareTask:
    """What the controller runs: the text of ``task_params.h`` plus what the comparison needs."""

    robot: Robot
    mode: str  # "resolved_rate" | "playback" | "fault_tolerant" | "weighted_gpm" | "sampled"
    header: str
    dt: float
    n_ticks: int  # index of the last tick
    source: str = ""
    output_every: int = 1
    joints: dict[int, str] = field(default_factory=dict)  # playback: robot joint -> plan joint name;
                                                           # sampled: robot joint -> plan column
    nseg: int = 0
    lock_tick: int = -1  # the runners report the joints of lock_mask locked from this tick (-1: never)
    lock_mask: int = 0

    @property
    def max_segments(self) -> int:
        return max(MAX_SEGMENTS, self.nseg)


def _blend(law, source: str) -> str:
    """The time law's blend for the controller, which checks it whatever the law: [0, 0.5]."""
    if not (math.isfinite(law.blend) and 0.0 <= law.blend <= 0.5):
        raise FirmwareError(f"{source}: timing.blend = {law.blend!r} must be in [0, 0.5] (the fraction of the duration "
                            "spent accelerating), also when the time law does not use it")
    return f".blend = {c_real(law.blend)},"


PROGRAM_TABLE = "fw_program_table"  # the program table's name in task_params.h


def _header(robot: Robot, source: str, body: list[str], comment: str, lock_tick: int = -1, lock_mask: int = 0,
            tables: Sequence[str] = ()) -> str:
    """The text of task_params.h; ``tables``: lines defining const data fw_task points to."""
    n = robot.n
    lines = [
        "/*",
        " * Task parameters of the armgen joint controller: `fw_task` (see controller.h).",
        f" * Generated by armgen.firmware from {Path(source).name or 'a task'}; do not edit.",
        f" * Robot '{robot.name}' ({n} DOF), robot file sha256 {robot.sha256}.",
        f" * {comment}",
        " */",
        f"typedef char fw_task_check_ndof[(CTRL_NDOF == {n}) ? 1 : -1]; /* built for the right robot */",
        f"typedef char fw_task_check_ntask[(CTRL_NTASK == {len(robot.task_rows)}) ? 1 : -1];",
        "",
        *tables,
        "const ctrl_config fw_task = {",
        *[f"    {line}" for line in body],
        "};",
        "",
        "/* The runners' drive model: from tick fw_lock_tick (-1: never) ctrl_input.locked reports the",
        " * joints of fw_lock_mask (bit i: joint i) locked. */",
        f"const uint32_t fw_lock_mask = {int(lock_mask)}u;",
        f"const int32_t fw_lock_tick = {int(lock_tick)};",
        "",
    ]
    return "\n".join(lines)


def speed_guard(robot: Robot) -> np.ndarray:
    """The controller's speed limit per joint: the robot file's qdlim, else DEFAULT_QDOT_MAX."""
    return np.where(np.isfinite(robot.qdlim), robot.qdlim, DEFAULT_QDOT_MAX)


def acceleration_limit(robot: Robot) -> np.ndarray:
    """MOVE_TO's acceleration per joint: the robot file's qddlim, else DEFAULT_QDDOT_MAX."""
    return np.where(np.isfinite(robot.qddlim), robot.qddlim, DEFAULT_QDDOT_MAX)


def check_controller_limits(robot: Robot, dt: float) -> None:
    """Refuse, while writing the project, the speed and acceleration limits that the controller's
    ``ctrl_init`` would refuse at run time (BAD_CONFIG): its bounds, mirrored from controller.c."""
    b, keep = MOVE_TO_BLEND, 1.0 - MOVE_TO_MARGIN
    qdot, qddot = speed_guard(robot), acceleration_limit(robot)
    for i, joint in enumerate(robot.joints):
        travel = float(robot.qmax[i] - robot.qmin[i])
        if not np.isfinite(travel):
            raise RobotFileError(f"robot '{robot.name}', joint {joint.name}: no finite position limits; the controller "
                                 f"needs them: give the joint a qlim in the robot file")
        ticks = max(travel / ((1.0 - b) * keep * qdot[i]), np.sqrt(travel / (b * (1.0 - b) * keep * qddot[i]))) / dt
        if qdot[i] > QDOT_MAX_LIMIT or qddot[i] > QDDOT_MAX_LIMIT or not ticks <= MOVE_TO_MAX_TICKS:
            raise RobotFileError(
                f"robot '{robot.name}', joint {joint.name}: qdlim = {qdot[i]:.6g}, qddlim = {qddot[i]:.6g} (SI) at a "
                f"{dt:g} s tick are outside what the controller takes (qdlim ≤ {QDOT_MAX_LIMIT:g}, qddlim ≤ "
                f"{QDDOT_MAX_LIMIT:g}, and a move over the joint's whole range within {MOVE_TO_MAX_TICKS:.0f} "
                f"ticks: here {ticks:.3g}); raise the limits in the robot file or lengthen the tick")


def _common_fields(robot: Robot, mode: str, dt: float, q_start: np.ndarray) -> list[str]:
    check_controller_limits(robot, dt)
    return [
        f".mode = {mode},",
        f".dt = {c_real(dt)},",
        f".q_start = {c_reals(q_start)},",
        f".q_min = {c_reals(robot.qmin)},",
        f".q_max = {c_reals(robot.qmax)},",
        f".qdot_max = {c_reals(speed_guard(robot))},",
        f".qddot_max = {c_reals(acceleration_limit(robot))},",
        f".residual_rel = {c_real(DEFAULT_RESIDUAL_REL)},",
        f".residual_abs = {c_real(DEFAULT_RESIDUAL_ABS)},",
        f".pos_err_max = {c_real(DEFAULT_POS_ERR_MAX)},",
    ]


def _program_fields(duration: float) -> list[str]:
    """The ``rr`` path fields of a program: the table and the plan's duration (whole ticks)."""
    return [
        ".path = CTRL_PATH_PROGRAM,",
        f".program = &{PROGRAM_TABLE},",
        f".duration = {c_real(duration)},",
        ".law = CTRL_LAW_CONSTANT, .blend = CTRL_LIT(0.0),",
        ".relative = 0,",
        f".turns = {c_real(1.0)},",
    ]


def _program_table(motion: ProgramMotion | None) -> list[str]:
    """The lines of the program table ``fw_task.rr.program`` points to (none for a circle or line)."""
    return [] if motion is None else [program_table_c(motion, PROGRAM_TABLE), ""]


def _need_motion(motion: ProgramMotion | None, source: str) -> ProgramMotion:
    if motion is None:  # task_from_plan / task_from_dict always pass the plan's
        raise FirmwareError(f"{source}: a program task needs its plan's time law; plan it first (armgen plan)")
    return motion


def cartesian_task(task: dict[str, Any], source: str, motion: ProgramMotion | None = None) -> FirmwareTask:
    """Resolved-rate parameters from a ``planner = "cartesian"`` task dict; a program path
    runs ``motion`` (the plan's final time law)."""
    from ..planning.cartesian.planner import CartesianPlanner, parse_cartesian_task

    parsed = parse_cartesian_task(json.loads(json.dumps(task)), source)
    if parsed.motion is not None:
        parsed = parsed.with_motion(_need_motion(motion, source))
    if parsed.integrator != "euler":
        raise FirmwareError(f"{source}: integrator.method = {excerpt(repr(parsed.integrator))}: the controller integrates with "
                            "explicit Euler, one step per tick; re-plan with integrator.method = \"euler\"")
    robot = parsed.robot
    mp = parsed.method
    axis, angle = np.array([0.0, 0.0, 1.0]), 0.0
    if parsed.end_rotation is not None:  # the planner's own axis/angle (from its FK of the start)
        path = CartesianPlanner(parsed, "symbolic").path
        axis, angle = path.axis_local, float(path.angle)
    steps = int(round(parsed.duration / parsed.step))
    if parsed.motion is not None:
        path_fields = _program_fields(parsed.duration)
    else:
        path_fields = [
            f".path = {'CTRL_PATH_CIRCLE' if parsed.path_type == 'circle' else 'CTRL_PATH_LINE'},",
            f".via = {c_reals(parsed.via if parsed.via is not None else np.zeros(3))},",
            f".end = {c_reals(parsed.end)},",
            f".rot_axis = {c_reals(axis)},",
            f".rot_angle = {c_real(angle)},",
            f".duration = {c_real(parsed.duration)},",
            f".law = {LAW_IDS[parsed.law.kind]},",
            _blend(parsed.law, source),
            ".relative = 0,",
            f".turns = {c_real(1.0)},",
        ]
    rr = [
        *path_fields,
        f".method = {METHOD_IDS[mp.name]},",
        f".rho_R = {c_real(mp.rho_R)}, .T_smo_R = {c_real(mp.T_smo_R)},",
        f".rho_L = {c_real(mp.rho_L)}, .theta_s = {c_real(mp.theta_s)},",
        f".T_smo_L = {c_real(mp.T_smo_L)}, .T_sum_L = {c_real(mp.T_sum_L)},",
        f".gamma_R_ramp = {c_real(mp.gamma_R_ramp)},",
        f".clik_gain = {c_real(parsed.clik_gain)},",
        # λ = 0: the planner damps only below σ_min = ε, which no bundled plan reaches; plans
        # that used damping are refused by compare_with_plan (summary.damped_steps > 0).
        f".damping = {c_real(0.0)},",
        ".task_rows = {" + ", ".join(str(r) for r in robot.task_rows) + "},",
    ]
    body = _common_fields(robot, "CTRL_MODE_RESOLVED_RATE", parsed.step, parsed.q_start)
    body += [".rr = {", *[f"    {line}" for line in rr], "},"]
    law = "the plan's trapezoidal" if parsed.motion is not None else parsed.law.kind
    comment = (f"Resolved rate: {parsed.path_type}, {law} law over {parsed.duration:g} s, method "
               f"{mp.name}, Euler h = {parsed.step:g} s ({steps} steps), CLIK gain {parsed.clik_gain:g}.")
    header = _header(robot, source, body, comment, tables=_program_table(parsed.motion))
    return FirmwareTask(robot, "resolved_rate", header, parsed.step, steps, source, parsed.output_every)


def _ptp_robot(meta: dict[str, Any], robot: Robot | None, source: str) -> tuple[Robot, dict[int, str]]:
    names = list(meta.get("joints", []))
    plan_robot = (meta.get("parameters") or {}).get("robot")
    if robot is None:
        if plan_robot is None:
            raise FirmwareError(f"{source}: the PTP plan names no robot; give the robot to play it on")
        robot = load_robot(plan_robot)
    robot_names = [j.name for j in robot.joints]
    if plan_robot is not None and all(n in robot_names for n in names):
        return robot, {robot_names.index(n): n for n in names}
    if len(names) == 1:  # a single-joint plan drives the robot's first joint
        return robot, {0: names[0]}
    raise FirmwareError(f"{source}: the PTP plan's joints {names} are not joints of robot '{robot.name}' "
                        f"({', '.join(robot_names)})")


def playback_task(plan: PlanResult, source: str, robot: Robot | None = None) -> FirmwareTask:
    """Playback parameters (knots, coefficients) from a ``planner = "ptp"`` plan's metadata."""
    meta = plan.metadata
    if "segments" not in meta or "knot_times_s" not in meta:
        raise FirmwareError(f"{source}: no segment coefficients in the plan metadata (plan.json of a ptp plan)")
    robot, joints = _ptp_robot(meta, robot, source)
    knots = np.asarray(meta["knot_times_s"], dtype=float)
    nseg = len(knots) - 1
    if knots.ndim != 1 or nseg < 1 or not np.all(np.isfinite(knots)) or not np.all(np.diff(knots) > 0):
        raise FirmwareError(f"{source}: knot_times_s = {excerpt(knots.tolist())} must be at least two finite, strictly "
                            "increasing times; regenerate plan.json with armgen plan")
    coeffs = meta["segments"]["coefficients"]
    t = plan.column("t_s")
    dt = float(meta.get("parameters", {}).get("step_s") or (t[1] - t[0]))
    q_start = np.zeros(robot.n)
    for i in range(robot.n):  # held joints: 0, or mid-range when 0 is outside the limits
        lo, hi = robot.joints[i].qlim
        q_start[i] = 0.0 if lo <= 0.0 <= hi else 0.5 * (lo + hi)
    active = [0] * robot.n
    rows = []
    for i, name in sorted(joints.items()):
        c = np.asarray(coeffs[name], dtype=float)
        if c.shape != (nseg, 6):
            raise FirmwareError(f"{source}: joint {name}: expected {nseg} x 6 coefficients, got {c.shape}")
        active[i] = 1
        q_start[i] = c[0, 0]
        rows.append(f"[{i}] = {c_reals(c)},")
    pb = [
        f".nseg = {nseg},",
        f".n_ticks = {len(t) - 1},",
        f".knots = {c_reals(knots)},",
        ".active = {" + ", ".join(map(str, active)) + "},",
        ".coeffs = {", *[f"    {r}" for r in rows], "},",
    ]
    body = _common_fields(robot, "CTRL_MODE_PLAYBACK", dt, q_start)
    body += [".pb = {", *[f"    {line}" for line in pb], "},"]
    comment = (f"Playback: {nseg} segments ({meta.get('method', '?')}), joints "
               f"{', '.join(f'{n} -> {robot.joints[i].name}' for i, n in joints.items())}, tick {dt:g} s.")
    header = _header(robot, source, body, comment)
    if nseg > MAX_SEGMENTS:
        header = header.replace("const ctrl_config fw_task", f"typedef char fw_task_check_nseg[(CTRL_MAX_SEGMENTS >= {nseg}) ? 1 : -1];\n"
                                "const ctrl_config fw_task", 1)
    return FirmwareTask(robot, "playback", header, dt, len(t) - 1, source, 1, joints, nseg)


def sample_column(joint) -> str:
    """The plan column of a joint's samples (the snake planner's naming): <name>_m for a
    prismatic joint, <name>_rad for a revolute one."""
    return f"{joint.name}_{'m' if joint.type == 'prismatic' else 'rad'}"


def _sampled_robot(plan: PlanResult, robot: Robot | None, source: str) -> Robot:
    """The robot the plan was made for (robot file SHA-256 in plan.json), or a FirmwareError."""
    meta_robot = plan.metadata.get("robot")
    planned = meta_robot.get("sha256") if isinstance(meta_robot, dict) else None
    name = meta_robot.get("name", "?") if isinstance(meta_robot, dict) else "?"
    if robot is None:
        ref = (plan.metadata.get("task") or {}).get("robot")
        if not isinstance(ref, str):
            raise FirmwareError(f"{source}: plan.json names no robot file (task.robot); give the robot to play it on")
        robot = load_robot(ref)
    if planned != robot.sha256:
        raise FirmwareError(f"{source}: the plan is for robot '{name}' (robot file sha256 {str(planned)[:12]}…), not "
                            f"'{robot.name}' ({robot.sha256[:12]}…); give the plan's robot file, or re-plan for this robot")
    return robot


def sampled_task(plan: PlanResult, source: str, robot: Robot | None = None) -> FirmwareTask:
    """CTRL_MODE_SAMPLED from a sampled plan (a snake plan): every robot joint's column (by
    name, :func:`sample_column`) as a const table in flash, one row per tick of the plan's
    output step; the controller commands row k at tick k."""
    robot = _sampled_robot(plan, robot, source)
    columns = [sample_column(j) for j in robot.joints]
    missing = [c for c in columns if c not in plan.columns]
    if missing:
        raise FirmwareError(f"{source}: the plan has no column {', '.join(missing)} for robot '{robot.name}''s joints "
                            "(a sampled plan gives every joint's samples by name)")
    t = plan.column("t_s")
    dt = float((plan.metadata.get("motion") or {}).get("output_step_s") or 0.0)
    if len(t) < 2 or not dt > 0.0:
        raise FirmwareError(f"{source}: a sampled plan needs at least two samples and motion.output_step_s > 0 in "
                            "plan.json; regenerate it with armgen plan")
    k = np.arange(len(t))
    if not np.all(np.abs(t - (t[0] + k * dt)) <= SAMPLE_TIME_TOL_S):
        raise FirmwareError(f"{source}: t_s is not t_0 + k·{dt:g} s: the controller ticks once per output step; "
                            "regenerate the plan with armgen plan")
    if len(t) > MAX_SAMPLES:
        raise FirmwareError(f"{source}: {len(t)} samples, more than the controller's table takes "
                            f"(CTRL_MAX_SAMPLES = {MAX_SAMPLES}); re-plan with a larger motion.output_step")
    q = np.column_stack([plan.column(c) for c in columns])
    if not np.all(np.isfinite(q)):
        raise FirmwareError(f"{source}: the plan has non-finite joint samples; regenerate it with armgen plan")
    n_rows = len(t)
    tables = [
        f"#define FW_TASK_SAMPLES {n_rows}",
        "typedef char fw_task_check_nsamples[(CTRL_MAX_SAMPLES >= FW_TASK_SAMPLES) ? 1 : -1];",
        "/* The plan's joint samples, row k = tick k (robot joint order; m for the prismatic joints, rad",
        " * for the revolute ones). const: it stays in flash and never changes; fw_task points to it.",
        " * Each value is the plan's double: exact in double, rounded once in float. */",
        "static const ctrl_real fw_task_samples[FW_TASK_SAMPLES][CTRL_NDOF] = {",
        *[f"    {c_reals(row, 'joint sample')}," for row in q],
        "};",
        "",
    ]
    sp = [".table = &fw_task_samples[0][0],", ".n_samples = FW_TASK_SAMPLES,"]
    body = _common_fields(robot, "CTRL_MODE_SAMPLED", dt, q[0])
    body += [".sp = {", *[f"    {line}" for line in sp], "},"]
    comment = (f"Sampled playback of a {plan.metadata.get('planner', '?')} plan: {n_rows} rows x {robot.n} joints, "
               f"tick {dt:g} s; table {n_rows * robot.n * 4} B in float, {n_rows * robot.n * 8} B in double.")
    header = _header(robot, source, body, comment, tables=tables)
    return FirmwareTask(robot, "sampled", header, dt, n_rows - 1, source, 1, dict(enumerate(columns)))


def _path_fields(path, source: str) -> list[str]:
    """The ``rr`` fields of a spec 30/35 path task (taskpath.PathTask): path, timing, CLIK."""
    rows = ".task_rows = {" + ", ".join(str(r) for r in path.robot.task_rows) + "},"
    if path.motion is not None:
        return [*_program_fields(path.duration), f".clik_gain = {c_real(path.clik_gain if path.clik else 0.0)},", rows]
    axis, angle = np.array([0.0, 0.0, 1.0]), 0.0
    if path.path_type == "line" and path.end_rotation is not None:  # the planner's own axis/angle
        from ..planning.backends import make_backend
        from ..planning.taskpath import TaskPath

        pose0, _ = make_backend(path.robot, "symbolic", ("fk_jacobian",)).call("fk_jacobian", path.q_start)
        line = TaskPath(path, np.asarray(pose0)).path
        axis, angle = line.axis_local, float(line.angle)
    return [
        f".path = {'CTRL_PATH_CIRCLE' if path.path_type == 'circle' else 'CTRL_PATH_LINE'},",
        f".via = {c_reals(path.via if path.via is not None else np.zeros(3))},",
        f".end = {c_reals(path.end)},",
        f".rot_axis = {c_reals(axis)},",
        f".rot_angle = {c_real(angle)},",
        f".duration = {c_real(path.duration)},",
        f".law = {LAW_IDS[path.law.kind]},",
        _blend(path.law, source),
        f".relative = {1 if path.relative else 0},",
        f".turns = {c_real(path.turns)},",
        f".clik_gain = {c_real(path.clik_gain if path.clik else 0.0)},",
        rows,
    ]


FT_METHOD_IDS = {"pinv": "CTRL_FT_PINV", "gpm": "CTRL_FT_GPM", "wln": "CTRL_FT_WLN"}
FT_INDEX_IDS = {"omega": "CTRL_FT_INDEX_OMEGA", "relative": "CTRL_FT_INDEX_RELATIVE"}


def fault_tolerant_task(task: dict[str, Any], source: str, motion: ProgramMotion | None = None) -> FirmwareTask:
    """FAULT_TOLERANT parameters from a ``planner = "fault_tolerant"`` task dict; the plan's
    fault (fault.joints from fault.time) becomes the runners' lock schedule; a program path
    runs ``motion`` (the plan's final time law)."""
    from ..planning.fault_tolerant.planner import parse_fault_tolerant_task

    parsed = parse_fault_tolerant_task(json.loads(json.dumps(task)), source)
    if parsed.path.motion is not None:
        parsed = replace(parsed, path=parsed.path.with_motion(_need_motion(motion, source)))
    path, m, robot = parsed.path, parsed.method, parsed.robot
    if m.index not in FT_INDEX_IDS:
        raise FirmwareError(f"{source}: method.index = {excerpt(repr(m.index))}: the controller computes the omega and relative "
                            "indices on board (generated ft_index); sigma_min is a NumPy SVD with a numeric gradient "
                            "in the planner only. Re-plan with method.index = \"omega\" or \"relative\"")
    ft = [
        f".method = {FT_METHOD_IDS[m.name]},",
        f".index = {FT_INDEX_IDS[m.index]},",
        f".K = {c_real(m.K)}, .b = {c_real(m.b)},",
        f".rule = {'CTRL_WLN_SMOOTH' if m.weight_rule == 'smooth' else 'CTRL_WLN_PLAIN'},",
        f".v_band = {c_real(m.v_band)}, .omega_floor = {c_real(m.omega_floor)}, .delta = {c_real(m.delta)},",
        f".a = {c_reals(m.a or (1.0,) * robot.n)},",
        f".epsilon = {c_real(path.damping_epsilon)}, .lambda_max = {c_real(path.damping_max)},",
    ]
    steps = path.steps
    lock_tick, lock_mask = -1, 0
    if parsed.fault.joints:  # FaultTolerantPlanner.lock_step
        k_f = int(math.ceil(parsed.fault.time / path.step - 1e-9))
        if k_f <= steps:
            lock_tick, lock_mask = k_f, sum(1 << j for j in parsed.fault.joints)
    body = _common_fields(robot, "CTRL_MODE_FAULT_TOLERANT", path.step, path.q_start)
    body += [".rr = {", *[f"    {line}" for line in _path_fields(path, source)], "},"]
    body += [".ft = {", *[f"    {line}" for line in ft], "},"]
    locked = ", ".join(robot.joints[j].name for j in parsed.fault.joints) or "none"
    comment = (f"Fault tolerant: {path.path_type} x {path.turns:g}, {m.label}, index {m.index}, Euler h = "
               f"{path.step:g} s ({steps} steps); lock of {locked} reported from tick {lock_tick}.")
    header = _header(robot, source, body, comment, lock_tick, lock_mask, _program_table(path.motion))
    return FirmwareTask(robot, "fault_tolerant", header, path.step, steps, source, path.output_every,
                        lock_tick=lock_tick, lock_mask=lock_mask)


def weighted_gpm_task(task: dict[str, Any], source: str, motion: ProgramMotion | None = None) -> FirmwareTask:
    """WEIGHTED_GPM parameters from a ``planner = "wgpm"`` task dict (method.name = "wgpm"); a
    program path runs ``motion`` (the plan's final time law)."""
    from ..planning.wgpm.planner import parse_wgpm_task

    parsed = parse_wgpm_task(json.loads(json.dumps(task)), source)
    if parsed.path.motion is not None:
        parsed = replace(parsed, path=parsed.path.with_motion(_need_motion(motion, source)))
    path, m, robot = parsed.path, parsed.method, parsed.path.robot
    if m.name != "wgpm":
        raise FirmwareError(f"{source}: method.name = {excerpt(repr(m.name))} is the planner's comparison baseline; the controller "
                            "runs method.name = \"wgpm\" (step_wgpm)")
    h_lo, h_hi, k_hi, k_lo, u_th, u_band = m.vectors()
    wg = [
        f".band = {c_real(m.band)}, .t_rmax = {c_real(m.t_rmax)}, .delta = {c_real(m.delta)},",
        f".epsilon = {c_real(path.damping_epsilon)}, .rho_max = {c_real(path.damping_max)},",
        f".ramp_time = {c_real(m.ramp_time)}, .ramp_out = {1 if m.ramp_out else 0},",
        f".H_lo = {c_reals(h_lo)}, .H_hi = {c_reals(h_hi)},",
        f".k_hi = {c_reals(k_hi)}, .k_lo = {c_reals(k_lo)},",
        f".u_th = {c_reals(u_th)}, .u_band = {c_reals(u_band)},",
    ]
    body = _common_fields(robot, "CTRL_MODE_WEIGHTED_GPM", path.step, path.q_start)
    body += [".rr = {", *[f"    {line}" for line in _path_fields(path, source)], "},"]
    body += [".wg = {", *[f"    {line}" for line in wg], "},"]
    comment = (f"Weighted GPM: {path.path_type} x {path.turns:g}, band {m.band:g}, ramp {m.ramp_time:g} s, Euler h = "
               f"{path.step:g} s ({path.steps} steps).")
    header = _header(robot, source, body, comment, tables=_program_table(path.motion))
    return FirmwareTask(robot, "weighted_gpm", header, path.step, path.steps, source, path.output_every)


def schedule_lock(task: FirmwareTask, spec: str, source: str = "--lock") -> FirmwareTask:
    """The task with the runners' drive model reporting a lock the plan did not know:
    ``spec`` = ``JOINTS@TIME``, joints by number (1-based) or name, ``+``-separated, time in s
    (the first tick at or after it)."""
    joints_text, sep, time_text = spec.partition("@")
    names = [j.name for j in task.robot.joints]
    try:
        t_lock = float(time_text)
    except ValueError:
        t_lock = math.nan
    if not sep or not math.isfinite(t_lock) or t_lock < 0:
        raise FirmwareError(f"{source} {excerpt(repr(spec))}: give JOINTS@TIME, e.g. 5@1.38 (joint 5 locks at t = 1.38 s)")
    mask = 0
    for item in joints_text.split("+"):
        item = item.strip()
        if item in names:
            mask |= 1 << names.index(item)
        elif item.isdigit() and 1 <= int(item) <= task.robot.n:
            mask |= 1 << (int(item) - 1)
        else:
            raise FirmwareError(f"{source} {excerpt(repr(spec))}: {excerpt(repr(item))} is not a joint of robot '{task.robot.name}': give a "
                                f"number 1..{task.robot.n} or a name ({', '.join(names)})")
    tick = int(math.ceil(t_lock / task.dt - 1e-9))
    header = re.sub(r"const uint32_t fw_lock_mask = \d+u;", f"const uint32_t fw_lock_mask = {mask}u;", task.header)
    header = re.sub(r"const int32_t fw_lock_tick = -?\d+;", f"const int32_t fw_lock_tick = {tick};", header)
    return dataclasses.replace(task, header=header, lock_tick=tick, lock_mask=mask)


TASK_BUILDERS = {"cartesian": cartesian_task, "fault_tolerant": fault_tolerant_task, "wgpm": weighted_gpm_task}


def _is_program(task: dict[str, Any]) -> bool:
    path = task.get("path")
    return isinstance(path, dict) and path.get("type") == "program"


def task_source(plan: PlanResult, source: str) -> str:
    """Where a plan's task was read from (its ``task_file``, when that file is still there),
    else the plan itself: a program's poses files are relative to it."""
    task_file = plan.metadata.get("task_file")
    return task_file if isinstance(task_file, str) and Path(task_file).is_file() else source


def _plan_motion(plan: PlanResult, task: dict[str, Any], source: str) -> ProgramMotion | None:
    """A program plan's final motion (geometry and time law, after any slowing down): the one
    the plan carries in memory, else (a plan read from disk) the task planned again, which
    must give the plan's own duration and samples — a plan from another armgen, robot file or
    poses file is refused rather than run with another path or time law."""
    if not _is_program(task):
        return None
    if plan.motion is not None:
        return plan.motion
    replanned = run_task(task, task_source(plan, source))
    recorded = (plan.metadata.get("path") or {}).get("program_duration_s")
    same = (recorded == replanned.motion.duration and replanned.columns == plan.columns
            and replanned.data.shape == plan.data.shape
            and bool(np.all(np.abs(replanned.data - plan.data) <= REPLANNED_SAMPLE_TOL)))
    if not same:
        raise FirmwareError(f"{source}: planning its task again does not give this plan (program of "
                            f"{replanned.motion.duration!r} s, the plan says {recorded!r} s; or other samples): it was "
                            "made by another armgen, robot file or poses file; plan the task again and give that plan, "
                            "or give the task file (--task)")
    return replanned.motion


def task_from_plan(plan: PlanResult, source: str, robot: Robot | None = None) -> FirmwareTask:
    """The controller task that reproduces a plan (read with :func:`read_plan`)."""
    planner = plan.metadata.get("planner")
    if planner in TASK_BUILDERS:
        task = plan.metadata.get("task")
        if not task:
            raise FirmwareError(f"{source}: no task in its plan.json (write plans with `armgen plan`)")
        return TASK_BUILDERS[planner](task, source, _plan_motion(plan, task, source))
    if planner == "ptp":
        return playback_task(plan, source, robot)
    if planner == "snake":
        return sampled_task(plan, source, robot)
    raise FirmwareError(f"{source}: the controller runs cartesian, ptp, snake, fault_tolerant and wgpm plans, not planner "
                        f"{excerpt(repr(planner))}")


def task_from_dict(task: dict[str, Any], source: str, robot: Robot | None = None) -> FirmwareTask:
    """From a task file's dict: circle and line tasks directly; programs (whose time law is the
    plan's), ptp and snake through their planner."""
    planner = task.get("planner")
    if planner in TASK_BUILDERS:
        motion = run_task(task, source).motion if _is_program(task) else None
        return TASK_BUILDERS[planner](task, source, motion)
    if planner == "ptp":
        return playback_task(run_task(task, source), source, robot)
    if planner == "snake":
        return sampled_task(run_task(task, source), source, robot)
    raise FirmwareError(f"{source}: the controller runs cartesian, ptp, snake, fault_tolerant and wgpm tasks, not planner "
                        f"{excerpt(repr(planner))}")



def refusal(plan: PlanResult) -> str | None:
    """Why the controller cannot reproduce this plan, or None."""
    meta = plan.metadata
    if meta.get("planner") == "cartesian":
        damped = int(meta.get("summary", {}).get("damped_steps", 0) or 0)
        if damped:
            return (f"the plan used damping on {damped} steps (σ_min < ε): the controller runs λ = 0 and stops at a "
                    "singular pose instead (CTRL_FAULT_SINGULAR); re-plan away from the singularity")
        integ = meta.get("integrator", {}).get("method", "euler")
        if integ != "euler":
            return f"the plan integrates with {integ}; the controller runs explicit Euler (one step per tick)"
    return None


def write_task_files(task: FirmwareTask, out_dir: str | Path, gen_dir: str | Path | None = None) -> list[Path]:
    """task_params.h, fw_ptp.{h,c} and robot_fw.c (the generated functions the controller
    calls, from ``gen_dir``, default generated/<robot>/) into ``out_dir``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    write_text_atomic(out_dir / "task_params.h", task.header)
    prefix = robot_prefix(task.robot)
    full = Path(gen_dir) if gen_dir is not None else GENERATED_DIR / task.robot.name
    text = (full / f"{prefix}.c").read_text(encoding="utf-8")
    write_text_atomic(out_dir / "robot_fw.c", extract_functions(text, prefix, firmware_functions(text, prefix)) or text)
    return [out_dir / "task_params.h", out_dir / "robot_fw.c", *generate_ptp_evaluator(out_dir, PTP_PREFIX, "double")]



def task_from_file(source: str | Path, robot: Robot | None = None, overrides: Sequence[str] = ()) -> FirmwareTask:
    """The controller task of a task file (.toml, with ``--set`` overrides) or a plan CSV (with
    its plan.json); ``robot``, when given, must be the task's."""
    src = Path(source)
    if src.suffix == ".csv":
        if overrides:
            raise FirmwareError(f"{src}: --set changes a task file, not a plan made already; re-plan the task instead")
        task = task_from_plan(read_plan(src), str(src), robot)
    else:
        doc, _ = load_task(src)
        apply_overrides(doc, list(overrides))
        task = task_from_dict(doc, str(src), robot)
    if robot is not None and task.robot.sha256 != robot.sha256:
        raise FirmwareError(f"{src}: the task is for robot '{task.robot.name}', the firmware is built for "
                            f"'{robot.name}' (give the task's robot)")
    return task
