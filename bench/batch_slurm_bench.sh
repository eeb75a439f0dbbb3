#!/usr/bin/env bash
# Batch throughput: N smoothing tasks on a two-node loopback Slurm cluster (two slurmd -N on this machine,
# one job slot each) and with `batch submit --local 2` (two slots too), plus the same for N trivial tasks
# (`info`), whose wall time is nearly all scheduling overhead. Needs root and the Slurm/munge packages.
#   usage (repository root): bench/batch_slurm_bench.sh build/ci/apps/rangebayes [N=32]
# Prints one table row per run: tasks/minute, and the overhead per task (see row() below); Slurm's extra
# overhead per task is the difference of the two rows.
set -euo pipefail
rb=$(realpath "$1")
n=${2:-32}
src=$(pwd)
source "$src"/tests/batch/slurm_local_cluster.sh
rb_cluster_have_binaries || { echo "Slurm or munge not installed (scripts/setup.sh)" >&2; exit 1; }
work=$(mktemp -d /tmp/rb_batch_bench.XXXXXX)
chmod 755 "$work"
trap 'rb_cluster_stop; rm -rf "$work"' EXIT
rb_cluster_start "$work"/cluster 2 1

m="$work"/manifest
mkdir -p "$m"
ln -s "$src"/tests/data/meshes "$m"/meshes
for i in $(seq 0 $((n - 1))); do
  echo "smooth meshes/trim-star_noisy_gauss_n3.obj s$i.ply --tolerance fast --threads 1"
done >"$m"/smooth.txt
for i in $(seq 0 $((n - 1))); do echo "info meshes/trim-star_noisy_gauss_n3.obj"; done >"$m"/info.txt

now() { date +%s.%N; }
wait_job() {
  while [ -n "$(squeue --noheader --jobs "$1" 2>/dev/null)" ]; do sleep 0.05; done
}
run_slurm() {  # run_slurm MANIFEST OUT -> seconds from submit to the last task leaving the queue
  local t0 job; t0=$(now)
  job=$("$rb" batch submit "$1" --out "$2")
  wait_job "$job"
  awk -v a="$(now)" -v b="$t0" 'BEGIN { print a - b }'
}
run_local() {
  local t0; t0=$(now)
  "$rb" batch submit "$1" --out "$2" --local 2 >/dev/null
  awk -v a="$(now)" -v b="$t0" 'BEGIN { print a - b }'
}
check() {
  "$rb" batch status "$1" | head -1 | grep -q "$n succeeded" || { "$rb" batch status "$1"; exit 1; }
}

# Seconds spent inside the tasks' commands (status files), summed over all tasks.
command_s() { cat "$1"/status/*.json | awk -F': ' '/"duration_s"/ { gsub(",", "", $2); t += $2 } END { print t }'; }
# Overhead per task = (wall x 2 slots - command time) / N: the time a slot spends on anything but a command
# (starting run-task and the command's process, and for Slurm scheduling, slurmstepd and the job script).
row() {  # row NAME PATH WALL DIR
  local c; c=$(command_s "$4")
  printf "| %d %s | %s | %.1f | %.1f | %.1f | %.2f |\n" "$n" "$1" "$2" "$3" \
    "$(awk -v n="$n" -v t="$3" 'BEGIN { print n * 60 / t }')" "$c" \
    "$(awk -v n="$n" -v t="$3" -v c="$c" 'BEGIN { print (t * 2 - c) / n }')"
}
printf "| tasks | path | wall (s) | tasks/min | command time (s) | overhead/task (s) |\n|---|---|---|---|---|---|\n"
for kind in smooth info; do
  tl=$(run_local "$m/$kind.txt" "$work/$kind-local"); check "$work/$kind-local"
  ts=$(run_slurm "$m/$kind.txt" "$work/$kind-slurm" 2>/dev/null); check "$work/$kind-slurm"
  row "$kind" "--local 2" "$tl" "$work/$kind-local"
  row "$kind" "Slurm, 2 nodes x 1 slot" "$ts" "$work/$kind-slurm"
done
