"""``armgen ik ROBOT --xyz X Y Z --rpy R P Y``: the joint angles that put the tool at a pose
(``docs/ik.md``). Exit 0 when found, 3 when not (the closest configuration reached is printed),
also when the arm reaches its task rows but the pose asks for other values in the rows it does
not control (a planar arm's z), and when every configuration found that reaches the pose comes
closer than the clearance to an obstacle of ``--obstacles`` or, for a robot with capsules, to
the arm itself. A bad obstacle file is exit 2."""

from __future__ import annotations

import math

import click
import numpy as np

from ..description.model import MAX_ABS_ANGLE_RAD, MAX_ABS_LENGTH_M, TASK_ROWS
from .handling import handle_errors


def _joints(robot, text: str, option: str, angle_scale: float) -> np.ndarray:
    """A named configuration, or n numbers separated by commas/spaces (angles in --units)."""
    from ..api import OptionError, excerpt

    if text in robot.configurations:
        return robot.configuration(text)
    try:
        values = [float(v) for v in text.replace(",", " ").split()]
    except ValueError:
        values = []
    if len(values) != robot.n or not all(math.isfinite(v) for v in values):
        known = ", ".join(sorted(robot.configurations)) or "none"
        raise OptionError(f"{option} {excerpt(repr(text))}: give a configuration name of robot '{robot.name}' "
                          f"({known}) or {robot.n} finite joint values separated by commas")
    scale = np.array([angle_scale if j.revolute else 1.0 for j in robot.joints])
    return np.array(values) * scale


@click.command("ik")
@click.argument("robot")
@click.option("--xyz", nargs=3, type=float, required=True, help="tool position in the base frame [m]")
@click.option("--rpy", nargs=3, type=float, default=None,
              help="tool orientation, R = Rz(yaw) Ry(pitch) Rx(roll) [--units] (default: 0 0 0, not required in the "
                   "orientation rows the arm does not control)")
@click.option("--seed", default=None, help="first start: a configuration name or n joint values (default: --q0, "
                                           "else the middle of the limits; without --q0 first turned about the "
                                           "first joint's axis toward the target)")
@click.option("--q0", default=None, help="stay near this configuration (name or values; default: away from the "
                                         "joint limits)")
@click.option("--max-iterations", type=click.IntRange(1, None), default=None,
              help="stop after this many steps (default: the solver's cap, 450)")
@click.option("--units", type=click.Choice(["rad", "deg"]), default="rad", show_default=True,
              help="angle unit of --rpy, --seed, --q0 and the printed joint angles")
@click.option("--obstacles", "obstacles", type=click.Path(dir_okay=False), default=None,
              help="a TOML file with [[obstacles]], [collision] (clearance, activation) and [units] as in a task "
                   "file: the solution keeps the clearance from them (the robot needs [[collision]] capsules)")
@handle_errors
def ik_cmd(robot: str, xyz: tuple[float, float, float], rpy: tuple[float, float, float] | None, seed: str | None,
           q0: str | None, max_iterations: int | None, units: str, obstacles: str | None) -> None:
    """Inverse kinematics: joint values that put the tool at a pose (exit 3 when none is found)."""
    from ..api import OptionError, PlanningError, load_robot, solve_ik
    from ..description import matrix_rpy, rpy_matrix

    r = load_robot(robot)
    scale = math.pi / 180 if units == "deg" else 1.0
    rpy_given, rpy = rpy, rpy or (0.0, 0.0, 0.0)
    if not all(math.isfinite(v) for v in (*xyz, *rpy)):
        raise OptionError("--xyz/--rpy: give finite numbers")
    if max(abs(v) for v in xyz) > MAX_ABS_LENGTH_M:
        raise OptionError(f"--xyz {' '.join(f'{v:g}' for v in xyz)}: beyond ±{MAX_ABS_LENGTH_M:g} m, out of any arm's "
                          "reach; give the position in metres")
    if max(abs(v * scale) for v in rpy) > MAX_ABS_ANGLE_RAD:
        raise OptionError(f"--rpy {' '.join(f'{v:g}' for v in rpy)}: beyond ±{MAX_ABS_ANGLE_RAD:g} rad; give angles "
                          f"of a few turns at most, in --units ({units})")
    pose = np.eye(4)
    pose[:3, :3] = rpy_matrix(*(v * scale for v in rpy))
    pose[:3, 3] = xyz
    # the orientation counts where the user gave one (--rpy), the position always (--xyz)
    result = solve_ik(r, pose, None if q0 is None else _joints(r, q0, "--q0", scale),
                      None if seed is None else _joints(r, seed, "--seed", scale), max_iterations,
                      orientation_given=rpy_given is not None, obstacles=obstacles)
    rows = ", ".join(TASK_ROWS[k] for k in r.task_rows)
    free_rows, free_position, free_orientation = (result.free_rows, result.free_position_error,
                                                  result.free_orientation_error)
    click.echo(f"{'solved' if result.solved else 'reached, colliding,' if result.colliding else 'closest reached'} in "
               f"{result.iterations} "
               f"iterations (task rows {rows}): position error {result.position_error:.3g} m, "
               f"orientation error {result.orientation_error:.3g} rad")
    if free_rows:
        reached = r.fk(result.q)
        click.echo(f"rows the arm does not control ({', '.join(free_rows)}): position error {free_position:.3g} m, "
                   f"orientation error {free_orientation:.3g} rad; the tool is at xyz "
                   f"{(np.round(reached[:3, 3], 9) + 0.0).tolist()} m, rpy "
                   f"{(np.round(matrix_rpy(reached[:3, :3]) / scale, 9) + 0.0).tolist()} {units}")  # + 0.0: no -0.0
    for joint, value in zip(r.joints, result.q):
        shown, unit = (value / scale, units) if joint.revolute else (value, "m")
        click.echo(f"  {joint.name:12s} {shown: .9g} {unit}")
    if result.clearance is not None:
        click.echo(f"least distance {result.clearance * 1e3:.1f} mm ({result.pair}), clearance "
                   f"{result.required_clearance * 1e3:.1f} mm")
    if result.colliding:
        raise PlanningError(f"no collision-free configuration of robot '{r.name}' was found for this pose: every one "
                            f"that reaches it comes closer than the clearance ({result.required_clearance * 1e3:.1f} "
                            f"mm); the one printed above comes to {result.clearance * 1e3:.1f} mm ({result.pair}). Move "
                            "the pose or the obstacles, lower [collision] clearance, or try another --seed")
    if result.converged and not result.free_rows_match:
        raise PlanningError(f"robot '{r.name}' controls only the rows {rows} of the tool pose: the configuration "
                            f"found reaches those, but the pose asks for other values in the rows "
                            f"{', '.join(free_rows)} ({free_position:.3g} m / {free_orientation:.3g} rad off); give "
                            "--xyz/--rpy the arm takes there (the tool pose reached is printed above)")
    if not result.converged:
        raise PlanningError(f"no configuration of robot '{r.name}' within the tolerances was found for this pose "
                            f"(the closest one reached is printed above); check that the pose is within reach, or "
                            f"try another --seed")
