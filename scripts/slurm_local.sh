#!/usr/bin/env bash
# A single-node SLURM cluster on this machine, for tests (docs/studies.md, "On
# a cluster"): munged, slurmctld and slurmd started directly (no systemd), as
# root, with every file in DIR.
#
#   scripts/slurm_local.sh start DIR   # installs slurm-wlm and munge if missing,
#                                      # writes DIR/slurm.conf, starts the daemons,
#                                      # waits until the node is idle
#   export SLURM_CONF=DIR/slurm.conf   # for sbatch, squeue, sinfo, ...
#   scripts/slurm_local.sh stop DIR    # stops the daemons, removes DIR
#
# On failure, start prints the daemons' logs and exits 1 (it stops what it
# started). Waits are bounded (SLURM_LOCAL_TIMEOUT seconds, default 60).
set -euo pipefail

usage() {
  echo "usage: $0 start|stop DIR" >&2
  exit 2
}
[ $# -eq 2 ] || usage
cmd="$1"
dir="$2"
timeout="${SLURM_LOCAL_TIMEOUT:-60}"
trap '' PIPE

stop() {
  local d="$1"
  [ -d "$d" ] || return 0
  # slurmd, slurmctld, then munged; SIGTERM, then SIGKILL after 10 s.
  for name in slurmd slurmctld munged; do
    local pf="$d/$name.pid"
    [ -f "$pf" ] || continue
    local pid
    pid="$(cat "$pf" 2>/dev/null || true)"
    if [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null; then
      kill -TERM "$pid" 2>/dev/null || true
      for _ in $(seq 100); do
        kill -0 "$pid" 2>/dev/null || break
        sleep 0.1
      done
      kill -0 "$pid" 2>/dev/null && kill -KILL "$pid" 2>/dev/null || true
    fi
  done
  rm -rf "$d"
}

logs() {
  local d="$1"
  for f in munged.log slurmctld.log slurmd.log; do
    echo "===== $d/$f" >&2
    tail -n 40 "$d/$f" >&2 2>/dev/null || echo "(none)" >&2
  done
}

fail() {
  # Stop first (a reader that went away must not leave the daemons running),
  # then print the logs kept aside.
  local kept
  kept="$(logs "$dir" 2>&1)"
  stop "$dir"
  echo "slurm_local.sh: $*" >&2
  echo "$kept" >&2
  exit 1
}

install_packages() {
  local missing=()
  for p in slurm-wlm munge; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  [ ${#missing[@]} -eq 0 ] && return 0
  echo "slurm_local.sh: installing ${missing[*]}" >&2
  local sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  export DEBIAN_FRONTEND=noninteractive
  $sudo apt-get update -q >&2
  $sudo apt-get install -y -q --no-install-recommends "${missing[@]}" >&2
}

free_port() {
  # A TCP port nothing listens on, from a range SLURM does not use by default.
  local p
  for _ in $(seq 200); do
    p=$((20000 + RANDOM % 20000))
    if ! ss -ltnH 2>/dev/null | awk '{print $4}' | grep -q ":$p\$"; then
      echo "$p"
      return 0
    fi
  done
  echo 16817
}

start() {
  [ "$(id -u)" -eq 0 ] || {
    echo "slurm_local.sh: must run as root (SlurmUser=root)" >&2
    exit 1
  }
  install_packages
  rm -rf "$dir"
  mkdir -p "$dir/state" "$dir/spool" "$dir/munge"
  dir="$(cd "$dir" && pwd)"
  chmod 700 "$dir" "$dir/munge"

  # munged with its own key and socket (clients find it through AuthInfo).
  dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 status=none
  chmod 400 "$dir/munge/munge.key"
  local sock="$dir/munge/munge.socket"
  /usr/sbin/munged --force --key-file="$dir/munge/munge.key" --socket="$sock" \
    --pid-file="$dir/munged.pid" --log-file="$dir/munged.log" --seed-file="$dir/munge/munge.seed" ||
    fail "munged did not start"

  local host node ctld_port slurmd_port
  host="$(hostname -s)"
  node="$(slurmd -C | head -n1 | sed 's/^NodeName=[^ ]*//')"
  ctld_port="$(free_port)"
  slurmd_port="$(free_port)"
  [ "$slurmd_port" = "$ctld_port" ] && slurmd_port=$((ctld_port + 1))
  cat >"$dir/slurm.conf" <<EOF
# Written by scripts/slurm_local.sh: a single-node cluster for tests.
ClusterName=ropsim-local
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$sock
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SchedulerType=sched/backfill
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
MpiDefault=none
ReturnToService=2
SchedulerParameters=sched_interval=1
MinJobAge=300
KillWait=5
InactiveLimit=0
SlurmctldTimeout=30
SlurmdTimeout=30
NodeName=$host NodeAddr=127.0.0.1$node State=UNKNOWN
PartitionName=local Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
  export SLURM_CONF="$dir/slurm.conf"
  /usr/sbin/slurmctld -c -f "$SLURM_CONF" || fail "slurmctld did not start"
  /usr/sbin/slurmd -f "$SLURM_CONF" || fail "slurmd did not start"

  local deadline=$((SECONDS + timeout)) state=""
  while [ $SECONDS -lt $deadline ]; do
    state="$(sinfo -h -N -o '%t' 2>/dev/null | head -n1 || true)"
    case "$state" in
    idle) break ;;
    down* | drain* | fail*) scontrol update NodeName="$host" State=RESUME >/dev/null 2>&1 || true ;;
    esac
    sleep 0.5
  done
  [ "$state" = "idle" ] || fail "the node is not idle after ${timeout}s (sinfo: '${state}')"
  echo "$SLURM_CONF"
}

case "$cmd" in
start) start ;;
stop) stop "$dir" ;;
*) usage ;;
esac
