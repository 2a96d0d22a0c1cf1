"""The planner output: one table (CSV) plus metadata (JSON sidecar), written atomically.

Column names carry their unit after the last underscore-separated token group, e.g.
``t_s``, ``q1_rad``, ``dq1_rad_s``, ``ddq1_rad_s2``, ``x_m``. ``--units deg`` rescales every
column whose unit starts with ``rad`` to degrees and renames it (``q1_deg``, ``dq1_deg_s``).
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..fileio import atomic_open

ANGLE_UNITS = ("rad", "deg")


@dataclass
class PlanResult:
    columns: list[str]
    data: np.ndarray  # shape (samples, len(columns))
    metadata: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.data = np.asarray(self.data, dtype=float)
        if self.data.ndim != 2 or self.data.shape[1] != len(self.columns):
            raise ValueError(f"plan data shape {self.data.shape} does not match {len(self.columns)} columns")

    def column(self, name: str) -> np.ndarray:
        return self.data[:, self.columns.index(name)]


def _split_unit(column: str) -> tuple[str, str]:
    """('dq1', 'rad_s') for 'dq1_rad_s'; unit is everything from the first unit token."""
    parts = column.split("_")
    for k in range(1, len(parts)):
        if parts[k] in ("rad", "deg", "m", "s", "mm", "1"):
            return "_".join(parts[:k]), "_".join(parts[k:])
    return column, ""


def convert_angle_units(columns: list[str], data: np.ndarray, units: str) -> tuple[list[str], np.ndarray]:
    if units not in ANGLE_UNITS:
        raise ValueError(f"units must be one of {ANGLE_UNITS}, got {units!r}")
    if units == "rad":
        return list(columns), data
    data = data.copy()
    out = []
    for k, col in enumerate(columns):
        stem, unit = _split_unit(col)
        if unit.startswith("rad"):
            data[:, k] = np.degrees(data[:, k])
            out.append(f"{stem}_deg{unit[3:]}")
        else:
            out.append(col)
    return out, data


def _json_default(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer)):
        return value.item()
    if isinstance(value, np.bool_):
        return bool(value)
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def _finite_json(value: Any) -> Any:
    """JSON has no NaN/inf: write them as strings so the file stays standard JSON."""
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {k: _finite_json(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_finite_json(v) for v in value]
    return value


def metadata_path(csv_path: str | Path) -> Path:
    return Path(csv_path).with_suffix(".json")


def write_plan(result: PlanResult, csv_path: str | Path, units: str = "rad") -> tuple[Path, Path]:
    """Write ``plan.csv`` and ``plan.json`` beside it, each atomically."""
    csv_path = Path(csv_path)
    columns, data = convert_angle_units(result.columns, result.data, units)
    with atomic_open(csv_path, "w", newline="") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(columns)
        for row in data.tolist():  # Python floats: repr is the shortest round-trip text
            writer.writerow(map(repr, row))
    meta = dict(result.metadata)
    meta["csv"] = {"file": csv_path.name, "columns": columns, "samples": int(data.shape[0]), "angle_units": units}
    json_path = metadata_path(csv_path)
    with atomic_open(json_path, "w") as handle:
        json.dump(_finite_json(json.loads(json.dumps(meta, default=_json_default))), handle, indent=2, sort_keys=False)
        handle.write("\n")
    return csv_path, json_path


def read_plan(csv_path: str | Path) -> PlanResult:
    """Read a plan CSV (and its JSON sidecar when present); angles come back in radians."""
    csv_path = Path(csv_path)
    with open(csv_path, newline="", encoding="utf-8") as handle:
        reader = csv.reader(handle)
        try:
            columns = next(reader)
        except StopIteration:
            raise ValueError(f"{csv_path}: empty plan file") from None
        rows = [[float(v) for v in row] for row in reader if row]
    data = np.array(rows, dtype=float).reshape(len(rows), len(columns))
    # back to SI: columns in degrees become radians
    out_cols = []
    for k, col in enumerate(columns):
        stem, unit = _split_unit(col)
        if unit.startswith("deg"):
            data[:, k] = np.radians(data[:, k])
            out_cols.append(f"{stem}_rad{unit[3:]}")
        else:
            out_cols.append(col)
    meta_file = metadata_path(csv_path)
    meta = json.loads(meta_file.read_text(encoding="utf-8")) if meta_file.is_file() else {}
    return PlanResult(out_cols, data, meta)
