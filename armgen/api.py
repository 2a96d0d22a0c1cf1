"""The Python API: load a robot, plan a task, generate C, verify it.

This module is what the command line does, minus the printing: every ``armgen`` command calls
the functions here (and the robot description's listing), nothing deeper. The main ones are
also in the :mod:`armgen` namespace (``armgen.plan`` …)::

    import armgen

    robot = armgen.load_robot("panda")            # bundled name, robot TOML or URDF
    T = robot.fk(robot.qr)                        # (4, 4)
    plan = armgen.plan("examples/iiwa14_fault_circle_gpm.toml", **{"fault.time": 1.0})  # overrides as --set
    plan.to_pandas().plot(x="t_s", y="q1_rad")
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

from .errors import (ArmgenError, Interrupted, OptionError, OutputError, PlanFileError, PlanningError,
                     RobotFileError, TaskFileError, ToolchainError, VerificationError, excerpt)
from .robot import Robot, load_robot, load_robot_any

if TYPE_CHECKING:  # heavy imports only for type checkers
    import pandas
    from matplotlib.figure import Figure

    from .planning.result import PlanResult
    from .planning.tasks import ResourceCaps, Task, TaskDocument

# The emulated cores `verify(target=...)` runs the firmware on: the keys of
# armgen.firmware.TARGETS (named here so the command line need not import the firmware layer;
# tests/test_targets.py checks they agree).
VERIFY_TARGETS = ("cortex-m4", "cortex-m7", "cortex-m33", "cortex-m0plus", "rv32imf")

__all__ = ["Robot", "load_robot", "read_task_document", "read_task", "plan", "Plan", "generate", "Generated", "verify", "VerifyReport", "VERIFY_TARGETS",
           "parse_override", "read_plan", "plan_metadata_path", "figure_format", "save_plot", "parse_frame_size",
           "animate_plan", "sweep", "solve_ik", "IkSolution", "generate_ptp", "json_schema", "write_text_atomic",
           "firmware_project", "firmware_task", "link_open", "link_status", "link_move_to", "link_stream",
           "LinkStreamReport", "link_watch", "link_servo", "read_twists",
           # the errors every call may raise, each with its command-line exit code
           "ArmgenError", "RobotFileError", "TaskFileError", "PlanningError", "ToolchainError", "VerificationError",
           "OutputError", "Interrupted", "PlanFileError", "OptionError", "excerpt"]


# -- planning -------------------------------------------------------------------------------

@dataclass
class Plan:
    """A planned trajectory: one row per sample, SI units (angles in rad).

    Attributes
    ----------
    result
        The planner's :class:`~armgen.planning.result.PlanResult` (columns, data, metadata).
    """

    result: PlanResult

    @property
    def columns(self) -> list[str]:
        """Column names with their units (``t_s``, ``q1_rad``, ``x_m`` …)."""
        return list(self.result.columns)

    @property
    def data(self):
        """The samples as a NumPy array of shape ``(samples, len(columns))``."""
        return self.result.data

    @property
    def metadata(self) -> dict[str, Any]:
        """Everything ``plan.json`` holds: task, robot, planner settings, summary."""
        return self.result.metadata

    @property
    def config(self) -> Any:
        """The planner's typed SI configuration the plan was made with (None for a plan read from disk)."""
        return self.result.config

    @property
    def summary(self) -> dict[str, Any]:
        """The planner's figures of merit (task error, limits, run time …)."""
        return dict(self.result.metadata.get("summary", {}))

    def to_pandas(self) -> pandas.DataFrame:
        """The samples as a :class:`pandas.DataFrame` with the plan's column names."""
        import pandas as pd

        return pd.DataFrame(self.result.data, columns=self.result.columns)

    def save(self, csv_path: str | Path, units: str = "rad") -> tuple[Path, Path]:
        """Write the CSV and ``plan.json`` beside it (each atomically), as ``armgen plan`` does.

        Parameters
        ----------
        csv_path
            The CSV to write; the JSON metadata gets the same name with ``.json``.
        units
            Angle unit of the CSV columns, ``"rad"`` or ``"deg"``.

        Returns
        -------
        tuple of pathlib.Path
            The CSV and JSON paths.
        """
        from .planning.result import write_plan

        return write_plan(self.result, csv_path, units)

    def plot(self) -> Figure:
        """The planner's figure (joint angles, velocities, criteria, task error).

        Returns
        -------
        matplotlib.figure.Figure
            A figure the caller may show, save or close.
        """
        from .planning.tasks import plot_plan

        return plot_plan(self.result, str(self.metadata.get("task_file", "plan")))

    def animate(self, path: str | Path, fps: float | None = None, duration: float | None = None) -> Path:
        """Render the arm moving through the plan, as ``armgen animate`` does.

        Parameters
        ----------
        path
            ``.gif`` (Pillow) or ``.mp4`` (needs ffmpeg), written atomically.
        fps
            Frames per second (default: ``armgen animate``'s).
        duration
            Seconds of video (default: the plan's duration, at most 10 s); the samples are
            subsampled to ``fps × duration`` frames.

        Returns
        -------
        pathlib.Path
            The file written.
        """
        from .planning.animation import DEFAULT_FPS, animate_plan

        return animate_plan(self.result, path, DEFAULT_FPS if fps is None else fps, duration)


