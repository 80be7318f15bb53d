# Cross toolchain: Arm Cortex-M3 (no FPU, soft-float ABI), arm-none-eabi-gcc
# (clang: cmake/toolchain-cortex-m3-clang.cmake).
#   cmake -S . -B build-m3 -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-cortex-m3.cmake
# The M3 build is fixed point only: ABBE_WITH_F32 defaults to OFF here and the
# target checks fail if any float/double library routine gets linked.
# Tests run under qemu-system-arm -M mps2-an385 (Cortex-M3).
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)

set(ABBE_CPU_FLAGS "-mcpu=cortex-m3 -mthumb -mfloat-abi=soft")
set(ABBE_TARGET_NAME "cortex-m3")
set(ABBE_TARGET_HAS_FPU FALSE)
set(ABBE_QEMU_MACHINE "mps2-an385")

include("${CMAKE_CURRENT_LIST_DIR}/arm-none-eabi-common.cmake")
