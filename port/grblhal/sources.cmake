# The grblHAL plugin's sources, listed once for every build that compiles
# them: CMakeLists.txt here (the core's unit tests), sim/CMakeLists.txt
# (grblHAL's Simulator with the plugin) and bench/CMakeLists.txt (the core on
# a Cortex-M). A firmware build adds all of src/ (docs/grblhal.md).
#   ABBE_GRBLHAL_CORE_SOURCES  the core: plain C99 on the abbe library, no grblHAL
#   ABBE_GRBLHAL_GLUE_SOURCES  the glue on grblHAL's interfaces (needs grblHAL's headers)
set(_abbe_grblhal_src "${CMAKE_CURRENT_LIST_DIR}/src")
set(ABBE_GRBLHAL_CORE_SOURCES
    "${_abbe_grblhal_src}/abbe_grblhal_core.c"         # state machine, segment length, forward transform, thermal clock
    "${_abbe_grblhal_src}/abbe_grblhal_core_eval.c"    # curvature scan, inverse transform
    "${_abbe_grblhal_src}/abbe_grblhal_core_line.c"    # line segmentation
    "${_abbe_grblhal_src}/abbe_grblhal_core_upload.c") # upload staging, stored-table header
set(ABBE_GRBLHAL_GLUE_SOURCES
    "${_abbe_grblhal_src}/abbe_grblhal.c"              # init, kinematics, messages, status report
    "${_abbe_grblhal_src}/abbe_grblhal_store.c"        # table in non-volatile storage, start-up table
    "${_abbe_grblhal_src}/abbe_grblhal_settings.c"     # $ settings
    "${_abbe_grblhal_src}/abbe_grblhal_commands.c")    # $ABBE, $ABBEU, $ABBET, $ABBERESET
