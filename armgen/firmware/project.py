"""``armgen firmware ROBOT --out DIR [--task TASK.toml | --plan plan.csv]``: a self-contained C
project for any robot, running the user's task or a demo.

The folder holds the robot (:func:`project_robot_files`), its generated kinematics (as ``armgen
gen`` writes them), the controller sources of the firmware stub, a compiled-in demo task with
armgen's plan of it (a ``--plan`` is planned again from its task and must match; only plans
within the joint limits are shipped), a ``CMakeLists.txt`` that builds the host demo out of
the box and, with the toolchain file it ships, the Cortex-M4F image, and a README. The folder appears complete or not at all: it is
assembled in a hidden staging folder beside ``DIR`` and renamed into place. Nothing outside
``DIR`` is written or deleted: a symbolic link on the way to any file the project owns is
refused (:func:`_check_no_links`).

The task the project's demo runs (:class:`ProjectTask`): the user's task file (planned here) or
plan, when given; else the built-in demo task (:func:`demo_task`): a straight line of the tool, orientation held, from the
robot's named configuration ``q0`` (else its first named configuration, else mid-range of
the limits), 5 cm in 1 s (cubic time law, pseudo-inverse, Euler at 10 ms). When that line
leaves the limits or the workspace, the next candidate direction (±x, ±y, ±z), then 2 cm,
is tried: the first one the planner completes is used.
"""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import json
import os
import shutil
import tempfile
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, Sequence

import numpy as np
import tomli_w

from .._version import __version__
from ..codegen.generate import CodegenConfig, generate
from ..errors import ArmgenError, OutputError, PlanningError, RobotFileError, TaskFileError, excerpt
from ..planning.limits import enforce_limits, enforce_speed_limits
from ..planning.result import PlanResult, read_plan, write_plan
from ..planning.tasks import apply_overrides, load_task, run_task
from ..planning.toolpath.task import MAX_POSES_FILE_BYTES
from ..robot import BUNDLED_DIR, Robot, load_robot, parse_robot, resolve_robot_path
from ..schemas import MAX_INPUT_FILE_BYTES, parse_toml_bounded, read_input_file
from .configuration import FirmwareTask, check_feedforward, with_feedforward, write_task_files
from .tasks import REPLANNED_SAMPLE_TOL, refusal, task_from_plan, task_source
from .errors import FirmwareError
from .project_bound import bound_targets, project_bounds, readme_table, require_bound_tools
from .targets import TARGETS

DEMO_DURATION_S = 1.0
DEMO_STEP_S = 0.01  # the controller's tick: 100 ticks, a short demo and a small CSV
DEMO_DISTANCES_M = (0.05, 0.02)
DEMO_DIRECTIONS = ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))
# A plan given with --plan is planned again from its task; each sample must come back to
# REPLANNED_SAMPLE_TOL (configuration.py: the CSV holds the doubles exactly) plus this
# fraction of its size: columns far from 1 (condition numbers ~1e6) round differently by
# ~1e-15 relative on another machine's BLAS, while an edited sample differs by far more.
REPLANNED_SAMPLE_RTOL = 1e-9
PROJECT_ROBOT_FILE = "robot.toml"  # the project's robot file (DH, or a URDF's wrapper); tasks name it so
PROJECT_URDF_FILE = "robot.urdf"  # the project's copy of a URDF: the robot file itself, or the one its wrapper names
# The first line of the project's copy of a URDF's wrapper (the same every time, so that
# regenerating the project from its own robot.toml gives the same bytes).
WRAPPER_COMMENT = "# The robot file of this project, written by `armgen firmware`: urdf names the project's copy."
MANIFEST = ".armgen-firmware"  # the files this command wrote there, with their SHA-256 (JSON)

# The stub's files the project needs, by their place in the project.
STUB_FILES = {
    "controller": ("controller.c", "controller.h", "ctrl_robot.h", "fw_program.c", "fw_program.h", "fw_csv.c", "fw_csv.h",
                   "fw_task.c", "fw_task.h", "fw_link.c", "fw_link.h", "fw_link_msgs.c", "fw_link_msgs.h"),
    "host": ("host/main.c", "host/link_main.c"),
    "arm": ("arm/fw_main.c", "arm/startup.c", "arm/semihost.c", "arm/semihost.h", "arm/fw_fastmath.c",
            "arm/mps2_an386.ld", "arm/mps2_an505.ld", "arm/fw_link_uart.c"),
    "riscv": ("riscv/startup.c", "riscv/virt.ld"),
}