def read_task_document(task: str | Path | dict[str, Any], **overrides: Any) -> TaskDocument:
    """A task file's TOML read once (or a dict copied), its relative file references resolved
    from its folder, ``overrides`` applied — not yet checked (:func:`read_task` does that).

    Parameters
    ----------
    task
        A task file path, or the task as a dict (the parsed TOML).
    **overrides
        Task fields to replace, with dotted keys for tables: ``**{"timing.duration": 4.0}``,
        or ``timing__duration=4.0`` (``__`` stands for the dot). Values are Python values.

    Raises
    ------
    TaskFileError
        The file cannot be read or is not TOML, or an override names no table (exit code 2).
    """
    from .planning.tasks import TaskDocument, load_task, set_field

    if isinstance(task, dict):
        document, sha, source = copy.deepcopy(task), "", "<task dict>"
    else:
        document, sha = load_task(task)
        source = str(task)
    for key, value in overrides.items():
        set_field(document, key.replace("__", "."), value, f"override {excerpt(repr(key))}")
    return TaskDocument(document, source, sha)


def read_task(task: str | Path | dict[str, Any] | TaskDocument | Task, *, for_robot: Robot | None = None,
              caps: ResourceCaps | None = None, **overrides: Any) -> Task:
    """Read a task once: the file (or dict) with its overrides, validated by its planner's
    schema, its robot loaded, and the planner's typed SI configuration made.

    Parameters
    ----------
    task
        A task file path, the task as a dict (the parsed TOML), a document from
        :func:`read_task_document`, or a task read already (returned as it is; overrides are
        not allowed with these two).
    for_robot
        The robot the task must name (e.g. a firmware's): checked before anything is planned
        (:class:`~armgen.errors.RobotMismatchError`, exit code 5, otherwise), and used instead of
        loading the task's robot file again. (Not ``robot``: that is the task field an override
        may set.)
    caps
        Caps on integration steps and output rows, checked from the validated task before its
        robot is loaded (default: :class:`~armgen.planning.tasks.ResourceCaps`).
    **overrides
        Task fields to replace, as in :func:`read_task_document`.

    Returns
    -------
    Task
        ``planner`` (the registry entry), ``model`` (the validated file, its units),
        ``config`` (SI), ``document`` (the TOML as read, overrides applied), ``source``, ``sha256``.

    Raises
    ------
    TaskFileError, RobotFileError
        The task or its robot file is malformed (exit code 2).
    RobotMismatchError
        The task names another robot than ``for_robot`` (exit code 5).
    """
    from .planning.tasks import ResourceCaps, Task, TaskDocument, configure_task

    if isinstance(task, Task):
        if overrides or for_robot is not None:
            raise OptionError("a task read already is used as it is: give its file or dict to change or check it")
        return task
    if not isinstance(task, TaskDocument):
        task = read_task_document(task, **overrides)
    elif overrides:
        raise OptionError("overrides change a task file: apply them with read_task_document")
    return configure_task(task.document, task.source, task.sha256, for_robot, caps or ResourceCaps())


def plan(task: str | Path | dict[str, Any] | TaskDocument | Task, backend: str = "symbolic", *,
         max_steps: int | None = None,
         max_samples: int | None = None, **overrides: Any) -> Plan:
    """Plan a task, as ``armgen plan`` does (without writing files).

    Parameters
    ----------
    task
        A task file path, the task as a dict (the parsed TOML), a document from
        :func:`read_task_document`, or a task from :func:`read_task`.
    backend
        ``"symbolic"`` (CasADi) or ``"c"`` (the generated C through ctypes).
    **overrides
        Task fields to replace, as in :func:`read_task`.
    max_steps, max_samples
        Caps on integration steps and output rows, checked before planning (default:
        :data:`~armgen.planning.tasks.MAX_INTEGRATION_STEPS`, ``MAX_OUTPUT_SAMPLES``).

    Returns
    -------
    Plan

    Raises
    ------
    TaskFileError
        The task is malformed (exit code 2 on the command line).
    PlanningError
        The task is infeasible (exit code 3).
    """
    from .planning.tasks import ResourceCaps, plan_configured

    caps = ResourceCaps()
    caps = ResourceCaps(max_steps or caps.max_steps, max_samples or caps.max_samples)
    return Plan(plan_configured(read_task(task, caps=caps, **overrides), backend, caps))


# -- code generation ----------------------------------------------------------------------------

