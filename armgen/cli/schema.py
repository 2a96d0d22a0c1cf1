"""``armgen schema robot|task [--planner P]``: the input files' JSON Schema, for editors that
complete and check TOML (e.g. Taplo / Even Better TOML, with a ``#:schema`` directive)."""

from __future__ import annotations

import json

import click

from .handling import handle_errors


@click.command("schema")
@click.argument("kind", type=click.Choice(["robot", "task"]))
@click.option("--planner", type=click.Choice(["ptp", "cartesian", "fault_tolerant", "wgpm", "snake"]), default=None,
              help="only this planner's task file (default: any task file, chosen by its 'planner' field)")
@handle_errors
def schema_cmd(kind: str, planner: str | None) -> None:
    """Print the JSON Schema of robot or task files."""
    from ..api import json_schema

    if planner is not None and kind != "task":
        raise click.UsageError("--planner applies to 'armgen schema task' only")
    click.echo(json.dumps(json_schema(kind, planner), indent=2))
