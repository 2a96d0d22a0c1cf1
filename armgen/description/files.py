"""Robot description files (TOML, or a URDF alone): loading, validation, conversion to SI.

A robot file holds a serial chain in standard or modified (Craig) DH, or references a URDF.
One path per file: its bytes (read once) -> TOML -> the pydantic model of
:mod:`armgen.description.schema` (types, ranges, defaults, rules across fields) -> one pure
function per file kind, :func:`dh_description` or :func:`urdf_description`, which converts
every length to metres and every angle to radians and cross-checks what needs the units or
the URDF's chain (limits in order and within two turns, speed limits, magnitudes,
configurations' lengths and limits, ``[limits]`` joint names); masses to kg and inertias to
kg·m² (the schema checked that each tensor is some body's, unit-free). The returned
:class:`~armgen.description.model.RobotDescription` is SI-only. Errors name the file, the
joint and the field, and say how to fix them.

Format (validation rules: ``docs/input-files.md``; examples: the bundled files in ``robots/``)::

    name = "planar3"
    convention = "standard"            # or "modified"
    [units]
    length = "m"                       # or "mm"
    angle = "deg"                      # or "rad"
    mass = "kg"                        # or "g"
    [[joints]]
    name = "j1"                        # optional, default "j<i>"
    type = "revolute"                  # or "prismatic"
    a = 1.0
    d = 0.0
    alpha = 0.0
    offset = 0.0                       # optional, default 0
    qlim = [-170, 170]
    mass = 1.2                         # optional, with com and inertia (on every joint or none)
    com = [-0.25, 0, 0]                # in the link frame (DH frame i)
    inertia = [0.001, 0.03, 0.03, 0, 0, 0]  # ixx iyy izz ixy ixz iyz about the COM ([units] mass x length^2)
    taumax = 20                        # optional, N·m
    [tool]                             # optional, likewise [base]
    xyz = [0, 0, 0.1]
    rpy = [0, 0, 0]                    # R = Rz(yaw) Ry(pitch) Rx(roll)
    [configurations]
    q0 = [0, 30, -45]
"""

from __future__ import annotations

import hashlib
from dataclasses import replace
import math
import re
from importlib import resources
from pathlib import Path
from typing import Any, Optional

import numpy as np

from pydantic import ValidationError

from ..errors import RobotFileError, excerpt
from ..schemas import (IDENTIFIER_PATTERN, MAX_INPUT_FILE_BYTES, format_validation_error, parse_toml_bounded,
                       read_input_file)
from .collision import MAX_CAPSULES, CollisionCapsule, CollisionModel, ObstacleSlots
from .frames import rpy_matrix, snap_quarter_turn
from .inertia import inertia_problem
from .model import (MAX_ABS_ANGLE_RAD, MAX_ABS_LENGTH_M, MAX_INERTIA_KGM2, MAX_MASS_KG, MAX_REVOLUTE_LIMIT_RAD,
                    MAX_TORQUE, MIN_JOINT_RATE, MIN_MASS_KG, TASK_ROWS, Inertial, Joint, RobotDescription)
from .schema import CollisionEntry, JointEntry, JointLimits, RobotFile, Transform, UrdfRobotFile
from .urdf import UrdfChain, UrdfJoint, parse_urdf

BUNDLED_DIR = Path(str(resources.files("armgen.data") / "robots"))

LENGTH_UNITS = {"m": 1.0, "mm": 1e-3}
ANGLE_UNITS = {"rad": 1.0, "deg": math.pi / 180.0}
MASS_UNITS = {"kg": 1.0, "g": 1e-3}

# A robot name becomes the default C prefix and output directory: letters, digits, _ and -.
_ROBOT_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_-]{0,63}")


def _fail(source: str, where: str, message: str) -> RobotFileError:
    return RobotFileError(f"{source}: {where}: {message}")


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
    if loc[0] == "collision" and len(loc) > 1 and isinstance(loc[1], int):  # numbered as armgen show lists them
        return f"[[collision]] capsule {loc[1]}" + "".join(f".{p}" for p in loc[2:])
    return "[" + ".".join(str(p) for p in loc) + "]"


