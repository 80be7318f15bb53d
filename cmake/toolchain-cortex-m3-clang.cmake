# Cross toolchain: Arm Cortex-M3 (no FPU, soft-float ABI), clang/LLVM + lld,
# with newlib's headers and libgcc.a of the arm-none-eabi-gcc packages.
#   cmake -S . -B build-m3-clang -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-cortex-m3-clang.cmake
# Fixed point only, as with GCC (cmake/toolchain-cortex-m3.cmake).
# Tests run under qemu-system-arm -M mps2-an385 (Cortex-M3).
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)

set(ABBE_CLANG_TARGET "thumbv7m-none-eabi")
set(ABBE_CPU_FLAGS "-mcpu=cortex-m3 -mthumb -mfloat-abi=soft")
set(ABBE_TARGET_NAME "cortex-m3")
set(ABBE_TARGET_HAS_FPU FALSE)
set(ABBE_QEMU_MACHINE "mps2-an385")

include("${CMAKE_CURRENT_LIST_DIR}/arm-none-eabi-common.cmake")
