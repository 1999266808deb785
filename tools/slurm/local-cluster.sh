#!/usr/bin/env bash
# A one-node Slurm cluster on this machine, for the farm's tests and for trying
# the farm scripts without a real cluster.
#
#   eval "$(tools/slurm/local-cluster.sh start DIR)"   # prints export SLURM_CONF=...
#   tools/slurm/local-cluster.sh stop DIR
#
# Everything it creates lives in DIR: munge key, socket, pid, log and seed
# files, slurm.conf, the controller's state, the node's spool, logs and pids.
# Nothing under /etc, /run or /var is touched and no systemd unit is used, so
# it runs beside a real Slurm or munge installation without disturbing it.
# Needs root (slurmd runs jobs as their submitting user) and the munge, slurmctld
# and slurmd binaries (Debian: munge, slurm-wlm).
#
# Environment:
#   LOCAL_CLUSTER_START_TIMEOUT  seconds to wait for the node to become idle (60)
#   LOCAL_CLUSTER_STOP_TIMEOUT   seconds to wait for a daemon to exit before SIGKILL (10)
set -euo pipefail

prog="local-cluster.sh"
marker=".voxshadow-local-cluster"

die() { echo "$prog: $*" >&2; exit 1; }
say() { echo "$prog: $*" >&2; }

usage() {
    echo "usage: $prog start DIR | stop DIR" >&2
    exit 2
}

