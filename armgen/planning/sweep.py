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
(:class:`concurrent.futures.ProcessPoolExecutor`), or on a Dask distributed cluster
(``scheduler`` = its address). The rows are sorted by run index whichever way they ran.
"""

from __future__ import annotations

import contextlib
import copy
import io
import itertools
import json
import os
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterator, Sequence

import numpy as np

from ..errors import ArmgenError, TaskFileError, ToolchainError
from ..fileio import atomic_open
from ..progress import progress
from .tasks import parse_value, run_task, set_field

FORMATS = (".csv", ".parquet")
FIXED_COLUMNS = ("run", "status", "exit_code", "message", "overrides")
# Summary entries that measure the machine, not the plan.
WALL_TIME_KEYS = ("run_time_s", "plan_seconds")


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

    def runs(self) -> list[dict[str, Any]]:
        """The runs' field values: every grid combination, times every draw when drawing."""
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
        raise TaskFileError(f"--grid {item!r}: the values must be a non-empty TOML array, e.g. {key}=[1, 2]")
    return key, values


def parse_range(item: str) -> Range:
    """``KEY=LO:HI`` (numbers, or TOML arrays of numbers for a vector field)."""
    where = f"--range {item!r}"
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
        raise TaskFileError(f"{option} {item!r}: expected {usage}")
    key, text = item.split("=", 1)
    return key.strip(), parse_value(text.strip(), f"{option} {item!r}") if parse else text.strip()


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
                set_field(run, key, value, f"sweep field {key!r}")
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


def read_table(path: str | Path):
    import pandas as pd

    path = Path(path)
    try:
        if path.suffix == ".parquet":
            return pd.read_parquet(path)
        return pd.read_csv(path, keep_default_na=False, na_values=[""])
    except Exception as exc:  # noqa: BLE001 -- any unreadable file gets the same advice
        raise TaskFileError(f"{path}: cannot read the sweep table to resume ({exc}); remove it or drop --resume") \
            from None


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
    keys = list(dict.fromkeys([k for k, _ in spec.grid] + [r.key for r in spec.ranges]))
    done: list[dict[str, Any]] = []
    if resume and output.exists():
        table = read_table(output)
        wanted = {json.dumps(fields, sort_keys=True) for fields in runs}
        done = [{k: v for k, v in r.items() if not _missing(v)} for r in table.to_dict("records")
                if r.get("overrides") in wanted]
        echo(f"resuming: {len(done)} of {len(runs)} runs already in {output}")
    finished = {r["overrides"] for r in done}
    todo = [(i, fields) for i, fields in enumerate(runs) if json.dumps(fields, sort_keys=True) not in finished]
    rows = list(done)
    try:
        with progress(len(todo), "sweep") as bar:
            for row in _execute(task, source, sha256, todo, backend, workers, scheduler):
                rows.append(row)
                bar.update(1)
    finally:  # an interrupted sweep keeps what it finished, for --resume
        if rows:
            write_table(rows, output, keys)
    return sorted(rows, key=lambda r: r["run"])


def _missing(value: Any) -> bool:
    return isinstance(value, float) and np.isnan(value)


def _execute(task, source, sha256, todo, backend, workers, scheduler) -> Iterator[dict[str, Any]]:
    args = [(task, source, sha256, i, fields, backend) for i, fields in todo]
    if scheduler:
        yield from _on_dask(scheduler, args)
    elif workers <= 1 or len(args) <= 1:
        for a in args:
            yield run_one(*a)
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            futures = [pool.submit(run_one, *a) for a in args]
            for future in as_completed(futures):
                yield future.result()


def _on_dask(address: str, args) -> Iterator[dict[str, Any]]:
    try:
        from distributed import Client, as_completed as dask_completed
    except ImportError:
        raise ToolchainError("--scheduler needs Dask distributed: pip install 'dask[distributed]'") from None
    try:
        client = Client(address, timeout="10s")
    except (OSError, TimeoutError) as exc:
        raise ToolchainError(f"--scheduler {address}: cannot reach the Dask scheduler ({exc}); start one with "
                             "`dask scheduler` and workers with `dask worker ADDRESS`") from None
    with client:
        futures = [client.submit(run_one, *a, pure=False) for a in args]
        for future in dask_completed(futures):
            yield future.result()
