"""The C toolchain: strict flags, compiling generated code into shared libraries and
executables, and a clear error when a compiler is missing."""

from __future__ import annotations

import functools
import os
import shutil
import subprocess
from pathlib import Path
from typing import Sequence

from ..errors import ToolchainError

# The quality bar of spec 10: every generated file must pass these with -Werror.
STRICT_FLAGS = (
    "-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror",
    "-Wdouble-promotion", "-Wfloat-conversion", "-Wshadow",
)
SANITIZER_FLAGS = ("-fsanitize=address,undefined", "-fno-sanitize-recover=all", "-fno-omit-frame-pointer")
ARM_CPU_FLAGS = ("-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16")


def find_tool(name: str, install_hint: str) -> str:
    path = shutil.which(name)
    if path is None:
        raise ToolchainError(f"'{name}' not found on PATH; {install_hint}")
    return path


def host_cc() -> str:
    return find_tool("gcc", "install a C compiler (apt-get install -y gcc)")


def compiler_identity() -> str:
    """The host compiler's path and version: a stored build of another compiler is not reused."""
    return _identity(os.path.realpath(host_cc()))


@functools.lru_cache(maxsize=8)
def _identity(cc: str) -> str:
    version = run_tool([cc, "--version"], "asking the C compiler its version", timeout=60).stdout
    return repr((cc, version.splitlines()[:1]))


def run_tool(cmd: Sequence[str], what: str, cwd: str | Path | None = None, timeout: float = 600) -> subprocess.CompletedProcess:
    try:
        proc = subprocess.run(list(cmd), cwd=cwd, capture_output=True, text=True, timeout=timeout)
    except FileNotFoundError as exc:
        raise ToolchainError(f"{what}: cannot run {cmd[0]!r}: {exc}") from None
    except subprocess.TimeoutExpired:
        raise ToolchainError(f"{what}: {cmd[0]} did not finish within {timeout:.0f} s") from None
    if proc.returncode != 0:
        raise ToolchainError(f"{what} failed (exit {proc.returncode}):\n$ {' '.join(map(str, cmd))}\n{proc.stdout}{proc.stderr}")
    return proc


def compile_shared(sources: Sequence[Path], output: Path, defines: Sequence[str] = (), extra: Sequence[str] = (),
                   opt: str = "-O2") -> Path:
    """Compile C sources with the strict flags into a shared library for ctypes."""
    cmd = [host_cc(), *STRICT_FLAGS, opt, "-fPIC", "-shared", *[f"-D{d}" for d in defines], *extra,
           *map(str, sources), "-o", str(output), "-lm"]
    run_tool(cmd, f"compiling {output.name}")
    return output
