#!/bin/sh
# bench/sumo_bench.sh — SUMO co-simulation timings (bench/README.md): on the 4x4 grid with 100
# and 1000 vehicles, 3000 steps of 0.1 s:
#   bare      the `sumo` binary alone (exactly the options ncosim's recording passes, without
#             the FCD output)
#   fcd       the same `sumo` command with the recording's FCD options (SUMO's own share)
#   record    `ncosim check` with an empty cache: ncosim start-up, input hashing, the `sumo`
#             process with FCD output for the 2 named vehicles, FCD parsing, the .traj file
#   replay    `ncosim run --runs 100` with the recording cached, per run
#   live      `ncosim run --runs 4` with sumo.mode = "live" (one `ncosim sumo-live` worker
#             process per run, libsumo stepped there), per run
#   startup   `ncosim list` and `sumo --version`
# bare, fcd and record are measured alternately, ROUNDS (default 7) times; the figure is the median of
# the per-round ratios record/bare (robust to the load of other processes on the machine), with
# the medians of each. replay and live: median of REPEAT (default 3). The load average is printed
# before and after.
# Usage: bench/sumo_bench.sh [BUILD_DIR]   (after scenarios/sumo/make_inputs.sh)
set -eu
here=$(cd "$(dirname "$0")" && pwd)
build=${1:-$here/../build}
ncosim="$build/sim/ncosim"
repeat=${REPEAT:-3}
rounds=${ROUNDS:-7}
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
  : >"$tmp/rounds"
  for i in $(seq $rounds); do
    bare=$(wall sumo -n "$gen/grid.net.xml" -r "$gen/grid$n.rou.xml" --no-step-log true --no-warnings true \
      --duration-log.disable true --xml-validation never --xml-validation.net never --xml-validation.routes never \
      --seed 1 --step-length 0.1 --begin 0 --end 299.9)
    fcd=$(wall sumo -n "$gen/grid.net.xml" -r "$gen/grid$n.rou.xml" --no-step-log true --no-warnings true \
      --duration-log.disable true --xml-validation never --xml-validation.net never --xml-validation.routes never \
      --seed 1 --step-length 0.1 --begin 0 --end 299.9 --fcd-output "$tmp/fcd.xml" --device.fcd.explicit 0,1 \
      --fcd-output.attributes x,y,speed,acceleration,odometer --precision 40)
    rm -rf "$tmp/cache"
    record=$(wall "$ncosim" check "$here/sumo_grid.toml" --set "sumo.routes=\"$routes\"" --set "sumo.cache=\"$tmp/cache\"")
    echo "$bare $record $fcd" >>"$tmp/rounds"
  done
  replay=$(for i in $(seq $repeat); do
    wall "$ncosim" run "$here/sumo_grid.toml" --quiet --out "$tmp/out" --set "sumo.routes=\"$routes\"" \
      --set "sumo.cache=\"$tmp/cache\"" --runs 100
  done | median)
  live=$(for i in $(seq $repeat); do
    wall "$ncosim" run "$here/sumo_grid.toml" --quiet --out "$tmp/out" --set "sumo.routes=\"$routes\"" \
      --set "sumo.cache=\"$tmp/cache\"" --set 'sumo.mode="live"' --runs 4
  done | median)
  python3 - "$n" "$tmp/rounds" "$replay" "$live" <<'PY'
import statistics, sys
n, rounds = sys.argv[1], [tuple(map(float, l.split())) for l in open(sys.argv[2])]
replay, live = map(float, sys.argv[3:])
bare = statistics.median(b for b, _, _ in rounds)
record = statistics.median(r for _, r, _ in rounds)
fcd = statistics.median(f for _, _, f in rounds)
ratio = statistics.median(r / b for b, r, _ in rounds)
fcd_ratio = statistics.median(f / b for b, _, f in rounds)
ratios = " ".join(f"{r / b:.2f}" for b, r, _ in rounds)
# Each command also replays run 0 once more to time the estimators (ns_per_period): 101 and 5 runs.
per_replay, per_live = replay / 101, live / 5
print(f"grid {n:>4} vehicles: bare sumo {bare:.3f} s | recording pass {record:.3f} s | record/bare median of "
      f"{len(rounds)} rounds {ratio:.2f}x (rounds: {ratios}) | sumo with the FCD output alone {fcd:.3f} s, "
      f"{fcd_ratio:.2f}x bare | replay {per_replay * 1e3:.1f} ms/run "
      f"(100 runs: {replay:.3f} s) | live {per_live:.3f} s/run | live/replay per run {per_live / per_replay:.0f}x")
PY
done
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
