#!/usr/bin/env bash
# tests/mpi/mpi_errors.sh NCOSIM SOURCE_DIR RANKS — an error that rank 0 finds under
# `mpirun -n RANKS ncosim run` (--resume without a store, --out /, an output folder locked by
# another process) ends as without mpirun: the same exit code, the same `ncosim: ...` message on
# stderr exactly once, and no MPI_ABORT / ORTE_ERROR_LOG (it used to end with rc 255 and the
# message lost). Label `mpi` in ctest.
set -uo pipefail
ncosim=$1 src=$2 k=$3
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mpi=(mpirun --allow-run-as-root --oversubscribe -n "$k")
scenario=$src/tests/cli/data/base.toml
fail=0

# check WHAT ARGS...: ncosim run SCENARIO ARGS with and without mpirun.
check() {
  local what=$1 bad=$fail
  fail=0
  shift
  local args=(run "$scenario" --runs 4 --periods 200 --quiet "$@")
  "$ncosim" "${args[@]}" >"$tmp/one.out" 2>"$tmp/one.err"
  local want=$?
  timeout 120 "${mpi[@]}" "$ncosim" "${args[@]}" >"$tmp/mpi.out" 2>"$tmp/mpi.err"
  local got=$?
  local msg
  msg=$(grep '^ncosim: ' "$tmp/one.err" | head -1)
  if [[ $want -ne 2 || -z $msg ]]; then
    echo "FAIL ($what): without mpirun: exit $want, message '$msg' (expected exit 2 and a message)"
    fail=1
    return 0
  fi
  if [[ $got -ne $want ]]; then echo "FAIL ($what): exit $got under mpirun, $want without"; fail=1; fi
  local n
  n=$(grep -cxF -- "$msg" "$tmp/mpi.err")
  if [[ $n -ne 1 ]]; then echo "FAIL ($what): '$msg' on stderr $n times under mpirun"; fail=1; fi
  if grep -qE 'ORTE_ERROR_LOG|MPI_ABORT' "$tmp/mpi.err" "$tmp/mpi.out"; then
    echo "FAIL ($what): MPI abort output"; fail=1
  fi
  if ((fail)); then sed 's/^/  | /' "$tmp/mpi.err"; fi
  ((fail |= bad))
}

check "--resume without a store" --resume --out "$tmp/nostore"
check "--out /" --out /
mkdir -p "$tmp/locked"
exec 9>"$tmp/.locked.lock"
flock -n 9 || { echo "FAIL: cannot take the test lock"; exit 1; }
check "locked output folder" --out "$tmp/locked"
exec 9>&-

if ((fail)); then exit 1; fi
echo "ok: $k rank(s): rank 0's errors exit as without mpirun, message once"
