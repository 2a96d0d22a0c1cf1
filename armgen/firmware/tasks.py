"""A plan or a task file → the controller's task (:class:`~.configuration.FirmwareTask`) through
its planner's adapter (:mod:`.adapters`).

The resolved-rate planners (cartesian, fault_tolerant, wgpm) hand the adapter the planner's
typed SI configuration the plan was made with (``PlanResult.config``: e.g. the integrator step
after any refinement), and a program the plan's final motion. A plan read from disk carries
neither: its recorded task (plan.json) is configured again for the firmware's robot, and a
program's task planned again, which must give the plan's samples. The playback planners (ptp,
snake) hand over the plan's result itself: the segments' coefficients, the joint samples.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..errors import excerpt
from ..planning.result import PlanResult, read_plan
from ..planning.common.collision import task_collision
from ..planning.tasks import Task, apply_overrides, configure_task, load_task, plan_configured
from ..robot import Robot
from .adapters import cartesian, fault_tolerant, ptp, snake, wgpm
from .configuration import FirmwareTask, with_collision
from .errors import FirmwareError

# The planners whose task the controller integrates on board: the adapter takes the typed
# config the plan was made with (the step after any refinement, a program's final motion).
RESOLVED_ADAPTERS = {"cartesian": cartesian.firmware_task, "fault_tolerant": fault_tolerant.firmware_task,
                     "wgpm": wgpm.firmware_task}
# The planners whose plan the controller plays back: the adapter takes the config and the plan's result.
PLAYBACK_PLANNERS = ("ptp", "snake")
# A program plan read from disk is planned again; its samples must come back to this (the
# CSV holds the doubles exactly; a plan made with another backend differs by ~1e-12, far
# below the double controller's 1e-9 replay bound, while another path or time law differs
# by far more).
REPLANNED_SAMPLE_TOL = 1e-9


def task_source(plan: PlanResult, source: str) -> str:
    """Where a plan's task was read from (its ``task_file``, when that file is still there),
    else the plan itself: a program's poses files are relative to it."""
    task_file = plan.metadata.get("task_file")
    return task_file if isinstance(task_file, str) and Path(task_file).is_file() else source


def _is_program(config: Any) -> bool:
    """A program path (its time law is the plan's, known only once planned)."""
    path = getattr(config, "path", config)  # fault_tolerant, wgpm: a PathTask; cartesian: the task itself
    return getattr(path, "motion", None) is not None


def _replanned(task: Task, plan: PlanResult, source: str) -> PlanResult:
    """A program plan read from disk planned again: it must give the plan's own duration and
    samples — a plan from another armgen, robot file or poses file is refused rather than run
    with another path or time law."""
    replanned = plan_configured(task)
    recorded = (plan.metadata.get("path") or {}).get("program_duration_s")
    same = (recorded == replanned.motion.duration and replanned.columns == plan.columns
            and replanned.data.shape == plan.data.shape
            and bool(np.all(np.abs(replanned.data - plan.data) <= REPLANNED_SAMPLE_TOL)))
    if not same:
        raise FirmwareError(f"{source}: planning its task again does not give this plan (program of "
                            f"{replanned.motion.duration!r} s, the plan says {recorded!r} s; or other samples): it was "
                            "made by another armgen, robot file or poses file; plan the task again and give that plan, "
                            "or give the task file (--task)")
    return replanned


def _adapted(name: str, config: Any, plan: PlanResult, source: str, robot: Robot | None) -> FirmwareTask:
    if name == "ptp":
        task = ptp.firmware_task(config, plan, source, robot)
    elif name == "snake":
        return snake.firmware_task(config, plan, source)  # its [[obstacles]] are the tube's (docs/snake.md)
    else:
        task = RESOLVED_ADAPTERS[name](config, source)
    return _checked(task, config)


def _checked(task: FirmwareTask, config: Any) -> FirmwareTask:
    """The task with the task's [collision] on board: every command's clearance checked, the
    resolved-rate modes descending the criterion as the plan did (docs/collision.md, "On the
    board"). Its obstacle slots are its robot's: a ptp task played on another robot is refused."""
    collision = task_collision(config)
    if collision is None or collision.settings is None:
        return task
    planned = next((r for holder in (config, getattr(config, "path", None))
                    for r in (getattr(holder, "robot_model", None), getattr(holder, "robot", None))
                    if isinstance(r, Robot)), None)
    if planned is None or planned.sha256 != task.robot.sha256:
        raise FirmwareError(f"{task.source}: the task's [collision] is set up for robot "
                            f"'{getattr(planned, 'name', '?')}''s capsules, not '{task.robot.name}''s; run it on its "
                            "own robot, or remove [[obstacles]] and [collision] from the task")
    return with_collision(task, collision)


def task_from_plan(plan: PlanResult, source: str, robot: Robot | None = None) -> FirmwareTask:
    """The controller task that reproduces a plan (made here, or read with :func:`read_plan`);
    ``robot``, when given, is the firmware's: a plan from disk must name it."""
    name = plan.metadata.get("planner")
    if name not in RESOLVED_ADAPTERS and name not in PLAYBACK_PLANNERS:
        raise FirmwareError(f"{source}: the controller runs cartesian, ptp, snake, fault_tolerant and wgpm plans, not "
                            f"planner {excerpt(repr(name))}")
    if plan.config is not None:
        return _adapted(name, plan.config, plan, source, robot)
    # read from disk: its recorded task configured again (a program's planned again and compared)
    recorded = plan.metadata.get("task")
    if not recorded:
        raise FirmwareError(f"{source}: no task in its plan.json (write plans with `armgen plan`)")
    task = configure_task(recorded, task_source(plan, source), robot=robot)
    if _is_program(task.config):
        replanned = _replanned(task, plan, source)
        return _adapted(name, replanned.config, replanned, source, robot)
    return _adapted(name, task.config, plan, source, robot)


def task_from_dict(document: dict[str, Any], source: str, robot: Robot | None = None) -> FirmwareTask:
    """From a task file's document: circle and line tasks from their configuration alone;
    programs (whose time law is the plan's), ptp and snake planned first."""
    task = configure_task(document, source, robot=robot)
    name = task.planner.name
    if name in RESOLVED_ADAPTERS and not _is_program(task.config):
        return _checked(RESOLVED_ADAPTERS[name](task.config, source), task.config)
    return task_from_plan(plan_configured(task), source, robot)


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


def task_from_file(source: str | Path, robot: Robot | None = None, overrides: Sequence[str] = ()) -> FirmwareTask:
    """The controller task of a task file (.toml, with ``--set`` overrides) or a plan CSV (with
    its plan.json); ``robot``, when given, must be the task's (checked when it is configured:
    a :class:`~armgen.errors.RobotMismatchError`)."""
    src = Path(source)
    if src.suffix == ".csv":
        if overrides:
            raise FirmwareError(f"{src}: --set changes a task file, not a plan made already; re-plan the task instead")
        return task_from_plan(read_plan(src), str(src), robot)
    doc, _ = load_task(src)
    apply_overrides(doc, list(overrides))
    return task_from_dict(doc, str(src), robot)