@dataclass(frozen=True)
class Generated:
    """The outcome of :func:`generate`.

    Attributes
    ----------
    prefix
        The C identifier prefix (``<prefix>_fk`` …).
    paths
        The files written (header, source, manifest).
    flops
        Operation count of each generated function.
    seconds
        Time taken by the symbolic derivation and code generation.
    """

    prefix: str
    paths: tuple[Path, ...]
    flops: dict[str, int] = field(default_factory=dict)
    seconds: float = 0.0


def generate(robot: Robot | str | Path, out: str | Path | None = None, precision: str = "double",
             prefix: str = "", functions: tuple[str, ...] | None = None) -> Generated:
    """Derive the robot's functions symbolically and write allocation-free C99.

    Parameters
    ----------
    robot
        A :class:`Robot`, a bundled name, a robot TOML or a URDF path.
    out
        Output directory (default: ``./generated/<robot>/`` under the current directory).
    precision
        The header's default real type, ``"double"`` or ``"float"``.
    prefix
        C identifier prefix (default: the robot name).
    functions
        Only these functions (default: all the robot supports).

    Returns
    -------
    Generated
    """
    from .codegen.generate import generate_robot

    try:
        code, paths = generate_robot(load_robot_any(robot), out, precision, prefix, functions)
    except ValueError as exc:  # an invalid prefix or function name
        raise OptionError(str(exc)) from None
    return Generated(code.prefix, tuple(paths), {e.name: e.flops for e in code.emitted}, code.generation_seconds)


# -- verification --------------------------------------------------------------------------------

@dataclass(frozen=True)
class VerifyReport:
    """The outcome of :func:`verify`: one stage per check (fresh, compile, callbacks, replay, target).

    ``bool(report)`` is ``report.passed``; ``str(report)`` is the table ``armgen verify`` prints.
    """

    robot: str
    stages: tuple[Any, ...]

    @property
    def passed(self) -> bool:
        """True when every stage passed."""
        return all(s.passed for s in self.stages)

    def __bool__(self) -> bool:
        return self.passed

    def __str__(self) -> str:
        return "\n".join(s.render() for s in self.stages)

    def to_dict(self) -> dict[str, Any]:
        """Plain data, as written to ``--report``."""
        return {"robot": self.robot, "passed": self.passed,
                "stages": [{"name": s.name, "passed": s.passed, "reused": s.reused, "message": s.message,
                            "columns": s.columns, "rows": s.rows} for s in self.stages]}


def verify(robot: Robot | str | Path, plan: str | Path | None = None, samples: int = 10_000,
           precision: str | None = None, target: str | None = None, report: str | Path | None = None,
           echo: Callable[[str], None] | None = None, generated: str | Path | None = None,
           run: str | Path | None = None, again: bool = False) -> VerifyReport:
    """Check that generated C, fresh for the robot's file, does what the symbolic model does.

    Parameters
    ----------
    robot
        A :class:`Robot`, bundled name, robot TOML or URDF path.
    plan
        A plan CSV (with its ``plan.json``) to replay through the C backend and firmware.
    samples
        Seeded samples per function in the callbacks stage.
    precision
        ``"double"`` or ``"float"`` only (default: both).
    target
        A core of :data:`VERIFY_TARGETS` (``"cortex-m4"``, ``"cortex-m7"``, ...) to also run
        the firmware on that emulated core (needs QEMU; docs/targets.md).
    report
        Also write the JSON report here.
    echo
        Called with each stage's table as it finishes (default: silent).
    generated
        The folder ``armgen.generate`` wrote (default: ``./generated/<robot>/``).
    run
        What a firmware run printed (CSV), compared with ``plan``.
    again
        Redo every build and stage, even those whose passed verdict on the same code, plan and
        options the kernel store holds (by default those are reused; docs/api.md#what-verify-reuses).

    Returns
    -------
    VerifyReport
        Check ``report.passed``; the command line exits with code 5 when it is false.
    """
    from .verification.pipeline import VerifyConfig, run_pipeline

    if run is not None and plan is None:
        raise OptionError("--run needs --plan: the plan the firmware ran (e.g. demo/plan.csv of `armgen firmware`)")
    if report is not None and Path(report).is_dir():
        raise OptionError(f"--report {report}: is a folder; give a file name, e.g. {Path(report) / 'verify.json'}")
    precisions = (precision,) if precision else ("double", "float")
    loaded = load_robot_any(robot)
    config = VerifyConfig(loaded, Path(plan) if plan else None, samples, precisions, target,
                          generated=Path(generated) if generated else None,
                          robot_ref=loaded.source if isinstance(robot, Robot) else str(robot),
                          run=Path(run) if run else None, reuse=not again)
    stages = run_pipeline(config, Path(report) if report else None, echo or (lambda _line: None))
    return VerifyReport(loaded.name, tuple(stages))



# -- plan files, figures, videos --------------------------------------------------------------------

