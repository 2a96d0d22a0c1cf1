"""Robot description files (TOML): loading, validation, conversion to SI.

A robot file holds a serial chain in standard or modified (Craig) DH. Every length is
converted to metres and every angle to radians on load; the returned :class:`Robot` is
SI-only. Errors name the file, the joint and the field, and say how to fix them.

Format (validation rules: ``docs/input-files.md``; examples: the bundled files in ``robots/``)::

    name = "planar3"
    convention = "standard"            # or "modified"
    [units]
    length = "m"                       # or "mm"
    angle = "deg"                      # or "rad"
    [[joints]]
    name = "j1"                        # optional, default "j<i>"
    type = "revolute"                  # or "prismatic"
    a = 1.0
    d = 0.0
    alpha = 0.0
    offset = 0.0                       # optional, default 0
    qlim = [-170, 170]
    [tool]                             # optional, likewise [base]
    xyz = [0, 0, 0.1]
    rpy = [0, 0, 0]                    # R = Rz(yaw) Ry(pitch) Rx(roll)
    [configurations]
    q0 = [0, 30, -45]
"""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from pydantic import ValidationError

from .errors import RobotFileError
from .robot_schema import RobotFile
from .schemas import IDENTIFIER_PATTERN, MAX_INPUT_FILE_BYTES, format_validation_error, parse_toml_bounded

BUNDLED_DIR = Path(str(resources.files("armgen.data") / "robots"))

LENGTH_UNITS = {"m": 1.0, "mm": 1e-3}
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180.0}
CONVENTIONS = ("standard", "modified")
JOINT_TYPES = ("revolute", "prismatic")
TASK_ROWS = ("vx", "vy", "vz", "wx", "wy", "wz")

# Angles this close to a multiple of 90 degrees (in units of a quarter turn) are snapped to
# it so that cos/sin become exact 0/±1 and the symbolic core drops the multiplications by
# them; 1e-12 of a quarter turn is far below any physical tolerance but above the rounding
# of a degree-to-radian conversion.
QUARTER_TURN_SNAP = 1e-12
# Physical bounds of a robot file's values (SI, after unit conversion): a 1 km link or a
# joint range of 160 turns is a typo, and keeping values this small keeps every product of
# the generated kinematics far from overflow, also in single precision (FLT_MAX ~ 3e38).
MAX_ABS_LENGTH_M = 1e3
MAX_ABS_ANGLE_RAD = 1e3


@dataclass(frozen=True)
class Joint:
    """One DH joint, SI units. For the modified convention ``a`` and ``alpha`` are
    ``a_{i-1}`` and ``alpha_{i-1}`` of the row, exactly as written in the file."""

    name: str
    type: str
    a: float
    d: float
    alpha: float
    offset: float
    qlim: tuple[float, float]
    theta: float = 0.0  # fixed joint angle of a prismatic joint (revolute joints: q + offset)

    @property
    def revolute(self) -> bool:
        return self.type == "revolute"


@dataclass(frozen=True)
class Robot:
    name: str
    convention: str
    joints: tuple[Joint, ...]
    base: np.ndarray  # 4x4 homogeneous
    tool: np.ndarray  # 4x4 homogeneous
    configurations: dict[str, np.ndarray]
    task_rows: tuple[int, ...]
    source: str  # path of the file it was read from
    sha256: str  # of the file's bytes
    description: str = ""
    units: dict[str, str] = field(default_factory=dict)

    @property
    def n(self) -> int:
        return len(self.joints)

    @property
    def qmin(self) -> np.ndarray:
        return np.array([j.qlim[0] for j in self.joints])

    @property
    def qmax(self) -> np.ndarray:
        return np.array([j.qlim[1] for j in self.joints])

    def configuration(self, name: str) -> np.ndarray:
        if name not in self.configurations:
            known = ", ".join(sorted(self.configurations)) or "none"
            raise RobotFileError(
                f"{self.source}: robot '{self.name}' has no configuration '{name}' (known: {known}); "
                "add it under [configurations] or give the joint values explicitly"
            )
        return self.configurations[name].copy()

    def check_within_limits(self, q: np.ndarray, what: str) -> None:
        """Raise a clear error when ``q`` is outside the joint limits or not finite."""
        q = np.asarray(q, dtype=float)
        if q.shape != (self.n,):
            raise RobotFileError(f"{what}: expected {self.n} joint values for robot '{self.name}', got {q.size}")
        for i, joint in enumerate(self.joints):
            if not math.isfinite(q[i]):
                raise RobotFileError(f"{what}: joint '{joint.name}' value is {q[i]}; give a finite number")
            lo, hi = joint.qlim
            if not lo <= q[i] <= hi:
                raise RobotFileError(
                    f"{what}: joint '{joint.name}' = {_fmt_joint(joint, q[i])} is outside its limits "
                    f"[{_fmt_joint(joint, lo)}, {_fmt_joint(joint, hi)}]; choose a start inside the limits"
                )


