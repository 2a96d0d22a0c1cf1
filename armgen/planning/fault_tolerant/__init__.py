"""Fault tolerance with locked joints, WLN vs GPM (spec 30): the planner's registry entry (:class:`armgen.planning.registry.Planner`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..registry import Planner
from .schema import FaultTolerantTaskFile, workload


# TRANSITIONAL (issue 36, replaced by config.configure / planner.plan): the task dict as the
# file gave it, for the planner's own reader.
@dataclass(frozen=True)
class _LegacyConfig:
    task: dict[str, Any]
    source: str


def _configure(model: FaultTolerantTaskFile, robot: Any, source: str) -> _LegacyConfig:
    return _LegacyConfig(model.model_dump(by_alias=True, exclude_unset=True), source)


def _plan(config: _LegacyConfig, backend: str = "symbolic"):
    from .planner import plan_task

    return plan_task(config.task, config.source, backend)


def _plot(result, robot=None):
    from .plots import plot_fault_tolerant

    return plot_fault_tolerant(result, robot=robot)


PLANNER = Planner(name="fault_tolerant", schema=FaultTolerantTaskFile, configure=_configure, plan=_plan, plot=_plot, workload=workload)
