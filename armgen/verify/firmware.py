"""The firmware stub (``firmware_stub/``) driven from Python: task parameters, builds, runs,
and the comparison with a plan (spec 60, stages replay and target).

- :func:`task_from_plan` / :func:`task_from_dict` turn a plan (its ``plan.json``) or a task
  file into a :class:`FirmwareTask`: the text of ``task_params.h``, which defines the
  controller's ``const ctrl_config fw_task`` (a few parameters for resolved-rate mode; knots
  and coefficients for playback). It is compiled in, so the host and the Cortex-M4F builds
  run the identical task.
- :class:`FirmwareBuilder` compiles the controller, the generated kinematics and the
  generated PTP evaluator with the strict flags of spec 10, for the host (gcc, optionally
  with ASan/UBSan) or the Cortex-M4F (arm-none-eabi-gcc, float), once per variant, and links
  one executable per task.
- :func:`run_host` / :func:`run_qemu` run them and parse the CSV they print.
- :func:`compare_with_plan` compares a run with the plan sample by sample.

Command line (used by ``firmware_stub/Makefile``)::

    python -m armgen.verify.firmware header TASK.toml|plan.csv -o DIR [--robot R] [--set k=v ...]

writes ``DIR/task_params.h``, the PTP evaluator ``DIR/fw_ptp.{h,c}`` and ``DIR/robot_fw.c`` (the
generated functions the controller calls, extracted from ``generated/<robot>/<robot>.c``).
"""

from __future__ import annotations

import argparse
import concurrent.futures
import dataclasses
import json
import math
import os
import re
import subprocess
import sys
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..codegen.generate import GENERATED_DIR, CodegenConfig, generate, write
from ..codegen.ptp_c import generate_ptp_evaluator
from ..codegen.toolchain import ARM_CPU_FLAGS, SANITIZER_FLAGS, STRICT_FLAGS, find_tool, host_cc, run_tool
from ..errors import ArmgenError, excerpt
from ..fileio import write_text_atomic
from ..planning.result import PlanResult
from ..robot import Robot, load_robot

FIRMWARE_DIR = Path(str(resources.files("armgen.data") / "firmware_stub"))
ARM_DIR = FIRMWARE_DIR / "arm"
APT_PACKAGES = "gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm"
APT_HINT = f"install them from the distribution: apt-get install -y {APT_PACKAGES}"
PTP_PREFIX = "fw"  # fw_ptp_eval, fw_real: must not clash with the robot prefix
QEMU_MACHINE = ("-M", "mps2-an386", "-nographic", "-semihosting-config", "enable=on,target=native")
# Deterministic time: one guest instruction = 1 ns, so SysTick counts instructions / 40 and
# the controller's overrun check never fires because the host was busy.
QEMU_ICOUNT = ("-icount", "shift=0")
MAX_SEGMENTS = 16  # CTRL_MAX_SEGMENTS default; plans with more segments get a -D

# Controller guards written into every task (see controller.h and docs/firmware.md).
DEFAULT_QDOT_MAX = 3.0  # rad/s: singular-pose guard, far above the bundled plans (< 0.5 rad/s)
DEFAULT_RESIDUAL_REL = 1e-3  # |J q̇ − ẋ|∞ ≤ 1e-3 |ẋ|∞ + 1e-6: float rounding stays below 1e-5
DEFAULT_RESIDUAL_ABS = 1e-6
DEFAULT_POS_ERR_MAX = 5e-3  # m: the planner's own MAX_PATH_ERROR

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

FAULT_NAMES = ("NONE", "BAD_CONFIG", "NONFINITE_INPUT", "NONFINITE_OUTPUT", "JOINT_LIMIT", "SINGULAR", "OVERRUN",
               "TRACKING", "PLAYBACK", "BAD_ARGS", "LOCK_REPORT", "REDUNDANCY", "SPEED")
STATE_NAMES = ("IDLE", "RUNNING", "DONE", "FAULT", "DEGRADED")
FAULT_STATE = STATE_NAMES.index("FAULT")
# Controller modes that integrate a Cartesian task on board (compared by q and task error).
RESOLVED_MODES = ("resolved_rate", "fault_tolerant", "weighted_gpm")
METHOD_IDS = {"pinv": "CTRL_METHOD_PINV", "repetitive": "CTRL_METHOD_REPETITIVE", "zghal": "CTRL_METHOD_ZGHAL",
              "zghal_improved": "CTRL_METHOD_ZGHAL_IMPROVED", "combined": "CTRL_METHOD_COMBINED"}
LAW_IDS = {"cubic": "CTRL_LAW_CUBIC", "trapezoidal": "CTRL_LAW_TRAPEZOIDAL", "constant": "CTRL_LAW_CONSTANT"}


class FirmwareError(ArmgenError):
    """A task the controller cannot run, or a firmware run that failed."""

    exit_code = 5


def robot_prefix(robot: Robot) -> str:
    return re.sub(r"[^0-9a-zA-Z_]", "_", robot.name).lower()


# The generated functions the controller calls: always, and per optional mode (a robot whose
# generated code lacks them gets a firmware without that mode: -DCTRL_HAS_<MODE>=0).
# The steps take the J of the tick's fk_jacobian (their *_from_jacobian twins).
FIRMWARE_FUNCTIONS = ("fk_jacobian", "zghal", "repetitive", "step_gpm_from_jacobian")
OPTIONAL_FUNCTIONS = {"FAULT_TOLERANT": ("ft_index_from_jacobian", "wln_weights", "step_fault_from_jacobian"),
                      "WEIGHTED_GPM": ("step_wgpm_from_jacobian",)}


