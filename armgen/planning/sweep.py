"""Parameter sweeps over a task file: every combination of some field values (a grid), random
draws over ranges, or both; one table row per run.

A run is the task file with some fields replaced (the same dotted keys as ``armgen plan
--set``). Its row holds the run's index, its field values, ``status`` (``ok`` or ``error``),
``exit_code`` (0, or the exit code ``armgen plan`` would return: 2 bad input, 3 infeasible …),
``message`` (the error's text), ``overrides`` (the run's fields as JSON: what ``--resume``
matches on) and every scalar of the plan's summary under its own name. Wall times
(``run_time_s``, ``plan_seconds``) are left out, so the table does not depend on where or
how fast it ran. A failing run is a row, not the end of the sweep.

Runs execute in this process (``workers = 1``), in local worker processes
(:class:`multiprocessing.pool.Pool`; the workers ignore SIGINT, so Ctrl-C reaches only this
process, which then terminates them), or on a Dask distributed cluster (``scheduler`` = its
address); workers get the runs in batches (:data:`BATCHES_PER_WORKER`, at most
:data:`MAX_RUNS_PER_BATCH` runs each). An interrupted or failed sweep writes the rows that
finished and says so (:class:`~armgen.errors.Interrupted`), so ``--resume`` runs only the rest.
The rows are sorted by run index whichever way they ran.

A sweep has at most :data:`MAX_SWEEP_RUNS` runs (grid combinations × draws), and every swept
key must be a field of the task's schema (:func:`check_fields`), both checked before anything
runs; a swept value the schema refuses is that run's error row. ``--resume`` reads the output
only when it is a table this command wrote (its fixed columns, integer run indices, JSON
``overrides``); anything else is refused, never replaced.
"""

from __future__ import annotations

import contextlib
import copy
import datetime
import io
import itertools
import json
import math
import multiprocessing
import os
import signal
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

import numpy as np
from pydantic import ValidationError

from ..errors import ArmgenError, Interrupted, TaskFileError, ToolchainError, excerpt
from ..fileio import atomic_open
from ..progress import progress
from ..schemas import closest_key
from .registry import PLANNER_NAMES, planner
from .tasks import parse_value, run_task, set_field, validate_task

FORMATS = (".csv", ".parquet")
FIXED_COLUMNS = ("run", "status", "exit_code", "message", "overrides")
# Summary entries that measure the machine, not the plan.
WALL_TIME_KEYS = ("run_time_s", "plan_seconds")
# The most runs one sweep may have (grid combinations × random draws): a table of this many
# rows is tens of MB and a day of planning; a longer survey is several sweeps (or --resume).
MAX_SWEEP_RUNS = 100_000


@dataclass(frozen=True)
class Range:
    """Uniform draws between ``low`` and ``high`` (numbers, or equally long lists: per element)."""

    key: str
    low: Any
    high: Any


@dataclass
class SweepSpec:
    grid: list[tuple[str, list[Any]]] = field(default_factory=list)
    ranges: list[Range] = field(default_factory=list)
    draws: int = 0
    seed: int = 0

    def count(self) -> int:
        """How many runs :meth:`runs` gives (without making them)."""
        return math.prod(len(values) for _, values in self.grid) * (self.draws if self.ranges else 1)

    def check(self) -> None:
        """Refuse a sweep that is not one: ranges without draws (or draws without ranges),
        nothing to vary, or more than :data:`MAX_SWEEP_RUNS` runs."""
        if self.ranges and not self.draws:
            raise TaskFileError("--range needs --random N (the number of draws)")
        if self.draws and not self.ranges:
            raise TaskFileError("--random needs at least one --range KEY=LO:HI to draw")
        if not self.grid and not self.ranges:
            raise TaskFileError("nothing to sweep: give --grid KEY=ARRAY and/or --random N with --range KEY=LO:HI")
        self.check_size()

    def check_size(self) -> None:
        count = self.count()
        if count > MAX_SWEEP_RUNS:
            sizes = " × ".join([str(len(v)) for _, v in self.grid] + ([f"{self.draws} draws"] if self.ranges else []))
            raise TaskFileError(f"the sweep has {count} runs ({sizes}), more than the cap of {MAX_SWEEP_RUNS}; "
                                "split it into smaller sweeps (fewer --grid values or --random draws)")

    def runs(self) -> list[dict[str, Any]]:
        """The runs' field values: every grid combination, times every draw when drawing."""
        self.check_size()
        combos = [dict(zip([k for k, _ in self.grid], values))
                  for values in itertools.product(*[v for _, v in self.grid])]
        if not self.ranges:
            return combos
        rng = np.random.default_rng(self.seed)
        draws = [{r.key: _draw(rng, r) for r in self.ranges} for _ in range(self.draws)]
        return [{**combo, **draw} for combo in combos for draw in draws]


