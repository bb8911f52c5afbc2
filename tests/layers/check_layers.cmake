# tests/layers/check_layers.cmake — the layers of the source tree, checked (cmake -P).
# Each folder may include only its own headers and those of the layers below it:
#   kernel         the kernel itself only; outside ncosim: the standard library, POSIX's
#                  <unistd.h>, <fcntl.h>, <poll.h> and <sys/*.h> (whole reads and writes on a file
#                  descriptor, kernel/wire.h) and Boost
#   config         kernel
#   lmi            nothing of ncosim
#   models         kernel, config
#   estimators     kernel, config, models, lmi
#   sumo           kernel, config, models
#   network        kernel, config, models (and ns-3)
# and the application, sim/, in sub-layers on all of those, each on the ones above it here:
#   sim/files      CSV text and atomic result sets
#   sim/scenario   scenario reading (the scenario types, sections, registries, resource limits)
#   sim/run        the run engine and the campaign
#   sim/store      the run store
#   sim/analysis   summaries, paired comparisons, validity, consistency, compare
#   sim/present    tables, figures, reports
#   sim/cmd        the commands (and MPI sessions) and main
# Every `#include "..."` and `#include <...>` of every .h and .cc below SRC is checked; a
# quoted include in kernel/ or config/ that names no folder of an allowed layer (e.g. the
# application's generated "ncosim_version.h") is a violation too, and so is a file of sim/ outside
# its sub-layers or an include of one. With -DLINKS=..., the link lines of the libraries are
# checked the same way ("kernel=a|b,config=...,sim_run=..."; ncosim_X names the layer X,
# ncosim_sim_X the layer sim/X and ncosim_core sim/cmd).
# Include loops: the quoted includes that name a file of the tree form a graph; every cycle in it
# is a violation, both between files and between modules (x.h and x.cc are one module: x.cc
# including y.h while y.h or y.cc includes x.h is a loop of x and y). Modules are checked in
# sim/; the files of the whole tree.
# Namespaces: a file opens only its layer's namespace (ncosim::kernel, ncosim::config, ncosim::lmi,
# ncosim::models, ncosim::est for estimators/, ncosim::sumo, ncosim::network, ncosim::sim for every sub-layer of
# sim/), or one nested in it.
# Prints every violation and fails when any is found, or, with -DEXPECT=N, when the count is not N
# (the test of this check on a tree with known faults).
cmake_minimum_required(VERSION 3.25)

set(sim_layers sim/files sim/scenario sim/run sim/store sim/analysis sim/present sim/cmd)
set(layers kernel config lmi models estimators sumo network ${sim_layers})
set(allowed_kernel kernel)
set(allowed_config kernel config)
set(allowed_lmi lmi)
set(allowed_models kernel config models)
set(allowed_estimators kernel config models lmi estimators)
set(allowed_sumo kernel config models sumo)
set(allowed_network kernel config models network)
set(below kernel config lmi models estimators sumo network)
foreach(layer IN LISTS sim_layers)
  list(APPEND below ${layer})
  set(allowed_${layer} ${below})
endforeach()

if(NOT SRC)
  message(FATAL_ERROR "usage: cmake -DSRC=<source tree> [-DLINKS=...] [-DEXPECT=N] -P check_layers.cmake")
endif()

# The layer of a path below SRC ("sim/run/x.h" -> sim/run), "" when it is in none; `sim` alone
# for a path in sim/ outside its sub-layers.
function(layer_of path out)
  string(REGEX MATCH "^([^/]+)/" _ "${path}")
  set(top "${CMAKE_MATCH_1}")
  if(top STREQUAL "sim")
    string(REGEX MATCH "^sim/([^/]+)/" _ "${path}")
    if(CMAKE_MATCH_1 AND "sim/${CMAKE_MATCH_1}" IN_LIST sim_layers)
      set(${out} "sim/${CMAKE_MATCH_1}" PARENT_SCOPE)
    else()
      set(${out} "sim" PARENT_SCOPE)
    endif()
  elseif(top AND top IN_LIST layers)
    set(${out} "${top}" PARENT_SCOPE)
  else()
    set(${out} "" PARENT_SCOPE)
  endif()
