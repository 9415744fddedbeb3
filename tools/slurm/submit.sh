#!/usr/bin/env bash
# Submits a split build (spec §16) to Slurm: an array job with one task per subset to build,
# then the merge, which runs once every task succeeded (--dependency=afterok).
#
#   tools/slurm/submit.sh [--wait] [--reuse-from OLD_OUTDIR] PLAN OUTDIR OUTPUT [SBATCH_ARGS...]
#
# After `oocfmt plan --update`, the array holds only the subsets the new plan cannot reuse, and
# the merge takes the others from OLD_OUTDIR. SBATCH_ARGS go to both sbatch calls (a partition,
# --cpus-per-task, --mem, ...). With --wait it returns when the merge ends: 0 when it succeeded,
# 1 when a task or the merge failed. Logs: OUTDIR/subset-I.log, OUTDIR/merge.log.
set -euo pipefail

usage() {
    echo "usage: $0 [--wait] [--reuse-from OLD_OUTDIR] PLAN OUTDIR OUTPUT [SBATCH_ARGS...]" >&2
    exit 2
}

wait=0
reuse_from=""
while [[ $# -gt 0 ]]; do
    case $1 in
    --wait) wait=1; shift ;;
    --reuse-from) [[ $# -ge 2 ]] || usage; reuse_from=$2; shift 2 ;;
    --) shift; break ;;
    -*) usage ;;
    *) break ;;
    esac
done
[[ $# -ge 3 ]] || usage
plan=$1
outdir=$2
output=$3
shift 3
extra=("$@")

here=$(cd "$(dirname "$0")" && pwd)
export OOCFMT_SLURM_DIR=$here
list=$(python3 "$here/plan-info.py" rebuild "$plan")
mkdir -p "$outdir"

merge_args=("$plan" "$outdir" "$output")
[[ -n $reuse_from ]] && merge_args+=("$reuse_from")
dependency=()
if [[ -n $list ]]; then
    array=$(sbatch --parsable --array="$list" --output="$outdir/subset-%a.log" "${extra[@]}" \
        "$here/oocfmt-subset.sbatch" "$plan" "$outdir")
    array=${array%%;*}
    echo "subsets: job $array (array $list)"
    dependency=(--dependency="afterok:$array" --kill-on-invalid-dep=yes)
else
    echo "subsets: none to build"
fi
merge=$(sbatch --parsable "${dependency[@]}" --output="$outdir/merge.log" "${extra[@]}" \
    "$here/oocfmt-merge.sbatch" "${merge_args[@]}")
merge=${merge%%;*}
echo "merge:   job $merge"
[[ $wait -eq 1 ]] || exit 0

# The merge's state, until it ends (a failed task cancels it: --kill-on-invalid-dep).
unknown=0
while :; do
    state=$(scontrol show job "$merge" 2>/dev/null | sed -n 's/.*JobState=\([A-Z_]*\).*/\1/p')
    case $state in
    COMPLETED) echo "merge:   completed"; exit 0 ;;
    PENDING | RUNNING | CONFIGURING | COMPLETING) unknown=0; sleep 1 ;;
    "")
        unknown=$((unknown + 1))
        if [[ $unknown -ge 30 ]]; then
            echo "merge:   job $merge is no longer known to Slurm" >&2
            exit 1
        fi
        sleep 1
        ;;
    *) echo "merge:   $state" >&2; exit 1 ;;
    esac
done
