# Cross toolchain: Arm Cortex-M4F (FPv4-SP, hard-float ABI), clang/LLVM + lld,
# with newlib's headers and libgcc.a of the arm-none-eabi-gcc packages.
#   cmake -S . -B build-m4f-clang -DCMAKE_TOOLCHAIN_FILE=cmake/toolchain-cortex-m4f-clang.cmake
# Tests run under qemu-system-arm -M mps2-an386 (Cortex-M4 with FPU).
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)

set(ABBE_CLANG_TARGET "thumbv7em-none-eabihf")
set(ABBE_CPU_FLAGS "-mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16")
# LLVM's Cortex-M4 model marks VFMA as slow (target feature slowfpvfmx) and then
# never contracts a * b + c into it, whatever -ffp-contract says; the library
# asks for the fused form (lib/CMakeLists.txt: one rounding instead of two, as
# GCC builds it). abbe_error_eval_f32 742 -> 732 instructions (bench/results.md).
set(ABBE_CLANG_FLAGS "-Xclang -target-feature -Xclang -slowfpvfmx")
set(ABBE_TARGET_NAME "cortex-m4f")
set(ABBE_TARGET_HAS_FPU TRUE)
set(ABBE_QEMU_MACHINE "mps2-an386")

include("${CMAKE_CURRENT_LIST_DIR}/arm-none-eabi-common.cmake")
