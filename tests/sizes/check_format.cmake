# tests/sizes/check_format.cmake: `clang-format --dry-run --Werror` over every git-tracked .h and
# .cc of SRC except the planted-fault trees (tests/layers/faulty, tests/sizes/faulty).
# Usage: cmake -DSRC=DIR -DCLANG_FORMAT=PATH -DGIT=PATH -P check_format.cmake
if(NOT CLANG_FORMAT OR CLANG_FORMAT MATCHES "NOTFOUND$")
  message(FATAL_ERROR "clang-format not found: install Debian's clang-format "
                      "(apt-get install clang-format; scripts/bootstrap.sh does) and configure again")
endif()
if(NOT GIT OR GIT MATCHES "NOTFOUND$")
  message(FATAL_ERROR "git not found: the files checked are the git-tracked ones (install git)")
endif()
execute_process(COMMAND ${GIT} ls-files -- "*.h" "*.cc" WORKING_DIRECTORY ${SRC}
                OUTPUT_VARIABLE listed RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "git ls-files failed in ${SRC} (not a git checkout?): ${err}")
endif()
string(REPLACE "\n" ";" listed "${listed}")
set(files)
foreach(f IN LISTS listed)
  if(f AND NOT f MATCHES "^tests/(layers|sizes)/faulty/")
    list(APPEND files ${f})
  endif()
endforeach()
list(LENGTH files n)
if(n EQUAL 0)
  message(FATAL_ERROR "no git-tracked .h or .cc files found in ${SRC}")
endif()
execute_process(COMMAND ${CLANG_FORMAT} --dry-run --Werror ${files} WORKING_DIRECTORY ${SRC}
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message("${err}")
  message(FATAL_ERROR "files not formatted as .clang-format says: run clang-format -i on them")
endif()
message(STATUS "${n} files formatted as .clang-format says")
