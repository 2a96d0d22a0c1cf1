"""The robot file's schema (pydantic), the parser of robot files: keys, types, finiteness,
sizes, defaults, name rules and the rules across fields that need no units (unique joint
names, ``theta`` on prismatic joints only, distinct task rows), in the file's own units.
:mod:`armgen.description.files` validates a file into these models, then one function per
file kind converts the model to SI and cross-checks what needs the units or the URDF's chain;
``armgen schema robot`` prints the schema as JSON Schema for editors."""

from __future__ import annotations

from typing import Annotated, Literal, Optional, Union

from pydantic import Discriminator, Field, StringConstraints, Tag, model_validator

from ..errors import excerpt
from ..schemas import IDENTIFIER_PATTERN, StrictModel, rule_error
from .collision import MAX_CAPSULES, MAX_OBSTACLE_SLOTS, ObstacleSlots
from .inertia import inertia_problem
from .model import DEFAULT_GRAVITY, TASK_ROWS

# Degrees of freedom a robot file may declare: the bundled snake has 25; the generated C
# stores n×n matrices on the stack of a microcontroller, so 64 is far beyond any use.
MAX_DOF = 64
# Named configurations per robot file.
MAX_CONFIGURATIONS = 256
# Free text (description) is only displayed and stored in manifests.
MAX_DESCRIPTION_CHARS = 500

Identifier = Annotated[str, StringConstraints(pattern=IDENTIFIER_PATTERN)]
Number = float
Vector3 = Annotated[list[Number], Field(min_length=3, max_length=3)]
TaskRow = Literal["vx", "vy", "vz", "wx", "wy", "wz"]
# The largest gravity a robot file may give (m/s²): 10 g, beyond any test rig; gravity written
# in mm/s² (9810) is the slip this catches.
MAX_GRAVITY = 100.0
GravityComponent = Annotated[Number, Field(ge=-MAX_GRAVITY, le=MAX_GRAVITY)]
Inertia = Annotated[list[Number], Field(min_length=6, max_length=6, description=(
    "[ixx, iyy, izz, ixy, ixz, iyz] about the centre of mass, link-frame axes, mass unit x length unit^2; "
    "ixy = -integral(x y dm) (the tensor entry, as in URDF)"))]
Torque = Annotated[Number, Field(gt=0, description="torque limit, N m (N for a prismatic joint); absent = none")]


class Units(StrictModel):
    length: Literal["m", "mm"] = Field("m", description="unit of a, d, xyz and prismatic values")
    angle: Literal["rad", "deg"] = Field("rad", description="unit of alpha, offset, theta, rpy and revolute values")
    mass: Literal["kg", "g"] = Field("kg", description="unit of mass, inertia (mass x length^2) and motor_inertia")


class JointEntry(StrictModel):
    name: Optional[Identifier] = Field(None, description="joint name (default j<i>)")
    type: Literal["revolute", "prismatic"]
    a: Number
    d: Number
    alpha: Number
    offset: Number = 0.0
    qlim: Annotated[list[Number], Field(min_length=2, max_length=2, description="[lower, upper]")]
    theta: Number = Field(0.0, description="fixed joint angle of a prismatic joint")
    qdlim: Optional[Annotated[Number, Field(gt=0)]] = Field(
        None, description="velocity limit (angle or length unit per s); absent = unlimited")
    qddlim: Optional[Annotated[Number, Field(gt=0)]] = Field(
        None, description="acceleration limit (angle or length unit per s^2); absent = unlimited")
    mass: Optional[Annotated[Number, Field(gt=0)]] = Field(
        None, description="mass of the link this joint moves ([units] mass); with com and inertia")
    com: Optional[Vector3] = Field(None, description="that link's centre of mass in the joint's link frame (length unit)")
    inertia: Optional[Inertia] = None
    motor_inertia: Optional[Annotated[Number, Field(ge=0)]] = Field(
        None, description="reflected rotor inertia added to the mass matrix's diagonal (mass x length^2; mass unit "
                          "for a prismatic joint); default 0")
    taumax: Optional[Torque] = None

    @model_validator(mode="after")
    def _theta_of_prismatic_only(self) -> JointEntry:
        if self.type == "revolute" and "theta" in self.model_fields_set:
            raise rule_error("field 'theta' is only for prismatic joints (a revolute joint's angle is q + offset)")
        return self

    @property
    def has_inertial(self) -> bool:
        return self.mass is not None

    @model_validator(mode="after")
    def _inertial_complete_and_physical(self) -> JointEntry:
        given = [key for key in ("mass", "com", "inertia") if getattr(self, key) is not None]
        if given and len(given) < 3:
            missing = [key for key in ("mass", "com", "inertia") if key not in given]
            raise rule_error(f"field '{given[0]}' needs {' and '.join(repr(k) for k in missing)} too: a link's "
                             "inertial is its mass, centre of mass (com) and inertia together; give all three or none")
        if self.motor_inertia is not None and not given:
            raise rule_error("field 'motor_inertia' needs the link's mass, com and inertia: give them too, or remove it")
        problem = inertia_problem(self.inertia) if self.inertia is not None else None
        if problem:
            raise rule_error(f"field 'inertia' = {excerpt(repr(self.inertia))} {problem}; give the link's tensor about "
                             "its centre of mass, [ixx, iyy, izz, ixy, ixz, iyz] with ixy = -∫xy dm (the tensor "
                             "entry, as in URDF; a CAD tool's product of inertia has the opposite sign)")
        return self


