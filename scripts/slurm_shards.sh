#!/usr/bin/env bash
# scripts/slurm_shards.sh — one shard of an ncosim campaign per Slurm array task.
#
#   sbatch --array=1-N scripts/slurm_shards.sh SCENARIO CAMPAIGN_DIR [ncosim run options...]
#   # after every task has finished:
#   build/sim/ncosim merge CAMPAIGN_DIR/merged CAMPAIGN_DIR/shard_*
#
# Any regular array works: --array=1-16, --array=0-15, --array=0-30:2 (and a throttle, %4). The
# tasks, in index order, are the shards 1..N (N = the array's task count): shard I runs the runs r
# with r mod N = I-1 into CAMPAIGN_DIR/shard_I (its own run store). An irregular list
# (--array=1,5,7) is refused: its tasks cannot be told apart from a regular array's.
#
# A task that was preempted, timed out or killed (SIGKILL included) is re-run with the same
# command: --resume continues it from the store its folder holds, or from the unfinished store a
# killed task leaves beside it (CAMPAIGN_DIR/.shard_I.partial.sqlite); a store of another
# campaign is refused. Every task must use the same ncosim binary. Plain POSIX-style expansions
# only: bash 3.2 and later (an empty array under `set -u` fails before bash 4.4).
#SBATCH --job-name=ncosim
#SBATCH --cpus-per-task=2
#SBATCH --time=01:00:00
#SBATCH --output=%x_%A_%a.log
set -euo pipefail
if (($# < 2)); then
  echo "usage: sbatch --array=1-N $0 SCENARIO CAMPAIGN_DIR [ncosim run options...]" >&2
  exit 2
fi
scenario=$1 dir=$2
shift 2
: "${SLURM_ARRAY_TASK_ID:?run under sbatch --array}" "${SLURM_ARRAY_TASK_COUNT:?run under sbatch --array}"
id=$SLURM_ARRAY_TASK_ID n=$SLURM_ARRAY_TASK_COUNT
min=${SLURM_ARRAY_TASK_MIN:-$id} max=${SLURM_ARRAY_TASK_MAX:-$id} step=${SLURM_ARRAY_TASK_STEP:-1}
for v in "$id" "$n" "$min" "$max" "$step"; do
  if ! [[ $v =~ ^[0-9]+$ ]]; then
    echo "slurm_shards.sh: expected integer SLURM_ARRAY_TASK_* variables, got '$v'" >&2
    exit 2
  fi
done
# Base 10 whatever the leading zeros.
id=$((10#$id)) n=$((10#$n)) min=$((10#$min)) max=$((10#$max)) step=$((10#$step))
if ((n < 1 || step < 1 || min + (n - 1) * step != max || id < min || id > max ||
  (id - min) % step != 0)); then
  echo "slurm_shards.sh: task $id of an array of $n tasks from $min to $max (step $step) is not" \
    "a regular array; use --array=FIRST-LAST or FIRST-LAST:STEP" >&2
  exit 2
fi
i=$(((id - min) / step + 1))
ncosim=${NCOSIM:-build/sim/ncosim}
out="$dir/shard_$i"
# A finished or stopped session left runs.sqlite in the folder; a killed one may have left its
# unfinished store beside it (even an empty one: --resume then starts the shard afresh).
if [[ -f "$out/runs.sqlite" || -e "$dir/.shard_$i.partial.sqlite" ]]; then
  set -- --resume "$@"
fi
exec "$ncosim" run "$scenario" --out "$out" --shard "$i/$n" --threads "${SLURM_CPUS_PER_TASK:-1}" "$@"
