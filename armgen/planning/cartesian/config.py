"""The Cartesian planner's configuration (spec 20): the validated task file
(:class:`~.schema.CartesianTaskFile`) and its loaded robot turned into a :class:`CartesianTask`
in SI units. The schema checked the types, ranges and choices; this converts the file's units,
gives each method its own defaults, and checks what needs the robot or several fields."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from ...errors import TaskFileError
from ...robot import Robot
from ..common.collision import TaskCollision, configure_collision
from ..common.path import WHOLE_STEP_SLACK, check_step, path_geometry, program_task, timing_law
from ..common.start import start_configuration, unit_scales
from ..limits import check_start_off_limits
from ..toolpath.accuracy import PathAccuracy, path_tolerance
from ..toolpath.paths import TimeLaw
from ..toolpath.schema import ProgramPath
from ..toolpath.task import ProgramSpec
from ..toolpath.timelaw import ProgramMotion
from .schema import CartesianTaskFile, Method

# The methods that descend Zghal's joint-limit criterion H_L (with gain rho_L).
JOINT_LIMIT_METHODS = ("zghal", "zghal_improved", "combined")


@dataclass(frozen=True)
class MethodParams:
    """The method's gains and times (SI): Zghal's plain defaults; :data:`METHOD_DEFAULTS` holds
    the methods whose own defaults differ."""

    name: str = "pinv"
    rho_R: float = 2.8
    T_smo_R: float = 10.0
    rho_L: float = 0.025
    theta_s: float = math.radians(20)
    T_smo_L: float = 40.0
    T_sum_L: float = 80.0
    gamma_R_ramp: float = 20.0


# The defaults of a method whose criterion is scaled or windowed differently: the combined
# method's linear windows want a far smaller H_L gain and shorter windows (spec 20).
METHOD_DEFAULTS = {
    "combined": MethodParams("combined", rho_L=1e-4, T_smo_L=20.0, T_sum_L=40.0),
    "zghal_improved": MethodParams("zghal_improved", rho_L=0.04, T_smo_L=40.0, T_sum_L=80.0),
}


@dataclass(frozen=True)
class CartesianTask:
    """A Cartesian path task in SI on its robot. ``path_type`` is "circle", "line" or
    "program"; a program's moves are ``program`` and its motion (geometry and time law from the
    start pose) ``motion``. ``tolerance``: the path tolerance (m) a plan must meet (None: the
    deviation is only reported); ``length_unit``: the file's (messages quote it); ``source``:
    the task file (messages name it)."""

    robot: Robot
    q_start: np.ndarray
    path_type: str
    via: np.ndarray | None
    end: np.ndarray
    end_rotation: np.ndarray | None
    duration: float
    law: TimeLaw
    method: MethodParams
    integrator: str = "euler"
    step: float = 0.02
    clik_gain: float = 0.0
    damping_epsilon: float = 0.01
    damping_max: float = 0.05
    output_every: int = 1
    program: ProgramSpec | None = None
    motion: ProgramMotion | None = None
    start_label: str = ""
    tolerance: float | None = None
    length_unit: str = "m"
    source: str = ""
    collision: TaskCollision | None = None  # the obstacles and [collision] (robot with capsules)

    @property
    def accuracy(self) -> PathAccuracy:
        """The tolerance a plan of this task must meet, from its step."""
        return PathAccuracy(self.tolerance, self.step, self.length_unit)

    def with_motion(self, motion: ProgramMotion) -> CartesianTask:
        """This task driven by ``motion``: the duration is the motion's, rounded up to whole steps."""
        return replace(self, motion=motion,
                       duration=math.ceil(motion.duration / self.step - WHOLE_STEP_SLACK) * self.step)


def method_params(method: Method, angle_scale: float, source: str) -> MethodParams:
    """The method's parameters in SI: those the file gives, the method's own defaults for the
    rest (the schema's defaults are Zghal's plain ones, in the file's angle unit)."""
    defaults = METHOD_DEFAULTS.get(method.name, MethodParams(method.name))
    given = method.model_fields_set
    values = {key: float(getattr(method, key)) if key in given else getattr(defaults, key)
              for key in ("rho_R", "T_smo_R", "rho_L", "T_smo_L", "T_sum_L", "gamma_R_ramp")}
    theta_s = float(method.theta_s) * angle_scale if "theta_s" in given else defaults.theta_s
    params = MethodParams(method.name, theta_s=theta_s, **values)
    if params.T_sum_L < params.T_smo_L:
        raise TaskFileError(f"{source}: method.T_sum_L = {params.T_sum_L} must be ≥ method.T_smo_L = {params.T_smo_L}")
    return params


def configure(model: CartesianTaskFile, robot: Robot, source: str) -> CartesianTask:
    """The validated task on its loaded robot, in SI; errors name ``source``'s field and the fix."""
    collision = configure_collision(model, robot, source)
    q_start, label = start_configuration(model.start, model.units, robot, source, "start" in model.model_fields_set,
                                         collision)
    ls, as_ = unit_scales(model.units)
    program = None
    if isinstance(model.path, ProgramPath):
        program = program_task(model.path, model.timing, robot, q_start, ls, as_, source)
        path = dict(path_type="program", via=None, end=np.zeros(3), end_rotation=None,
                    duration=program.motion.duration, law=TimeLaw("constant"))
    else:
        geometry = path_geometry(model.path, ls, as_)
        duration, law = timing_law(model.timing, source)
        path = dict(path_type=geometry.type, via=geometry.via, end=geometry.end, end_rotation=geometry.end_rotation,
                    duration=duration, law=law)
    params = method_params(model.method, as_, source)
    if params.name in JOINT_LIMIT_METHODS and params.rho_L > 0:
        check_start_off_limits(robot, q_start, f"method '{params.name}'", source)
    integ = model.integrator
    if program is None:
        check_step(integ.step, path["duration"], source)
    # the default tolerance applies to a program, and to a circle or line that leaves the step to armgen
    step_unset = "step" not in integ.model_fields_set
    task = CartesianTask(
        robot=robot, q_start=q_start, **path, method=params, integrator=integ.method, step=float(integ.step),
        clik_gain=float(integ.clik_gain), damping_epsilon=float(model.damping.epsilon),
        damping_max=float(model.damping.lambda_max), output_every=integ.output_every,
        program=None if program is None else program.spec, start_label=label,
        tolerance=path_tolerance(model.check.path_tolerance, model.units.length, program is not None or step_unset),
        length_unit=model.units.length, source=source, collision=collision)
    return task if program is None else task.with_motion(program.motion)
