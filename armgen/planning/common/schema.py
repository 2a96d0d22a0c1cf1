"""The task-file vocabulary every planner shares (spec 20's tables, reused by specs 30, 35 and
the ptp and snake planners): the robot reference, the start (a configuration, joint values or a
tool pose), the file's units, the circle/line path and its timing, damping, and the limit
policies of ``[check]``. Values are in the file's units; :mod:`armgen.planning.common.start`
and :mod:`armgen.planning.common.path` convert them to SI. No planner owns this module."""

from __future__ import annotations

from typing import Annotated, Any, Literal, Optional, Union

from pydantic import Field, StringConstraints, ValidationInfo, field_validator
from pydantic_core import PydanticCustomError

from ...schemas import StrictModel
from ..toolpath.schema import ProgramPath

# A path or bundled name; longer text is not a file name.
RobotReference = Annotated[str, StringConstraints(min_length=1, max_length=4096)]
Description = Annotated[str, StringConstraints(max_length=2000)]
Vector3 = Annotated[list[float], Field(min_length=3, max_length=3)]
Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]
JointValues = Annotated[list[float], Field(min_length=1, max_length=64)]
ConfigurationName = Annotated[str, StringConstraints(min_length=1, max_length=64)]


class Target(StrictModel):
    xyz: Vector3 = Field(description="position (length unit)")
    rpy: Vector3 = Field(description="roll, pitch, yaw (angle unit): R = Rz(yaw) Ry(pitch) Rx(roll)")


class StartPose(StrictModel):
    """A start given as a tool pose, solved by the robot's inverse kinematics."""

    pose: Target = Field(description="the start tool pose (xyz, rpy) in the file's units")
    seed: Union[ConfigurationName, JointValues] = Field(
        "q0", description="the configuration the IK starts from (a name or joint values)")


Start = Union[ConfigurationName, JointValues, StartPose]


class Units(StrictModel):
    length: Literal["m", "mm"] = "m"
    angle: Literal["rad", "deg"] = "rad"


class Path(StrictModel):
    type: Literal["circle", "line"] = "circle"
    via: Optional[Vector3] = Field(None, validate_default=True,
                                   description="circle: the second point (start → via → end → start)")
    end: Vector3
    orientation: Literal["hold", "interpolate"] = "hold"
    end_rpy: Optional[Vector3] = Field(None, validate_default=True,
                                       description="line with orientation = 'interpolate': final roll, pitch, yaw")

    @field_validator("via")
    @classmethod
    def _circle_needs_via(cls, via: Optional[list[float]], info: ValidationInfo) -> Optional[list[float]]:
        if via is None and info.data.get("type") == "circle":
            raise PydanticCustomError("missing", "a circle runs start → via → end → start")
        return via

    @field_validator("orientation")
    @classmethod
    def _interpolate_on_lines(cls, orientation: str, info: ValidationInfo) -> str:
        if orientation == "interpolate" and info.data.get("type") != "line":
            raise ValueError("the orientation turns along a line only: set path.type = 'line' or path.orientation = "
                             "'hold'")
        return orientation

    @field_validator("end_rpy")
    @classmethod
    def _interpolate_needs_end_rpy(cls, end_rpy: Optional[list[float]], info: ValidationInfo) -> Optional[list[float]]:
        if end_rpy is None and info.data.get("orientation") == "interpolate":
            raise PydanticCustomError("missing", "orientation = 'interpolate' turns the tool to end_rpy")
        return end_rpy


class Timing(StrictModel):
    duration: Positive = Field(description="s")
    law: Literal["cubic", "trapezoidal", "constant"] = "cubic"
    blend: float = Field(0.2, description="trapezoidal: fraction of the duration spent accelerating, (0, 0.5]")


class Damping(StrictModel):
    epsilon: Positive = 0.01
    lambda_max: NonNegative = 0.05


class Check(StrictModel):
    limits: Literal["error", "report"] = Field(
        "error", description="a plan that leaves a joint's position, speed or torque limits: 'error' (exit 3, nothing "
                             "written) or 'report' (written; listed in the summary's limit_violations, "
                             "joint_speed.beyond_speed_limits, joint_torque.beyond_torque_limits)")
    path_tolerance: Optional[Positive] = Field(
        None, description="length unit: the most the tool may deviate from the path (default 0.1 mm for programs and "
                          "for cartesian circles/lines that leave integrator.step unset); the step is halved to meet it, else "
                          "exit 3")


class SpeedCheck(StrictModel):
    """``[check]`` of the planners that never leave the position limits (ptp, snake): only the
    joints' speed limits are left to the policy."""

    limits: Literal["error", "report"] = Field(
        "error", description="a plan beyond a joint's speed limit (the robot file's qdlim or qddlim) or torque limit "
                             "(taumax, a robot with inertials): 'error' (exit 3, nothing written) or 'report' (written; "
                             "listed in summary.joint_speed.beyond_speed_limits, joint_torque.beyond_torque_limits)")


class RelativePath(Path):
    relative: bool = Field(False, description="via/end are offsets from the start tool position")
    turns: Positive = Field(1.0, description="circle: turns over the duration")

    @field_validator("turns")
    @classmethod
    def _turns_of_circles(cls, turns: float, info: ValidationInfo) -> float:
        if turns != 1.0 and info.data.get("type") == "line":
            raise ValueError("turns are for circles only; remove path.turns or set path.type = 'circle'")
        return turns


class EulerIntegrator(StrictModel):
    method: str = Field("euler", description="'euler' only: the weights use the previous step's velocity",
                        json_schema_extra={"enum": ["euler"]})
    step: Positive = Field(0.02, description="s")
    clik: bool = True
    clik_gain: NonNegative = 10.0
    output_every: Annotated[int, Field(ge=1)] = 1


def program_duration_estimate(path: ProgramPath) -> float:
    """A program's duration (s) before its geometry is built: the straight distances between the
    line and arc targets at each move's speed (a poses move's file is not read yet: 0)."""
    total, previous = 0.0, None
    for move in path.moves:
        if move.to is not None:
            if previous is not None:
                distance = sum((a - b) ** 2 for a, b in zip(move.to.xyz, previous)) ** 0.5
                total += distance / (move.speed or path.speed)
            previous = move.to.xyz
    return total


def resolved_rate_workload(task: Any) -> tuple[float, float]:
    """(integration steps, CSV samples) a resolved-rate task (``timing``, ``integrator`` and a
    circle, line or program ``path``) asks for, estimated before planning."""
    if isinstance(task.path, ProgramPath):
        duration = program_duration_estimate(task.path)
    elif task.timing is None:
        return 0.0, 0.0  # the planner reports the missing [timing]
    else:
        duration = task.timing.duration
    steps = duration / task.integrator.step
    return steps, steps / task.integrator.output_every + 1