def available_modes(source: str, prefix: str) -> tuple[str, ...]:
    """The optional controller modes whose generated functions the robot's source defines."""
    return tuple(mode for mode, names in OPTIONAL_FUNCTIONS.items()
                 if all(re.search(rf"^(?:void|{prefix}_status) {prefix}_{n}\(", source, re.M) for n in names))


def firmware_functions(source: str, prefix: str) -> tuple[str, ...]:
    """Every generated function the firmware of this robot calls."""
    return FIRMWARE_FUNCTIONS + tuple(n for mode in available_modes(source, prefix) for n in OPTIONAL_FUNCTIONS[mode])


def extract_functions(source: str, prefix: str, names: Sequence[str] = FIRMWARE_FUNCTIONS) -> str | None:
    """The generated source reduced to the named functions: its preamble and includes, then
    each definition byte for byte. None when the file does not have the generator's layout
    (``/* name: ops */`` above each definition) or lacks a function.

    The firmware needs a few of the robot's functions; compiling only those keeps the builds
    fast (the whole generated file of modular8 is > 40 000 lines)."""
    pattern = re.compile(rf"^/\* (\w+): [^\n]*\*/\n(?:void|{prefix}_status) {prefix}_(\w+)\(", re.M)
    matches = list(pattern.finditer(source))
    if not matches or any(m.group(1) != m.group(2) for m in matches):
        return None
    blocks = {m.group(1): source[m.start():(nxt.start() if nxt is not None else len(source))]
              for m, nxt in zip(matches, [*matches[1:], None])}
    if not all(n in blocks for n in names):
        return None
    # and the loop functions (symbolic.loops) that those call
    names = [*names, *(m for m in blocks if m not in names and any(f" {prefix}_{m}(" in blocks[n] for n in names))]
    note = (f"/* The definitions of {', '.join(names)} from {prefix}.c, byte for byte\n"
            " * (extracted by armgen.verify.firmware for the firmware build). */\n")
    body = "".join(blocks[n].rstrip("\n") + "\n\n" for n in names)
    return source[:matches[0].start()] + note + "\n" + body


# ------------------------------------------------------------------------------------------
# task parameters
# ------------------------------------------------------------------------------------------

@dataclass
class FirmwareTask:
    """What the controller runs: the text of ``task_params.h`` plus what the comparison needs."""

    robot: Robot
    mode: str  # "resolved_rate" | "playback" | "fault_tolerant" | "weighted_gpm"
    header: str
    dt: float
    n_ticks: int  # index of the last tick
    source: str = ""
    output_every: int = 1
    joints: dict[int, str] = field(default_factory=dict)  # playback: robot joint -> plan joint name
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
    return f".blend = {_lit(law.blend)},"


def _lit(x: float) -> str:
    x = float(x)
    if not math.isfinite(x):
        raise FirmwareError(f"task parameter {x} is not finite")
    return f"CTRL_LIT({x!r})"


def _vec(values) -> str:
    return "{" + ", ".join(_lit(v) for v in np.asarray(values, dtype=float).ravel()) + "}"


