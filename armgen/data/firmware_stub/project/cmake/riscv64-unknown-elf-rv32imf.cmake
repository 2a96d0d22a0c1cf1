# CMake toolchain file: RISC-V RV32IMF (single-precision FPU, ilp32f), bare metal, machine mode,
# GNU RISC-V toolchain with picolibc (apt-get install gcc-riscv64-unknown-elf picolibc-riscv64-unknown-elf qemu-system-misc).
# Boards of this core: ESP32-P4 (rv32imafc), SiFive E76. Emulated by `qemu-system-riscv32 -M virt` (QEMU's virt board runs any RV32GC code; the image uses rv32imf only).
#   cmake -S . -B build-rv32imf -DCMAKE_TOOLCHAIN_FILE=cmake/riscv64-unknown-elf-rv32imf.cmake
#   cmake --build build-rv32imf && cmake --build build-rv32imf --target qemu   # writes build-rv32imf/run-rv32imf.csv
# armgen's own build of this core: armgen.firmware.targets (tests/test_targets.py checks they agree).
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR rv32imf)
set(CMAKE_C_COMPILER riscv64-unknown-elf-gcc)
set(CMAKE_ASM_COMPILER riscv64-unknown-elf-gcc)
# No host link step while probing the compiler: there is no operating system to link against.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)
set(CMAKE_C_FLAGS_INIT "-march=rv32imf -mabi=ilp32f -mcmodel=medany --specs=picolibc.specs")
# (not --specs again: CMake links with the compile flags too, and a second picolibc.specs is an error)
set(CMAKE_EXE_LINKER_FLAGS_INIT "-march=rv32imf -mabi=ilp32f -mcmodel=medany")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
# What CMakeLists.txt builds and runs for this core:
set(ARMGEN_TARGET rv32imf)  # the image <prefix>_rv32imf.elf, the CSV run-rv32imf.csv
set(ARMGEN_FLOAT ON)  # float: the FPU is single precision
set(ARMGEN_STARTUP riscv/startup.c)
set(ARMGEN_LINKER_SCRIPT riscv/virt.ld)
set(ARMGEN_LINK_SPECS "")
set(ARMGEN_CPU_HZ 160000000)  # FW_CPU_HZ: the clock the overrun check measures a tick in
set(ARMGEN_QEMU qemu-system-riscv32)
set(ARMGEN_QEMU_MACHINE "-M;virt;-bios;none")
