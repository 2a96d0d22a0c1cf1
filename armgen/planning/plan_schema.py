"""Schema of a plan's metadata (``plan.json``) as :func:`armgen.planning.result.read_plan`
reads it. The fields every plan has are typed, and so are the summary's figures that every
planner reports (joint limits, joint speeds, joint torques, clearance, run time, path accuracy); each
planner adds its own result blocks (``robot``, ``comparison``, ...) and summary figures, kept
as they are because only that planner's figure and the firmware's adapter of that planner read
them.

Formats (``format``): 1 — no ``format`` field (armgen before issue 36); 2 — ``format = 2``,
otherwise the same blocks. A reader takes every format up to :data:`PLAN_FORMAT`."""

from __future__ import annotations

from typing import Annotated, Any, Literal, Optional, Union

from pydantic import BaseModel, ConfigDict, Field, StrictInt, StrictStr

from ..schemas import StrictModel


class CsvInfo(StrictModel):
    file: StrictStr
    columns: Annotated[list[StrictStr], Field(min_length=1)]
    samples: Annotated[StrictInt, Field(ge=0)]
    angle_units: Literal["rad", "deg"]


# The plan.json format this armgen writes.
PLAN_FORMAT = 2


# plan.json writes a non-finite float as a string (JSON has no inf/nan); a joint without a
# limit has null in the per-joint lists.
JsonFloat = Union[float, Literal["inf", "-inf", "nan"]]
PerJoint = list[Optional[JsonFloat]]


class _Block(BaseModel):
    # Numbers as JSON gives them (an integral float may be written as 0); a planner may add fields.
    model_config = ConfigDict(extra="allow", protected_namespaces=())


class LimitViolation(_Block):
    """A joint beyond its position limits (one entry of ``summary.limit_violations``)."""

    joint: StrictStr
    first_t_s: float
    last_t_s: float
    worst_t_s: float
    worst_deg: float
    limit_deg: float
    max_abs_deg: float


class JointSpeed(_Block):
    """The plan against the joints' speed and acceleration limits (``summary.joint_speed``)."""

    qdlim: PerJoint
    peak_speed_ratio: PerJoint
    max_speed_ratio: Optional[JsonFloat]
    within_speed_limits: bool
    enforced: bool
    qddlim: Optional[PerJoint] = None
    peak_acceleration_ratio: Optional[PerJoint] = None
    beyond_speed_limits: list[dict[str, Any]] = Field(default_factory=list)


class TorqueExcess(_Block):
    """A joint whose plan needs more than its ``taumax`` (one entry of
    ``summary.joint_torque.beyond_torque_limits``): its peak torque and when."""

    joint: StrictStr
    torque: float
    taumax: float
    ratio: float
    t_s: float
    unit: Literal["N·m", "N"]


class SlowedStretch(_Block):
    """A stretch of a program the slowing made slower (one entry of ``slowed``)."""

    moves: list[StrictInt]
    s_from_mm: float
    s_to_mm: float
    t_from_s: float
    t_to_s: float
    slowest_speed_fraction: float


class TorqueSlowing(_Block):
    """How much a program was slowed to stay within the joints' ``taumax``
    (``summary.joint_torque.slowing``): its time law's duration with and without the torque
    bounds, and the stretches they slowed."""

    enforced: bool
    nominal_duration_s: float
    duration_without_torque_s: float
    duration_s: float
    time_added_s: float
    slowdown_factor: float
    slowed: list[SlowedStretch] = Field(default_factory=list)


class JointTorque(_Block):
    """The plan's joint torques (inverse dynamics at the samples) against the joints' ``taumax``
    (``summary.joint_torque``, a robot with inertials only); ``computed`` is false, with the
    ``reason``, for a plan whose columns do not give every joint's position and rate."""

    computed: bool
    reason: Optional[StrictStr] = None
    acceleration_rule: Optional[StrictStr] = None
    peak_torque: Optional[list[float]] = None  # N·m (N for a prismatic joint), per joint
    peak_torque_t_s: Optional[list[float]] = None
    taumax: Optional[PerJoint] = None
    peak_torque_ratio: Optional[PerJoint] = None
    max_torque_ratio: Optional[JsonFloat] = None
    within_torque_limits: Optional[bool] = None
    beyond_torque_limits: list[TorqueExcess] = Field(default_factory=list)
    slowing: Optional[TorqueSlowing] = None  # a program on a robot with taumax


class PathAccuracy(_Block):
    """How far the tool left its path, and the integrator step that kept it within the tolerance."""

    tolerance_mm: Optional[float]
    max_deviation_mm: float
    step_s: float
    task_step_s: float
    step_halvings: StrictInt


class Clearance(_Block):
    """The plan's least distances (a robot with collision capsules, ``summary.collision``): over
    every sample and checked pair, its pair and time; the least of the arm's self pairs; against
    the task's ``[collision] clearance`` (docs/collision.md)."""

    min_clearance_m: float
    pair: StrictStr
    t_s: float
    clearance_m: float
    within_clearance: bool
    samples_checked: StrictInt
    obstacles: StrictInt
    min_self_clearance_m: Optional[float] = None
    self_pair: Optional[StrictStr] = None
    self_t_s: Optional[float] = None


class PlanSummary(_Block):
    """The figures of merit every planner reports, typed; a planner's own figures are extra fields."""

    run_time_s: Optional[float] = None
    limit_violations: list[LimitViolation] = Field(default_factory=list)
    joint_speed: Optional[JointSpeed] = None
    path_accuracy: Optional[PathAccuracy] = None
    joint_torque: Optional[JointTorque] = None
    collision: Optional[Clearance] = None


class PlanMetadata(BaseModel):
    model_config = ConfigDict(extra="allow", strict=True, protected_namespaces=())

    format: Annotated[StrictInt, Field(ge=1, le=PLAN_FORMAT)] = 1
    planner: Literal["ptp", "cartesian", "fault_tolerant", "wgpm", "snake"]
    armgen_version: Optional[StrictStr] = None
    task_file: Optional[StrictStr] = None
    task_sha256: Optional[StrictStr] = None
    backend: Optional[Literal["symbolic", "c"]] = None
    task: Optional[dict[str, Any]] = None
    summary: Optional[PlanSummary] = None
    csv: Optional[CsvInfo] = None
