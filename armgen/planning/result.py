"""The planner output: one table (CSV) plus metadata (JSON sidecar), written atomically.

Column names carry their unit after the last underscore-separated token group, e.g.
``t_s``, ``q1_rad``, ``dq1_rad_s``, ``ddq1_rad_s2``, ``x_m``. ``--units deg`` rescales every
column whose unit starts with ``rad`` to degrees and renames it (``q1_deg``, ``dq1_deg_s``).
"""

from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from pydantic import ValidationError

from ..errors import OutputError, PlanFileError, excerpt
from ..fileio import write_file_set
from ..schemas import format_validation_error, read_input_file
from .plan_schema import PLAN_FORMAT, PlanMetadata, PlanSummary

ANGLE_UNITS = ("rad", "deg")


@dataclass
class PlanResult:
    columns: list[str]
    data: np.ndarray  # shape (samples, len(columns))
    metadata: dict[str, Any] = field(default_factory=dict)
    # The planner's typed SI configuration the plan was made with (e.g. after the integrator
    # step was refined to meet the path tolerance): the firmware's controller task is made
    # from it. In memory only (plan.json records the task it came from); None for a plan read
    # from disk.
    config: Any = field(default=None, repr=False, compare=False)
    # A program plan's final motion (toolpath.timelaw.ProgramMotion: its geometry and the time
    # law after any slowing down), in memory only: the controller's program table is made
    # from it. Not written to the CSV or plan.json; None for every other plan.
    motion: Any = field(default=None, repr=False, compare=False)

    def __post_init__(self) -> None:
        self.data = np.asarray(self.data, dtype=float)
        if self.data.ndim != 2 or self.data.shape[1] != len(self.columns):
            raise ValueError(f"plan data shape {self.data.shape} does not match {len(self.columns)} columns")

    def column(self, name: str) -> np.ndarray:
        return self.data[:, self.columns.index(name)]

    @property
    def summary(self) -> PlanSummary:
        """The planner's figures of merit (``metadata["summary"]``), typed."""
        return PlanSummary.model_validate(_plain(self.metadata.get("summary", {})))


# Columns whose +inf is a value, not a failure: the clearance to obstacles of a task that has
# none. NaN and -inf are never valid in any column.
UNBOUNDED_COLUMN_PREFIXES = ("clearance_",)


def first_invalid_sample(columns: list[str], data: np.ndarray) -> tuple[int, int] | None:
    """(row, column) of the first non-finite sample (other than +inf where it is a value), or None."""
    bad = ~np.isfinite(data)
    for k, name in enumerate(columns):
        if name.startswith(UNBOUNDED_COLUMN_PREFIXES):
            bad[:, k] = np.isnan(data[:, k]) | (data[:, k] == -np.inf)
    hits = np.argwhere(bad)
    return (int(hits[0][0]), int(hits[0][1])) if hits.size else None


def _split_unit(column: str) -> tuple[str, str]:
    """('dq1', 'rad_s') for 'dq1_rad_s'; unit is everything from the first unit token."""
    parts = column.split("_")
    for k in range(1, len(parts)):
        if parts[k] in ("rad", "deg", "m", "s", "mm", "1"):
            return "_".join(parts[:k]), "_".join(parts[k:])
    return column, ""


def convert_angle_units(columns: list[str], data: np.ndarray, units: str) -> tuple[list[str], np.ndarray]:
    if units not in ANGLE_UNITS:
        raise ValueError(f"units must be one of {ANGLE_UNITS}, got {excerpt(repr(units))}")
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


def _plain(value: Any) -> Any:
    """``value`` as plain JSON data: NumPy arrays and scalars become lists and Python numbers,
    tuples lists, and non-finite floats strings ("inf", "nan"), since JSON has no inf/NaN."""
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, (np.floating, np.integer)):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if value is None or isinstance(value, (str, int, float, bool)):
        return value
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def metadata_path(csv_path: str | Path) -> Path:
    return Path(csv_path).with_suffix(".json")


def write_plan(result: PlanResult, csv_path: str | Path, units: str = "rad") -> tuple[Path, Path]:
    """Write ``plan.csv`` and ``plan.json`` beside it, together or not at all."""
    csv_path = Path(csv_path)
    columns, data = convert_angle_units(result.columns, result.data, units)
    table = io.StringIO()
    csv.writer(table, lineterminator="\n").writerow(columns)
    # Python floats: repr is the shortest round-trip text, and no number needs CSV quoting
    table.writelines(",".join(map(repr, row)) + "\n" for row in data.tolist())
    meta = {"format": PLAN_FORMAT, **result.metadata}
    meta["csv"] = {"file": csv_path.name, "columns": columns, "samples": int(data.shape[0]), "angle_units": units}
    json_path = metadata_path(csv_path)
    if json_path == csv_path:
        raise OutputError(f"{csv_path}: the plan CSV needs a name ending in .csv (its plan.json goes beside it)")
    meta_text = json.dumps(_plain(meta), indent=2) + "\n"
    write_file_set({csv_path: table.getvalue(), json_path: meta_text})
    return csv_path, json_path


