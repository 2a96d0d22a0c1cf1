"""The Python API: load a robot, plan a task, generate C, verify it.

Everything here is re-exported from the :mod:`armgen` namespace (``armgen.plan`` …) and is
what the command line does, minus the printing::

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

from .errors import OptionError, excerpt
from .robot import Robot, load_robot, load_robot_any

if TYPE_CHECKING:  # heavy imports only for type checkers
    import pandas
    from matplotlib.figure import Figure

    from .planning.result import PlanResult
    from .planning.tasks import Task

__all__ = ["Robot", "load_robot", "read_task", "plan", "Plan", "generate", "Generated", "verify", "VerifyReport"]


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


def read_task(task: str | Path | dict[str, Any] | Task, robot: Robot | None = None, **overrides: Any) -> Task:
    """Read a task once: the file (or dict) with its overrides, validated by its planner's
    schema, its robot loaded, and the planner's typed SI configuration made.

    Parameters
    ----------
    task
        A task file path, the task as a dict (the parsed TOML), or a task read already
        (returned as it is; overrides are not allowed then).
    robot
        The robot the task must name (e.g. a firmware's): checked before anything is planned,
        and used instead of loading the task's robot file again.
    **overrides
        Task fields to replace, with dotted keys for tables: ``**{"timing.duration": 4.0}``,
        or ``timing__duration=4.0`` (``__`` stands for the dot). Values are Python values.

    Returns
    -------
    Task
        ``planner`` (the registry entry), ``model`` (the validated file, its units),
        ``config`` (SI), ``document`` (the TOML as read, overrides applied), ``source``, ``sha256``.

    Raises
    ------
    TaskFileError, RobotFileError
        The task or its robot file is malformed, or the task names another robot (exit code 2).
    """
    from .planning.tasks import Task, configure_task, load_task, set_field

    if isinstance(task, Task):
        if overrides:
            raise OptionError("overrides change a task file: give the file or its dict, not a task read already")
        return task
    if isinstance(task, dict):
        document, sha, source = copy.deepcopy(task), "", "<task dict>"
    else:
        document, sha = load_task(task)
        source = str(task)
    for key, value in overrides.items():
        set_field(document, key.replace("__", "."), value, f"override {excerpt(repr(key))}")
    return configure_task(document, source, sha, robot)


def plan(task: str | Path | dict[str, Any] | Task, backend: str = "symbolic", *, max_steps: int | None = None,
         max_samples: int | None = None, **overrides: Any) -> Plan:
    """Plan a task, as ``armgen plan`` does (without writing files).

    Parameters
    ----------
    task
        A task file path, the task as a dict (the parsed TOML), or a task from :func:`read_task`.
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

    configured = read_task(task, **overrides)
    caps = ResourceCaps()
    caps = ResourceCaps(max_steps or caps.max_steps, max_samples or caps.max_samples)
    return Plan(plan_configured(configured, backend, caps))


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
                "stages": [{"name": s.name, "passed": s.passed, "message": s.message, "columns": s.columns,
                            "rows": s.rows} for s in self.stages]}


def verify(robot: Robot | str | Path, plan: str | Path | None = None, samples: int = 10_000,
           precision: str | None = None, target: str | None = None, report: str | Path | None = None,
           echo: Callable[[str], None] | None = None, generated: str | Path | None = None,
           run: str | Path | None = None) -> VerifyReport:
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
        ``"cortex-m4"`` to also run on the emulated target (needs QEMU).
    report
        Also write the JSON report here.
    echo
        Called with each stage's table as it finishes (default: silent).
    generated
        The folder ``armgen.generate`` wrote (default: ``./generated/<robot>/``).
    run
        What a firmware run printed (CSV), compared with ``plan``.

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
                          run=Path(run) if run else None)
    stages = run_pipeline(config, Path(report) if report else None, echo or (lambda _line: None))
    return VerifyReport(loaded.name, tuple(stages))
