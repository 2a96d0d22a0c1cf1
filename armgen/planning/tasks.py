"""Task files (TOML): loading, ``--set`` overrides, and the one path from a task's bytes to its
plan: the planner's schema validates the document (:func:`validate_task`), the task's robot is
loaded once, the planner's ``configure`` turns both into its typed SI config
(:func:`configure_task` → :class:`Task`), and its ``plan`` plans that (:func:`plan_configured`).
The planners are found through :mod:`.registry`."""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

from .._version import __version__
from ..errors import PlanFileError, PlanningError, RobotFileError, RobotMismatchError, TaskFileError, excerpt
from ..description import bundled_robots, resolve_robot_path
from ..schemas import (MAX_INPUT_FILE_BYTES, MAX_NESTING_DEPTH, format_validation_error, parse_toml_bounded,
                       read_input_file)
from .common.collision import clearance_report, enforce_clearance, task_collision
from .limits import enforce_limits, enforce_speed_limits
from .torque import enforce_torque_limits, joint_columns, planned_robot, torque_report
from ..robot import Robot, load_robot
from .registry import Planner, planner
from .result import PlanResult, first_invalid_sample

# Resource caps, checked from the validated task before any planning starts. Each can be
# raised for one run with the CLI option named in the error (``armgen plan --max-steps N``).
# At the resolved-rate planners' ~0.3 ms per step, 2e6 steps is about ten minutes.
MAX_INTEGRATION_STEPS = 2_000_000
# 1e6 rows of ~25 columns is ~0.4 GB of CSV, beyond any controller's memory.
MAX_OUTPUT_SAMPLES = 1_000_000


@dataclass(frozen=True)
class ResourceCaps:
    max_steps: int = MAX_INTEGRATION_STEPS
    max_samples: int = MAX_OUTPUT_SAMPLES


# Task fields that name a file. A relative path there is relative to the task file's folder
# (as in CMake, Cargo, pyproject), so `armgen plan tasks/job.toml` works from any folder; a
# bundled robot name stays a name. Values given with --set are relative to the current folder.
FILE_FIELDS = ("robot",)


def resolve_file_fields(task: dict[str, Any], folder: Path) -> None:
    """Rewrite the task's relative file references (:data:`FILE_FIELDS`) to paths from ``folder``."""
    for key in FILE_FIELDS:
        value = task.get(key)
        if isinstance(value, str) and value not in bundled_robots() and not Path(value).is_absolute():
            task[key] = str(folder / value)


def load_task(path: str | Path) -> tuple[dict[str, Any], str]:
    """Read a task file (size and nesting bounded); returns the parsed dict, its file references
    resolved from the file's folder, and the file's sha256."""
    path = Path(path)
    data = read_input_file(path, MAX_INPUT_FILE_BYTES, "task file", TaskFileError)
    task = parse_toml_bounded(data, str(path), TaskFileError)
    resolve_file_fields(task, path.parent)
    return task, hashlib.sha256(data).hexdigest()


def parse_value(text: str, where: str) -> Any:
    """A TOML value as given on the command line (``where`` names the option in errors)."""
    try:
        doc = parse_toml_bounded(f"v = {text}", where, TaskFileError)
    except TaskFileError as exc:
        if "not valid TOML" not in str(exc):
            raise
        return text  # a bare word is a string
    return doc["v"]


def set_field(task: dict[str, Any], key: str, value: Any, where: str) -> None:
    """Set the task field ``key`` (dotted keys reach into tables) to ``value``; ``where`` names
    the option in errors."""
    parts = [p.strip() for p in key.split(".")]
    if not all(parts):
        raise TaskFileError(f"{where}: empty key component in {excerpt(repr(key))}")
    if len(parts) > MAX_NESTING_DEPTH:
        raise TaskFileError(f"{where}: key nested deeper than {MAX_NESTING_DEPTH} levels")
    node = task
    for part in parts[:-1]:
        nxt = node.setdefault(part, {})
        if not isinstance(nxt, dict):
            raise TaskFileError(f"{where}: '{part}' is not a table in the task file")
        node = nxt
    node[parts[-1]] = value


def parse_override(item: str) -> tuple[str, Any]:
    """``key=value`` as given to ``--set`` → (dotted key, value parsed as TOML)."""
    if "=" not in item:
        raise TaskFileError(f"--set {excerpt(repr(item))}: expected key=value (e.g. --set integrator.h=0.01)")
    key, raw = item.split("=", 1)
    return key.strip(), parse_value(raw.strip(), f"--set {excerpt(repr(item))}")


