#!/usr/bin/env bash
# tests/cli/slurm_shards_test.sh NCOSIM SOURCE_DIR — scripts/slurm_shards.sh under a fake Slurm
# environment (the SLURM_ARRAY_TASK_* variables sbatch sets): arrays 1-N, 0-(N-1) and stepped
# give the shards 1..N whose merge is bit-identical to one process; an irregular array is refused;
# a task killed by SIGKILL (after its last run, before its exports: the unfinished store beside
# the folder; or while creating its store: an empty one) is finished by running the same command
# again; the script uses no array expansion (`"${a[@]}"` of an empty array under `set -u` fails
# before bash 4.4). Label `cli` in ctest.
set -uo pipefail
ncosim=$1 src=$2
script=$src/scripts/slurm_shards.sh
scenario=$src/tests/cli/data/base.toml
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
fail=0
flags=(--runs 6 --periods 300 --no-timing --quiet)

no() { echo "FAIL: $*"; fail=1; }

# task ID COUNT MIN MAX STEP DIR [env...]: one array task, as sbatch would start it.
task() {
  local id=$1 count=$2 min=$3 max=$4 step=$5 dir=$6
  shift 6
  env "$@" NCOSIM="$ncosim" SLURM_ARRAY_TASK_ID="$id" SLURM_ARRAY_TASK_COUNT="$count" \
    SLURM_ARRAY_TASK_MIN="$min" SLURM_ARRAY_TASK_MAX="$max" SLURM_ARRAY_TASK_STEP="$step" \
    SLURM_CPUS_PER_TASK=1 bash "$script" "$scenario" "$dir" "${flags[@]}" >"$tmp/task.log" 2>&1
}

"$ncosim" run "$scenario" --out "$tmp/ref" --threads 1 "${flags[@]}" >/dev/null 2>&1 ||
  no "the reference campaign"

# merged DIR WHAT: merges DIR/shard_* and compares with the reference.
merged() {
  local dir=$1 what=$2
  if ! "$ncosim" merge "$dir/merged" "$dir"/shard_* >"$tmp/merge.log" 2>&1; then
    no "$what: merge failed: $(cat "$tmp/merge.log")"
    return
  fi
  for f in summary.csv runs.csv links.csv; do
    cmp -s "$tmp/ref/$f" "$dir/merged/$f" || no "$what: $f differs from one process"
  done
}

# Arrays 1-3, 0-2 and 0-4:2 (IDs 0, 2, 4): shards 1/3, 2/3, 3/3 into shard_1..shard_3.
for spec in "1 3 1" "0 2 1" "0 4 2"; do
  read -r min max step <<<"$spec"
  dir=$tmp/array_${min}_${max}_$step
  for ((id = min; id <= max; id += step)); do
    task "$id" 3 "$min" "$max" "$step" "$dir" || no "array $min-$max:$step task $id: $(cat "$tmp/task.log")"
  done
  for i in 1 2 3; do
    grep -q "\"shard\": \"$i/3\"" "$dir/shard_$i/manifest.json" 2>/dev/null ||
      no "array $min-$max:$step: shard_$i is not shard $i/3"
  done
  merged "$dir" "array $min-$max:$step"
done

# An irregular array (1,5,7: count 3, min 1, max 7, step 1) is refused, nothing written.
dir=$tmp/irregular
task 5 3 1 7 1 "$dir"
rc=$?
[[ $rc -eq 2 ]] || no "irregular array: exit $rc, expected 2"
grep -q "not a regular array" "$tmp/task.log" || no "irregular array: $(cat "$tmp/task.log")"
[[ ! -e $dir ]] || no "irregular array: $dir written"

# SIGKILL after the last run, before the exports: the unfinished store stays beside the folder;
# the same command finishes it (--resume), with the runs it had.
dir=$tmp/killed
(task 1 2 1 2 1 "$dir" NCOSIM_TEST_RAISE_AFTER_RUNS=9) 2>/dev/null
[[ -e $dir/.shard_1.partial.sqlite ]] || no "killed task: no unfinished store beside the folder"
task 1 2 1 2 1 "$dir" || no "killed task re-run: $(cat "$tmp/task.log")"
grep -q "3 stored before, 0 simulated now" "$tmp/task.log" ||
  no "killed task re-run did not resume: $(cat "$tmp/task.log")"
# The same command once more on a finished shard: nothing to do, exit 0.
task 1 2 1 2 1 "$dir" || no "finished task re-run: $(cat "$tmp/task.log")"
# SIGKILL while creating its store: an empty store beside the folder, which holds nothing.
: >"$dir/.shard_2.partial.sqlite"
task 2 2 1 2 1 "$dir" || no "task with an empty unfinished store: $(cat "$tmp/task.log")"
merged "$dir" "killed tasks"

# A real SIGKILL at a random moment of a longer task (Slurm's time limit past KillWait, a node
# failure), then the same command.
dir=$tmp/sigkill
flags=(--runs 24 --periods 200000 --no-timing --quiet)  # a task lasts seconds even on an idle machine
"$ncosim" run "$scenario" --out "$tmp/ref" --threads 2 --replace "${flags[@]}" >/dev/null 2>&1 ||
  no "the second reference campaign"
for i in 1 2; do
  env NCOSIM="$ncosim" NCOSIM_TEST_COMMIT_MS=10 SLURM_ARRAY_TASK_ID=$i SLURM_ARRAY_TASK_COUNT=2 \
    SLURM_ARRAY_TASK_MIN=1 SLURM_ARRAY_TASK_MAX=2 SLURM_ARRAY_TASK_STEP=1 \
    bash "$script" "$scenario" "$dir" "${flags[@]}" >/dev/null 2>&1 &
  pid=$!
  sleep "0.$((RANDOM % 5 + 2))"
  kill -KILL "$pid" 2>/dev/null
  wait "$pid" 2>/dev/null
  rc=$?
  [[ $rc -eq 137 ]] || no "task $i was not killed (exit $rc): the campaign is too short"
  task "$i" 2 1 2 1 "$dir" || no "SIGKILLed task $i re-run: $(cat "$tmp/task.log")"
done
merged "$dir" "SIGKILLed tasks"

# No array expansion: an empty one fails under set -u before bash 4.4.
if grep -nE '\$\{[A-Za-z_]+\[[@*]\]' "$script"; then no "the script expands an array"; fi

exit $fail
