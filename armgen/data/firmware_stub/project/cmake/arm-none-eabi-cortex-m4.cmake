# CMake toolchain file: Cortex-M4F with single-precision FPU (hard float), bare metal,
# GNU Arm Embedded toolchain (apt-get install gcc-arm-none-eabi libnewlib-arm-none-eabi).
#   cmake -S . -B build-m4 -DCMAKE_TOOLCHAIN_FILE=cmake/arm-none-eabi-cortex-m4.cmake
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR cortex-m4)
set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_ASM_COMPILER arm-none-eabi-gcc)
# No host link step while probing the compiler: there is no operating system to link against.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)
set(CMAKE_C_FLAGS_INIT "-mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16")
set(CMAKE_EXE_LINKER_FLAGS_INIT "-mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16")
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
# What CMakeLists.txt builds and runs for this core (its defaults; the other cores' files set them too):
set(ARMGEN_TARGET m4)  # the image <prefix>_m4.elf, the CSV run-m4.csv
set(ARMGEN_FLOAT ON)  # float: the FPU is single precision
set(ARMGEN_STARTUP arm/startup.c)
set(ARMGEN_LINKER_SCRIPT arm/mps2_an386.ld)
set(ARMGEN_LINK_SPECS "--specs=nano.specs")
set(ARMGEN_CPU_HZ 25000000)  # FW_CPU_HZ: the clock the overrun check measures a tick in
set(ARMGEN_QEMU qemu-system-arm)
set(ARMGEN_QEMU_MACHINE "-M;mps2-an386")
