"""Robot description files (TOML, or a URDF alone): loading, validation, conversion to SI.

A robot file holds a serial chain in standard or modified (Craig) DH, or references a URDF.
Every length is converted to metres and every angle to radians on load; the returned
:class:`~armgen.description.model.RobotDescription` is SI-only. Errors name the file, the
joint and the field, and say how to fix them.

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
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from pydantic import ValidationError

from ..errors import RobotFileError, excerpt
from ..schemas import (IDENTIFIER_PATTERN, MAX_INPUT_FILE_BYTES, format_validation_error, parse_toml_bounded,
                       read_input_file)
from .frames import rpy_matrix, snap_quarter_turn
from .model import (JOINT_TYPES, MAX_ABS_ANGLE_RAD, MAX_ABS_LENGTH_M, MAX_REVOLUTE_LIMIT_RAD, MIN_JOINT_RATE,
                    TASK_ROWS, Joint, RobotDescription)
from .schema import RobotFile, UrdfRobotFile
from .urdf import parse_urdf

BUNDLED_DIR = Path(str(resources.files("armgen.data") / "robots"))

LENGTH_UNITS = {"m": 1.0, "mm": 1e-3}
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180.0}
CONVENTIONS = ("standard", "modified")


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
            raise self.fail(where, f"field '{key}' must be a number, got {type(value).__name__} {excerpt(repr(value))}")
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
            raise self.fail(where, f"field '{key}' must be a non-empty string, got {excerpt(repr(value))}")
        if choices is not None and value not in choices:
            raise self.fail(where, f"field '{key}' = {excerpt(repr(value))} is not one of {', '.join(choices)}")
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
                raise self.fail(where, f"field '{key}'[{k}] must be a number, got {excerpt(repr(item))}")
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


_JOINT_FIELDS = {"name", "type", "a", "d", "alpha", "offset", "qlim", "theta", "qdlim", "qddlim"}


def _beyond_turns(angle_unit: str) -> str:
    """Why revolute limits beyond ``MAX_REVOLUTE_LIMIT_RAD`` are refused, and the fix."""
    hint = ('if these are degrees, set [units] angle = "deg"' if angle_unit == "rad"
            else "check the values")
    return (f"reaches beyond ±{MAX_REVOLUTE_LIMIT_RAD:.4g} rad (two turns either side of zero, more than any arm's "
            f"joint turns); the file's angles are in {angle_unit} ([units] angle): {hint}")


def _rate(reader: _Reader, table: dict, key: str, where: str, scale: float, default: float) -> float:
    """A joint's speed (``qdlim``) or acceleration (``qddlim``) limit in SI; ``default`` where
    ``table`` gives none (unlimited, or a URDF's velocity)."""
    if key not in table:
        return default
    value = reader.number(table, key, where) * scale
    if not value >= MIN_JOINT_RATE:
        raise reader.fail(where, f"field '{key}' = {table[key]} is below {MIN_JOINT_RATE:g} SI units (rad or m per "
                                 "s, per s²): a unit slip; check the value and [units]")
    return value


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


def validate_robot_document(doc: dict[str, Any], source: str) -> RobotFile | UrdfRobotFile:
    """Check a parsed robot file against :class:`RobotFile`, or :class:`UrdfRobotFile` when it
    references a URDF (keys, types, finite numbers, name rules)."""
    try:
        return (UrdfRobotFile if "urdf" in doc else RobotFile).model_validate(doc)
    except ValidationError as exc:
        raise RobotFileError(format_validation_error(exc, source, doc, where=lambda loc: _robot_place(doc, loc))) from None


def _task_rows(reader: _Reader, doc: dict) -> tuple[int, ...]:
    task_rows_raw = doc.get("task_rows", list(TASK_ROWS))
    if not isinstance(task_rows_raw, list) or not task_rows_raw or any(r not in TASK_ROWS for r in task_rows_raw) \
            or len(set(task_rows_raw)) != len(task_rows_raw):
        raise reader.fail("file", f"task_rows = {excerpt(repr(task_rows_raw))} must be a non-empty list of distinct names from {', '.join(TASK_ROWS)}")
    return tuple(sorted(TASK_ROWS.index(r) for r in task_rows_raw))


def parse_description(text: str, source: str, sha256: str | None = None,
                      directory: Path | None = None) -> RobotDescription:
    """Parse robot TOML text. ``source`` names the file in error messages; ``directory``
    resolves a relative ``urdf`` reference (default: the current directory)."""
    reader = _Reader(source)
    doc = parse_toml_bounded(text, source, RobotFileError)
    sha256 = sha256 or hashlib.sha256(text.encode()).hexdigest()
    validate_robot_document(doc, source)
    if "urdf" in doc:
        return _parse_urdf_robot_file(reader, doc, sha256, directory or Path("."))
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
        if jtype == "revolute" and max(abs(lo), abs(hi)) > MAX_REVOLUTE_LIMIT_RAD:
            raise reader.fail(where, f"qlim = {qlim} {angle_unit} {_beyond_turns(angle_unit)}")
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
            qdlim=_rate(reader, raw, "qdlim", where, q_scale, math.inf),
            qddlim=_rate(reader, raw, "qddlim", where, q_scale, math.inf),
        ))

    q_scales = np.array([as_ if j.revolute else ls for j in joints])
    configurations: dict[str, np.ndarray] = {}
    for cname, values in reader.table(doc, "configurations", "file").items():
        vec = np.array(reader.vector({cname: values}, cname, "[configurations]", len(joints))) * q_scales
        configurations[cname] = vec

    task_rows = _task_rows(reader, doc)

    robot = RobotDescription(
        name=name,
        convention=convention,
        joints=tuple(joints),
        base=_transform(reader, doc, "base", ls, as_),
        tool=_transform(reader, doc, "tool", ls, as_),
        configurations=configurations,
        task_rows=task_rows,
        source=source,
        sha256=sha256,
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
            if candidate.exists() and not candidate.is_file():
                raise RobotFileError(f"{candidate}: not a regular file (a folder, FIFO or device); give the robot file "
                                     "itself")
            if not candidate.is_file():
                raise RobotFileError(f"{candidate}: robot file not found")
            return candidate
        bundled = BUNDLED_DIR / f"{name_or_path}.toml"
        if re.fullmatch(IDENTIFIER_PATTERN, str(name_or_path)) and bundled.is_file():
            return bundled
    except (OSError, ValueError) as exc:  # a name too long for the file system, a NUL byte, no permission
        raise RobotFileError(f"{excerpt(str(candidate))}: not a readable robot file ({exc.strerror or exc}); give a "
                             f"bundled name ({', '.join(bundled_robots())}) or a path") from None
    raise RobotFileError(
        f"unknown robot '{excerpt(str(name_or_path))}': not a file and not bundled (bundled: {', '.join(bundled_robots())})"
    )


def load_description(name_or_path: str | Path) -> RobotDescription:
    """A robot by bundled name, robot TOML path or URDF path (``.urdf``: see :func:`read_urdf`)."""
    if Path(name_or_path).suffix.lower() == ".urdf":
        return read_urdf(name_or_path)
    path = resolve_robot_path(name_or_path)
    data = _read_bounded(path)
    source = path.name if path.parent == BUNDLED_DIR else str(path)
    return parse_description(_decode(path, data), source, hashlib.sha256(data).hexdigest(), path.parent)


def _read_bounded(path: Path) -> bytes:
    """The bytes of a robot or URDF file, refusing a missing, unreadable, oversized or not regular one."""
    return read_input_file(path, MAX_INPUT_FILE_BYTES, "robot file", RobotFileError)


def _decode(path: Path, data: bytes) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise RobotFileError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None


def read_urdf(path: str | Path, base_link: str | None = None, tip_link: str | None = None) -> RobotDescription:
    """Read the serial chain from ``base_link`` to ``tip_link`` of a URDF file.

    Parameters
    ----------
    path
        The URDF file.
    base_link, tip_link
        The chain's ends; None infers them when the file holds a single chain.

    Returns
    -------
    RobotDescription
        Convention ``"urdf"``, tool = the tip link frame, configurations ``qz`` (zeros,
        when inside the limits) and ``qmid`` (middle of the limits).

    Raises
    ------
    RobotFileError
        The file is missing, malformed or has no usable chain (see :mod:`armgen.description.urdf`).
    """
    path = Path(path)
    data = _read_bounded(path)
    return _urdf_robot(path, data, base_link, tip_link, hashlib.sha256(data).hexdigest())


# -- URDF robots ------------------------------------------------------------------------

# A robot name becomes the default C prefix and output directory: letters, digits, _ and -.
_ROBOT_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,63}")


