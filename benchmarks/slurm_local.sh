#!/usr/bin/env bash
# A throwaway single-node SLURM cluster on this machine, to try (and test) psbench's SLURM
# launchers without a real cluster. Needs root: slurmd starts jobs as their user.
#
#   eval "$(sudo benchmarks/slurm_local.sh start)"     # prints: export SLURM_CONF=...
#   psbench -m hydra/launcher=submitit_slurm mask=Th,xNL
#   psbench +experiment=table2_1 scale=ci launcher=submitit_slurm shards=2
#   sudo benchmarks/slurm_local.sh stop
#
# start   installs what is missing (Debian/Ubuntu: slurmctld slurmd slurm-client munge, via
#         apt-get), writes slurm.conf and a fresh munge key (the key in its own folder
#         /tmp/psbench-munge.*), starts munged (as user munge, on its own socket, so a
#         system munged is left alone), slurmctld and slurmd directly (no
#         systemd needed), waits until the node is idle and prints the export line on
#         stdout (how to use it on stderr). Running it again while the cluster is up only
#         prints the export line again.
# stop    cancels the cluster's jobs, stops exactly the daemons start started (by PID) and
#         removes the cluster folder. Nothing to stop is not an error.
# status  the daemons' PIDs and `sinfo`.
# env     the export line of a running cluster.
#
# The cluster folder is $PSBENCH_SLURM_DIR (default ${TMPDIR:-/tmp}/psbench-slurm); several
# clusters can run side by side in different folders (each picks free ports).
# No cgroups (containers): ProctrackType=proctrack/linuxproc, TaskPlugin=task/none. No
# accounting database: `sacct` reports "accounting storage is disabled" (psbench's shard
# jobs are followed with squeue; submitit, under `-m hydra/launcher=submitit_slurm`, warns
# at each poll); finished jobs are recorded in <folder>/log/jobcomp.txt (`sacct -c`).
# Exit codes: 0 ok, 1 the cluster did not come up (logs are printed), 2 usage or
# environment error (not root, no apt-get, a folder that is not a cluster's).
set -euo pipefail
export PATH="$PATH:/usr/sbin:/sbin"

DIR="${PSBENCH_SLURM_DIR:-${TMPDIR:-/tmp}/psbench-slurm}"
MARK="$DIR/.psbench-slurm-local"
PIDS="$DIR/pids"
WAIT_S="${PSBENCH_SLURM_WAIT:-60}"

die() { echo "slurm_local: error: $1" >&2; exit "${2:-2}"; }
say() { echo "slurm_local: $*" >&2; }

# munged's folder: outside $DIR, whose parents user munge may not be allowed to enter
munge_dir() { cat "$DIR/munge_dir" 2> /dev/null || true; }

# "name pid" lines of the daemons start started, whose command line still names this
# cluster's folders (so a recycled PID is never touched)
our_pids() {
  [ -f "$PIDS" ] || return 0
  local name pid cmd mdir
  mdir=$(munge_dir)
  while read -r name pid; do
    [ -r "/proc/$pid/cmdline" ] || continue
    cmd=$(tr '\0' ' ' < "/proc/$pid/cmdline")
    if [[ "$cmd" == *"$DIR/"* ]] || { [ -n "$mdir" ] && [[ "$cmd" == *"$mdir/"* ]]; }; then
      echo "$name $pid"
    fi
  done < "$PIDS"
}

all_up() {
  [ -f "$PIDS" ] && [ "$(our_pids | wc -l)" -eq 3 ]
}

# names of the daemons start started that have exited (or are zombies), judged by PID
# alone: while a daemon execs (setsid -> slurmd, setpriv -> munged) its command line reads
# empty for a moment, so matching it, as our_pids does, can miss a live daemon
exited() {
  [ -f "$PIDS" ] || return 0
  local name pid st
  while read -r name pid; do
    st=$(sed -n 's/^State:[[:space:]]*\([A-Z]\).*/\1/p' "/proc/$pid/status" 2> /dev/null || true)
    case "$st" in "" | Z | X) echo "$name" ;; esac
  done < "$PIDS"
}

env_line() { echo "export SLURM_CONF=$DIR/slurm.conf"; }

