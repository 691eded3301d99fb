# Sourced by the Slurm tests: starts a single-node Slurm (munged, slurmctld, slurmd) by hand, in
# its own folder with its own ports, without systemd, and stops it on exit. Needs Debian's munge,
# slurmctld, slurmd and slurm-client (.ci/install-deps). Sets SLURM_CONF for the clients and
# `cluster` to the folder. Every client call has a deadline: a daemon that is not answering
# makes Slurm's clients retry for minutes.
# Facts of this kind of machine: proctrack/cgroup fails (linuxproc with task/none works); munged's
# socket folder must be searchable by all; SlurmctldHost and NodeName must be `hostname -s`;
# batch_sched_delay=0 removes a 3 s gap between waves of tasks.

cluster=$(mktemp -d /tmp/pdsim_slurm.XXXXXX)
chmod 755 "$cluster"
daemons=()

stop_cluster() {
  set +e
  cd / # this shell must not be among the processes working in the folder
  if [ -n "${SLURM_CONF:-}" ]; then
    timeout 10 scancel --user="$(id -un)" >/dev/null 2>&1
    for _ in $(seq 50); do
      [ -z "$(timeout 5 squeue -h -o %i 2>/dev/null)" ] && break
      sleep 0.2
    done
  fi
  for pid in "${daemons[@]}"; do kill "$pid" 2>/dev/null; done
  sleep 0.5
  for pid in "${daemons[@]}"; do kill -9 "$pid" 2>/dev/null; done
  # Whatever still runs in the folder (job processes, slurmstepd), by working directory.
  for proc in /proc/[0-9]*; do
    case "$(readlink "$proc/cwd" 2>/dev/null)" in "$cluster"*) kill -9 "${proc#/proc/}" 2>/dev/null ;; esac
  done
  rm -rf "$cluster"
}
trap stop_cluster EXIT

# Two free TCP ports, so that concurrent tests do not clash on 6817/6818.
read -r ctld_port slurmd_port < <(/usr/bin/python3 -c '
import socket
s = [socket.socket() for _ in range(2)]
for x in s: x.bind(("127.0.0.1", 0))
print(*[x.getsockname()[1] for x in s])')

mkdir -m 755 "$cluster/munge"
dd if=/dev/urandom of="$cluster/munge/munge.key" bs=1024 count=1 status=none
chmod 400 "$cluster/munge/munge.key"
munged --foreground --force --socket="$cluster/munge/socket" \
  --key-file="$cluster/munge/munge.key" --pid-file="$cluster/munge/munged.pid" \
  --log-file="$cluster/munge/munged.log" --seed-file="$cluster/munge/seed" \
  >>"$cluster/munge/munged.out" 2>&1 &
daemons+=($!)

node=$(hostname -s)
memory=$(awk '/MemTotal/ {print int($2 / 1024 * 0.9)}' /proc/meminfo)
mkdir -p "$cluster/state" "$cluster/spool"
cat > "$cluster/slurm.conf" <<CONF
ClusterName=pdsimtest
SlurmctldHost=$node
SlurmUser=$(id -un)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
AuthType=auth/munge
AuthInfo=socket=$cluster/munge/socket
CredType=cred/munge
StateSaveLocation=$cluster/state
SlurmdSpoolDir=$cluster/spool
SlurmctldPidFile=$cluster/slurmctld.pid
SlurmdPidFile=$cluster/slurmd.pid
SlurmctldLogFile=$cluster/slurmctld.log
SlurmdLogFile=$cluster/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerParameters=batch_sched_delay=0
ReturnToService=2
KillWait=5
MinJobAge=300
NodeName=$node CPUs=$(nproc) RealMemory=$memory State=UNKNOWN
PartitionName=test Nodes=ALL Default=YES MaxTime=INFINITE State=UP
CONF
export SLURM_CONF="$cluster/slurm.conf"
for _ in $(seq 50); do [ -S "$cluster/munge/socket" ] && break; sleep 0.1; done
slurmctld -D -i >>"$cluster/slurmctld.out" 2>&1 &
daemons+=($!)
slurmd -D >>"$cluster/slurmd.out" 2>&1 &
daemons+=($!)
for _ in $(seq 100); do
  state=$(timeout 5 sinfo -h -o %T 2>/dev/null || true)
  [ "$state" = idle ] && break
  sleep 0.2
done
if [ "$state" != idle ]; then
  echo "FAIL: the test's Slurm did not start (node state '$state'); its logs:"
  tail -n 20 "$cluster"/*.log "$cluster"/*.out "$cluster"/munge/*.log
  exit 1
fi
