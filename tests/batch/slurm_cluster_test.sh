#!/usr/bin/env bash
# End to end on a real one-node Slurm cluster started here (tests/batch/slurm_local_cluster.sh): a manifest
# of replays of the bundled recording and smooths of bundled meshes, one task failing on a missing input,
# goes through `batch submit` (split into two job arrays: the cluster's MaxArraySize is 3); `batch status` names
# the failure with its error line; after the fix, `batch resubmit` runs exactly that task; `batch cancel` cancels
# both arrays of a split batch; a requeued task (scontrol requeue) publishes once, with its
# attempt counted and its Slurm output appended; a hanging task stopped at --task-timeout, and one stopped at
# Slurm's own time limit (--time=1, a minute: it runs alongside the rest), both read "timeout"; and every output
# equals, byte for byte, that of `batch submit --local 2`.
#   usage: slurm_cluster_test.sh RANGEBAYES_BINARY   (from the repository root)
# Exit 77 (skip) only when the Slurm or munge programs are not installed (scripts/setup.sh installs them).
set -euo pipefail

rb=$(realpath "$1")
src=$(pwd)
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=slurm_test_harness.sh
source "$here"/slurm_test_harness.sh

rb_test_begin rb_slurm_test

# sbatch --wait returns late: a job is done when it has left the queue.
wait_job() { wait_for 120 "job $1 to leave the queue" job_gone "$1"; }
running() { grep -qs '"state": "running"' "$1"; }

# One slot more than the two the first job takes (--max-parallel 2), for the task that waits for its time limit;
# MaxArraySize 3, so that the 5 tasks of the first batch take two job arrays (tasks 0-2, and 3-4 as 0-1).
rb_cluster_start "$work"/cluster 1 3 3
phase "cluster up"

# The manifest's folder: the bundled data under the names the manifest uses.
m="$work"/manifest
mkdir -p "$m"
ln -s "$src"/recordings "$m"/recordings
ln -s "$src"/tests/data/meshes "$m"/meshes
cat >"$m"/tasks.txt <<'MANIFEST'
# replays of the bundled recording (small options), smooths of bundled meshes
replay recordings/synth_planes_320x240 --count 2 --downsample 4 --tolerance fast --out replay_a
replay recordings/synth_planes_320x240 --first 2 --count 1 --downsample 4 --no-decimate --out replay_b

smooth meshes/trim-star_noisy_gauss_n3.obj trim-star.ply --tolerance fast --threads 1
smooth meshes/fandisk_noisy_gauss0.3.obj "fandisk smoothed.ply" --noise 0.3 --tolerance fast --threads 1
# fails until later/block.obj exists beside the manifest
smooth later/block.obj block.ply --tolerance fast --threads 1
MANIFEST

# Tasks that hang: `info` of a FIFO that nobody writes. One is stopped at Slurm's time limit (a minute, the least
# Slurm takes; its controller checks limits every 30 s), checked at the end.
mkfifo "$m"/stuck.obj
echo "info stuck.obj" >"$m"/hang.txt
slurm_limit="$work"/slurm_limit
limit_job=$("$rb" batch submit "$m"/hang.txt --out "$slurm_limit" --slurm-arg=--time=1)

# sbatch refusing (an unknown partition) and sbatch missing: one error line each, exit 1.
if err=$("$rb" batch submit "$m"/tasks.txt --out "$work"/refused --partition nope 2>&1); then fail "submit to partition nope"; fi
expect_in "$err" "rangebayes batch submit: error: sbatch refused the job (exit 1): sbatch: error:" "sbatch refusing"
[ "$(wc -l <<<"$err")" -eq 1 ] || fail "more than one error line: $err"
if err=$(PATH=/nonexistent "$rb" batch submit "$m"/tasks.txt --out "$work"/nosbatch 2>&1); then fail "submit without sbatch"; fi
expect_in "$err" "sbatch: cannot run sbatch (No such file or directory)" "sbatch missing"

