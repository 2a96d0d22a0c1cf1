"""Joint-space point-to-point splines, 3-4-...-4 and friends (spec 40): the planner's registry entry (:class:`armgen.planning.registry.Planner`)."""

from __future__ import annotations

from ..registry import Planner
from .config import configure
from .planner import plan
from .schema import PtpTaskFile, workload


def _plot(result, robot=None):
    from .plots import plot_ptp  # matplotlib only when a figure is drawn; the arm only for a robot with capsules

    return plot_ptp(result, robot)


PLANNER = Planner(name="ptp", schema=PtpTaskFile, configure=configure, plan=plan, plot=_plot, workload=workload)
