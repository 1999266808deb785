#!/usr/bin/env bash
# Sharded bake on a one-node Slurm cluster, with one shard cancelled mid-run and
# requeued: the merged image and sidecar must equal a reference bake's.
#
#   tests/farm/slurm_farm_check.sh VOXSHADOW SCENE REFERENCE_EXR WORKDIR
#
# REFERENCE_EXR and REFERENCE_EXR.json come from an ordinary bake of SCENE.
# Needs root and the munge and slurm-wlm packages; exits 77 (skipped) without them.
# Everything it starts lives under WORKDIR/cluster and is stopped on exit.
set -uo pipefail

prog=slurm_farm_check
say() { echo "$prog: $*"; }
fail() { echo "$prog: FAIL: $*" >&2; exit 1; }
skip() { echo "$prog: skipped: $*"; exit 77; }

[ $# -eq 4 ] || { echo "usage: $0 VOXSHADOW SCENE REFERENCE_EXR WORKDIR" >&2; exit 2; }
root="$(cd "$(dirname "$(readlink -f "${BASH_SOURCE[0]}")")/../.." && pwd)"
slurm_tools="$root/tools/slurm"
voxshadow=$(readlink -f -- "$1")
scene=$(readlink -f -- "$2")
reference=$(readlink -f -- "$3")
mkdir -p -- "$4" || fail "cannot create $4"
work=$(cd "$4" && pwd)

[ -x "$voxshadow" ] || fail "$voxshadow is not executable"
[ -f "$scene" ] || fail "no scene $scene"
[ -f "$reference" ] && [ -f "$reference.json" ] || fail "need $reference and $reference.json"
[ "$(id -u)" = 0 ] || skip "needs root to run slurmd"
for tool in munged mungekey slurmctld slurmd sbatch squeue scontrol scancel; do
    command -v "$tool" >/dev/null 2>&1 || PATH="$PATH:/usr/sbin:/sbin" command -v "$tool" >/dev/null 2>&1 \
        || skip "$tool not installed (Debian: munge slurm-wlm)"
done

start_time=$SECONDS
cluster="$work/cluster"
out="$work/farm.exr"
parts="$out.parts"
farm_pid=""
scancel_pid=""

cleanup() {
    local rc=$?
    [ -n "$scancel_pid" ] && kill "$scancel_pid" 2>/dev/null
    if [ -n "$farm_pid" ] && kill -0 "$farm_pid" 2>/dev/null; then
        kill "$farm_pid" 2>/dev/null
        wait "$farm_pid" 2>/dev/null
    fi
    "$slurm_tools/local-cluster.sh" stop "$cluster" || rc=1
    say "cluster stopped; $(( SECONDS - start_time )) s in all"
    exit $rc
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# A cluster left by an interrupted run would hold the directory.
"$slurm_tools/local-cluster.sh" stop "$cluster" || fail "cannot remove the old $cluster"
conf=$("$slurm_tools/local-cluster.sh" start "$cluster") || fail "local cluster did not start"
eval "$conf"
say "cluster up in $(( SECONDS - start_time )) s ($SLURM_CONF)"

rm -rf -- "$out" "$out.json" "$parts"
"$slurm_tools/voxshadow-farm" "$scene" -o "$out" --shards 4 --voxshadow "$voxshadow" >"$work/farm.log" 2>&1 &
farm_pid=$!
say "voxshadow-farm started (pid $farm_pid, output in $work/farm.log)"

task_field() { scontrol -o show job "$1" 2>/dev/null | sed -n "s/.*[[:space:]]$2=\([^[:space:]]*\).*/\1/p" | head -n 1; }

# Cancel one running shard with SIGTERM to its whole batch step; the batch
# script then requeues itself. A shard can finish before the signal lands
# (the real bakes take seconds), so another running one is tried then.
victim=""
tried=" "
deadline=$((SECONDS + 120))
while [ -z "$victim" ]; do
    [ $SECONDS -lt $deadline ] || fail "no shard could be cancelled mid-run within 120 s"
    kill -0 "$farm_pid" 2>/dev/null || fail "voxshadow-farm ended before a shard could be cancelled: $(tail -n 5 "$work/farm.log")"
    candidate=""
    for task in $(squeue -h -r -t RUNNING --name=voxshadow-bake -o %i 2>/dev/null); do
        [[ "$tried" == *" $task "* ]] && continue
        # Only once the bake itself has been started by the batch script.
        if grep -qF -- "$voxshadow bake" "$parts/$task.log" 2>/dev/null; then
            candidate=$task
            break
        fi
    done
    if [ -z "$candidate" ]; then
        sleep 0.1
        continue
    fi
    tried+="$candidate "
    say "cancelling running shard $candidate: scancel --signal=TERM --full $candidate"
    # In the background: scancel may wait and retry for seconds after the
    # signal has already been delivered.
    scancel --signal=TERM --full "$candidate" >"$work/scancel.log" 2>&1 &
    scancel_pid=$!
    wait_until=$((SECONDS + 30))
    while [ $SECONDS -lt $wait_until ]; do
        restarts=$(task_field "$candidate" Restarts)
        state=$(task_field "$candidate" JobState)
        if [ "${restarts:-0}" -ge 1 ]; then
            victim=$candidate
            break
        fi
        case "$state" in
            COMPLETED)
                say "shard $candidate completed before the signal reached it; trying another"
                break ;;
            FAILED | CANCELLED | TIMEOUT | NODE_FAIL | OUT_OF_MEMORY)
                fail "shard $candidate ended $state after SIGTERM instead of being requeued; see $parts/$candidate.log" ;;
        esac
        sleep 0.1
    done
    kill "$scancel_pid" 2>/dev/null
    wait "$scancel_pid" 2>/dev/null
    scancel_pid=""
    [ -n "$victim" ] || [ "$state" = COMPLETED ] \
        || fail "shard $candidate was not requeued within 30 s of SIGTERM (state $state, restarts ${restarts:-?})"