def parse_override(item: str) -> tuple[str, Any]:
    """``key=value`` as given to ``--set`` → (dotted key, value parsed as TOML; a bare word is a
    string), for ``read_task(task, **{key: value})``. Raises :class:`TaskFileError` (exit 2)."""
    from .planning.tasks import parse_override as parse

    return parse(item)


def read_plan(csv_path: str | Path) -> Plan:
    """A plan CSV that ``armgen plan`` or :meth:`Plan.save` wrote, with its ``plan.json`` when it
    is there (:func:`plan_metadata_path`; else ``metadata`` is empty). Angles come back in rad.
    Raises :class:`PlanFileError` (exit 2) for a malformed CSV or ``plan.json``."""
    from .planning.result import read_plan as read

    return Plan(read(csv_path))


def plan_metadata_path(csv_path: str | Path) -> Path:
    """The ``plan.json`` beside a plan CSV (the CSV's name with ``.json``)."""
    from .planning.result import metadata_path

    return metadata_path(csv_path)


def figure_format(path: str | Path) -> str:
    """The figure format of an output name (``"png"``, ``"svg"``, ``"pdf"``), checked before any
    work. Raises :class:`ArmgenError`: no file name or another extension (exit 2), a folder (exit 4)."""
    from .planning.plotting import figure_format as check

    return check(path)


def save_plot(plan: Plan, out: str | Path, robot: Robot | str | Path | None = None,
              plan_file: str | Path | None = None) -> Path:
    """Write a plan's figure, as ``armgen plot`` does; returns the path written.

    Parameters
    ----------
    plan
        From :func:`plan`, or :func:`read_plan` with its ``plan.json``.
    out
        ``.png``, ``.svg`` or ``.pdf`` (checked first, written atomically).
    robot
        The arm drawn through its own kinematics (default: the one ``plan.json`` records); a
        PTP figure draws none.
    plan_file
        Where the plan was read from: the recorded robot is also looked for beside it, and
        errors name it (default: the plan's task file).
    """
    from .planning.plotting import plan_robot, save_figure
    from .planning.tasks import plot_plan

    figure_format(out)
    source = str(plan_file) if plan_file is not None else str(plan.metadata.get("task_file", "plan"))
    arm = plan_robot(plan.result, plan_file, robot) if plan.metadata.get("planner") != "ptp" else None
    return save_figure(plot_plan(plan.result, source, arm), out)


def parse_frame_size(text: str) -> tuple[int, int]:
    """A video frame size ``WIDTHxHEIGHT`` in pixels (``"960x720"``): even numbers from 160 to
    3840, else a :class:`TaskFileError` (exit 2)."""
    from .planning.animation import parse_size

    return parse_size(text)


def animate_plan(plan: Plan, out: str | Path, fps: float | None = None, duration: float | None = None,
            size: tuple[int, int] | None = None, robot: Robot | str | Path | None = None,
            plan_file: str | Path | None = None) -> Path:
    """Render the arm moving through a plan, as ``armgen animate`` does; returns the path written.

    Parameters
    ----------
    plan
        From :func:`plan` or :func:`read_plan`.
    out
        ``.gif`` (Pillow) or ``.mp4`` (needs ffmpeg), written atomically.
    fps, duration
        Frames per second (default 20) and seconds of video (default: the plan's, at most 10 s).
    size
        ``(width, height)`` in pixels (default 960×720; :func:`parse_frame_size` reads ``"WxH"``).
    robot, plan_file
        As in :func:`save_plot`; a plan without ``plan.json`` needs ``robot`` (its joint columns are drawn).
    """
    from .planning.animation import DEFAULT_FPS, DEFAULT_SIZE, animate_plan
    from .planning.plotting import plan_robot

    arm = plan_robot(plan.result, plan_file, robot)
    return animate_plan(plan.result, out, DEFAULT_FPS if fps is None else fps, duration, size or DEFAULT_SIZE, arm)


# -- sweeps, inverse kinematics -------------------------------------------------------------------

def sweep(task: str | Path, out: str | Path, grids: tuple[str, ...] = (), ranges: tuple[str, ...] = (),
          draws: int = 0, seed: int = 0, overrides: tuple[str, ...] = (), backend: str = "symbolic",
          workers: int | None = None, scheduler: str | None = None, resume: bool = False,
          echo: Callable[[str], None] | None = None) -> list[dict[str, Any]]:
    """Plan a task once per combination of grid values (and per random draw), as ``armgen sweep``.

    Parameters
    ----------
    task
        The task file.
    out
        The table to write, ``.csv`` or ``.parquet``: one row per run, failed runs included.
    grids, ranges, overrides
        Strings as ``--grid KEY=ARRAY``, ``--range KEY=LO:HI`` and ``--set key=value`` take them.
    draws, seed
        Random draws over the ranges (per grid combination), and their seed.
    backend
        ``"symbolic"`` or ``"c"``.
    workers, scheduler
        Local worker processes (default: the CPUs), or a Dask scheduler's address (trusted).
    resume
        Skip the runs already in ``out``.
    echo
        Called with progress lines (default: silent).

    Returns
    -------
    list of dict
        The table's rows by run (``status`` ``"ok"`` or why not, ``exit_code``, the summary).
    """
    import os

    from .planning.sweep import SweepSpec, parse_grid, parse_range, sweep as run_sweep
    from .planning.tasks import apply_overrides, load_task

    document, sha = load_task(task)
    apply_overrides(document, list(overrides))
    spec = SweepSpec([parse_grid(g) for g in grids], [parse_range(r) for r in ranges], draws, seed)
    spec.check()
    return run_sweep(document, str(task), sha, spec, out, backend, workers or os.cpu_count() or 1, scheduler, resume,
                     echo or (lambda _line: None))


