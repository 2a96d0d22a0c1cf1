"""Cartesian redundancy resolution along a path (spec 20): the planner's registry entry (:class:`armgen.planning.registry.Planner`).

The schema is imported with the package; the configuration, the planner and the figure when
first used, so that reading a task's schema (``armgen schema``, validation) does not load
CasADi, SciPy or matplotlib."""

from __future__ import annotations

from ..registry import Planner
from .schema import CartesianTaskFile, workload


def _configure(model, robot, source):
    from .config import configure

    return configure(model, robot, source)


def _plan(config, backend="symbolic"):
    from .planner import plan

    return plan(config, backend)


def _plot(result, robot=None):
    from .plots import plot_resolved_rate

    return plot_resolved_rate(result, robot=robot)


PLANNER = Planner(name="cartesian", schema=CartesianTaskFile, configure=_configure, plan=_plan, plot=_plot,
                  workload=workload)
