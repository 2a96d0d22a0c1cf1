"""Snake-arm tip following (spec 50): the planner's registry entry (:class:`armgen.planning.registry.Planner`)."""

from __future__ import annotations

from ..registry import Planner
from .config import configure
from .planner import plan
from .schema import SnakeTaskFile, workload


def _plot(result, robot=None):
    from .plots import plot_snake  # matplotlib only when a figure is drawn

    return plot_snake(result, robot=robot)


def _animation_scene(fig, result, frames, robot):
    from .plots import animation_scene

    return animation_scene(fig, result, frames, robot)


PLANNER = Planner(name="snake", schema=SnakeTaskFile, configure=configure, plan=plan, plot=_plot, workload=workload,
                  animation_scene=_animation_scene)
