"""The planners: one :class:`Planner` object per planner package, found by name.

A planner package (``armgen.planning.<name>``) has the same layout for every planner:
``schema.py`` (the task file's pydantic model and its workload estimate), ``config.py`` (the
typed SI configuration and ``configure``), ``planner.py`` (``plan``), ``plots.py``, and its
``__init__`` exposing ``PLANNER``. A package is imported only when its name is asked for, so
``armgen plan`` of a ptp task never imports the resolved-rate machinery.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Optional

from ..errors import TaskFileError, excerpt
from ..schemas import StrictModel, closest_key

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ..robot import Robot
    from .result import PlanResult

# The planner packages, by the name a task file gives in ``planner = "..."``.
PLANNER_NAMES = ("ptp", "cartesian", "fault_tolerant", "wgpm", "snake")


@dataclass(frozen=True)
class Planner:
    """What the task pipeline needs of a planner.

    ``configure(model, robot, source)`` turns the validated task (``schema``'s model, in the
    file's units) and the task's robot (loaded once by the pipeline; None for a task that names
    none) into the planner's typed SI configuration, raising :class:`TaskFileError` naming the
    file, the field and the fix; ``plan(config, backend)`` plans it; ``plot(result, robot)``
    draws the plan's figure (``robot`` None: the one plan.json records); ``workload(model)``
    estimates (integration steps, CSV samples) before planning; ``animation_scene(figure,
    result, frames, robot)``, for a planner whose arm the joint frames do not show, lays out the
    animation's scene and returns the function drawing frame ``f`` (None: the serial arm's)."""

    name: str
    schema: type[StrictModel]
    configure: Callable[[Any, Optional[Robot], str], Any]
    plan: Callable[[Any, str], PlanResult]
    plot: Callable[..., Figure]
    workload: Callable[[Any], tuple[float, float]]
    animation_scene: Optional[Callable[..., Callable[[int], None]]] = None


def planner(name: Any, source: str = "") -> Planner:
    """The planner called ``name``; an unknown name is a :class:`TaskFileError` naming ``source``'s field."""
    if not isinstance(name, str) or name not in PLANNER_NAMES:
        near = closest_key(name, list(PLANNER_NAMES)) if isinstance(name, str) else None
        raise TaskFileError(
            f"{source}: field 'planner' = {excerpt(repr(name))} is not one of {', '.join(sorted(PLANNER_NAMES))}"
            + (f" (did you mean `{near}`?)" if near else "")
            + "; set planner = \"<name>\" at the top of the task file")
    return importlib.import_module(f"{__package__}.{name}").PLANNER
