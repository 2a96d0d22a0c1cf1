"""Shared machinery of the input schemas (robot file, task files, plan metadata).

Every file kind has one pydantic model; this module holds what they share: the strict base
model (unknown keys are errors that suggest the closest valid key, numbers must be finite,
no silent type coercion), bounded TOML reading (file size and nesting depth), the identifier
rule for names that later become file names and C identifiers, and the conversion of a
pydantic ``ValidationError`` into one message that names the file, the field and the fix.
"""

from __future__ import annotations

import difflib
import os
import stat
import sys
from pathlib import Path
from typing import Any, Callable

from pydantic import BaseModel, ConfigDict, ValidationError, model_validator
from pydantic_core import PydanticCustomError

from .errors import excerpt

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

# An input file larger than this is not a hand-written robot or task description; refusing
# it up front keeps a stray binary or log from taking the parser's time and memory.
MAX_INPUT_FILE_BYTES = 1 << 20
# The deepest nesting any armgen file needs is 4 (a task's [method.criteria.<name>] table of
# arrays); 16 leaves room while keeping the recursive parser and validator far from the
# interpreter's recursion limit.
MAX_NESTING_DEPTH = 16
# Names become file names (generated/<name>/) and C identifiers: ASCII letter first, then
# letters, digits and underscores, at most 48 characters (C99 guarantees 63 significant
# characters of an external identifier; the longest prefix armgen adds is 15).
IDENTIFIER_PATTERN = r"^[A-Za-z][A-Za-z0-9_]{0,47}$"
IDENTIFIER_HELP = "use a letter then letters, digits or '_' (at most 48 characters), e.g. 'my_arm7'"


def closest_key(key: str, allowed: list[str]) -> str | None:
    match = difflib.get_close_matches(key, allowed, n=1, cutoff=0.6)
    return match[0] if match else None


def _allowed_keys(model: type[BaseModel]) -> list[str]:
    return sorted(info.alias or name for name, info in model.model_fields.items())


class StrictModel(BaseModel):
    """Base of every file schema: strict types, finite numbers, unknown keys rejected with
    a suggestion of the closest valid key."""

    model_config = ConfigDict(extra="forbid", strict=True, allow_inf_nan=False, populate_by_name=True,
                              protected_namespaces=())

    @model_validator(mode="before")
    @classmethod
    def _unknown_keys(cls, data: Any) -> Any:
        if isinstance(data, dict):
            allowed = _allowed_keys(cls)
            unknown = sorted(str(k) for k in data if k not in allowed)
            if unknown:
                nested = [f"{name}.{sub}" for name, info in cls.model_fields.items()
                          if isinstance(info.annotation, type) and issubclass(info.annotation, BaseModel)
                          for sub in _allowed_keys(info.annotation)]
                raise PydanticCustomError("unknown_field", "unknown field(s) {unknown}; allowed: {allowed}",
                                          {"unknown": unknown, "allowed": allowed, "nested": nested})
        return data


# The error type of a rule across fields that a model validator checks (a duplicate name, a
# field only one kind of entry may have): its message is complete, in the file's words.
RULE_ERROR = "armgen_rule"


def rule_error(message: str, at: tuple = ()) -> PydanticCustomError:
    """A model validator's failure of a rule across fields, for :func:`format_validation_error`
    to print as ``<source>: <place>: <message>``; ``at`` (keys below the validated model, e.g.
    ``("joints", 1)``) narrows the place to the entry at fault."""
    return PydanticCustomError(RULE_ERROR, "{message}", {"message": message, "at": at})