def _draw(rng: np.random.Generator, r: Range) -> Any:
    value = rng.uniform(np.asarray(r.low, dtype=float), np.asarray(r.high, dtype=float))
    return np.asarray(value).tolist()


def parse_grid(item: str) -> tuple[str, list[Any]]:
    """``KEY=ARRAY`` (ARRAY a TOML array of the field's values)."""
    key, values = _split(item, "--grid", "KEY=ARRAY, e.g. --grid 'method.K=[0, 1, 2]'")
    if not isinstance(values, list) or not values:
        raise TaskFileError(f"--grid {excerpt(repr(item))}: the values must be a non-empty TOML array, e.g. "
                            f"{excerpt(key)}=[1, 2]")
    if _holds_date(values):
        raise TaskFileError(f"--grid {excerpt(repr(item))}: a TOML date or time is no task value; give numbers, "
                            "strings, booleans or arrays of them")
    return key, values


def _holds_date(value: Any) -> bool:
    """Whether a parsed TOML value holds a date, time or date-time (no task field takes one)."""
    if isinstance(value, (datetime.date, datetime.time)):
        return True
    children = value.values() if isinstance(value, dict) else value if isinstance(value, list) else ()
    return any(_holds_date(v) for v in children)


def check_fields(task: dict[str, Any], spec: SweepSpec, source: str) -> None:
    """Refuse, before any run, a swept key the task's schema does not have (a typo would make
    every run an error row) or that cannot be set (a key through a value that is no table).
    A value the schema refuses stays that run's error row: a sweep may probe invalid values."""
    fields = [("--grid", key, values[0]) for key, values in spec.grid] + \
        [("--range", r.key, r.low) for r in spec.ranges]
    first = copy.deepcopy(task)
    for option, key, value in fields:
        set_field(first, key, value, f"{option} {excerpt(repr(key))}")
    if first.get("planner") not in PLANNER_NAMES:
        validate_task(first, source)  # names the unknown planner (exit 2)
    known = _unknown_fields(task)
    for option, key, value in fields:
        where = f"{option} {excerpt(repr(key))}"
        probe = copy.deepcopy(task)
        set_field(probe, key, value, where)
        for table, name, allowed in _unknown_fields(probe) - known:
            near = closest_key(name, list(allowed))
            raise TaskFileError(f"{where}: the {task['planner']} task has no field {excerpt(name)!r}"
                                f"{f' in [{table}]' if table else ''}{f' (did you mean `{near}`?)' if near else ''}; "
                                f"allowed there: {', '.join(allowed)}. Nothing was run")


def _unknown_fields(task: dict[str, Any]) -> set[tuple[str, str, tuple[str, ...]]]:
    """(table, key, allowed keys) of each key of ``task`` its planner's schema does not know
    (none when the planner is unknown: no schema to ask)."""
    if task.get("planner") not in PLANNER_NAMES:
        return set()
    try:
        planner(task["planner"]).schema.model_validate(task)
    except ValidationError as exc:
        return {(_table_name(task, err["loc"]), name, tuple(err["ctx"]["allowed"]))
                for err in exc.errors(include_url=False) if err["type"] == "unknown_field"
                for name in err["ctx"]["unknown"]}
    return set()


def _table_name(task: dict[str, Any], loc: tuple) -> str:
    """The dotted name of the table at a pydantic error location, without its union-member tags
    (the parts that are no key of the task)."""
    names, node = [], task
    for part in loc:
        if isinstance(node, dict) and part in node:
            node = node[part]
            names.append(str(part))
    return ".".join(names)


