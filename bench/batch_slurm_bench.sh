#!/usr/bin/env bash
# Batch throughput: N smoothing tasks on a two-node loopback Slurm cluster (two slurmd -N on this machine,
# one job slot each) and with `batch submit --local 2` (two slots too), plus the same for N trivial tasks
# (`info`), whose wall time is nearly all scheduling overhead. Needs root and the Slurm/munge packages.
#   usage (repository root): bench/batch_slurm_bench.sh build/ci/apps/rangebayes [N=32]
# Prints one table row per run: tasks/minute and the overhead per task of Slurm against --local,
# (wall_slurm - wall_local) * slots / N.
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

printf "| tasks | path | wall (s) | tasks/min | overhead/task vs --local (s) |\n|---|---|---|---|---|\n"
for kind in smooth info; do
  tl=$(run_local "$m/$kind.txt" "$work/$kind-local"); check "$work/$kind-local"
  ts=$(run_slurm "$m/$kind.txt" "$work/$kind-slurm"); check "$work/$kind-slurm"
  printf "| %d %s | --local 2 | %.2f | %.0f | |\n" "$n" "$kind" "$tl" "$(awk -v n="$n" -v t="$tl" 'BEGIN { print n * 60 / t }')"
  printf "| %d %s | Slurm, 2 nodes x 1 slot | %.2f | %.0f | %.3f |\n" "$n" "$kind" "$ts" \
    "$(awk -v n="$n" -v t="$ts" 'BEGIN { print n * 60 / t }')" \
    "$(awk -v n="$n" -v s="$ts" -v l="$tl" 'BEGIN { print (s - l) * 2 / n }')"
done