def _unknown_message(err: dict[str, Any], loc: tuple, label: str | None) -> str:
    """'<table>' has unknown field(s) k (table.k; did you mean `key`?); allowed: ..."""
    allowed = err["ctx"]["allowed"]
    parts = []
    for key in err["ctx"]["unknown"]:
        notes = [f"{_dotted(loc)}.{key}"] if loc and label is None else []
        by_last = {n.rsplit(".", 1)[1]: n for n in reversed(err["ctx"]["nested"])}
        near = by_last.get(key) or closest_key(key, allowed)
        if near is None:
            near = by_last.get(closest_key(key, list(by_last)) or "")
        if near:
            notes.append(f"did you mean `{near}`?")
        parts.append(excerpt(key) + (f" ({'; '.join(notes)})" if notes else ""))
    head = f"{label}: " if label else (f"'{_dotted(loc)}' has " if loc else "")
    return f"{head}unknown field(s) {', '.join(parts)}; allowed: {', '.join(allowed)}"


def nesting_depth(value: Any, limit: int = MAX_NESTING_DEPTH + 1) -> int:
    """Depth of nested tables/arrays (a scalar is 0), counted up to ``limit``."""
    if limit <= 0 or not isinstance(value, (dict, list)):
        return 0
    children = value.values() if isinstance(value, dict) else value
    return 1 + max((nesting_depth(v, limit - 1) for v in children), default=0)


def read_input_file(path: str | Path, limit: int, what: str, error: type[Exception]) -> bytes:
    """The bytes of an input file (robot, URDF, task, plan), at most ``limit``: read with that
    bound, not by the size the file reports (a /proc file says 0 and has more); a FIFO, device
    or folder is refused without waiting for a writer. Every failure is ``error`` naming ``what``."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except FileNotFoundError:
        raise error(f"{path}: {what} not found") from None
    except OSError as exc:
        raise error(f"{path}: cannot read the {what}: {exc.strerror or exc}") from None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            raise error(f"{path}: not a regular file (a folder, FIFO or device); give the {what} itself")
        chunks, size = [], 0
        while size <= limit:
            chunk = os.read(fd, min(1 << 20, limit + 1 - size))
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
    except OSError as exc:
        raise error(f"{path}: cannot read the {what}: {exc.strerror or exc}") from None
    finally:
        os.close(fd)
    if size > limit:
        raise error(f"{path}: larger than the {limit} bytes a {what} may have")
    return b"".join(chunks)


def parse_toml_bounded(data: bytes | str, source: str, error: type[Exception]) -> dict[str, Any]:
    """TOML text to a dict with the size and depth caps; every failure is ``error``."""
    size = len(data)
    if size > MAX_INPUT_FILE_BYTES:
        raise error(f"{source}: {size} bytes is larger than the {MAX_INPUT_FILE_BYTES} bytes an armgen input file "
                    "may have; give the robot or task description, not another file")
    if isinstance(data, bytes):
        try:
            data = data.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise error(f"{source}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    try:
        doc = tomllib.loads(data)
    except ValueError as exc:  # a TOMLDecodeError, or an integer beyond Python's digit limit
        raise error(f"{source}: not valid TOML: {excerpt(str(exc), 200)}") from None
    except RecursionError:
        doc = None
    if doc is None or nesting_depth(doc) > MAX_NESTING_DEPTH:
        raise error(f"{source}: tables/arrays nested deeper than {MAX_NESTING_DEPTH} levels; an armgen file needs "
                    "at most 4")
    return doc


def _render(value: Any) -> str:
    return excerpt(repr(value))


def _dotted(loc: tuple) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{excerpt(part)}" if out else excerpt(part))
    return out


def describe_error(err: dict[str, Any], quoted: str) -> str:
    """One pydantic error about the field named ``quoted`` as a sentence in armgen's phrasing."""
    kind, ctx, value = err["type"], err.get("ctx", {}), err.get("input")
    if kind == "missing":
        bare = quoted.strip("'")
        return f"missing field {quoted}; add '{bare.rsplit('.', 1)[-1]} = <value>'"
    if kind == "finite_number":
        return f"field {quoted} is {value}; give a finite number"
    if kind in ("float_type", "int_type", "int_from_float", "float_parsing", "int_parsing"):
        want = "an integer" if kind.startswith("int") else "a number"
        return f"field {quoted} must be {want}, got {type(value).__name__} {_render(value)}"
    wants = {"string_type": "a string", "bool_type": "true or false", "list_type": "an array",
             "dict_type": "a table", "model_type": "a table", "model_attributes_type": "a table"}
    if kind in wants:
        return f"field {quoted} must be {wants[kind]}, got {type(value).__name__} {_render(value)}"
    if kind == "literal_error":
        choices = ctx.get("expected", "").replace("'", "").replace(" or ", ", ")
        return f"field {quoted} = {_render(value)} is not one of {choices}"
    if kind in ("too_short", "too_long"):
        lo, hi, actual = ctx.get("min_length"), ctx.get("max_length"), ctx.get("actual_length")
        bound = f"at least {ctx.get('min_length')}" if kind == "too_short" else f"at most {hi}"
        if lo is not None and hi is not None and lo == hi:
            bound = str(lo)
        return f"field {quoted} must have {bound} entries, got {actual}"
    if kind in ("greater_than", "greater_than_equal", "less_than", "less_than_equal"):
        op = {"greater_than": ">", "greater_than_equal": "≥", "less_than": "<", "less_than_equal": "≤"}[kind]
        return f"field {quoted} = {_render(value)} must be {op} {next(iter(ctx.values()))}"
    if kind == "string_too_short" and ctx.get("min_length") == 1:
        return f"field {quoted} must be a non-empty string, got {_render(value)}"
    if kind == "string_pattern_mismatch":
        return f"field {quoted} = {_render(value)} is not a valid name: {IDENTIFIER_HELP}"
    return f"field {quoted} = {_render(value)}: {err['msg'].removeprefix('Value error, ')}"


