"""Schema of a plan's metadata (``plan.json``) as :func:`armgen.planning.result.read_plan`
reads it. The fields every plan has are typed; each planner adds its own result blocks
(``summary``, ``robot``, ``comparison``, ...), which are kept as they are because only that
planner's figure reads them."""

from __future__ import annotations

from typing import Annotated, Any, Literal, Optional

from pydantic import BaseModel, ConfigDict, Field, StrictInt, StrictStr

from ..schemas import StrictModel


class CsvInfo(StrictModel):
    file: StrictStr
    columns: Annotated[list[StrictStr], Field(min_length=1)]
    samples: Annotated[StrictInt, Field(ge=0)]
    angle_units: Literal["rad", "deg"]


class PlanMetadata(BaseModel):
    model_config = ConfigDict(extra="allow", strict=True, protected_namespaces=())

    planner: Literal["ptp", "cartesian", "fault_tolerant", "wgpm", "snake"]
    armgen_version: Optional[StrictStr] = None
    task_file: Optional[StrictStr] = None
    task_sha256: Optional[StrictStr] = None
    backend: Optional[Literal["symbolic", "c"]] = None
    task: Optional[dict[str, Any]] = None
    summary: Optional[dict[str, Any]] = None
    csv: Optional[CsvInfo] = None
