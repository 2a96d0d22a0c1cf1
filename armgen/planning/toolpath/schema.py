"""Schema of ``[path] type = "program"`` (shared by the cartesian, fault_tolerant and wgpm task
files): values in the file's ``[units]``, each kind of move with exactly the targets it takes;
:mod:`.task` converts them to SI and reads a poses move's CSV."""

from __future__ import annotations

from typing import Annotated, Any, Literal, Optional, Union

from pydantic import Discriminator, Field, StringConstraints, Tag, ValidationInfo, field_validator
from pydantic_core import PydanticCustomError

from ...schemas import StrictModel

Vector3 = Annotated[list[float], Field(min_length=3, max_length=3)]
Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]
# Moves per program: a CAD/CAM contour is one `poses` move, so hand-written moves are few.
MAX_MOVES = 10_000


class Target(StrictModel):
    xyz: Vector3 = Field(description="position (length unit)")
    rpy: Optional[Vector3] = Field(None, description="roll, pitch, yaw (angle unit); absent: keep the orientation")


# The targets each kind of move takes (the others are errors, not ignored).
MOVE_TARGETS = {"line": ("to",), "arc": ("to", "via"), "poses": ("file",)}


class Move(StrictModel):
    kind: Literal["line", "arc", "poses"]
    to: Optional[Target] = Field(None, validate_default=True, description="line, arc: the end pose")
    via: Optional[Target] = Field(None, validate_default=True,
                                  description="arc: a point on the arc between the start and `to` (xyz only)")
    file: Optional[Annotated[str, StringConstraints(min_length=1, max_length=4096)]] = Field(
        None, validate_default=True,
        description="poses: CSV (x, y, z and roll, pitch, yaw or qw, qx, qy, qz), relative to the task file")
    speed: Optional[Positive] = Field(None, description="overrides path.speed for this move")
    acceleration: Optional[Positive] = Field(None, description="overrides path.acceleration for this move")
    blend: Optional[NonNegative] = Field(None, description="overrides path.blend at this move's end")

    @field_validator("to", "via", "file")
    @classmethod
    def _targets_of_the_kind(cls, value: Any, info: ValidationInfo) -> Any:
        kind = info.data.get("kind")
        if kind is None:  # the kind itself is wrong: that is the error to report
            return value
        needed = MOVE_TARGETS[kind]
        if value is None and info.field_name in needed:
            raise PydanticCustomError("missing", "a {kind} move needs it", {"kind": kind})
        if value is not None and info.field_name not in needed:
            raise ValueError(f"not used by a {kind} move (it takes {' and '.join(needed)}); remove it")
        if info.field_name == "via" and value is not None and value.rpy is not None:
            raise ValueError("via.rpy is not used (the orientation turns from the start to `to`); remove it")
        return value


class ProgramPath(StrictModel):
    type: Literal["program"]
    speed: Positive = Field(description="tool speed along the path (length unit per s)")
    acceleration: Positive = Field(description="tool acceleration along the path (length unit per s^2)")
    angular_speed: Optional[Positive] = Field(None, description="cap on the orientation's rate (angle unit per s)")
    blend: NonNegative = Field(0.0, description="corner blend radius (length unit); 0 = stop at the corner")
    moves: Annotated[list[Move], Field(min_length=1, max_length=MAX_MOVES)]


def _path_kind(value: Any) -> str:
    return "program" if isinstance(value, dict) and value.get("type") == "program" else "geometric"


def path_union(geometric: type) -> Any:
    """``[path]``: a program, or the planner's circle/line table ``geometric``."""
    return Annotated[Union[Annotated[geometric, Tag("geometric")], Annotated[ProgramPath, Tag("program")]],
                     Discriminator(_path_kind)]
