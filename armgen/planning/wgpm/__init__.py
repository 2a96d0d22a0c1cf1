"""Multi-constraint weighted gradient projection with damped least squares (spec 35): the planner's registry entry (:class:`armgen.planning.registry.Planner`)."""

from __future__ import annotations

from ..registry import Planner
from .config import configure
from .planner import plan
from .schema import WgpmTaskFile, workload


def _plot(result, robot=None):
    from .plots import plot_wgpm  # matplotlib only when a figure is drawn

    return plot_wgpm(result, robot=robot)


PLANNER = Planner(name="wgpm", schema=WgpmTaskFile, configure=configure, plan=plan, plot=_plot, workload=workload)