install_missing() {
  local missing=0 c
  for c in munged slurmctld slurmd sbatch; do
    command -v "$c" > /dev/null || missing=1
  done
  [ "$missing" -eq 0 ] && return 0
  command -v apt-get > /dev/null \
    || die "SLURM is not installed and apt-get is not available: install slurmctld, slurmd, slurm-client and munge"
  say "installing slurmctld slurmd slurm-client munge (apt-get)"
  local pkgs=(slurmctld slurmd slurm-client munge) log
  log=$(mktemp)
  export DEBIAN_FRONTEND=noninteractive
  if ! apt-get install -y -q --no-install-recommends "${pkgs[@]}" > "$log" 2>&1; then
    apt-get update -q > /dev/null 2>&1 || true          # a fresh machine has no package lists
    apt-get install -y -q --no-install-recommends "${pkgs[@]}" > "$log" 2>&1 \
      || { tail -20 "$log" >&2; die "apt-get install failed (log: $log)"; }
  fi
  rm -f "$log"
}

free_port() {   # first port >= $1 nobody listens on (and not in $2)
  local p=$1
  while (exec 3<> "/dev/tcp/127.0.0.1/$p") 2> /dev/null || [ "$p" = "${2:-}" ]; do
    p=$((p + 1))
  done
  echo "$p"
}