@dataclass(frozen=True)
class IkSolution:
    """The outcome of :func:`solve_ik`: ``q`` (the solution, else the closest configuration
    reached); ``converged``, ``iterations``, ``position_error`` (m) and ``orientation_error``
    (rad) in the rows the arm controls; ``free_rows``, the task rows it does not control
    (``"vz"``, ``"wx"`` … of a planar arm), with the pose's largest error there
    (``free_position_error`` m, ``free_orientation_error`` rad, a rotation-vector component)
    and whether both are within the tolerances (``free_rows_match``). For a robot with capsules
    (or given obstacles): ``clearance`` (the least distance at ``q``, m), its ``pair``
    (``"capsule 2 – obstacles[0] (sphere)"``), the clearance asked for (``required_clearance``)
    and ``colliding`` (the pose was reached, but by no configuration found clear of collisions:
    ``converged`` is then False)."""

    q: Any
    converged: bool
    iterations: int
    position_error: float
    orientation_error: float
    free_rows: tuple[str, ...]
    free_position_error: float
    free_orientation_error: float
    free_rows_match: bool
    clearance: float | None = None
    pair: str = ""
    required_clearance: float = 0.0
    colliding: bool = False

    @property
    def solved(self) -> bool:
        """The whole pose is reached: the controlled rows converged and the others match."""
        return self.converged and self.free_rows_match


def solve_ik(robot: Robot | str | Path, pose: Any, q0: Any = None, seed: Any = None, max_iterations: int | None = None,
             orientation_given: bool = True, obstacles: str | Path | None = None) -> IkSolution:
    """Joint values that put the tool at ``pose``, as ``armgen ik`` does (``docs/ik.md``).

    Parameters
    ----------
    robot
        A :class:`Robot`, bundled name, robot TOML or URDF path.
    pose
        The tool pose in the base frame, a 4×4 homogeneous matrix (m).
    q0, seed
        A configuration to stay near, and the first attempt's start (:meth:`Robot.ik`).
    max_iterations
        Stop after this many steps (at most the solver's own cap, the default).
    orientation_given
        False: the pose's orientation is not required in the rows the arm does not control.
    obstacles
        An obstacle file: ``[units]``, ``[[obstacles]]`` and ``[collision]`` as in a task file
        (docs/ik.md, "Collision-free solutions"); the solution keeps ``[collision] clearance``
        from them and between the arm's capsules.

    Raises
    ------
    TaskFileError
        A bad obstacle file, or obstacles for a robot without capsules (exit 2).
    """
    import numpy as np

    from .planning.common.collision import ik_arguments, load_obstacle_file, nearest_pair
    from .planning.ptp.poses import uncontrolled_error
    from .symbolic.ik import MAX_ITERATIONS, TOL_ORIENTATION, TOL_POSITION

    arm, pose = load_robot_any(robot), np.asarray(pose, dtype=float)
    collision = None if obstacles is None else load_obstacle_file(obstacles, arm)
    arguments = ik_arguments(collision)
    result = arm.ik(pose, q0, seed=seed,
                    max_iterations=None if max_iterations is None else min(max_iterations, MAX_ITERATIONS), **arguments)
    free_rows, free_position, free_orientation = uncontrolled_error(arm, pose, result.q)
    match = free_position <= TOL_POSITION and (not orientation_given or free_orientation <= TOL_ORIENTATION)
    checked = {}
    if result.clearance is not None:
        least, pair = nearest_pair(arm, result.q, collision)
        checked = dict(clearance=least, pair=pair, required_clearance=arguments.get("clearance", 0.0),
                       colliding=bool(result.colliding))
    return IkSolution(result.q, bool(result.success), int(result.iterations), float(result.position_error),
                      float(result.orientation_error), tuple(free_rows), free_position, free_orientation, match,
                      **checked)


# -- firmware ---------------------------------------------------------------------------------------