# A plan file larger than this is not something armgen wrote for a controller; reading it
# would only exhaust memory (a 10 kHz plan of 100 columns over an hour is ~0.5 GB).
MAX_PLAN_FILE_BYTES = 1 << 30


def read_plan(csv_path: str | Path) -> PlanResult:
    """Read a plan CSV (and its JSON sidecar when present); angles come back in radians.
    Any malformed content is a :class:`PlanFileError` naming the file and the line."""
    csv_path = Path(csv_path)
    try:
        text = read_input_file(csv_path, MAX_PLAN_FILE_BYTES, "plan", PlanFileError).decode("utf-8")
    except UnicodeDecodeError as exc:
        raise PlanFileError(f"{csv_path}: not UTF-8 text ({exc.reason} at byte {exc.start}); give a plan CSV "
                            "written by armgen plan") from None
    try:
        lines = list(csv.reader(io.StringIO(text, newline="")))
    except csv.Error as exc:
        raise PlanFileError(f"{csv_path}: not a CSV file ({exc}); give a plan CSV written by armgen plan") from None
    if not lines or not lines[0]:
        raise PlanFileError(f"{csv_path}: empty plan file; give a plan CSV written by armgen plan")
    columns = [c.strip() for c in lines[0]]
    if "t_s" not in columns or len(set(columns)) != len(columns):
        raise PlanFileError(f"{csv_path}: line 1: the header {excerpt(repr(columns[:6]))}... must name distinct columns including "
                            "'t_s'; give a plan CSV written by armgen plan")
    rows = []
    for number, row in enumerate(lines[1:], start=2):
        if not row:
            continue
        if len(row) != len(columns):
            raise PlanFileError(f"{csv_path}: line {number}: {len(row)} values for {len(columns)} columns; "
                                "every row needs one value per header column")
        try:
            values = [float(v) for v in row]
        except ValueError:
            bad = next(v for v in row if not _is_float(v))
            raise PlanFileError(f"{csv_path}: line {number}: {excerpt(repr(bad[:40]))} is not a number") from None
        rows.append(values)
    if not rows:
        raise PlanFileError(f"{csv_path}: no samples after the header line")
    data = np.array(rows, dtype=float)
    invalid = first_invalid_sample(columns, data)
    if invalid is not None:
        raise PlanFileError(f"{csv_path}: line {invalid[0] + 2}: column '{columns[invalid[1]]}' is "
                            f"{data[invalid]}; a plan holds finite numbers only")
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
    meta = read_plan_metadata(meta_file, columns, len(rows)) if meta_file.is_file() and meta_file != csv_path else {}
    return PlanResult(out_cols, data, meta)


def _is_float(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def read_plan_metadata(path: Path, columns: list[str], samples: int) -> dict[str, Any]:
    """plan.json (any format up to :data:`PLAN_FORMAT`), checked against :class:`PlanMetadata`
    and against its CSV."""
    try:
        raw = json.loads(read_input_file(path, MAX_PLAN_FILE_BYTES, "plan.json", PlanFileError).decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError, RecursionError) as exc:
        raise PlanFileError(f"{path}: not valid JSON ({exc}); regenerate it with armgen plan") from None
    written = raw.get("format") if isinstance(raw, dict) else None
    if isinstance(written, int) and not isinstance(written, bool) and written > PLAN_FORMAT:
        raise PlanFileError(f"{path}: field 'format' = {written}: written by a newer armgen (this one reads plan.json "
                            f"formats 1 to {PLAN_FORMAT}); upgrade armgen, or plan the task again with this one")
    try:
        meta = PlanMetadata.model_validate(raw)
    except ValidationError as exc:
        raise PlanFileError(format_validation_error(exc, str(path), raw, "regenerate it with armgen plan")) from None
    if meta.csv is not None and (meta.csv.columns != columns or meta.csv.samples != samples):
        raise PlanFileError(f"{path}: field 'csv' describes {meta.csv.samples} samples of {len(meta.csv.columns)} "
                            f"columns but the CSV has {samples} of {len(columns)}; the two files do not belong together")
    return raw
