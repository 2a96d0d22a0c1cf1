"""What ``armgen verify`` does not redo (issue 41): builds and verdicts kept in the kernel store
(:mod:`armgen.codegen.kernel_store`: this user's alone, every file's SHA-256 checked), keyed by
the content hashes of everything they depend on.

- A **build** (the kernel library of a precision: :func:`armgen.codegen.api_kernel.kernel_library`,
  shared with the API; the sanitizer driver) is named by the digest of the bytes it is compiled
  from, the compiler and its flags; it is used only when its bytes match the SHA-256 its entry
  records, else it is built again (a tampered or truncated file is replaced, never loaded).
- A **verdict** (the fresh stage's; a precision's compile and callbacks rows; the replay of a plan) is stored only
  when it passed, under the digest of every input that decides it: the generated files' bytes,
  armgen itself (all its sources, templates and firmware files, CasADi's and NumPy's versions),
  the compiler, the options (samples, seed, precision) and, for the replay, the plan's CSV and
  plan.json bytes. A change to any of them is another key: the stage runs again. So
  ``armgen verify --plan P --run R`` right after ``armgen verify --plan P`` of the same folder
  only hashes the folder's files and the plan, and compares the run.
"""

from __future__ import annotations

import functools
import hashlib
import platform
import sys
import time
from pathlib import Path
from typing import Any

import casadi as ca
import numpy as np

from ..codegen import kernel_store

# Bumped when a record's layout or what a verdict means changes: older records are not read.
RECORD_FORMAT = 1


@functools.lru_cache(maxsize=1)
def armgen_fingerprint() -> str:
    """armgen's every file (sources, templates, firmware stub, bundled data) and the versions of
    the numerics it runs on (CasADi, NumPy, Python, the C library whose libm both the reference
    and the C call): an edit anywhere verifies afresh (~10 ms)."""
    digest = hashlib.sha256(repr((RECORD_FORMAT, ca.__version__, np.__version__, sys.version,
                                  platform.libc_ver())).encode())
    package = Path(__file__).resolve().parents[1]
    for path in sorted(package.rglob("*")):
        if path.is_file() and "__pycache__" not in path.parts:
            digest.update(str(path.relative_to(package)).encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def content_key(*parts: Any) -> str:
    """The SHA-256 of ``parts`` (their repr: strings, numbers, tuples of them)."""
    return hashlib.sha256(repr(parts).encode()).hexdigest()


def file_digests(folder: Path, names: list[str]) -> tuple[tuple[str, str], ...]:
    """(name, SHA-256 of its bytes) of each file, in order."""
    return tuple((name, kernel_store.digest((folder / name).read_bytes())) for name in names)


def read_verdict(kind: str, key: str) -> dict[str, Any] | None:
    """A passed verdict stored under ``key`` (:func:`write_verdict`), or None."""
    record = kernel_store.read_record(f"verdict_{kind}", key)
    return record if isinstance(record, dict) and record.get("format") == RECORD_FORMAT else None


def write_verdict(kind: str, key: str, value: dict[str, Any]) -> None:
    """Keep a passed verdict under ``key``, with the time it was reached."""
    kernel_store.write_record(f"verdict_{kind}", key, {"format": RECORD_FORMAT, "verified_at": time.time(), **value})


def when(record: dict[str, Any]) -> str:
    """When a verdict was reached, as the report says it."""
    return time.strftime("%Y-%m-%d %H:%M:%S UTC", time.gmtime(float(record["verified_at"])))
