"""The microcontroller targets the firmware is cross-compiled for and emulated on: one table,
read by the builder (compiler flags, linker script), the QEMU runner (machine) and
``armgen verify --target NAME`` (which precision runs natively). docs/targets.md explains
each choice.

Every target runs the same runner (firmware_stub/arm/fw_main.c with its semihosting console;
the startup code and linker script of the board) under QEMU with ``-icount shift=0``, where
the timer the runner reads (SysTick on the Arm cores, mcycle on RISC-V) counts executed
instructions (calibrated at start: see arm/fw_main.c).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..codegen.toolchain import ARM_CPU_FLAGS

ARM_APT_PACKAGES = ("gcc-arm-none-eabi", "libnewlib-arm-none-eabi", "qemu-system-arm")
RISCV_APT_PACKAGES = ("gcc-riscv64-unknown-elf", "picolibc-riscv64-unknown-elf", "qemu-system-misc")


@dataclass(frozen=True)
class Target:
    name: str  # what `armgen verify --target` takes
    cpu_flags: tuple[str, ...]  # the compiler's -mcpu/-march, -mabi/-mfloat-abi, -mfpu
    qemu_machine: str  # QEMU's -M
    precision: str  # the build verify runs: the widest the FPU computes in hardware ("float" without FPU)
    linker_script: str  # under firmware_stub/
    cpu_hz: int  # FW_CPU_HZ: the clock the controller's overrun check measures a tick's period in
    boards: str  # the boards this core stands for (docs)
    note: str = ""  # how the emulation differs from the core, if it does
    family: str = "arm"  # "arm" | "riscv": the builder's Variant.target
    compiler: str = "arm-none-eabi-gcc"
    qemu: str = "qemu-system-arm"
    qemu_extra: tuple[str, ...] = ()  # more machine options
    startup: str = "arm/startup.c"  # under firmware_stub/
    # The C library: newlib-nano at link, or picolibc's specs at compile (its headers) and so
    # at link too (given once: the compile flags are the link's)
    compile_specs: tuple[str, ...] = ()
    link_specs: tuple[str, ...] = ("--specs=nano.specs",)
    apt_packages: tuple[str, ...] = ARM_APT_PACKAGES

    @property
    def description(self) -> str:
        return f"{self.name} (QEMU {self.qemu_machine}), {self.precision}"

    @property
    def tools(self) -> tuple[str, ...]:
        return (self.compiler, self.compiler.replace("-gcc", "-size"), self.qemu)


TARGETS: dict[str, Target] = {t.name: t for t in (
    Target("cortex-m4", ARM_CPU_FLAGS,  # the flags the codegen's own Cortex-M4F checks build with
           "mps2-an386", "float", "arm/mps2_an386.ld", 25_000_000, "STM32F4, Teensy 3.6, nRF52840"),
    # Double-precision FPU (FPv5-D16): the double build is the native one.
    Target("cortex-m7", ("-mcpu=cortex-m7", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv5-d16"),
           "mps2-an500", "double", "arm/mps2_an386.ld", 25_000_000, "Teensy 4.x, STM32H7, STM32F7"),
    # Armv8-M Mainline with single-precision FPU; AN505 boots in the Secure state with its vector
    # table at 0x10000000 (the Secure alias of SSRAM1): its own linker script.
    Target("cortex-m33", ("-mcpu=cortex-m33", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv5-sp-d16"),
           "mps2-an505", "float", "arm/mps2_an505.ld", 20_000_000, "STM32U5, RP2350, nRF5340"),
    # No FPU: float in software (libgcc). QEMU 7.2 models no M0+ board with room for the image
    # (micro:bit's Cortex-M0 has 16 KB RAM), so the Armv6-M code runs on the AN385's Cortex-M3:
    # Armv6-M's Thumb instructions are a subset of Armv7-M's with the same semantics, so the run
    # executes exactly the instructions an M0+ would. Its clock: the RP2040's 133 MHz.
    Target("cortex-m0plus", ("-mcpu=cortex-m0plus", "-mthumb", "-mfloat-abi=soft"),
           "mps2-an385", "float", "arm/mps2_an386.ld", 133_000_000, "RP2040, SAMD21, STM32G0",
           "emulated on the AN385's Cortex-M3 (Armv6-M code is a subset of Armv7-M)"),
    # RISC-V with single-precision FPU (ESP32-P4's class; GD32V and ESP32-C3/C6 lack the F
    # extension) on QEMU's virt board, machine mode, picolibc. The clock: a 160 MHz part.
    Target("rv32imf", ("-march=rv32imf", "-mabi=ilp32f", "-mcmodel=medany"),
           "virt", "float", "riscv/virt.ld", 160_000_000, "ESP32-P4 (rv32imafc), SiFive E76",
           "QEMU's virt board runs any RV32GC code; the image uses rv32imf only", family="riscv",
           compiler="riscv64-unknown-elf-gcc", qemu="qemu-system-riscv32", qemu_extra=("-bios", "none"),
           startup="riscv/startup.c", compile_specs=("--specs=picolibc.specs",),
           link_specs=(), apt_packages=RISCV_APT_PACKAGES),
)}

