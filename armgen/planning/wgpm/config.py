"""The weighted-GPM planner's configuration (spec 35): the validated task file
(:class:`~.schema.WgpmTaskFile`) and its robot turned into a :class:`WgpmTask` in SI units."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...errors import TaskFileError
from ...robot import Robot
from ...symbolic.steps import WGPM_CRITERIA
from ..limits import check_start_off_limits
from ..common.start import unit_scales
from ..taskpath import PathTask, configure_path_task
from . import schema
from .schema import WgpmTaskFile

# SI defaults of the fields whose value is a physical quantity (the schema leaves them None).
DEFAULT_T_RMAX = math.radians(10.0)  # rad/s: the repulsive speed at a limit
# A plan "tracks" when its tool stays within these of the path (spec 35 asks whether the method
# both respects the limits and tracks); task-file [tracking] overrides them.
DEFAULT_POS_TOL = 1e-3  # m
DEFAULT_ORI_TOL = math.radians(1.0)  # rad


@dataclass(frozen=True)
class Criterion:
    """One normalised criterion: gain k_hi when it is bad (u ≤ u_th), k_lo when good
    (u ≥ u_th + u_band); off when both gains are 0."""

    k_hi: float
    k_lo: float
    H_lo: float
    H_hi: float
    u_th: float
    u_band: float


@dataclass(frozen=True)
class WgpmMethod:
    name: str  # wgpm, pinv, clamp
    band: float  # Ω: damping-band width as a fraction of each joint's range
    t_rmax: float  # rad/s
    delta: float
    ramp_time: float  # s
    ramp_out: bool
    criteria: tuple[Criterion, ...]  # in WGPM_CRITERIA's order

    def vectors(self) -> list[np.ndarray]:
        """The step's H_lo, H_hi, k_hi, k_lo, u_th, u_band inputs."""
        return [np.array([getattr(c, k) for c in self.criteria]) for k in ("H_lo", "H_hi", "k_hi", "k_lo", "u_th",
                                                                            "u_band")]


@dataclass(frozen=True)
class WgpmTask:
    path: PathTask
    method: WgpmMethod
    pos_tol: float  # m
    ori_tol: float  # rad
    source: str  # the task file, named in messages

    @property
    def robot(self) -> Robot:
        return self.path.robot


def configure(model: WgpmTaskFile, robot: Robot, source: str) -> WgpmTask:
    """The task in SI units, checked against ``robot`` and the plan's duration; a
    :class:`TaskFileError` names the field and the fix."""
    path = configure_path_task(model, robot, source)
    length, angle = unit_scales(model.units)
    m = model.method
    # a criterion the file leaves out has the schema's defaults: both gains 0, off
    criteria = tuple(Criterion(**(getattr(m.criteria, name) or schema.Criterion()).model_dump())
                     for name in WGPM_CRITERIA)
    method = WgpmMethod(name=m.name, band=m.band, t_rmax=DEFAULT_T_RMAX if m.t_rmax is None else m.t_rmax * angle,
                        delta=m.delta, ramp_time=m.ramp_time, ramp_out=m.ramp_out, criteria=criteria)
    if m.name == "wgpm" and criteria[WGPM_CRITERIA.index("zghal")].k_hi > 0:
        check_start_off_limits(robot, path.q_start, "method.criteria.zghal", source)
    if m.ramp_out and 2 * m.ramp_time > path.duration:
        what = "the program's duration" if path.motion is not None else "timing.duration"
        raise TaskFileError(f"{source}: method.ramp_time = {m.ramp_time} s is more than half of {what} = "
                            f"{path.duration:g} s; shorten it or set method.ramp_out = false")
    t = model.tracking
    return WgpmTask(path=path, method=method,
                    pos_tol=DEFAULT_POS_TOL if t.pos_tol is None else t.pos_tol * length,
                    ori_tol=DEFAULT_ORI_TOL if t.ori_tol is None else t.ori_tol * angle, source=source)
