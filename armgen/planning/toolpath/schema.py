"""Schema of ``[path] type = "program"`` (shared by the cartesian, fault_tolerant and wgpm task
files): values in the file's ``[units]``; :mod:`.task` converts them to SI and checks what a
schema cannot (which fields each kind of move needs)."""

from __future__ import annotations

from typing import Annotated, Any, Literal, Optional, Union

from pydantic import Discriminator, Field, StringConstraints, Tag

from ...schemas import StrictModel

Vector3 = Annotated[list[float], Field(min_length=3, max_length=3)]
Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]
# Moves per program: a CAD/CAM contour is one `poses` move, so hand-written moves are few.
MAX_MOVES = 10_000


class Target(StrictModel):
    xyz: Vector3 = Field(description="position (length unit)")
    rpy: Optional[Vector3] = Field(None, description="roll, pitch, yaw (angle unit); absent: keep the orientation")


class Move(StrictModel):
    kind: Literal["line", "arc", "poses"]
    to: Optional[Target] = Field(None, description="line, arc: the end pose")
    via: Optional[Target] = Field(None, description="arc: a point on the arc between the start and `to` (xyz only)")
    file: Optional[Annotated[str, StringConstraints(min_length=1, max_length=4096)]] = Field(
        None, description="poses: CSV (x, y, z and roll, pitch, yaw or qw, qx, qy, qz), relative to the task file")
    speed: Optional[Positive] = Field(None, description="overrides path.speed for this move")
    acceleration: Optional[Positive] = Field(None, description="overrides path.acceleration for this move")
    blend: Optional[NonNegative] = Field(None, description="overrides path.blend at this move's end")


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
