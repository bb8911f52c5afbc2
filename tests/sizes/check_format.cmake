# tests/sizes/check_format.cmake: `clang-format --dry-run --Werror` over every .h and .cc of SRC's
# source folders except the planted-fault trees (tests/layers/faulty, tests/sizes/faulty).
# Usage: cmake -DSRC=DIR -DCLANG_FORMAT=PATH -P check_format.cmake
if(NOT CLANG_FORMAT OR CLANG_FORMAT MATCHES "NOTFOUND$")
  message(FATAL_ERROR "clang-format not found: install Debian's clang-format "
                      "(apt-get install clang-format; scripts/bootstrap.sh does) and configure again")
endif()
# The source folders, globbed (not `git ls-files`: a tree unpacked from `git archive`, as CI and
# scripts/bootstrap.sh's users have it, has no .git).
set(files)
foreach(dir kernel config lmi models estimators sumo sim tests bench examples)
  file(GLOB_RECURSE found RELATIVE ${SRC} "${SRC}/${dir}/*.h" "${SRC}/${dir}/*.cc")
  foreach(f IN LISTS found)
    if(NOT f MATCHES "^tests/(layers|sizes)/faulty/")
      list(APPEND files ${f})
    endif()
  endforeach()
endforeach()
list(LENGTH files n)
if(n EQUAL 0)
  message(FATAL_ERROR "no .h or .cc files found in ${SRC}")
endif()
execute_process(COMMAND ${CLANG_FORMAT} --dry-run --Werror ${files} WORKING_DIRECTORY ${SRC}
                RESULT_VARIABLE rc ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message("${err}")
  message(FATAL_ERROR "files not formatted as .clang-format says: run clang-format -i on them")
endif()
message(STATUS "${n} files formatted as .clang-format says")