write_conf() {
  local node=$1 hw cpus mem ctld_port d_port
  # the node as slurmd sees it (CPUs, sockets, cores, threads, memory)
  hw=$(slurmd -C | head -1 | sed -e 's/^NodeName=[^ ]* //')
  cpus=$(sed -n 's/.*CPUs=\([0-9]*\).*/\1/p' <<< "$hw")
  mem=$(sed -n 's/.*RealMemory=\([0-9]*\).*/\1/p' <<< "$hw")
  ctld_port=$(free_port 6817)
  d_port=$(free_port $((ctld_port + 1)) "$ctld_port")
  cat > "$DIR/slurm.conf" << EOF
# throwaway single-node cluster written by psbench's benchmarks/slurm_local.sh
ClusterName=psbench
SlurmctldHost=$node(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$d_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$(munge_dir)/munge.socket.2
StateSaveLocation=$DIR/state
SlurmdSpoolDir=$DIR/spool
SlurmctldPidFile=$DIR/state/slurmctld.pid
SlurmdPidFile=$DIR/spool/slurmd.pid
SlurmctldLogFile=$DIR/log/slurmctld.log
SlurmdLogFile=$DIR/log/slurmd.log
# no cgroups in containers
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
MpiDefault=none
ReturnToService=2
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
# without a default each job would take the whole node's memory
DefMemPerCPU=$((mem / cpus))
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/filetxt
JobCompLoc=$DIR/log/jobcomp.txt
NodeName=$node NodeAddr=127.0.0.1 $hw State=UNKNOWN
PartitionName=debug Nodes=$node Default=YES MaxTime=INFINITE State=UP
EOF
}

start_daemon() {   # name, command...: started in its own session, PID recorded
  local name=$1 pid
  shift
  setsid "$@" < /dev/null > "$DIR/log/$name.out" 2>&1 &
  pid=$!
  echo "$name $pid" >> "$PIDS"
  # until the forked shell has exec'd the daemon, its command line is this script's, and
  # our_pids would count it as exited: wait (up to 10 s) for the exec or the exit
  for _ in $(seq 100); do
    [ -r "/proc/$pid/cmdline" ] || break
    [ "$(tr '\0' ' ' < "/proc/$pid/cmdline")" != "$(tr '\0' ' ' < /proc/$$/cmdline)" ] && break
    sleep 0.1
  done
}

show_logs() {
  local f
  for f in "$DIR"/log/*.out "$DIR"/log/*.log; do
    if [ -f "$f" ]; then echo "--- $f" >&2; tail -15 "$f" >&2; fi
  done
  return 0   # an unmatched glob must not end the script (set -e) before it says why
}

stop() {
  if [ ! -e "$DIR" ]; then
    say "no cluster in $DIR (nothing to stop)"
    return 0
  fi
  [ -f "$MARK" ] || die "$DIR exists but is not a cluster folder of this script; not touching it"
  local name pid live n
  if [ -f "$DIR/slurm.conf" ] && all_up; then       # no job steps left behind
    SLURM_CONF="$DIR/slurm.conf" scancel --partition=debug 2> /dev/null || true
    for _ in $(seq 20); do
      n=$(SLURM_CONF="$DIR/slurm.conf" squeue -h 2> /dev/null | wc -l) || n=0
      [ "$n" -eq 0 ] && break
      sleep 0.5
    done
  fi
  live=$(our_pids | tac)                        # slurmd, slurmctld, then munged
  while read -r name pid; do
    [ -n "${pid:-}" ] && kill -TERM "$pid" 2> /dev/null && say "stopped $name (pid $pid)"
  done <<< "$live"
  for _ in $(seq 50); do
    [ -z "$(our_pids)" ] && break
    sleep 0.2
  done
  while read -r name pid; do
    [ -n "${pid:-}" ] && kill -KILL "$pid" 2> /dev/null && say "killed $name (pid $pid)"
  done <<< "$(our_pids)"
  local mdir
  mdir=$(munge_dir)
  case "$mdir" in /tmp/psbench-munge.*) rm -rf "$mdir" ;; esac
  rm -rf "$DIR"
  say "removed $DIR${mdir:+ and $mdir}"
}

start() {
  [ "$(id -u)" -eq 0 ] \
    || die "start needs root (slurmd starts jobs as their user): run it with sudo"
  if [ -e "$DIR" ]; then
    [ -f "$MARK" ] \
      || die "$DIR exists and is not a cluster folder of this script; set PSBENCH_SLURM_DIR"
    if all_up; then
      say "already running in $DIR"
      env_line
      return 0
    fi
    say "cleaning a cluster that is no longer complete in $DIR"
    stop
  fi
  install_missing
  id munge > /dev/null 2>&1 || die "user munge does not exist (is the munge package installed?)"
  local node
  node=$(hostname -s)
  mkdir -p "$DIR"
  chmod 755 "$DIR"
  touch "$MARK"
  mkdir -p "$DIR/state" "$DIR/spool" "$DIR/log"
  # munged insists: key readable by its user only, socket folder and all its parents
  # enterable by everyone (so not inside $DIR, which may be in a private folder)
  local mdir
  mdir=$(mktemp -d /tmp/psbench-munge.XXXXXX)
  echo "$mdir" > "$DIR/munge_dir"
  head -c 1024 /dev/urandom > "$mdir/munge.key"
  chown -R munge:munge "$mdir"
  chmod 755 "$mdir"
  chmod 400 "$mdir/munge.key"
  write_conf "$node"
  : > "$PIDS"
  start_daemon munged setpriv --reuid=munge --regid=munge --init-groups munged --foreground \
    --socket="$mdir/munge.socket.2" --key-file="$mdir/munge.key" \
    --pid-file="$mdir/munged.pid" --seed-file="$mdir/munged.seed" \
    --log-file="$mdir/munged.log"
  for _ in $(seq 50); do
    [ -S "$mdir/munge.socket.2" ] && break
    sleep 0.2
  done
  [ -S "$mdir/munge.socket.2" ] || { show_logs; stop; die "munged did not start" 1; }
  start_daemon slurmctld slurmctld -D -f "$DIR/slurm.conf"
  start_daemon slurmd slurmd -D -f "$DIR/slurm.conf" -N "$node"
  local t0=$SECONDS state="" dead
  while [ $((SECONDS - t0)) -lt "$WAIT_S" ]; do
    dead=$(exited)
    [ -z "$dead" ] || { show_logs; stop; die "exited while starting: $(echo $dead)" 1; }
    state=$(SLURM_CONF="$DIR/slurm.conf" sinfo -h -N -n "$node" -o %T 2> /dev/null || true)
    [ "$state" = "idle" ] && break
    sleep 0.5
  done
  if [ "$state" != "idle" ]; then
    show_logs
    stop
    die "node $node not idle after ${WAIT_S} s (state: ${state:-none})" 1
  fi
  local cpus
  cpus=$(sed -n 's/^NodeName=.* CPUs=\([0-9]*\).*/\1/p' "$DIR/slurm.conf")
  say "cluster up in $DIR: node $node ($cpus CPUs), partition debug;" \
    "PIDs: $(our_pids | tr '\n' ' ')"
  cat >&2 << EOF
slurm_local: use it (the results folder must be one the jobs see; one node: any local path):
  $(env_line)
  psbench -m hydra/launcher=submitit_slurm mask=Th,xNL
  psbench +experiment=table2_1 scale=ci launcher=submitit_slurm shards=2
  squeue; sinfo; cat $DIR/log/jobcomp.txt
slurm_local: stop it with: $0 stop
EOF
  env_line
}

status() {
  if [ ! -f "$MARK" ]; then
    say "no cluster in $DIR"
    return 1
  fi
  our_pids | sed 's/^/slurm_local: running: /' >&2
  all_up || { say "not complete (expected munged, slurmctld and slurmd)"; return 1; }
  SLURM_CONF="$DIR/slurm.conf" sinfo >&2
}

case "${1:-}" in
  start) start ;;
  stop) stop ;;
  status) status ;;
  env) all_up || die "no running cluster in $DIR" 1; env_line ;;
  *)
    echo "usage: $0 start|stop|status|env" >&2
    echo "  cluster folder: \$PSBENCH_SLURM_DIR (default ${TMPDIR:-/tmp}/psbench-slurm)" >&2
    exit 2
    ;;
esac
