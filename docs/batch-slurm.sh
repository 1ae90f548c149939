#!/bin/bash
# dcv batch over a Slurm job array: array task K of N compresses the items of shard K/N of the archive
# (dcv batch --shard K/N: after sorting, the items whose index modulo N is K-1), so N tasks cover every
# item exactly once. The tasks share OUTPUT_DIR; each writes its own summary, batch-summary-K-of-N.csv.
# A task that was killed, or failed on some items, is resubmitted as is: the valid .dcv files are kept.
#
#   sbatch --array=1-16 docs/batch-slurm.sh /archive /compressed --bpv 0.03125
#   DCV=/opt/dcv/bin/dcv sbatch --array=1-16 docs/batch-slurm.sh /archive /compressed --bpv 0.03125
#
# N is the size of the array (SLURM_ARRAY_TASK_COUNT): give a whole range without a step (1-16, 0-15).
# To redo one task K alone, keep its N: DCV_SHARD=5/16 sbatch docs/batch-slurm.sh /archive /compressed ...
#
#SBATCH --job-name=dcv-batch
#SBATCH --cpus-per-task=2
#SBATCH --output=dcv-batch-%A_%a.log
set -euo pipefail

if [ $# -lt 2 ]; then
  echo "usage: sbatch --array=1-N $0 INPUT_TREE OUTPUT_DIR (--bpv R | --psnr DB | --points N) [dcv batch options]" >&2
  exit 1
fi
if [ -n "${DCV_SHARD:-}" ]; then
  shard=$DCV_SHARD
else
  : "${SLURM_ARRAY_TASK_ID:?submit as a job array (sbatch --array=1-N), or set DCV_SHARD=K/N}"
  # Task ids need not start at 1 (--array=0-15): K counts from the first one.
  shard=$((SLURM_ARRAY_TASK_ID - ${SLURM_ARRAY_TASK_MIN:-1} + 1))/${SLURM_ARRAY_TASK_COUNT:?Slurm 18.08 or later}
fi
# One item per allocated core at a time; each item's encoder is single-threaded.
exec "${DCV:-dcv}" batch "$@" --shard "$shard" --jobs "${SLURM_CPUS_PER_TASK:-1}"
