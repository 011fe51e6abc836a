#!/usr/bin/env bash
# A margins survey as a Slurm job array: one shard per array task, then one merge.
# NOT RUN in this project's CI (there is no Slurm there); the commands it runs are the ones
# cli/tests/cli/shard_cli.rs tests (N shards merged = the unsharded run, byte for byte).
#
#   sbatch --array=0-15 deploy/slurm-margins.sh          # 16 shards, indices 0..15
#   sbatch --dependency=afterok:<JOBID> --wrap 'deploy/slurm-margins.sh merge'
#
# Needs the `tilting` binary on every node (cargo build --release -p tilting; $TILTING below)
# and a shared directory for the shard files ($OUT). Each shard prints its JSON only at its
# end; it is written to a temporary name and renamed, so a task that dies leaves no file that
# looks complete, and `tilting plan merge` refuses a missing or torn shard (exit code 2,
# nothing printed as if whole). Seeds derive from each point's coordinates and --seed, never
# from the shard or the order of execution: re-running a failed index gives the same bytes.
#SBATCH --job-name=tilting-margins
#SBATCH --cpus-per-task=2
#SBATCH --time=02:00:00
#SBATCH --output=margins-%A_%a.log
set -euo pipefail

TILTING=${TILTING:-tilting}
OUT=${OUT:-$PWD/margins-shards}
# The survey: every task must pass the same flags (merge refuses shards of different grids).
FLAGS=(plan margins --tilts 200 --seed 1
       --delays 0,0.002,0.004,0.006,0.008,0.010,0.015,0.020
       --losses 0,0.05,0.1,0.2,0.3,0.5)

if [[ "${1:-}" == merge ]]; then
    "$TILTING" plan merge "$OUT"/shard-*.json > "$OUT/margins.json.tmp"
    mv "$OUT/margins.json.tmp" "$OUT/margins.json"
    echo "merged: $OUT/margins.json"
    exit 0
fi

: "${SLURM_ARRAY_TASK_ID:?run with sbatch --array=0-(N-1)}"
N=${SLURM_ARRAY_TASK_COUNT:?}
I=$SLURM_ARRAY_TASK_ID
mkdir -p "$OUT"
# Rayon uses the task's cores.
export RAYON_NUM_THREADS=${SLURM_CPUS_PER_TASK:-2}
"$TILTING" "${FLAGS[@]}" --shard "$I/$N" > "$OUT/shard-$I.json.tmp"
mv "$OUT/shard-$I.json.tmp" "$OUT/shard-$I.json"
