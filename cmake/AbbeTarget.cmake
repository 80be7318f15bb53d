# Helpers for bare-metal images on the MPS2 boards under QEMU (cross builds).
# Used by tests/target/ and bench/. Needs a cmake/toolchain-cortex-*.cmake.
include_guard(GLOBAL)

if(NOT ABBE_QEMU_MACHINE)
    message(FATAL_ERROR "cross build without ABBE_QEMU_MACHINE: use cmake/toolchain-cortex-*.cmake")
endif()
find_program(ABBE_NM NAMES ${ABBE_TOOLCHAIN_PREFIX}nm REQUIRED)
find_program(ABBE_SIZE NAMES ${ABBE_TOOLCHAIN_PREFIX}size)
find_program(ABBE_QEMU NAMES qemu-system-arm)
set(ABBE_TARGET_TIMEOUT 120 CACHE STRING "Timeout of one target test under QEMU, seconds")
set(ABBE_TARGET_DIR "${PROJECT_SOURCE_DIR}/tests/target")
set(ABBE_TARGET_LDSCRIPT "${ABBE_TARGET_DIR}/mps2.ld")

# Run-time support: vector table, reset handler, semihosting, mem* functions.
add_library(abbe_target_rt OBJECT
    "${ABBE_TARGET_DIR}/startup.c" "${ABBE_TARGET_DIR}/semihost.c")
target_include_directories(abbe_target_rt PUBLIC "${ABBE_TARGET_DIR}")
# memcpy & co. must not be turned back into calls to themselves (clang:
# -ffreestanding implies -fno-builtin, which keeps its loop idioms out).
target_compile_options(abbe_target_rt PRIVATE -ffreestanding
    $<$<C_COMPILER_ID:GNU>:-fno-tree-loop-distribute-patterns> -Wall -Wextra)

# Heap and newlib allocator entry points: never in an image.
set(ABBE_FORBID_HEAP
    "^(_?malloc|_?free|_?calloc|_?realloc|_sbrk|_sbrk_r|_malloc_r|_free_r|_calloc_r|_realloc_r|__malloc_.*)$")
# Every float/double routine of libgcc (ARM EABI and generic names; checked
# against all 1275 symbols of GCC 12's v7-m/nofp libgcc.a: the 188 float ones
# match, no integer helper does).
set(ABBE_FORBID_FLOAT
    "^(__aeabi_(f|d|h2f|[iu]i?2[fd]|u?l2[fd]|cf|cd).*|__(add|sub|mul|div|neg|cmp|eq|ne|lt|le|gt|ge|unord)[sdt]f[23]|__(extend|trunc)[sdth]f[sdth]f2|__fix(uns)?[sdt]f[sdt]i|__float(un)?[sdt]i[sdt]f|__powi[sdt]f2|__(mul|div)[sdt]c3|__gnu_(f2h|d2h|h2f)_.*|__gnu_(sat)?fract.*[sd]f.*)$")

# abbe_add_target_image(NAME [NEWLIB] SOURCES...): an image linked against
# abbe and the run-time support with -nostdlib (no newlib at all), or with
# newlib's libm/libc when NEWLIB is given (benchmark reference code only).
# Writes NAME.map next to the image.
function(abbe_add_target_image name)
    cmake_parse_arguments(ARG "NEWLIB" "" "" ${ARGN})
    add_executable(${name} ${ARG_UNPARSED_ARGUMENTS})
    set_target_properties(${name} PROPERTIES SUFFIX ".elf")
    target_link_libraries(${name} PRIVATE abbe_target_rt abbe::abbe)
    target_compile_options(${name} PRIVATE -Wall -Wextra)
    if(ARG_NEWLIB AND CMAKE_C_COMPILER_ID MATCHES "Clang")
        # clang has no GCC specs: newlib-nano's libc by name (the toolchain
        # file puts newlib's multilib directory on the library path)
        target_link_options(${name} PRIVATE -nostdlib)
        target_link_libraries(${name} PRIVATE m c_nano gcc)
    elseif(ARG_NEWLIB)
        target_link_options(${name} PRIVATE -nostartfiles --specs=nano.specs)
        target_link_libraries(${name} PRIVATE m c gcc)
    else()
        target_link_options(${name} PRIVATE -nostdlib)
        target_link_libraries(${name} PRIVATE gcc)
    endif()
    target_link_options(${name} PRIVATE -T "${ABBE_TARGET_LDSCRIPT}"
        -Wl,--gc-sections -Wl,-Map=$<TARGET_FILE_DIR:${name}>/${name}.map)
    set_property(TARGET ${name} APPEND PROPERTY LINK_DEPENDS "${ABBE_TARGET_LDSCRIPT}")