def validate_robot_document(doc: dict[str, Any], source: str) -> RobotFile | UrdfRobotFile:
    """The model of a parsed robot file: :class:`RobotFile`, or :class:`UrdfRobotFile` when it
    references a URDF (keys, types, finite numbers, name rules, rules across fields)."""
    try:
        return (UrdfRobotFile if "urdf" in doc else RobotFile).model_validate(doc)
    except ValidationError as exc:
        raise RobotFileError(format_validation_error(exc, source, doc, where=lambda loc: _robot_place(doc, loc))) from None


# -- conversion to SI and cross-checks ----------------------------------------------------


def _beyond_turns(angle_unit: str) -> str:
    """Why revolute limits beyond ``MAX_REVOLUTE_LIMIT_RAD`` are refused, and the fix."""
    hint = ('if these are degrees, set [units] angle = "deg"' if angle_unit == "rad"
            else "check the values")
    return (f"reaches beyond ±{MAX_REVOLUTE_LIMIT_RAD:.4g} rad (two turns either side of zero, more than any arm's "
            f"joint turns); the file's angles are in {angle_unit} ([units] angle): {hint}")


def _rate(value: Optional[float], key: str, where: str, scale: float, default: float, source: str) -> float:
    """A joint's speed (``qdlim``) or acceleration (``qddlim``) limit in SI; ``default`` where
    the file gives none (unlimited, or a URDF's velocity)."""
    if value is None:
        return default
    si = value * scale
    if not si >= MIN_JOINT_RATE:
        raise _fail(source, where, f"field '{key}' = {value} is below {MIN_JOINT_RATE:g} SI units (rad or m per s, "
                                   "per s²): a unit slip; check the value and [units]")
    return si


def _torque(value: Optional[float], where: str, default: float, source: str) -> float:
    """A joint's torque (force) limit ``taumax`` in N·m (N), always SI; ``default`` where the
    file gives none (unlimited, or a URDF's effort)."""
    if value is None:
        return default
    if value > MAX_TORQUE:
        raise _fail(source, where, f"field 'taumax' = {value} is beyond {MAX_TORQUE:g} N·m (N for a prismatic joint), "
                                   "more than any drive gives; taumax is in N·m whatever [units] says: check the value")
    return value


def _inertial(entry: JointEntry, where: str, length: float, mass_unit: str, source: str) -> Inertial | None:
    """A joint's ``mass``, ``com``, ``inertia`` and ``motor_inertia`` in SI (kg, m, kg·m²),
    within the physical bounds; None where the file gives none (the schema checked that
    they come together and that the tensor is some body's)."""
    if not entry.has_inertial:
        return None
    mass = MASS_UNITS[mass_unit]
    units = f"[units] mass = \"{mass_unit}\" and length"
    si_mass = entry.mass * mass
    if not MIN_MASS_KG <= si_mass <= MAX_MASS_KG:
        raise _fail(source, where, f"field 'mass' = {entry.mass} {mass_unit} is outside [{MIN_MASS_KG:g}, "
                                   f"{MAX_MASS_KG:g}] kg, no arm link's mass: check the value and {units}")
    com = tuple(v * length for v in entry.com)
    if max(abs(v) for v in com) > MAX_ABS_LENGTH_M:
        raise _fail(source, where, f"field 'com' = {entry.com} is beyond ±{MAX_ABS_LENGTH_M:g} m; check the value and "
                                   f"{units}")
    inertia_scale = mass * length ** 2
    inertia = tuple(v * inertia_scale for v in entry.inertia)
    motor_scale = inertia_scale if entry.type == "revolute" else mass
    motor = (entry.motor_inertia or 0.0) * motor_scale
    for key, values in (("inertia", inertia), ("motor_inertia", (motor,))):
        if max(abs(v) for v in values) > MAX_INERTIA_KGM2:
            raise _fail(source, where, f"field '{key}' is beyond {MAX_INERTIA_KGM2:g} kg·m² (10 t at 1 m); its unit "
                                       f"is mass × length² ({units}): check the values")
    if inertia_problem(inertia):  # the file's tensor is some body's: only an underflow to 0 in SI breaks it
        raise _fail(source, where, f"field 'inertia' = {entry.inertia} is too small to hold in kg·m² ({inertia}); its "
                                   f"unit is mass × length² ({units}): check the values")
    return Inertial(mass=si_mass, com=com, inertia=inertia, motor_inertia=motor)


