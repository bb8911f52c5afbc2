# tests/install/tdma_test.cmake — run by CTest: install the build into WORK_DIR/prefix, build
# examples/tdma_bus against it (find_package(ncosim): a network backend written against the
# installed network/backend.h), and check that the fates a campaign records are those computed by
# hand in examples/tdma_bus/scenario.toml: record-link's delays of the first 13 packets, and
# links.csv's delay histogram of a 13-period run.
cmake_policy(SET CMP0007 NEW)  # links.csv's empty cells are list elements too
include(${CMAKE_CURRENT_LIST_DIR}/install_common.cmake)
if(EXISTS ${prefix}/include/ncosim/network/ns3/world.h)
  message(FATAL_ERROR "cmake --install installed the ns-3 backend's private header network/ns3/world.h")
endif()
set(launcher "")
if(LAUNCHER)
  set(launcher -DCMAKE_CXX_COMPILER_LAUNCHER=${LAUNCHER})
endif()
set(example ${SOURCE_DIR}/examples/tdma_bus)
run("configuring the example" ${CMAKE_COMMAND} -S ${example} -B ${WORK_DIR}/build
    -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=${CXX} ${launcher} -DCMAKE_PREFIX_PATH=${prefix})
run("building the example" ${CMAKE_COMMAND} --build ${WORK_DIR}/build -j2)
set(exe ${WORK_DIR}/build/my_tdma)

# (`list` shows no network kinds, built-in or not: that the program knows tdma_bus is shown by
# the record-link below, which reads the scenario's [[network]] kind = "tdma_bus".)
# Packet by packet: the table of scenario.toml (an empty delay: lost at the full queue).
run("my_tdma record-link" ${exe} record-link ${example}/scenario.toml --link bus --runs 1 --set run.warmup=1
    --periods 13 --out ${WORK_DIR}/record --quiet)
file(READ ${WORK_DIR}/record/bus.csv recorded)
set(expected "seq,delay\n0,1\n1,2\n2,2\n3,3\n4,4\n5,4\n6,\n7,4\n8,4\n9,\n10,4\n11,\n12,4\n")
if(NOT recorded STREQUAL expected)
  message(FATAL_ERROR "record-link's delays are not the hand-computed ones:\n${recorded}\nexpected:\n${expected}")
endif()

# A campaign of 13 periods: by the end of period 12 (60 ms) packets 0..8 are received or lost
# (10 and 12 are still queued, 11 decided lost): 11 fates, 8 delivered with delays 1, 2, 2, 3, 4,
# 4, 4, 4 (so P(delay d) = 0, 1/11, 2/11, 1/11, 4/11 per packet sent), 3 dropped at the queue; 8
# transmissions started (packet 8's at 56 ms).
run("my_tdma run" ${exe} run ${example}/scenario.toml --runs 1 --periods 13 --set run.warmup=1
    --out ${WORK_DIR}/out --quiet --no-timing)
file(READ ${WORK_DIR}/out/links.csv text)
string(REPLACE ";" "|" text "${text}")  # delay_pmf's own separators, kept apart from CMake lists
string(REPLACE "\n" ";" rows "${text}")
list(GET rows 0 header)
list(GET rows 1 row)
string(REPLACE "," ";" names "${header}")
string(REPLACE "," ";" values "${row}")
set(got "")
foreach(column packets_sent packets_delivered delay_max delay_pmf drops_queue mac_attempts)
  list(FIND names ${column} i)
  if(i EQUAL -1)
    message(FATAL_ERROR "links.csv has no column ${column}:\n${header}")
  endif()
  list(GET values ${i} value)
  string(APPEND got "${column}=${value} ")
endforeach()
set(by_hand "packets_sent=11 packets_delivered=8 delay_max=4 delay_pmf=0|0.0909091|0.181818|0.0909091|0.363636 drops_queue=3 mac_attempts=8 ")
if(NOT got STREQUAL by_hand)
  message(FATAL_ERROR "links.csv:\n  ${got}\nby hand:\n  ${by_hand}\n${header}\n${row}")
endif()
message(STATUS "examples/tdma_bus built against the installed package; its fates are the hand-computed ones")
