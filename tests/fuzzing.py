"""Mutation fuzzing of robot and task files, shared by ``tests/test_fuzz.py`` (hypothesis,
derandomized) and ``benchmarks/fuzz.py`` (10 000+ seeded cases and a summary table).

A case is a bundled robot file or example task mutated a few times. Each mutation says
whether it certainly makes the file invalid (an unknown key, a wrong type, a non-finite
number, a path as a name, nesting beyond the cap); a case with such a mutation that is
accepted is "accepted nonsense". Every case ends in one of: accepted, a clean ArmgenError
(exit 2 for bad input, 3 for an infeasible plan), a traceback (any other exception), or a
hang (over its time limit).
"""

from __future__ import annotations

import contextlib
import copy
import functools
import json
import random
import signal
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator

from armgen.errors import ArmgenError
from armgen.planning.result import write_plan
from armgen.planning.tasks import ResourceCaps, configure_task, load_task, run_task
from armgen.robot import BUNDLED_DIR, parse_robot

EXAMPLES_DIR = BUNDLED_DIR.parent / "examples"
ROBOT_BASES = {name: (BUNDLED_DIR / f"{name}.toml").read_text() for name in ("planar3", "panda", "iiwa14")}
TASK_BASES = {p.stem: load_task(p)[0] for p in sorted(EXAMPLES_DIR.glob("*.toml"))}
# The fully planned point-to-point cases sample at 10 ms instead of the examples' 1 ms.
for _name in ("ptp_single_joint", "ptp_single_joint_timed"):
    TASK_BASES[_name]["step"] = 0.01
# Tasks planned in full for a sample of the cases: the point-to-point examples plan in
# milliseconds, so a full plan (and its write) fits the per-case limit.
FULL_PLAN_BASES = ("ptp_single_joint", "ptp_single_joint_timed")
# Caps of the fully planned cases: a mutation that asks for more is refused before work.
FUZZ_CAPS = ResourceCaps(max_steps=50_000, max_samples=200_000)
VALIDATE_LIMIT_S = 5.0
PLAN_LIMIT_S = 30.0

JUNK_VALUES: list[Any] = ["x", "", "../../etc/passwd", "x */ int injected = 42; /*", "n" * 300, float("nan"),
                          float("inf"), -float("inf"), 1e308, -1e308, 5e-324, 0, -1, 0.5, 1e300, True, [],
                          [1, 2, 3], [float("nan")], ["a", 1], {}, {"k": 1}, 10**30, "1979-05-27"]
FREE_TEXT_KEYS = ("description", "robot", "start", "name")
BAD_TYPE_VALUES: list[Any] = [float("nan"), float("inf"), "x */ y", [[[]]], {"k": {"k": 1}}]


class Hang(Exception):
    """A case exceeded its time limit."""


