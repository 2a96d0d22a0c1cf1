"""Cartesian redundancy resolution along a path (spec 20): the planner's registry entry (:class:`armgen.planning.registry.Planner`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..registry import Planner
from .schema import CartesianTaskFile, workload


# TRANSITIONAL (issue 36, replaced by config.configure / planner.plan): the task dict as the
# file gave it, for the planner's own reader.
@dataclass(frozen=True)
class _LegacyConfig:
    task: dict[str, Any]
    source: str


def _configure(model: CartesianTaskFile, robot: Any, source: str) -> _LegacyConfig:
    return _LegacyConfig(model.model_dump(by_alias=True, exclude_unset=True), source)


def _plan(config: _LegacyConfig, backend: str = "symbolic"):
    from .planner import plan_task

    return plan_task(config.task, config.source, backend)


def _plot(result, robot=None):
    from .plots import plot_resolved_rate

    return plot_resolved_rate(result, robot=robot)


PLANNER = Planner(name="cartesian", schema=CartesianTaskFile, configure=_configure, plan=_plan, plot=_plot, workload=workload)