slurm="$work"/slurm
jobs=$("$rb" batch submit "$m"/tasks.txt --out "$slurm" --max-parallel 2)
[[ $jobs =~ ^[0-9]+\ [0-9]+$ ]] || fail "batch submit printed '$jobs', not two job ids"
job=${jobs% *} job_b=${jobs#* }
grep -q -- "--dependency=afterany:$job" "$slurm"/batch.json || fail "the second array does not wait for the first"
wait_job "$job"
wait_job "$job_b"
phase "first jobs done"

status=$("$rb" batch status "$slurm") && rc=0 || rc=$?
echo "$status"
[ "$rc" -eq 3 ] || fail "batch status exited $rc with a failed task, not 3"
expect_in "$status" "5 tasks: 4 succeeded, 1 failed, 0 running, 0 missing" "status after the first job"
expect_in "$status" "failed: task 4 (manifest line 8, exit 1, attempt 0, host node1): rangebayes smooth: error:" \
  "the failed task and its host"
expect_in "$status" "later/block.obj" "the error line names the missing input"
json=$("$rb" batch status "$slurm" --json) || true
expect_in "$json" '"failed": 1' "status --json counts"
expect_in "$json" "\"job_id\": \"$job\"" "status --json job id"
expect_in "$json" "\"job_id\": \"$job_b\"" "status --json job id of the second array"
[ ! -e "$slurm"/tasks/4 ] || fail "the failed task published a folder"
ls -A "$slurm"/tasks | grep -q '^\.' && fail "a temporary task folder was left behind: $(ls -A "$slurm"/tasks)"
[ -s "$slurm/slurm/${job_b}_1.out" ] || fail "no Slurm output file for task 4 (array index 1 of job $job_b)"

# The fix: the input appears beside the manifest; resubmit runs exactly task 4.
mkdir -p "$m"/later
cp "$src"/tests/data/meshes/block_noisy_gauss0.4.obj "$m"/later/block.obj
job2=$("$rb" batch resubmit "$slurm")
[[ $job2 =~ ^[0-9]+$ && $job2 != "$job" && $job2 != "$job_b" ]] || fail "resubmit printed '$job2', not a new job id"
[ "$(grep -c -- '"--array=1"' "$slurm"/batch.json)" -eq 1 ] && grep -q '"array_offset": 3' "$slurm"/batch.json ||
  fail "resubmit did not submit exactly task 4 (array index 1 at offset 3): $(cat "$slurm"/batch.json)"
wait_job "$job2"
phase "resubmitted job done"
status=$("$rb" batch status "$slurm")
echo "$status"
expect_in "$status" "5 tasks: 5 succeeded, 0 failed, 0 running, 0 missing" "status after resubmit"
if "$rb" batch resubmit "$slurm" 2>/dev/null; then fail "resubmit of a finished batch succeeded"; fi

# Requeue safety: a task requeued while it runs publishes once; its Slurm output keeps both attempts.
cat >"$m"/slow.txt <<'MANIFEST'
smooth meshes/real_angel_scan.obj angel.ply --tolerance tight --threads 1
MANIFEST
rq="$work"/requeue
job3=$("$rb" batch submit "$m"/slow.txt --out "$rq")
wait_for 30 "the slow task to run" running "$rq"/status/0.json
phase "slow task running"
scontrol requeue "${job3}_0"
# Slurm holds a requeued job for about two minutes (BeginTime); let it start again at once.
wait_for 30 "job $job3 to be requeued (pending)" job_pending "$job3"
scontrol update JobId="${job3}_0" StartTime=now
wait_job "$job3"
phase "requeued job done"
status=$("$rb" batch status "$rq" --json)
expect_in "$status" '"succeeded": 1' "requeued task finished"
expect_in "$status" '"attempt": 1' "requeued task's attempt from SLURM_RESTART_COUNT"
[ "$(grep -c '^task 0:' "$rq/slurm/${job3}_0.out")" -eq 2 ] ||
  fail "Slurm output of the requeued task was not appended: $(cat "$rq/slurm/${job3}_0.out")"
ls -A "$rq"/tasks | grep -q '^\.' && fail "a temporary task folder was left behind after requeue"
[ -s "$rq"/tasks/0/angel.ply ] || fail "requeued task has no result"

# Cancel: a split batch of four hanging tasks (arrays 0-2 and 3), some running, some queued.
cancel_dir="$work"/cancel
printf 'info stuck.obj\n%.0s' 1 2 3 4 >"$m"/hang4.txt
cancel_jobs=$("$rb" batch submit "$m"/hang4.txt --out "$cancel_dir")
[[ $cancel_jobs =~ ^[0-9]+\ [0-9]+$ ]] || fail "batch submit of 4 tasks printed '$cancel_jobs', not two job ids"
out=$("$rb" batch cancel "$cancel_dir")
expect_in "$out" "cancelled Slurm jobs $cancel_jobs of $cancel_dir" "batch cancel"
for j in $cancel_jobs; do wait_job "$j"; done
if err=$("$rb" batch cancel "$cancel_dir" 2>&1); then fail "a second batch cancel succeeded"; fi
expect_in "$err" "no Slurm job of this batch is queued or running" "cancel with nothing queued"
phase "split batch cancelled"

# A hanging task stopped by run-task at --task-timeout; sbatch's --time leaves room for it.
tt="$work"/task_timeout
tt_job=$("$rb" batch submit "$m"/hang.txt --out "$tt" --task-timeout 1)
grep -q -- '"--time=2"' "$tt"/batch.json || fail "--task-timeout 1 did not set sbatch's --time=2: $(cat "$tt"/batch.json)"
wait_job "$tt_job"
status=$("$rb" batch status "$tt") && rc=0 || rc=$?
echo "$status"
[ "$rc" -eq 3 ] || fail "batch status exited $rc with a timed-out task, not 3"
expect_in "$status" "1 tasks: 0 succeeded, 0 failed, 1 timeout, 0 running, 0 missing" "status after --task-timeout"
expect_in "$status" "timeout: task 0 (manifest line 1, exit 143, attempt 0, host node1): time limit of 1 s reached (--task-timeout): stopped with SIGTERM" \
  "the --task-timeout line"
phase "--task-timeout task stopped"

# The same manifest on two local workers gives the same files.
local_out="$work"/local
"$rb" batch submit "$m"/tasks.txt --out "$local_out" --local 2 >"$work"/local.txt ||
  { cat "$work"/local.txt; fail "batch submit --local 2"; }
phase "local run done"
expect_in "$(cat "$work"/local.txt)" "5 tasks: 5 succeeded" "local run"
# replay's summary.json holds wall-clock timings (frames/s, latencies); every other file must be identical.
diff -r -x summary.json "$slurm"/tasks "$local_out"/tasks || fail "Slurm and --local outputs differ"
[ "$(find "$slurm"/tasks -type f | wc -l)" -gt 10 ] || fail "too few output files: $(find "$slurm"/tasks -type f)"
cmp "$slurm"/tasks/4/block.ply "$local_out"/tasks/4/block.ply

# Slurm's own time limit: the task reads timeout, naming it, not a cancellation.
wait_for 180 "job $limit_job to reach its time limit and leave the queue" job_gone "$limit_job"
phase "time-limit job done"
status=$("$rb" batch status "$slurm_limit") && rc=0 || rc=$?
echo "$status"
[ "$rc" -eq 3 ] || fail "batch status exited $rc with a task at Slurm's time limit, not 3"
expect_in "$status" "1 tasks: 0 succeeded, 0 failed, 1 timeout, 0 running, 0 missing" "status after Slurm's time limit"
expect_in "$status" "(Slurm job $limit_job reached its time limit of 00:01:00)" "the time limit named"
echo "PASS: $(find "$slurm"/tasks -type f ! -name summary.json | wc -l) output files identical between Slurm and --local 2"
