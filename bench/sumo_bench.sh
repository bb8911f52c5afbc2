#!/bin/sh
# bench/sumo_bench.sh — SUMO co-simulation timings (bench/README.md): on the 4x4 grid with 100
# and 1000 vehicles, 3000 steps of 0.1 s:
#   bare      the `sumo` binary alone (same options as ncosim's workers)
#   record    `ncosim check` with an empty cache: start-up + one worker process recording
#   replay    `ncosim run --runs 100` with the recording cached, per run
#   live      `ncosim run --runs 4` with sumo.mode = "live" (libsumo stepped in-process), per run
#   startup   `ncosim list` and `sumo --version` (process start-up, ~220 shared libraries)
# Each figure is the median of REPEAT (default 3) wall-clock measurements.
# Usage: bench/sumo_bench.sh [BUILD_DIR]   (after scenarios/sumo/make_inputs.sh)
set -eu
here=$(cd "$(dirname "$0")" && pwd)
build=${1:-$here/../build}
ncosim="$build/sim/ncosim"
repeat=${REPEAT:-3}
export SUMO_HOME=${SUMO_HOME:-/usr/share/sumo}
gen="$here/../scenarios/sumo/gen"
[ -f "$gen/grid.net.xml" ] || { echo "run scenarios/sumo/make_inputs.sh first" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# wall seconds of a command (stdout and stderr discarded)
wall() {
  python3 - "$@" <<'PY'
import subprocess, sys, time
t = time.perf_counter()
subprocess.run(sys.argv[1:], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
print(f"{time.perf_counter() - t:.4f}")
PY
}
median() { sort -n | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }

echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'); load: $(cut -d' ' -f1-3 /proc/loadavg)"
echo "startup  ncosim list:    $(for i in $(seq $repeat); do wall "$ncosim" list; done | median) s"
echo "startup  sumo --version: $(for i in $(seq $repeat); do wall sumo --version; done | median) s"
for n in 100 1000; do
  routes="../scenarios/sumo/gen/grid$n.rou.xml"
  bare=$(for i in $(seq $repeat); do
    wall sumo -n "$gen/grid.net.xml" -r "$gen/grid$n.rou.xml" --step-length 0.1 --begin 0 --end 299.9 \
      --seed 1 --no-step-log true --no-warnings true --duration-log.disable true --xml-validation never
  done | median)
  record=$(for i in $(seq $repeat); do
    rm -rf "$tmp/cache"
    wall "$ncosim" check "$here/sumo_grid.toml" --set "sumo.routes=\"$routes\"" --set "sumo.cache=\"$tmp/cache\""
  done | median)
  replay=$(for i in $(seq $repeat); do
    wall "$ncosim" run "$here/sumo_grid.toml" --quiet --out "$tmp/out" --set "sumo.routes=\"$routes\"" \
      --set "sumo.cache=\"$tmp/cache\"" --runs 100
  done | median)
  live=$(for i in $(seq $repeat); do
    wall "$ncosim" run "$here/sumo_grid.toml" --quiet --out "$tmp/out" --set "sumo.routes=\"$routes\"" \
      --set "sumo.cache=\"$tmp/cache\"" --set 'sumo.mode="live"' --runs 4
  done | median)
  python3 - "$n" "$bare" "$record" "$replay" "$live" <<'PY'
import sys
n, bare, record, replay, live = sys.argv[1], *map(float, sys.argv[2:])
# Each command also replays run 0 once more to time the estimators (ns_per_period): 101 and 5 runs.
per_replay, per_live = replay / 101, live / 5
print(f"grid {n:>4} vehicles: bare sumo {bare:.3f} s | recording pass {record:.3f} s ({record / bare:.2f}x bare) | "
      f"replay {per_replay * 1e3:.1f} ms/run (100 runs: {replay:.3f} s) | live {per_live:.3f} s/run | "
      f"live/replay per run {per_live / per_replay:.0f}x")
PY
done