def _loc_in_data(loc: tuple, data: Any) -> tuple:
    """The error location without pydantic's union-member tags (parts that are no key of the
    validated data), so it names the field as the file does."""
    out, node = [], data
    for k, part in enumerate(loc):
        if isinstance(node, dict) and part in node:
            node = node[part]
        elif isinstance(node, list) and isinstance(part, int) and 0 <= part < len(node):
            node = node[part]
        elif not (k == len(loc) - 1 and isinstance(node, dict)):
            continue  # a union tag such as 'list[float]'
        out.append(part)
    return tuple(out)


def format_validation_error(exc: ValidationError, source: str, data: Any, fix: str = "",
                            where: Callable[[tuple], str] | None = None) -> str:
    """The first error of ``exc`` as ``<source>: [<where>: ]<what>[; <fix>]``. Without
    ``where`` the field is named by its dotted path (``integrator.step``); with it, ``where``
    names the table holding the field (e.g. ``joint 2 ('elbow')``) and the field its key."""
    err = exc.errors(include_url=False)[0]
    loc = _loc_in_data(tuple(err["loc"]), data)
    if err["type"] == RULE_ERROR:
        loc += tuple(err["ctx"]["at"])
        place = where(loc) if where else _dotted(loc)
        return f"{source}: {place + ': ' if place else ''}{err['ctx']['message']}" + (f"; {fix}" if fix else "")
    unknown = err["type"] == "unknown_field"
    field_loc = loc[:-1] if loc and isinstance(loc[-1], int) else loc  # an array entry: name the array
    index = f"[{loc[-1]}]" if loc and isinstance(loc[-1], int) else ""
    if unknown:
        message = f"{source}: {_unknown_message(err, loc, where(loc) if where else None)}"
    elif where:
        quoted = f"'{field_loc[-1]}'{index}" if field_loc else "value"
        message = f"{source}: {where(field_loc[:-1])}: {describe_error(err, quoted)}"
    else:
        message = f"{source}: {describe_error(err, f'{_dotted(field_loc)!r}{index}')}"
    more = len(exc.errors()) - 1
    if more:
        message += f" (and {more} more problem{'s' if more > 1 else ''})"
    return message + (f"; {fix}" if fix else "")