def _urdf_robot(path: Path, data: bytes, base_link: str | None, tip_link: str | None, sha256: str,
                reader: _Reader | None = None, doc: dict | None = None) -> RobotDescription:
    """A description from URDF bytes; ``doc`` is the referencing robot file's table (None: URDF alone)."""
    chain = parse_urdf(_decode(path, data), str(path), base_link, tip_link)
    doc = doc or {}
    reader = reader or _Reader(str(path))
    name = reader.string(doc, "name", "file", default=chain.robot_name)
    if not _ROBOT_NAME.fullmatch(name):
        raise reader.fail("file", f"robot name {excerpt(repr(name))} must be a letter then letters, digits, _ or - "
                                  "(at most 64); set name = \"…\" in a robot file that references the URDF")
    units = reader.table(doc, "units", "file")
    unknown_units = set(units) - {"length", "angle"}
    if unknown_units:
        raise reader.fail("[units]", f"unknown field(s) {', '.join(sorted(unknown_units))}; allowed: length, angle")
    length_unit = reader.string(units, "length", "[units]", tuple(LENGTH_UNITS), default="m")
    angle_unit = reader.string(units, "angle", "[units]", tuple(ANGLE_UNITS), default="rad")
    ls, as_ = LENGTH_UNITS[length_unit], ANGLE_UNITS[angle_unit]
    q_scales = np.array([ls if j.type == "prismatic" else as_ for j in chain.joints])

    limits = reader.table(doc, "limits", "file")
    names = [j.name for j in chain.joints]
    unknown_limits = set(limits) - set(names)
    if unknown_limits:
        raise reader.fail("[limits]", f"no joint named {', '.join(sorted(unknown_limits))} on the chain "
                                      f"(joints: {', '.join(names)})")
    joints = []
    for j, scale in zip(chain.joints, q_scales):
        # `joint = [lower, upper]` is short for `joint = { qlim = [lower, upper] }`
        entry = limits.get(j.name, {})
        entry, field = ({"qlim": entry}, j.name) if isinstance(entry, list) else (entry, f"{j.name}.qlim")
        revolute = j.type != "prismatic"
        joints.append(Joint(name=j.name, type="revolute" if revolute else "prismatic",
                            a=0.0, d=0.0, alpha=0.0, offset=0.0, origin=j.origin, axis=j.axis,
                            qlim=_limit_override(reader, entry, field, scale, revolute, angle_unit) or j.qlim,
                            qdlim=_rate(reader, entry, "qdlim", f"[limits] {j.name}", scale, j.qdlim),
                            qddlim=_rate(reader, entry, "qddlim", f"[limits] {j.name}", scale, math.inf)))

    qmin, qmax = np.array([j.qlim[0] for j in joints]), np.array([j.qlim[1] for j in joints])
    configurations: dict[str, np.ndarray] = {"qmid": 0.5 * (qmin + qmax)}
    if np.all((qmin <= 0.0) & (qmax >= 0.0)):
        configurations["qz"] = np.zeros(len(joints))
    for cname, values in reader.table(doc, "configurations", "file").items():
        configurations[cname] = np.array(reader.vector({cname: values}, cname, "[configurations]", len(joints))) * q_scales

    robot = RobotDescription(
        name=name,
        convention="urdf",
        joints=tuple(joints),
        base=_transform(reader, doc, "base", ls, as_),
        tool=chain.tip @ _transform(reader, doc, "tool", ls, as_),
        configurations=configurations,
        task_rows=_task_rows(reader, doc),
        source=reader.source,
        sha256=sha256,
        description=reader.string(doc, "description", "file", default=f"URDF {path.name}: {chain.base_link} -> {chain.tip_link}"),
        units={"length": length_unit, "angle": angle_unit},
        urdf={"file": str(path), "base_link": chain.base_link, "tip_link": chain.tip_link,
              "continuous": [j.name for j, joint in zip(chain.joints, joints)
                             if j.type == "continuous" and joint.qlim == j.qlim]},
    )
    for cname, vec in configurations.items():
        robot.check_within_limits(vec, f"{reader.source}: [configurations] {cname}")
    return robot


