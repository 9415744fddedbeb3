#!/usr/bin/env bash
# The split build on a real Slurm: starts a one-node cluster on this machine (munged,
# slurmctld and slurmd, from a config written under a temporary folder), submits a plan's
# subsets as an array job and the merge after it (submit.sh), and checks that the merged
# container is byte for byte the one-process `oocfmt convert --plan` and passes
# `verify --deep`; then an update (`plan --update`) rebuilds only what changed, as a second
# array job whose merge reuses the first build's other subsets; then a failing task must
# cancel the merge and make submit.sh --wait fail, and the merge must refuse a folder holding
# a subset file the plan does not have. Installs Debian's slurm-wlm and munge when they are
# missing; stops every daemon it started and removes its folder, whatever happens.
#
#   tools/slurm/one-node-test.sh [PLAN_ARGS...]
#
# oocfmt is $OOCFMT, else target/release/oocfmt. PLAN_ARGS go to the first `oocfmt plan`
# (e.g. --codec zstd --lod both). Runs as root. Everything after the install must finish within
# $OOCFMT_SLURM_TEST_TIMEOUT seconds (default 300). OOCFMT_SLURM_TEST_KEEP=1 keeps the folder.
set -euo pipefail

root=$(cd "$(dirname "$0")/../.." && pwd)
cd "$root"
oocfmt=${OOCFMT:-$root/target/release/oocfmt}
if [[ $oocfmt != */* ]]; then
    oocfmt=$(command -v "$oocfmt" || true)
fi
[[ -n $oocfmt && -x $oocfmt ]] || {
    echo "FAIL: no oocfmt binary at ${OOCFMT:-$root/target/release/oocfmt} (cargo build --release -p oocfmt-cli)" >&2
    exit 1
}
oocfmt=$(cd "$(dirname "$oocfmt")" && pwd)/$(basename "$oocfmt")
export OOCFMT=$oocfmt
export PATH=$PATH:/usr/sbin:/sbin
limit=${OOCFMT_SLURM_TEST_TIMEOUT:-300}

tmp=""
child="" # the command bounded() waits for
policy_added=0
daemons=() # "name pid", in the order they were started
cleanup() {
    local rc=$? entry name pid i p log
    set +e
    trap - EXIT
    if [[ $policy_added -eq 1 ]]; then rm -f /usr/sbin/policy-rc.d; fi
    if [[ -n $child ]]; then # interrupted while waiting: timeout passes the TERM on
        kill "$child" 2>/dev/null
        wait "$child" 2>/dev/null
    fi
    if [[ $rc -ne 0 && -n $tmp ]]; then
        for name in munged slurmctld slurmd; do # a daemon's log, else what it printed
            log=$tmp/$name.log
            [[ -s $log ]] || log=$tmp/$name.out
            [[ -s $log ]] && { echo "--- $log (last lines)"; tail -n 25 "$log"; }
        done
        for log in "$tmp"/work/*/*.log; do
            [[ -s $log ]] && { echo "--- $log (last lines)"; tail -n 25 "$log"; }
        done
    fi
    if [[ ${#daemons[@]} -gt 1 ]]; then # slurmctld runs: cancel what is left
        timeout 15 scancel --quiet --user="$(id -un)" 2>/dev/null
    fi
    # Stop the daemons, the last started first: TERM, then KILL after 10 s.
    for ((i = ${#daemons[@]} - 1; i >= 0; i--)); do
        read -r name pid <<<"${daemons[i]}"
        kill "$pid" 2>/dev/null
        for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.2; done
        if kill -0 "$pid" 2>/dev/null; then
            echo "$name ($pid) ignored TERM: killing it" >&2
            kill -KILL "$pid" 2>/dev/null
        fi
        wait "$pid" 2>/dev/null
    done
    # What slurmd started and outlived it (slurmstepd, job scripts) carries our SLURM_CONF.
    if [[ -n $tmp ]]; then
        for p in /proc/[0-9]*; do
            pid=${p#/proc/}
            [[ $pid -ne $$ ]] || continue
            if grep -qzx "SLURM_CONF=$tmp/slurm.conf" "$p/environ" 2>/dev/null; then
                echo "left over: $pid $(tr '\0' ' ' <"$p/cmdline" 2>/dev/null): killing it" >&2
                kill -KILL "$pid" 2>/dev/null
            fi
        done
        if [[ ${OOCFMT_SLURM_TEST_KEEP:-0} == 1 ]]; then echo "kept $tmp"; else rm -rf "$tmp"; fi
    fi
    if [[ $rc -eq 0 ]]; then echo "PASS: slurm one-node test"; else echo "FAIL: slurm one-node test (exit $rc)"; fi
    exit "$rc"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

fail() {
    echo "FAIL: $*" >&2
    exit 1
}

if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null || ! command -v munged >/dev/null ||
    ! command -v sbatch >/dev/null; then
    echo "== installing slurm-wlm and munge"
    start=$SECONDS
    if [[ ! -e /usr/sbin/policy-rc.d ]]; then # no daemon of the packages' own starts
        printf '#!/bin/sh\nexit 101\n' >/usr/sbin/policy-rc.d
        chmod 755 /usr/sbin/policy-rc.d
        policy_added=1
    fi
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends slurm-wlm munge >/dev/null
    if [[ $policy_added -eq 1 ]]; then rm -f /usr/sbin/policy-rc.d; policy_added=0; fi
    echo "installed in $((SECONDS - start)) s"
fi
version=$(slurmd -V | awk '{print $2}')
echo "== slurm $version, oocfmt $oocfmt"

# From here on, every wait is bounded by the deadline.
deadline=$((SECONDS + limit))
bounded() {
    local left=$((deadline - SECONDS))
    if [[ $left -le 0 ]]; then
        echo "out of time ($limit s)" >&2
        return 124
    fi
    # In the background, so that a TERM or INT to this script ends the wait at once.
    local rc=0
    timeout "$left" "$@" &
    child=$!
    wait "$child" || rc=$?
    child=""
    [[ $rc -ne 124 ]] || echo "timed out after $limit s in total: $*" >&2
    return "$rc"
}
alive() { # name pid
    kill -0 "$2" 2>/dev/null || fail "$1 exited (see its log)"
}

tmp=$(mktemp -d /tmp/oocfmt-slurm.XXXXXX)
chmod 755 "$tmp" # munged wants its socket reachable; the key itself is 0400

echo "== munged"
dd if=/dev/urandom of="$tmp/munge.key" bs=1024 count=1 status=none
chmod 400 "$tmp/munge.key"
munged --foreground --force --key-file="$tmp/munge.key" --socket="$tmp/munge.socket" \
    --pid-file="$tmp/munged.pid" --log-file="$tmp/munged.log" --seed-file="$tmp/munge.seed" \
    >"$tmp/munged.out" 2>&1 &
pid=$!
daemons+=("munged $pid")
until munge -n -S "$tmp/munge.socket" 2>/dev/null | unmunge -S "$tmp/munge.socket" >/dev/null 2>&1; do
    alive munged "$pid"
    [[ $SECONDS -lt $deadline ]] || fail "munged did not answer"
    sleep 0.2
done

echo "== slurm.conf"
host=$(hostname -s)
node=$(slurmd -C 2>/dev/null | grep -m 1 '^NodeName=' || true)
if [[ -n $node ]]; then
    node="NodeName=$host NodeAddr=127.0.0.1 ${node#NodeName=* }"
else
    node="NodeName=$host NodeAddr=127.0.0.1 CPUs=$(nproc) RealMemory=$(free -m | awk '/^Mem:/ {print int($2 * 0.95)}')"
fi
mkdir -p "$tmp/state" "$tmp/spool"
write_conf() { # SelectType
    local select=$1 params=""
    [[ $select == select/cons_tres ]] && params="SelectTypeParameters=CR_CPU"
    cat >"$tmp/slurm.conf" <<CONF
ClusterName=oocfmt-test
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=16817
SlurmdPort=16818
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$tmp/munge.socket
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/slurmctld.pid
SlurmdPidFile=$tmp/slurmd.pid
SlurmctldLogFile=$tmp/slurmctld.log
SlurmdLogFile=$tmp/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=$select
$params
SchedulerType=sched/backfill
MpiDefault=none
ReturnToService=2
JobCompType=jobcomp/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MailProg=/bin/true
MinJobAge=600
$node State=UNKNOWN
PartitionName=oocfmt Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
}
# Slurm 23.11 and later set up cgroups whatever the proctrack and task plugins; say not to.
if [[ $(printf '%s\n' 23.11 "$version" | sort -V | head -n 1) == 23.11 ]]; then
    echo "CgroupPlugin=disabled" >"$tmp/cgroup.conf"
fi
export SLURM_CONF=$tmp/slurm.conf

echo "== slurmctld"
for select in select/cons_tres select/linear; do
    write_conf "$select"
    slurmctld -D -f "$SLURM_CONF" >"$tmp/slurmctld.out" 2>&1 &
    pid=$!
    up=0
    while kill -0 "$pid" 2>/dev/null && [[ $SECONDS -lt $deadline ]]; do
        if timeout 5 scontrol ping 2>/dev/null | grep -q 'is UP'; then up=1; break; fi
        sleep 0.5
    done
    if [[ $up -eq 1 ]]; then
        daemons+=("slurmctld $pid")
        echo "slurmctld runs with $select"
        break
    fi
    kill "$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
    echo "slurmctld did not start with $select:" >&2
    tail -n 5 "$tmp/slurmctld.out" "$tmp/slurmctld.log" >&2 2>/dev/null || true
    [[ $select == select/linear ]] && fail "slurmctld did not start"
done

echo "== slurmd"
slurmd -D -f "$SLURM_CONF" >"$tmp/slurmd.out" 2>&1 &
daemons+=("slurmd $!")
state=""
while [[ $state != idle ]]; do
    for entry in "${daemons[@]}"; do
        read -r name pid <<<"$entry"
        alive "$name" "$pid"
    done
    [[ $SECONDS -lt $deadline ]] || fail "the node did not come up (state '$state')"
    sleep 0.5
    state=$(timeout 5 sinfo -h -o %t 2>/dev/null | head -n 1 || true)
done
sinfo

mkdir -p "$tmp/work"
cd "$tmp/work"
submit=$root/tools/slurm/submit.sh

echo "== a plan of 4 subsets, built as a Slurm array job, then merged"
bounded "$oocfmt" gen mandelbulb --tris 30000 -o m.obj --quiet
bounded "$oocfmt" plan m.obj --subsets 4 --mem-limit 16M -o plan.json --quiet "$@"
bounded "$submit" --wait plan.json parts model.oocf || fail "submit.sh --wait plan.json parts model.oocf"
bounded "$oocfmt" convert --plan plan.json -o single.oocf --quiet >/dev/null
cmp model.oocf single.oocf || fail "the merged container differs from convert --plan"
echo "PASS: the merged container is the one-process build, byte for byte"
bounded "$oocfmt" verify --deep model.oocf || fail "verify --deep model.oocf"
echo "PASS: verify --deep"

echo "== an assembly of 6 parts in 8 subsets; one part changes; the update rebuilds what it reaches"
for f in 0 1 2 3 4 5; do
    awk -v f="$f" -v bump=0 'BEGIN {
        for (k = 0; k < 400; k++) {
            x = f * 2 + (k % 40) * 0.04; y = int(k / 40) * 0.1; z = ((k + (f == 4 ? bump : 0)) % 5) * 0.1
            printf "v %g %g %g\nv %g %g 0.2\nv %g %g 0.1\n", x, y, z, x + 0.05, y, x, y + 0.08
        }
        for (k = 0; k < 400; k++) printf "f %d %d %d\n", 3 * k + 1, 3 * k + 2, 3 * k + 3
    }' >"p$f.obj"
done
bounded "$oocfmt" plan p0.obj p1.obj p2.obj p3.obj p4.obj p5.obj --subsets 8 --mem-limit 16M -o old.json --quiet >/dev/null
bounded "$submit" --wait old.json old old.oocf || fail "submit.sh --wait old.json old old.oocf"
sed -i 's/^v 8 0 0$/v 8 0 0.3/' p4.obj
bounded "$oocfmt" plan --update old.json -o new.json
rebuild=$(python3 "$root/tools/slurm/plan-info.py" rebuild new.json)
[[ -n $rebuild && $rebuild != 0-7 ]] || fail "the update should rebuild some subsets, not '$rebuild'"
bounded "$submit" --wait --reuse-from old new.json new new.oocf || fail "submit.sh --wait --reuse-from old new.json new new.oocf"
bounded "$oocfmt" convert --plan new.json -o full.oocf --quiet >/dev/null
cmp new.oocf full.oocf || fail "the update's merge differs from the full rebuild"
echo "PASS: the update (array $rebuild) is the full rebuild, byte for byte"

echo "== a failing task: the merge must not run, submit.sh --wait must fail"
cat >"$tmp/failing-oocfmt" <<WRAP
#!/bin/sh
# oocfmt, except that subset 2 fails
prev=
for a in "\$@"; do
    if [ "\$prev" = --subset ] && [ "\$a" = 2 ]; then echo "subset 2 fails, as the test asks" >&2; exit 1; fi
    prev=\$a
done
exec "$oocfmt" "\$@"
WRAP
chmod 755 "$tmp/failing-oocfmt"
rc=0
OOCFMT=$tmp/failing-oocfmt bounded "$submit" --wait plan.json failing failing.oocf || rc=$?
[[ $rc -ne 0 ]] || fail "submit.sh --wait succeeded although subset 2 failed"
[[ $rc -ne 124 ]] || fail "submit.sh --wait did not return"
[[ ! -e failing.oocf && ! -e failing/part-2.oocfp ]] || fail "a failed build left failing.oocf or part-2"
[[ -f failing/part-0.oocfp && -f failing/part-1.oocfp && -f failing/part-3.oocfp ]] ||
    fail "the other subsets of the failing build are missing"
echo "PASS: a failed task cancels the merge (submit.sh --wait exit $rc)"

echo "== a subset file the plan does not have: the merge must refuse the folder"
mkdir stray
cp parts/part-*.oocfp stray/
cp parts/part-0.oocfp stray/part-4.oocfp
rc=0
bounded sbatch --wait --quiet --output=stray/merge.log "$root/tools/slurm/oocfmt-merge.sbatch" \
    plan.json stray stray.oocf || rc=$?
[[ $rc -ne 0 && $rc -ne 124 && ! -e stray.oocf ]] || fail "the merge took a folder with part-4 for a 4-subset plan"
grep -q 'part-4.oocfp is not one of' stray/merge.log || fail "the merge failed, but not on part-4: $(cat stray/merge.log)"
echo "PASS: the merge refuses a stray subset file"
