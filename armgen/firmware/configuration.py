"""The controller's C configuration, what every planner's adapter (:mod:`.adapters`) shares: the
text of ``task_params.h``, which defines ``const ctrl_config fw_task`` (a few parameters for
the resolved-rate modes; knots and coefficients for playback; a joint table for sampled
playback). It is compiled in, so the host and the Cortex-M4F builds run the identical task.

The C text is in the templates ``armgen/data/templates/firmware/*`` (``string.Template``: a
missing value is an error); this module and the adapters supply the values, C literals made by
:mod:`.literals`. :func:`write_task_files` writes ``task_params.h``, the PTP evaluator
``fw_ptp.{h,c}`` and ``robot_fw.c`` (the generated functions the controller calls) for the
stub's Makefile (``armgen firmware-task``).
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..codegen.generate import GENERATED_DIR
from ..codegen.ptp_c import generate_ptp_evaluator
from ..data import render_template
from ..description.collision import obstacle_kind
from ..errors import OptionError, RobotFileError, excerpt
from ..fileio import write_text_atomic
from ..planning.toolpath.timelaw import ProgramMotion
from ..robot import Robot
from ..symbolic.dynamics import require_dynamics
from .errors import FirmwareError
from .literals import c_ints, c_real, c_reals
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
DEFAULT_RESIDUAL_REL = 1e-3  # |J q̇ − ẋ|∞ ≤ 1e-3 |ẋ|∞ + 1e-6: float rounding stays below 1e-5
DEFAULT_RESIDUAL_ABS = 1e-6
DEFAULT_POS_ERR_MAX = 5e-3  # m: the planner's own MAX_PATH_ERROR

# Controller modes that integrate a Cartesian task on board (compared by q and task error).
RESOLVED_MODES = ("resolved_rate", "fault_tolerant", "weighted_gpm")
LAW_IDS = {"cubic": "CTRL_LAW_CUBIC", "trapezoidal": "CTRL_LAW_TRAPEZOIDAL", "constant": "CTRL_LAW_CONSTANT"}
PATH_IDS = {"circle": "CTRL_PATH_CIRCLE", "line": "CTRL_PATH_LINE"}
PROGRAM_TABLE = "fw_program_table"  # the program table's name in task_params.h
# The feed-forward torque of each command (ctrl_config.feedforward; a robot with inertials only):
# none, gravity g(q), or the inverse dynamics rnea(q, q̇, q̈) — the default, the torque a
# current-controlled drive needs and the one the TORQUE fault must check.
FEEDFORWARD_IDS = {"none": "CTRL_FF_NONE", "gravity": "CTRL_FF_GRAVITY", "inverse_dynamics": "CTRL_FF_INVERSE_DYNAMICS"}
DEFAULT_FEEDFORWARD = "inverse_dynamics"
_FEEDFORWARD_LINE = re.compile(r"^    \.feedforward = CTRL_FF_\w+,$", re.M)  # feedforward.h's first line


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
    feedforward: str = ""  # FEEDFORWARD_IDS' key in the header; "" (as the adapters make it): the robot's default
    collision: Any = None  # the TaskCollision the controller checks every command against (with_collision), or None

    def __post_init__(self) -> None:
        if not self.feedforward:
            self.feedforward = default_feedforward(self.robot)

    @property
    def max_segments(self) -> int:
        return max(MAX_SEGMENTS, self.nseg)


def template(name: str, **values: object) -> str:
    """The firmware template ``name`` (``armgen/data/templates/firmware/``) filled with ``values``."""
    return render_template(f"firmware/{name}", **values)


def number(x: float) -> str:
    """A number for a comment of the generated C (``%g``)."""
    return format(x, "g")


def blend(law, source: str) -> str:
    """The time law's blend for the controller, which checks it whatever the law: [0, 0.5]."""
    if not (math.isfinite(law.blend) and 0.0 <= law.blend <= 0.5):
        raise FirmwareError(f"{source}: timing.blend = {law.blend!r} must be in [0, 0.5] (the fraction of the duration "
                            "spent accelerating), also when the time law does not use it")
    return c_real(law.blend)


def _lock_lines(lock_tick: int, lock_mask: int) -> str:
    return template("task_lock.h", lock_mask=int(lock_mask), lock_tick=int(lock_tick))