def apply_overrides(task: dict[str, Any], overrides: list[str]) -> dict[str, Any]:
    """Apply ``key=value`` overrides; dotted keys reach into tables; values are TOML. The
    result is validated by the planner's schema like the file itself (in :func:`run_task`)."""
    for item in overrides:
        key, value = parse_override(item)
        set_field(task, key, value, f"--set {excerpt(repr(item))}")
    return task


# No quantity in a task file exceeds this magnitude in any unit armgen accepts (the largest,
# a link's axial stiffness EA, is ~1e9 N); bounding every number keeps products and squares
# of task values (~1e24) far from floating-point overflow.
MAX_ABS_TASK_NUMBER = 1e12


def _check_magnitudes(value: Any, where: str, source: str) -> None:
    if isinstance(value, (int, float)) and not isinstance(value, bool) and abs(value) > MAX_ABS_TASK_NUMBER:
        raise TaskFileError(f"{source}: field '{where}' = {value:g} is beyond ±{MAX_ABS_TASK_NUMBER:g}; no "
                            "physical quantity of a task is that large: check the value and its unit")
    if isinstance(value, dict):
        for key, item in value.items():
            _check_magnitudes(item, f"{where}.{key}" if where else str(key), source)
    elif isinstance(value, list):
        for k, item in enumerate(value):
            _check_magnitudes(item, f"{where}[{k}]", source)


def validate_task(task: dict[str, Any], source: str) -> Any:
    """The task checked against its planner's schema (keys, types, ranges); returns the model."""
    spec = planner(task.get("planner") if isinstance(task, dict) else None, source)
    try:
        model = spec.schema.model_validate(task)
    except ValidationError as exc:
        raise TaskFileError(format_validation_error(exc, source, task)) from None
    _check_magnitudes(task, "", source)
    return model


def check_caps(spec: Planner, model: Any, caps: ResourceCaps, source: str) -> None:
    """Refuse, before planning, a task whose steps or samples exceed the caps."""
    steps, samples = spec.workload(model)
    if steps > caps.max_steps:
        raise TaskFileError(f"{source}: the task needs {steps:.3g} integration steps, more than the cap of "
                            f"{caps.max_steps}; raise integrator.step (or shorten the duration), or lift the cap "
                            "with --max-steps N")
    if samples > caps.max_samples:
        raise TaskFileError(f"{source}: the plan would have {samples:.3g} samples, more than the cap of "
                            f"{caps.max_samples}; write fewer (integrator.output_every, step, output_step) or "
                            "lift the cap with --max-samples N")


@dataclass(frozen=True)
class TaskDocument:
    """A task file's TOML as read (file references resolved, overrides applied), not yet checked."""

    document: dict[str, Any]
    source: str
    sha256: str = ""


@dataclass(frozen=True)
class Task:
    """A task file read once and checked: its planner, the validated document (file units), the
    planner's typed SI configuration, and where it came from."""

    planner: Planner
    model: Any
    config: Any
    source: str
    sha256: str = ""
    document: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)


def task_robot(model: Any, source: str, robot: Robot | None = None) -> Robot | None:
    """The robot the task names, loaded once; with ``robot`` given (a firmware's), the task must
    name that robot (checked here, before anything is planned: a
    :class:`~armgen.errors.RobotMismatchError` otherwise) and it is used as it is."""
    reference = getattr(model, "robot", None)
    if reference is None:
        return robot
    try:
        if robot is not None and robot.path and resolve_robot_path(reference).resolve() == Path(robot.path):
            return robot
        named = load_robot(reference)
    except RobotFileError as exc:
        raise RobotFileError(f"{source}: field 'robot' = {excerpt(repr(reference))}: {exc}") from None
    if robot is not None and named.sha256 != robot.sha256:  # another path may hold the same file
        raise RobotMismatchError(f"{source}: the task is for robot '{named.name}' ({reference}), not '{robot.name}' "
                                 f"({robot.source}); give the task's robot, or plan the task for this robot")
    return robot if robot is not None else named


def configure_task(task: dict[str, Any], source: str, sha256: str = "", robot: Robot | None = None,
                   caps: ResourceCaps = ResourceCaps()) -> Task:
    """Validate ``task`` (a task file's document, overrides applied), refuse a workload beyond
    ``caps`` (before anything is loaded), load its robot once (or check it names ``robot``) and
    make its planner's typed SI configuration."""
    model = validate_task(task, source)
    spec = planner(task["planner"], source)
    check_caps(spec, model, caps, source)
    config = spec.configure(model, task_robot(model, source, robot), source)
    return Task(spec, model, config, source, sha256, task)


