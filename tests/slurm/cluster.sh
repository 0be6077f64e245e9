#!/usr/bin/env bash
# A real single-node Slurm cluster in a folder, for the --farm slurm tests and
# benchmarks: munged, slurmctld and slurmd, all state, sockets, logs and pid
# files under DIR, no systemd. Run as root (slurmd launches the jobs as their
# users); munged runs as the munge user (it refuses to run as root).
#
#   tests/slurm/cluster.sh start DIR   writes DIR/slurm.conf, starts the daemons,
#                                      waits until the node takes jobs, prints
#                                      "export SLURM_CONF=DIR/slurm.conf"
#   tests/slurm/cluster.sh stop DIR    kills the daemons this script started in DIR
#
# `start` exits non-zero with one line on stderr ("cluster.sh: ...") where the
# daemons cannot start, so a test can skip with that reason; it stops what it
# started before failing. Ports are picked free, so clusters in different
# folders do not meet. Each cluster has its own munge key and socket.
set -u

die() {
  echo "cluster.sh: $*" >&2
  exit 1
}

usage() {
  echo "usage: cluster.sh start|stop DIR" >&2
  exit 2
}

[ $# -eq 2 ] || usage
cmd=$1
dir=$2
case $dir in /*) ;; *) dir="$PWD/$dir" ;; esac

# The pid in pid file $1 if it is still the program named $2 (a stale pid
# file must not kill an unrelated process that reused the pid).
pid_of() {
  local pid
  [ -s "$1" ] || return 1
  pid=$(cat "$1" 2>/dev/null) || return 1
  case $pid in '' | *[!0-9]*) return 1 ;; esac
  [ "$(cat /proc/"$pid"/comm 2>/dev/null)" = "$2" ] || return 1
  echo "$pid"
}

# The jobs still on the cluster in DIR cancelled (slurmstepd and the job's
# processes outlive slurmd otherwise), then SIGTERM to the daemons this
# script started there, all at once; SIGKILL to any still there after 5 s.
stop_all() {
  local pids=() f prog pid jobs
  if pid_of "$dir/run/slurmctld.pid" slurmctld >/dev/null && [ -s "$dir/slurm.conf" ]; then
    jobs=$(SLURM_CONF="$dir/slurm.conf" squeue -h -o %A 2>/dev/null)
    if [ -n "$jobs" ]; then
      # shellcheck disable=SC2086
      SLURM_CONF="$dir/slurm.conf" scancel $jobs 2>/dev/null
      for _ in $(seq 100); do
        [ -z "$(SLURM_CONF="$dir/slurm.conf" squeue -h -o %A 2>/dev/null)" ] && break
        sleep 0.05
      done
    fi
  fi
  for f in run/slurmd.pid:slurmd run/slurmctld.pid:slurmctld munge/munged.pid:munged; do
    prog=${f#*:}
    f="$dir/${f%%:*}"
    if pid=$(pid_of "$f" "$prog"); then
      kill "$pid" 2>/dev/null && pids+=("$pid")
    fi
    rm -f "$f"
  done
  for _ in $(seq 250); do
    for i in "${!pids[@]}"; do
      [ -d /proc/"${pids[$i]}" ] || unset "pids[$i]"
    done
    ((${#pids[@]})) || return 0
    sleep 0.02
  done
  kill -9 "${pids[@]}" 2>/dev/null
  return 0
}

# A free TCP port on 127.0.0.1 (nothing listening on it now).
free_port() {
  local p
  for _ in $(seq 200); do
    p=$((20000 + RANDOM % 20000))
    if ! ss -Htln "sport = :$p" 2>/dev/null | grep -q .; then
      echo "$p"
      return 0
    fi
  done
  return 1
}

if [ "$cmd" = stop ]; then
  [ -d "$dir" ] || exit 0
  stop_all
  exit 0
fi
[ "$cmd" = start ] || usage

[ "$(id -u)" -eq 0 ] || die "must run as root (slurmd starts jobs as their users)"
for prog in munged slurmctld slurmd sbatch squeue scontrol; do
  command -v "$prog" >/dev/null 2>&1 || [ -x /usr/sbin/"$prog" ] ||
    die "$prog not installed (scripts/install-deps.sh installs it)"
done
PATH="$PATH:/usr/sbin"
id munge >/dev/null 2>&1 || die "no munge user (install the munge package)"
command -v ss >/dev/null 2>&1 || die "ss not installed (iproute2)"

if [ -s "$dir/run/slurmctld.pid" ] || [ -s "$dir/munge/munged.pid" ]; then
  stop_all # a cluster left running in DIR by an earlier start
fi
mkdir -p "$dir"/{state,spool,log,run,munge} || die "cannot create $dir"
t0=$(date +%s.%N)

# munged checks that its folder is its own, not writable by others, and
# searchable by all (clients reach its socket there).
chown munge:munge "$dir/munge" && chmod 0755 "$dir/munge" || die "cannot chown $dir/munge to munge"
if [ ! -s "$dir/munge/munge.key" ]; then
  (umask 077 && head -c 128 /dev/urandom >"$dir/munge/munge.key") &&
    chown munge:munge "$dir/munge/munge.key" || die "cannot create the munge key"
fi
sock="$dir/munge/munge.sock"
# A Unix socket's path holds at most 107 bytes.
[ ${#sock} -le 107 ] || die "$sock: path too long for a socket (${#sock} > 107 bytes); use a shorter DIR"
runuser -u munge -- munged --socket="$sock" --key-file="$dir/munge/munge.key" \
  --pid-file="$dir/munge/munged.pid" --seed-file="$dir/munge/munged.seed" \
  --log-file="$dir/munge/munged.log" --num-threads=2 2>"$dir/log/munged.err" ||
  die "munged did not start: $(tail -n 1 "$dir/log/munged.err" | tr -d '\n')"

t_munge=$(date +%s.%N)
ctld_port=$(free_port) && slurmd_port=$(free_port) || die "no free port"
[ "$ctld_port" != "$slurmd_port" ] || slurmd_port=$((slurmd_port + 1))
# RealMemory: the machine's, less 1 GiB, in MiB (slurmd drains a node that
# claims more than it has).
mem=$(awk '/^MemTotal:/ { m = int($2 / 1024) - 1024; if (m < 256) m = int($2 / 2048); print m }' /proc/meminfo)
cpus=${SLURM_TEST_CPUS:-2}

cat >"$dir/slurm.conf" <<EOF
# Written by tests/slurm/cluster.sh: a single-node test cluster.
ClusterName=setlighttest
SlurmctldHost=localhost
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$sock
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/run/slurmctld.pid
SlurmdPidFile=$dir/run/slurmd.pid
SlurmctldLogFile=$dir/log/slurmctld.log
SlurmdLogFile=$dir/log/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SwitchType=switch/none
SchedulerType=sched/backfill
SchedulerParameters=batch_sched_delay=0
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
ReturnToService=2
MinJobAge=300
InactiveLimit=0
KillWait=5
Waittime=0
DefMemPerCPU=512
NodeName=localhost NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=main Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$dir/slurm.conf"

slurmctld -c 2>"$dir/log/slurmctld.err" || {
  stop_all
  die "slurmctld did not start: $(tail -n 1 "$dir/log/slurmctld.err" | tr -d '\n')"
}
slurmd -N localhost 2>"$dir/log/slurmd.err" || {
  stop_all
  die "slurmd did not start: $(tail -n 1 "$dir/log/slurmd.err" | tr -d '\n')"
}

t_daemons=$(date +%s.%N)
# Up when the node is idle (it registered and takes jobs): about 0.1 s.
state=""
for _ in $(seq 300); do
  state=$(sinfo -h -n localhost -o %T 2>/dev/null)
  case $state in idle*) break ;; esac
  sleep 0.02
done
case $state in
  idle*) ;;
  *)
    stop_all
    why=$(grep -h -iE 'error|fatal' "$dir/log/slurmctld.log" "$dir/log/slurmd.log" 2>/dev/null | tail -n 1)
    die "the node did not come up (state '${state:-none}')${why:+: $why}"
    ;;
esac
t1=$(date +%s.%N)
# run/start_seconds: the whole start, then munged, slurmctld + slurmd, the
# node's registration (docs/slurm.md quotes them).
awk -v a="$t0" -v m="$t_munge" -v d="$t_daemons" -v b="$t1" \
  'BEGIN { printf "%.3f munged %.3f daemons %.3f node %.3f\n", b - a, m - a, d - m, b - d }' \
  >"$dir/run/start_seconds"
echo "export SLURM_CONF=$dir/slurm.conf"