def demo_start(robot: Robot) -> tuple[str | None, np.ndarray]:
    """(name, q) of the demo's start: q0, else the first named configuration, else mid-range."""
    names = sorted(robot.configurations)
    name = "q0" if "q0" in robot.configurations else (names[0] if names else None)
    return name, (robot.configuration(name) if name else 0.5 * (robot.qmin + robot.qmax))


def demo_task(robot: Robot, robot_ref: str, distance: float = DEMO_DISTANCES_M[0],
              direction: tuple[float, float, float] = DEMO_DIRECTIONS[0]) -> dict[str, Any]:
    """A short line of the tool from the demo start, as a cartesian task dict (SI units)."""
    name, q = demo_start(robot)
    pose = np.array(robot.symbolic.function("fk")(q))  # the robot's model, built once for every candidate
    end = pose[:3, 3] + distance * np.asarray(direction, dtype=float)
    return {"planner": "cartesian", "robot": robot_ref, "start": name if name else q.tolist(),
            "path": {"type": "line", "end": end.tolist(), "orientation": "hold"},
            "timing": {"duration": DEMO_DURATION_S, "law": "cubic"},
            "integrator": {"method": "euler", "step": DEMO_STEP_S}, "method": {"name": "pinv"}}


def plan_demo(robot: Robot, robot_ref: str, source: str = "demo task"):
    """The first candidate line the planner completes and the controller can run:
    (task dict, plan result, description)."""
    reasons = []
    for distance in DEMO_DISTANCES_M:
        for direction in DEMO_DIRECTIONS:
            task = demo_task(robot, robot_ref, distance, direction)
            try:
                result = run_task(task, source, robot=robot)
            except ArmgenError as exc:
                reasons.append(str(exc).splitlines()[0])
                continue
            if refusal(result) is None:
                axis = "xyz"[int(np.flatnonzero(direction)[0])]
                sign = "+" if sum(direction) > 0 else "-"
                start = task["start"] if isinstance(task["start"], str) else "mid-range of the limits"
                return task, result, (f"a {distance * 100:g} cm line along {sign}{axis} in {DEMO_DURATION_S:g} s "
                                      f"from configuration {start}, orientation held")
    fix = ("add a named configuration q0 away from the limits and singular poses to the robot file" if not robot.urdf
           else "a URDF holds no named configuration: write a robot file that references it (urdf = "
                f"\"{Path(robot.urdf['file']).name}\") with [configurations] q0 = [...] away from the limits and "
                "singular poses, and give that file (or give --task with a start of your own)")
    raise PlanningError(f"robot '{robot.name}': no demo line (±x, ±y, ±z; 5 or 2 cm) can be planned from its "
                        f"start configuration ({demo_start(robot)[0] or 'mid-range of the limits'}); "
                        f"{fix} (last reason: {reasons[-1] if reasons else '?'})")


@dataclass
class ProjectTask:
    """The task the project's demo runs: the task dict (None for a plan without one), its plan,
    the controller's configuration of it, and a description for the README."""

    task: dict[str, Any] | None
    result: PlanResult
    firmware: FirmwareTask
    description: str
    source: str
    folder: Path | None = None  # the folder the task's own files (a program's poses) are relative to


def _within_limits(result: PlanResult, source: str) -> None:
    """Refuse a plan that leaves a joint's position, speed or acceleration limits, whatever its
    task's ``[check] limits`` says: "report" writes such a plan to inspect it, never to run it."""
    summary = result.metadata.get("summary") or {}
    try:
        enforce_limits(summary.get("limit_violations") or [], "enforce", source)
        enforce_speed_limits(summary.get("joint_speed"), "enforce", source, str(result.metadata.get("planner", "")))
    except PlanningError as exc:
        raise PlanningError(f"{exc}. The firmware runs only plans within the joint limits, whatever [check] limits "
                            "says (\"report\" writes a plan to inspect it, never to run it)") from None