def _transform(table: Transform, key: str, length_scale: float, angle_scale: float, source: str) -> np.ndarray:
    """The ``[base]`` or ``[tool]`` table as a 4×4 transform (m)."""
    xyz = np.array(table.xyz) * length_scale
    if np.max(np.abs(xyz)) > MAX_ABS_LENGTH_M:
        raise _fail(source, f"[{key}]", f"field 'xyz' is beyond ±{MAX_ABS_LENGTH_M:g} m; check [units] length and the "
                                        "value")
    out = np.eye(4)
    out[:3, :3] = rpy_matrix(*(snap_quarter_turn(v * angle_scale) for v in table.rpy))
    out[:3, 3] = xyz
    return out


def _capsule(entry: CollisionEntry, index: int, frame: int, pose: np.ndarray, link: str, length: float,
             source: str) -> CollisionCapsule:
    """A ``[[collision]]`` entry in SI, its ends moved by ``pose`` (a URDF link's pose in its
    joint's link frame; the identity for a frame index)."""
    where = f"[[collision]] capsule {index}"
    values = [*entry.a, *entry.end, entry.radius]
    if max(abs(v) * length for v in values) > MAX_ABS_LENGTH_M:
        raise _fail(source, where, f"a, b or radius is beyond ±{MAX_ABS_LENGTH_M:g} m; check [units] length and the values")
    a, b = (pose[:3, :3] @ (np.asarray(v, dtype=float) * length) + pose[:3, 3] for v in (entry.a, entry.end))
    return CollisionCapsule(frame=frame, a=tuple(float(v) for v in a), b=tuple(float(v) for v in b),
                            radius=entry.radius * length, link=link)


def _collision_model(model: RobotFile | UrdfRobotFile, capsules: list[CollisionCapsule], unusable: str,
                     source: str) -> CollisionModel:
    """The capsules with ``[collision_check]``: ignored pairs (within the capsules, in order) and slots."""
    for k, pair in enumerate(model.collision_check.ignore):
        if max(pair) >= len(capsules):
            raise _fail(source, f"[collision_check] ignore {k}", f"pair {pair} names capsule {max(pair)}, but the robot "
                                                                 f"has {len(capsules)} capsules (armgen show lists them)")
    slots = model.collision_check.max_obstacles
    collision = CollisionModel(capsules=tuple(capsules), ignore=tuple(sorted({tuple(sorted(p)) for p in
                                                                              model.collision_check.ignore})),
                               slots=ObstacleSlots(slots.sphere, slots.capsule, slots.box, slots.plane),
                               unusable=unusable)
    if capsules and not unusable and not collision.pair_labels():  # the functions would have an empty output
        collision = replace(collision, unusable="its capsules give no pair to check (none two frames apart or more, "
                                                "and no obstacle slot for a moving capsule)")
    return collision


def _configurations(given: dict[str, list[float]], q_scales: np.ndarray, source: str) -> dict[str, np.ndarray]:
    """The ``[configurations]`` table in SI, one value per joint."""
    out = {}
    for name, values in given.items():
        if len(values) != len(q_scales):
            raise _fail(source, "[configurations]",
                        f"field '{name}' must have {len(q_scales)} entries, got {len(values)}")
        out[name] = np.array(values) * q_scales
    return out