def firmware_project(robot: str | Path, out: str | Path, task: str | Path | None = None,
                     plan: str | Path | None = None, overrides: tuple[str, ...] | list[str] = (),
                     feedforward: str | None = None, bound: tuple[str, ...] | list[str] = ()) -> tuple[Robot, list[Path]]:
    """Write a self-contained firmware project (``armgen firmware``): the robot's generated C,
    the controller, a CMake host demo, the Cortex-M4F toolchain file and a README.

    Parameters
    ----------
    robot
        A bundled name or a robot file (TOML or URDF); read once.
    out
        The project folder: new, empty, or one this function wrote earlier (its own files are
        updated, files changed by hand are never overwritten). It appears complete or not at all.
    task
        A task file for ``robot`` (read once, its robot checked before it is planned): planned
        here, and the demo runs it.
    plan
        A plan CSV with its plan.json (``armgen plan``): its recorded task is planned again and
        must give the CSV's samples; the demo runs it.
    overrides
        ``key=value`` changes of ``task`` (as ``--set``).
    feedforward
        ``"none"``, ``"gravity"`` or ``"inverse_dynamics"``: each command's feed-forward torque
        (``ctrl_output.tau_ff``, checked against ``taumax``: the ``TORQUE`` fault). Default: the
        inverse dynamics for a robot with inertials; a robot without has no feed-forward.
    bound
        Cores of ``armgen.firmware.TARGETS`` (names, or comma lists of them): the project is
        built for each with its cross toolchain, and the static worst-case bounds of each
        generated function in the image and of a running tick of the task's mode (instructions,
        and cycles where the core has a cycle model) go into the manifest (``"bounds"``) and a
        table of the README (docs/targets.md, "Static bound"). Default: none, no toolchain needed.

    Returns
    -------
    (Robot, list[pathlib.Path])
        The robot and the files written. Without ``task`` or ``plan`` the demo is a short line
        of the tool from the robot's ``q0``.

    Raises
    ------
    OptionError
        Both ``task`` and ``plan``, ``overrides`` without ``task``, or a ``feedforward`` other than
        ``"none"`` for a robot without inertials (exit 2).
    RobotFileError, TaskFileError, PlanFileError
        A bad robot, task or plan file (exit 2).
    PlanningError
        The task (or the demo) cannot be planned, or its plan leaves the joint limits (exit 3).
    OutputError
        ``out`` cannot be written (exit 4).
    ToolchainError
        A core of ``bound`` whose cross compiler or binutils are missing: the message names the
        packages to install; checked before anything is planned or written (exit 4).
    RobotMismatchError
        The task (or the task the plan records) names another robot, refused before it is
        planned (exit 5).
    ArmgenError
        ``armgen.firmware.FirmwareError`` (exit 5): the controller cannot run the plan, or a
        plan its recorded task does not plan to.
    """
    from .firmware.project import write_firmware_project

    if task is not None and plan is not None:
        raise OptionError("give --task or --plan, not both (a task is planned here; a plan was made from one)")
    if overrides and task is None:
        raise OptionError("--set changes a task file: give --task (a plan was made already; re-plan its task instead)")
    return write_firmware_project(robot, out, task, plan, tuple(overrides), feedforward, tuple(bound))


def firmware_task(source: str | Path, out: str | Path, robot: Robot | str | Path | None = None,
                  overrides: tuple[str, ...] | list[str] = (), gen_dir: str | Path | None = None,
                  lock: str | None = None, feedforward: str | None = None,
                  bound: tuple[str, ...] | list[str] = ()) -> list[Path]:
    """Write the controller's task files (``armgen firmware-task``, used by the firmware stub's
    Makefile): ``task_params.h``, the PTP evaluator ``fw_ptp.{h,c}`` and ``robot_fw.c``.

    Parameters
    ----------
    source
        A task file (planned when the controller needs the plan: programs, ptp, snake) or a plan
        CSV with its plan.json.
    out
        The folder to write into.
    robot
        The firmware's robot: the task must name it (default: the task's robot).
    overrides
        ``key=value`` changes of a task file (as ``--set``).
    gen_dir
        The robot's generated C (default ``generated/<robot>/``).
    lock
        ``JOINTS@TIME`` (e.g. ``"5@1.38"``): the runners report these joints locked from TIME s
        on, a fault the plan does not know.
    feedforward
        Each command's feed-forward torque, as :func:`firmware_project`'s.
    bound
        Cores, as :func:`firmware_project`'s: the task's build for each is bounded and the
        bounds (the list a project's manifest holds as ``"bounds"``) written to ``bounds.json``
        in ``out``; a missing cross toolchain is a ToolchainError (exit 4) before any file is
        written.

    Returns
    -------
    list[pathlib.Path]
        The files written.

    Raises
    ------
    TaskFileError, PlanFileError
        A bad task or plan file (exit 2).
    OptionError
        A ``feedforward`` other than ``"none"`` for a robot without inertials (exit 2).
    RobotMismatchError
        A task for another robot than ``robot`` (exit 5).
    OutputError
        ``out`` cannot be written (exit 4).
    ArmgenError
        ``armgen.firmware.FirmwareError`` (exit 5): a task the controller cannot run.
    """
    from .firmware.configuration import schedule_lock, with_feedforward
    from .firmware.project_bound import write_task_files_with_bounds
    from .firmware.tasks import task_from_file

    controller = task_from_file(source, load_robot_any(robot) if robot is not None else None, tuple(overrides))
    if lock:
        controller = schedule_lock(controller, lock)
    if feedforward is not None:
        controller = with_feedforward(controller, feedforward)
    return write_task_files_with_bounds(controller, out, gen_dir, tuple(bound))


