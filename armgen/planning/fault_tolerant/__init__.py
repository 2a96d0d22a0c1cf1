"""Fault tolerance with locked joints, WLN vs GPM (spec 30): the planner's registry entry (:class:`armgen.planning.registry.Planner`)."""

from __future__ import annotations

from ..registry import Planner
from .config import configure
from .planner import plan
from .schema import FaultTolerantTaskFile, workload


def _plot(result, robot=None):
    from .plots import plot_fault_tolerant  # matplotlib only when a figure is drawn

    return plot_fault_tolerant(result, robot=robot)


PLANNER = Planner(name="fault_tolerant", schema=FaultTolerantTaskFile, configure=configure, plan=plan, plot=_plot,
                  workload=workload)