def _dh_joint(entry: JointEntry, name: str, where: str, length: float, angle: float, units: dict[str, str],
              source: str) -> Joint:
    """One ``[[joints]]`` entry in SI, its limits in order and every value within the physical bounds."""
    revolute = entry.type == "revolute"
    q_scale = angle if revolute else length
    lo, hi = entry.qlim[0] * q_scale, entry.qlim[1] * q_scale
    if not lo < hi:
        raise _fail(source, where, f"qlim = {entry.qlim} is empty or reversed; write [lower, upper] with lower < upper")
    if revolute and max(abs(lo), abs(hi)) > MAX_REVOLUTE_LIMIT_RAD:
        raise _fail(source, where, f"qlim = {entry.qlim} {units['angle']} {_beyond_turns(units['angle'])}")
    for key in ("a", "d", "alpha", "offset", "theta", "qlim"):
        is_angle = key in ("alpha", "theta") or (key in ("offset", "qlim") and revolute)
        scale, bound, unit = (angle, MAX_ABS_ANGLE_RAD, "rad") if is_angle else (length, MAX_ABS_LENGTH_M, "m")
        values = getattr(entry, key)
        for value in values if isinstance(values, list) else [values]:
            if abs(value * scale) > bound:
                raise _fail(source, where, f"field '{key}' = {value} is beyond ±{bound:g} {unit}; check the units "
                                           "([units] length/angle) and the value")
    return Joint(
        name=name,
        type=entry.type,
        a=entry.a * length,
        d=entry.d * length,
        alpha=snap_quarter_turn(entry.alpha * angle),
        offset=(snap_quarter_turn if revolute else float)(entry.offset * q_scale),
        qlim=(lo, hi),
        theta=snap_quarter_turn(entry.theta * angle),
        qdlim=_rate(entry.qdlim, "qdlim", where, q_scale, math.inf, source),
        qddlim=_rate(entry.qddlim, "qddlim", where, q_scale, math.inf, source),
        inertial=_inertial(entry, where, length, units["mass"], source),
        taumax=_torque(entry.taumax, where, math.inf, source),
    )


def dh_description(model: RobotFile, source: str, sha256: str) -> RobotDescription:
    """A DH robot file's model in SI, cross-checked (see :func:`_dh_joint`; configurations of
    one value per joint, within the limits). ``source`` names the file in errors."""
    length, angle = LENGTH_UNITS[model.units.length], ANGLE_UNITS[model.units.angle]
    units = {"length": model.units.length, "angle": model.units.angle, "mass": model.units.mass}
    joints = tuple(_dh_joint(entry, name, f"joint {i + 1} ('{name}')", length, angle, units, source)
                   for i, (entry, name) in enumerate(zip(model.joints, model.joint_names)))
    q_scales = np.array([angle if j.revolute else length for j in joints])
    configurations = _configurations(model.configurations, q_scales, source)
    robot = RobotDescription(
        name=model.name,
        convention=model.convention,
        joints=joints,
        base=_transform(model.base, "base", length, angle, source),
        tool=_transform(model.tool, "tool", length, angle, source),
        configurations=configurations,
        task_rows=tuple(sorted(TASK_ROWS.index(r) for r in model.task_rows)),
        source=source,
        sha256=sha256,
        description=model.description,
        units={"length": model.units.length, "angle": model.units.angle, "mass": model.units.mass},
        gravity=tuple(model.gravity),
        collision=_collision_model(model, [_capsule(entry, k, entry.link, np.eye(4), f"frame {entry.link}", length,
                                                    source) for k, entry in enumerate(model.collision)], "", source),
    )
    for name, q in configurations.items():
        robot.check_within_limits(q, f"{source}: [configurations] {name}")
    return robot


def _limit_override(qlim: list[float], field: str, scale: float, revolute: bool, angle_unit: str,
                    source: str) -> tuple[float, float]:
    """A robot file's position limits of a URDF joint in SI, in order and within the bounds."""
    lo, hi = qlim[0] * scale, qlim[1] * scale
    if not lo < hi:
        raise _fail(source, "[limits]", f"{field} = {qlim} is empty or reversed; write [lower, upper]")
    if revolute and max(abs(lo), abs(hi)) > MAX_REVOLUTE_LIMIT_RAD:
        raise _fail(source, "[limits]", f"{field} = {qlim} {angle_unit} {_beyond_turns(angle_unit)}")
    if not revolute and max(abs(lo), abs(hi)) > MAX_ABS_LENGTH_M:
        raise _fail(source, "[limits]", f"{field} = {qlim} is beyond ±{MAX_ABS_LENGTH_M:g} m; check [units] length "
                                        "and the values")
    return (lo, hi)