def task_header(robot: Robot, source: str, fields: str, comment: str, lock_tick: int = -1, lock_mask: int = 0,
                tables: str = "") -> str:
    """The text of task_params.h: ``fields`` the initialiser of ``fw_task``, ``tables`` the const
    data it points to (complete lines)."""
    return template("task_params.h", source=Path(source).name or "a task", robot=robot.name, ndof=robot.n,
                    sha256=robot.sha256, comment=comment, ntask=len(robot.task_rows), tables=tables, fields=fields,
                    lock=_lock_lines(lock_tick, lock_mask)) + "\n"


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


def default_feedforward(robot: Robot) -> str:
    """The feed-forward a task of ``robot`` gets unless asked otherwise: the inverse dynamics for a
    robot with inertials, none without (its firmware has no dynamics)."""
    return DEFAULT_FEEDFORWARD if robot.has_dynamics else "none"


def torque_limits(robot: Robot) -> np.ndarray:
    """``ctrl_config.tau_max``: each joint's taumax (N·m, N), 0 (no limit) where the robot gives none."""
    return np.where(np.isfinite(robot.taumax), robot.taumax, 0.0)


def feedforward_fields(robot: Robot, choice: str) -> str:
    """The feed-forward fields of ``fw_task`` (a robot with inertials only)."""
    return template("feedforward.h", feedforward=FEEDFORWARD_IDS[choice], tau_max=c_reals(torque_limits(robot)))


def common_fields(robot: Robot, mode: str, dt: float, q_start: np.ndarray) -> str:
    """The fields of ``fw_task`` every mode has (after checking the robot's limits fit the
    controller); for a robot with inertials, the default feed-forward and the torque limits too
    (without inertials the controller has no such fields: the text is as before dynamics)."""
    check_controller_limits(robot, dt)
    fields = template("common_fields.h", mode=mode, dt=c_real(dt), q_start=c_reals(q_start), q_min=c_reals(robot.qmin),
                      q_max=c_reals(robot.qmax), qdot_max=c_reals(speed_guard(robot)),
                      qddot_max=c_reals(acceleration_limit(robot)), residual_rel=c_real(DEFAULT_RESIDUAL_REL),
                      residual_abs=c_real(DEFAULT_RESIDUAL_ABS), pos_err_max=c_real(DEFAULT_POS_ERR_MAX))
    if not robot.has_dynamics:
        return fields
    return f"{fields}\n{feedforward_fields(robot, default_feedforward(robot))}"


def check_feedforward(robot: Robot, choice: str, source: str = "--feedforward") -> None:
    """Refuse a feed-forward choice that is not one of :data:`FEEDFORWARD_IDS`, or anything but
    ``none`` for a robot without inertials (naming its file and the fix)."""
    if choice not in FEEDFORWARD_IDS:
        raise OptionError(f"{source} {excerpt(repr(choice))}: give one of {', '.join(FEEDFORWARD_IDS)}")
    if choice != "none":
        try:
            require_dynamics(robot)
        except RobotFileError as exc:
            raise OptionError(f"{source} {choice}: {exc}; or leave the feed-forward at none") from None


def with_feedforward(task: FirmwareTask, choice: str, source: str = "--feedforward") -> FirmwareTask:
    """The task with the controller computing ``choice`` as each command's feed-forward torque
    (``none``, ``gravity``, ``inverse_dynamics``); anything but ``none`` needs a robot with inertials."""
    check_feedforward(task.robot, choice, source)
    if not task.robot.has_dynamics:
        return task  # none: the firmware of a robot without inertials has no feed-forward at all
    lines = _FEEDFORWARD_LINE.findall(task.header)
    if len(lines) != 1:
        raise FirmwareError(f"{source}: the task's task_params.h does not hold one feed-forward field (edited by hand?)")
    new = feedforward_fields(task.robot, choice).splitlines()[0]
    return dataclasses.replace(task, header=task.header.replace(lines[0], new), feedforward=choice)


# The resolved-rate modes descend the collision criterion (-gain ∇H_C in their null-space term);
# the others only check the clearance.
CRITERION_MODES = RESOLVED_MODES
_FW_TASK_OPENING = "const ctrl_config fw_task = {\n"  # task_params.h's initialiser (task_params.h)