def plan_configured(task: Task, backend: str = "symbolic", caps: ResourceCaps = ResourceCaps()) -> PlanResult:
    """Plan a configured task (caps checked first), and reject a plan with a non-finite sample
    or (policy ``[check] limits = "error"``) one that leaves the joints' limits (position, speed,
    and for a robot with inertials, torque: ``summary.joint_torque``)."""
    source = task.source
    check_caps(task.planner, task.model, caps, source)
    started = time.perf_counter()
    try:
        with np.errstate(all="ignore"):  # a non-finite result is reported below, as an infeasible plan
            result: PlanResult = task.planner.plan(task.config, backend)
    except OverflowError as exc:
        raise PlanningError(f"{source}: the plan overflowed ({exc}); the task's numbers are too large for a "
                            "physical motion (check durations, steps and gains)") from None
    elapsed = time.perf_counter() - started
    invalid = first_invalid_sample(result.columns, result.data)
    if invalid is not None:
        row, col = invalid
        raise PlanningError(f"{source}: the plan is not feasible: column '{result.columns[col]}' is "
                            f"{result.data[row, col]} at sample {row}; nothing was written (check the timing "
                            "and the numbers of the task)")
    summary = result.metadata.get("summary", {})  # every planner's task has [check] limits
    enforce_limits(summary.get("limit_violations", []), task.model.check.limits, source)
    enforce_speed_limits(summary.get("joint_speed"), task.model.check.limits, source, task.planner.name)
    robot = planned_robot(task.config)
    slowing = summary.get("joint_torque", {}).get("slowing")  # a program slowed for torque (toolpath.limits)
    torque = None if robot is None else torque_report(robot, result.columns, result.data, slowing)
    if torque is not None:  # a robot with inertials (docs/dynamics.md, "Torque limits in planning")
        result.metadata.setdefault("summary", {})["joint_torque"] = torque
    enforce_torque_limits(torque, task.model.check.limits, source, task.planner.name)
    clearance = plan_clearance(task.config, robot, result.columns, result.data)
    if clearance is not None:  # a robot with capsules (docs/collision.md, "Obstacles in task files")
        result.metadata.setdefault("summary", {})["collision"] = clearance
    # a snake plan measures its links itself (its CSV has universal-joint angles, not joint columns)
    enforce_clearance(result.metadata.get("summary", {}).get("collision"), task.model.check.limits, source)
    meta = {
        "armgen_version": __version__,
        "task_file": source,
        "task_sha256": task.sha256,
        "planner": task.planner.name,
        "backend": backend,
        "task": task.document,  # the task as read (overrides applied): configure_task plans it again
    }
    meta.update(result.metadata)
    meta.setdefault("summary", {})["run_time_s"] = elapsed
    result.metadata = meta
    if result.config is None:
        result.config = task.config
    return result


def plan_clearance(config: Any, robot: Robot | None, columns: list[str], data: np.ndarray) -> dict[str, Any] | None:
    """``summary.collision`` of a plan whose task has a :class:`~.common.collision.TaskCollision`
    (a robot with capsules) and whose columns give the joints: every sample measured."""
    collision = task_collision(config)
    found = None if robot is None or collision is None else joint_columns(robot, columns)
    if found is None or "t_s" not in columns:
        return None
    return clearance_report(robot, data[:, columns.index("t_s")], data[:, found.q], collision)


def run_task(task: dict[str, Any], source: str, task_sha256: str = "", backend: str = "symbolic",
             caps: ResourceCaps = ResourceCaps(), robot: Robot | None = None) -> PlanResult:
    """Configure ``task`` (:func:`configure_task`) and plan it (:func:`plan_configured`)."""
    return plan_configured(configure_task(task, source, task_sha256, robot, caps), backend, caps)


def plot_plan(result: PlanResult, source: str, robot=None):
    """The plan's figure (a :class:`matplotlib.figure.Figure`) drawn by its planner's plots
    module; write it with :func:`armgen.planning.plotting.save_figure`. An arm is drawn through
    ``robot``'s kinematics (a :class:`~armgen.robot.Robot`; default: the one ``plan.json``
    records, :func:`armgen.planning.plotting.plan_robot`); a PTP figure draws the arm only for a
    robot with capsules (at its closest approach)."""
    name = result.metadata.get("planner")
    try:
        spec = planner(name, source)
    except TaskFileError:
        raise PlanFileError(f"{source}: no plot for planner {excerpt(repr(name))} (plan.json missing or unknown planner); "
                            "keep the plan.json that armgen plan wrote beside the CSV") from None
    try:
        return spec.plot(result, robot=robot)
    except (KeyError, IndexError, TypeError, ValueError) as exc:
        # A plan.json that validates but lacks a block the figure needs (hand-edited, from
        # another version) is a PlanFileError, not a crash.
        raise PlanFileError(f"{source}: the plan and its plan.json do not fit the {name} figure "
                            f"({type(exc).__name__}: {str(exc)[:120]}); regenerate them with armgen plan") from None
