#!/usr/bin/env bash
# tests/mpi/mpi_ranks.sh NCOSIM SOURCE_DIR RANKS — `mpirun -n RANKS ncosim run` gives exports
# bit-identical to one process with --threads 1 (links.csv included; error_curve.csv on the sweep): on the flagship (fewer periods), on a sweep
# scenario, and with --target-ci (same stopping point and numbers; stopped by --max-runs on the
# flagship, whose S1 row is heavy-tailed, and by the target on the small test scenario), and a
# network scenario when ncosim has ns-3. Label `mpi` in ctest.
set -euo pipefail
ncosim=$1 src=$2 k=$3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mpi=(mpirun --allow-run-as-root --oversubscribe -n "$k")
fail=0
same() {  # same REF OTHER WHAT: every export but the timing fields
  local f
  [[ -e $1/links.csv ]] || { echo "FAIL ($3): no links.csv"; fail=1; }
  for f in summary.csv summary.md runs.csv transmissions.csv confusion.csv links.csv error_curve.csv; do
    if [[ -e $1/$f || -e $2/$f ]] && ! cmp -s "$1/$f" "$2/$f"; then
      echo "FAIL ($3): $f differs"; diff "$1/$f" "$2/$f" | head -5; fail=1
    fi
  done
  if ! grep -q '"complete": true' "$2/manifest.json"; then echo "FAIL ($3): not complete"; fail=1; fi
  if ! grep -q "\"ranks\": $k" "$2/manifest.json"; then echo "FAIL ($3): manifest ranks"; fail=1; fi
}
flagship=$src/scenarios/dolz2014_table2.toml
common=(--no-timing --quiet)
"$ncosim" run "$flagship" --runs 12 --periods 3000 "${common[@]}" --threads 1 --out "$tmp/ref" >/dev/null
"${mpi[@]}" "$ncosim" run "$flagship" --runs 12 --periods 3000 "${common[@]}" --out "$tmp/mpi" >/dev/null
same "$tmp/ref" "$tmp/mpi" "flagship"

{ cat "$src/tests/cli/data/base.toml"; printf '\n[[sweep]]\nkey = "link[1].loss"\nvalues = [0.1, 0.4]\n'; } > "$tmp/sweep.toml"
# With the error curve: the worker ranks' curves are collected by rank 0 after each case.
curve=(--set run.error_curve=true)
"$ncosim" run "$tmp/sweep.toml" --runs 7 --periods 800 "${common[@]}" "${curve[@]}" --threads 1 --out "$tmp/sref" >/dev/null
"${mpi[@]}" "$ncosim" run "$tmp/sweep.toml" --runs 7 --periods 800 "${common[@]}" "${curve[@]}" --out "$tmp/smpi" >/dev/null
[[ -s $tmp/smpi/error_curve.csv ]] || { echo "FAIL (sweep): no error_curve.csv"; fail=1; }
same "$tmp/sref" "$tmp/smpi" "sweep"

target=(--runs 10 --periods 2000 --target-ci 0.05 --max-runs 200)
"$ncosim" run "$flagship" "${target[@]}" "${common[@]}" --threads 1 --out "$tmp/tref" >/dev/null
"${mpi[@]}" "$ncosim" run "$flagship" "${target[@]}" "${common[@]}" --out "$tmp/tmpi" >/dev/null
same "$tmp/tref" "$tmp/tmpi" "target-ci"

target=(--runs 10 --periods 1000 --target-ci 0.02 --max-runs 400)
"$ncosim" run "$src/tests/cli/data/base.toml" "${target[@]}" "${common[@]}" --threads 1 --out "$tmp/bref" >/dev/null
"${mpi[@]}" "$ncosim" run "$src/tests/cli/data/base.toml" "${target[@]}" "${common[@]}" --out "$tmp/bmpi" >/dev/null
same "$tmp/bref" "$tmp/bmpi" "target-ci reached"
grep -q '"stop": "target_ci"' "$tmp/bmpi/manifest.json" || { echo "FAIL: target not reached"; fail=1; }

# A network scenario (builds with ns-3): every run in a process of its own on whichever rank, the
# same bytes as --threads 1 (run 0's trace and the error curve included); a run whose ns-3 aborts
# (the test hook NCOSIM_TEST_CRASH_RUN, network/ns3/ns3_engine.cc) gets its status on any rank.
wsn=$src/scenarios/wsn_star.toml
label="no network"
if "$ncosim" check "$wsn" >/dev/null 2>&1; then
  net=(--runs 5 --periods 300 --trace --set run.error_curve=true)
  "$ncosim" run "$wsn" "${net[@]}" "${common[@]}" --threads 1 --out "$tmp/nref" >/dev/null
  "${mpi[@]}" "$ncosim" run "$wsn" "${net[@]}" "${common[@]}" --out "$tmp/nmpi" >/dev/null
  same "$tmp/nref" "$tmp/nmpi" "network"
  cmp -s "$tmp/nref/trajectory.csv" "$tmp/nmpi/trajectory.csv" || { echo "FAIL (network): trajectory.csv differs"; fail=1; }
  rc=0
  NCOSIM_TEST_CRASH_RUN=3 "${mpi[@]}" -x NCOSIM_TEST_CRASH_RUN "$ncosim" run "$wsn" --runs 5 --periods 300 \
    "${common[@]}" --out "$tmp/ncrash" >/dev/null 2>"$tmp/ncrash.err" || rc=$?
  [[ $rc == 3 ]] || { echo "FAIL (network crash): exit $rc"; cat "$tmp/ncrash.err"; fail=1; }
  [[ $(grep -c '^3,.*,network_failure,' "$tmp/ncrash/runs.csv") == 2 ]] || { echo "FAIL (network crash): runs.csv"; fail=1; }
  grep -q 'ncosim: run 3: network_failure: .*msg="NCOSIM_TEST_CRASH_RUN: run 3 fails"' "$tmp/ncrash.err" || { echo "FAIL (network crash): message"; fail=1; }
  label="network"
fi

if ((fail)); then exit 1; fi
echo "ok: $k rank(s) bit-identical to one process (flagship, sweep, --target-ci, $label)"
