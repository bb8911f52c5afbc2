#!/usr/bin/env bash
# ci-examples/run_locally.sh NCOSIM — runs the `run:` steps of github-actions.yml here, as
# GitHub would (each step in its own `bash -e`, stopping at the first failure except the
# `if: always()` steps), with NCOSIM the given executable and OUT and GITHUB_STEP_SUMMARY in a
# temporary folder. Steps whose name says "(CI only)" (set-up, upload) are skipped. Checks:
#   1. against the committed baseline the job passes and writes compare.csv, compare.md and the
#      job summary;
#   2. against a baseline whose S4 row is 3 % better (the same folder with that row's mse_ext
#      scaled by 0.97) the job fails at the compare step with exit 1, and still writes the summary.
# Exit 0 when both hold. Part of the test suite (ctest -R ci_example).
set -euo pipefail
[[ $# -eq 1 ]] || { echo "usage: $0 NCOSIM" >&2; exit 2; }
ncosim=$(realpath "$1")
here=$(cd "$(dirname "$0")" && pwd)
root=$(dirname "$here")
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$root"

# Split the workflow into one file per step to run: step_NN.sh, and step_NN.always when the
# step has `if: always()`.
awk -v dir="$work" '
  function flush() {
    if (body != "" && name !~ /\(CI only\)/) {
      n++; f = sprintf("%s/step_%02d.sh", dir, n)
      printf "# %s\n%s", name, body > f; close(f)
      if (always) { a = sprintf("%s/step_%02d.always", dir, n); printf "" > a; close(a) }
    }
    body = ""; name = ""; always = 0; inrun = 0
  }
  /^      - / { flush(); if ($0 ~ /name:/) name = substr($0, index($0, "name:") + 6); next }
  /^        name:/ { name = substr($0, index($0, "name:") + 6); next }
  /^        if: always\(\)/ { always = 1; next }
  /^        run: \|/ { inrun = 1; next }
  inrun && /^          / { body = body substr($0, 11) "\n"; next }
  inrun { inrun = 0 }
  END { flush() }
' "$here/github-actions.yml"
steps=("$work"/step_*.sh)
[[ ${#steps[@]} -ge 3 ]] || { echo "run_locally: expected at least 3 local steps in github-actions.yml" >&2; exit 1; }

# job BASELINE OUT: runs the steps; prints the failing step's exit code (0 when all passed).
job() {
  local failed=0 code
  for s in "${steps[@]}"; do
    if [[ $failed -ne 0 && ! -e ${s%.sh}.always ]]; then continue; fi
    echo "run_locally: $(head -1 "$s" | cut -c3-)" >&2
    code=0
    NCOSIM="$ncosim" OUT="$2" BASELINE="$1" GITHUB_STEP_SUMMARY="$2.summary.md" bash -e "$s" >&2 || code=$?
    if [[ $code -ne 0 && $failed -eq 0 ]]; then failed=$code; fi
  done
  echo "$failed"
}

fail() { echo "run_locally: FAIL: $*" >&2; exit 1; }

baseline=$(awk '/^      BASELINE:/ { print $2 }' "$here/github-actions.yml")
[[ -d $baseline ]] || fail "the workflow's BASELINE '$baseline' is not a folder of this repository"

code=$(job "$baseline" "$work/ok")
[[ $code -eq 0 ]] || fail "the job fails against the committed baseline (exit $code)"
for f in "$work/ok/compare/compare.csv" "$work/ok/compare/compare.md" "$work/ok/new/summary.csv" "$work/ok.summary.md"; do
  [[ -s $f ]] || fail "missing $f"
done
grep -q ': exit 0$' "$work/ok.summary.md" || fail "the job summary does not end with exit 0"

# A baseline 3 % better on one row: the same job must fail with exit 1 at the compare step.
better="$work/better"
cp -r "$baseline" "$better"
awk -F, 'BEGIN { OFS = "," }
  NR == 1 { for (i = 1; i <= NF; i++) if ($i == "mse_ext") c = i; print; next }
  /^[0-9]+,"S4, 60 gains",/ { split($0, q, "\""); n = split(q[3], f, ","); f[3] = f[3] * 0.97;
    line = q[1] "\"" q[2] "\""; for (i = 2; i <= n; i++) line = line "," f[i]; print line; next }
  { print }' "$baseline/runs.csv" > "$better/runs.csv"
cmp -s "$baseline/runs.csv" "$better/runs.csv" && fail "the tampered baseline equals the committed one"
code=$(job "$better" "$work/bad")
[[ $code -eq 1 ]] || fail "expected the compare step to fail with exit 1 on a 3 % regression, got $code"
grep -q '\*\*worse\*\*' "$work/bad.summary.md" || fail "the job summary does not show the worse row"
echo "run_locally: ok (passes on the committed baseline, fails with exit 1 on a 3 % regression)"