@contextlib.contextmanager
def time_limit(seconds: float) -> Iterator[None]:
    """Raise :class:`Hang` in the main thread after ``seconds`` (SIGALRM)."""
    def on_alarm(signum, frame):
        raise Hang(f"over {seconds} s")

    previous = signal.signal(signal.SIGALRM, on_alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _typo(rng: random.Random, key: str) -> str:
    if len(key) < 2:
        return key + "x"
    k = rng.randrange(len(key) - 1)
    return key[:k] + key[k + 1] + key[k] + key[k + 2:] if key[k] != key[k + 1] else key + "e"


def _deep(depth: int) -> Any:
    value: Any = 1
    for _ in range(depth):
        value = [value]
    return value


def _toml_value(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return {float("inf"): "inf", -float("inf"): "-inf"}.get(value, "nan" if value != value else repr(value))
    if isinstance(value, str):
        return json.dumps(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{k} = {_toml_value(v)}" for k, v in value.items()) + "}"
    return str(value)


def mutate_robot(rng: random.Random) -> tuple[str, bool]:
    """(robot TOML text, whether it certainly is invalid)."""
    lines = ROBOT_BASES[rng.choice(sorted(ROBOT_BASES))].splitlines()
    invalid = False
    for _ in range(rng.randint(1, 3)):
        k = rng.randrange(len(lines))
        action = rng.choice(["drop", "value", "dup", "garble", "unknown", "bad", "deep", "name", "huge"])
        line = lines[k]
        has_value = "=" in line and not line.lstrip().startswith("#")
        if action == "drop":
            lines.pop(k)
        elif action == "dup":
            lines.insert(k, line)
        elif action == "garble":
            lines[k] = line[: len(line) // 2] + "".join(rng.choice("[]{}=\"'#.,x 0\n") for _ in range(rng.randint(1, 8)))
        elif action == "value" and has_value:
            lines[k] = line.split("=")[0] + "= " + _toml_value(rng.choice(JUNK_VALUES))
        elif action == "unknown" and has_value:
            key = line.split("=")[0].strip()
            if key.isidentifier():
                lines.insert(k + 1, f"{_typo(rng, key)}x = 1")
                invalid = True
        elif action == "bad" and has_value:
            lines[k] = line.split("=")[0] + "= " + _toml_value(rng.choice(BAD_TYPE_VALUES))
            invalid = not lines[k].lstrip().startswith(("description", "#"))
        elif action == "deep" and has_value:
            depth = rng.choice([17, 100, 500])
            lines[k] = line.split("=")[0] + "= " + "[" * depth + "1" + "]" * depth
            invalid = True
        elif action == "name":
            bad = rng.choice(["../../x", "/abs", ".", "a b", "x" * 300, "1x", "x*/y", ""])
            idx = next((i for i, ln in enumerate(lines) if ln.startswith("name")), None)
            if idx is not None:
                lines[idx] = f"name = {json.dumps(bad)}"
                invalid = True
        elif action == "huge" and has_value and line.split("=")[0].strip() in ("a", "d"):
            lines[k] = line.split("=")[0] + "= " + rng.choice(["1e300", "1e20", "-1e300"])
            invalid = True
        if not lines or invalid:  # later mutations could remove what made the file invalid
            break
    return "\n".join(lines), invalid


def _tables(node: Any, path: tuple = ()) -> Iterator[tuple[tuple, Any]]:
    if isinstance(node, dict):
        yield path, node
        for key, value in node.items():
            yield from _tables(value, path + (key,))
    elif isinstance(node, list):
        for k, value in enumerate(node):
            yield from _tables(value, path + (k,))


def mutate_task(rng: random.Random, bases: tuple[str, ...] | None = None) -> tuple[str, dict[str, Any], bool]:
    """(base name, mutated task dict, whether it certainly is invalid)."""
    name = rng.choice(sorted(bases or TASK_BASES))
    task = copy.deepcopy(TASK_BASES[name])
    invalid = False
    for _ in range(rng.randint(1, 3)):
        tables = [(p, t) for p, t in _tables(task) if isinstance(t, dict)]
        path, table = rng.choice(tables)
        keys = [k for k in table if k != "planner"]
        action = rng.choice(["value", "drop", "unknown", "bad", "deep", "extreme", "extreme", "value"])
        if not keys:
            action = "unknown"
        key = rng.choice(keys) if keys else "x"
        if action == "value":
            table[key] = copy.deepcopy(rng.choice(JUNK_VALUES))
        elif action == "drop":
            del table[key]
        elif action == "unknown":
            table[_typo(rng, key) + "x"] = 1
            invalid = True
        elif action == "bad":
            value = copy.deepcopy(rng.choice(BAD_TYPE_VALUES))
            table[key] = value
            # free text (description, an obstacle's name) and file references (robot, a
            # start configuration's name) may hold any string
            invalid = not (isinstance(value, str) and key in FREE_TEXT_KEYS)
        elif action == "deep":
            table[key] = _deep(rng.choice([17, 100]))
            invalid = True
        else:  # an extreme number where a number was
            if isinstance(table[key], (int, float)) and not isinstance(table[key], bool):
                table[key] = rng.choice([0, -1, 1e308, 5e-324, 1e-300, 10**30, 1e-9, 0.5])
        if invalid:  # later mutations could remove what made the task invalid
            break
    return name, task, invalid


def parse_task(task: dict[str, Any]) -> Any:
    """Everything before planning: the schema, the robot, the planner's configure (units,
    joint names, cross-field rules)."""
    return configure_task(task, "fuzz.toml").config


@dataclass
class Outcome:
    kind: str  # "accepted", "clean", "traceback", "hang"
    detail: str = ""
    wrote: bool = False  # files appeared although the case failed


def _classify(call: Callable[[], Any], limit: float, exit_codes: tuple[int, ...]) -> Outcome:
    try:
        with time_limit(limit):
            call()
    except Hang as exc:
        return Outcome("hang", str(exc))
    except ArmgenError as exc:
        if exc.exit_code not in exit_codes or not str(exc).strip():
            return Outcome("traceback", f"{type(exc).__name__} exit {exc.exit_code}: {exc}")
        return Outcome("clean", str(exc))
    except Exception as exc:  # noqa: BLE001 - the point of fuzzing is to find these
        return Outcome("traceback", f"{type(exc).__name__}: {str(exc)[:200]}")
    return Outcome("accepted")


def robot_case(text: str) -> Outcome:
    outcome = _classify(lambda: parse_robot(text, "fuzz.toml"), VALIDATE_LIMIT_S, (2,))
    if outcome.kind == "clean" and not outcome.detail.startswith("fuzz.toml:"):
        return Outcome("traceback", f"message does not name the file: {outcome.detail}")
    return outcome


def task_case(task: dict[str, Any], full_plan: bool) -> Outcome:
    """Validate (schema) the task; with ``full_plan`` also plan it and write the plan into a
    fresh folder, which must stay empty when the case fails."""
    if not full_plan:
        return _classify(lambda: parse_task(task), VALIDATE_LIMIT_S, (2,))
    with tempfile.TemporaryDirectory(prefix="armgen-fuzz-") as tmp:
        out = Path(tmp) / "plan.csv"
        outcome = _classify(lambda: write_plan(run_task(task, "fuzz.toml", caps=FUZZ_CAPS), out), PLAN_LIMIT_S,
                            (2, 3))
        outcome.wrote = outcome.kind != "accepted" and any(Path(tmp).iterdir())
        return outcome


# -- URDF files ---------------------------------------------------------------------------

# A six-joint chain with the features the importer handles: fixed joints before, between and
# after the moving ones, oblique axes, a continuous and a prismatic joint, non-trivial origins.
URDF_JOINTS = [("mount", "fixed", "0.1 -0.2 0.05", "0.1 0.2 0.3", None, None),
               ("j1", "revolute", "0 0 0.3", "0 0 0", "0 0 1", ("-2.9", "2.9")),
               ("j2", "revolute", "0.05 0.02 0.1", "-1.5707963267948966 0 0.4", "0.3 0.5 0.8", ("-1.5", "1.7")),
               ("j3", "continuous", "0.3 0 0", "0 0.7 0", "0 -1 0", None),
               ("j4", "prismatic", "0 0.1 0.2", "0.2 -0.1 1.0", "1 1 0", ("-0.1", "0.25")),
               ("elbow", "fixed", "0.01 0.02 0.03", "3.141592653589793 0 0", None, None),
               ("j5", "revolute", "0 0 0.25", "0 0 0", "-1 0 0", ("-2", "2")),
               ("j6", "revolute", "0.08 0 0.02", "0 -0.3 0.9", "0.0 0.6 -0.8", ("-3", "3")),
               ("tcp", "fixed", "0 0 0.12", "0 0 -0.7853981633974483", None, None)]


def _urdf_text(joints: list[list[Any]], robot: str = "fuzzarm", prolog: str = "") -> str:
    links = "".join(f'<link name="l{k}"/>' for k in range(len(joints) + 1))
    body = []
    for k, (name, jtype, xyz, rpy, axis, limit) in enumerate(joints):
        parts = [f'<joint name="{name}" type="{jtype}"><parent link="l{k}"/><child link="l{k + 1}"/>',
                 f'<origin xyz="{xyz}" rpy="{rpy}"/>']
        if axis is not None:
            parts.append(f'<axis xyz="{axis}"/>')
        if limit is not None:
            parts.append(f'<limit lower="{limit[0]}" upper="{limit[1]}" effort="1" velocity="1"/>')
        body.append("".join(parts) + "</joint>")
    return f'{prolog}<robot name="{robot}">{links}{"".join(body)}</robot>'


def mutate_urdf(rng: random.Random) -> tuple[str, bool]:
    """(URDF text, whether it certainly is invalid): the robot-file bounds (joint count,
    origin and limit magnitudes, names, axes) and XML-level damage."""
    joints = [list(j) for j in URDF_JOINTS]
    robot, prolog, invalid = "fuzzarm", "", False
    moving = [k for k, j in enumerate(joints) if j[1] != "fixed"]
    bounded = [k for k, j in enumerate(joints) if j[5] is not None]
    for _ in range(rng.randint(1, 3)):
        action = rng.choice(["many", "origin", "limit", "name", "long_name", "axis", "zero_axis", "nan", "doctype",
                             "swap", "type", "robot_name", "fine_origin", "fine_limit", "garble", "degrees"])
        k = rng.choice(moving)
        if action == "many":
            count = rng.choice([65, 200, 1000])
            joints = [[f"j{i}", "revolute", "0 0 0.01", "0 0 0", "0 0 1", ("-1", "1")] for i in range(count)]
            invalid = True
        elif action == "origin":
            joints[rng.randrange(len(joints))][2] = rng.choice(["1e12 0 0", "0 -1e300 0", "0 0 1001"])
            invalid = True
        elif action == "limit" and bounded:
            b = rng.choice([i for i in bounded if i < len(joints)] or [0])
            if joints[b][5] is not None:
                joints[b][5] = rng.choice([("-1e300", "1e300"), ("-1", "1e12"), ("-1001", "0")])
                invalid = True
        elif action == "degrees":  # revolute limits written in degrees
            b = rng.choice([i for i, j in enumerate(joints) if j[1] == "revolute"] or [None])
            if b is not None:
                joints[b][5] = rng.choice([("-170", "170"), ("-360", "360"), ("0", "270")])
                invalid = True
        elif action == "name":
            joints[k][0] = rng.choice(["not a name", "1abc", "a-b", "x*/y", "naïve", "../x"])
            invalid = True
        elif action == "long_name":
            joints[rng.randrange(len(joints))][0] = "x" * rng.choice([257, 5000, 500_000])
            invalid = True
        elif action == "axis":
            joints[k][4] = rng.choice(["1e155 1e155 1e155", "1e200 0 1e200", "-1e308 -1e308 0"])
            invalid = True
        elif action == "zero_axis":
            joints[k][4] = "0 0 0"
            invalid = True
        elif action == "nan":
            field = rng.choice([2, 3, 4])
            joints[k][field] = rng.choice(["nan 0 0", "0 inf 0", "0 0 -inf"])
            invalid = True
        elif action == "doctype":
            prolog = '<!DOCTYPE r [<!ENTITY e "x">]>'
            invalid = True
        elif action == "swap" and joints[k][5] is not None:
            joints[k][5] = (joints[k][5][1], joints[k][5][0])
            invalid = True
        elif action == "type":
            joints[k][1] = rng.choice(["floating", "planar", "spherical", ""])
            invalid = True
        elif action == "robot_name":
            robot = rng.choice(["not an identifier", "r" * 500_000, "../r"])
            invalid = True
        elif action == "fine_origin":  # within the bounds: must still load
            joints[rng.randrange(len(joints))][2] = rng.choice(["999 0 0", "0 -0.001 1e-9", "1e-300 0 0"])
        elif action == "fine_limit" and joints[k][5] is not None:  # revolute ones within two turns (±4π)
            joints[k][5] = rng.choice([("-12.5", "12.5"), ("-1e-6", "1e-6"), ("0", "1")])
        elif action == "garble":  # may or may not still be a valid file
            text = _urdf_text(joints, robot, prolog)
            cut = rng.randrange(len(text))
            return text[:cut] + "".join(rng.choice("<>/=\"' x0") for _ in range(rng.randint(1, 6))) + text[cut:], \
                invalid
        if invalid:
            break
    return _urdf_text(joints, robot, prolog), invalid


def urdf_case(text: str) -> Outcome:
    """Load the URDF as ``armgen show f.urdf`` does (a file in a fresh folder)."""
    from armgen.robot import load_robot

    with tempfile.TemporaryDirectory(prefix="armgen-fuzz-") as tmp:
        path = Path(tmp) / "fuzz.urdf"
        path.write_text(text, encoding="utf-8", errors="surrogatepass")
        outcome = _classify(lambda: load_robot(path), VALIDATE_LIMIT_S, (2,))
        if outcome.kind == "clean" and (not outcome.detail.startswith(str(path)) or len(outcome.detail) > MAX_MESSAGE_CHARS):
            return Outcome("traceback", f"message does not name the file or is too long: {outcome.detail[:300]}")
        return outcome


# An error message names the file, the place and the fix, quoting a bounded excerpt.
MAX_MESSAGE_CHARS = 600


# -- sweep options ---------------------------------------------------------------------------

SWEEP_BASE = "ptp_single_joint"
SWEEP_GRIDS = ["step=[0.01, 0.02]", "method=[\"cubic\", \"3-4\"]", "compare=[[], [\"cubic\"]]"]
SWEEP_RANGES = ["step=0.01:0.02", "waypoints.t=[0, 5, 13, 22, 35]:[0, 6, 14, 23, 36]"]


def mutate_sweep(rng: random.Random) -> tuple[dict[str, Any], bool]:
    """(the options of ``armgen sweep``: grids, ranges, draws, a table to resume from; whether
    they certainly are invalid)."""
    grids = rng.sample(SWEEP_GRIDS, rng.randint(0, 2))
    ranges = rng.sample(SWEEP_RANGES, rng.randint(0, 1))
    draws = rng.choice([1, 3]) if ranges else 0
    table = None
    invalid = False
    action = rng.choice(["none", "grid", "range", "draws", "huge_grid", "table", "key", "no_draws", "range_key",
                         "date"])
    if action == "grid":
        grids.append(rng.choice(["step", "step=", "=[1]", "step=3", "step=[]", "step=[1", "step={a=1}",
                                 "step=" + "9" * 5000, "x" * 500_000 + "=[1]"]))
        invalid = True
    elif action == "range":
        ranges.append(rng.choice(["step=1", "step=a:b", "step=3:1", "step=0:nan", "step=[1, 2]:[3]", "step=1:2:3",
                                  "step=" + "1" * 5000 + ":2"]))
        draws = max(draws, 1)
        invalid = True
    elif action == "draws":
        ranges = ranges or [SWEEP_RANGES[0]]
        draws = rng.choice([100_001, 10**9, 10**18])
        invalid = True
    elif action == "huge_grid":
        values = ", ".join(["0.01"] * rng.choice([400, 3000]))
        grids = [f"step=[{values}]", f"compare=[{', '.join(['[]'] * 400)}]"]
        invalid = True
    elif action == "table":
        table = rng.choice(["date,city\n2020-01-01,Paris\n", "run,status,exit_code,message,overrides\nx,ok,0,,{}\n",
                            "run,status,exit_code,message,overrides\n0,maybe,0,,\"{}\"\n",
                            "run,status,exit_code,message,overrides\n0,ok,0,,[[\n", "\x00\xff garbage",
                            "run,status,exit_code,message,overrides\n-1,ok,0,,\"{}\"\n"])
        grids = grids or [SWEEP_GRIDS[0]]
        invalid = True
    elif action == "no_draws" and ranges:
        draws = 0
        invalid = True
    elif action == "key":  # a key the task does not have (a typo): refused before any run
        grids.append(rng.choice(["nosuch.field=[1, 2]", "waypoints.nosuch=[1]", "a..b=[1]", "stpe=[0.01]",
                                 "waypoints.tt=[[0, 5, 13, 22, 35]]", "step.x=[1]"]))
        invalid = True
    elif action == "range_key":
        ranges.append(rng.choice(["stpe=0.01:0.02", "timing.omeg_max=[1, 1, 1, 1]:[2, 2, 2, 2]"]))
        draws = max(draws, 1)
        invalid = True
    elif action == "date":  # a TOML date or time: no task value
        grids.append(rng.choice(["step=[1979-05-27]", "step=[07:32:00]", "compare=[[1979-05-27T07:32:00Z]]",
                                 "waypoints.t=[[0, 5, 1979-05-27, 22, 35]]"]))
        invalid = True
    if not grids and not ranges:
        grids = [SWEEP_GRIDS[0]]
    return {"grids": grids, "ranges": ranges, "draws": draws, "table": table}, invalid


def sweep_case(options: dict[str, Any]) -> Outcome:
    """Everything ``armgen sweep`` does before planning: parse the options, size the sweep,
    check the swept keys, read the table to resume, and validate every run's task (schema and
    planner parser)."""
    from armgen.planning.sweep import SweepSpec, check_fields, parse_grid, parse_range, read_table
    from armgen.planning.tasks import set_field

    def run() -> None:
        spec = SweepSpec([parse_grid(g) for g in options["grids"]], [parse_range(r) for r in options["ranges"]],
                         options["draws"], 0)
        spec.check()
        check_fields(TASK_BASES[SWEEP_BASE], spec, "fuzz.toml")
        if options["table"] is not None:
            with tempfile.TemporaryDirectory(prefix="armgen-fuzz-") as tmp:
                path = Path(tmp) / "table.csv"
                path.write_bytes(options["table"].encode("utf-8", "surrogateescape"))
                read_table(path)
        for fields in spec.runs():
            task = copy.deepcopy(TASK_BASES[SWEEP_BASE])
            for key, value in fields.items():
                set_field(task, key, value, f"sweep field {key!r}")
            parse_task(task)

    return _classify(run, VALIDATE_LIMIT_S, (2,))


# -- poses CSV files (a program's `poses` move) ------------------------------------------------

POSES_TASK = "panda_polish_contour_program"
POSES_BASE = (EXAMPLES_DIR / "panda_polish_contour.csv").read_text()
POSES_COLUMNS = ("x", "y", "z", "roll", "pitch", "yaw", "qw", "qx", "qy", "qz")
# (cell text, whether it certainly makes the file invalid) for a data cell
POSES_CELLS: list[tuple[str, bool]] = [
    ("nan", True), ("inf", True), ("-Infinity", True), ("", True), ("x", True), ("1e300", True), ("-1e300", True),
    ("0x10", True), ("1" * 5000, True), ("1" * 200_000, True), ("2e6", True), ("1,5", False), ("  551.5 ", False),
    ("5e-324", False), ("1_0", False), ("-0", False)]


def _quaternion_rows(lines: list[str], scale: float) -> list[str]:
    """The poses with qw, qx, qy, qz columns (scaled by ``scale``) instead of roll, pitch, yaw."""
    from scipy.spatial.transform import Rotation

    out = []
    for line in lines:
        if line.startswith("#") or line.startswith("x,"):
            out.append("x,y,z,qw,qx,qy,qz" if line.startswith("x,") else line)
            continue
        x, y, z, *rpy = (float(v) for v in line.split(","))
        qx, qy, qz, qw = Rotation.from_euler("xyz", rpy, degrees=True).as_quat() * scale
        out.append(f"{x},{y},{z},{qw!r},{qx!r},{qy!r},{qz!r}")
    return out


def mutate_poses(rng: random.Random) -> tuple[bytes, bool]:
    """(poses CSV bytes of the polishing example, whether they certainly are invalid): cells,
    columns, rows, comments, quoting, encodings, and field lengths beyond the CSV reader's."""
    lines = POSES_BASE.splitlines()
    invalid, newline, prefix, tail = False, "\n", "", b""
    for _ in range(rng.randint(1, 3)):
        header = next((k for k, line in enumerate(lines) if not line.startswith("#")), None)
        data = [k for k, line in enumerate(lines) if header is not None and k > header and not line.startswith("#")]
        if not data:
            break
        action = rng.choice(["cell", "cell", "header_only", "empty", "drop_column", "extra_column", "reorder",
                             "case", "long_comment", "long_header", "quote", "nul", "bad_utf8", "bom", "crlf",
                             "quaternion", "duplicate", "truncate", "garble"])
        k = rng.choice(data)
        if action == "cell":
            cells = lines[k].split(",")
            used = [i for i, c in enumerate(lines[header].split(",")) if c.strip().lower() in POSES_COLUMNS]
            text, certain = rng.choice(POSES_CELLS)
            column = rng.choice(used) if used and rng.random() < 0.9 else rng.randrange(len(cells))
            if column < len(cells):
                cells[column] = text
                lines[k] = ",".join(cells)
                invalid = certain and column in used
        elif action == "header_only":
            lines = lines[:header + 1]
            invalid = True
        elif action == "empty":
            lines = rng.choice([[], ["# only a comment"], [""]])
            invalid = True
        elif action == "drop_column":  # a pose column renamed
            cells = lines[header].split(",")
            named = [i for i, c in enumerate(cells) if c.strip().lower() in POSES_COLUMNS]
            if named:
                cells[rng.choice(named)] = "w"
                lines[header] = ",".join(cells)
                invalid = True
        elif action == "extra_column":
            lines = [line + (",note" if i == header else ",a b" if i in data else "") for i, line in enumerate(lines)]
        elif action == "reorder":  # the columns of every full row, in one new order
            count = len(lines[header].split(","))
            order = rng.sample(range(count), count)
            lines = [",".join(line.split(",")[o] for o in order) if i >= header and line.count(",") == count - 1
                     else line for i, line in enumerate(lines)]
        elif action == "case":
            lines[header] = " X , Y ,z,ROLL, pitch ,Yaw"
        elif action == "long_comment":
            lines.insert(rng.randrange(len(lines) + 1), "# " + "c" * rng.choice([200, 140_000]) + rng.choice(['"', ""]))
        elif action == "long_header":  # an ignored column, named beyond the CSV reader's limit or not
            length = rng.choice([5000, 200_000])
            lines[header] += "," + "h" * length
            invalid = length > 131_072
        elif action == "quote":
            at = rng.randrange(len(lines[k]) + 1)
            lines[k] = lines[k][:at] + '"' + lines[k][at:]
        elif action == "nul":  # in a pose cell (an ignored column may hold one)
            cells = lines[k].split(",")
            used = [i for i, c in enumerate(lines[header].split(",")) if c.strip().lower() in POSES_COLUMNS]
            if used and max(used) < len(cells):
                cells[rng.choice(used)] += "\x00"
                lines[k] = ",".join(cells)
                invalid = True
        elif action == "bad_utf8":
            tail = rng.choice([b"\xff\xfe", b"\xc3", b"\xed\xa0\x80"])
            invalid = True
        elif action == "bom":
            prefix = "\ufeff"
        elif action == "crlf":
            newline = "\r\n"
        elif action == "quaternion":
            scale, certain = rng.choice([(1.0, False), (7.0, False), (1e300, True), (0.0, True), (1e-9, True)])
            lines = _quaternion_rows(POSES_BASE.splitlines(), scale)  # the earlier mutations are dropped
            invalid = certain
        elif action == "duplicate":
            lines.insert(k, lines[k])
            invalid = True
        elif action == "truncate":
            lines = lines[:header + 1] + [lines[i] for i in data[:2]]
            invalid = True
        elif action == "garble":  # may or may not still be a valid file
            at = rng.randrange(len(lines[k]) + 1)
            junk = "".join(rng.choice(",.#\"e-x 9") for _ in range(rng.randint(1, 6)))
            lines[k] = lines[k][:at] + junk + lines[k][at:]
        if invalid or not lines:
            break
    return (prefix + newline.join(lines) + newline).encode("utf-8") + tail, invalid


def poses_case(data: bytes) -> Outcome:
    """The example program with its poses move reading ``data``, up to its time law (what
    ``armgen plan`` does before integrating): read the CSV, build the path, check the reach."""
    import math

    import numpy as np

    from armgen.planning.toolpath.schema import ProgramPath
    from armgen.planning.toolpath.task import program_motion, program_spec
    from armgen.robot import load_robot, rpy_matrix

    task = TASK_BASES[POSES_TASK]
    start = np.eye(4)
    start[:3, :3] = rpy_matrix(*np.radians(task["start"]["pose"]["rpy"]))
    start[:3, 3] = np.asarray(task["start"]["pose"]["xyz"]) * 1e-3
    with tempfile.TemporaryDirectory(prefix="armgen-fuzz-") as tmp:
        source = str(Path(tmp) / "fuzz.toml")
        (Path(tmp) / "panda_polish_contour.csv").write_bytes(data)
        path = ProgramPath.model_validate(task["path"])
        outcome = _classify(lambda: program_motion(program_spec(path, source, 1e-3, math.pi / 180), start,
                                                   load_robot(task["robot"]), source), PLAN_LIMIT_S, (2,))
        if outcome.kind == "clean" and not (outcome.detail.startswith(source)
                                            and len(outcome.detail) <= MAX_MESSAGE_CHARS):
            return Outcome("traceback", f"message does not name the file or is too long: {outcome.detail[:300]}")
        return outcome


# -- the IK entry points (Robot.ik and `armgen ik`) ------------------------------------------

IK_ROBOTS = ("planar3", "panda")
# The names an argument error of Robot.ik starts with (anything else raised is a traceback).
IK_ARGUMENTS = ("pose", "q0", "seed", "tol_position", "tol_orientation", "max_iterations")
# (value, whether it certainly is invalid) per argument
IK_TOLERANCES: list[tuple[Any, bool]] = [(float("nan"), True), (float("inf"), True), (-1e-6, True), (0, True),
                                         (1e30, True), (0.0100001, True), ("1e-3", True), (True, True), (1e-3j, True),
                                         ([1e-3], True), (None, False), (1e-3, False), (0.01, False), (5e-324, False)]
IK_ITERATIONS: list[tuple[Any, bool]] = [(True, True), (0, True), (-1, True), (451, True), (2.5, True), ("10", True),
                                         (10**30, True), (None, False), (1, False), (450, False)]
IK_POSE_ENTRIES: list[tuple[float, bool]] = [(float("nan"), True), (float("inf"), True), (1e300, True),
                                             (-1e308, True), (1001.0, True), (5.0, False), (-0.0, False)]


@functools.lru_cache(maxsize=None)
def _ik_robot(name: str):
    from armgen.robot import load_robot

    return load_robot(name)


def mutate_ik(rng: random.Random) -> tuple[dict[str, Any], bool]:
    """(the arguments of one Robot.ik call, whether they certainly are invalid): a reachable
    pose (the FK of a configuration within the limits), then junk in the pose's entries, type
    and shape, the seed, q0, the tolerances and max_iterations."""
    import numpy as np

    name = rng.choice(IK_ROBOTS)
    robot = _ik_robot(name)
    q = np.array([rng.uniform(lo, hi) for lo, hi in zip(robot.qmin, robot.qmax)])
    args: dict[str, Any] = {"robot": name, "pose": robot.fk(q), "kwargs": {}}
    invalid = False
    for _ in range(rng.randint(1, 2)):
        action = rng.choice(["entry", "rotation", "last_row", "type", "shape", "batch", "tolerance", "iterations",
                             "seed", "q0", "seed_name"])
        pose = args["pose"]
        if not (isinstance(pose, np.ndarray) and pose.shape == (4, 4) and pose.dtype == float):
            break  # its type or shape was mutated: that is the case
        pose = pose.copy()
        if action == "entry":
            value, invalid = rng.choice(IK_POSE_ENTRIES)
            row, col = (rng.randrange(3), 3) if abs(value) < 1e3 and value == value else (rng.randrange(3),
                                                                                           rng.randrange(4))
            pose[row, col] = value
            args["pose"] = pose
        elif action == "rotation":
            pose[rng.randrange(3), rng.randrange(3)] += rng.choice([1e-3, 0.5, -2.0])
            args["pose"], invalid = pose, True
        elif action == "last_row":
            pose[3, rng.randrange(4)] += rng.choice([1.0, 1e-3, -0.5])  # far beyond rounding
            args["pose"], invalid = pose, True
        elif action == "type":
            converted = rng.choice([pose.astype(complex), pose.astype(str), pose.astype(bool), pose.astype(object),
                                    "eye", [[str(v) for v in row] for row in pose.tolist()]])
            args["pose"], invalid = converted, True
        elif action == "shape":
            args["pose"] = rng.choice([pose[:3], pose.ravel(), pose[None, None], np.zeros((0, 4, 4)), pose[:, :3]])
            invalid = args["pose"].shape[-2:] != (4, 4)
        elif action == "batch":
            args["pose"] = np.stack([pose, robot.fk(robot.qmid)])
        elif action in ("tolerance", "iterations"):
            key = rng.choice(["tol_position", "tol_orientation"]) if action == "tolerance" else "max_iterations"
            value, certain = rng.choice(IK_TOLERANCES if action == "tolerance" else IK_ITERATIONS)
            args["kwargs"][key] = value
            invalid = certain
        elif action in ("seed", "q0"):
            value, certain = rng.choice([(np.full(robot.n, np.nan), True), (np.zeros(robot.n + 1), True),
                                         (np.zeros(robot.n) + 0j, True), (["a"] * robot.n, True),
                                         ([True] * robot.n, True),
                                         (np.full(robot.n, 1e6), False), (robot.qmid.copy(), False),
                                         (np.zeros((2, robot.n)), False)])
            args["kwargs"][action] = value
            invalid = certain or (np.ndim(value) == 2 and np.ndim(args["pose"]) != 3)
        else:
            args["kwargs"]["seed"] = rng.choice(["nosuch", "", "q0" if name == "planar3" else "qr"])
            invalid = args["kwargs"]["seed"] != ("q0" if name == "planar3" else "qr")
        if invalid:
            break
    return args, invalid


def ik_case(args: dict[str, Any]) -> Outcome:
    """One Robot.ik call: a result, or a TypeError/ValueError naming the argument (or a clean
    ArmgenError: an unknown seed name). A success must be one: the FK of ``q`` within the
    tolerance of the pose in the position rows the robot controls."""
    import numpy as np

    from armgen.symbolic import ik

    robot = _ik_robot(args["robot"])
    try:
        with time_limit(VALIDATE_LIMIT_S):
            result = robot.ik(args["pose"], **args["kwargs"])
    except Hang as exc:
        return Outcome("hang", str(exc))
    except ArmgenError as exc:
        if exc.exit_code != 2:
            return Outcome("traceback", f"exit {exc.exit_code}: {exc}")
        return Outcome("clean", str(exc))
    except (TypeError, ValueError) as exc:
        if str(exc).startswith(IK_ARGUMENTS) and len(str(exc)) <= MAX_MESSAGE_CHARS:
            return Outcome("clean", str(exc))
        return Outcome("traceback", f"{type(exc).__name__}: {str(exc)[:200]}")
    except Exception as exc:  # noqa: BLE001 - the point of fuzzing is to find these
        return Outcome("traceback", f"{type(exc).__name__}: {str(exc)[:200]}")
    tol = args["kwargs"].get("tol_position") or ik.TOL_POSITION
    rows = [k for k in robot.task_rows if k < 3]
    pose = np.asarray(args["pose"], dtype=float)
    reached = robot.fk(result.q)
    off = np.max(np.abs(pose[..., rows, 3] - reached[..., rows, 3]), axis=-1, initial=0.0)
    if np.any(result.success & (off > tol * (1 + 1e-9) + 1e-12)):
        return Outcome("traceback", f"success claimed {float(np.max(off)):.3g} m from the pose (tolerance {tol:g})")
    return Outcome("accepted")


# (text, whether it certainly is invalid) of one number of --xyz / --rpy
IK_CLI_NUMBERS: list[tuple[str, bool]] = [("nan", True), ("inf", True), ("-inf", True), ("1e300", True), ("x", True),
                                          ("", True), ("1001", True), ("0x1p3", True), ("-0", False), ("1e-320", False),
                                          ("0.3", False)]


def mutate_ik_cli(rng: random.Random) -> tuple[list[str], bool]:
    """(the arguments of `armgen ik`, whether they certainly are invalid): a reachable pose of
    planar3 or panda, then junk in --xyz, --rpy, --seed, --q0, --max-iterations and --units."""
    import numpy as np

    from armgen.robot import matrix_rpy

    name = rng.choice(IK_ROBOTS)
    robot = _ik_robot(name)
    pose = robot.fk(np.array([rng.uniform(lo, hi) for lo, hi in zip(robot.qmin, robot.qmax)]))
    xyz = [repr(float(v)) for v in pose[:3, 3]]
    rpy = [repr(float(v)) for v in matrix_rpy(pose[:3, :3])]
    options: dict[str, list[str]] = {"--xyz": xyz, "--rpy": rpy}
    invalid = False
    for _ in range(rng.randint(1, 2)):
        action = rng.choice(["xyz", "rpy", "seed", "q0", "iterations", "units", "drop_rpy", "off_plane"])
        if action in ("xyz", "rpy"):
            text, invalid = rng.choice(IK_CLI_NUMBERS)
            options.setdefault(f"--{action}", ["0", "0", "0"])[rng.randrange(3)] = text
        elif action in ("seed", "q0"):
            text, invalid = rng.choice([("nosuch", True), ("1,2", True), (",".join(["nan"] * robot.n), True),
                                        (",".join(["0"] * (robot.n + 1)), True), ("x" * 5000, True),
                                        (",".join(["0.1"] * robot.n), False),
                                        ("q0" if name == "planar3" else "qr", False)])
            options[f"--{action}"] = [text]
        elif action == "iterations":
            text, invalid = rng.choice([("0", True), ("-5", True), ("x", True), ("1e3", True), ("1", False),
                                        ("450", False), ("100000", False)])
            options["--max-iterations"] = [text]
        elif action == "units":
            text, invalid = rng.choice([("grad", True), ("deg", False), ("rad", False)])
            options["--units"] = [text]
        elif action == "drop_rpy":
            options.pop("--rpy", None)
        elif action == "off_plane":  # a z a planar arm cannot take: exit 3, never "solved"
            options["--xyz"][2] = "0.6"
        if invalid:
            break
    argv = ["ik", name]
    for option, values in options.items():
        argv += [option, *values]
    return argv, invalid


def ik_cli_case(argv: list[str]) -> Outcome:
    """`armgen ik ARGV`: exit 0 (accepted), 2 (a bad option) or 3 (no configuration), with
    an error message of bounded length; exit 1 (an internal error) or a hang is a bug. Exit 0
    may say "solved" only for a pose the arm reaches (planar3: in its plane, z = 0)."""
    from click.testing import CliRunner

    from armgen.cli.main import cli

    try:
        with time_limit(PLAN_LIMIT_S):
            result = CliRunner().invoke(cli, argv)
    except Hang as exc:
        return Outcome("hang", str(exc))
    output = result.output
    errors = [line for line in output.splitlines() if line.startswith(("error:", "Error:"))]
    if result.exit_code not in (0, 2, 3) or "internal error" in output or "Traceback" in output:
        return Outcome("traceback", f"exit {result.exit_code}: {output[-300:]}")
    if any(len(line) > MAX_MESSAGE_CHARS for line in errors):
        return Outcome("traceback", f"message too long: {errors[0][:300]}")
    if result.exit_code == 0 and argv[1] == "planar3" and abs(float(argv[argv.index("--xyz") + 3])) > 1e-6:
        return Outcome("traceback", f"solved a pose off planar3's plane: {argv}")
    return Outcome("accepted" if result.exit_code == 0 else "clean", output[-300:])
