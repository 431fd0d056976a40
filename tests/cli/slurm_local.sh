#!/bin/bash
# A throw-away single-node Slurm for tests/cli/test_sweep_slurm.cpp, entirely inside DIR: its own munge
# key and socket, slurm.conf (proctrack/linuxproc, task/none, one node, one partition "test"), state and
# logs; daemons started directly (no systemd) and stopped by their pid files.
#   slurm_local.sh start DIR   -> exit 0 when the node is idle (prints SLURM_CONF=DIR/slurm.conf),
#                                 exit 77 with the reason on stderr when Slurm cannot start here
#   slurm_local.sh stop DIR
set -u
cmd="$1"
dir="$(cd "$2" && pwd)"
conf="$dir/slurm.conf"
if [ "$cmd" = stop ]; then
  for p in slurmd slurmctld munged; do
    [ -f "$dir/$p.pid" ] && kill "$(cat "$dir/$p.pid")" 2>/dev/null
  done
  for _ in $(seq 50); do
    alive=0
    for p in slurmd slurmctld munged; do
      [ -f "$dir/$p.pid" ] && kill -0 "$(cat "$dir/$p.pid")" 2>/dev/null && alive=1
    done
    [ $alive = 0 ] && exit 0
    sleep 0.1
  done
  exit 0
fi
skip() { echo "slurm cannot start here: $*" >&2; exit 77; }
[ "$(id -u)" = 0 ] || skip "not root (the test starts munged, slurmctld and slurmd itself)"
for b in munged munge slurmctld slurmd sbatch squeue sinfo scontrol; do
  command -v "$b" >/dev/null || skip "$b not installed (Debian: apt-get install slurm-wlm munge; scripts/install-deps.sh)"
done
host="$(hostname -s)"
# Ports from the folder's name, so concurrent test runs do not collide.
base=$(( 20000 + $(printf '%s' "$dir" | cksum | cut -d' ' -f1) % 20000 ))
mkdir -p "$dir/state" "$dir/spool"
chmod 755 "$dir"
head -c 1024 /dev/urandom > "$dir/munge.key"
chmod 0400 "$dir/munge.key"
munged -f --socket="$dir/munge.sock" --key-file="$dir/munge.key" --log-file="$dir/munged.log" \
  --pid-file="$dir/munged.pid" --seed-file="$dir/munged.seed" || skip "munged failed: $(tail -2 "$dir/munged.log")"
cat > "$conf" <<CONF
ClusterName=roetest
SlurmctldHost=$host
AuthType=auth/munge
AuthInfo=socket=$dir/munge.sock
CredType=cred/munge
SlurmUser=root
SlurmdUser=root
SlurmctldPort=$base
SlurmdPort=$((base + 1))
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
NodeName=$host NodeAddr=127.0.0.1 CPUs=$(nproc) RealMemory=1000 State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$conf"
slurmctld -f "$conf" || skip "slurmctld failed: $(tail -2 "$dir/slurmctld.log" 2>/dev/null)"
slurmd -f "$conf" || skip "slurmd failed: $(tail -2 "$dir/slurmd.log" 2>/dev/null)"
for _ in $(seq 100); do
  if sinfo -h -o %t 2>/dev/null | grep -q idle; then
    echo "SLURM_CONF=$conf"
    exit 0
  fi
  sleep 0.2
done
skip "the node did not come up idle in 20 s: $(sinfo -h 2>&1 | head -1); $(tail -2 "$dir/slurmd.log" 2>/dev/null)"
