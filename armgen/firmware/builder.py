"""Builds of the firmware for one robot: the controller, the generated kinematics and the
generated PTP evaluator with the strict flags of spec 10, for the host (gcc, optionally with
ASan/UBSan) or a microcontroller core of targets.TARGETS (the Cortex-M4F by default,
arm-none-eabi-gcc, float), once per variant, and one executable per task."""

from __future__ import annotations

import concurrent.futures
import dataclasses
import hashlib
import os
import re
from dataclasses import dataclass
from pathlib import Path

from ..codegen.generate import GENERATED_DIR, CodegenConfig, generate, write
from ..codegen.ptp_c import generate_ptp_evaluator
from ..codegen.toolchain import SANITIZER_FLAGS, STRICT_FLAGS, find_tool, host_cc, run_tool
from ..fileio import write_text_atomic
from ..robot import Robot, load_robot
from .configuration import MAX_SEGMENTS, FirmwareTask
from .errors import FirmwareError
from .targets import TARGETS
from .sources import (ARM_DIR, FIRMWARE_DIR, OPTIONAL_FUNCTIONS, PTP_PREFIX, available_modes, extract_functions,
                      firmware_functions, robot_prefix)

APT_PACKAGES = "gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm"
APT_HINT = f"install them from the distribution: apt-get install -y {APT_PACKAGES}"


@dataclass(frozen=True)
class Variant:
    target: str = "host"  # "host" (gcc) | a cross build: "arm" (arm-none-eabi-gcc) or "riscv", of the core `cpu`
    precision: str = "double"
    sanitize: bool = False
    opt: str = "-O2"
    max_segments: int = MAX_SEGMENTS
    print_rows: bool = True  # arm: FW_PRINT_ROWS
    fast_trig: bool = True  # arm: <P>_BOUNDED_TRIG=1 for the generated code, sinf/cosf from arm/fw_fastmath.c
                            # (-Wl,--wrap) for the rest; else newlib's everywhere
    gen_opt: str | None = None  # optimisation of the generated kinematics (default: opt)
    extra: tuple[str, ...] = ()  # more compiler flags (e.g. -fcallgraph-info=su for the benchmark)
    source_opts: tuple[tuple[str, tuple[str, ...]], ...] = ()  # (source file name, flags replacing opt)
    cpu: str = "cortex-m4"  # arm: the core, a key of targets.TARGETS (flags, linker script, clock)
    runner: str = "csv"  # host: "csv" (host/main.c), "link" (host/link_main.c: the link over a pty) or
                         # "link_fuzz" (host/link_fuzz.c: the link's parser fuzz and codec echo);
                         # Arm: "csv" (arm/fw_main.c), "link_bench" (bench/link_bench.c: the link's cost) or
                         # "link_uart" (bench/link_uart.c: the link on the MPS2's UART0)

    @property
    def name(self) -> str:
        san = "_san" if self.sanitize else ""
        rows = "" if self.print_rows else "_quiet"
        trig = "" if self.fast_trig or self.target == "host" else "_newlibtrig"
        gen = f"_gen{self.gen_opt.replace('-', '_')}" if self.gen_opt and self.gen_opt != self.opt else ""
        extra = "_x" + re.sub(r"[^0-9a-zA-Z]+", "_", "".join(self.extra)).strip("_") if self.extra else ""
        tuned = "_" + hashlib.sha256(repr(self.source_opts).encode()).hexdigest()[:8] if self.source_opts else ""
        runner = "" if self.runner == "csv" else f"_{self.runner}"
        cpu = "" if self.cpu == "cortex-m4" else "_" + self.cpu.replace("-", "_")
        return (f"{self.target}{cpu}_{self.precision}{san}{self.opt.replace('-', '_')}{gen}_s{self.max_segments}{rows}"
                f"{trig}{extra}{tuned}{runner}")


# The Cortex-M4F build's optimisation per source, where it is not -O3 (flash against executed
# instructions; docs/firmware.md, "Builds"). The controller: -O2 with its fixed-length loops
# unrolled up to 120 instructions (the tick's short loops over the joints; -O3 unrolled every
# loop, the cold ones of ctrl_init too) and two of -O3's passes that the ticks gain from
# (inlining functions not declared inline, loop unswitching): 20 KB instead of 26 KB, ~65
# instructions a resolved-rate tick more than -O3 (measured; 160 and cloning for constant
# arguments gained 65 back for 2 KB, which the 100 KB image does not have). The CSV
# printer and the runner (main, semihosting, startup) run outside the timed tick: -Os. So does
# the program evaluator (6.4 KB at -O3, 4.6 KB at -Os), which only a program's tick calls.
ARM_CONTROLLER_FLAGS = ("-O2", "-fpeel-loops", "-finline-functions", "-funswitch-loops",
                        "--param=max-completely-peeled-insns=120")
ARM_SOURCE_OPTS = (("controller.c", ARM_CONTROLLER_FLAGS),
                   *((name, ("-Os",)) for name in ("fw_program.c", "fw_csv.c", "fw_main.c", "semihost.c", "startup.c")))


