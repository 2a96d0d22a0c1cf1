"""``armgen ik ROBOT --xyz X Y Z --rpy R P Y``: the joint angles that put the tool at a pose
(``docs/ik.md``). Exit 0 when found, 3 when not (the closest configuration reached is printed)."""

from __future__ import annotations

import math

import click
import numpy as np

from .handling import handle_errors


def _joints(robot, text: str, option: str, angle_scale: float) -> np.ndarray:
    """A named configuration, or n numbers separated by commas/spaces (angles in --units)."""
    from ..errors import OptionError

    if text in robot.configurations:
        return robot.configuration(text)
    try:
        values = [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        values = []
    if len(values) != robot.n or not all(math.isfinite(v) for v in values):
        known = ", ".join(sorted(robot.configurations)) or "none"
        raise OptionError(f"{option} {text!r}: give a configuration name of robot '{robot.name}' ({known}) or "
                          f"{robot.n} finite joint values separated by commas")
    scale = np.array([angle_scale if j.revolute else 1.0 for j in robot.joints])
    return np.array(values) * scale


@click.command("ik")
@click.argument("robot")
@click.option("--xyz", nargs=3, type=float, required=True, help="tool position in the base frame [m]")
@click.option("--rpy", nargs=3, type=float, default=(0.0, 0.0, 0.0), show_default=True,
              help="tool orientation, R = Rz(yaw) Ry(pitch) Rx(roll) [--units]")
@click.option("--seed", default=None, help="first start: a configuration name or n joint values (default: --q0, "
                                           "else the middle of the limits; without --q0 first turned about the "
                                           "first joint's axis toward the target)")
@click.option("--q0", default=None, help="stay near this configuration (name or values; default: away from the "
                                         "joint limits)")
@click.option("--max-iterations", type=click.IntRange(1, None), default=None,
              help="stop after this many steps (default: the solver's cap, 450)")
@click.option("--units", type=click.Choice(["rad", "deg"]), default="rad", show_default=True,
              help="angle unit of --rpy, --seed, --q0 and the printed joint angles")
@handle_errors
def ik_cmd(robot: str, xyz: tuple[float, float, float], rpy: tuple[float, float, float], seed: str | None,
           q0: str | None, max_iterations: int | None, units: str) -> None:
    """Inverse kinematics: joint values that put the tool at a pose (exit 3 when none is found)."""
    from ..errors import OptionError, PlanningError
    from ..description import rpy_matrix
    from ..robot import load_robot_any
    from ..symbolic import ik

    r = load_robot_any(robot)
    scale = math.pi / 180 if units == "deg" else 1.0
    if not all(math.isfinite(v) for v in (*xyz, *rpy)):
        raise OptionError("--xyz/--rpy: give finite numbers")
    pose = np.eye(4)
    pose[:3, :3] = rpy_matrix(*(v * scale for v in rpy))
    pose[:3, 3] = xyz
    result = r.ik(pose, None if q0 is None else _joints(r, q0, "--q0", scale),
                  seed=None if seed is None else _joints(r, seed, "--seed", scale),
                  max_iterations=None if max_iterations is None else min(max_iterations, ik.MAX_ITERATIONS))
    rows = ", ".join(f"{'vx vy vz wx wy wz'.split()[k]}" for k in r.task_rows)
    click.echo(f"{'solved' if result.success else 'closest reached'} in {int(result.iterations)} iterations "
               f"(task rows {rows}): position error {float(result.position_error):.3g} m, "
               f"orientation error {float(result.orientation_error):.3g} rad")
    for joint, value in zip(r.joints, result.q):
        shown, unit = (value / scale, units) if joint.revolute else (value, "m")
        click.echo(f"  {joint.name:12s} {shown: .9g} {unit}")
    if not result.success:
        raise PlanningError(f"no configuration of robot '{r.name}' within the tolerances was found for this pose "
                            f"(the closest one reached is printed above); check that the pose is within reach, or "
                            f"try another --seed")