def collision_tables(robot: Robot, collision, mode: str) -> str:
    """task_params.h's lines of a task with ``[collision]`` (``collision``: its
    :class:`~armgen.planning.common.collision.TaskCollision`): the obstacle slots as const data, the
    generated collision functions bound to them, and the ``ctrl_collision`` the configuration
    points to. The criterion is bound only where the mode descends it with a gain above 0."""
    settings = collision.settings
    slots = []
    for name, matrix in collision.parameters.items():  # the functions' input order (obstacle_parameters)
        values = np.asarray(matrix, dtype=float).reshape(-1, order="F")  # one column per slot
        slots.append(template("collision_slot.h", kind=name, size=values.size, values=c_reals(values, f"obstacle {name}")))
    arguments = "".join(f"fw_task_{name}, " for name in collision.parameters)
    descends = mode in CRITERION_MODES and settings.gain > 0.0
    kinds: dict[str, int] = {}
    for obstacle in collision.obstacles:
        kinds[obstacle_kind(obstacle)] = kinds.get(obstacle_kind(obstacle), 0) + 1
    described = ", ".join(f"{n} {k}{'s' if n > 1 else ''}" for k, n in kinds.items()) or "no obstacle (the arm itself)"
    return template("collision.h", obstacles=described, clearance=number(settings.clearance),
                    activation=number(settings.activation), gain=number(settings.gain),
                    gain_note="" if descends or settings.gain == 0.0 else " (this mode only checks the clearance)",
                    ndist=len(robot.collision_pairs()), slots="\n".join(slots), arguments=arguments,
                    criterion=template("collision_criterion.h", arguments=arguments) if descends else "",
                    clearance_literal=c_real(settings.clearance), activation_literal=c_real(settings.activation),
                    gain_literal=c_real(settings.gain if descends else 0.0),
                    criterion_name="fw_task_criterion" if descends else "NULL") + "\n\n"


def with_collision(task: FirmwareTask, collision) -> FirmwareTask:
    """The task with the controller checking every command against ``[collision]``'s clearance
    (the arm's self pairs and the task's obstacles: the COLLISION fault) and, in the resolved-rate
    modes, descending the criterion as the planners do; ``collision`` None (a robot without
    capsules) or without settings (a task without ``[collision]``): the task as it is, unchecked
    on board (docs/collision.md, "On the board")."""
    if collision is None or collision.settings is None:
        return task
    if task.header.count(_FW_TASK_OPENING) != 1:
        raise FirmwareError(f"{task.source}: the task's task_params.h does not hold one fw_task (edited by hand?)")
    tables = collision_tables(task.robot, collision, task.mode)
    header = task.header.replace(_FW_TASK_OPENING,
                                 f"{tables}{_FW_TASK_OPENING}    .collision = &fw_task_collision,\n")
    return dataclasses.replace(task, header=header, collision=collision)


def program_path(duration: float) -> str:
    """The ``rr`` path fields of a program: the table and the plan's duration (whole ticks)."""
    return template("path_program.h", table=PROGRAM_TABLE, duration=c_real(duration))


def geometric_path(path_type: str, via, end, axis, angle: float, duration: float, law, source: str,
                   relative: bool = False, turns: float = 1.0) -> str:
    """The ``rr`` path fields of a circle or a line: its points, the end orientation's axis and
    angle (the planner's own, from its FK of the start), the time law."""
    return template("path_geometric.h", path=PATH_IDS[path_type], via=c_reals(via if via is not None else np.zeros(3)),
                    end=c_reals(end), rot_axis=c_reals(axis), rot_angle=c_real(angle), duration=c_real(duration),
                    law=LAW_IDS[law.kind], blend=blend(law, source), relative=1 if relative else 0,
                    turns=c_real(turns))


def program_tables(motion: ProgramMotion | None) -> str:
    """The program table ``fw_task.rr.program`` points to, as complete lines ("" for a circle or line)."""
    return "" if motion is None else program_table_c(motion, PROGRAM_TABLE) + "\n\n"


def sample_column(joint) -> str:
    """The plan column of a joint's samples (the snake planner's naming): <name>_m for a
    prismatic joint, <name>_rad for a revolute one."""
    return f"{joint.name}_{'m' if joint.type == 'prismatic' else 'rad'}"


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
    # The lock's lines end task_params.h (task_header): the same lines with the new schedule.
    scheduled = _lock_lines(task.lock_tick, task.lock_mask) + "\n"
    if not task.header.endswith(scheduled):
        raise FirmwareError(f"{source}: the task's task_params.h does not end with its lock schedule (edited by hand?)")
    header = task.header[:-len(scheduled)] + _lock_lines(tick, mask) + "\n"
    return dataclasses.replace(task, header=header, lock_tick=tick, lock_mask=mask)


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
