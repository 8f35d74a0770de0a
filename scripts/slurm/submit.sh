#!/bin/bash
# Submit a sharded sweep as a SLURM job array plus a merge job that waits for it.
#   scripts/slurm/submit.sh CONFIG SHARDS OUT_DIR [--set section.key=value ...]
# e.g.  scripts/slurm/submit.sh configs/fig10.toml 16 out/fig10 --set grid.x.num=4096 --set grid.y.num=4096
set -euo pipefail
if [ $# -lt 3 ]; then
    echo "usage: $0 CONFIG SHARDS OUT_DIR [--set section.key=value ...]" >&2
    exit 2
fi
CONFIG=$1 SHARDS=$2 OUT=$3
shift 3
HERE=$(cd "$(dirname "$0")" && pwd)
array_job=$(sbatch --parsable --array="0-$((SHARDS - 1))" \
    --export=ALL,CONFIG="$CONFIG",OUT="$OUT",SET="$*" "$HERE/sweep_array.sbatch")
sbatch --parsable --dependency=afterok:"${array_job%%;*}" \
    --export=ALL,OUT="$OUT",MERGED="$OUT.h5" "$HERE/merge.sbatch"
