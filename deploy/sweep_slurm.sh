#!/bin/bash
# SPDX-License-Identifier: MIT
# Submit a sweep as a Slurm array of TASKS tasks and its collect step, which
# runs when every task has succeeded (docs/explanation/modal.md, "Sweeps as a Slurm
# array"):
#
#   deploy/sweep_slurm.sh SWEEP.json OUTDIR [TASKS]     (TASKS default 16)
#
# The table is then OUTDIR/sweep.csv and OUTDIR/sweep.h5, the same columns
# and values as the daemon's `sweep` job on the same arguments.
set -euo pipefail
SPEC=$(realpath "${1:?usage: sweep_slurm.sh SWEEP.json OUTDIR [TASKS]}")
OUT=$(realpath -m "${2:?usage: sweep_slurm.sh SWEEP.json OUTDIR [TASKS]}")
TASKS=${3:-16}
HERE=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$OUT"
jid=$(sbatch --parsable --array=0-$((TASKS - 1)) "$HERE/sweep_array.slurm" "$SPEC" "$OUT")
cid=$(sbatch --parsable --dependency=afterok:"$jid" "$HERE/sweep_array.slurm" "$SPEC" "$OUT")
echo "array job $jid ($TASKS tasks), collect job $cid: $OUT/sweep.csv"
