# Cross toolchain: Arm Cortex-M4F (FPv4-SP, hard-float ABI), arm-none-eabi-gcc
# (clang: cmake/toolchain-cortex-m4f-clang.cmake).
#   cmake -S . -B build-m4f -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-cortex-m4f.cmake
# Tests run under qemu-system-arm -M mps2-an386 (Cortex-M4 with FPU).
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)

set(ABBE_CPU_FLAGS "-mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16")
set(ABBE_TARGET_NAME "cortex-m4f")
set(ABBE_TARGET_HAS_FPU TRUE)
set(ABBE_QEMU_MACHINE "mps2-an386")

include("${CMAKE_CURRENT_LIST_DIR}/arm-none-eabi-common.cmake")
