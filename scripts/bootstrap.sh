#!/usr/bin/env bash
# scripts/bootstrap.sh — set up a Debian 12 machine and build ncosim, then either run the
# flagship scenario (`run`) or the whole test suite (`test`: Release, then the unit tests
# again under -fsanitize=address,undefined). Idempotent: installs only missing packages
# (one `apt-get update`), reuses existing build directories.
set -euo pipefail
mode=${1:-run}
case $mode in run|test) ;; *) echo "usage: $0 run|test" >&2; exit 2 ;; esac
cd "$(dirname "$0")/.."

packages=(g++ make cmake libeigen3-dev libboost-dev libboost-random-dev libboost-math-dev
          libfmt-dev libtomlplusplus-dev libcli11-dev nlohmann-json3-dev
          libgtest-dev libgmock-dev libbenchmark-dev
          libsdp-dev liblapack-dev libblas-dev libopenblas0-serial gnuplot-nox sumo sumo-tools
          libsqlite3-dev libboost-mpi-dev libopenmpi-dev openmpi-bin
          chromium libxml2-utils clang-format python3-jsonschema libns3-dev libgsl-dev
          pybind11-dev python3-dev python3-numpy python3-pandas python3-pytest python3-nbclient
          python3-ipykernel python3-matplotlib python3-tqdm)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  sudo=""; [[ $(id -u) -ne 0 ]] && sudo=sudo
  echo "ncosim: installing ${missing[*]}"
  log=$(mktemp)
  if ! { $sudo apt-get update -qq && DEBIAN_FRONTEND=noninteractive \
         $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"; } >"$log" 2>&1; then
    cat "$log"; echo "ncosim: package installation failed" >&2; exit 1
  fi
  rm -f "$log"
fi

jobs=$(nproc)
stage_start=$SECONDS
stage() {  # how long each stage took: where CI's minutes go
  echo "ncosim: $1 in $((SECONDS - stage_start)) s"; stage_start=$SECONDS
}
stage "packages checked"
# The Python package (python/) is built for Debian's python3, whatever else is on PATH.
python=(-DPython_EXECUTABLE=/usr/bin/python3)
build() {  # build DIR [cmake options...] [-- targets...]: configure and build quietly, show the log on failure
  local dir=$1; shift
  local options=() targets=()
  while (($#)) && [[ $1 != -- ]]; do options+=("$1"); shift; done
  (($#)) && shift && targets=(--target "$@")
  mkdir -p "$dir"
  if ! { cmake -S . -B "$dir" "${options[@]}" && cmake --build "$dir" -j "$jobs" "${targets[@]}"; } >"$dir/build.log" 2>&1; then
    tail -40 "$dir/build.log"; echo "ncosim: build failed (full log: $dir/build.log)" >&2; exit 1
  fi
  stage "built $dir"
}

if [[ $mode == run ]]; then
  echo "ncosim: building (Release)..."
  build build -DCMAKE_BUILD_TYPE=Release -DNCOSIM_BUILD_TESTS=OFF -DNCOSIM_BUILD_BENCH=OFF "${python[@]}"
  # Into build/ so that the committed reference results/dolz2014_table2/ stays as committed;
  # --replace: a re-run after an update replaces the previous demo campaign.
  exec build/sim/ncosim run scenarios/dolz2014_table2.toml --out build/results/dolz2014_table2 --replace
fi

echo "ncosim: building (Release)..."
build build -DCMAKE_BUILD_TYPE=Release -DNCOSIM_BUILD_TESTS=ON -DNCOSIM_BUILD_BENCH=ON -DNCOSIM_WERROR=ON "${python[@]}"
echo "ncosim: test suite (Release)"
ctest --test-dir build --output-on-failure -j "$jobs"
stage "test suite ran"
echo "ncosim: building the unit tests with -fsanitize=address,undefined..."
# Only what the `unit` label runs (its test programs, and ncosim, which the network kinds' workers
# and some unit tests start): the other programs are built and run in Release above.
build build-asan -DCMAKE_BUILD_TYPE=Debug -DNCOSIM_SANITIZE=ON -DNCOSIM_BUILD_BENCH=OFF -DNCOSIM_WERROR=ON \
  -DNCOSIM_PYTHON=OFF -- ncosim kernel_test config_test sim_test models_test estimators_test lmi_test \
  conformance_test
echo "ncosim: unit tests under AddressSanitizer + UndefinedBehaviorSanitizer"
ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
  ctest --test-dir build-asan -L unit --output-on-failure -j "$jobs"
stage "sanitizer tests ran"