# The Cortex-M4F build: float; the PTP evaluator and sinf/cosf (arm/fw_fastmath.c) at -O3,
# the controller, the program evaluator and the runner as ARM_SOURCE_OPTS, the generated
# straight-line kinematics at -Os (smaller, and on the M4 also fewer executed instructions
# than -O2, whose scheduling spills more).
ARM_VARIANT = Variant("arm", "float", opt="-O3", gen_opt="-Os", source_opts=ARM_SOURCE_OPTS)


def target_variant(name: str) -> Variant:
    """The build of the Cortex-M4F's flags for another core (targets.TARGETS), in the precision
    its FPU computes natively (double on the Cortex-M7)."""
    t = TARGETS[name]
    return dataclasses.replace(ARM_VARIANT, target=t.family, cpu=name, precision=t.precision)


def arm_tools() -> dict[str, str]:
    """The cross toolchain and the emulator, or a ToolchainError naming the apt packages."""
    return {name: find_tool(name, APT_HINT) for name in
            ("arm-none-eabi-gcc", "arm-none-eabi-size", "qemu-system-arm")}


def target_tools(name: str) -> dict[str, str]:
    """A core's cross toolchain and emulator (targets.TARGETS), or a ToolchainError naming its
    apt packages."""
    t = TARGETS[name]
    hint = f"install them from the distribution: apt-get install -y {' '.join(t.apt_packages)}"
    return {tool: find_tool(tool, hint) for tool in t.tools}


