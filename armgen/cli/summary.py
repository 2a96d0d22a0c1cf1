"""What ``armgen plan`` prints: the plan's summary as a short table in the task file's units, and
a hint when a task without ``[units]`` holds numbers that look like millimetres or degrees.

``plan.json``'s ``summary`` stays in the units its keys name (``max_pos_error_mm``,
``max_abs_q_deg``: SI or the planner's choice); the table converts each figure to the task
file's ``[units]`` (default m and rad), so the numbers read like the ones the user wrote. A list
(one value per joint or link) is shown by its extreme and where it is; a table of named values
(per joint, per obstacle) likewise or in full when short. docs/input-files.md describes both.
"""

from __future__ import annotations

import math
from typing import Any

from ..description.files import ANGLE_UNITS, LENGTH_UNITS

# Summary-key unit tokens (the last "_"-separated token, before any time exponent "s"/"s2"):
# dimension, SI scale of the token's unit, and power of the dimension.
UNIT_TOKENS = {
    "m": ("length", 1.0, 1), "mm": ("length", 1e-3, 1), "mm3": ("length", 1e-3, 3),
    "rad": ("angle", 1.0, 1), "deg": ("angle", math.pi / 180, 1), "rad2": ("angle", 1.0, 2),
}
TIME_TOKENS = {"s": 1, "s2": 2, "s3": 3}
FILE_UNIT_SCALE = {**LENGTH_UNITS, **ANGLE_UNITS}  # the robot and task files' units, to SI
SUPERSCRIPTS = {1: "", 2: "²", 3: "³"}
SHOWN_IN_FULL = 3  # a list or table of at most this many values is printed whole (xyz, a range, two obstacles)
SIGNIFICANT = 4  # digits of a figure in the table: enough to compare runs, short enough to scan
# The hint's thresholds. No arm armgen plans for reaches 3 m from its base (the bundled arms
# reach at most 1.3 m, large industrial arms about 3 m): a position beyond reads as millimetres.
# An orientation angle or joint value beyond a full turn reads as degrees.
HINT_LENGTH_M = 3.0
HINT_ANGLE_RAD = 2 * math.pi


def file_units(metadata: dict[str, Any]) -> tuple[str, str]:
    """(length, angle) unit of the task file a plan was made from (default m, rad)."""
    task = metadata.get("task") if isinstance(metadata.get("task"), dict) else {}
    units = task.get("units") if isinstance(task.get("units"), dict) else {}
    length, angle = units.get("length", "m"), units.get("angle", "rad")
    return (length if length in FILE_UNIT_SCALE else "m"), (angle if angle in FILE_UNIT_SCALE else "rad")


def _label(tokens: list[str]) -> str:
    """Words of a key, a symbol's subscript kept: H_M_before_lock → "H_M before lock"."""
    label = tokens[0]
    for previous, token in zip(tokens, tokens[1:]):
        label += ("_" if len(previous) == 1 and previous.isupper() and len(token) == 1 else " ") + token
    return label


def _key_unit(key: str) -> tuple[str, tuple[str, float, int] | None, int]:
    """(label, (dimension, SI scale, power) or None, time exponent) of a summary key."""
    tokens = key.split("_")
    per_time = 0
    if len(tokens) > 1 and tokens[-1] in TIME_TOKENS and tokens[-2] in UNIT_TOKENS:
        per_time = TIME_TOKENS[tokens.pop()]
    if len(tokens) > 1 and tokens[-1] in UNIT_TOKENS:
        unit = UNIT_TOKENS[tokens.pop()]
        return _label(tokens), unit, per_time
    if len(tokens) > 1 and tokens[-1] == "s":  # a time: duration_s, run_time_s
        tokens.pop()
        return _label(tokens), None, -1
    return _label(tokens), None, 0


class _Converter:
    """A summary key's values in the file's units, and the unit's name."""

    def __init__(self, key: str, units: tuple[str, str]):
        self.label, unit, per_time = _key_unit(key)
        self.factor, self.unit = 1.0, ""
        if per_time == -1:
            self.unit = "s"
        elif unit is not None:
            dimension, si_scale, power = unit
            shown = units[0] if dimension == "length" else units[1]
            self.factor = (si_scale / FILE_UNIT_SCALE[shown]) ** power
            self.unit = shown + SUPERSCRIPTS[power] + (f"/s{SUPERSCRIPTS[per_time]}" if per_time else "")

    def number(self, value: float) -> str:
        return _figure(value * self.factor)


def _figure(value: Any) -> str:
    if value is None:
        return "—"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        return f"{value + 0.0:.{SIGNIFICANT}g}"  # + 0.0: no "-0"
    return str(value)


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _extreme(values: list[float], smallest: bool) -> int:
    """Index of the smallest value (a minimum's key) or of the largest magnitude."""
    if smallest:
        return min(range(len(values)), key=lambda k: values[k])
    return max(range(len(values)), key=lambda k: abs(values[k]))


