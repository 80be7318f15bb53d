# Run a command and require a given exit status and output: the self-tests of
# the checks use it, so a check that fails for the wrong reason (a crash, a
# missing tool) does not count as the expected failure.
#   cmake -DCMD=prog@@arg@@... -DEXPECT_RC=1 -DEXPECT_REGEX=regex -P expect_run.cmake
# CMD uses "@@" between arguments.
string(REPLACE "@@" ";" cmd "${CMD}")
execute_process(COMMAND ${cmd} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
set(all "${out}${err}")
message("${all}")
if(NOT "${rc}" STREQUAL "${EXPECT_RC}")
    message(FATAL_ERROR "expected exit status ${EXPECT_RC}, got ${rc}")
endif()
if(NOT all MATCHES "${EXPECT_REGEX}")
    message(FATAL_ERROR "output does not match: ${EXPECT_REGEX}")
endif()
message(STATUS "exit status ${rc} and output as expected")
