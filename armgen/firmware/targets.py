"""The microcontroller targets the firmware is cross-compiled for and emulated on: one table,
read by the builder (compiler flags, linker script), the QEMU runner (machine) and
``armgen verify --target NAME`` (which precision runs natively). docs/targets.md explains
each choice.

Every target runs the same Arm runner (firmware_stub/arm/: startup, semihosting console,
SysTick timing) on an MPS2 board model of ``qemu-system-arm`` under ``-icount shift=0``, so
SysTick counts executed instructions (calibrated at start: see arm/fw_main.c).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..codegen.toolchain import ARM_CPU_FLAGS

@dataclass(frozen=True)
class Target:
    name: str  # what `armgen verify --target` takes
    cpu_flags: tuple[str, ...]  # arm-none-eabi-gcc's -mcpu/-mthumb/-mfloat-abi/-mfpu
    qemu_machine: str  # qemu-system-arm -M
    precision: str  # the build verify runs: the widest the FPU computes in hardware ("float" without FPU)
    linker_script: str  # in firmware_stub/arm/
    cpu_hz: int  # FW_CPU_HZ: the clock the controller's overrun check measures a tick's period in
    boards: str  # the boards this core stands for (docs)
    note: str = ""  # how the emulation differs from the core, if it does

    @property
    def description(self) -> str:
        return f"{self.name} (QEMU {self.qemu_machine}), {self.precision}"


TARGETS: dict[str, Target] = {t.name: t for t in (
    Target("cortex-m4", ARM_CPU_FLAGS,  # the flags the codegen's own Cortex-M4F checks build with
           "mps2-an386", "float", "mps2_an386.ld", 25_000_000, "STM32F4, Teensy 3.6, nRF52840"),
    # Double-precision FPU (FPv5-D16): the double build is the native one.
    Target("cortex-m7", ("-mcpu=cortex-m7", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv5-d16"),
           "mps2-an500", "double", "mps2_an386.ld", 25_000_000, "Teensy 4.x, STM32H7, STM32F7"),
    # Armv8-M Mainline with single-precision FPU; AN505 boots in the Secure state with its vector
    # table at 0x10000000 (the Secure alias of SSRAM1): its own linker script.
    Target("cortex-m33", ("-mcpu=cortex-m33", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv5-sp-d16"),
           "mps2-an505", "float", "mps2_an505.ld", 20_000_000, "STM32U5, RP2350, nRF5340"),
    # No FPU: float in software (libgcc). QEMU 7.2 models no M0+ board with room for the image
    # (micro:bit's Cortex-M0 has 16 KB RAM), so the Armv6-M code runs on the AN385's Cortex-M3:
    # Armv6-M's Thumb instructions are a subset of Armv7-M's with the same semantics, so the run
    # executes exactly the instructions an M0+ would. Its clock: the RP2040's 133 MHz.
    Target("cortex-m0plus", ("-mcpu=cortex-m0plus", "-mthumb", "-mfloat-abi=soft"),
           "mps2-an385", "float", "mps2_an386.ld", 133_000_000, "RP2040, SAMD21, STM32G0",
           "emulated on the AN385's Cortex-M3 (Armv6-M code is a subset of Armv7-M)"),
)}


def target(name: str) -> Target:
    try:
        return TARGETS[name]
    except KeyError:
        raise KeyError(f"unknown target {name!r}; known: {', '.join(TARGETS)}") from None