class Transform(StrictModel):
    xyz: Vector3 = Field(default_factory=lambda: [0.0, 0.0, 0.0])
    rpy: Vector3 = Field(default_factory=lambda: [0.0, 0.0, 0.0], description="R = Rz(yaw) Ry(pitch) Rx(roll)")


LinkName = Annotated[str, StringConstraints(min_length=1, max_length=256)]
Length = Annotated[Number, Field(ge=0)]


class CollisionEntry(StrictModel):
    """One ``[[collision]]`` capsule, in the file's length unit."""

    link: Union[Annotated[int, Field(ge=0, le=MAX_DOF)], LinkName] = Field(
        description="frame index (0 = base, i = joint i's link frame, n = flange), or a URDF link name (a robot "
                    "file that references a URDF: the segment is then in that link's frame)")
    a: Vector3 = Field(description="one end of the segment, in that frame (length unit)")
    b: Optional[Vector3] = Field(None, description="the other end (default a: a sphere)")
    radius: Length = Field(description="the capsule's radius (length unit)")

    @property
    def end(self) -> list[float]:
        return self.a if self.b is None else self.b


SlotCount = Annotated[int, Field(ge=0, le=MAX_OBSTACLE_SLOTS)]


class ObstacleSlotCounts(StrictModel):
    """How many obstacles of each kind the generated collision functions take (fixed sizes)."""

    sphere: SlotCount = ObstacleSlots.sphere
    capsule: SlotCount = ObstacleSlots.capsule
    box: SlotCount = ObstacleSlots.box
    plane: SlotCount = ObstacleSlots.plane


CapsulePair = Annotated[list[Annotated[int, Field(ge=0)]], Field(min_length=2, max_length=2)]


class CollisionCheck(StrictModel):
    """``[collision_check]``: the pairs of capsules never checked (besides adjacent links) and
    the obstacle slots."""

    ignore: Annotated[list[CapsulePair], Field(max_length=MAX_CAPSULES * MAX_CAPSULES)] = Field(
        default_factory=list, description="pairs [i, j] of capsule indices (from 0, in the order armgen show lists "
                                          "them) never checked; pairs on the same or adjacent frames never are")
    max_obstacles: ObstacleSlotCounts = Field(default_factory=ObstacleSlotCounts)

    @model_validator(mode="after")
    def _distinct_pairs(self) -> CollisionCheck:
        for k, (i, j) in enumerate(self.ignore):
            if i == j:
                raise rule_error(f"pair [{i}, {j}] names one capsule twice; give two different capsule indices",
                                 at=("ignore", k))
        return self


class _RobotFileCommon(StrictModel):
    """The fields every robot file has, whatever describes its chain."""

    description: Annotated[str, StringConstraints(min_length=1, max_length=MAX_DESCRIPTION_CHARS)] = "-"
    units: Units = Field(default_factory=Units)
    base: Transform = Field(default_factory=Transform)
    tool: Transform = Field(default_factory=Transform)
    configurations: Annotated[dict[Identifier, list[Number]], Field(max_length=MAX_CONFIGURATIONS)] = Field(
        default_factory=dict)
    task_rows: Annotated[list[TaskRow], Field(min_length=1, max_length=6, json_schema_extra={"uniqueItems": True})] = \
        Field(default_factory=lambda: list(TASK_ROWS))
    gravity: Annotated[list[GravityComponent], Field(min_length=3, max_length=3)] = Field(
        default_factory=lambda: list(DEFAULT_GRAVITY), description="gravity vector in the base frame, m/s^2 (whatever "
                                                                   "[units] length is)")
    collision: Annotated[list[CollisionEntry], Field(max_length=MAX_CAPSULES)] = Field(
        default_factory=list, description="the arm's capsules (docs/collision.md)")
    collision_check: CollisionCheck = Field(default_factory=CollisionCheck)

    @model_validator(mode="after")
    def _distinct_task_rows(self) -> _RobotFileCommon:
        if len(set(self.task_rows)) != len(self.task_rows):
            raise rule_error(f"task_rows = {excerpt(repr(self.task_rows))} must be a non-empty list of distinct names "
                             f"from {', '.join(TASK_ROWS)}")
        return self