def _urdf_joint(joint: UrdfJoint, entry: list[float] | JointLimits | None, scale: float, angle_unit: str,
                source: str) -> Joint:
    """A URDF chain's joint with the robot file's ``[limits]`` entry applied (SI)."""
    # `joint = [lower, upper]` is short for `joint = { qlim = [lower, upper] }`
    limits, field = (JointLimits(qlim=entry), joint.name) if isinstance(entry, list) else \
        (entry or JointLimits(), f"{joint.name}.qlim")
    revolute = joint.type != "prismatic"
    qlim = joint.qlim if limits.qlim is None else _limit_override(limits.qlim, field, scale, revolute, angle_unit,
                                                                  source)
    where = f"[limits] {joint.name}"
    return Joint(name=joint.name, type="revolute" if revolute else "prismatic",
                 a=0.0, d=0.0, alpha=0.0, offset=0.0, origin=joint.origin, axis=joint.axis, qlim=qlim,
                 qdlim=_rate(limits.qdlim, "qdlim", where, scale, joint.qdlim, source),
                 qddlim=_rate(limits.qddlim, "qddlim", where, scale, math.inf, source),
                 inertial=joint.inertial, taumax=_torque(limits.taumax, where, joint.taumax, source))


def urdf_description(model: UrdfRobotFile, chain: UrdfChain, source: str, sha256: str,
                     urdf_file: Path) -> RobotDescription:
    """A URDF's chain with what its robot file adds (name, units, ``[limits]``, base, tool,
    configurations, task rows), in SI and cross-checked. ``source`` names the robot file in
    errors (the URDF itself for a URDF read alone); configurations ``qmid`` (the middle of the
    limits) and ``qz`` (zeros, when inside the limits) come first."""
    name = model.name or chain.robot_name
    if not _ROBOT_NAME.fullmatch(name):
        raise _fail(source, "file", f"robot name {excerpt(repr(name))} must be a letter then letters, digits, _ or - "
                                    "(at most 64); set name = \"…\" in a robot file that references the URDF")
    length, angle = LENGTH_UNITS[model.units.length], ANGLE_UNITS[model.units.angle]
    names = [j.name for j in chain.joints]
    unknown = set(model.limits) - set(names)
    if unknown:
        raise _fail(source, "[limits]", f"no joint named {', '.join(sorted(unknown))} on the chain "
                                        f"(joints: {', '.join(names)})")
    q_scales = np.array([length if j.type == "prismatic" else angle for j in chain.joints])
    joints = tuple(_urdf_joint(j, model.limits.get(j.name), scale, model.units.angle, source)
                   for j, scale in zip(chain.joints, q_scales))
    qmin, qmax = np.array([j.qlim[0] for j in joints]), np.array([j.qlim[1] for j in joints])
    configurations: dict[str, np.ndarray] = {"qmid": 0.5 * (qmin + qmax)}
    if np.all((qmin <= 0.0) & (qmax >= 0.0)):
        configurations["qz"] = np.zeros(len(joints))
    configurations.update(_configurations(model.configurations, q_scales, source))
    robot = RobotDescription(
        name=name,
        convention="urdf",
        joints=joints,
        base=_transform(model.base, "base", length, angle, source),
        tool=chain.tip @ _transform(model.tool, "tool", length, angle, source),
        configurations=configurations,
        task_rows=tuple(sorted(TASK_ROWS.index(r) for r in model.task_rows)),
        source=source,
        sha256=sha256,
        description=(f"URDF {urdf_file.name}: {chain.base_link} -> {chain.tip_link}" if model.description is None
                     else model.description),
        units={"length": model.units.length, "angle": model.units.angle, "mass": model.units.mass},
        urdf={"file": str(urdf_file), "base_link": chain.base_link, "tip_link": chain.tip_link,
              "continuous": [j.name for j, joint in zip(chain.joints, joints)
                             if j.type == "continuous" and joint.qlim == j.qlim]}
        | ({"no_dynamics": chain.no_dynamics} if chain.no_dynamics else {}),
        gravity=tuple(model.gravity),
        collision=_urdf_collision(model, chain, length, source),
    )
    for cname, q in configurations.items():
        robot.check_within_limits(q, f"{source}: [configurations] {cname}")
    return robot


