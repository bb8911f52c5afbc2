#!/usr/bin/env bash
# scripts/slurm_shards.sh — one shard of an ncosim campaign per Slurm array task.
#
#   sbatch --array=1-N scripts/slurm_shards.sh SCENARIO CAMPAIGN_DIR [ncosim run options...]
#   # after every task has finished:
#   build/sim/ncosim merge CAMPAIGN_DIR/merged CAMPAIGN_DIR/shard_*
#
# Task I of N runs the runs r with r mod N = I-1 into CAMPAIGN_DIR/shard_I (its own run store).
# A task that was preempted or timed out is re-run with the same command: --resume continues it
# (a store of another campaign is refused). Every task must use the same ncosim binary.
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
ncosim=${NCOSIM:-build/sim/ncosim}
i=$SLURM_ARRAY_TASK_ID n=$SLURM_ARRAY_TASK_COUNT
out="$dir/shard_$i"
resume=()
[[ -f "$out/runs.sqlite" ]] && resume=(--resume)
exec "$ncosim" run "$scenario" --out "$out" --shard "$i/$n" --threads "${SLURM_CPUS_PER_TASK:-1}" "${resume[@]}" "$@"