endfunction()

set(violations 0)
set(checked 0)
set(nodes "")  # every file (path below SRC) and, in sim/, every module (path without extension)
file(GLOB_RECURSE files LIST_DIRECTORIES false RELATIVE "${SRC}" "${SRC}/kernel/*.h" "${SRC}/kernel/*.cc"
     "${SRC}/config/*.h" "${SRC}/config/*.cc" "${SRC}/lmi/*.h" "${SRC}/lmi/*.cc" "${SRC}/models/*.h"
     "${SRC}/models/*.cc" "${SRC}/estimators/*.h" "${SRC}/estimators/*.cc" "${SRC}/sumo/*.h"
     "${SRC}/sumo/*.cc" "${SRC}/network/*.h" "${SRC}/network/*.cc" "${SRC}/sim/*.h" "${SRC}/sim/*.cc")
list(SORT files)
foreach(rel IN LISTS files)
  math(EXPR checked "${checked} + 1")
  layer_of("${rel}" layer)
  if(layer STREQUAL "sim")
    math(EXPR violations "${violations} + 1")
    string(REPLACE ";" ", " subs "${sim_layers}")
    message("${rel}: is in sim/ outside its sub-layers (${subs})")
    continue()
  endif()
  # Each layer declares its names in its own namespace (kernel/: ncosim::kernel, ...), so that a
  # qualifier says which layer a name comes from.
  string(REGEX REPLACE "^sim/.*" "sim" own_ns "${layer}")
  if(layer STREQUAL "estimators")
    set(own_ns est)
  endif()
  file(STRINGS "${SRC}/${rel}" ns_lines REGEX "^namespace ncosim(::[a-z_]+)*[ \t]*{")
  foreach(line IN LISTS ns_lines)
    string(REGEX MATCH "^namespace ncosim(::([a-z_]+))?" _ "${line}")
    if(NOT CMAKE_MATCH_2 STREQUAL own_ns)
      math(EXPR violations "${violations} + 1")
      message("${rel}: declares \"${line}\", but ${layer}/ declares its names in ncosim::${own_ns}")
    endif()
  endforeach()
  file(STRINGS "${SRC}/${rel}" lines REGEX "^[ \t]*#[ \t]*include[ \t]*[<\"]")
  string(REGEX REPLACE "\\.[a-z]+$" "" module "${rel}")
  set(edges_${rel} "")
  foreach(line IN LISTS lines)
    string(REGEX MATCH "[<\"]([^>\"]+)[>\"]" _ "${line}")
    set(target "${CMAKE_MATCH_1}")
    string(REGEX MATCH "^([^/]+)/" _ "${target}")
    set(top "${CMAKE_MATCH_1}")
    layer_of("${target}" tlayer)
    set(ok TRUE)
    if(tlayer)
      if(NOT tlayer IN_LIST allowed_${layer})
        set(ok FALSE)
      endif()
    elseif(line MATCHES "\"" AND (layer STREQUAL "kernel" OR layer STREQUAL "config"))
      # A quoted include outside the layer folders (generated or local headers).
      set(ok FALSE)
    elseif(layer STREQUAL "kernel" AND NOT (target MATCHES "^[a-z_]+$" OR top STREQUAL "boost" OR
                                            target MATCHES "^(unistd|fcntl|poll|sys/[a-z_]+)\\.h$"))
      # The kernel: standard headers (<vector>, <cstdint>), POSIX's and Boost only.
      set(ok FALSE)
    endif()
    if(NOT ok)
      math(EXPR violations "${violations} + 1")
      string(REPLACE ";" ", " may "${allowed_${layer}}")
      if(layer STREQUAL "kernel")
        set(may "${may} (and the standard library, POSIX and Boost)")
      endif()
      message("${rel}: includes \"${target}\", but ${layer}/ may include only ${may}")
    endif()
    # The include graph: quoted includes of files of the tree.
    if(line MATCHES "\"" AND EXISTS "${SRC}/${target}" AND NOT IS_DIRECTORY "${SRC}/${target}")
      list(APPEND edges_${rel} "${target}")
      if(rel MATCHES "^sim/")
        string(REGEX REPLACE "\\.[a-z]+$" "" tmodule "${target}")
        if(NOT tmodule STREQUAL module)
          list(APPEND medges_${module} "${tmodule}")
          list(APPEND nodes "${module}")
        endif()
      endif()
    endif()
  endforeach()
  list(APPEND nodes "${rel}")