def _header(robot: Robot, source: str, body: list[str], comment: str, lock_tick: int = -1, lock_mask: int = 0) -> str:
    n = robot.n
    lines = [
        "/*",
        " * Task parameters of the armgen joint controller: `fw_task` (see controller.h).",
        f" * Generated by armgen.verify.firmware from {Path(source).name or 'a task'}; do not edit.",
        f" * Robot '{robot.name}' ({n} DOF), robot file sha256 {robot.sha256}.",
        f" * {comment}",
        " */",
        f"typedef char fw_task_check_ndof[(CTRL_NDOF == {n}) ? 1 : -1]; /* built for the right robot */",
        f"typedef char fw_task_check_ntask[(CTRL_NTASK == {len(robot.task_rows)}) ? 1 : -1];",
        "",
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


def _common_fields(robot: Robot, mode: str, dt: float, q_start: np.ndarray) -> list[str]:
    return [
        f".mode = {mode},",
        f".dt = {_lit(dt)},",
        f".q_start = {_vec(q_start)},",
        f".q_min = {_vec(robot.qmin)},",
        f".q_max = {_vec(robot.qmax)},",
        f".qdot_max = {_lit(DEFAULT_QDOT_MAX)},",
        f".residual_rel = {_lit(DEFAULT_RESIDUAL_REL)},",
        f".residual_abs = {_lit(DEFAULT_RESIDUAL_ABS)},",
        f".pos_err_max = {_lit(DEFAULT_POS_ERR_MAX)},",
    ]


def cartesian_task(task: dict[str, Any], source: str) -> FirmwareTask:
    """Resolved-rate parameters from a ``planner = "cartesian"`` task dict."""
    from ..planning.cartesian.planner import CartesianPlanner, parse_cartesian_task

    parsed = parse_cartesian_task(json.loads(json.dumps(task)), source)
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
    rr = [
        f".path = {'CTRL_PATH_CIRCLE' if parsed.path_type == 'circle' else 'CTRL_PATH_LINE'},",
        f".via = {_vec(parsed.via if parsed.via is not None else np.zeros(3))},",
        f".end = {_vec(parsed.end)},",
        f".rot_axis = {_vec(axis)},",
        f".rot_angle = {_lit(angle)},",
        f".duration = {_lit(parsed.duration)},",
        f".law = {LAW_IDS[parsed.law.kind]},",
        _blend(parsed.law, source),
        f".method = {METHOD_IDS[mp.name]},",
        f".rho_R = {_lit(mp.rho_R)}, .T_smo_R = {_lit(mp.T_smo_R)},",
        f".rho_L = {_lit(mp.rho_L)}, .theta_s = {_lit(mp.theta_s)},",
        f".T_smo_L = {_lit(mp.T_smo_L)}, .T_sum_L = {_lit(mp.T_sum_L)},",
        f".gamma_R_ramp = {_lit(mp.gamma_R_ramp)},",
        ".relative = 0,",
        f".turns = {_lit(1.0)},",
        f".clik_gain = {_lit(parsed.clik_gain)},",
        # λ = 0: the planner damps only below σ_min = ε, which no bundled plan reaches; plans
        # that used damping are refused by compare_with_plan (summary.damped_steps > 0).
        f".damping = {_lit(0.0)},",
        ".task_rows = {" + ", ".join(str(r) for r in robot.task_rows) + "},",
    ]
    body = _common_fields(robot, "CTRL_MODE_RESOLVED_RATE", parsed.step, parsed.q_start)
    body += [".rr = {", *[f"    {line}" for line in rr], "},"]
    comment = (f"Resolved rate: {parsed.path_type}, {parsed.law.kind} law over {parsed.duration:g} s, method "
               f"{mp.name}, Euler h = {parsed.step:g} s ({steps} steps), CLIK gain {parsed.clik_gain:g}.")
    return FirmwareTask(robot, "resolved_rate", _header(robot, source, body, comment), parsed.step, steps, source,
                        parsed.output_every)


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
        rows.append(f"[{i}] = {_vec(c)},")
    pb = [
        f".nseg = {nseg},",
        f".n_ticks = {len(t) - 1},",
        f".knots = {_vec(knots)},",
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


def _path_fields(path, source: str) -> list[str]:
    """The ``rr`` fields of a spec 30/35 path task (taskpath.PathTask): path, timing, CLIK."""
    axis, angle = np.array([0.0, 0.0, 1.0]), 0.0
    if path.path_type == "line" and path.end_rotation is not None:  # the planner's own axis/angle
        from ..planning.backends import make_backend
        from ..planning.taskpath import TaskPath

        pose0, _ = make_backend(path.robot, "symbolic", ("fk_jacobian",)).call("fk_jacobian", path.q_start)
        line = TaskPath(path, np.asarray(pose0)).path
        axis, angle = line.axis_local, float(line.angle)
    return [
        f".path = {'CTRL_PATH_CIRCLE' if path.path_type == 'circle' else 'CTRL_PATH_LINE'},",
        f".via = {_vec(path.via if path.via is not None else np.zeros(3))},",
        f".end = {_vec(path.end)},",
        f".rot_axis = {_vec(axis)},",
        f".rot_angle = {_lit(angle)},",
        f".duration = {_lit(path.duration)},",
        f".law = {LAW_IDS[path.law.kind]},",
        _blend(path.law, source),
        f".relative = {1 if path.relative else 0},",
        f".turns = {_lit(path.turns)},",
        f".clik_gain = {_lit(path.clik_gain if path.clik else 0.0)},",
        ".task_rows = {" + ", ".join(str(r) for r in path.robot.task_rows) + "},",
    ]


FT_METHOD_IDS = {"pinv": "CTRL_FT_PINV", "gpm": "CTRL_FT_GPM", "wln": "CTRL_FT_WLN"}
FT_INDEX_IDS = {"omega": "CTRL_FT_INDEX_OMEGA", "relative": "CTRL_FT_INDEX_RELATIVE"}


def fault_tolerant_task(task: dict[str, Any], source: str) -> FirmwareTask:
    """FAULT_TOLERANT parameters from a ``planner = "fault_tolerant"`` task dict; the plan's
    fault (fault.joints from fault.time) becomes the runners' lock schedule."""
    from ..planning.fault_tolerant.planner import parse_fault_tolerant_task

    parsed = parse_fault_tolerant_task(json.loads(json.dumps(task)), source)
    path, m, robot = parsed.path, parsed.method, parsed.robot
    if m.index not in FT_INDEX_IDS:
        raise FirmwareError(f"{source}: method.index = {excerpt(repr(m.index))}: the controller computes the omega and relative "
                            "indices on board (generated ft_index); sigma_min is a NumPy SVD with a numeric gradient "
                            "in the planner only. Re-plan with method.index = \"omega\" or \"relative\"")
    ft = [
        f".method = {FT_METHOD_IDS[m.name]},",
        f".index = {FT_INDEX_IDS[m.index]},",
        f".K = {_lit(m.K)}, .b = {_lit(m.b)},",
        f".rule = {'CTRL_WLN_SMOOTH' if m.weight_rule == 'smooth' else 'CTRL_WLN_PLAIN'},",
        f".v_band = {_lit(m.v_band)}, .omega_floor = {_lit(m.omega_floor)}, .delta = {_lit(m.delta)},",
        f".a = {_vec(m.a or (1.0,) * robot.n)},",
        f".epsilon = {_lit(path.damping_epsilon)}, .lambda_max = {_lit(path.damping_max)},",
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
    return FirmwareTask(robot, "fault_tolerant", _header(robot, source, body, comment, lock_tick, lock_mask),
                        path.step, steps, source, path.output_every, lock_tick=lock_tick, lock_mask=lock_mask)


def weighted_gpm_task(task: dict[str, Any], source: str) -> FirmwareTask:
    """WEIGHTED_GPM parameters from a ``planner = "wgpm"`` task dict (method.name = "wgpm")."""
    from ..planning.wgpm.planner import parse_wgpm_task

    parsed = parse_wgpm_task(json.loads(json.dumps(task)), source)
    path, m, robot = parsed.path, parsed.method, parsed.path.robot
    if m.name != "wgpm":
        raise FirmwareError(f"{source}: method.name = {excerpt(repr(m.name))} is the planner's comparison baseline; the controller "
                            "runs method.name = \"wgpm\" (step_wgpm)")
    h_lo, h_hi, k_hi, k_lo, u_th, u_band = m.vectors()
    wg = [
        f".band = {_lit(m.band)}, .t_rmax = {_lit(m.t_rmax)}, .delta = {_lit(m.delta)},",
        f".epsilon = {_lit(path.damping_epsilon)}, .rho_max = {_lit(path.damping_max)},",
        f".ramp_time = {_lit(m.ramp_time)}, .ramp_out = {1 if m.ramp_out else 0},",
        f".H_lo = {_vec(h_lo)}, .H_hi = {_vec(h_hi)},",
        f".k_hi = {_vec(k_hi)}, .k_lo = {_vec(k_lo)},",
        f".u_th = {_vec(u_th)}, .u_band = {_vec(u_band)},",
    ]
    body = _common_fields(robot, "CTRL_MODE_WEIGHTED_GPM", path.step, path.q_start)
    body += [".rr = {", *[f"    {line}" for line in _path_fields(path, source)], "},"]
    body += [".wg = {", *[f"    {line}" for line in wg], "},"]
    comment = (f"Weighted GPM: {path.path_type} x {path.turns:g}, band {m.band:g}, ramp {m.ramp_time:g} s, Euler h = "
               f"{path.step:g} s ({path.steps} steps).")
    return FirmwareTask(robot, "weighted_gpm", _header(robot, source, body, comment), path.step, path.steps, source,
                        path.output_every)


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


def _refuse_program(task: dict[str, Any], source: str) -> None:
    path = task.get("path")
    if isinstance(path, dict) and path.get("type") == "program":
        raise FirmwareError(f"{source}: the controller runs circle and line paths; a program (path.type = "
                            "'program') has no firmware task yet: plan it on the host (armgen plan)")


def task_from_plan(plan: PlanResult, source: str, robot: Robot | None = None) -> FirmwareTask:
    """The controller task that reproduces a plan (read with :func:`read_plan`)."""
    planner = plan.metadata.get("planner")
    if planner in TASK_BUILDERS:
        task = plan.metadata.get("task")
        if not task:
            raise FirmwareError(f"{source}: no task in its plan.json (write plans with `armgen plan`)")
        _refuse_program(task, source)
        return TASK_BUILDERS[planner](task, source)
    if planner == "ptp":
        return playback_task(plan, source, robot)
    raise FirmwareError(f"{source}: the controller runs cartesian, ptp, fault_tolerant and wgpm plans, not planner "
                        f"{excerpt(repr(planner))}")


def task_from_dict(task: dict[str, Any], source: str, robot: Robot | None = None) -> FirmwareTask:
    """From a task file's dict: cartesian directly; ptp through the (fast) PTP planner."""
    planner = task.get("planner")
    if planner in TASK_BUILDERS:
        _refuse_program(task, source)
        return TASK_BUILDERS[planner](task, source)
    if planner == "ptp":
        from ..planning.tasks import run_task

        return playback_task(run_task(task, source), source, robot)
    raise FirmwareError(f"{source}: the controller runs cartesian, ptp, fault_tolerant and wgpm tasks, not planner "
                        f"{excerpt(repr(planner))}")


# ------------------------------------------------------------------------------------------
# builds
# ------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Variant:
    target: str = "host"  # "host" (gcc) | "arm" (arm-none-eabi-gcc, Cortex-M4F)
    precision: str = "double"
    sanitize: bool = False
    opt: str = "-O2"
    max_segments: int = MAX_SEGMENTS
    print_rows: bool = True  # arm: FW_PRINT_ROWS
    fast_trig: bool = True  # arm: <P>_BOUNDED_TRIG=1 for the generated code, sinf/cosf from arm/fw_fastmath.c
                            # (-Wl,--wrap) for the rest; else newlib's everywhere
    gen_opt: str | None = None  # optimisation of the generated kinematics (default: opt)
    extra: tuple[str, ...] = ()  # more compiler flags (e.g. -fcallgraph-info=su for the benchmark)

    @property
    def name(self) -> str:
        san = "_san" if self.sanitize else ""
        rows = "" if self.print_rows else "_quiet"
        trig = "" if self.fast_trig or self.target != "arm" else "_newlibtrig"
        gen = f"_gen{self.gen_opt.replace('-', '_')}" if self.gen_opt and self.gen_opt != self.opt else ""
        extra = "_x" + re.sub(r"[^0-9a-zA-Z]+", "_", "".join(self.extra)).strip("_") if self.extra else ""
        return f"{self.target}_{self.precision}{san}{self.opt.replace('-', '_')}{gen}_s{self.max_segments}{rows}{trig}{extra}"


# The Cortex-M4F build: float; the controller at -O3 (its short fixed-length loops unrolled),
# the generated straight-line kinematics at -Os (smaller, and on the M4 also fewer executed
# instructions than -O2, whose scheduling spills more); sinf/cosf from arm/fw_fastmath.c.
ARM_VARIANT = Variant("arm", "float", opt="-O3", gen_opt="-Os")


def arm_tools() -> dict[str, str]:
    """The cross toolchain and the emulator, or a ToolchainError naming the apt packages."""
    return {name: find_tool(name, APT_HINT) for name in
            ("arm-none-eabi-gcc", "arm-none-eabi-size", "qemu-system-arm")}


class FirmwareBuilder:
    """Compiles the firmware for one robot into ``work``: objects once per variant, one
    executable per task."""

    def __init__(self, robot: Robot | str, work: str | Path, gen_dir: str | Path | None = None):
        self.robot = load_robot(robot) if isinstance(robot, str) else robot
        self.work = Path(work)
        self.work.mkdir(parents=True, exist_ok=True)
        self.prefix = robot_prefix(self.robot)
        self.gen_dir = Path(gen_dir).resolve() if gen_dir is not None else self._generated_dir()
        source = (self.gen_dir / f"{self.prefix}.c").read_text(encoding="utf-8")
        self.modes = available_modes(source, self.prefix)
        self.robot_source = self._robot_source(source)
        self.ptp_dir = self.work / "ptp"
        if not (self.ptp_dir / f"{PTP_PREFIX}_ptp.c").is_file():
            generate_ptp_evaluator(self.ptp_dir, PTP_PREFIX, "double")
        self._objects: dict[Variant, list[Path]] = {}
        self._count = 0

    def _generated_dir(self) -> Path:
        """The checked-in generated/<robot>/ when it belongs to this robot file, else fresh code."""
        checked_in = (GENERATED_DIR / self.robot.name).resolve()  # the compilers run in their own folders
        header = checked_in / f"{self.prefix}.h"
        if header.is_file() and f'ROBOT_SHA256 "{self.robot.sha256}"' in header.read_text(encoding="utf-8"):
            return checked_in
        fresh = self.work / "gen"
        write(generate(CodegenConfig(self.robot)), fresh)
        return fresh

    def _robot_source(self, source: str) -> Path:
        full = self.gen_dir / f"{self.prefix}.c"
        reduced = extract_functions(source, self.prefix, firmware_functions(source, self.prefix))
        if reduced is None:
            return full
        path = self.work / "robot" / f"{self.prefix}_fw.c"
        write_text_atomic(path, reduced)
        return path

    def defines(self, v: Variant) -> list[str]:
        P = self.prefix.upper()
        flag = 1 if v.precision == "float" else 0
        d = [f"-DCTRL_ROBOT={self.prefix}", f"-DCTRL_ROBOT_UC={P}", f'-DCTRL_ROBOT_HEADER="{self.prefix}.h"',
             f"-D{P}_USE_FLOAT={flag}", f"-D{PTP_PREFIX.upper()}_USE_FLOAT={flag}",
             f"-DCTRL_MAX_SEGMENTS={v.max_segments}"]
        d += [f"-DCTRL_HAS_{mode}={1 if mode in self.modes else 0}" for mode in OPTIONAL_FUNCTIONS]
        if v.target == "arm":
            d += ["-DFW_CSV_HEX=1", f"-DFW_PRINT_ROWS={1 if v.print_rows else 0}"]
            # the generated kinematics' own bounded-range sin/cos (inline, ≤ 2 ulp on the joint range)
            d += [f"-D{P}_BOUNDED_TRIG={1 if v.fast_trig else 0}"]
        return d

    def cflags(self, v: Variant) -> list[str]:
        flags = [*STRICT_FLAGS, v.opt, "-g"]
        if v.target == "arm":
            flags += [*ARM_CPU_FLAGS, "-ffunction-sections", "-fdata-sections", "-fstack-usage"]
        else:
            if v.sanitize:
                flags += list(SANITIZER_FLAGS)
        return flags + list(v.extra) + self.defines(v) + [f"-I{FIRMWARE_DIR}", f"-I{self.gen_dir}", f"-I{self.ptp_dir}", f"-I{ARM_DIR}"]

    def compiler(self, v: Variant) -> str:
        if v.target == "arm":
            return find_tool("arm-none-eabi-gcc", APT_HINT)
        return host_cc()

    def sources(self, v: Variant) -> list[Path]:
        common = [self.robot_source, self.ptp_dir / f"{PTP_PREFIX}_ptp.c",
                  FIRMWARE_DIR / "controller.c", FIRMWARE_DIR / "fw_csv.c"]
        if v.target == "arm":
            fast = [ARM_DIR / "fw_fastmath.c"] if v.fast_trig else []
            return common + [ARM_DIR / "startup.c", ARM_DIR / "semihost.c", ARM_DIR / "fw_main.c", *fast]
        return common + [FIRMWARE_DIR / "host" / "main.c"]

    def object_dir(self, v: Variant) -> Path:
        return self.work / f"obj_{v.name}"

    def objects(self, v: Variant) -> list[Path]:
        """Compile every source of the variant (in parallel); cached."""
        if v in self._objects:
            return self._objects[v]
        cc, flags = self.compiler(v), self.cflags(v)
        out_dir = self.object_dir(v)
        out_dir.mkdir(parents=True, exist_ok=True)

        gen_source = self.robot_source

        def compile_one(src: Path) -> Path:
            obj = out_dir / (src.stem + ".o")
            f = flags if src != gen_source or not v.gen_opt else [v.gen_opt if x == v.opt else x for x in flags]
            run_tool([cc, *f, "-c", str(src), "-o", str(obj)], f"compiling {src.name} ({v.name})", cwd=out_dir)
            return obj

        with concurrent.futures.ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 2)) as pool:
            objs = list(pool.map(compile_one, self.sources(v)))
        self._objects[v] = objs
        return objs

    def executable(self, v: Variant, task: FirmwareTask, name: str | None = None) -> Path:
        """Link the firmware running ``task``: compiles task_params.h via fw_task.c."""
        if task.robot.sha256 != self.robot.sha256:
            raise FirmwareError(f"task for robot '{task.robot.name}' given to the firmware of '{self.robot.name}'")
        if task.max_segments > v.max_segments:
            v = dataclasses.replace(v, max_segments=task.max_segments)
        objs = self.objects(v)
        self._count += 1
        name = name or f"task{self._count}"
        task_dir = self.work / f"{v.name}_{name}"
        task_dir.mkdir(parents=True, exist_ok=True)
        write_text_atomic(task_dir / "task_params.h", task.header)
        cc, flags = self.compiler(v), self.cflags(v)
        task_obj = task_dir / "fw_task.o"
        run_tool([cc, *flags, f"-I{task_dir}", "-c", str(FIRMWARE_DIR / "fw_task.c"), "-o", str(task_obj)],
                 f"compiling the task parameters of {task.source or name}", cwd=task_dir)
        if v.target == "arm":
            out = task_dir / "fw_m4.elf"
            wrap = ["-Wl,--wrap=sinf", "-Wl,--wrap=cosf"] if v.fast_trig else []
            run_tool([cc, *flags, "-nostartfiles", "--specs=nano.specs", "-T", str(ARM_DIR / "mps2_an386.ld"), *wrap,
                      "-Wl,--gc-sections", f"-Wl,-Map={out.with_suffix('.map')}", *map(str, objs), str(task_obj),
                      "-lm", "-o", str(out)], "linking the Cortex-M4F firmware")
        else:
            out = task_dir / "fw_host"
            run_tool([cc, *flags, *map(str, objs), str(task_obj), "-lm", "-o", str(out)], "linking the host firmware")
        return out


# ------------------------------------------------------------------------------------------
# runs
# ------------------------------------------------------------------------------------------

@dataclass
class FirmwareRun:
    """The CSV a firmware printed, and its '# key value' summary."""

    columns: list[str]
    data: np.ndarray
    summary: dict[str, str]
    text: str = ""

    def column(self, name: str) -> np.ndarray:
        return self.data[:, self.columns.index(name)]

    @property
    def state(self) -> str:
        return self.summary.get("state", "?")

    @property
    def fault(self) -> str:
        return self.summary.get("fault", "?")

    def by_tick(self) -> dict[int, np.ndarray]:
        """The first row of each tick index (later rows of the same tick show the hold)."""
        out: dict[int, np.ndarray] = {}
        for row in self.data:
            out.setdefault(int(row[0]), row)
        return out

    def q(self, n: int) -> np.ndarray:
        return self.data[:, 2:2 + n]


def _real(token: str) -> float:
    token = token.strip()
    return float.fromhex(token) if "0x" in token else float(token)


def parse_output(text: str) -> FirmwareRun:
    columns: list[str] | None = None
    rows, summary = [], {}
    for line in text.splitlines():
        line = line.strip()
        if line.startswith("tick,"):
            columns = line.split(",")
        elif line.startswith("# "):
            key, _, value = line[2:].partition(" ")
            summary[key] = value.strip()
        elif columns is not None and line[:1].isdigit():
            cells = line.split(",")
            if len(cells) == len(columns):
                rows.append([_real(c) for c in cells])
    if columns is None:
        raise FirmwareError(f"the firmware printed no CSV header:\n{text[-2000:]}")
    data = np.array(rows, dtype=float).reshape(len(rows), len(columns))
    return FirmwareRun(columns, data, summary, text)


def run_host(exe: Path, args: Sequence[str] = (), timeout: float = 300) -> FirmwareRun:
    env = dict(os.environ, ASAN_OPTIONS="detect_leaks=1:abort_on_error=0", UBSAN_OPTIONS="print_stacktrace=1")
    try:
        proc = subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        raise FirmwareError(f"{exe.name} did not finish within {timeout:.0f} s") from None
    if proc.returncode != 0:
        raise FirmwareError(f"{exe.name} {' '.join(args)} failed (exit {proc.returncode}):\n{proc.stderr[-4000:]}")
    if proc.stderr.strip():  # a sanitizer that recovered would still print here
        raise FirmwareError(f"{exe.name} wrote to stderr:\n{proc.stderr[-4000:]}")
    return parse_output(proc.stdout)


def run_qemu(elf: Path, timeout: float = 600, icount: bool = True) -> FirmwareRun:
    qemu = find_tool("qemu-system-arm", APT_HINT)
    cmd = [qemu, *QEMU_MACHINE, *(QEMU_ICOUNT if icount else ()), "-kernel", str(elf)]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        raise FirmwareError(f"qemu-system-arm did not finish {elf.name} within {timeout:.0f} s") from None
    text = proc.stdout + proc.stderr  # semihosting console output goes to stderr in QEMU 7
    if proc.returncode != 0 or "# end" not in text:
        raise FirmwareError(f"the Cortex-M4F firmware failed under QEMU (exit {proc.returncode}):\n{text[-3000:]}")
    return parse_output(text)


def instructions_per_tick(run: FirmwareRun) -> dict[str, float]:
    """From the QEMU run's SysTick counts (needs -icount shift=0): mean and max per tick."""
    s = {k: float(v) for k, v in run.summary.items() if re.fullmatch(r"-?\d+(\.\d+)?", v)}
    ipt = s["calib_insns"] / s["calib_ticks"]
    n = s["ticks"]
    return {"insns_per_systick": ipt, "ticks": n,
            "mean": (s["tick_systicks_sum"] - s["stub_systicks_sum"]) * ipt / n,
            "max": s["tick_systicks_max"] * ipt - s["stub_systicks_sum"] * ipt / n,
            "min": s["tick_systicks_min"] * ipt - s["stub_systicks_sum"] * ipt / n,
            "resolution": ipt}


# ------------------------------------------------------------------------------------------
# comparison with the plan
# ------------------------------------------------------------------------------------------

@dataclass
class Comparison:
    rows: list[list[Any]]  # [run, quantity, value, bound, ok]
    passed: bool
    max_dq: float = float("nan")
    max_dtask: float = float("nan")
    fault_tick: int | None = None


def bounds_for(precision: str, mode: str) -> tuple[float, float]:
    if precision == "double":
        return FW_DOUBLE_BOUND_RAD, FW_DOUBLE_BOUND_M
    if mode == "playback":
        return FW_FLOAT_PLAYBACK_BOUND_RAD, FW_FLOAT_PLAYBACK_BOUND_RAD_S
    return FW_FLOAT_BOUND_RAD, FW_FLOAT_BOUND_M


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


def _expected_fault_ticks(plan: PlanResult, task: FirmwareTask,
                          plan_ticks: np.ndarray) -> tuple[int, int, str] | None:
    """Where a guarded controller must stop, and with which fault: at the plan's first sample
    outside the joint limits (JOINT_LIMIT; the planners do not enforce them) or, in the
    resolved-rate modes, farther than the tracking guard from the path (TRACKING: e.g. a lock
    that leaves the arm unable to follow) — or, when the plan keeps only every k-th sample,
    anywhere after the last good sample and up to that one."""
    robot = task.robot
    if task.mode in RESOLVED_MODES:
        idx = list(range(robot.n))
        q = np.column_stack([plan.column(f"q{i + 1}_rad") for i in idx])
    else:
        idx = sorted(task.joints)
        q = np.column_stack([plan.column(f"theta_{task.joints[i]}_rad") for i in idx])
    bad_q = ((q > robot.qmax[idx]) | (q < robot.qmin[idx])).any(axis=1)
    bad_e = plan.column("pos_err_m") > DEFAULT_POS_ERR_MAX if task.mode in RESOLVED_MODES else np.zeros_like(bad_q)
    rows = np.flatnonzero(bad_q | bad_e)
    if not rows.size:
        return None
    r = int(rows[0])
    hi = int(plan_ticks[r])
    lo = int(plan_ticks[r - 1]) + 1 if r > 0 else hi
    return lo, hi, "JOINT_LIMIT" if bad_q[r] else "TRACKING"


def compare_with_plan(plan: PlanResult, run: FirmwareRun, task: FirmwareTask, precision: str, label: str,
                      tick_slack: int | None = None) -> Comparison:
    """Sample-by-sample comparison of a firmware run with the plan it reproduces.

    Resolved rate: max |Δq| and max |Δ task error| (|p_d − p|) over the plan's samples;
    playback: max |Δθ| and |Δω|. A plan that leaves the joint limits must make the controller
    stop there with CTRL_FAULT_JOINT_LIMIT at that sample (± ``tick_slack``: 0 in double,
    1 in float), holding a finite command inside the limits; otherwise the run must end DONE.
    """
    robot = task.robot
    n = robot.n
    bound_q, bound_2 = bounds_for(precision, task.mode)
    slack = tick_slack if tick_slack is not None else (0 if precision == "double" else 1)
    t_plan = plan.column("t_s")
    if task.mode in RESOLVED_MODES:
        plan_ticks = np.rint(t_plan / task.dt).astype(int)
    else:
        plan_ticks = np.arange(len(t_plan))
    fw = run.by_tick()
    expected = _expected_fault_ticks(plan, task, plan_ticks)
    fault_ticks = [k for k, row in fw.items() if int(row[-2]) == FAULT_STATE]
    fault_tick = min(fault_ticks) if fault_ticks else None
    stop = fault_tick if fault_tick is not None else task.n_ticks + 1
    use = [(r, k) for r, k in enumerate(plan_ticks) if k < stop]
    missing = [k for _, k in use if k not in fw]
    rows: list[list[Any]] = []
    passed = True
    if missing:
        return Comparison([[label, "samples", f"{len(missing)} plan samples have no firmware tick (first {missing[0]})",
                            "all", False]], False)
    fw_rows = np.array([fw[k] for _, k in use]) if use else np.zeros((0, len(run.columns)))
    plan_rows = [r for r, _ in use]
    if task.mode in RESOLVED_MODES:
        q_plan = np.column_stack([plan.column(f"q{i + 1}_rad")[plan_rows] for i in range(n)])
        dq = float(np.max(np.abs(fw_rows[:, 2:2 + n] - q_plan))) if use else 0.0
        e_plan = plan.column("pos_err_m")[plan_rows]
        de = float(np.max(np.abs(fw_rows[:, run.columns.index("pos_err_m")] - e_plan))) if use else 0.0
        quantities = (("max |Δq| [rad]", dq, bound_q), ("max |Δ task error| [m]", de, bound_2))
    else:
        idx = sorted(task.joints)
        th = np.column_stack([plan.column(f"theta_{task.joints[i]}_rad")[plan_rows] for i in idx])
        om = np.column_stack([plan.column(f"omega_{task.joints[i]}_rad_s")[plan_rows] for i in idx])
        dq = float(np.max(np.abs(fw_rows[:, [2 + i for i in idx]] - th))) if use else 0.0
        de = float(np.max(np.abs(fw_rows[:, [2 + n + i for i in idx]] - om))) if use else 0.0
        quantities = (("max |Δθ| [rad]", dq, bound_q), ("max |Δω| [rad/s]", de, bound_2))
    for what, value, bound in quantities:
        ok = bool(np.isfinite(value) and value <= bound)
        rows.append([label, what, value, bound, ok])
        passed &= ok
    # how the run ended
    last = run.data[-1]
    held_ok = bool(np.all(np.isfinite(run.data[:, 2:2 + 2 * n])))
    if expected is None:
        ok = run.state == "DONE" and run.fault == "NONE" and fault_tick is None
        rows.append([label, "end", f"{run.state}/{run.fault} after {int(last[0])} ticks", f"DONE at {task.n_ticks}",
                     ok and int(last[0]) == task.n_ticks])
        passed &= ok and int(last[0]) == task.n_ticks
    else:
        lo, hi, expected_fault = expected
        ok = run.fault == expected_fault and fault_tick is not None and lo - slack <= fault_tick <= hi + slack
        if ok and fault_tick in fw and fault_tick - 1 in fw:
            held = fw[fault_tick][2:2 + n]
            prev = fw[fault_tick - 1][2:2 + n]
            ok = bool(np.array_equal(held, prev) and np.all(held <= robot.qmax) and np.all(held >= robot.qmin))
        where = f"tick {fault_tick}" if fault_tick is not None else "none"
        span = f"tick {hi}" if lo == hi else f"ticks {lo}..{hi}"
        why = "limits" if expected_fault == "JOINT_LIMIT" else "tracking guard"
        rows.append([label, f"end (plan leaves the {why})", f"{run.state}/{run.fault} at {where}",
                     f"{expected_fault} at {span} (t = {hi * task.dt:.4g} s)", ok])
        passed &= ok
    rows.append([label, "commands finite", "yes" if held_ok else "NO", "yes", held_ok])
    passed &= held_ok
    return Comparison(rows, passed, dq, de, fault_tick)


# ------------------------------------------------------------------------------------------
# command line (the Makefile's task step)
# ------------------------------------------------------------------------------------------

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


def main(argv: Sequence[str] | None = None) -> int:
    from ..planning.result import read_plan
    from ..planning.tasks import apply_overrides, load_task

    ap = argparse.ArgumentParser(prog="python -m armgen.verify.firmware", description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    h = sub.add_parser("header", help="write task_params.h and fw_ptp.{h,c} for a task file or a plan CSV")
    h.add_argument("source", help="a task file (.toml) or a plan CSV with its plan.json")
    h.add_argument("-o", "--out", required=True, help="output directory")
    h.add_argument("--robot", default=None, help="the firmware's robot (checked against the task's)")
    h.add_argument("--set", dest="overrides", action="append", default=[], help="override a task field (TOML value)")
    h.add_argument("--gen-dir", default=None, help="the robot's generated code (default generated/<robot>/)")
    h.add_argument("--lock", default=None, metavar="JOINTS@TIME",
                   help="the drives report these joints locked from TIME s on (e.g. 5@1.38), unknown to the plan")
    args = ap.parse_args(argv)
    try:
        robot = load_robot(args.robot) if args.robot else None
        src = Path(args.source)
        if src.suffix == ".csv":
            task = task_from_plan(read_plan(src), str(src), robot)
        else:
            doc, _ = load_task(src)
            apply_overrides(doc, list(args.overrides))
            task = task_from_dict(doc, str(src), robot)
        if args.lock:
            task = schedule_lock(task, args.lock)
        if robot is not None and task.robot.sha256 != robot.sha256:
            raise FirmwareError(f"{src}: the task is for robot '{task.robot.name}', the firmware is built for "
                                f"'{robot.name}' (make ROBOT={task.robot.name})")
        for path in write_task_files(task, args.out, args.gen_dir):
            print(f"wrote {path}")
    except ArmgenError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return exc.exit_code
    return 0


if __name__ == "__main__":
    sys.exit(main())
