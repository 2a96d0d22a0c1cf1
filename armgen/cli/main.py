"""The ``armgen`` command line. It only strings library stages together; every command
maps an :class:`ArmgenError` to its exit code and a one-paragraph message on stderr."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import click

from .._version import __version__
from ..api import VERIFY_TARGETS
from .handling import handle_errors
from .options import out_option, plan_robot_option, plan_with_metadata


@click.group()
@click.version_option(__version__, prog_name="armgen")
def cli() -> None:
    """armgen: redundant-arm kinematics to verified embedded C, and trajectory planning."""


@cli.command("robots")
@click.option("--json", "as_json", is_flag=True, help="print a JSON list instead of a table")
@handle_errors
def robots_cmd(as_json: bool) -> None:
    """List the bundled robots."""
    from ..api import load_robot
    from ..description import bundled_robots, describe

    robots = [load_robot(name) for name in bundled_robots()]
    if as_json:
        click.echo(json.dumps([describe(r) | {"description": r.description} for r in robots], indent=2))
        return
    for robot in robots:
        click.echo(f"{robot.name:12s} {robot.n:3d} DOF  {robot.convention:8s}  {robot.description}")


def _show_data(r) -> dict:
    """Everything `show` prints, SI units (rad, m), for --json."""
    from ..description import describe, matrix_rpy

    joints = []
    for j in r.joints:
        entry = {"name": j.name, "type": j.type, "qlim": list(j.qlim),
                 # null: the robot file gives no limit (unlimited)
                 "qdlim": j.qdlim if math.isfinite(j.qdlim) else None,
                 "qddlim": j.qddlim if math.isfinite(j.qddlim) else None,
                 "taumax": j.taumax if math.isfinite(j.taumax) else None,
                 # the link's mass, com, inertia (ixx, iyy, izz, ixy, ixz, iyz) in its link frame; null: none
                 "inertial": dataclasses.asdict(j.inertial) if j.inertial else None}
        if j.origin is not None:
            entry |= {"xyz": j.origin[:3, 3].tolist(), "rpy": matrix_rpy(j.origin[:3, :3]).tolist(), "axis": list(j.axis)}
        else:
            entry |= {"a": j.a, "d": j.d, "alpha": j.alpha, "offset": j.offset, "theta": j.theta}
        joints.append(entry)
    return describe(r) | {
        "description": r.description, "urdf": r.urdf, "joints": joints,
        "task_rows": list(r.task_rows), "gravity": list(r.gravity),
        "base": {"xyz": r.base[:3, 3].tolist(), "rpy": matrix_rpy(r.base[:3, :3]).tolist()},
        "tool": {"xyz": r.tool[:3, 3].tolist(), "rpy": matrix_rpy(r.tool[:3, :3]).tolist()},
        "configurations": {name: q.tolist() for name, q in r.configurations.items()},
    }


@cli.command("show")
@click.argument("robot")
@click.option("--json", "as_json", is_flag=True, help="print JSON (SI units: m, rad) instead of text")
@handle_errors
def show_cmd(robot: str, as_json: bool) -> None:
    """Print a robot's joints (DH table or URDF origin/axis), limits, base/tool and configurations (mm, deg)."""
    from ..api import load_robot

    r = load_robot(robot)
    if as_json:
        click.echo(json.dumps(_show_data(r), indent=2))
        return
    click.echo(r.show_text())


@cli.command("gen")
@click.argument("robot")
@out_option("out_dir", "output directory (default: ./generated/<robot>/ under the current directory)", old=(),
            type=click.Path(file_okay=False), default=None)
@click.option("--precision", type=click.Choice(["double", "float"]), default="double", show_default=True,
              help="the header's default real type (one switch; -D<PREFIX>_USE_FLOAT overrides)")
@click.option("--prefix", default="", help="C identifier prefix (default: the robot name)")
@click.option("--function", "functions", multiple=True, help="generate only these functions (repeatable)")
@handle_errors
def gen_cmd(robot: str, out_dir: str | None, precision: str, prefix: str, functions: tuple[str, ...]) -> None:
    """Derive the robot's functions symbolically and write C (header, source, manifest)."""
    from ..api import generate

    generated = generate(robot, out_dir, precision, prefix, functions or None)
    for path in generated.paths:
        click.echo(f"wrote {path}")
    flops = ", ".join(f"{name} {count}" for name, count in generated.flops.items())
    click.echo(f"generated {len(generated.flops)} functions in {generated.seconds:.2f} s; flops: {flops}")


@cli.command("gen-ptp")
@out_option("out_dir", "output directory (default: ./generated/ptp/ under the current directory)", old=(),
            type=click.Path(file_okay=False), default=None)
@click.option("--precision", type=click.Choice(["double", "float"]), default="double", show_default=True)
@click.option("--prefix", default="armgen", show_default=True, help="C identifier prefix")
@handle_errors
def gen_ptp_cmd(out_dir: str | None, precision: str, prefix: str) -> None:
    """Write the C evaluator of PTP segment polynomials (the firmware's playback)."""
    from ..api import generate_ptp

    for path in generate_ptp(out_dir, precision, prefix):
        click.echo(f"wrote {path}")


@cli.command("plan")
@click.argument("task_file", type=click.Path(dir_okay=False))
@out_option("output", "CSV to write (default: <task name>.csv in the current directory); plan.json goes beside it",
            type=click.Path(), default=None)
@click.option("--backend", type=click.Choice(["symbolic", "c"]), default="symbolic", show_default=True)
@click.option("--set", "overrides", multiple=True, help="override a task field: key=value (dotted keys, TOML values)")
@click.option("--units", type=click.Choice(["rad", "deg"]), default="rad", show_default=True,
              help="angle unit of the CSV columns")