def _numbers(key: str, values: list[Any], names: list[str], convert: _Converter) -> str:
    """A list (names "joint k") or table of numbers: whole when short, else its extreme and where."""
    shown = [(name, value) for name, value in zip(names, values) if _is_number(value)]
    if not shown:
        return "—"
    if len(values) <= SHOWN_IN_FULL:
        if names[0].startswith("#"):
            return "[" + ", ".join(convert.number(v) for _, v in shown) + "]"
        return ", ".join(f"{name} {convert.number(v)}" for name, v in shown)
    k = _extreme([v for _, v in shown], smallest=key.startswith("min"))
    kind = "min" if key.startswith("min") else "max |·|" if any(v < 0 for _, v in shown) else "max"
    name = shown[k][0].replace("#", "joint ") if shown[k][0].startswith("#") else shown[k][0]
    return f"{kind} {convert.number(shown[k][1])} ({name} of {len(values)})"


def _entries(value: list[Any]) -> str:
    """A list of findings (limit violations, speed excursions): how many, and the first."""
    if not value:
        return "none"
    first = value[0]
    if isinstance(first, dict):
        first = ", ".join(f"{k} {_figure(v)}" for k, v in first.items() if not isinstance(v, (list, dict)))
    return f"{len(value)} (first: {first})" if len(value) > 1 else str(first)


def _joint_speed_rows(speed: dict[str, Any]) -> list[tuple[str, str, str]]:
    """The joint-speed report, as a robotics engineer reads it: peak ratios and the verdict."""
    rows = []
    for label, ratios, limit in (("peak joint speed", speed.get("peak_speed_ratio"), "qdlim"),
                                 ("peak joint acceleration", speed.get("peak_acceleration_ratio"), "qddlim")):
        known = [(k, r) for k, r in enumerate(ratios or []) if _is_number(r)]
        if known:
            k, ratio = max(known, key=lambda item: item[1])
            rows.append((label, f"{ratio:.0%} of {limit} (joint {k + 1})", ""))
    if "within_speed_limits" in speed:
        rows.append(("within speed limits", _figure(speed["within_speed_limits"]), ""))
    if speed.get("beyond_speed_limits"):
        rows.append(("beyond speed limits", _entries(speed["beyond_speed_limits"]), ""))
    if _is_number(speed.get("time_added_s")) and speed["time_added_s"] > 0:
        rows.append(("time added to keep them", _figure(float(speed["time_added_s"])), "s"))
    return rows


def _joint_torque_rows(torque: dict[str, Any]) -> list[tuple[str, str, str]]:
    """The joint-torque report (a robot with inertials): the peak torque per joint in N·m (N for a
    prismatic joint), the highest share of a taumax and the verdict."""
    if not torque.get("computed", True):
        return [("joint torque", "not computed", "")]
    rows = []
    peaks = torque.get("peak_torque") or []
    if peaks and all(_is_number(v) for v in peaks):
        rows.append(("peak joint torque", _numbers("peak_torque", peaks, [f"#{k + 1}" for k in range(len(peaks))],
                                                   _Converter("peak_torque", ("m", "rad"))), "N·m"))
    known = [(k, r) for k, r in enumerate(torque.get("peak_torque_ratio") or []) if _is_number(r)]
    if known:
        k, ratio = max(known, key=lambda item: item[1])
        rows.append(("peak joint torque of taumax", f"{ratio:.0%} (joint {k + 1})", ""))
    if "within_torque_limits" in torque:
        rows.append(("within torque limits", _figure(torque["within_torque_limits"]), ""))
    if torque.get("beyond_torque_limits"):
        rows.append(("beyond torque limits", _entries(torque["beyond_torque_limits"]), ""))
    slowing = torque.get("slowing") or {}
    if _is_number(slowing.get("time_added_s")) and slowing["time_added_s"] > 0:
        rows.append(("time added for torque", _figure(float(slowing["time_added_s"])), "s"))
    return rows


def _rows(key: str, value: Any, units: tuple[str, str], prefix: str = "") -> list[tuple[str, str, str]]:
    convert = _Converter(key, units)
    label = prefix + convert.label
    if key == "joint_speed" and isinstance(value, dict):
        return _joint_speed_rows(value)
    if key == "joint_torque" and isinstance(value, dict):
        return _joint_torque_rows(value)
    if isinstance(value, dict):
        named_units = any(_key_unit(sub)[1] is not None or _key_unit(sub)[2] for sub in value)
        if convert.unit or (value and not named_units and all(_is_number(v) for v in value.values())):
            # values per joint or obstacle, in the key's unit
            flat = {name: _extreme_of(v, key) if isinstance(v, list) else v for name, v in value.items()}
            return [(label, _numbers(key, list(flat.values()), list(flat), convert), convert.unit)]
        return [row for sub, item in value.items() for row in _rows(sub, item, units, label + " ")]
    if isinstance(value, list):
        if value and all(_is_number(v) for v in value):
            return [(label, _numbers(key, value, [f"#{k + 1}" for k in range(len(value))], convert), convert.unit)]
        return [(label, _entries(value), "")]
    if _is_number(value):
        return [(label, convert.number(value), convert.unit)]
    return [(label, _figure(value), "")]