def parse_range(item: str) -> Range:
    """``KEY=LO:HI`` (numbers, or TOML arrays of numbers for a vector field)."""
    where = f"--range {excerpt(repr(item))}"
    key, text = _split(item, "--range", "KEY=LO:HI, e.g. --range 'method.K=0:4'", parse=False)
    if text.count(":") != 1:
        raise TaskFileError(f"{where}: expected KEY=LO:HI, e.g. --range 'method.K=0:4'")
    low, high = (parse_value(part.strip(), where) for part in text.split(":"))

    def numbers(v):
        flat = v if isinstance(v, list) else [v]
        return all(isinstance(x, (int, float)) and not isinstance(x, bool) and np.isfinite(x) for x in flat)

    if not (numbers(low) and numbers(high)) or isinstance(low, list) != isinstance(high, list) or \
            (isinstance(low, list) and len(low) != len(high)):
        raise TaskFileError(f"{where}: LO and HI must be finite numbers, or TOML arrays of numbers of one length")
    if np.any(np.asarray(low, dtype=float) > np.asarray(high, dtype=float)):
        raise TaskFileError(f"{where}: LO exceeds HI; give the range as LO:HI")
    return Range(key, low, high)


def _split(item: str, option: str, usage: str, parse: bool = True) -> tuple[str, Any]:
    if "=" not in item or not item.split("=", 1)[0].strip():
        raise TaskFileError(f"{option} {excerpt(repr(item))}: expected {usage}")
    key, text = item.split("=", 1)
    return key.strip(), parse_value(text.strip(), f"{option} {excerpt(repr(item))}") if parse else text.strip()


def _cell(value: Any) -> Any:
    """A table cell: scalars as they are, lists and tables as JSON text."""
    return value if isinstance(value, (bool, int, float, str)) else json.dumps(value)


def run_one(task: dict[str, Any], source: str, sha256: str, index: int, fields: dict[str, Any],
            backend: str) -> dict[str, Any]:
    """Plan one run; never raises for a failed plan (the row says why)."""
    row: dict[str, Any] = {"run": index, **{k: _cell(v) for k, v in fields.items()}}
    row["overrides"] = json.dumps(fields, sort_keys=True)
    with _quiet():
        try:
            run = copy.deepcopy(task)
            for key, value in fields.items():
                set_field(run, key, value, f"sweep field {excerpt(repr(key))}")
            summary = run_task(run, source, sha256, backend).metadata.get("summary", {})
        except ArmgenError as exc:
            return {**row, "status": "error", "exit_code": exc.exit_code, "message": str(exc)}
        except Exception as exc:  # noqa: BLE001 -- a bug in one run is that run's row, not the sweep's end
            return {**row, "status": "error", "exit_code": 1, "message": f"{type(exc).__name__}: {exc}"}
    row.update(status="ok", exit_code=0, message="")
    for key, value in summary.items():
        if key not in WALL_TIME_KEYS and key not in row and isinstance(value, (bool, int, float, str)):
            row[key] = value
    return row


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """No per-plan progress bars inside a sweep (the sweep has its own)."""
    before = os.environ.get("ARMGEN_NO_PROGRESS")
    os.environ["ARMGEN_NO_PROGRESS"] = "1"
    try:
        yield
    finally:
        if before is None:
            del os.environ["ARMGEN_NO_PROGRESS"]
        else:
            os.environ["ARMGEN_NO_PROGRESS"] = before


def read_table(path: str | Path) -> list[dict[str, Any]]:
    """The rows of a sweep table this command wrote, to resume; anything else is refused."""
    import pandas as pd

    path = Path(path)
    advice = "choose another -o, or drop --resume (the file is left as it is)"
    try:
        if path.suffix == ".parquet":
            frame = pd.read_parquet(path)
        else:
            frame = pd.read_csv(path, keep_default_na=False, na_values=[""])
    except Exception as exc:  # noqa: BLE001 -- any unreadable file gets the same advice
        raise TaskFileError(f"{path}: cannot read the sweep table to resume ({excerpt(str(exc))}); {advice}") \
            from None
    missing = [c for c in FIXED_COLUMNS if c not in frame.columns]
    if missing:
        raise TaskFileError(f"{path}: not a table of `armgen sweep` (no column {', '.join(missing)}); {advice}")
    rows = [{k: v for k, v in r.items() if not _missing(v)} for r in frame.to_dict("records")]
    for number, row in enumerate(rows, start=2):
        problem = _row_problem(row)
        if problem:
            raise TaskFileError(f"{path}: row {number} is not a row of `armgen sweep` ({problem}); {advice}")
        row["run"] = int(row["run"])
    return rows