class RobotFile(_RobotFileCommon):
    """A serial chain in standard or modified (Craig) DH."""

    name: Identifier
    convention: Literal["standard", "modified"]
    joints: Annotated[list[JointEntry], Field(min_length=1, max_length=MAX_DOF)]

    @property
    def joint_names(self) -> list[str]:
        """Each joint's name, ``j<i>`` (from 1) where the file gives none."""
        return [joint.name or f"j{i + 1}" for i, joint in enumerate(self.joints)]

    @model_validator(mode="after")
    def _unique_joint_names(self) -> RobotFile:
        seen: set[str] = set()
        for i, name in enumerate(self.joint_names):
            if name in seen:
                default = "" if self.joints[i].name else f" (the default name of joint {i + 1}, which has none)"
                raise rule_error(f"duplicate joint name '{name}'{default}; joint names must be unique", at=("joints", i))
            seen.add(name)
        return self

    @model_validator(mode="after")
    def _capsules_on_frames(self) -> RobotFile:
        for k, entry in enumerate(self.collision):
            if isinstance(entry.link, str):
                raise rule_error(f"link = {excerpt(repr(entry.link))} names a URDF link, but this robot file is DH: give "
                                 f"the frame index (0 = base, 1 … {len(self.joints)} = joint i's link frame)",
                                 at=("collision", k, "link"))
            if entry.link > len(self.joints):
                raise rule_error(f"link = {entry.link} is beyond the flange: the robot has {len(self.joints)} joints, so "
                                 f"the frames are 0 (base) … {len(self.joints)}", at=("collision", k, "link"))
        for k, pair in enumerate(self.collision_check.ignore):
            if max(pair) >= len(self.collision):
                raise rule_error(f"pair {pair} names capsule {max(pair)}, but the file has {len(self.collision)} "
                                 f"[[collision]] capsules (indices 0 … {len(self.collision) - 1})",
                                 at=("collision_check", "ignore", k))
        return self

    @model_validator(mode="after")
    def _inertials_on_every_joint_or_none(self) -> RobotFile:
        with_inertial = [joint.has_inertial for joint in self.joints]
        if any(with_inertial) and not all(with_inertial):
            first = with_inertial.index(False)
            given = ", ".join(name for name, has in zip(self.joint_names, with_inertial) if has)
            raise rule_error(f"no mass, com and inertia, while joint(s) {given} have them: the dynamics need every "
                             "link's inertial; give this joint's too, or remove them all", at=("joints", first))
        return self


Limits = Annotated[list[Number], Field(min_length=2, max_length=2, description="[lower, upper]")]
Rate = Annotated[Number, Field(gt=0)]


class JointLimits(StrictModel):
    """One joint's limits set by a robot file that references a URDF, in the file's units:
    what the URDF gives is replaced, what it cannot hold (accelerations) is added."""

    qlim: Optional[Limits] = Field(None, description="[lower, upper], replacing the URDF's <limit lower upper>")
    qdlim: Optional[Rate] = Field(
        None, description="velocity limit (angle or length unit per s), replacing the URDF's <limit velocity>")
    qddlim: Optional[Rate] = Field(
        None, description="acceleration limit (angle or length unit per s^2); a URDF has none")
    taumax: Optional[Torque] = Field(None, description="torque limit (N m; N for a prismatic joint), replacing the "
                                                       "URDF's <limit effort>")


# A [limits] entry: `joint = [lower, upper]` (position limits only) or a table; chosen by the
# value's type, so an error names the problem of that form, not of the other.
LimitsEntry = Annotated[Union[Annotated[Limits, Tag("list")], Annotated[JointLimits, Tag("table")]],
                        Discriminator(lambda value: "list" if isinstance(value, list) else "table")]


class UrdfRobotFile(_RobotFileCommon):
    """A robot file that takes its chain from a URDF: the chain from ``base_link`` to
    ``tip_link`` (defaults: the URDF's root and its single leaf), with the usual name, units,
    base/tool transforms, named configurations, task rows and optional per-joint limits
    (position, velocity, acceleration)."""

    urdf: Annotated[str, StringConstraints(min_length=1, max_length=4096)] = Field(
        description="path of the URDF file, relative to this robot file")
    name: Optional[Identifier] = Field(None, description="robot name (default: the URDF's robot name)")
    description: Optional[Annotated[str, StringConstraints(min_length=1, max_length=MAX_DESCRIPTION_CHARS)]] = Field(
        None, description="one line of text (default: 'URDF <file>: <base_link> -> <tip_link>')")
    base_link: Optional[Annotated[str, StringConstraints(min_length=1, max_length=256)]] = None
    tip_link: Optional[Annotated[str, StringConstraints(min_length=1, max_length=256)]] = None
    limits: Annotated[dict[str, LimitsEntry],
                      Field(max_length=MAX_DOF, description="joint name = [lower, upper], or a table of qlim, qdlim, "
                                                            "qddlim, taumax: the joint's limits for this robot file")] = Field(
        default_factory=dict)
