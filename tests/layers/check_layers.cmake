# tests/layers/check_layers.cmake — the layers of the source tree, checked (cmake -P).
# Each folder may include only its own headers and those of the layers below it:
#   kernel       the kernel itself only; outside ncosim: the standard library and Boost
#   config       kernel
#   lmi          nothing of ncosim
#   models       kernel, config
#   estimators   kernel, config, models, lmi
#   sumo         kernel, config, models
#   sim          anything (the application, on top)
# Every `#include "..."` and `#include <...>` of every .h and .cc below SRC is checked; a
# quoted include in kernel/ or config/ that names no folder of an allowed layer (e.g. the
# application's generated "ncosim_version.h") is a violation too. With -DLINKS=..., the link
# lines of the libraries are checked the same way ("kernel=a|b,config=..."; ncosim_X names
# the layer X). Prints every violation and fails when any is found, or, with
# -DEXPECT=N, when the count is not N (the test of this check on a tree with known faults).
cmake_minimum_required(VERSION 3.25)

set(layers kernel config lmi models estimators sumo sim)
set(allowed_kernel kernel)
set(allowed_config kernel config)
set(allowed_lmi lmi)
set(allowed_models kernel config models)
set(allowed_estimators kernel config models lmi estimators)
set(allowed_sumo kernel config models sumo)

if(NOT SRC)
  message(FATAL_ERROR "usage: cmake -DSRC=<source tree> [-DLINKS=...] [-DEXPECT=N] -P check_layers.cmake")
endif()

set(violations 0)
set(checked 0)
foreach(layer IN LISTS layers)
  if(layer STREQUAL "sim")
    continue()
  endif()
  file(GLOB_RECURSE files LIST_DIRECTORIES false "${SRC}/${layer}/*.h" "${SRC}/${layer}/*.cc")
  foreach(f IN LISTS files)
    math(EXPR checked "${checked} + 1")
    file(STRINGS "${f}" lines REGEX "^[ \t]*#[ \t]*include[ \t]*[<\"]")
    file(RELATIVE_PATH rel "${SRC}" "${f}")
    foreach(line IN LISTS lines)
      string(REGEX MATCH "[<\"]([^>\"]+)[>\"]" _ "${line}")
      set(target "${CMAKE_MATCH_1}")
      string(REGEX MATCH "^([^/]+)/" _ "${target}")
      set(top "${CMAKE_MATCH_1}")
      set(ok TRUE)
      if(top AND top IN_LIST layers)
        if(NOT top IN_LIST allowed_${layer})
          set(ok FALSE)
        endif()
      elseif(line MATCHES "\"" AND (layer STREQUAL "kernel" OR layer STREQUAL "config"))
        # A quoted include outside the layer folders (generated or local headers).
        set(ok FALSE)
      elseif(layer STREQUAL "kernel" AND NOT (target MATCHES "^[a-z_]+$" OR top STREQUAL "boost"))
        # The kernel: standard headers (<vector>, <cstdint>) and Boost only.
        set(ok FALSE)
      endif()
      if(NOT ok)
        math(EXPR violations "${violations} + 1")
        string(REPLACE ";" ", " may "${allowed_${layer}}")
        if(layer STREQUAL "kernel")
          set(may "${may} (and the standard library and Boost)")
        endif()
        message("${rel}: includes \"${target}\", but ${layer}/ may include only ${may}")
      endif()
    endforeach()
  endforeach()
endforeach()

# Link lines: LINKS = "kernel=lib|lib,config=lib|..." from the build (tests/layers/CMakeLists.txt).
string(REPLACE "," ";" link_entries "${LINKS}")
foreach(entry IN LISTS link_entries)
  string(REGEX MATCH "^([a-z]+)=(.*)$" _ "${entry}")
  set(layer "${CMAKE_MATCH_1}")
  string(REPLACE "|" ";" libs "${CMAKE_MATCH_2}")
  foreach(lib IN LISTS libs)
    if(lib MATCHES "ncosim_([a-z]+)")
      set(dep "${CMAKE_MATCH_1}")
      if(NOT dep IN_LIST allowed_${layer})
        math(EXPR violations "${violations} + 1")
        string(REPLACE ";" ", " may "${allowed_${layer}}")
        message("library ncosim_${layer} links ${lib}, but ${layer}/ may use only ${may}")
      endif()
    endif()
  endforeach()
endforeach()

if(checked EQUAL 0)
  message(FATAL_ERROR "no source files found below ${SRC}")
endif()
if(DEFINED EXPECT)
  if(NOT violations EQUAL EXPECT)
    message(FATAL_ERROR "expected ${EXPECT} layer violations in ${SRC}, found ${violations}")
  endif()
  message("${violations} layer violations found, as expected (${checked} files)")
elseif(violations GREATER 0)
  message(FATAL_ERROR "${violations} includes or links run up the layers (${checked} files checked)")
else()
  message("layers: ${checked} files checked, no include or link runs up the layers")
endif()