def _limit_override(reader: _Reader, entry: dict, field: str, scale: float, revolute: bool,
                    angle_unit: str) -> tuple[float, float] | None:
    """A robot file's position limits of a URDF joint (SI), or None where it keeps the URDF's."""
    if "qlim" not in entry:
        return None
    lo, hi = (v * scale for v in reader.vector(entry, "qlim", "[limits]", 2))
    if not lo < hi:
        raise reader.fail("[limits]", f"{field} = {entry['qlim']} is empty or reversed; write [lower, upper]")
    if revolute and max(abs(lo), abs(hi)) > MAX_REVOLUTE_LIMIT_RAD:
        raise reader.fail("[limits]", f"{field} = {entry['qlim']} {angle_unit} {_beyond_turns(angle_unit)}")
    if not revolute and max(abs(lo), abs(hi)) > MAX_ABS_LENGTH_M:
        raise reader.fail("[limits]", f"{field} = {entry['qlim']} is beyond ±{MAX_ABS_LENGTH_M:g} m; check [units] "
                                      "length and the values")
    return (lo, hi)


def _parse_urdf_robot_file(reader: _Reader, doc: dict, sha256: str, directory: Path) -> RobotDescription:
    """A robot file that references a URDF (validated as :class:`UrdfRobotFile`): ``urdf``,
    ``base_link``, ``tip_link`` plus the usual name, units, base, tool, configurations,
    task_rows and a ``[limits]`` table."""
    urdf_path = directory / reader.string(doc, "urdf", "file")
    if not urdf_path.is_file():
        raise reader.fail("urdf", f"URDF file {urdf_path} not found (the path is relative to the robot file)")
    data = _read_bounded(urdf_path)
    base_link = reader.string(doc, "base_link", "file") if "base_link" in doc else None
    tip_link = reader.string(doc, "tip_link", "file") if "tip_link" in doc else None
    combined = hashlib.sha256((sha256 + hashlib.sha256(data).hexdigest()).encode()).hexdigest()
    return _urdf_robot(urdf_path, data, base_link, tip_link, combined, reader, doc)
