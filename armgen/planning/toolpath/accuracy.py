"""The path tolerance of the resolved-rate planners (``[check] path_tolerance``).

The deviation is the plan's ``pos_err_m``: the tool's distance from where the path puts it at
that time (an upper bound on its distance from the path), at the written samples. Explicit
Euler's error is first order, of the order of ``ṡ h`` (4 mm at 200 mm/s and h = 20 ms on the
seam of tests/test_path_tolerance.py, open loop), so a plan that misses the tolerance is made again with the integrator step halved
(the same integrator: the controller runs a plan one Euler step per tick) until it meets the
tolerance, and refused (exit 3) when halving no longer helps.

The tolerance applies to every program, to a circle or line whose task states
``path_tolerance``, and to a Cartesian circle or line that leaves ``integrator.step`` to armgen;
any other circle or line (the papers' reproductions pin their step) is planned as given, its
deviation reported. The step a plan used goes back to its planner, whose ``result.config``
carries it (nothing is written into the task's document).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ...description.files import LENGTH_UNITS
from ...errors import PlanningError

# The default tolerance (m): a welding or gluing seam wants the torch within a tenth of a mm.
DEFAULT_PATH_TOLERANCE = 1e-4
# Halvings of the task's step at most (20 ms → 78 µs): Euler's error is first order, ~v·h at
# the speed ramps (4 mm at 200 mm/s and 20 ms), so eight halvings meet 0.1 mm up to ~1 m/s.
MAX_STEP_HALVINGS = 8
# A halving that leaves more than this fraction of the deviation is not fixing an integration
# error (an unreachable pose or a singularity): stop refining and report.
CONVERGENCE_RATIO = 0.75
# Steps of a refined plan at most: the default cap on a plan's samples (planning.tasks).
MAX_REFINED_STEPS = 1_000_000


def path_tolerance(stated: float | None, length_unit: str, default_applies: bool) -> float | None:
    """The tolerance (m) a plan must meet: the task's ``[check] path_tolerance`` (``stated``, in
    the file's ``length_unit``), else :data:`DEFAULT_PATH_TOLERANCE` where the default applies
    (a program; a Cartesian circle or line that leaves ``integrator.step`` unset); None: the
    deviation is only reported."""
    if stated is not None:
        return float(stated) * LENGTH_UNITS[length_unit]
    return DEFAULT_PATH_TOLERANCE if default_applies else None


@dataclass(frozen=True)
class PathAccuracy:
    """The tolerance a plan must meet (m; None: only reported), the task's integrator step (s)
    and the file's length unit (errors quote the deviation in it)."""

    tolerance: float | None
    step: float
    length_unit: str


def _deviation(result) -> tuple[float, int]:
    error = result.column("pos_err_m")
    k = int(np.argmax(error))
    return float(error[k]), k


def plan_accurately(run: Callable[[float], Any], accuracy: PathAccuracy, duration: float, source: str,
                    where: Callable[[Any, int], str], check: Callable[[Any], None], start_step: float | None = None):
    """``run(step)`` → a plan, at the task's step (or ``start_step``, a step already found
    necessary), halved until the plan meets the tolerance; ``check(plan)`` raises for a plan
    that is infeasible for another reason (the tool far off an unreachable path), before the
    tolerance is judged. ``where(plan, k)`` names the path at sample k. Returns (plan, step,
    report)."""
    step = accuracy.step if start_step is None else start_step
    result = run(step)
    deviation, k = _deviation(result)
    if accuracy.tolerance is None:
        check(result)
        return result, step, _report(accuracy, deviation, step)
    while deviation > accuracy.tolerance:
        finer = step / 2
        halvings = round(math.log2(accuracy.step / finer))
        if halvings > MAX_STEP_HALVINGS or duration / finer > MAX_REFINED_STEPS:
            break
        refined = run(finer)
        new_deviation, new_k = _deviation(refined)
        if new_deviation > CONVERGENCE_RATIO * deviation:
            break
        result, step, deviation, k = refined, finer, new_deviation, new_k
    check(result)
    if deviation > accuracy.tolerance:
        scale = LENGTH_UNITS[accuracy.length_unit]
        unit = accuracy.length_unit
        t = result.column("t_s")[k]
        raise PlanningError(
            f"{source}: the tool leaves the path by {deviation / scale:.4g} {unit} at t = {t:.3f} s ({where(result, k)}), "
            f"more than [check] path_tolerance = {accuracy.tolerance / scale:.4g} {unit}, even at integrator.step = "
            f"{step:g} s (the task's {accuracy.step:g} s halved until it stopped helping or reached "
            f"{accuracy.step / 2 ** MAX_STEP_HALVINGS:g} s); lower path.speed or path.acceleration, close the loop "
            "(integrator.clik_gain), integrate with integrator.method = \"rk4\" (cartesian), or state a larger "
            "[check] path_tolerance")
    return result, step, _report(accuracy, deviation, step)


def _report(accuracy: PathAccuracy, deviation: float, step: float) -> dict[str, Any]:
    return {"tolerance_mm": None if accuracy.tolerance is None else accuracy.tolerance * 1e3,
            "max_deviation_mm": deviation * 1e3, "step_s": step, "task_step_s": accuracy.step,
            "step_halvings": round(math.log2(accuracy.step / step))}