def _row_problem(row: dict[str, Any]) -> str | None:
    run, status, overrides = row.get("run"), row.get("status"), row.get("overrides")
    # (one text cell makes pandas read the whole column as text)
    if isinstance(run, bool) or not (isinstance(run, (int, np.integer)) and run >= 0
                                     or isinstance(run, str) and run.isascii() and run.isdigit()):
        return f"run {excerpt(repr(run))} is not a run index"
    if status not in ("ok", "error"):
        return f"status {excerpt(repr(status))} is neither ok nor error"
    try:
        fields = json.loads(overrides) if isinstance(overrides, str) else None
    except ValueError:
        fields = None
    if not isinstance(fields, dict):
        return f"overrides {excerpt(repr(overrides))} is not a JSON table of fields"
    return None


def write_table(rows: list[dict[str, Any]], path: str | Path, keys: Sequence[str]) -> None:
    """The rows sorted by run index, fixed columns first, written atomically (CSV or Parquet)."""
    import pandas as pd

    path = Path(path)
    frame = pd.DataFrame(sorted(rows, key=lambda r: r["run"]))
    first = ["run", *[k for k in keys if k in frame.columns], "status", "exit_code", "message", "overrides"]
    frame = frame[first + [c for c in frame.columns if c not in first]]
    try:
        if path.suffix == ".parquet":
            buffer = io.BytesIO()
            frame.to_parquet(buffer, index=False)
            with atomic_open(path, "wb") as handle:
                handle.write(buffer.getvalue())
        else:
            with atomic_open(path, "w", newline="") as handle:
                frame.to_csv(handle, index=False, lineterminator="\n")
    except OSError as exc:
        raise ToolchainError(f"{path}: cannot write the sweep table: {exc}") from None


def sweep(task: dict[str, Any], source: str, sha256: str, spec: SweepSpec, output: str | Path,
          backend: str = "symbolic", workers: int = 1, scheduler: str | None = None, resume: bool = False,
          echo: Callable[[str], None] = lambda _: None) -> list[dict[str, Any]]:
    """Run the sweep and write its table to ``output``; returns the rows (sorted by run)."""
    output = Path(output)
    if output.suffix not in FORMATS:
        raise TaskFileError(f"-o {output}: the table must be .csv or .parquet")
    runs = spec.runs()
    check_fields(task, spec, source)
    index = {json.dumps(fields, sort_keys=True): i for i, fields in enumerate(runs)}
    keys = list(dict.fromkeys([k for k, _ in spec.grid] + [r.key for r in spec.ranges]))
    done: list[dict[str, Any]] = []
    if resume and output.exists():
        # a finished run keeps its row, under its index in this sweep
        done = [{**r, "run": index[r["overrides"]]} for r in read_table(output) if r["overrides"] in index]
        echo(f"resuming: {len(done)} of {len(runs)} runs already in {output}")
    finished = {r["overrides"] for r in done}
    todo = [(i, fields) for i, fields in enumerate(runs) if json.dumps(fields, sort_keys=True) not in finished]
    new: list[dict[str, Any]] = []
    try:
        with contextlib.closing(_execute(task, source, sha256, todo, backend, workers, scheduler)) as results, \
                progress(len(todo), "sweep") as bar:
            for row in results:
                new.append(row)
                bar.update(1)
    except KeyboardInterrupt:
        kept = _keep(done + new, new, output, keys)
        raise Interrupted(f"interrupted after {len(new)} of {len(todo)} runs; {kept}") from None
    except BaseException as exc:
        if new:
            echo(f"the sweep stopped ({type(exc).__name__}); {_keep(done + new, new, output, keys)}")
        raise
    write_table(done + new, output, keys)
    return sorted(done + new, key=lambda r: r["run"])


def _keep(rows: list[dict[str, Any]], new: list[dict[str, Any]], output: Path, keys: Sequence[str]) -> str:
    """Write the rows of a sweep that stopped early; say what was written."""
    if not new:
        return f"no run finished: {output} was not written"
    write_table(rows, output, keys)
    return f"wrote the {len(rows)} finished runs to {output}; run the same command with --resume for the rest"


def _missing(value: Any) -> bool:
    return isinstance(value, float) and np.isnan(value)