endfunction()

# abbe_qemu_command(OUT_VAR IMAGE_FILE): the QEMU command line for an image.
function(abbe_qemu_command out image)
    set(${out} ${ABBE_QEMU} -M ${ABBE_QEMU_MACHINE} -nographic
        -semihosting-config enable=on,target=native -kernel ${image} PARENT_SCOPE)
endfunction()

# abbe_add_qemu_test(NAME IMAGE_TARGET): run an image under QEMU; its exit
# status (semihosting SYS_EXIT_EXTENDED) is the test result.
function(abbe_add_qemu_test name image)
    if(NOT ABBE_QEMU)
        message(WARNING "qemu-system-arm not found: ${name} is not registered")
        return()
    endif()
    abbe_qemu_command(cmd $<TARGET_FILE:${image}>)
    add_test(NAME ${name} COMMAND ${cmd})
    set_tests_properties(${name} PROPERTIES LABELS "target;qemu" TIMEOUT ${ABBE_TARGET_TIMEOUT})
endfunction()

# abbe_add_symbol_check_selftest(NAME FILE REGEX WHAT SYMBOL): the check must
# fail on FILE and name SYMBOL (proves the check sees what it should).
function(abbe_add_symbol_check_selftest name file regex what symbol)
    add_test(NAME ${name}
        COMMAND ${CMAKE_COMMAND}
            "-DCMD=${CMAKE_COMMAND}@@-DNM=${ABBE_NM}@@-DFILE=${file}@@-DFORBID=${regex}@@-DWHAT=${what}@@-P@@${PROJECT_SOURCE_DIR}/cmake/check_symbols.cmake"
            -DEXPECT_RC=1 "-DEXPECT_REGEX=forbidden ${what} symbols:.*${symbol}"
            -P ${PROJECT_SOURCE_DIR}/cmake/expect_run.cmake)
    set_tests_properties(${name} PROPERTIES LABELS "target;symbols" TIMEOUT 60)
endfunction()

# abbe_add_symbol_check(NAME FILE REGEX WHAT): fail if nm lists a matching symbol.
function(abbe_add_symbol_check name file regex what)
    add_test(NAME ${name}
        COMMAND ${CMAKE_COMMAND} -DNM=${ABBE_NM} -DFILE=${file} -DFORBID=${regex}
            -DWHAT=${what} -P ${PROJECT_SOURCE_DIR}/cmake/check_symbols.cmake)
    set_tests_properties(${name} PROPERTIES LABELS "target;symbols" TIMEOUT 60)
endfunction()

# abbe_add_image_checks(IMAGE_TARGET): no heap in any image; no float/double
# routine in an image for a target without FPU.
function(abbe_add_image_checks image)
    abbe_add_symbol_check(${image}_no_heap $<TARGET_FILE:${image}> "${ABBE_FORBID_HEAP}" "heap")
    if(NOT ABBE_TARGET_HAS_FPU)
        abbe_add_symbol_check(${image}_no_float $<TARGET_FILE:${image}> "${ABBE_FORBID_FLOAT}"
            "float/double routine")
    endif()
endfunction()