def _runnable(result: PlanResult, source: str, robot: Robot) -> FirmwareTask:
    """The controller's task of a plan for ``robot`` (its task checked to name it when it was
    configured) that the controller reproduces and that stays within the joint limits; else the
    error that says why not."""
    reason = refusal(result)
    if reason is not None:
        raise FirmwareError(f"{source}: the controller cannot reproduce this plan: {reason}")
    firmware = task_from_plan(result, source, robot)
    _within_limits(result, source)
    return firmware


def demo_project_task(robot: Robot, robot_ref: str) -> ProjectTask:
    planned, result, description = plan_demo(robot, robot_ref, "demo/demo.toml")
    return ProjectTask(planned, result, _runnable(result, "demo/demo.toml", robot), description, "demo task")


def task_file_project_task(robot: Robot, task_path: str | Path, overrides: Sequence[str] = ()) -> ProjectTask:
    """The user's task file (``overrides`` as ``--set``), planned here (``armgen plan``'s planner
    and checks) after checking that it names ``robot``."""
    task, sha = load_task(task_path)
    apply_overrides(task, list(overrides))
    source = str(task_path)
    result = run_task(task, source, sha, robot=robot)
    return ProjectTask(task, result, _runnable(result, source, robot),
                       f"the task of {Path(task_path).name} (planner {task.get('planner')})", source,
                       Path(task_path).parent)


def _differing_sample(recorded: PlanResult, replanned: PlanResult) -> str | None:
    """Where the recorded plan differs from its task planned again (None: nowhere beyond
    :data:`REPLANNED_SAMPLE_TOL` + :data:`REPLANNED_SAMPLE_RTOL` · |sample|)."""
    if replanned.columns != recorded.columns or replanned.data.shape != recorded.data.shape:
        return (f"{replanned.data.shape[0]} samples of {len(replanned.columns)} columns, the CSV has "
                f"{recorded.data.shape[0]} of {len(recorded.columns)}")
    close = np.isclose(recorded.data, replanned.data, rtol=REPLANNED_SAMPLE_RTOL, atol=REPLANNED_SAMPLE_TOL)
    if close.all():
        return None
    row, col = (int(k) for k in np.argwhere(~close)[0])
    return (f"line {row + 2}, column '{recorded.columns[col]}': {recorded.data[row, col]!r} in the CSV, "
            f"{replanned.data[row, col]!r} planned")


def plan_project_task(robot: Robot, plan_path: str | Path) -> ProjectTask:
    """A plan made already by ``armgen plan`` (its CSV and plan.json). Its recorded task is
    planned again and must give the CSV's samples (a hand-edited CSV, or a plan.json whose task
    was changed, is refused); the project uses that new plan, never the file's metadata."""
    source = str(plan_path)
    recorded = read_plan(plan_path)
    task = recorded.metadata.get("task")
    if not isinstance(task, dict) or not task:
        raise FirmwareError(f"{source}: its plan.json holds no task, and the firmware runs only a plan it can "
                            "reproduce from its task; keep the plan.json `armgen plan` wrote beside the CSV, or give "
                            "the task file (--task)")
    result = run_task(task, task_source(recorded, source), str(recorded.metadata.get("task_sha256") or ""),
                      robot=robot)
    differs = _differing_sample(recorded, result)
    if differs is not None:
        raise FirmwareError(f"{source}: planning the task recorded in its plan.json again does not give this plan "
                            f"({differs}): the CSV or plan.json was edited, or made by another armgen, robot file or "
                            "poses file; plan the task again with `armgen plan` and give that plan, or give the task "
                            "file (--task)")
    return ProjectTask(task, result, _runnable(result, source, robot),
                       f"the plan {Path(plan_path).name} (planner {result.metadata.get('planner')})", source,
                       Path(task_source(recorded, source)).parent)


def _parse_robot(path: Path, data: bytes) -> Robot:
    """The robot of the file ``path`` whose bytes are ``data`` (read once for the robot and the
    project's copy), as :func:`load_robot` gives it (named, and with its ``path``: a task that
    names the same file is checked without reading it again). A URDF is read by its own parser."""
    if path.suffix.lower() == ".urdf":
        return load_robot(path)
    source = path.name if path.parent == BUNDLED_DIR else str(path)  # load_description's naming
    robot = parse_robot(data, source, hashlib.sha256(data).hexdigest(), path.parent)
    return dataclasses.replace(robot, path=str(path.resolve()))


