"""``armgen firmware ROBOT --out DIR``: a self-contained C project for any robot.

The folder holds the robot file, its generated kinematics (as ``armgen gen`` writes them), the
controller sources of the firmware stub, a compiled-in demo task with armgen's plan of it, a
``CMakeLists.txt`` that builds the host demo out of the box and, with the toolchain file it
ships, the Cortex-M4F image, and a README. The folder appears complete or not at all: it is
assembled in a hidden staging folder beside ``DIR`` and renamed into place.

The demo task (:func:`demo_task`): a straight line of the tool, orientation held, from the
robot's named configuration ``q0`` (else its first named configuration, else mid-range of
the limits), 5 cm in 1 s (cubic time law, pseudo-inverse, Euler at 10 ms). When that line
leaves the limits or the workspace, the next candidate direction (±x, ±y, ±z), then 2 cm,
is tried: the first one the planner completes is used.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import shutil
import tempfile
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from ..codegen.generate import CodegenConfig, generate
from ..errors import ArmgenError, OutputError, PlanningError
from ..planning.result import write_plan
from ..planning.tasks import run_task
from ..robot import Robot, load_robot, resolve_robot_path
from ..symbolic.model import SymbolicModel
from . import firmware as fw

DEMO_DURATION_S = 1.0
DEMO_STEP_S = 0.01  # the controller's tick: 100 ticks, a short demo and a small CSV
DEMO_DISTANCES_M = (0.05, 0.02)
DEMO_DIRECTIONS = ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))
PROJECT_ROBOT_FILE = "robot.toml"  # the project's copy of the robot file; tasks name it so
MARKER = ".armgen-firmware"  # marks a folder this command wrote (it may replace it)

# The stub's files the project needs, by their place in the project.
STUB_FILES = {
    "controller": ("controller.c", "controller.h", "ctrl_robot.h", "fw_csv.c", "fw_csv.h", "fw_task.c", "fw_task.h"),
    "host": ("host/main.c",),
    "arm": ("arm/fw_main.c", "arm/startup.c", "arm/semihost.c", "arm/semihost.h", "arm/fw_fastmath.c",
            "arm/mps2_an386.ld"),
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
    pose = np.array(SymbolicModel(robot).function("fk")(q))
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
                result = run_task(task, source)
            except ArmgenError as exc:
                reasons.append(str(exc).splitlines()[0])
                continue
            if fw.refusal(result) is None:
                axis = "xyz"[int(np.flatnonzero(direction)[0])]
                sign = "+" if sum(direction) > 0 else "-"
                start = task["start"] if isinstance(task["start"], str) else "mid-range of the limits"
                return task, result, (f"a {distance * 100:g} cm line along {sign}{axis} in {DEMO_DURATION_S:g} s "
                                      f"from configuration {start}, orientation held")
    raise PlanningError(f"robot '{robot.name}': no demo line (±x, ±y, ±z; 5 or 2 cm) can be planned from its "
                        f"start configuration; add a named configuration q0 away from the limits and singular "
                        f"poses to the robot file (last reason: {reasons[-1] if reasons else '?'})")


def _toml_value(value: Any) -> str:
    if isinstance(value, str):
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    return repr(float(value)) if isinstance(value, float) else repr(value)


def task_toml(task: dict[str, Any], comment: str) -> str:
    """A task dict (top-level scalars, one level of tables) as TOML text."""
    lines = [f"# {comment}", "# Written by `armgen firmware`; plan it with `armgen plan demo/demo.toml` in the project."]
    lines += [f"{k} = {_toml_value(v)}" for k, v in task.items() if not isinstance(v, dict)]
    for key, table in task.items():
        if isinstance(table, dict):
            lines += ["", f"[{key}]", *(f"{k} = {_toml_value(v)}" for k, v in table.items())]
    return "\n".join(lines) + "\n"


def _fill(template: str, values: dict[str, str]) -> str:
    for key, value in values.items():
        template = template.replace(f"@{key}@", value)
    return template


def _check_out(out: Path) -> None:
    if out.exists() and not out.is_dir():
        raise OutputError(f"--out {out}: is a file; give a folder for the firmware project (nothing was written)")
    if out.is_dir() and any(out.iterdir()) and not (out / MARKER).is_file():
        raise OutputError(f"--out {out}: the folder exists and was not written by `armgen firmware`; give a new or "
                          "empty folder (nothing was written)")
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


def _assemble(stage: Path, robot: Robot, robot_bytes: bytes, robot_ref: str) -> None:
    stub = resources.files("armgen.data") / "firmware_stub"
    (stage / PROJECT_ROBOT_FILE).write_bytes(robot_bytes)
    code = generate(CodegenConfig(robot))
    (stage / "generated").mkdir()
    for name, text in code.files.items():
        (stage / "generated" / name).write_text(text, encoding="utf-8")
    for folder, names in STUB_FILES.items():
        (stage / folder).mkdir(exist_ok=True)
        for name in names:
            (stage / folder / Path(name).name).write_bytes((stub / name).read_bytes())
    planned, result, description = plan_demo(robot, robot_ref, "demo/demo.toml")
    # The project names its own copy of the robot file, so it plans and verifies in place.
    task = dict(planned, robot=PROJECT_ROBOT_FILE)
    toml_text = task_toml(task, f"Demo task of robot '{robot.name}': {description}.")
    (stage / "demo").mkdir()
    (stage / "demo" / "demo.toml").write_text(toml_text, encoding="utf-8")
    result.metadata["task"] = task
    result.metadata["task_sha256"] = hashlib.sha256(toml_text.encode()).hexdigest()
    result.metadata["task_file"] = "demo/demo.toml"
    write_plan(result, stage / "demo" / "plan.csv")
    fw.write_task_files(fw.task_from_dict(planned, "demo/demo.toml", robot), stage / "task", stage / "generated")
    values = {"ROBOT": robot.name, "NDOF": str(robot.n), "PREFIX": code.prefix, "PREFIX_UC": code.prefix.upper(),
              "MAX_SEGMENTS": str(fw.MAX_SEGMENTS), "VERSION": __version__, "SHA256": robot.sha256,
              "DEMO": description}
    project = stub / "project"
    (stage / "CMakeLists.txt").write_text(_fill((project / "CMakeLists.txt.in").read_text(encoding="utf-8"), values),
                                          encoding="utf-8")
    (stage / "README.md").write_text(_fill((project / "README.md.in").read_text(encoding="utf-8"), values),
                                     encoding="utf-8")
    (stage / "cmake").mkdir()
    (stage / "cmake" / "arm-none-eabi-cortex-m4.cmake").write_bytes(
        (project / "cmake" / "arm-none-eabi-cortex-m4.cmake").read_bytes())
    (stage / MARKER).write_text(f"armgen {__version__} firmware project of robot {robot.name}\n", encoding="utf-8")


def write_firmware_project(robot_ref: str, out: str | Path) -> tuple[Robot, list[Path]]:
    """Write the project into ``out`` (new, empty, or a project this command wrote earlier,
    which is replaced as a whole). Returns the robot and the files written."""
    out = Path(out)
    _check_out(out)
    robot_path = resolve_robot_path(robot_ref)
    robot = load_robot(robot_ref)
    robot_bytes = robot_path.read_bytes()
    parent = out.resolve().parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
        stage = Path(tempfile.mkdtemp(prefix=".armgen-firmware-", dir=parent))
    except OSError as exc:
        raise OutputError(f"--out {out}: cannot write in {parent}: {exc.strerror or exc}; choose a writable "
                          "folder (nothing was written)") from None
    old = None
    try:
        _assemble(stage, robot, robot_bytes, robot_ref)
        _apply_umask(stage)
        if out.exists():
            old = Path(tempfile.mkdtemp(prefix=".armgen-firmware-old-", dir=parent))
            os.replace(out, old / "project")
        os.replace(stage, out)
    except OSError as exc:
        if old is not None and not out.exists():
            os.replace(old / "project", out)
        raise OutputError(f"--out {out}: cannot write the project: {exc.strerror or exc} ({exc.filename}); "
                          "choose a writable folder with free space (nothing was written)") from None
    finally:
        with contextlib.suppress(OSError):
            shutil.rmtree(stage)
        if old is not None:
            shutil.rmtree(old, ignore_errors=True)
    return robot, sorted(p for p in out.rglob("*") if p.is_file())
