"""Cartesian redundancy resolution along a path (spec 20): the planner's registry entry (:class:`armgen.planning.registry.Planner`)."""

from __future__ import annotations

from ..registry import Planner
from .config import configure
from .planner import plan
from .schema import CartesianTaskFile, workload


def _plot(result, robot=None):
    from .plots import plot_resolved_rate  # matplotlib only when a figure is drawn

    return plot_resolved_rate(result, robot=robot)


PLANNER = Planner(name="cartesian", schema=CartesianTaskFile, configure=configure, plan=plan, plot=_plot,
                  workload=workload)
