#!/usr/bin/env bash
# The split build on a real Slurm: starts a one-node cluster on this machine (munged,
# slurmctld and slurmd, from a config written under a temporary folder), submits a plan's
# subsets as an array job and the merge after it (submit.sh), and checks that the merged
# container is byte for byte the one-process `oocfmt convert --plan` and passes
# `verify --deep`; then an update (`plan --update`) rebuilds only what changed, as a second
# array job whose merge reuses the first build's other subsets. Installs Debian's slurm-wlm
# and munge when they are missing; stops every daemon it started and removes its folder,
# whatever happens.
#
#   tools/slurm/one-node-test.sh          # oocfmt from $OOCFMT, else target/release/oocfmt
set -euo pipefail

root=$(cd "$(dirname "$0")/../.." && pwd)
oocfmt=${OOCFMT:-$root/target/release/oocfmt}
[[ -x $oocfmt ]] || { echo "FAIL: no oocfmt binary at $oocfmt (cargo build --release -p oocfmt-cli)" >&2; exit 1; }
oocfmt=$(cd "$(dirname "$oocfmt")" && pwd)/$(basename "$oocfmt")
export OOCFMT=$oocfmt

if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null || ! command -v munged >/dev/null; then
    echo "== installing slurm-wlm and munge"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends slurm-wlm munge >/dev/null
fi

tmp=$(mktemp -d /tmp/oocfmt-slurm.XXXXXX)
chmod 700 "$tmp"
started=()
cleanup() {
    local rc=$?
    if [[ $rc -ne 0 ]]; then
        for log in "$tmp"/slurmctld.log "$tmp"/slurmd.log "$tmp"/work/parts*/*.log; do
            [[ -f $log ]] && { echo "--- $log"; tail -n 20 "$log"; }
        done
    fi
    scancel --full --quiet --user=root 2>/dev/null || true
    for pidfile in "${started[@]}"; do
        if [[ -f $pidfile ]]; then kill "$(cat "$pidfile")" 2>/dev/null || true; fi
    done
    for _ in $(seq 50); do
        alive=0
        for pidfile in "${started[@]}"; do
            [[ -f $pidfile ]] && kill -0 "$(cat "$pidfile")" 2>/dev/null && alive=1
        done
        [[ $alive -eq 0 ]] && break
        sleep 0.2
    done
    rm -rf "$tmp"
    if [[ $rc -eq 0 ]]; then echo "PASS: slurm one-node test"; else echo "FAIL: slurm one-node test (exit $rc)"; fi
    exit "$rc"
}
trap cleanup EXIT

echo "== munge"
dd if=/dev/urandom of="$tmp/munge.key" bs=1024 count=1 status=none
chmod 400 "$tmp/munge.key"
munged --force --key-file="$tmp/munge.key" --socket="$tmp/munge.socket" \
    --pid-file="$tmp/munged.pid" --log-file="$tmp/munged.log" --seed-file="$tmp/munge.seed"
started+=("$tmp/munged.pid")

echo "== slurm.conf"
host=$(hostname -s)
node=$(slurmd -C | head -n 1 | sed "s/^NodeName=[^ ]*/NodeName=$host NodeAddr=127.0.0.1/")
mkdir -p "$tmp/state" "$tmp/spool"
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
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
MpiDefault=none
ReturnToService=2
JobCompType=jobcomp/none
AccountingStorageType=accounting_storage/none
MailProg=/bin/true
MinJobAge=600
$node State=UNKNOWN
PartitionName=oocfmt Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF=$tmp/slurm.conf

echo "== slurmctld and slurmd"
slurmctld -f "$SLURM_CONF"
started+=("$tmp/slurmctld.pid")
slurmd -f "$SLURM_CONF"
started+=("$tmp/slurmd.pid")
for i in $(seq 60); do
    for pidfile in "$tmp/slurmctld.pid" "$tmp/slurmd.pid"; do
        if ! kill -0 "$(cat "$pidfile" 2>/dev/null || echo 0)" 2>/dev/null; then
            echo "$(basename "$pidfile" .pid) is not running" >&2
            exit 1
        fi
    done
    state=$(timeout 5 sinfo -h -o %t 2>/dev/null | head -n 1 || true)
    [[ $state == idle ]] && break
    [[ $i -eq 60 ]] && { echo "the node did not come up (state '$state')" >&2; exit 1; }
    sleep 1
done
sinfo

mkdir -p "$tmp/work"
cd "$tmp/work"
echo "== a plan of 4 subsets, built as a Slurm array job, then merged"
"$oocfmt" gen mandelbulb --tris 30000 -o m.obj --quiet
"$oocfmt" plan m.obj --subsets 4 --mem-limit 16M -o plan.json --quiet
timeout 300 "$root/tools/slurm/submit.sh" --wait plan.json parts model.oocf
"$oocfmt" convert --plan plan.json -o single.oocf --quiet >/dev/null
cmp model.oocf single.oocf
echo "the merged container is the one-process build, byte for byte"
"$oocfmt" verify --deep model.oocf

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
"$oocfmt" plan p0.obj p1.obj p2.obj p3.obj p4.obj p5.obj --subsets 8 --mem-limit 16M -o old.json --quiet >/dev/null
timeout 300 "$root/tools/slurm/submit.sh" --wait old.json old old.oocf
sed -i 's/^v 8 0 0$/v 8 0 0.3/' p4.obj
"$oocfmt" plan --update old.json -o new.json
rebuild=$(python3 "$root/tools/slurm/plan-info.py" rebuild new.json)
[[ -n $rebuild && $rebuild != 0-7 ]] || { echo "the update should rebuild some subsets, not '$rebuild'" >&2; exit 1; }
timeout 300 "$root/tools/slurm/submit.sh" --wait --reuse-from old new.json new new.oocf
"$oocfmt" convert --plan new.json -o full.oocf --quiet >/dev/null
cmp new.oocf full.oocf
echo "the update (array $rebuild) is the full rebuild, byte for byte"
