#!/usr/bin/env bash
# Runs the whole ctest suite of the tsan preset (built first: cmake --preset tsan && cmake --build --preset tsan)
# under ThreadSanitizer, in one shard per CPU, each shard's processes pinned to its own CPU.
#
#   scripts/sanitizers/tsan-suite.sh [SHARDS]     (default: nproc)
#
# Why pinned: Debian's oneTBB (which our parallel loops and OpenCV's use) is not built with -fsanitize=thread,
# so TSan cannot see the synchronisation of its scheduler and reports every hand-over of loop data between a
# TBB worker and another thread as a race. oneTBB sizes its pool from the process's CPU affinity mask, so a
# process pinned to one CPU runs every TBB loop on the thread that calls it: the reports that TSan cannot get
# right go away, and every race between threads that we start ourselves (pipeline stages, recorder, console
# server, batch workers) is still seen, with the happens-before edges of our own mutexes, atomics and queues.
# What this does not cover: two iterations of one TBB loop racing with each other.
#
# Shard k of n runs ctest's tests k, k+n, k+2n, ... (ctest -I k,,n). Each shard's ctest output is in
# build/tsan/tsan-shard-K.log (every test's whole output: tsan-shard-K.ctest.log); what TSan said, one file per
# process that said something, in build/tsan/tsan-reports/. Exit status: 0 when every shard passed and no
# process reported, else 1. The reports counted and the suppressions used are printed at the end.
set -uo pipefail
cd "$(dirname "$0")/../.."
build=build/tsan
shards="${1:-$(nproc)}"
if [ ! -x "$build/apps/rangebayes" ]; then
  echo "tsan-suite: error: $build is not built (cmake --preset tsan && cmake --build --preset tsan)" >&2
  exit 1
fi
if ! command -v taskset >/dev/null; then
  echo "tsan-suite: error: taskset not found (package util-linux)" >&2
  exit 1
fi
cpus=()
while IFS= read -r c; do cpus+=("$c"); done < <(taskset -cp $$ | sed 's/.*: //' | tr ',' '\n' |
  awk -F- '{ if (NF == 2) for (i = $1; i <= $2; ++i) print i; else print $1 }')
[ "$shards" -ge 1 ] || { echo "tsan-suite: error: SHARDS must be at least 1" >&2; exit 1; }

# Every process writes what TSan says (reports, the suppressions it used) to its own file, also the CLI
# processes that a test starts and whose stderr the test reads.
reports_dir="$PWD/$build/tsan-reports"
rm -rf "$reports_dir" && mkdir -p "$reports_dir"
export TSAN_OPTIONS="print_suppressions=1:log_path=$reports_dir/tsan${TSAN_OPTIONS:+:$TSAN_OPTIONS}"
pids=()
start=$SECONDS
for k in $(seq "$shards"); do
  cpu=${cpus[$(((k - 1) % ${#cpus[@]}))]}
  taskset -c "$cpu" ctest --preset tsan -I "$k,,$shards" --output-log "$build/tsan-shard-$k.ctest.log" \
    >"$build/tsan-shard-$k.log" 2>&1 &
  pids+=("$!")
done
rc=0
for k in $(seq "$shards"); do
  if ! wait "${pids[$((k - 1))]}"; then rc=1; fi
  tail -n 4 "$build/tsan-shard-$k.log" | sed "s/^/shard $k: /"
done
echo "tsan-suite: $shards shard(s), $((SECONDS - start)) s"
reports=$(cat "$reports_dir"/* 2>/dev/null | grep -c '^WARNING: ThreadSanitizer' || true)
echo "tsan-suite: TSan reports: $reports (in $reports_dir: $(grep -l '^WARNING: ThreadSanitizer' "$reports_dir"/* 2>/dev/null | wc -l) processes)"
[ "$reports" -eq 0 ] || rc=1
echo "tsan-suite: suppressions used (matches, summed over the processes):"
cat "$reports_dir"/* 2>/dev/null | grep -E '^[0-9]+ (race|race_top|thread|mutex|signal|deadlock|called_from_lib):' |
  awk '{ n[$2] += $1 } END { for (k in n) print "  " n[k], k }'
exit "$rc"