def project_robot_files(robot_path: Path, data: bytes, robot: Robot) -> tuple[str, dict[str, bytes]]:
    """The project's copy of the robot: (the file tasks and the README name, {file: bytes}).

    A DH robot file is ``robot.toml`` and a URDF ``robot.urdf``, byte for byte (the same
    SHA-256, so the robot is the same one for every check). A robot file that references a URDF
    becomes ``robot.toml`` with ``urdf = "robot.urdf"`` beside the URDF's copy: every other
    field as the user wrote it (comments are not kept), since its own reference may point
    anywhere (``../urdf/arm.urdf``, a ROS package) and the project must stand alone. ``data``:
    the robot file's bytes."""
    if not robot.urdf:
        return PROJECT_ROBOT_FILE, {PROJECT_ROBOT_FILE: data}
    if robot_path.suffix.lower() == ".urdf":  # the URDF itself (as load_robot tells them apart)
        return PROJECT_URDF_FILE, {PROJECT_URDF_FILE: data}
    urdf_path = Path(robot.urdf["file"])
    urdf = read_input_file(urdf_path, MAX_INPUT_FILE_BYTES, "URDF file", RobotFileError)
    doc = dict(parse_toml_bounded(data, str(robot_path), RobotFileError), urdf=PROJECT_URDF_FILE)
    text = f"{WRAPPER_COMMENT}\n{tomli_w.dumps(doc)}"
    return PROJECT_ROBOT_FILE, {PROJECT_ROBOT_FILE: text.encode("utf-8"), PROJECT_URDF_FILE: urdf}


def _project_robot(stage: Path, robot_file: str) -> Robot:
    """The robot as the project's own copy describes it, named by its place in the project."""
    return dataclasses.replace(load_robot(stage / robot_file), source=robot_file)


def _relocate_robot(metadata: dict[str, Any], robot: Robot) -> None:
    """The plan's record of its robot names the project's copy (the plan was made from the
    user's file: the same robot, which a URDF wrapper's copy gives another SHA-256)."""
    recorded = metadata.get("robot")
    if isinstance(recorded, dict):
        metadata["robot"] = dict(recorded, file=robot.source, sha256=robot.sha256)


def task_toml(task: dict[str, Any], comment: str) -> str:
    """A task dict (as a task file parses) as TOML text, under a comment saying where it came from."""
    header = f"# {comment}\n# Written by `armgen firmware`; plan it with `armgen plan demo/demo.toml` in the project.\n"
    return header + tomli_w.dumps(task)


def _fill(template: str, values: dict[str, str]) -> str:
    for key, value in values.items():
        template = template.replace(f"@{key}@", value)
    return template


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _owned_files(out: Path) -> dict[str, str]:
    """The files (relative path → SHA-256) the manifest of an earlier project lists; {} for a
    new or empty folder. A folder without a readable manifest is refused, and so is a project
    with a symbolic link on the way to the manifest or to a file it lists."""
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out}: is a file; give a folder for the firmware project (nothing was written)")
    if not out.is_dir() or not any(out.iterdir()):
        return {}
    _check_no_links(out, [MANIFEST])
    try:
        manifest = json.loads((out / MANIFEST).read_text(encoding="utf-8"))
        files = manifest["files"]
        if not isinstance(files, dict) or not all(isinstance(v, str) for v in files.values()):
            raise ValueError
    except (OSError, ValueError, KeyError, TypeError):
        raise OutputError(f"--out {out}: the folder exists and was not written by `armgen firmware` (no readable "
                          f"{MANIFEST} manifest); give a new or empty folder (nothing was written)") from None
    for name in files:
        if not name or Path(name).is_absolute() or ".." in Path(name).parts:
            raise OutputError(f"--out {out}: {MANIFEST} lists {excerpt(name)!r}, not a file of the project; "
                              "give a new or empty folder (nothing was written)")
    _check_no_links(out, files)
    return files


def _link_on_the_way(out: Path, name: str) -> Path | None:
    """The first symbolic link among the folders and the file of ``out / name`` (``out`` itself
    is the user's choice), or None: the path then resolves to itself inside ``out``."""
    path = out
    for part in Path(name).parts:
        path = path / part
        if path.is_symlink():
            return path
    return None