done
say "shard $victim requeued (restarts $(task_field "$victim" Restarts), state $(task_field "$victim" JobState))"

# voxshadow-farm waits for the merge itself; the bound only catches a hang.
deadline=$((SECONDS + 200))
while kill -0 "$farm_pid" 2>/dev/null; do
    [ $SECONDS -lt $deadline ] || fail "voxshadow-farm still running after 200 s more: $(tail -n 5 "$work/farm.log")"
    sleep 0.5
done
wait "$farm_pid"
farm_rc=$?
farm_pid=""
sed 's/^/  | /' "$work/farm.log"
[ $farm_rc = 0 ] || fail "voxshadow-farm exited with $farm_rc"

restarts=$(task_field "$victim" Restarts)
state=$(task_field "$victim" JobState)
runs=$(grep -c 'bake-shards: shard .* on ' "$parts/$victim.log")
[ "$state" = COMPLETED ] || fail "shard $victim ended $state"
[ "${restarts:-0}" -ge 1 ] && [ "$runs" -ge 2 ] \
    || fail "shard $victim was not run again (restarts ${restarts:-?}, runs in its log $runs)"
say "shard $victim: $runs runs, restarts $restarts, final state $state"

# The merge must have waited for the requeued shard's second run.
merge_job=$(sed -n 's/.*merge job \([0-9][0-9]*\).*/\1/p' "$work/farm.log" | head -n 1)
merge_start=$(task_field "$merge_job" StartTime)
victim_end=$(task_field "$victim" EndTime)
[ -n "$merge_start" ] && [ -n "$victim_end" ] || fail "no start/end times for the merge job $merge_job and shard $victim"
[[ ! "$merge_start" < "$victim_end" ]] \
    || fail "merge job $merge_job started at $merge_start, before shard $victim ended at $victim_end"
say "merge job $merge_job started $merge_start, after shard $victim ended $victim_end"

cmp -- "$out" "$reference" || fail "$out differs from $reference"
cmp -- "$out.json" "$reference.json" || fail "$out.json differs from $reference.json"
say "$out and its sidecar are identical to the reference"
say "PASS"