@click.option("--max-steps", type=click.IntRange(min=1), default=None,
              help="cap on integration steps, checked before planning (default: planning.tasks.MAX_INTEGRATION_STEPS)")
@click.option("--max-samples", type=click.IntRange(min=1), default=None,
              help="cap on CSV rows, checked before planning (default: planning.tasks.MAX_OUTPUT_SAMPLES)")
@click.option("--json", "as_json", is_flag=True,
              help="print the files written and plan.json's summary as JSON (for scripts) instead of the table")
@handle_errors
def plan_cmd(task_file: str, output: str | None, backend: str, overrides: tuple[str, ...], units: str,
             max_steps: int | None, max_samples: int | None, as_json: bool) -> None:
    """Plan a task file to CSV plus JSON metadata (written together or not at all), and print a
    summary table in the task file's units."""
    from ..api import parse_override, plan, read_task_document
    from .summary import summary_table, units_hints

    document = read_task_document(task_file, **dict(parse_override(item) for item in overrides))  # read once
    for hint in units_hints(document.document, task_file):  # before the task is checked: a unit may be why it fails
        click.echo(f"warning: {hint}", err=True)
    planned = plan(document, backend, max_steps=max_steps, max_samples=max_samples)
    out = Path(output) if output else Path(Path(task_file).stem + ".csv")
    csv_path, json_path = planned.save(out, units)
    start = planned.metadata.get("start", {}).get("label", "")
    if "; note: " in start:  # a start armgen chose (a pose without a seed on a robot without q0)
        click.echo(f"note: {start.split('; note: ', 1)[1]}", err=True)
    if as_json:  # the summary as plan.json holds it (its keys name their units)
        written = json.loads(json_path.read_text(encoding="utf-8"))
        click.echo(json.dumps({"csv": str(csv_path), "json": str(json_path), "samples": int(planned.data.shape[0]),
                               "summary": written.get("summary", {})}, indent=2))
        return
    click.echo(f"wrote {csv_path} ({planned.data.shape[0]} samples) and {json_path}")
    click.echo(summary_table(json.loads(json_path.read_text(encoding="utf-8"))))


@cli.command("verify")
@click.argument("robot")
@click.option("--plan", "plan_csv", type=click.Path(exists=True, dir_okay=False), default=None,
              help="a plan CSV (with its plan.json) to replay through the C backend")
@click.option("--samples", type=click.IntRange(min=1), default=10_000, show_default=True,
              help="seeded samples per function in the callbacks stage")
@click.option("--precision", type=click.Choice(["double", "float"]), default=None, help="only this precision (default: both)")
@click.option("--target", type=click.Choice(list(VERIFY_TARGETS)), default=None,
              help="also run the firmware on an emulated core (docs/targets.md)")
@click.option("--report", type=click.Path(dir_okay=False), default=None, help="write the JSON report here")
@out_option("generated", "the folder `armgen gen -o` wrote, to verify (default: ./generated/<robot>/)",
            old=("--generated",), type=click.Path(), default=None)
@click.option("--run", "run_csv", type=click.Path(exists=True, dir_okay=False), default=None,
              help="what a firmware run printed (e.g. the demo of `armgen firmware`), compared with --plan")
@click.option("--again", is_flag=True, default=False,
              help="redo every build and stage (by default a passed verdict on the same code, plan and options is reused)")
@handle_errors
def verify_cmd(robot: str, plan_csv: str | None, samples: int, precision: str | None, target: str | None,
               report: str | None, generated: str | None, run_csv: str | None, again: bool) -> None:
    """Check that generated C (fresh for ROBOT's file) does what the symbolic reference does.

    Exit codes: 0 all stages passed, 2 bad input (no manifest, code generated from another
    robot file, a malformed plan), 4 a missing tool, 5 a stage failed (stale code included)."""
    from ..api import VerificationError, verify

    if not verify(robot, plan_csv, samples, precision, target, report, click.echo, generated, run_csv, again):
        raise VerificationError("verification failed: see the FAIL stages above")
    click.echo("all stages passed")


@cli.command("plot")
@click.argument("plan_csv", type=click.Path(exists=True, dir_okay=False))
@out_option("output", "figure to write: .png, .svg or .pdf (default: the CSV's name with .png, beside it)",
            default=None)
@plan_robot_option()
@handle_errors
def plot_cmd(plan_csv: str, output: str | None, robot: str | None) -> None:
    """Draw a plan: joint angles with limits, velocities with bounds, criteria, task error, tool
    path (the arm's own forward kinematics); on a robot with capsules also the arm at its closest
    approach with its capsules and the task's obstacles."""
    from ..api import figure_format, save_plot

    out = Path(output) if output is not None else Path(plan_csv).with_suffix(".png")
    figure_format(output if output is not None else out)  # a bad -o fails before any work
    save_plot(plan_with_metadata(plan_csv, robot, "plot"), out, robot, plan_csv)
    click.echo(f"wrote {out}")


# Commands with a module of their own; each applies handle_errors itself.
from .animate import animate_cmd  # noqa: E402
from .examples import examples_cmd  # noqa: E402
from .firmware import firmware_cmd, firmware_task_cmd  # noqa: E402
from .ik import ik_cmd  # noqa: E402
from .link import link_cmd  # noqa: E402
from .schema import schema_cmd  # noqa: E402
from .sweep import sweep_cmd  # noqa: E402

for command in (animate_cmd, examples_cmd, firmware_cmd, firmware_task_cmd, ik_cmd, link_cmd, schema_cmd, sweep_cmd):
    cli.add_command(command)

if __name__ == "__main__":  # pragma: no cover
    cli()