def _check_no_links(out: Path, names) -> None:
    """Refuse to write or delete ``out / name`` for any of ``names`` through a symbolic link: a
    linked folder or file of the project would make this command touch what the link points to,
    outside --out."""
    for name in names:
        link = _link_on_the_way(out, name)
        if link is not None:
            what = "file" if link == out / name else "folder"
            raise OutputError(f"--out {out}: {link} is a symbolic link (to {excerpt(os.readlink(link))}), and "
                              f"`armgen firmware` writes and deletes the project's files ({excerpt(name)}) only inside "
                              f"--out, never through a link; replace {link} by a real {what} of the project (or "
                              "remove it) and run again (nothing was written)")


def _conflicts(out: Path, owned: dict[str, str], new: list[str]) -> list[str]:
    """The user's files the update would overwrite or remove: owned files edited since they
    were written, and files it would write that it does not own."""
    edited = [name for name, sha in owned.items() if (out / name).is_file() and _digest(out / name) != sha]
    foreign = [name for name in new if name not in owned and (out / name).exists()]
    return sorted(edited + foreign)


def _check_writable(out: Path) -> None:
    parent = out.resolve().parent
    if not os.access(parent if parent.exists() else Path.cwd(), os.W_OK):
        raise OutputError(f"--out {out}: cannot write in {parent}; choose a writable folder (nothing was written)")


def _apply_umask(root: Path) -> None:
    """Staged files get the permissions the umask gives (0644/0755 under 022)."""
    mask = os.umask(0)
    os.umask(mask)
    for folder, dirs, files in os.walk(root):
        os.chmod(folder, 0o777 & ~mask)
        for name in files:
            os.chmod(os.path.join(folder, name), 0o666 & ~mask)


def _copy_poses_files(task: dict[str, Any], folder: Path | None, demo: Path) -> dict[str, Any]:
    """The task with each program ``poses`` file copied beside the project's demo.toml (as
    ``poses_<move>.csv``: the project plans in place; the user's file name never becomes a
    path of the project) and the move naming that copy."""
    path = task.get("path")
    if not (isinstance(path, dict) and isinstance(path.get("moves"), list)):
        return task
    moves = []
    for k, move in enumerate(path["moves"]):  # k as in path.moves[k] of the planners' messages
        if isinstance(move, dict) and isinstance(move.get("file"), str):
            source = Path(move["file"]) if folder is None else folder / move["file"]
            name = f"poses_{k}.csv"
            (demo / name).write_bytes(read_input_file(source, MAX_POSES_FILE_BYTES, "poses file", TaskFileError))
            move = dict(move, file=name)
        moves.append(move)
    return dict(task, path=dict(path, moves=moves))


def _assemble(stage: Path, robot_file: str, robot_files: dict[str, bytes], job: ProjectTask) -> None:
    stub = resources.files("armgen.data") / "firmware_stub"
    for name, data in robot_files.items():
        (stage / name).write_bytes(data)
    robot = _project_robot(stage, robot_file)
    code = generate(CodegenConfig(robot))
    (stage / "generated").mkdir()
    for name, text in code.files.items():
        (stage / "generated" / name).write_text(text, encoding="utf-8")
    for folder, names in STUB_FILES.items():
        (stage / folder).mkdir(exist_ok=True)
        for name in names:
            (stage / folder / Path(name).name).write_bytes((stub / name).read_bytes())
    write_task_files(job.firmware, stage / "task", stage / "generated")
    (stage / "demo").mkdir()
    result = job.result
    if job.task is not None:
        # The project names its own copy of the robot file, so it plans and verifies in place:
        # demo.toml relative to itself (as every task file), the plan's task from the project.
        task = _copy_poses_files(dict(job.task, robot=robot_file), job.folder, stage / "demo")
        toml_text = task_toml(dict(task, robot=f"../{robot_file}"),
                              f"The task of robot '{robot.name}' the demo runs: {job.description}.")
        (stage / "demo" / "demo.toml").write_text(toml_text, encoding="utf-8")
        result.metadata["task"] = task
        result.metadata["task_sha256"] = hashlib.sha256(toml_text.encode()).hexdigest()
        result.metadata["task_file"] = "demo/demo.toml"
    _relocate_robot(result.metadata, robot)
    write_plan(result, stage / "demo" / "plan.csv")
    values = {"ROBOT": robot.name, "ROBOT_FILE": robot_file, "ROBOT_FILES": _robot_rows(robot_files),
              "NDOF": str(robot.n), "PREFIX": code.prefix, "PREFIX_UC": code.prefix.upper(),
              "MAX_SEGMENTS": str(job.firmware.max_segments), "VERSION": __version__, "SHA256": robot.sha256,
              "DEMO": job.description, "HAS_DYNAMICS": "1" if robot.has_dynamics else "0",
              "HAS_COLLISION": "1" if robot.has_collision else "0",
              "FEEDFORWARD": _feedforward_note(job.firmware)}
    project = stub / "project"
    (stage / "CMakeLists.txt").write_text(_fill((project / "CMakeLists.txt.in").read_text(encoding="utf-8"), values),
                                          encoding="utf-8")
    (stage / "README.md").write_text(_fill((project / "README.md.in").read_text(encoding="utf-8"), values),
                                     encoding="utf-8")
    (stage / "cmake").mkdir()
    for toolchain in sorted((project / "cmake").glob("*.cmake")):  # one per core of targets.TARGETS
        (stage / "cmake" / toolchain.name).write_bytes(toolchain.read_bytes())


