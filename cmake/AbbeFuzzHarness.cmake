# abbe_fuzz_harness(NAME SOURCES src... [LIBS lib...] CORPUS dir... [MAX_LEN n] [SECONDS s])
#
# A libFuzzer harness (ABBE_BUILD_FUZZ=ON, clang) and its two CTest tests,
# label "fuzz":
#   NAME_seeds  every input of the CORPUS directories (seeds, committed
#               regressions) once, without a report: a quick regression run;
#   NAME_run    a bounded run, fixed seed (-seed=1), SECONDS long (default
#               ABBE_PORT_FUZZ_SECONDS); new inputs go to NAME-corpus/ in the
#               build tree. Longer runs: scripts/fuzz_c.sh.
set(ABBE_PORT_FUZZ_SECONDS 10 CACHE STRING "Duration of each port harness' CTest fuzz run, seconds")

function(abbe_fuzz_harness name)
    cmake_parse_arguments(F "" "MAX_LEN;SECONDS" "SOURCES;LIBS;CORPUS" ${ARGN})
    if(NOT F_MAX_LEN)
        set(F_MAX_LEN 4096)
    endif()
    if(NOT F_SECONDS)
        set(F_SECONDS ${ABBE_PORT_FUZZ_SECONDS})
    endif()
    add_executable(${name} ${F_SOURCES})
    target_link_libraries(${name} PRIVATE ${F_LIBS})
    target_compile_options(${name} PRIVATE -fsanitize=fuzzer)
    target_link_options(${name} PRIVATE -fsanitize=fuzzer)
    set(work "${CMAKE_CURRENT_BINARY_DIR}/${name}-corpus")
    file(MAKE_DIRECTORY "${work}")
    add_test(NAME ${name}_seeds COMMAND ${name} -runs=0 ${F_CORPUS})
    add_test(NAME ${name}_run
        COMMAND ${CMAKE_COMMAND} -E chdir "${CMAKE_CURRENT_BINARY_DIR}"
            $<TARGET_FILE:${name}> -seed=1 -max_len=${F_MAX_LEN} -timeout=10
            -max_total_time=${F_SECONDS} -print_final_stats=1 "${work}" ${F_CORPUS})
    set_tests_properties(${name}_seeds ${name}_run PROPERTIES
        LABELS "fuzz"
        ENVIRONMENT "ASAN_OPTIONS=detect_leaks=1;UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1")
    set_tests_properties(${name}_seeds PROPERTIES TIMEOUT 120)
    math(EXPR _timeout "${F_SECONDS} * 4 + 60")
    set_tests_properties(${name}_run PROPERTIES TIMEOUT ${_timeout})
endfunction()

# abbe_fuzz_seeds(TARGET generator OUT dir): run a seed-writing program at build time.
function(abbe_fuzz_seeds generator out)
    add_custom_command(OUTPUT "${out}/.stamp"
        COMMAND ${CMAKE_COMMAND} -E remove_directory "${out}"
        COMMAND ${CMAKE_COMMAND} -E make_directory "${out}"
        COMMAND ${generator} "${out}"
        COMMAND ${CMAKE_COMMAND} -E touch "${out}/.stamp"
        DEPENDS ${generator}
        COMMENT "Writing the seeds of ${generator}")
    add_custom_target(${generator}_run ALL DEPENDS "${out}/.stamp")
endfunction()
