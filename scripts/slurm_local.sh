#!/usr/bin/env bash
# A single-node SLURM cluster on this machine, for tests (docs/studies.md, "On
# a cluster"): munged, slurmctld and slurmd started directly (no systemd), as
# root, with every file in DIR.
#
#   scripts/slurm_local.sh start DIR   # installs slurm-wlm and munge if missing,
#                                      # writes DIR/slurm.conf, starts the daemons,
#                                      # waits until the node is idle
#   export SLURM_CONF=DIR/slurm.conf   # for sbatch, squeue, sinfo, ...
#   scripts/slurm_local.sh stop DIR    # cancels the jobs, stops the daemons, the
#                                      # job steps and their processes, removes DIR
#
# On failure, start prints the daemons' logs and exits 1 (it stops what it
# started). Waits are bounded (SLURM_LOCAL_TIMEOUT seconds, default 60).
# With SLURM_LOCAL_OWNER=PID, start also leaves a watcher that stops the
# cluster when process PID ends (a test interrupted or killed before its own
# stop), so no daemon outlives its test.
set -euo pipefail

usage() {
  echo "usage: $0 start|stop DIR" >&2
  exit 2
}
[ $# -eq 2 ] || { [ $# -eq 3 ] && [ "$1" = watch ]; } || usage
cmd="$1"
dir="$2"
timeout="${SLURM_LOCAL_TIMEOUT:-60}"
trap '' PIPE

# The processes of the cluster in DIR, one pid a line: the daemons (their
# command line or SLURM_CONF=DIR/slurm.conf in their environment names DIR),
# the job steps (slurmstepd started by this slurmd) and everything below a step
# (the jobs' scripts and programs).
ours() {
  local d="$1" pid exe steps=() p
  for p in /proc/[0-9]*; do
    pid="${p#/proc/}"
    [ "$pid" = "$$" ] && continue
    exe="$(readlink "$p/exe" 2>/dev/null)" || continue
    case "$exe" in
    */slurmctld | */slurmd | */slurmstepd | */munged)
      # slurmctld's helper slurmscriptd and the steps have DIR only in their
      # environment (start exports SLURM_CONF before the daemons).
      if tr '\0' ' ' <"$p/cmdline" 2>/dev/null | grep -qF -- "$d/" ||
        tr '\0' '\n' <"$p/environ" 2>/dev/null | grep -qxF -- "SLURM_CONF=$d/slurm.conf"; then
        echo "$pid"
        case "$exe" in */slurmstepd) steps+=("$pid") ;; esac
      fi
      ;;
    esac
  done
  [ ${#steps[@]} -eq 0 ] && return 0
  # Descendants of the steps, breadth first.
  local -A children=()
  local ppid
  for p in /proc/[0-9]*; do
    pid="${p#/proc/}"
    ppid="$(awk '/^PPid:/ {print $2}' "$p/status" 2>/dev/null)" || continue
    [ -n "$ppid" ] && children[$ppid]+=" $pid"
  done
  local queue=("${steps[@]}") next
  while [ ${#queue[@]} -gt 0 ]; do
    next="${queue[0]}"
    queue=("${queue[@]:1}")
    for p in ${children[$next]:-}; do
      echo "$p"
      queue+=("$p")
    done
  done
}

alive() { # the pids given that still run (not zombies)
  local pid st
  for pid in "$@"; do
    st="$(awk '/^State:/ {print $2}' "/proc/$pid/status" 2>/dev/null)" || continue
    [ -n "$st" ] && [ "$st" != "Z" ] && echo "$pid"
  done
}

stop() {
  local d="$1"
  [ -d "$d" ] || return 0
  d="$(cd "$d" && pwd)"
  # Cancel the jobs while the controller runs (at most 10 s), so that the
  # steps end their jobs themselves.
  if [ -f "$d/slurm.conf" ] && [ -n "$(alive "$(cat "$d/slurmctld.pid" 2>/dev/null || echo 0)")" ]; then
    local jobs
    jobs="$(SLURM_CONF="$d/slurm.conf" timeout 5 squeue -h -o %A 2>/dev/null || true)"
    if [ -n "$jobs" ]; then
      # shellcheck disable=SC2086
      SLURM_CONF="$d/slurm.conf" timeout 5 scancel $jobs >/dev/null 2>&1 || true
      local deadline=$((SECONDS + 10))
      while [ $SECONDS -lt $deadline ]; do
        [ -z "$(SLURM_CONF="$d/slurm.conf" timeout 2 squeue -h -o %A 2>/dev/null || true)" ] && break
        sleep 0.2
      done
    fi
  fi
  # slurmctld, slurmd, then munged: SIGTERM, then SIGKILL after 10 s.
  local gone=()
  for name in slurmctld slurmd munged; do
    local pf="$d/$name.pid"
    [ -f "$pf" ] || continue
    local pid
    pid="$(cat "$pf" 2>/dev/null || true)"
    if [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null; then
      kill -TERM "$pid" 2>/dev/null || true
      for _ in $(seq 100); do
        [ -z "$(alive "$pid")" ] && break
        sleep 0.1
      done
      if [ -n "$(alive "$pid")" ]; then kill -KILL "$pid" 2>/dev/null || true; fi
      gone+=("$pid")
    fi
  done
  # Whatever is left (steps and their jobs, a daemon whose pid file is
  # missing, slurmctld's helper): SIGKILL, until none runs (at most 10 s).
  local left=() all=()
  for _ in $(seq 50); do
    mapfile -t all < <(ours "$d")
    mapfile -t left < <(alive "${all[@]}")
    [ ${#left[@]} -eq 0 ] && break
    gone+=("${left[@]}")
    kill -KILL "${left[@]}" 2>/dev/null || true
    sleep 0.2
  done
  # The processes ended are zombies until init reaps them (pgrep lists
  # them): wait for that too, at most 5 s.
  local pid
  for _ in $(seq 50); do
    local any=""
    for pid in "${gone[@]}"; do [ -e "/proc/$pid" ] && any=1; done
    [ -z "$any" ] && break
    sleep 0.1
  done
  if [ -f "$d/run.dir" ]; then
    local run
    run="$(cat "$d/run.dir")"
    case "$run" in /tmp/slurm-local.??????) rm -rf "$run" ;; esac
  fi
  rm -rf "$d"
  if [ ${#left[@]} -gt 0 ]; then
    echo "slurm_local.sh: processes of $d still run: ${left[*]}" >&2
    return 1
  fi
}

# Run in the background by start when SLURM_LOCAL_OWNER names a process:
# stops the cluster when that process ends (a test killed or interrupted
# before it could stop the cluster itself), or returns once DIR is gone.
watch() {
  local d="$1" owner="$2"
  while [ -d "$d" ] && kill -0 "$owner" 2>/dev/null; do
    sleep 1
  done
  stop "$d"
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

missing_packages() {
  local p
  for p in slurm-wlm munge; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || echo "$p"
  done
}

install_packages() {
  [ -z "$(missing_packages)" ] && return 0
  # Tests start clusters in parallel (ctest -j): on a fresh machine one
  # installs while the others wait for it (a second apt-get at once fails on
  # apt's lock), then find the packages there.
  local lock="${TMPDIR:-/tmp}/ropsim-slurm-install.lock"
  exec 9>"$lock"
  flock 9
  local missing
  mapfile -t missing < <(missing_packages)
  if [ ${#missing[@]} -gt 0 ]; then
    echo "slurm_local.sh: installing ${missing[*]}" >&2
    local sudo=""
    [ "$(id -u)" -ne 0 ] && sudo="sudo"
    export DEBIAN_FRONTEND=noninteractive
    $sudo apt-get update -q >&2
    $sudo apt-get install -y -q --no-install-recommends "${missing[@]}" >&2
  fi
  flock -u 9
  exec 9>&-
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
  mkdir -p "$dir/state" "$dir/munge"
  dir="$(cd "$dir" && pwd)"
  chmod 700 "$dir" "$dir/munge"

  # munged with its own key and socket (clients find it through AuthInfo).
  dd if=/dev/urandom of="$dir/munge/munge.key" bs=1024 count=1 status=none
  chmod 400 "$dir/munge/munge.key"
  # The sockets (munged's, and the job steps' in slurmd's spool folder) go
  # to a short folder: a socket's path is at most 108 bytes, which a deep DIR
  # would exceed (the steps then fail to launch). stop removes it.
  local run
  run="$(mktemp -d /tmp/slurm-local.XXXXXX)"
  chmod 755 "$run"
  echo "$run" >"$dir/run.dir"
  mkdir -p "$run/spool"
  local sock="$run/munge.socket"
  /usr/sbin/munged --force --key-file="$dir/munge/munge.key" --socket="$sock" \
    --pid-file="$dir/munged.pid" --log-file="$dir/munged.log" --seed-file="$dir/munge/munge.seed" ||
    fail "munged did not start"

  local host node ctld_port slurmd_port
  host="$(hostname -s)"
  node="$(slurmd -C | head -n1 | sed 's/^NodeName=[^ ]*//')"
  # The node advertises its memory, so that a job with --mem is scheduled
  # (without RealMemory SLURM assumes 1 MB and refuses every --mem request).
  case "$node" in
  *RealMemory=[1-9]*) ;;
  *) fail "slurmd -C gives no RealMemory: '$node'" ;;
  esac
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
SlurmdSpoolDir=$run/spool
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
  if [ -n "${SLURM_LOCAL_OWNER:-}" ]; then
    # Detached from the caller's session and outputs; stops the cluster when
    # the owner ends without stopping it.
    setsid bash "${BASH_SOURCE[0]}" watch "$dir" "$SLURM_LOCAL_OWNER" </dev/null >/dev/null 2>&1 &
  fi
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
  local mem
  mem="$(sinfo -h -N -o '%m' 2>/dev/null | head -n1 || true)"
  [ "${mem:-0}" -gt 1 ] 2>/dev/null || fail "the node advertises no memory (sinfo %m: '${mem}')"
  echo "$SLURM_CONF"
}

# In one block, read whole before it runs: a watcher runs for as long as its
# test, and must not read a script edited meanwhile.
{
  case "$cmd" in
  start) start ;;
  stop) stop "$dir" ;;
  watch)
    [ -n "${3:-}" ] || usage
    watch "$dir" "$3"
    ;;
  *) usage ;;
  esac
  exit
}
