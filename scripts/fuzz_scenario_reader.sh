#!/usr/bin/env bash
# scripts/fuzz_scenario_reader.sh — builds the coverage-guided fuzz target of the scenario reader
# (tests/fuzz/scenario_reader_fuzz.cc) with clang 14 and -fsanitize=fuzzer,address in its own
# build folder, seeds its corpus from scenarios/ and tests/cli/data/, and runs it.
#
#   bash scripts/fuzz_scenario_reader.sh [SECONDS=600] [BUILD_DIR=build-fuzz]
#
# Needs Debian's clang (clang++-14) and libclang-rt-14-dev. Not part of CI. Findings (crashes,
# sanitizer reports, exceptions that are not ScenarioError, exit-2 messages without FILE:LINE)
# are written to BUILD_DIR/artifacts/; turn each into a regression test (tests/cli, tests/fuzz).
set -euo pipefail
seconds=${1:-600}
build=${2:-build-fuzz}
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
cxx=$(command -v clang++-14 || command -v clang++)
cc=$(command -v clang-14 || command -v clang)
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_COMPILER="$cc" -DCMAKE_CXX_COMPILER="$cxx" \
  -DCMAKE_CXX_FLAGS="-fsanitize=fuzzer-no-link,address -fno-omit-frame-pointer" \
  -DNCOSIM_BUILD_TESTS=ON -DNCOSIM_BUILD_BENCH=OFF -DNCOSIM_WERROR=OFF -DNCOSIM_FUZZ_TARGET=ON \
  -DNCOSIM_SUMO=OFF ${CMAKE_CXX_COMPILER_LAUNCHER:+-DCMAKE_CXX_COMPILER_LAUNCHER=$CMAKE_CXX_COMPILER_LAUNCHER} >/dev/null
nice cmake --build "$build" -j"${JOBS:-2}" --target scenario_reader_fuzz
mkdir -p "$build/corpus" "$build/artifacts"
cp scenarios/*.toml tests/cli/data/*.toml "$build/corpus/"
cd "$build"
# -rss_limit_mb: every input stays under 2 GB; -timeout: 120 s of wall time per input. The
# reader's caps are 200 MB and 2 GFLOP per design, but a sweep designs every case: the slowest
# seed, scenarios/dolz2014_fig1c.toml, takes about 20 s under ASan on a 2-core machine with one
# other job (and a 30 s timeout fired on it under heavier load). -max_len 8192 covers the
# shipped scenarios.
ASAN_OPTIONS=detect_leaks=0:allocator_may_return_null=1 nice -n 19 ./tests/scenario_reader_fuzz \
  -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=120 -max_len=8192 -print_final_stats=1 \
  -artifact_prefix=artifacts/ corpus