def _feedforward_note(firmware: FirmwareTask) -> str:
    """The README's sentence on the feed-forward torque (a robot with inertials), else nothing."""
    if not firmware.robot.has_dynamics:
        return ""
    what = {"none": "zeros (the task was written with `--feedforward none`)",
            "gravity": "the gravity torques of each command (`--feedforward gravity`)",
            "inverse_dynamics": "the inverse dynamics of each command, gravity included"}[firmware.feedforward]
    return (f" The robot has inertials: `out.tau_ff` holds {what}, N·m, for a current or torque loop "
            "(`send_joint_torques(out.tau_ff)`), and a command that would need more than a joint's `taumax` "
            "is the `TORQUE` fault (docs/firmware.md, \"Feed-forward torque\"; choose with `armgen firmware "
            "--feedforward none|gravity|inverse_dynamics`).")


def _robot_rows(robot_files: dict[str, bytes]) -> str:
    """The README's rows for the project's robot files."""
    if PROJECT_URDF_FILE not in robot_files:
        return f"| `{PROJECT_ROBOT_FILE}` | the robot file the code was generated from (byte for byte) |"
    if PROJECT_ROBOT_FILE not in robot_files:
        return f"| `{PROJECT_URDF_FILE}` | the URDF the code was generated from (byte for byte) |"
    return (f"| `{PROJECT_ROBOT_FILE}` | the robot file the code was generated from, its `urdf` naming "
            f"`{PROJECT_URDF_FILE}` |\n| `{PROJECT_URDF_FILE}` | the URDF it references (byte for byte) |")


