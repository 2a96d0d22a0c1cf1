"""``armgen schema robot|task [--planner P]``: the input files' JSON Schema, for editors that
complete and check TOML (e.g. Taplo / Even Better TOML, with a ``#:schema`` directive)."""

from __future__ import annotations

import json
from typing import Annotated, Union

import click

from .handling import handle_errors


def schema_of(kind: str, planner: str | None = None) -> dict:
    """JSON Schema of the robot file, one planner's task file, or any task file."""
    from pydantic import Field, TypeAdapter

    from ..planning.registry import PLANNER_NAMES, planner as planner_named
    from ..description.schema import RobotFile, UrdfRobotFile

    if kind == "robot":
        schema = TypeAdapter(Union[RobotFile, UrdfRobotFile]).json_schema()
        schema["title"] = "armgen robot file (DH table, or a URDF reference)"
        return schema
    models = {name: planner_named(name).schema for name in PLANNER_NAMES}
    if planner is not None:
        return models[planner].model_json_schema()
    union = Annotated[Union[tuple(models.values())], Field(discriminator="planner")]
    schema = TypeAdapter(union).json_schema()
    schema["title"] = "armgen task file"
    return schema


@click.command("schema")
@click.argument("kind", type=click.Choice(["robot", "task"]))
@click.option("--planner", type=click.Choice(["ptp", "cartesian", "fault_tolerant", "wgpm", "snake"]), default=None,
              help="only this planner's task file (default: any task file, chosen by its 'planner' field)")
@handle_errors
def schema_cmd(kind: str, planner: str | None) -> None:
    """Print the JSON Schema of robot or task files."""
    if planner is not None and kind != "task":
        raise click.UsageError("--planner applies to 'armgen schema task' only")
    click.echo(json.dumps(schema_of(kind, planner), indent=2))
