"""``armgen firmware ROBOT --out DIR``: a self-contained C project (kinematics, controller,
CMake host demo, Cortex-M4F toolchain file, README) for a bundled robot or a robot file."""

from __future__ import annotations

import click

from .handling import handle_errors
from .options import out_option


@click.command("firmware")
@click.argument("robot")
@out_option("out_dir", "the project folder (new, empty, or one this command wrote earlier)", old=(),
            type=click.Path(), required=True)
@handle_errors
def firmware_cmd(robot: str, out_dir: str) -> None:
    """Write a firmware project for ROBOT (a bundled name or a robot file) into --out.

    Exit codes: 2 bad robot file, 3 no demo task can be planned, 4 the folder cannot be
    written (a file, a foreign non-empty folder, read-only)."""
    from ..verify.firmware_project import write_firmware_project

    r, paths = write_firmware_project(robot, out_dir)
    click.echo(f"wrote {len(paths)} files of the firmware project of '{r.name}' into {out_dir}")
    click.echo(f"build the host demo:  cmake -S {out_dir} -B {out_dir}/build && cmake --build {out_dir}/build")
    click.echo(f"see {out_dir}/README.md for the Cortex-M4F image and the controller's API")
