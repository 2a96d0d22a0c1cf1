# CMake toolchain file: Cortex-M0+ (Armv6-M), no FPU: float in software (libgcc),
# GNU Arm Embedded toolchain (apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm).
# Boards of this core: RP2040, SAMD21, STM32G0. Emulated by `qemu-system-arm -M mps2-an385` (emulated on the AN385's Cortex-M3 (Armv6-M code is a subset of Armv7-M)).
#   cmake -S . -B build-m0plus -DCMAKE_TOOLCHAIN_FILE=cmake/arm-none-eabi-cortex-m0plus.cmake
#   cmake --build build-m0plus && cmake --build build-m0plus --target qemu   # writes build-m0plus/run-m0plus.csv
# armgen's own build of this core: armgen.firmware.targets (tests/test_targets.py checks they agree).
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR cortex-m0plus)
set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_ASM_COMPILER arm-none-eabi-gcc)
# No host link step while probing the compiler: there is no operating system to link against.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)
set(CMAKE_C_FLAGS_INIT "-mcpu=cortex-m0plus -mthumb -mfloat-abi=soft")
set(CMAKE_EXE_LINKER_FLAGS_INIT "-mcpu=cortex-m0plus -mthumb -mfloat-abi=soft")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
# What CMakeLists.txt builds and runs for this core:
set(ARMGEN_TARGET m0plus)  # the image <prefix>_m0plus.elf, the CSV run-m0plus.csv
set(ARMGEN_FLOAT ON)  # float: in software
set(ARMGEN_STARTUP arm/startup.c)
set(ARMGEN_LINKER_SCRIPT arm/mps2_an386.ld)
set(ARMGEN_LINK_SPECS "--specs=nano.specs")
set(ARMGEN_CPU_HZ 133000000)  # FW_CPU_HZ: the clock the overrun check measures a tick in
set(ARMGEN_QEMU qemu-system-arm)
set(ARMGEN_QEMU_MACHINE "-M;mps2-an385")
