# CMake toolchain file: Cortex-M7 with double-precision FPU (FPv5-D16, hard float): the double build runs natively,
# GNU Arm Embedded toolchain (apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi qemu-system-arm).
# Boards of this core: Teensy 4.x, STM32H7, STM32F7. Emulated by `qemu-system-arm -M mps2-an500`.
#   cmake -S . -B build-m7 -DCMAKE_TOOLCHAIN_FILE=cmake/arm-none-eabi-cortex-m7.cmake
#   cmake --build build-m7 && cmake --build build-m7 --target qemu   # writes build-m7/run-m7.csv
# armgen's own build of this core: armgen.firmware.targets (tests/test_targets.py checks they agree).
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR cortex-m7)
set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_ASM_COMPILER arm-none-eabi-gcc)
# No host link step while probing the compiler: there is no operating system to link against.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)
set(CMAKE_C_FLAGS_INIT "-mcpu=cortex-m7 -mthumb -mfloat-abi=hard -mfpu=fpv5-d16")
set(CMAKE_EXE_LINKER_FLAGS_INIT "-mcpu=cortex-m7 -mthumb -mfloat-abi=hard -mfpu=fpv5-d16")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
# What CMakeLists.txt builds and runs for this core:
set(ARMGEN_TARGET m7)  # the image <prefix>_m7.elf, the CSV run-m7.csv
set(ARMGEN_FLOAT OFF)  # the FPU computes double
set(ARMGEN_STARTUP arm/startup.c)
set(ARMGEN_LINKER_SCRIPT arm/mps2_an386.ld)
set(ARMGEN_LINK_SPECS "--specs=nano.specs")
set(ARMGEN_CPU_HZ 25000000)  # FW_CPU_HZ: the clock the overrun check measures a tick in
set(ARMGEN_QEMU qemu-system-arm)
set(ARMGEN_QEMU_MACHINE "-M;mps2-an500")
