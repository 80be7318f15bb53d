# Strict warnings for the library core (lib/) and the ports (port/).
#
# Two equivalent ways to apply them (use one):
#   abbe_strict_warnings(abbe)                                 # function: PRIVATE options
#   target_link_libraries(abbe PRIVATE abbe_strict_warnings)   # INTERFACE target
# The interface target is exported with an empty interface (its options are
# BUILD_INTERFACE only), so installed consumers never inherit -Werror.
set(ABBE_STRICT_WARNING_FLAGS
    -Wall -Wextra -Wpedantic -Wconversion -Wsign-conversion -Wdouble-promotion
    -Wfloat-equal -Wshadow -Wcast-align -Wstrict-prototypes -Wmissing-prototypes -Werror)

if(NOT TARGET abbe_strict_warnings)
    add_library(abbe_strict_warnings INTERFACE)
    target_compile_options(abbe_strict_warnings INTERFACE
        "$<BUILD_INTERFACE:$<$<C_COMPILER_ID:GNU,Clang,AppleClang>:${ABBE_STRICT_WARNING_FLAGS}>>")
endif()

function(abbe_strict_warnings)
    foreach(target IN LISTS ARGN)
        target_compile_options(${target} PRIVATE
            "$<$<C_COMPILER_ID:GNU,Clang,AppleClang>:${ABBE_STRICT_WARNING_FLAGS}>")
    endforeach()
endfunction()