def _urdf_collision(model: UrdfRobotFile, chain: UrdfChain, length: float, source: str) -> CollisionModel:
    """The robot file's ``[[collision]]`` capsules (a frame index, or a URDF link whose own
    collision shapes they replace), then the URDF's capsules of the other links; a mesh left on
    a link makes the geometry unusable, with the link and the fix."""
    capsules, replaced = [], set()
    for k, entry in enumerate(model.collision):
        if isinstance(entry.link, int):
            if entry.link > len(chain.joints):
                raise _fail(source, f"[[collision]] capsule {k}", f"link = {entry.link} is beyond the flange: the chain "
                                                                  f"has {len(chain.joints)} moving joints")
            capsules.append(_capsule(entry, k, entry.link, np.eye(4), f"frame {entry.link}", length, source))
            continue
        if entry.link not in chain.link_frames:
            raise _fail(source, f"[[collision]] capsule {k}", f"link = {excerpt(repr(entry.link))} is not a link of the "
                                                              f"chain (links: {', '.join(chain.link_frames)})")
        frame, pose = chain.link_frames[entry.link]
        capsules.append(_capsule(entry, k, frame, pose, entry.link, length, source))
        replaced.add(entry.link)
    unusable = ""
    for shape in chain.collision:
        if shape.link in replaced:
            continue
        if shape.capsule is None:
            unusable = unusable or (f"link '{shape.link}' has a <mesh> collision shape, which armgen does not take; give "
                                    f"its capsules in a robot file that references the URDF ([[collision]] link = "
                                    f"\"{shape.link}\", a = [...], b = [...], radius = ...: they replace the link's URDF "
                                    "shapes, docs/collision.md)")
            continue
        capsules.append(shape.capsule)
    if len(capsules) > MAX_CAPSULES and not unusable:  # the robot still loads, without a collision model
        unusable = (f"the URDF's and the robot file's shapes make {len(capsules)} capsules, more than {MAX_CAPSULES}; "
                    "replace some links' shapes by fewer capsules in a robot file that references the URDF "
                    "([[collision]] link = \"<link>\": they replace the link's URDF shapes, docs/collision.md)")
    return _collision_model(model, capsules, unusable, source)


# -- reading files ------------------------------------------------------------------------


def _parse(data: bytes | str, source: str, sha256: str, directory: Path) -> RobotDescription:
    """A robot file's bytes (or text) to its description; a URDF it references is read once."""
    model = validate_robot_document(parse_toml_bounded(data, source, RobotFileError), source)
    if isinstance(model, RobotFile):
        return dh_description(model, source, sha256)
    urdf_path = directory / model.urdf
    if not urdf_path.is_file():
        raise _fail(source, "urdf", f"URDF file {urdf_path} not found (the path is relative to the robot file)")
    urdf_data = _read_bounded(urdf_path)
    chain = parse_urdf(_decode(urdf_path, urdf_data), str(urdf_path), model.base_link, model.tip_link)
    combined = hashlib.sha256((sha256 + hashlib.sha256(urdf_data).hexdigest()).encode()).hexdigest()
    return urdf_description(model, chain, source, combined, urdf_path)


def parse_description(text: str, source: str, sha256: str | None = None,
                      directory: Path | None = None) -> RobotDescription:
    """Parse robot TOML text. ``source`` names the file in error messages; ``directory``
    resolves a relative ``urdf`` reference (default: the current directory)."""
    return _parse(text, source, sha256 or hashlib.sha256(text.encode()).hexdigest(), directory or Path("."))


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
    return replace(_parse(data, source, hashlib.sha256(data).hexdigest(), path.parent), path=str(path.resolve()))


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
    chain = parse_urdf(_decode(path, data), str(path), base_link, tip_link)
    # a URDF read alone is a robot file that only names it
    alone = UrdfRobotFile.model_construct(urdf=str(path), base_link=base_link, tip_link=tip_link)
    return replace(urdf_description(alone, chain, str(path), hashlib.sha256(data).hexdigest(), path),
                   path=str(path.resolve()))