def write_firmware_project(robot_ref: str | Path, out: str | Path, task: str | Path | None = None,
                           plan: str | Path | None = None, overrides: Sequence[str] = (),
                           feedforward: str | None = None, bound: Sequence[str] = ()) -> tuple[Robot, list[Path]]:
    """Write the project into ``out`` (new, empty, or a project this command wrote earlier:
    its own files are updated, the user's left alone), its demo running ``task`` (a task file,
    planned here, with ``overrides`` as ``--set``) or ``plan`` (a plan CSV), else the built-in
    demo task. Returns the robot and the files written. Give at most one of ``task`` and
    ``plan``. The robot file and the task file are each read once; the task must name the robot
    (checked before it is planned). ``feedforward`` (one of :data:`FEEDFORWARD_IDS`, default the
    robot's: the inverse dynamics with inertials, none without) is each command's feed-forward
    torque; asking for one of a robot without inertials is refused first (OptionError).
    ``bound``: cores of targets.TARGETS (names or comma lists) the project is built for, whose
    static worst-case bounds (:func:`project_bounds`) go into the manifest's ``"bounds"`` and a
    table of the README; their cross toolchains are checked before anything is planned."""
    out = Path(out)
    targets = [TARGETS[name] for name in bound_targets(bound)]
    for target in targets:
        require_bound_tools(target)
    owned = _owned_files(out)
    _check_writable(out)
    robot_path = resolve_robot_path(robot_ref)
    data = read_input_file(robot_path, MAX_INPUT_FILE_BYTES, "robot file", RobotFileError)
    robot = _parse_robot(robot_path, data)
    robot_file, robot_files = project_robot_files(robot_path, data, robot)
    if feedforward is not None:
        check_feedforward(robot, feedforward)  # before anything is planned
    if task is not None:
        job = task_file_project_task(robot, task, overrides)
    elif plan is not None:
        job = plan_project_task(robot, plan)
    else:
        job = demo_project_task(robot, robot_ref)
    if feedforward is not None:
        job = dataclasses.replace(job, firmware=with_feedforward(job.firmware, feedforward))
    parent = out.resolve().parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        stage = Path(tempfile.mkdtemp(prefix=".armgen-firmware-", dir=parent))
    except OSError as exc:
        raise OutputError(f"--out {out}: cannot write in {parent}: {exc.strerror or exc}; choose a writable "
                          "folder (nothing was written)") from None
    try:
        _assemble(stage, robot_file, robot_files, job)
        bounds = [project_bounds(target, job.firmware.robot, stage / "generated", job.firmware) for target in targets]
        if bounds:
            _add_bounds_table(stage / "README.md", readme_table(bounds))
        _apply_umask(stage)
        new = sorted(p.relative_to(stage).as_posix() for p in stage.rglob("*") if p.is_file())
        _check_no_links(out, new)
        conflicts = _conflicts(out, owned, new)
        if conflicts:
            raise OutputError(f"--out {out}: these files were changed or added by hand and the new project would "
                              f"replace them: {', '.join(excerpt(c) for c in conflicts[:20])}"
                              f"{' …' if len(conflicts) > 20 else ''}; move your changes elsewhere (or delete the "
                              "files) and run again (nothing was written)")
        manifest = {"armgen": __version__, "robot": robot.name,
                    "files": {name: _digest(stage / name) for name in new}}
        if bounds:
            manifest["bounds"] = bounds
        (stage / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n", encoding="utf-8")
        _apply_umask(stage)
        _move_in(stage, out, new + [MANIFEST], [name for name in owned if name not in new])
    except OSError as exc:
        raise OutputError(f"--out {out}: cannot write the project: {exc.strerror or exc} ({exc.filename}); "
                          "choose a writable folder with free space (nothing was written)") from None
    finally:
        shutil.rmtree(stage, ignore_errors=True)
    return robot, [out / name for name in new + [MANIFEST]]


README_BOUND_SECTION = "## Worst case per tick"  # README.md.in's section the bounds' table ends


def _add_bounds_table(readme: Path, table: str) -> None:
    """Append ``table`` to the README's worst-case section (before the next section)."""
    text = readme.read_text(encoding="utf-8")
    start = text.index(README_BOUND_SECTION)
    end = text.find("\n## ", start + len(README_BOUND_SECTION))
    end = len(text) if end < 0 else end + 1
    readme.write_text(text[:end] + table + "\n" + text[end:], encoding="utf-8")


def _move_in(stage: Path, out: Path, names: list[str], dropped: list[str]) -> None:
    """Move the staged ``names`` into ``out`` and remove its ``dropped`` files (both owned by
    this command); the old versions wait in the staging folder until every file is in, and go
    back on any failure."""
    aside = stage / ".old"
    done: list[tuple[str, bool]] = []  # (name, an old version was set aside)
    try:
        for name in names + dropped:
            _check_no_links(out, [name])  # again: the folder may have changed since the first check
            target = out / name
            kept = aside / name
            had_old = target.is_file()
            if had_old:
                kept.parent.mkdir(parents=True, exist_ok=True)
                os.replace(target, kept)
            done.append((name, had_old))
            if name in names:
                target.parent.mkdir(parents=True, exist_ok=True)
                os.replace(stage / name, target)
    except (OSError, OutputError):
        for name, had_old in reversed(done):
            with contextlib.suppress(OSError):
                if name in names and (out / name).is_file():
                    os.replace(out / name, stage / name)
                if had_old:
                    os.replace(aside / name, out / name)
        raise
    for name in dropped:  # folders this command made and that are empty now
        with contextlib.suppress(OSError):
            for folder in Path(name).parents[:-1]:
                (out / folder).rmdir()
