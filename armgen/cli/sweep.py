"""``armgen sweep``: plan a task file over a grid of field values and/or random draws; one
table row per run (see :mod:`armgen.planning.sweep`)."""

from __future__ import annotations

from pathlib import Path

import click

from .handling import handle_errors
from .options import out_option


@click.command("sweep")
@click.argument("task_file", type=click.Path(dir_okay=False))
@click.option("--grid", "grids", multiple=True, metavar="KEY=ARRAY",
              help="a task field and a TOML array of its values; every combination of the grids runs")
@click.option("--random", "draws", type=click.IntRange(min=0), default=0, show_default=True,
              help="draws over the --range fields (per grid combination)")
@click.option("--range", "ranges", multiple=True, metavar="KEY=LO:HI",
              help="a task field drawn uniformly in [LO, HI] (numbers, or TOML arrays for a vector field)")
@click.option("--seed", type=int, default=0, show_default=True, help="seed of the random draws")
@click.option("--set", "overrides", multiple=True, help="override a task field for every run: key=value")
@out_option("output", "the table: .csv or .parquet (default: <task name>_sweep.csv)",
            type=click.Path(dir_okay=False), default=None)
@click.option("--backend", type=click.Choice(["symbolic", "c"]), default="symbolic", show_default=True)
@click.option("--workers", type=click.IntRange(min=1), default=None,
              help="local worker processes (default: the number of CPUs)")
@click.option("--scheduler", default=None, metavar="ADDRESS",
              help="run on this Dask distributed scheduler (e.g. tcp://host:8786) instead of local workers; "
                   "it and its workers are trusted (Dask exchanges pickles)")
@click.option("--resume", is_flag=True, help="skip the runs already in the output table")
@handle_errors
def sweep_cmd(task_file, grids, draws, ranges, seed, overrides, output, backend, workers, scheduler, resume) -> None:
    """Plan TASK_FILE once per combination of the --grid values (and per --random draw).

    Exit codes: 0 the table was written (failed runs are rows), 2 bad options or task file,
    3 every run failed, 4 the table or the scheduler cannot be used, 130 interrupted (the
    finished runs are written; --resume runs the rest)."""
    from ..api import PlanningError, sweep

    out = Path(output) if output else Path(Path(task_file).stem + "_sweep.csv")
    rows = sweep(task_file, out, grids, ranges, draws, seed, overrides, backend, workers, scheduler, resume, click.echo)
    failed = sum(r["status"] != "ok" for r in rows)
    click.echo(f"wrote {out}: {len(rows)} runs, {len(rows) - failed} ok, {failed} failed")
    if rows and failed == len(rows):
        raise PlanningError(f"every run of the sweep failed; {out} holds why (column 'message')")
