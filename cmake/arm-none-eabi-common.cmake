# Shared part of the arm-none-eabi toolchain files (do not use it directly).
# Expects ABBE_CPU_FLAGS, ABBE_TARGET_NAME, ABBE_TARGET_HAS_FPU, ABBE_QEMU_MACHINE.
set(ABBE_TOOLCHAIN_PREFIX "arm-none-eabi-" CACHE STRING "Prefix of the cross tools")

find_program(CMAKE_C_COMPILER NAMES ${ABBE_TOOLCHAIN_PREFIX}gcc REQUIRED)
find_program(CMAKE_AR NAMES ${ABBE_TOOLCHAIN_PREFIX}gcc-ar ${ABBE_TOOLCHAIN_PREFIX}ar)
find_program(CMAKE_RANLIB NAMES ${ABBE_TOOLCHAIN_PREFIX}gcc-ranlib ${ABBE_TOOLCHAIN_PREFIX}ranlib)
find_program(ABBE_NM NAMES ${ABBE_TOOLCHAIN_PREFIX}nm)
find_program(ABBE_SIZE NAMES ${ABBE_TOOLCHAIN_PREFIX}size)
find_program(ABBE_OBJDUMP NAMES ${ABBE_TOOLCHAIN_PREFIX}objdump)
find_program(ABBE_QEMU NAMES qemu-system-arm)

# Only static libraries can be linked without a board's start-up code.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)

set(CMAKE_C_FLAGS_INIT "${ABBE_CPU_FLAGS} -ffunction-sections -fdata-sections")
# Release is -O2 on the MCU (CMake's default -O3 trades flash for little).
# Cache entries: CMake would append its own defaults to *_INIT values.
set(CMAKE_C_FLAGS_RELEASE "-O2 -DNDEBUG" CACHE STRING "C flags, Release")
set(CMAKE_C_FLAGS_MINSIZEREL "-Os -DNDEBUG" CACHE STRING "C flags, MinSizeRel")
set(CMAKE_C_FLAGS_RELWITHDEBINFO "-O2 -g -DNDEBUG" CACHE STRING "C flags, RelWithDebInfo")
set(CMAKE_EXE_LINKER_FLAGS_INIT "-Wl,--gc-sections")

# Search headers and libraries in the target environment only.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
