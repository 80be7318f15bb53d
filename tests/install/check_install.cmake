# Install the abbe build ABBE_BUILD_DIR into a scratch prefix, then configure,
# build and run the consumer in ABBE_CONSUMER_SRC against it.
file(REMOVE_RECURSE "${ABBE_WORK_DIR}")
set(prefix "${ABBE_WORK_DIR}/prefix")

function(run)
    execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc)
    if(NOT rc EQUAL 0)
        string(REPLACE ";" " " cmd "${ARGN}")
        message(FATAL_ERROR "failed (${rc}): ${cmd}")
    endif()
endfunction()

set(config_args)
if(ABBE_CONFIG)
    set(config_args --config ${ABBE_CONFIG})
endif()
run(${CMAKE_COMMAND} --install "${ABBE_BUILD_DIR}" --prefix "${prefix}" ${config_args})
file(GLOB_RECURSE pcfile "${prefix}/*/abbe.pc")
file(GLOB_RECURSE cfgfile "${prefix}/*/abbeConfig.cmake")
if(NOT pcfile OR NOT cfgfile)
    message(FATAL_ERROR "install is missing abbe.pc or abbeConfig.cmake")
endif()
get_filename_component(pcdir "${pcfile}" DIRECTORY)

set(ENV{PKG_CONFIG_PATH} "${pcdir}")
# The C++ consumer too (tests/cxx/), given a C++ compiler and the golden data.
set(exes consumer_cmake consumer_pkgconfig)
set(cxx_args)
if(ABBE_CXX_COMPILER AND ABBE_GOLDEN_DIR)
    set(cxx_args -DCMAKE_CXX_COMPILER=${ABBE_CXX_COMPILER} -DABBE_GOLDEN_DIR=${ABBE_GOLDEN_DIR}
        -DABBE_CXX_SOURCE=${ABBE_CONSUMER_SRC}/../cxx/cxx_consumer.cpp)
    list(APPEND exes consumer_cmake_cxx consumer_pkgconfig_cxx)
endif()
run(${CMAKE_COMMAND} -S "${ABBE_CONSUMER_SRC}" -B "${ABBE_WORK_DIR}/build"
    -G "${ABBE_GENERATOR}" -DCMAKE_C_COMPILER=${ABBE_C_COMPILER} ${cxx_args}
    -DCMAKE_PREFIX_PATH=${prefix} -DCMAKE_BUILD_TYPE=Release)
run(${CMAKE_COMMAND} --build "${ABBE_WORK_DIR}/build")
foreach(exe IN LISTS exes)
    if(NOT EXISTS "${ABBE_WORK_DIR}/build/${exe}")
        message(FATAL_ERROR "the consumer build made no ${exe}")
    endif()
    run("${ABBE_WORK_DIR}/build/${exe}")
endforeach()
string(REPLACE ";" ", " exes "${exes}")
message(STATUS "find_package(abbe) and pkg-config abbe both work from ${prefix}: ${exes}")
