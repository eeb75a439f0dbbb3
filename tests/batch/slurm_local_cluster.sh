# Source this file: starts a throw-away Slurm cluster on loopback, everything under one temporary folder
# (nothing in /etc, no systemd). Used by the Slurm tests (through slurm_test_harness.sh) and
# bench/batch_slurm_bench.sh.
#
#   rb_cluster_start ROOT [NODES [CPUS [MAXARRAY]]]  # ROOT: a new temporary folder; NODES slurmd on this
#                                         # machine (1), each offering CPUS job slots (default: nproc; more than
#                                         # the machine has are taken: SlurmdParameters=config_overrides);
#                                         # MAXARRAY: MaxArraySize (default: Slurm's, 1001)
#   rb_cluster_stop               # kills what rb_cluster_start started (call it from an EXIT trap)
#
# Exports SLURM_CONF, so sbatch/squeue (and rangebayes batch) talk to this cluster. Needs root: slurmd runs
# jobs as the submitting user, and munged must run as the munge user.
# Facts this relies on (Debian 12, Slurm 22.05, containers without systemd): munged runs as the munge user
# with its socket in a folder of mode 755 (AuthInfo=socket=...); the cgroup plugins abort every job here, so
# ProctrackType=proctrack/linuxproc and TaskPlugin=task/none.

rb_cluster_pids=()

rb_cluster_log() { echo "slurm-cluster: $*" >&2; }

rb_cluster_have_binaries() {
  command -v slurmctld >/dev/null && command -v slurmd >/dev/null && command -v sbatch >/dev/null &&
    command -v squeue >/dev/null && command -v munged >/dev/null
}

# What a cluster test needs before it starts one: exits 77 (ctest's skip) when the Slurm or munge programs are
# not installed, 1 when not root (slurmd runs jobs as the submitter, munged as the munge user).
rb_cluster_require() {
  if ! rb_cluster_have_binaries; then
    echo "SKIP: slurmctld, slurmd, sbatch, squeue or munged not installed (scripts/setup.sh installs them)"
    exit 77
  fi
  if [ "$(id -u)" -ne 0 ]; then
    echo "FAIL: needs root (slurmd runs jobs as the submitter, munged runs as the munge user)" >&2
    exit 1
  fi
}

# Echoes a TCP port on 127.0.0.1 that nothing listens on, starting the search at $1.
rb_cluster_free_port() {
  local port=$1
  while (echo >/dev/tcp/127.0.0.1/"$port") 2>/dev/null; do port=$((port + 1)); done
  echo "$port"
}

rb_cluster_start() {
  local root=$1 nodes=${2:-1} cpus=${3:-$(nproc)} max_array=${4:-}
  local t0; t0=$(date +%s%N)
  RB_CLUSTER_ROOT=$root
  mkdir -p "$root"/munge "$root"/munge-run "$root"/state "$root"/spool "$root"/log
  chmod 755 "$root" "$root"/munge-run
  chmod 700 "$root"/munge
  # The munge key: 1024 random bytes, readable by the munge user only.
  dd if=/dev/urandom of="$root"/munge/munge.key bs=1024 count=1 status=none
  chmod 400 "$root"/munge/munge.key
  chown -R munge:munge "$root"/munge "$root"/munge-run
  runuser -u munge -- munged --force --key-file="$root"/munge/munge.key \
    --socket="$root"/munge-run/munge.socket --pid-file="$root"/munge-run/munged.pid \
    --log-file="$root"/munge/munged.log --seed-file="$root"/munge/munged.seed || {
    rb_cluster_log "munged did not start:"; cat "$root"/munge/munged.log >&2; return 1; }
  local i
  for i in $(seq 50); do [ -s "$root"/munge-run/munged.pid ] && break; sleep 0.1; done
  rb_cluster_pids+=("$(cat "$root"/munge-run/munged.pid)")

  local base=$((20000 + RANDOM % 20000))
  local ctld_port; ctld_port=$(rb_cluster_free_port "$base")
  local conf="$root"/slurm.conf
  cat >"$conf" <<CONF
ClusterName=rangebayes-test
SlurmctldHost=localhost(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$root/munge-run/munge.socket
CredType=cred/munge
StateSaveLocation=$root/state
SlurmdSpoolDir=$root/spool/%n
SlurmctldPidFile=$root/slurmctld.pid
SlurmdPidFile=$root/slurmd-%n.pid
SlurmctldLogFile=$root/log/slurmctld.log
SlurmdLogFile=$root/log/slurmd-%n.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
MpiDefault=none
JobCompType=jobcomp/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
MessageTimeout=10
SlurmctldTimeout=30
SlurmdTimeout=30
InactiveLimit=0
MinJobAge=2
SlurmdParameters=config_overrides
CONF
  [ -z "$max_array" ] || echo "MaxArraySize=$max_array" >>"$conf"
  local names=() port=$((ctld_port + 1)) n
  for n in $(seq "$nodes"); do
    port=$(rb_cluster_free_port "$port")
    echo "NodeName=node$n NodeHostname=localhost NodeAddr=127.0.0.1 Port=$port CPUs=$cpus State=UNKNOWN" >>"$conf"
    names+=("node$n")
    port=$((port + 1))
  done
  local list; list=$(IFS=,; echo "${names[*]}")
  echo "PartitionName=batch Nodes=$list Default=YES MaxTime=INFINITE State=UP OverSubscribe=NO" >>"$conf"
  export SLURM_CONF=$conf

  slurmctld -f "$conf" -i || { rb_cluster_log "slurmctld did not start"; cat "$root"/log/slurmctld.log >&2; return 1; }
  for i in $(seq 100); do [ -s "$root"/slurmctld.pid ] && break; sleep 0.1; done
  rb_cluster_pids+=("$(cat "$root"/slurmctld.pid)")
  for n in "${names[@]}"; do
    mkdir -p "$root"/spool/"$n"
    slurmd -f "$conf" -N "$n" || { rb_cluster_log "slurmd $n did not start"; cat "$root"/log/slurmd-"$n".log >&2; return 1; }
    for i in $(seq 100); do [ -s "$root"/slurmd-"$n".pid ] && break; sleep 0.1; done
    rb_cluster_pids+=("$(cat "$root"/slurmd-"$n".pid)")
  done
  # Up when every node is idle.
  for i in $(seq 300); do
    local idle; idle=$(sinfo -h -N -t idle -o %N 2>/dev/null | sort -u | wc -l)
    if [ "$idle" -ge "$nodes" ]; then
      local ms=$((($(date +%s%N) - t0) / 1000000))
      rb_cluster_log "up: $nodes node(s), $cpus CPUs each, $((ms / 1000)).$(printf %03d $((ms % 1000))) s after the start"
      return 0
    fi
    sleep 0.1
  done
  rb_cluster_log "nodes did not become idle:"; sinfo -N >&2 || true; tail -20 "$root"/log/*.log >&2
  return 1
}

rb_cluster_stop() {
  local pid
  for pid in "${rb_cluster_pids[@]}"; do kill "$pid" 2>/dev/null || true; done
  for pid in "${rb_cluster_pids[@]}"; do
    for _ in $(seq 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
    kill -9 "$pid" 2>/dev/null || true
  done
  rb_cluster_pids=()
}
