#!/usr/bin/env bash
# Submits a split build (spec §16) to Slurm: an array job with one task per subset to build,
# then the merge, which runs once every task succeeded (--dependency=afterok).
#
#   tools/slurm/submit.sh [--wait] [--logs DIR] [--reuse-from OLD_OUTDIR] PLAN OUTDIR OUTPUT [SBATCH_ARGS...]
#
# M, the number of subsets, is the plan's `subsets`; the array is 0-(M-1). After
# `oocfmt plan --update`, the array holds only the subsets the new plan cannot reuse, and the
# merge takes the others from OLD_OUTDIR. SBATCH_ARGS go to both sbatch calls (a partition,
# --cpus-per-task, --mem, ...). Prints the two job ids. With --wait it returns when the merge
# ends: 0 when it succeeded, 1 when a task or the merge failed (a failed task cancels the
# merge). Logs: DIR/subset-I.log and DIR/merge.log, DIR being OUTDIR unless --logs says.
# Needs python3 (plan-info.py) where it runs; the jobs need the plan, the inputs, OUTDIR and
# the oocfmt binary ($OOCFMT, else oocfmt on the PATH) at the same paths on the compute nodes.
set -euo pipefail

usage() {
    echo "usage: $0 [--wait] [--logs DIR] [--reuse-from OLD_OUTDIR] PLAN OUTDIR OUTPUT [SBATCH_ARGS...]" >&2
    exit 2
}

wait=0
logs=""
reuse_from=""
while [[ $# -gt 0 ]]; do
    case $1 in
    --wait) wait=1; shift ;;
    --logs) [[ $# -ge 2 ]] || usage; logs=$2; shift 2 ;;
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
list=$(python3 "$here/plan-info.py" rebuild "$plan")
logs=${logs:-$outdir}
mkdir -p "$outdir" "$logs"

merge_args=("$plan" "$outdir" "$output")
[[ -n $reuse_from ]] && merge_args+=("$reuse_from")
dependency=()
array=""
if [[ -n $list ]]; then
    array=$(sbatch --parsable --array="$list" --output="$logs/subset-%a.log" "${extra[@]}" \
        "$here/oocfmt-subset.sbatch" "$plan" "$outdir")
    array=${array%%;*}
    echo "subsets: job $array (array $list)"
    dependency=(--dependency="afterok:$array" --kill-on-invalid-dep=yes)
else
    echo "subsets: none to build"
fi
merge=$(sbatch --parsable "${dependency[@]}" --output="$logs/merge.log" "${extra[@]}" \
    "$here/oocfmt-merge.sbatch" "${merge_args[@]}")
merge=${merge%%;*}
echo "merge:   job $merge"
[[ $wait -eq 1 ]] || exit 0

# The state of job $1 (for an array, its tasks' states, one a line); nothing once Slurm has
# forgotten it (MinJobAge after it ended).
job_state() {
    scontrol -o show job "$1" 2>/dev/null | sed -n 's/.*JobState=\([A-Z_]*\).*/\1/p' || true
}

# Which tasks of the array did not complete, and how they ended.
report_tasks() {
    [[ -n $array ]] || return 0
    scontrol -o show job "$array" 2>/dev/null |
        sed -n 's/.*ArrayTaskId=\([^ ]*\) .*JobState=\([A-Z_]*\).*ExitCode=\([^ ]*\).*/\1 \2 \3/p' |
        while read -r task state code; do
            [[ $state == COMPLETED ]] || echo "subsets: task $task $state (exit $code)" >&2
        done
}

# The merge's state, until it ends (a failed task cancels it: --kill-on-invalid-dep).
unknown=0
while :; do
    state=$(job_state "$merge")
    case $state in
    COMPLETED) echo "merge:   completed"; exit 0 ;;
    PENDING)
        unknown=0
        if scontrol -o show job "$merge" 2>/dev/null | grep -q 'Reason=DependencyNeverSatisfied'; then
            # A cluster that keeps such jobs (kill_invalid_depend not honoured): end it here.
            scancel "$merge" 2>/dev/null || true
            echo "merge:   cancelled, a subset task failed" >&2
            report_tasks
            exit 1
        fi
        sleep 2
        ;;
    RUNNING | CONFIGURING | COMPLETING | SUSPENDED | REQUEUED | RESIZING) unknown=0; sleep 2 ;;
    "")
        unknown=$((unknown + 1))
        if [[ $unknown -ge 15 ]]; then
            echo "merge:   job $merge is no longer known to Slurm" >&2
            exit 1
        fi
        sleep 2
        ;;
    *) echo "merge:   $state" >&2; report_tasks; exit 1 ;;
    esac
done