def _fmt_joint(joint: Joint, value: float) -> str:
    return f"{math.degrees(value):.4g} deg" if joint.revolute else f"{value * 1e3:.4g} mm"


def snap_quarter_turn(angle: float) -> float:
    """Return ``angle`` snapped to the nearest multiple of pi/2 when within QUARTER_TURN_SNAP."""
    quarters = angle / (math.pi / 2)
    nearest = round(quarters)
    if abs(quarters - nearest) < QUARTER_TURN_SNAP:
        return nearest * (math.pi / 2)
    return angle


def exact_cos_sin(angle: float) -> tuple[float, float]:
    """cos and sin, exact (0, ±1) at multiples of pi/2 so products with them vanish symbolically."""
    quarters = angle / (math.pi / 2)
    nearest = round(quarters)
    if abs(quarters - nearest) < QUARTER_TURN_SNAP:
        return [(1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0)][nearest % 4]
    return math.cos(angle), math.sin(angle)


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll)."""
    cr, sr = exact_cos_sin(roll)
    cp, sp = exact_cos_sin(pitch)
    cy, sy = exact_cos_sin(yaw)
    rz = np.array([[cy, -sy, 0.0], [sy, cy, 0.0], [0.0, 0.0, 1.0]])
    ry = np.array([[cp, 0.0, sp], [0.0, 1.0, 0.0], [-sp, 0.0, cp]])
    rx = np.array([[1.0, 0.0, 0.0], [0.0, cr, -sr], [0.0, sr, cr]])
    return rz @ ry @ rx


def matrix_rpy(rot: np.ndarray) -> np.ndarray:
    """[roll, pitch, yaw] of R = Rz(yaw) Ry(pitch) Rx(roll) (pitch in [-pi/2, pi/2])."""
    pitch = math.atan2(-rot[2, 0], math.hypot(rot[0, 0], rot[1, 0]))
    yaw = math.atan2(rot[1, 0], rot[0, 0])
    roll = math.atan2(rot[2, 1], rot[2, 2])
    return np.array([roll, pitch, yaw])


class _Reader:
    """Field access with errors that say where (file, table, field) and what to do."""

    def __init__(self, source: str):
        self.source = source

    def fail(self, where: str, message: str) -> RobotFileError:
        return RobotFileError(f"{self.source}: {where}: {message}")

    def number(self, table: dict, key: str, where: str, default: float | None = None) -> float:
        if key not in table:
            if default is not None:
                return default
            raise self.fail(where, f"missing field '{key}'; add '{key} = <number>'")
        value = table[key]
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(where, f"field '{key}' must be a number, got {type(value).__name__} {value!r}")
        if not math.isfinite(value):
            raise self.fail(where, f"field '{key}' is {value}; give a finite number")
        return float(value)

    def string(self, table: dict, key: str, where: str, choices: tuple[str, ...] | None = None,
               default: str | None = None) -> str:
        if key not in table:
            if default is not None:
                return default
            raise self.fail(where, f"missing field '{key}'")
        value = table[key]
        if not isinstance(value, str) or not value:
            raise self.fail(where, f"field '{key}' must be a non-empty string, got {value!r}")
        if choices is not None and value not in choices:
            raise self.fail(where, f"field '{key}' = {value!r} is not one of {', '.join(choices)}")
        return value

    def vector(self, table: dict, key: str, where: str, length: int | None = None,
               default: list[float] | None = None) -> list[float]:
        if key not in table:
            if default is not None:
                return list(default)
            raise self.fail(where, f"missing field '{key}'")
        value = table[key]
        if not isinstance(value, list):
            raise self.fail(where, f"field '{key}' must be an array of numbers, got {type(value).__name__}")
        if length is not None and len(value) != length:
            raise self.fail(where, f"field '{key}' must have {length} entries, got {len(value)}")
        out = []
        for k, item in enumerate(value):
            if isinstance(item, bool) or not isinstance(item, (int, float)):
                raise self.fail(where, f"field '{key}'[{k}] must be a number, got {item!r}")
            if not math.isfinite(item):
                raise self.fail(where, f"field '{key}'[{k}] is {item}; give a finite number")
            out.append(float(item))
        return out

    def table(self, doc: dict, key: str, where: str, required: bool = False) -> dict:
        if key not in doc:
            if required:
                raise self.fail(where, f"missing table [{key}]")
            return {}
        value = doc[key]
        if not isinstance(value, dict):
            raise self.fail(where, f"'{key}' must be a table ([{key}])")
        return value


def _transform(reader: _Reader, doc: dict, key: str, length_scale: float, angle_scale: float) -> np.ndarray:
    table = reader.table(doc, key, "file")
    where = f"[{key}]"
    unknown = set(table) - {"xyz", "rpy"}
    if unknown:
        raise reader.fail(where, f"unknown field(s) {', '.join(sorted(unknown))}; allowed: xyz, rpy")
    xyz = np.array(reader.vector(table, "xyz", where, 3, [0.0, 0.0, 0.0])) * length_scale
    if np.max(np.abs(xyz)) > MAX_ABS_LENGTH_M:
        raise reader.fail(where, f"field 'xyz' is beyond ±{MAX_ABS_LENGTH_M:g} m; check [units] length and the value")
    rpy = [snap_quarter_turn(v * angle_scale) for v in reader.vector(table, "rpy", where, 3, [0.0, 0.0, 0.0])]
    out = np.eye(4)
    out[:3, :3] = rpy_matrix(*rpy)
    out[:3, 3] = xyz
    return out


_JOINT_FIELDS = {"name", "type", "a", "d", "alpha", "offset", "qlim", "theta"}


def _robot_place(doc: dict[str, Any], loc: tuple) -> str:
    """How robot-file errors name a place: 'file', '[units]', "joint 2 ('elbow')"."""
    if not loc:
        return "file"
    if loc[0] == "joints" and len(loc) > 1 and isinstance(loc[1], int):
        raw = doc["joints"][loc[1]]
        name = raw.get("name") if isinstance(raw, dict) else None
        valid = isinstance(name, str) and re.fullmatch(IDENTIFIER_PATTERN, name)
        label = f"joint {loc[1] + 1}" + (f" ('{name}')" if valid else "")
        return label + "".join(f".{p}" for p in loc[2:])
    return "[" + ".".join(str(p) for p in loc) + "]"


def validate_robot_document(doc: dict[str, Any], source: str) -> RobotFile:
    """Check a parsed robot file against :class:`RobotFile` (keys, types, finite numbers, name rules)."""
    try:
        return RobotFile.model_validate(doc)
    except ValidationError as exc:
        raise RobotFileError(format_validation_error(exc, source, doc, where=lambda loc: _robot_place(doc, loc))) from None


def parse_robot(text: str, source: str, sha256: str | None = None) -> Robot:
    """Parse robot TOML text. ``source`` names the file in error messages."""
    reader = _Reader(source)
    doc = parse_toml_bounded(text, source, RobotFileError)
    validate_robot_document(doc, source)
    name = reader.string(doc, "name", "file")
    description = reader.string(doc, "description", "file", default="-")
    convention = reader.string(doc, "convention", "file", CONVENTIONS)
    units = reader.table(doc, "units", "file")
    unknown_units = set(units) - {"length", "angle"}
    if unknown_units:
        raise reader.fail("[units]", f"unknown field(s) {', '.join(sorted(unknown_units))}; allowed: length, angle")
    length_unit = reader.string(units, "length", "[units]", tuple(LENGTH_UNITS), default="m")
    angle_unit = reader.string(units, "angle", "[units]", tuple(ANGLE_UNITS), default="rad")
    ls, as_ = LENGTH_UNITS[length_unit], ANGLE_UNITS[angle_unit]

    raw_joints = doc.get("joints")
    if not isinstance(raw_joints, list) or not raw_joints:
        raise reader.fail("file", "missing or empty [[joints]] array; add one [[joints]] table per joint")
    joints: list[Joint] = []
    seen: set[str] = set()
    for i, raw in enumerate(raw_joints):
        label = f"joint {i + 1}"
        if not isinstance(raw, dict):
            raise reader.fail(label, "each [[joints]] entry must be a table")
        jname = reader.string(raw, "name", label, default=f"j{i + 1}")
        where = f"joint {i + 1} ('{jname}')"
        unknown_j = set(raw) - _JOINT_FIELDS
        if unknown_j:
            raise reader.fail(where, f"unknown field(s) {', '.join(sorted(unknown_j))}; allowed: {', '.join(sorted(_JOINT_FIELDS))}")
        if jname in seen:
            raise reader.fail(where, f"duplicate joint name '{jname}'; joint names must be unique")
        seen.add(jname)
        jtype = reader.string(raw, "type", where, JOINT_TYPES)
        q_scale = as_ if jtype == "revolute" else ls
        if jtype == "revolute" and "theta" in raw:
            raise reader.fail(where, "field 'theta' is only for prismatic joints (a revolute joint's angle is q + offset)")
        qlim = reader.vector(raw, "qlim", where, 2)
        lo, hi = qlim[0] * q_scale, qlim[1] * q_scale
        if not lo < hi:
            raise reader.fail(where, f"qlim = {qlim} is empty or reversed; write [lower, upper] with lower < upper")
        q_is_angle = jtype == "revolute"
        for key in ("a", "d", "alpha", "offset", "theta", "qlim"):
            is_angle = key in ("alpha", "theta") or (key in ("offset", "qlim") and q_is_angle)
            scale, bound, unit = (as_, MAX_ABS_ANGLE_RAD, "rad") if is_angle else (ls, MAX_ABS_LENGTH_M, "m")
            values = raw.get(key, 0.0)
            for value in values if isinstance(values, list) else [values]:
                if abs(value * scale) > bound:
                    raise reader.fail(where, f"field '{key}' = {value} is beyond ±{bound:g} {unit}; check the units "
                                             "([units] length/angle) and the value")
        joints.append(Joint(
            name=jname,
            type=jtype,
            a=reader.number(raw, "a", where) * ls,
            d=reader.number(raw, "d", where) * ls,
            alpha=snap_quarter_turn(reader.number(raw, "alpha", where) * as_),
            offset=(snap_quarter_turn if jtype == "revolute" else float)(
                reader.number(raw, "offset", where, default=0.0) * q_scale),
            qlim=(lo, hi),
            theta=snap_quarter_turn(reader.number(raw, "theta", where, default=0.0) * as_),
        ))

    q_scales = np.array([as_ if j.revolute else ls for j in joints])
    configurations: dict[str, np.ndarray] = {}
    for cname, values in reader.table(doc, "configurations", "file").items():
        vec = np.array(reader.vector({cname: values}, cname, "[configurations]", len(joints))) * q_scales
        configurations[cname] = vec

    task_rows_raw = doc.get("task_rows", list(TASK_ROWS))
    if not isinstance(task_rows_raw, list) or not task_rows_raw or any(r not in TASK_ROWS for r in task_rows_raw) \
            or len(set(task_rows_raw)) != len(task_rows_raw):
        raise reader.fail("file", f"task_rows = {task_rows_raw!r} must be a non-empty list of distinct names from {', '.join(TASK_ROWS)}")
    task_rows = tuple(sorted(TASK_ROWS.index(r) for r in task_rows_raw))

    robot = Robot(
        name=name,
        convention=convention,
        joints=tuple(joints),
        base=_transform(reader, doc, "base", ls, as_),
        tool=_transform(reader, doc, "tool", ls, as_),
        configurations=configurations,
        task_rows=task_rows,
        source=source,
        sha256=sha256 or hashlib.sha256(text.encode()).hexdigest(),
        description=description,
        units={"length": length_unit, "angle": angle_unit},
    )
    for cname, vec in configurations.items():
        robot.check_within_limits(vec, f"{source}: [configurations] {cname}")
    return robot


def bundled_robots() -> list[str]:
    return sorted(p.stem for p in BUNDLED_DIR.glob("*.toml"))


def resolve_robot_path(name_or_path: str | Path) -> Path:
    """A bundled robot name or a path to a robot file."""
    candidate = Path(name_or_path)
    try:
        if candidate.suffix == ".toml" or candidate.exists():
            if not candidate.is_file():
                raise RobotFileError(f"{candidate}: robot file not found")
            return candidate
        bundled = BUNDLED_DIR / f"{name_or_path}.toml"
        if re.fullmatch(IDENTIFIER_PATTERN, str(name_or_path)) and bundled.is_file():
            return bundled
    except (OSError, ValueError) as exc:  # a name too long for the file system, a NUL byte, no permission
        raise RobotFileError(f"{str(candidate)[:80]}: not a readable robot file ({exc.strerror or exc}); give a "
                             f"bundled name ({', '.join(bundled_robots())}) or a path") from None
    raise RobotFileError(
        f"unknown robot '{name_or_path}': not a file and not bundled (bundled: {', '.join(bundled_robots())})"
    )


def load_robot(name_or_path: str | Path) -> Robot:
    path = resolve_robot_path(name_or_path)
    try:
        if path.stat().st_size > MAX_INPUT_FILE_BYTES:
            raise RobotFileError(f"{path}: larger than the {MAX_INPUT_FILE_BYTES} bytes a robot file may have")
        data = path.read_bytes()
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RobotFileError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise RobotFileError(f"{path}: cannot read the robot file: {exc.strerror or exc}") from None
    source = path.name if path.parent == BUNDLED_DIR else str(path)
    return parse_robot(text, source, hashlib.sha256(data).hexdigest())


def load_robot_any(robot: Robot | str | Path) -> Robot:
    return robot if isinstance(robot, Robot) else load_robot(robot)


def describe(robot: Robot) -> dict[str, Any]:
    """A plain-data description for display and metadata."""
    return {
        "name": robot.name,
        "convention": robot.convention,
        "dof": robot.n,
        "source": robot.source,
        "sha256": robot.sha256,
    }
