"""Task files (TOML): loading, ``--set`` overrides, and dispatch to the planner named by
the file's ``planner`` field. Each planner module exposes ``plan_task(task, source)``
returning a :class:`PlanResult`; it parses the task dict into its own typed config."""

from __future__ import annotations

import hashlib
import importlib
import math
import sys
import time
from pathlib import Path
from typing import Any

from .. import __version__
from ..errors import TaskFileError
from .result import PlanResult

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

# planner name -> its package: ``planner.plan_task(task: dict, source: str, backend: str)`` and
# ``plots.<function>(result, out_path)``
PLANNERS = {
    "ptp": "armgen.planning.ptp",
    "cartesian": "armgen.planning.cartesian",
    "fault_tolerant": "armgen.planning.fault_tolerant",
    "wgpm": "armgen.planning.wgpm",
    "snake": "armgen.planning.snake",
}
PLOT_FUNCTIONS = {"ptp": "plot_ptp", "cartesian": "plot_resolved_rate", "fault_tolerant": "plot_fault_tolerant",
                  "wgpm": "plot_wgpm", "snake": "plot_snake"}


def load_task(path: str | Path) -> tuple[dict[str, Any], str]:
    """Read a task file; returns the parsed dict and the file's sha256."""
    path = Path(path)
    if not path.is_file():
        raise TaskFileError(f"{path}: task file not found")
    data = path.read_bytes()
    try:
        task = tomllib.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise TaskFileError(f"{path}: not valid TOML: {exc}") from None
    return task, hashlib.sha256(data).hexdigest()


def _parse_value(text: str) -> Any:
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text  # a bare word is a string


def set_field(task: dict[str, Any], key: str, value: Any, where: str) -> None:
    """Set the task field ``key`` (dotted keys reach into tables) to ``value``; ``where`` names
    the option in errors."""
    parts = [p.strip() for p in key.split(".")]
    if not all(parts):
        raise TaskFileError(f"{where}: empty key component in {key!r}")
    node = task
    for part in parts[:-1]:
        nxt = node.setdefault(part, {})
        if not isinstance(nxt, dict):
            raise TaskFileError(f"{where}: '{part}' is not a table in the task file")
        node = nxt
    node[parts[-1]] = value


def apply_overrides(task: dict[str, Any], overrides: list[str]) -> dict[str, Any]:
    """Apply ``key=value`` overrides; dotted keys reach into tables; values are TOML."""
    for item in overrides:
        if "=" not in item:
            raise TaskFileError(f"--set {item!r}: expected key=value (e.g. --set integrator.h=0.01)")
        key, raw = item.split("=", 1)
        set_field(task, key, _parse_value(raw.strip()), f"--set {item!r}")
    return task


def check_finite_tree(value: Any, where: str, source: str) -> None:
    """Reject NaN/inf anywhere in a task (TOML allows 'nan' and 'inf' literals)."""
    if isinstance(value, float) and not math.isfinite(value):
        raise TaskFileError(f"{source}: field '{where}' is {value}; give a finite number")
    if isinstance(value, dict):
        for k, v in value.items():
            check_finite_tree(v, f"{where}.{k}" if where else k, source)
    elif isinstance(value, list):
        for k, v in enumerate(value):
            check_finite_tree(v, f"{where}[{k}]", source)


def run_task(task: dict[str, Any], source: str, task_sha256: str = "", backend: str = "symbolic") -> PlanResult:
    check_finite_tree(task, "", source)
    planner = task.get("planner")
    if planner not in PLANNERS:
        raise TaskFileError(
            f"{source}: field 'planner' = {planner!r} is not one of {', '.join(sorted(PLANNERS))}; "
            "set planner = \"<name>\" at the top of the task file"
        )
    module = importlib.import_module(PLANNERS[planner] + ".planner")
    started = time.perf_counter()
    result: PlanResult = module.plan_task(task, source, backend)
    elapsed = time.perf_counter() - started
    meta = {
        "armgen_version": __version__,
        "task_file": source,
        "task_sha256": task_sha256,
        "planner": planner,
        "backend": backend,
        "task": task,
    }
    meta.update(result.metadata)
    meta.setdefault("summary", {})["run_time_s"] = elapsed
    result.metadata = meta
    return result


def plot_plan(result: PlanResult, out_path: str | Path, source: str) -> None:
    """Draw a plan with its planner's figure."""
    planner = result.metadata.get("planner")
    if planner not in PLANNERS:
        raise TaskFileError(f"{source}: no plot for planner {planner!r} (plan.json missing or unknown planner)")
    module = importlib.import_module(PLANNERS[planner] + ".plots")
    getattr(module, PLOT_FUNCTIONS[planner])(result, out_path)