class FirmwareBuilder:
    """Compiles the firmware for one robot into ``work``: objects once per variant, one
    executable per task."""

    def __init__(self, robot: Robot | str, work: str | Path, gen_dir: str | Path | None = None):
        self.robot = load_robot(robot) if isinstance(robot, str) else robot
        self.work = Path(work)
        self.work.mkdir(parents=True, exist_ok=True)
        self.prefix = robot_prefix(self.robot)
        self.gen_dir = Path(gen_dir).resolve() if gen_dir is not None else self._generated_dir()
        source = (self.gen_dir / f"{self.prefix}.c").read_text(encoding="utf-8")
        self.modes = available_modes(source, self.prefix)
        self.robot_source = self._robot_source(source)
        self.ptp_dir = self.work / "ptp"
        if not (self.ptp_dir / f"{PTP_PREFIX}_ptp.c").is_file():
            generate_ptp_evaluator(self.ptp_dir, PTP_PREFIX, "double")
        self._objects: dict[Variant, list[Path]] = {}
        self._count = 0

    def _generated_dir(self) -> Path:
        """The checked-in generated/<robot>/ when it belongs to this robot file, else fresh code."""
        checked_in = (GENERATED_DIR / self.robot.name).resolve()  # the compilers run in their own folders
        header = checked_in / f"{self.prefix}.h"
        if header.is_file() and f'ROBOT_SHA256 "{self.robot.sha256}"' in header.read_text(encoding="utf-8"):
            return checked_in
        fresh = self.work / "gen"
        write(generate(CodegenConfig(self.robot)), fresh)
        return fresh

    def _robot_source(self, source: str) -> Path:
        full = self.gen_dir / f"{self.prefix}.c"
        reduced = extract_functions(source, self.prefix, firmware_functions(source, self.prefix))
        if reduced is None:
            return full
        path = self.work / "robot" / f"{self.prefix}_fw.c"
        write_text_atomic(path, reduced)
        return path

    def defines(self, v: Variant) -> list[str]:
        P = self.prefix.upper()
        flag = 1 if v.precision == "float" else 0
        d = [f"-DCTRL_ROBOT={self.prefix}", f"-DCTRL_ROBOT_UC={P}", f'-DCTRL_ROBOT_HEADER="{self.prefix}.h"',
             f"-D{P}_USE_FLOAT={flag}", f"-D{PTP_PREFIX.upper()}_USE_FLOAT={flag}",
             f"-DCTRL_MAX_SEGMENTS={v.max_segments}"]
        d += [f"-DCTRL_HAS_{mode}={1 if mode in self.modes else 0}" for mode in OPTIONAL_FUNCTIONS]
        if v.target != "host":
            d += ["-DFW_CSV_HEX=1", f"-DFW_PRINT_ROWS={1 if v.print_rows else 0}"]
            # the generated kinematics' own bounded-range sin/cos (inline, ≤ 2 ulp on the joint range)
            d += [f"-D{P}_BOUNDED_TRIG={1 if v.fast_trig else 0}", f"-DFW_CPU_HZ={TARGETS[v.cpu].cpu_hz}u"]
        return d

    def cflags(self, v: Variant) -> list[str]:
        flags = [*STRICT_FLAGS, v.opt, "-g"]
        if v.target != "host":
            flags += [*TARGETS[v.cpu].cpu_flags, *TARGETS[v.cpu].compile_specs, "-ffunction-sections", "-fdata-sections", "-fstack-usage"]
        else:
            if v.sanitize:
                flags += list(SANITIZER_FLAGS)
        return flags + list(v.extra) + self.defines(v) + [f"-I{FIRMWARE_DIR}", f"-I{self.gen_dir}", f"-I{self.ptp_dir}", f"-I{ARM_DIR}"]

    def compiler(self, v: Variant) -> str:
        if v.target != "host":
            t = TARGETS[v.cpu]
            return target_tools(v.cpu)[t.compiler]
        return host_cc()

    def sources(self, v: Variant) -> list[Path]:
        common = [self.robot_source, self.ptp_dir / f"{PTP_PREFIX}_ptp.c",
                  FIRMWARE_DIR / "controller.c", FIRMWARE_DIR / "fw_program.c", FIRMWARE_DIR / "fw_csv.c"]
        if v.target != "host":  # the runner of arm/ (its timer and semihosting call have a RISC-V branch)
            fast = [ARM_DIR / "fw_fastmath.c"] if v.fast_trig else []
            if v.runner in ("link_bench", "link_uart"):  # the link's cost; the link on UART0 (Arm only)
                return common + [FIRMWARE_DIR / "fw_link.c", FIRMWARE_DIR / "fw_link_msgs.c",
                                 FIRMWARE_DIR / TARGETS[v.cpu].startup, ARM_DIR / "semihost.c",
                                 FIRMWARE_DIR / "bench" / f"{v.runner}.c", *fast]
            return common + [FIRMWARE_DIR / TARGETS[v.cpu].startup, ARM_DIR / "semihost.c", ARM_DIR / "fw_main.c", *fast]
        if v.runner == "csv":
            return common + [FIRMWARE_DIR / "host" / "main.c"]
        runner = {"link": "link_main.c", "link_fuzz": "link_fuzz.c"}[v.runner]
        return common + [FIRMWARE_DIR / "fw_link.c", FIRMWARE_DIR / "fw_link_msgs.c", FIRMWARE_DIR / "host" / runner]

    def object_dir(self, v: Variant) -> Path:
        return self.work / f"obj_{v.name}"

    def objects(self, v: Variant) -> list[Path]:
        """Compile every source of the variant (in parallel); cached."""
        if v in self._objects:
            return self._objects[v]
        cc, flags = self.compiler(v), self.cflags(v)
        out_dir = self.object_dir(v)
        out_dir.mkdir(parents=True, exist_ok=True)

        gen_source = self.robot_source

        def compile_one(src: Path) -> Path:
            obj = out_dir / (src.stem + ".o")
            f = flags if src != gen_source or not v.gen_opt else [v.gen_opt if x == v.opt else x for x in flags]
            own = dict(v.source_opts).get(src.name)
            if own is not None:
                f = [y for x in f for y in (own if x == v.opt else (x,))]
            run_tool([cc, *f, "-c", str(src), "-o", str(obj)], f"compiling {src.name} ({v.name})", cwd=out_dir)
            return obj

        with concurrent.futures.ThreadPoolExecutor(max_workers=max(2, os.cpu_count() or 2)) as pool:
            objs = list(pool.map(compile_one, self.sources(v)))
        self._objects[v] = objs
        return objs

    def executable(self, v: Variant, task: FirmwareTask, name: str | None = None) -> Path:
        """Link the firmware running ``task``: compiles task_params.h via fw_task.c."""
        if task.robot.sha256 != self.robot.sha256:
            raise FirmwareError(f"task for robot '{task.robot.name}' given to the firmware of '{self.robot.name}'")
        if task.max_segments > v.max_segments:
            v = dataclasses.replace(v, max_segments=task.max_segments)
        objs = self.objects(v)
        self._count += 1
        name = name or f"task{self._count}"
        task_dir = self.work / f"{v.name}_{name}"
        task_dir.mkdir(parents=True, exist_ok=True)
        write_text_atomic(task_dir / "task_params.h", task.header)
        cc, flags = self.compiler(v), self.cflags(v)
        task_obj = task_dir / "fw_task.o"
        run_tool([cc, *flags, f"-I{task_dir}", "-c", str(FIRMWARE_DIR / "fw_task.c"), "-o", str(task_obj)],
                 f"compiling the task parameters of {task.source or name}", cwd=task_dir)
        if v.target != "host":
            out = task_dir / ("fw_m4.elf" if v.cpu == "cortex-m4" else f"fw_{v.cpu.replace('-', '_')}.elf")
            wrap = ["-Wl,--wrap=sinf", "-Wl,--wrap=cosf"] if v.fast_trig else []
            t = TARGETS[v.cpu]
            run_tool([cc, *flags, "-nostartfiles", *t.link_specs, "-T", str(FIRMWARE_DIR / t.linker_script), *wrap,
                      "-Wl,--gc-sections", f"-Wl,-Map={out.with_suffix('.map')}", *map(str, objs), str(task_obj),
                      "-lm", "-o", str(out)], f"linking the {v.cpu} firmware")
        else:
            out = task_dir / "fw_host"
            run_tool([cc, *flags, *map(str, objs), str(task_obj), "-lm", "-o", str(out)], "linking the host firmware")
        return out
