# cmake/version.cmake — run at every build: writes the version header with the current git
# commit (suffixed "-dirty" when the tree has uncommitted changes); unchanged content keeps
# the file's time stamp, so nothing is rebuilt needlessly.
execute_process(COMMAND git rev-parse --short=12 HEAD WORKING_DIRECTORY ${SRC}
                OUTPUT_VARIABLE NCOSIM_GIT_COMMIT OUTPUT_STRIP_TRAILING_WHITESPACE
                ERROR_QUIET RESULT_VARIABLE rc)
if(NOT rc EQUAL 0 OR NCOSIM_GIT_COMMIT STREQUAL "")
  set(NCOSIM_GIT_COMMIT "unknown")
else()
  execute_process(COMMAND git diff --quiet HEAD -- WORKING_DIRECTORY ${SRC} RESULT_VARIABLE dirty ERROR_QUIET)
  if(NOT dirty EQUAL 0)
    set(NCOSIM_GIT_COMMIT "${NCOSIM_GIT_COMMIT}-dirty")
  endif()
endif()
set(PROJECT_VERSION ${VERSION})
configure_file(${SRC}/sim/cmd/version.h.in ${OUT} @ONLY)
