# CMake toolchain file: Cortex-M33 (Armv8-M Mainline) with single-precision FPU (FPv5-SP-D16, hard float),
# GNU Arm Embedded toolchain (apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm).
# Boards of this core: STM32U5, RP2350, nRF5340. Emulated by `qemu-system-arm -M mps2-an505`.
#   cmake -S . -B build-m33 -DCMAKE_TOOLCHAIN_FILE=cmake/arm-none-eabi-cortex-m33.cmake
#   cmake --build build-m33 && cmake --build build-m33 --target qemu   # writes build-m33/run-m33.csv
# armgen's own build of this core: armgen.firmware.targets (tests/test_targets.py checks they agree).
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR cortex-m33)
set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_ASM_COMPILER arm-none-eabi-gcc)
# No host link step while probing the compiler: there is no operating system to link against.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)
set(CMAKE_C_FLAGS_INIT "-mcpu=cortex-m33 -mthumb -mfloat-abi=hard -mfpu=fpv5-sp-d16")
set(CMAKE_EXE_LINKER_FLAGS_INIT "-mcpu=cortex-m33 -mthumb -mfloat-abi=hard -mfpu=fpv5-sp-d16")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
# What CMakeLists.txt builds and runs for this core:
set(ARMGEN_TARGET m33)  # the image <prefix>_m33.elf, the CSV run-m33.csv
set(ARMGEN_FLOAT ON)  # float: the FPU is single precision
set(ARMGEN_STARTUP arm/startup.c)
set(ARMGEN_LINKER_SCRIPT arm/mps2_an505.ld)
set(ARMGEN_LINK_SPECS "--specs=nano.specs")
set(ARMGEN_CPU_HZ 20000000)  # FW_CPU_HZ: the clock the overrun check measures a tick in
set(ARMGEN_QEMU qemu-system-arm)
set(ARMGEN_QEMU_MACHINE "-M;mps2-an505")
