# Shared part of the arm-none-eabi toolchain files (do not use it directly).
# Expects ABBE_CPU_FLAGS, ABBE_TARGET_NAME, ABBE_TARGET_HAS_FPU, ABBE_QEMU_MACHINE;
# ABBE_CLANG_TARGET (a triple) selects clang instead of arm-none-eabi-gcc, with
# ABBE_CLANG_FLAGS (optional) for clang alone.
set(ABBE_TOOLCHAIN_PREFIX "arm-none-eabi-" CACHE STRING "Prefix of the cross tools")

if(ABBE_CLANG_TARGET)
    # clang/LLVM (what Arm Compiler 6, the LLVM Embedded Toolchain for Arm and
    # Zephyr's LLVM builds are): the compiler and lld; newlib's headers
    # (string.h, the library's only libc header) and the multilib libgcc.a come
    # from the GNU arm-none-eabi packages, which the images link with
    # -nostdlib as with GCC. GNU nm/size/objdump read lld's ELF files.
    find_program(CMAKE_C_COMPILER NAMES clang REQUIRED)
    find_program(CMAKE_CXX_COMPILER NAMES clang++)
    set(CMAKE_C_COMPILER_TARGET ${ABBE_CLANG_TARGET})
    set(CMAKE_CXX_COMPILER_TARGET ${ABBE_CLANG_TARGET})
    find_program(CMAKE_AR NAMES llvm-ar ${ABBE_TOOLCHAIN_PREFIX}ar)
    find_program(CMAKE_RANLIB NAMES llvm-ranlib ${ABBE_TOOLCHAIN_PREFIX}ranlib)
    find_program(ABBE_GNU_GCC NAMES ${ABBE_TOOLCHAIN_PREFIX}gcc REQUIRED)
    separate_arguments(_abbe_cpu_flags UNIX_COMMAND "${ABBE_CPU_FLAGS}")
    foreach(_abbe_file libgcc.a libc.a)
        execute_process(COMMAND ${ABBE_GNU_GCC} ${_abbe_cpu_flags} -print-file-name=${_abbe_file}
            OUTPUT_VARIABLE _abbe_path OUTPUT_STRIP_TRAILING_WHITESPACE)
        if(NOT IS_ABSOLUTE "${_abbe_path}")
            message(FATAL_ERROR "${ABBE_GNU_GCC} ${ABBE_CPU_FLAGS} has no ${_abbe_file}")
        endif()
        get_filename_component(_abbe_dir "${_abbe_path}" DIRECTORY)
        list(APPEND _abbe_lib_dirs "-L${_abbe_dir}")
    endforeach()
    # newlib's headers: <prefix>/arm-none-eabi/include next to the GCC driver (Debian: /usr/lib/...)
    find_path(ABBE_NEWLIB_INCLUDE string.h NO_DEFAULT_PATH NO_CMAKE_FIND_ROOT_PATH
        PATHS /usr/lib/arm-none-eabi/include /usr/arm-none-eabi/include
              ${_abbe_dir}/../../../../include ${_abbe_dir}/../../../include)
    if(NOT ABBE_NEWLIB_INCLUDE)
        message(FATAL_ERROR "newlib's headers not found: set ABBE_NEWLIB_INCLUDE")
    endif()
    string(REPLACE ";" " " _abbe_lib_dirs "${_abbe_lib_dirs}")
    # -munaligned-access: ARMv7-M loads words at any address (LDR; LDRD, LDM
    # and VLDR still need alignment, which both compilers respect), and GCC
    # assumes it by default there; clang assumes strict alignment on bare
    # metal and then reads each little-endian word of a table byte by byte
    # (abbe_ld_u32: 4 loads, 3 ORs): the fixed-point kernel ran 2x the
    # instructions (bench/results.md, section 9).
    set(_abbe_compiler_flags "-munaligned-access ${ABBE_CLANG_FLAGS} -isystem ${ABBE_NEWLIB_INCLUDE}")
    set(_abbe_linker_flags "-fuse-ld=lld ${_abbe_lib_dirs}")
else()
    find_program(CMAKE_C_COMPILER NAMES ${ABBE_TOOLCHAIN_PREFIX}gcc REQUIRED)
    find_program(CMAKE_CXX_COMPILER NAMES ${ABBE_TOOLCHAIN_PREFIX}g++)
    find_program(CMAKE_AR NAMES ${ABBE_TOOLCHAIN_PREFIX}gcc-ar ${ABBE_TOOLCHAIN_PREFIX}ar)
    find_program(CMAKE_RANLIB NAMES ${ABBE_TOOLCHAIN_PREFIX}gcc-ranlib ${ABBE_TOOLCHAIN_PREFIX}ranlib)
    set(_abbe_compiler_flags "")
    set(_abbe_linker_flags "")
endif()
find_program(ABBE_NM NAMES ${ABBE_TOOLCHAIN_PREFIX}nm)
find_program(ABBE_SIZE NAMES ${ABBE_TOOLCHAIN_PREFIX}size)
find_program(ABBE_OBJDUMP NAMES ${ABBE_TOOLCHAIN_PREFIX}objdump)
find_program(ABBE_QEMU NAMES qemu-system-arm)

# Only static libraries can be linked without a board's start-up code.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)

set(CMAKE_C_FLAGS_INIT "${ABBE_CPU_FLAGS} -ffunction-sections -fdata-sections ${_abbe_compiler_flags}")
# C++ (the C++ consumer test, tests/cxx/): as firmware builds it, no exceptions or RTTI.
set(CMAKE_CXX_FLAGS_INIT "${CMAKE_C_FLAGS_INIT} -fno-exceptions -fno-rtti -fno-threadsafe-statics")
# Release is -O2 on the MCU (CMake's default -O3 trades flash for little).
# Cache entries: CMake would append its own defaults to *_INIT values.
set(CMAKE_C_FLAGS_RELEASE "-O2 -DNDEBUG" CACHE STRING "C flags, Release")
set(CMAKE_C_FLAGS_MINSIZEREL "-Os -DNDEBUG" CACHE STRING "C flags, MinSizeRel")
set(CMAKE_C_FLAGS_RELWITHDEBINFO "-O2 -g -DNDEBUG" CACHE STRING "C flags, RelWithDebInfo")
set(CMAKE_CXX_FLAGS_RELEASE "-O2 -DNDEBUG" CACHE STRING "C++ flags, Release")
set(CMAKE_CXX_FLAGS_MINSIZEREL "-Os -DNDEBUG" CACHE STRING "C++ flags, MinSizeRel")
set(CMAKE_CXX_FLAGS_RELWITHDEBINFO "-O2 -g -DNDEBUG" CACHE STRING "C++ flags, RelWithDebInfo")
set(CMAKE_EXE_LINKER_FLAGS_INIT "-Wl,--gc-sections ${_abbe_linker_flags}")

# Search headers and libraries in the target environment only.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
