"""``armgen firmware ROBOT --out DIR [--task TASK.toml | --plan plan.csv]``: a self-contained C
project (kinematics, controller, CMake host demo, Cortex-M4F toolchain file, README) for a
bundled robot or a robot file; ``armgen firmware-task``: the task files the stub's Makefile
compiles in."""

from __future__ import annotations

import click

from .handling import handle_errors

# armgen.firmware.configuration.FEEDFORWARD_IDS (the CLI imports only the API and the description)
FEEDFORWARD_CHOICES = ("none", "gravity", "inverse_dynamics")
FEEDFORWARD_HELP = ("a robot with inertials: each command's feed-forward torque (ctrl_output.tau_ff, checked against "
                    "taumax: fault TORQUE); default inverse_dynamics; a robot without inertials has none")
from .options import out_option

# armgen.firmware.TARGETS' names (the CLI imports only the API and the description)
BOUND_HELP = ("also build the task for this core (cortex-m4, cortex-m7, cortex-m33, cortex-m0plus, rv32imf; repeat "
              "it or give a comma list) and write the static worst-case bounds of each generated function and of "
              "the task's tick (needs the core's cross toolchain)")


@click.command("firmware")
@click.argument("robot")
@out_option("out_dir", "the project folder (new, empty, or one this command wrote earlier)", old=(),
            type=click.Path(), required=True)
@click.option("--task", "task_file", type=click.Path(exists=True, dir_okay=False), default=None,
              help="a task file for ROBOT: planned here, and the project's demo runs it")
@click.option("--plan", "plan_csv", type=click.Path(exists=True, dir_okay=False), default=None,
              help="a plan CSV (with its plan.json) made by `armgen plan`: its task is planned again, must give "
                   "the CSV's samples, and the project's demo runs it")
@click.option("--feedforward", type=click.Choice(FEEDFORWARD_CHOICES), default=None, help=FEEDFORWARD_HELP)
@click.option("--bound", "bound_targets", multiple=True, metavar="TARGET",
              help=BOUND_HELP + ": into the manifest and the README")
@handle_errors
def firmware_cmd(robot: str, out_dir: str, task_file: str | None, plan_csv: str | None,
                 feedforward: str | None, bound_targets: tuple[str, ...]) -> None:
    """Write a firmware project for ROBOT (a bundled name or a robot file) into --out; its demo
    runs --task or --plan, else a short built-in line.

    Exit codes: 2 bad robot, task or plan file (or --feedforward for a robot without inertials), 3 the task (or, without one, the demo) cannot
    be planned or its plan leaves the joint limits (also under [check] limits = "report"), 4 the
    folder cannot be written (a file, a foreign non-empty folder, read-only, a symbolic link in
    the project's paths), 5 the controller cannot run the task (another robot's, refused before
    planning, or a mode it does not have) or a --plan its recorded task does not plan to; with
    --bound: 2 an unknown core, 4 its cross toolchain missing (the message names the packages;
    nothing was written), 5 the image holds code the static bound cannot count."""
    from ..api import firmware_project

    r, paths = firmware_project(robot, out_dir, task_file, plan_csv, feedforward=feedforward, bound=bound_targets)
    click.echo(f"wrote {len(paths)} files of the firmware project of '{r.name}' into {out_dir}")
    click.echo(f"build the host demo:  cmake -S {out_dir} -B {out_dir}/build && cmake --build {out_dir}/build")
    click.echo(f"see {out_dir}/README.md for the Cortex-M4F image and the controller's API")
    if bound_targets:
        click.echo(f"static worst-case bounds ({', '.join(bound_targets)}): {out_dir}/README.md, \"Worst case per "
                   "tick\", and the manifest's \"bounds\"")


@click.command("firmware-task")
@click.argument("source", type=click.Path(exists=True, dir_okay=False))
@out_option("out_dir", "the folder of task_params.h, fw_ptp.{h,c} and robot_fw.c", old=(), type=click.Path(),
            required=True)
@click.option("--robot", default=None, help="the firmware's robot (checked against the task's)")
@click.option("--set", "overrides", multiple=True, help="override a task field (TOML value), e.g. timing.duration=5")
@click.option("--gen-dir", type=click.Path(file_okay=False), default=None,
              help="the robot's generated code (default generated/<robot>/)")
@click.option("--lock", default=None, metavar="JOINTS@TIME",
              help="the drives report these joints locked from TIME s on (e.g. 5@1.38), unknown to the plan")
@click.option("--feedforward", type=click.Choice(FEEDFORWARD_CHOICES), default=None, help=FEEDFORWARD_HELP)
@click.option("--bound", "bound_targets", multiple=True, metavar="TARGET", help=BOUND_HELP + ": into bounds.json")
@handle_errors
def firmware_task_cmd(source: str, out_dir: str, robot: str | None, overrides: tuple[str, ...], gen_dir: str | None,
                      lock: str | None, feedforward: str | None, bound_targets: tuple[str, ...]) -> None:
    """Write the controller's task for SOURCE (a task file or a plan CSV): task_params.h, the PTP
    evaluator fw_ptp.{h,c} and robot_fw.c (the generated functions the controller calls).

    Used by firmware_stub/Makefile. Exit codes: 2 bad task file (or --feedforward for a robot without
    inertials), 4 unwritable output, 5 a task
    the controller cannot run (e.g. one for another --robot); with --bound: 2 an unknown core, 4 its
    cross toolchain missing (nothing written), 5 an image the static bound cannot count."""
    from ..api import firmware_task

    for path in firmware_task(source, out_dir, robot, overrides, gen_dir, lock, feedforward, bound_targets):
        click.echo(f"wrote {path}")