# -- C of the PTP playback, input schemas, files --------------------------------------------------

def generate_ptp(out: str | Path | None = None, precision: str = "double", prefix: str = "armgen") -> tuple[Path, ...]:
    """Write the C evaluator of PTP segment polynomials (the firmware's playback), as ``armgen
    gen-ptp``: ``<prefix>_ptp.h`` and ``.c`` in ``out`` (default ``./generated/ptp/``), with the
    real type ``precision`` (``"double"`` or ``"float"``). Returns the paths written."""
    from .codegen.generate import GENERATED_DIR
    from .codegen.ptp_c import generate_ptp_evaluator

    return tuple(generate_ptp_evaluator(Path(out) if out else GENERATED_DIR / "ptp", prefix, precision))


def json_schema(kind: str, planner: str | None = None) -> dict[str, Any]:
    """The JSON Schema of the ``"robot"`` file (DH table or URDF reference) or of a ``"task"``
    file (one ``planner``'s, default any: told apart by its ``planner`` field), for editors."""
    from typing import Annotated, Union

    from pydantic import Field, TypeAdapter

    from .description.schema import RobotFile, UrdfRobotFile
    from .planning.registry import PLANNER_NAMES, planner as planner_named

    if kind == "robot":
        schema = TypeAdapter(Union[RobotFile, UrdfRobotFile]).json_schema()
        schema["title"] = "armgen robot file (DH table, or a URDF reference)"
        return schema
    models = {name: planner_named(name).schema for name in PLANNER_NAMES}
    if planner is not None:
        return models[planner].model_json_schema()
    union = Annotated[Union[tuple(models.values())], Field(discriminator="planner")]
    schema = TypeAdapter(union).json_schema()
    schema["title"] = "armgen task file"
    return schema


def write_text_atomic(path: str | Path, text: str) -> None:
    """Write a text file that appears complete or not at all; an :class:`OutputError` (exit 4)
    when it cannot be written (a folder in the way, no permission, a full disk)."""
    from .fileio import write_text_atomic as write

    write(path, text)


# -- the host link (issue 40, docs/link.md) ----------------------------------------------------


def link_open(port: str, timeout: float = 2.0, telemetry_period: int = 0, replies: str = "TELEMETRY") -> Any:
    """A session with a board on ``port`` (a serial device, a pseudo-terminal, ``socket://host:port``):
    an :class:`armgen.link.LinkClient` after the version handshake. ``replies="ACK"``: the board
    answers command frames with a 16-byte ACK instead of the full TELEMETRY. Raises ``LinkError``
    (exit 4) when the port cannot be opened or nothing answers in this protocol version."""
    from .link import LinkClient

    return LinkClient(port, timeout=timeout, telemetry_period=telemetry_period, replies=replies)


def link_status(port: str, timeout: float = 2.0) -> Any:
    """The board's telemetry (:class:`armgen.link.Telemetry`): state, fault, joints, tool pose, counters."""
    with link_open(port, timeout) as link:
        return link.status()


def link_move_to(port: str, joints: Any = None, pose: Any = None, wait: bool = True, timeout: float = 2.0) -> Any:
    """Move the arm to a joint target (``joints``, rad / m) or a tool pose (``pose``, 4x4, m):
    the board plans the move within its limits (a pose through its IK). ``wait``: until the arm
    stops, sending the watchdog's heartbeat meanwhile. Returns the last telemetry; a refusal is
    ``CommandRefused`` (exit 3) naming the reason."""
    from .link import LinkError

    if (joints is None) == (pose is None):
        raise LinkError("give a joint target or a tool pose (one of them)")
    with link_open(port, timeout) as link:
        reply = link.move_to_joints(joints) if joints is not None else link.move_to_pose(pose)
        return link.wait_idle() if wait else reply


@dataclass(frozen=True)
class LinkStreamReport:
    """A streamed plan: waypoints sent, the telemetry at the end, and the largest difference
    between a reply's joint command and the plan at the reply's tick (rad / m; for a pose stream
    the tool position's, m; NaN with ACK replies, which carry no joints)."""

    waypoints: int
    end: Any
    max_deviation: float
    poses: bool = False