# Absolute path without requiring it to exist (stop must work on a missing DIR).
abspath() {
    case "$1" in
        /*) printf '%s\n' "$1" ;;
        *) printf '%s/%s\n' "$(pwd)" "$1" ;;
    esac
}

# Ports in LISTEN state on any address, from /proc, so no extra tool is needed.
listening_ports() {
    local f
    for f in /proc/net/tcp /proc/net/tcp6; do
        [ -r "$f" ] || continue
        # local_address is HEXADDR:HEXPORT, st 0A is LISTEN.
        awk 'NR > 1 && $4 == "0A" { split($2, a, ":"); print a[2] }' "$f"
    done | while read -r hex; do printf '%d\n' "0x$hex"; done
}

free_port() {
    local used="$1" avoid="$2" p tries=0
    while [ $tries -lt 200 ]; do
        p=$(( 20000 + (RANDOM * 32768 + RANDOM) % 40000 ))
        tries=$((tries + 1))
        [ "$p" = "$avoid" ] && continue
        grep -qx "$p" <<<"$used" && continue
        # A connect probe catches listeners that /proc does not list (another network namespace).
        if (exec 3<>"/dev/tcp/127.0.0.1/$p") 2>/dev/null; then continue; fi
        echo "$p"
        return 0
    done
    return 1
}

# True when PID is alive and its command line mentions DIR, so a recycled pid
# of an unrelated process is never signalled.
ours() {
    local pid="$1" dir="$2"
    [ -n "$pid" ] || return 1
    grep -qzF -- "$dir" "/proc/$pid/cmdline" 2>/dev/null
}

# slurmstepd processes forked by our slurmd carry the tag in their environment
# (it is inherited from slurmd); their command lines do not name DIR.
step_pids() {
    local dir="$1" p
    for p in /proc/[0-9]*; do
        [ "$(cat "$p/comm" 2>/dev/null)" = slurmstepd ] || continue
        if grep -qzxF -- "VOXSHADOW_LOCAL_CLUSTER=$dir" "$p/environ" 2>/dev/null; then
            echo "${p#/proc/}"
        fi
    done
}

descendants() {
    local pid="$1" child
    for child in $(ps -o pid= --ppid "$pid" 2>/dev/null); do
        echo "$child"
        descendants "$child"
    done
}

wait_gone() {
    local timeout="$1"; shift
    local deadline=$((SECONDS + timeout)) pid alive
    while :; do
        alive=""
        for pid in "$@"; do
            kill -0 "$pid" 2>/dev/null && alive="$alive $pid"
        done
        [ -z "$alive" ] && return 0
        [ $SECONDS -ge $deadline ] && { echo "$alive"; return 1; }
        sleep 0.2
    done
}

# Signals the given pids, waits, and SIGKILLs what is left after the timeout.
terminate() {
    local what="$1"; shift
    [ $# -gt 0 ] || return 0
    local left
    kill -TERM "$@" 2>/dev/null || true
    if ! left=$(wait_gone "${LOCAL_CLUSTER_STOP_TIMEOUT:-10}" "$@"); then
        say "$what did not exit after SIGTERM; sending SIGKILL to$left"
        # shellcheck disable=SC2086
        kill -KILL $left 2>/dev/null || true
        # shellcheck disable=SC2086
        wait_gone 5 $left >/dev/null || say "$what still alive:$left"
    fi
}

stop_daemons() {
    local dir="$1" name pid pids=()

    # Cancel what still runs so that slurmstepd ends its jobs' processes itself;
    # killed daemons would otherwise leave them orphaned.
    if [ -f "$dir/slurm.conf" ] && [ -r "$dir/pids" ] && grep -q '^slurmctld ' "$dir/pids"; then
        pid=$(awk '$1 == "slurmctld" { print $2 }' "$dir/pids")
        if ours "$pid" "$dir"; then
            local jobs
            jobs=$(SLURM_CONF="$dir/slurm.conf" timeout 10 squeue -h -o %A 2>/dev/null | sort -u || true)
            if [ -n "$jobs" ]; then
                # shellcheck disable=SC2086
                SLURM_CONF="$dir/slurm.conf" timeout 10 scancel $jobs 2>/dev/null || true
                local deadline=$((SECONDS + 15))
                while [ $SECONDS -lt $deadline ] && [ -n "$(step_pids "$dir")" ]; do sleep 0.2; done
            fi
        fi
    fi

    # Step daemons and their jobs' processes that outlived the cancel.
    local steps=() p
    for p in $(step_pids "$dir"); do
        steps+=("$p")
        # shellcheck disable=SC2207
        steps+=($(descendants "$p"))
    done

    # Both Slurm daemons at once (each takes a second or two to shut down),
    # munged after them since they authenticate until they are gone.
    if [ -r "$dir/pids" ]; then
        local group
        for group in "slurmd slurmctld" "munged"; do
            pids=()
            for name in $group; do
                pid=$(awk -v n="$name" '$1 == n { print $2 }' "$dir/pids")
                ours "$pid" "$dir" && pids+=("$pid")
            done
            [ ${#pids[@]} -gt 0 ] && terminate "$group" "${pids[@]}"
        done
    fi
    pids=()
    if [ ${#steps[@]} -gt 0 ]; then
        # Only those still alive, and never a daemon already handled above.
        for p in "${steps[@]}"; do kill -0 "$p" 2>/dev/null && pids+=("$p"); done
        [ ${#pids[@]} -gt 0 ] && terminate "job processes" "${pids[@]}"
    fi
    return 0
}

log_tails() {
    local dir="$1" f
    for f in "$dir/munge/munged.log" "$dir/log/slurmctld.log" "$dir/log/slurmd.log" \
             "$dir/log/slurmctld.out" "$dir/log/slurmd.out" "$dir/log/munged.out"; do
        [ -s "$f" ] || continue
        echo "---- tail of $f" >&2
        tail -n 15 "$f" >&2
    done
}

fail_start() {
    say "$*"
    log_tails "$dir"
    stop_daemons "$dir"
    say "daemons stopped; $dir kept for inspection (remove it with: $prog stop $dir)"
    exit 1
}

start_daemon() {
    local name="$1"; shift
    # setsid: no controlling terminal, so a ^C in the caller's terminal does not reach them.
    # The tag lets stop find slurmstepd processes, which inherit slurmd's environment.
    VOXSHADOW_LOCAL_CLUSTER="$dir" setsid "$@" </dev/null >>"$dir/log/$name.out" 2>&1 &
    echo "$name $!" >>"$dir/pids"
}

cmd_start() {
    local need
    for need in mungekey munged slurmctld slurmd sinfo; do
        command -v "$need" >/dev/null 2>&1 || PATH="$PATH:/usr/sbin:/sbin" command -v "$need" >/dev/null 2>&1 \
            || die "$need not found (Debian: apt-get install munge slurm-wlm)"
    done
    PATH="$PATH:/usr/sbin:/sbin"
    [ "$(id -u)" = 0 ] || die "must run as root (slurmd starts jobs as their owners)"
    id munge >/dev/null 2>&1 || die "no 'munge' user (it comes with the munge package)"

    if [ -e "$dir" ]; then
        if [ -e "$dir/$marker" ]; then
            die "$dir already holds a local cluster; run '$prog stop $dir' first"
        fi
        [ -z "$(ls -A "$dir")" ] || die "$dir exists and is not empty"
    fi
    mkdir -p "$dir"
    : >"$dir/$marker"
    : >"$dir/pids"
    mkdir -p "$dir/munge" "$dir/state" "$dir/spool" "$dir/log"

    # munged: its socket directory must be owned by the user munged runs as, not
    # writable by others, and executable for all so that clients can reach the
    # socket; every directory above it must be traversable by that user.
    local md="$dir/munge"
    mungekey --create --bits=1024 --keyfile="$md/munge.key" >/dev/null 2>&1 \
        || fail_start "mungekey could not create $md/munge.key"
    chmod 0755 "$dir" "$md"
    # setpriv execs in place (runuser would stay as a parent), so the recorded pid is munged's.
    local munge_as=(setpriv --reuid=munge --regid=munge --init-groups --) force=()
    chown -R munge:munge "$md"
    chmod 0600 "$md/munge.key"
    if ! runuser -u munge -- test -x "$md" 2>/dev/null; then
        # A parent of DIR is closed to other users: fall back to root, which
        # munged refuses unless forced.
        say "the munge user cannot reach $md; running munged as root"
        chown -R root:root "$md"
        munge_as=() force=(--force)
    fi
    start_daemon munged "${munge_as[@]}" munged --foreground "${force[@]}" \
        --socket="$md/munge.socket" --key-file="$md/munge.key" \
        --pid-file="$md/munged.pid" --log-file="$md/munged.log" --seed-file="$md/munged.seed"
    for _ in $(seq 50); do
        [ -S "$md/munge.socket" ] && break
        sleep 0.1
    done
    [ -S "$md/munge.socket" ] || fail_start "munged did not create $md/munge.socket"
    munge -n -S "$md/munge.socket" | unmunge -S "$md/munge.socket" >/dev/null 2>&1 \
        || fail_start "munge credentials do not round-trip through $md/munge.socket"

    # Node hardware as slurmd sees it; the node name is this host's short name.
    local node hw
    node=$(hostname -s)
    hw=$(slurmd -C 2>/dev/null | head -n 1) || true
    [[ "$hw" == NodeName=* ]] || fail_start "slurmd -C printed nothing usable: $hw"
    hw=$(sed -e 's/^NodeName=[^ ]* *//' <<<"$hw")

    local used ctld_port d_port
    used=$(listening_ports | sort -u)
    ctld_port=$(free_port "$used" "") || fail_start "no free port for slurmctld"
    d_port=$(free_port "$used" "$ctld_port") || fail_start "no free port for slurmd"

    cat >"$dir/slurm.conf" <<EOF
# Generated by $prog for a one-node cluster whose whole state is under $dir.
ClusterName=vslocal
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$d_port
AuthType=auth/munge
CredType=cred/munge
# cred_expire is also how long a requeued job waits before it may start again
# (default 120 s). 20 s is short for tests yet longer than the ~18 s over which
# scancel retries a signal it was told came too early, so a retry never hits
# the requeued run.
AuthInfo=socket=$md/munge.socket,cred_expire=20
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/log/slurmctld.pid
SlurmdPidFile=$dir/log/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
# No cgroup setup needed: jobs are tracked by parent pid.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SwitchType=switch/none
MpiDefault=none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
# Short timers keep tests fast; jobs here are seconds long.
KillWait=5
SchedulerParameters=sched_interval=2
MessageTimeout=10
MailProg=/bin/true
JobRequeue=1
ReturnToService=2
MinJobAge=300
NodeName=$node NodeAddr=127.0.0.1 $hw State=UNKNOWN
PartitionName=local Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF

    start_daemon slurmctld slurmctld -D -i -f "$dir/slurm.conf"
    start_daemon slurmd slurmd -D -N "$node" -f "$dir/slurm.conf"

    local timeout="${LOCAL_CLUSTER_START_TIMEOUT:-60}" deadline state="" name pid
    deadline=$((SECONDS + timeout))
    while :; do
        for name in munged slurmctld slurmd; do
            pid=$(awk -v n="$name" '$1 == n { print $2 }' "$dir/pids")
            kill -0 "$pid" 2>/dev/null || fail_start "$name (pid $pid) exited during start"
        done
        state=$(SLURM_CONF="$dir/slurm.conf" sinfo -h -N -n "$node" -o %T 2>/dev/null | head -n 1) || true
        [ "$state" = idle ] && break
        [ $SECONDS -ge $deadline ] && fail_start "node $node not idle after ${timeout}s (state: ${state:-no answer})"
        sleep 0.2
    done
    say "node $node idle; slurmctld on 127.0.0.1:$ctld_port, slurmd on :$d_port"
    printf 'export SLURM_CONF=%q\n' "$dir/slurm.conf"
}

cmd_stop() {
    [ -e "$dir" ] || return 0
    [ -e "$dir/$marker" ] || die "$dir was not made by '$prog start'; not touching it"
    stop_daemons "$dir"
    rm -rf -- "$dir"
}

[ $# -eq 2 ] || usage
[ -n "$2" ] || usage
dir=$(abspath "$2")
dir="${dir%/}"
[ -n "$dir" ] && [ "$dir" != / ] || die "refusing DIR '/'"
# slurm.conf has no quoting for paths.
[[ "$dir" != *[[:space:]]* ]] || die "DIR must not contain white space: '$dir'"
case "$1" in
    start) cmd_start ;;
    stop) cmd_stop ;;
    *) usage ;;
esac
