"""Runners of a built firmware: the host executable, and a target's image under QEMU
(the Cortex-M4F's by default; targets.TARGETS)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path
from typing import Sequence

from ..codegen.toolchain import find_tool
from .builder import APT_HINT
from .errors import FirmwareError
from .output import FirmwareRun, parse_output
from .targets import TARGETS

QEMU_MACHINE = ("-M", "mps2-an386", "-nographic", "-semihosting-config", "enable=on,target=native")
# Deterministic time: one guest instruction = 1 ns, so SysTick counts instructions / 40 and
# the controller's overrun check never fires because the host was busy.
QEMU_ICOUNT = ("-icount", "shift=0")


def run_host(exe: Path, args: Sequence[str] = (), timeout: float = 300) -> FirmwareRun:
    env = dict(os.environ, ASAN_OPTIONS="detect_leaks=1:abort_on_error=0", UBSAN_OPTIONS="print_stacktrace=1")
    try:
        proc = subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=timeout, env=env)
    except subprocess.TimeoutExpired:
        raise FirmwareError(f"{exe.name} did not finish within {timeout:.0f} s") from None
    if proc.returncode != 0:
        raise FirmwareError(f"{exe.name} {' '.join(args)} failed (exit {proc.returncode}):\n{proc.stderr[-4000:]}")
    if proc.stderr.strip():  # a sanitizer that recovered would still print here
        raise FirmwareError(f"{exe.name} wrote to stderr:\n{proc.stderr[-4000:]}")
    return parse_output(proc.stdout)


def run_qemu(elf: Path, timeout: float = 600, icount: bool = True, target: str = "cortex-m4") -> FirmwareRun:
    t = TARGETS[target]
    qemu = find_tool(t.qemu, APT_HINT if t.family == "arm" else
                     f"install them from the distribution: apt-get install -y {' '.join(t.apt_packages)}")
    machine = ("-M", t.qemu_machine, *t.qemu_extra, *QEMU_MACHINE[2:])
    cmd = [qemu, *machine, *(QEMU_ICOUNT if icount else ()), "-kernel", str(elf)]
    try:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        raise FirmwareError(f"{t.qemu} did not finish {elf.name} within {timeout:.0f} s") from None
    text = proc.stdout + proc.stderr  # semihosting console output goes to stderr in QEMU 7
    if proc.returncode != 0 or "# end" not in text:
        raise FirmwareError(f"the {target} firmware failed under QEMU (exit {proc.returncode}):\n{text[-3000:]}")
    return parse_output(text)