# Runs travel to a worker in batches of several: a run takes tens of milliseconds, and each
# task costs the Dask scheduler and client ~5 ms of CPU on the machine that also computes
# (measured: 0.5 CPU s for 100 one-run tasks). This many batches per worker keeps that cost
# small and still lets the last batches even out the workers' loads.
BATCHES_PER_WORKER = 16
# ... and a batch holds at most this many runs: a batch's rows come back when all of it is done,
# and Ctrl-C stops the workers at once, so an interrupted sweep loses at most one batch a
# worker (16 runs: about a second of planning) instead of 1/16 of its share (a 20 000-run sweep
# on 2 workers: 625 runs a batch, nothing kept after 45 s). The per-task cost (~5 ms on Dask)
# stays a few per cent of a batch's work.
MAX_RUNS_PER_BATCH = 16


def run_batch(task: dict[str, Any], source: str, sha256: str, runs: list[tuple[int, dict[str, Any]]],
              backend: str) -> list[dict[str, Any]]:
    """:func:`run_one` for each ``(index, fields)`` of ``runs``: a worker's unit of work."""
    return [run_one(task, source, sha256, index, fields, backend) for index, fields in runs]


def _batches(todo: list, workers: int) -> list[list]:
    size = min(MAX_RUNS_PER_BATCH, max(1, -(-len(todo) // (workers * BATCHES_PER_WORKER))))
    return [todo[k:k + size] for k in range(0, len(todo), size)]


def _ignore_sigint() -> None:
    """In a worker: Ctrl-C is for the sweep's own process, which stops the workers."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _run_batch_args(args: tuple) -> list[dict[str, Any]]:
    return run_batch(*args)


@contextlib.contextmanager
def _deferred_sigint() -> Iterator[list[int]]:
    """Ctrl-C during an in-process sweep only sets a flag (the list it yields fills), checked
    between runs. A KeyboardInterrupt raised inside a run would not stop the sweep: CasADi turns
    an interrupt in its C++ into a RuntimeError, which becomes that run's error row, and the
    sweep went on to the end. (Main thread only: Python delivers signals there.)"""
    pending: list[int] = []
    if threading.current_thread() is not threading.main_thread():
        yield pending
        return
    previous = signal.signal(signal.SIGINT, lambda signum, frame: pending.append(signum))
    try:
        yield pending
    finally:
        signal.signal(signal.SIGINT, previous)


def _execute(task, source, sha256, todo, backend, workers, scheduler) -> Iterator[dict[str, Any]]:
    if scheduler:
        yield from _on_dask(scheduler, task, source, sha256, todo, backend)
    elif workers <= 1 or len(todo) <= 1:
        with _deferred_sigint() as interrupted:
            for index, fields in todo:
                row = run_one(task, source, sha256, index, fields, backend)
                if interrupted:  # the run in progress is not kept: the signal also reached its compiler
                    raise KeyboardInterrupt
                yield row
    else:
        # The planner's modules, imported once here, are inherited by forked workers.
        if task.get("planner") in PLANNER_NAMES:
            planner(task["planner"])
        batches = _batches(todo, workers)
        pool = multiprocessing.Pool(min(workers, len(batches)), initializer=_ignore_sigint)
        try:
            for rows in pool.imap_unordered(_run_batch_args, [(task, source, sha256, b, backend) for b in batches]):
                yield from rows
        except BaseException:
            pool.terminate()  # Ctrl-C, an error, or the caller closing this generator: stop the workers now
            raise
        else:
            pool.close()
        finally:
            pool.join()


# How long connecting to --scheduler may take (a scheduler answers in milliseconds).
SCHEDULER_TIMEOUT_S = 10


def _on_dask(address: str, task, source, sha256, todo, backend) -> Iterator[dict[str, Any]]:
    try:
        from distributed import Client, as_completed as dask_completed
    except ImportError:
        raise ToolchainError("--scheduler needs Dask distributed: pip install 'dask[distributed]'") from None
    try:
        client = Client(address, timeout=f"{SCHEDULER_TIMEOUT_S}s")
    except Exception as exc:  # noqa: BLE001 -- whatever the address holds, it is not a usable scheduler
        raise ToolchainError(f"--scheduler {excerpt(address)}: cannot reach a Dask scheduler there "
                             f"({type(exc).__name__}: {excerpt(str(exc))}); start one with `dask scheduler` "
                             "and workers with `dask worker ADDRESS`, and give its address (tcp://host:8786)") from None
    with client:
        workers = max(1, sum(client.nthreads().values()))
        futures = [client.submit(run_batch, task, source, sha256, batch, backend, pure=False)
                   for batch in _batches(todo, workers)]
        for future in dask_completed(futures):
            yield from future.result()