def _extreme_of(values: list[Any], key: str) -> float | None:
    numbers = [v for v in values if _is_number(v)]
    return numbers[_extreme(numbers, key.startswith("min"))] if numbers else None


def summary_rows(metadata: dict[str, Any]) -> list[tuple[str, str, str]]:
    """(quantity, value, unit) of every figure in the plan's summary, in the task file's units."""
    units = file_units(metadata)
    summary = metadata.get("summary") if isinstance(metadata.get("summary"), dict) else {}
    return [row for key, value in summary.items() for row in _rows(key, value, units)]


def summary_table(metadata: dict[str, Any]) -> str:
    """The plan's summary as an aligned text table (:func:`summary_rows`)."""
    rows = summary_rows(metadata)
    length, angle = file_units(metadata)
    width = max((len(label) for label, _, _ in rows), default=0)
    lines = [f"summary in the task file's units ({length}, {angle}); plan.json holds every figure:"]
    lines += [f"  {label:<{width}}  {value} {unit}".rstrip() for label, value, unit in rows]
    return "\n".join(lines)


# -- the [units] hint ---------------------------------------------------------------------------

def _points(value: Any) -> list[float]:
    """The numbers of a point, a list of points or a table of per-joint lists."""
    if _is_number(value):
        return [float(value)]
    if isinstance(value, list):
        return [x for item in value for x in _points(item)]
    if isinstance(value, dict):
        return [x for item in value.values() for x in _points(item)]
    return []


def _fields(task: dict[str, Any]) -> tuple[list[tuple[str, Any]], list[tuple[str, Any]]]:
    """(length fields, angle fields) of a task, as (dotted name, value), by planner."""
    def at(*keys: Any) -> Any:
        value: Any = task
        for key in keys:
            if isinstance(key, int):
                value = value[key] if isinstance(value, list) and key < len(value) else None
            else:
                value = value.get(key) if isinstance(value, dict) else None
        return value

    lengths, angles = [], []
    if task.get("planner") == "ptp":
        angles += [("waypoints.theta", at("waypoints", "theta")), ("waypoints.rpy", at("waypoints", "rpy"))]
        return [], angles
    if task.get("planner") == "snake":
        lengths += [("path.waypoints", at("path", "waypoints")), ("rail.start", at("rail", "start"))]
        return lengths, []
    lengths += [("path.via", at("path", "via")), ("path.end", at("path", "end")),
                ("start.pose.xyz", at("start", "pose", "xyz"))]
    angles += [("path.end_rpy", at("path", "end_rpy")), ("start.pose.rpy", at("start", "pose", "rpy")),
               ("start", at("start") if isinstance(at("start"), list) else None),
               ("start.seed", at("start", "seed") if isinstance(at("start", "seed"), list) else None)]
    moves = at("path", "moves")
    for k in range(len(moves) if isinstance(moves, list) else 0):
        lengths += [(f"path.moves[{k}].to.xyz", at("path", "moves", k, "to", "xyz")),
                    (f"path.moves[{k}].via.xyz", at("path", "moves", k, "via", "xyz"))]
        angles.append((f"path.moves[{k}].to.rpy", at("path", "moves", k, "to", "rpy")))
    return lengths, angles


def units_hints(task: dict[str, Any], source: str) -> list[str]:
    """One line per unit the task leaves to the default (m, rad) although its numbers look like
    millimetres (a position beyond :data:`HINT_LENGTH_M`) or degrees (an angle beyond
    :data:`HINT_ANGLE_RAD`); empty when ``[units]`` names the unit or the numbers fit."""
    units = task.get("units") if isinstance(task.get("units"), dict) else {}
    lengths, angles = _fields(task)
    hints = []
    for fields, unit, bound, what, fix in (
            (lengths, "length", HINT_LENGTH_M, "m: no arm reaches that far", 'length = "mm"'),
            (angles, "angle", HINT_ANGLE_RAD, "rad: more than a full turn", 'angle = "deg"')):
        if unit in units:
            continue
        for name, value in fields:
            big = [x for x in _points(value) if abs(x) > bound]
            if big:
                hints.append(f"{source}: {name} holds {big[0]:g}, read as {big[0]:g} {what} (the file has no [units] "
                             f"{unit}); if the file is in {'millimetres' if unit == 'length' else 'degrees'}, add "
                             f"[units] {fix}")
                break
    return hints