endforeach()
list(REMOVE_DUPLICATES nodes)
foreach(n IN LISTS nodes)
  if(n MATCHES "\\.(h|cc)$")
    set(out_${n} ${edges_${n}})
  else()
    set(out_${n} ${medges_${n}})
    list(REMOVE_DUPLICATES out_${n})
  endif()
endforeach()

# Cycles: repeatedly drop the nodes without an edge to a node left (they are on no cycle); a node
# left then leads to a cycle, found by walking its edges until a node repeats. Each cycle found is
# reported once and its nodes dropped, and the search goes on with the rest.
set(left ${nodes})
while(left)
  set(changed TRUE)
  while(changed)
    set(changed FALSE)
    set(keep "")
    foreach(n IN LISTS left)
      set(live FALSE)
      foreach(t IN LISTS out_${n})
        if(t IN_LIST left)
          set(live TRUE)
          break()
        endif()
      endforeach()
      if(live)
        list(APPEND keep "${n}")
      else()
        set(changed TRUE)
      endif()
    endforeach()
    set(left ${keep})
  endwhile()
  if(NOT left)
    break()
  endif()
  list(GET left 0 n)
  set(path "")
  while(NOT n IN_LIST path)
    list(APPEND path "${n}")
    foreach(t IN LISTS out_${n})
      if(t IN_LIST left)
        set(n "${t}")
        break()
      endif()
    endforeach()
  endwhile()
  list(FIND path "${n}" at)
  list(SUBLIST path ${at} -1 cycle)
  list(APPEND cycle "${n}")
  string(REPLACE ";" " -> " shown "${cycle}")
  if(n MATCHES "\\.(h|cc)$")
    message("include loop between files: ${shown}")
  else()
    message("include loop between modules (x.h and x.cc): ${shown}")
  endif()
  math(EXPR violations "${violations} + 1")
  list(REMOVE_ITEM left ${cycle})
endwhile()

# Link lines: LINKS = "kernel=lib|lib,config=lib|..." from the build (tests/layers/CMakeLists.txt).
function(layer_of_library lib out)
  if(lib STREQUAL "ncosim_core")
    set(${out} "sim/cmd" PARENT_SCOPE)
  elseif(lib MATCHES "^ncosim_sim_([a-z]+)$")
    set(${out} "sim/${CMAKE_MATCH_1}" PARENT_SCOPE)
  elseif(lib MATCHES "ncosim_([a-z]+)")
    set(${out} "${CMAKE_MATCH_1}" PARENT_SCOPE)
  else()
    set(${out} "" PARENT_SCOPE)
  endif()
endfunction()
string(REPLACE "," ";" link_entries "${LINKS}")
foreach(entry IN LISTS link_entries)
  string(REGEX MATCH "^([a-z_]+)=(.*)$" _ "${entry}")
  set(library "ncosim_${CMAKE_MATCH_1}")
  layer_of_library("${library}" layer)
  string(REPLACE "|" ";" libs "${CMAKE_MATCH_2}")
  foreach(lib IN LISTS libs)
    layer_of_library("${lib}" dep)
    if(dep AND NOT dep IN_LIST allowed_${layer})
      math(EXPR violations "${violations} + 1")
      string(REPLACE ";" ", " may "${allowed_${layer}}")
      message("library ${library} links ${lib}, but ${layer}/ may use only ${may}")
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
  message(FATAL_ERROR "${violations} includes or links run up the layers or in a loop (${checked} files checked)")
else()
  message("layers: ${checked} files checked, no include or link runs up the layers or in a loop")
endif()