def link_stream(port: str, plan_csv: str | Path, rate_hz: float = 50.0, lead_s: float = 0.1,
                timeout: float = 2.0, poses: bool = False, replies: str = "TELEMETRY") -> LinkStreamReport:
    """Stream a plan's joint samples as timed waypoints at ``rate_hz`` (the board interpolates
    them at its tick within its limits), in real time, each ``lead_s`` ahead; waits until the arm
    is at rest. The plan must start where the arm is (its held command). ``poses`` (or a file
    without the board's joint columns, a pose file: ``t_s x_m y_m z_m roll_rad pitch_rad
    yaw_rad``): stream the tool poses instead, interpolated in task space on the board and
    followed by its resolved-rate step. ``replies="ACK"``: light replies (no deviation measured)."""
    import numpy as np

    from .link import plan_pose_waypoints, plan_waypoints
    from .link.waypoints import POSE_COLUMNS, StreamFileError, has_joints

    plan_read = read_plan(plan_csv)
    columns, data = list(plan_read.columns), plan_read.data
    with link_open(port, timeout, replies=replies) as link:
        poses = poses or not has_joints(columns, link.ndof)
        try:
            if poses:
                t, tool, twists = plan_pose_waypoints(columns, data, rate_hz)
            else:
                t, q, qd = plan_waypoints(columns, data, link.ndof, rate_hz)
        except StreamFileError as exc:
            raise StreamFileError(f"{plan_csv}: {exc}") from None
        if poses:
            answers = link.stream_poses(t, tool, twists, lead_s=lead_s)
        else:
            answers = link.stream(t, q, qd, lead_s=lead_s)
        end = link.wait_idle()
    dt = link.hello["dt_us"] * 1e-6
    t_plan = data[:, columns.index("t_s")] - data[0, columns.index("t_s")]
    names = list(POSE_COLUMNS[:3]) if poses else _joint_names(columns, link.ndof)
    want_plan = data[:, [columns.index(c) for c in names]]
    deviation = 0.0 if replies == "TELEMETRY" else float("nan")
    for reply in answers:
        if reply.state_name == "RUNNING" and "q" in reply.values:
            at = reply["motion_tick"] * dt
            want = np.array([np.interp(at, t_plan, want_plan[:, i]) for i in range(len(names))])
            got = np.array(reply["tool"][:3]) if poses else reply.q
            deviation = max(deviation, float(np.abs(got - want).max()))
    return LinkStreamReport(len(t), end, deviation, poses)


def _joint_names(columns: list[str], ndof: int) -> list[str]:
    from .link.waypoints import joint_columns

    return [columns[i] for i in joint_columns(columns, ndof)[0]]


def link_servo(port: str, twists: Any, period_s: float = 0.02, timeout: float = 2.0, criterion: str = "TASK",
               gain: float = 0.0) -> Any:
    """Servo the tool: one twist ``[vx vy vz wx wy wz]`` (base frame, m/s, rad/s) every
    ``period_s``, each followed by the board within its limits (scaled down, never beyond them)
    until the next; then a zero twist until the arm rests, and STOP. ``criterion``, ``gain``: the
    self-motion (:data:`armgen.link.protocol.CRITERIA`; TASK: the compiled-in task's). Returns
    the last telemetry."""
    with link_open(port, timeout) as link:
        link.servo_setup(criterion, gain)
        link.servo(twists, period_s)
        return link.status()


def read_twists(csv_path: str | Path) -> Any:
    """A twist trace: a CSV with the columns ``vx_m_s vy_m_s vz_m_s wx_rad_s wy_rad_s wz_rad_s``
    (any others ignored), one row per period. Raises ``PlanFileError`` (exit 2) naming what is missing."""
    import numpy as np
    import pandas as pd

    names = ("vx_m_s", "vy_m_s", "vz_m_s", "wx_rad_s", "wy_rad_s", "wz_rad_s")
    try:
        table = pd.read_csv(csv_path)
    except (OSError, ValueError) as exc:
        raise PlanFileError(f"{csv_path}: cannot read a twist trace: {excerpt(str(exc))}") from None
    missing = [n for n in names if n not in table.columns]
    if missing:
        raise PlanFileError(f"{csv_path}: no column {missing[0]}; a twist trace has the columns {' '.join(names)}")
    twists = table[list(names)].to_numpy(dtype=float)
    if not np.all(np.isfinite(twists)):
        raise PlanFileError(f"{csv_path}: a twist holds NaN or inf; give finite numbers")
    return twists


def link_watch(port: str, period_s: float = 0.1, count: int | None = None, timeout: float = 2.0) -> Any:
    """Telemetry every ``period_s`` (``count`` of them, or until interrupted); its STATUS requests
    are the watchdog's heartbeat."""
    with link_open(port, timeout) as link:
        for k, reply in enumerate(link.watch(period_s)):
            yield reply
            if count is not None and k + 1 >= count:
                return
