#!/usr/bin/env bash
# A Slurm node killed mid-task, on a real one-node cluster started here (tests/batch/slurm_local_cluster.sh):
# while two long tasks (a replay of the bundled recording played 16 times; task 1 of batch A, submitted with
# --no-requeue, and task 0 of batch B, submitted as by default) write their outputs, slurmd, their slurmstepd
# processes and every task process get SIGKILL at once, as when a node loses power. Nothing of the killed tasks
# is published in tasks/ (their partial outputs stay in the .tmp-* folders). The controller marks the node down,
# ending A's job and requeueing B's; the node comes back; `batch resubmit` takes exactly A's task 1 and refuses
# B while Slurm still holds its job; both complete, and every output equals, byte for byte, that of
# `batch submit --local 2`.
#   usage: slurm_node_kill_test.sh RANGEBAYES_BINARY   (from the repository root)
# Exit 77 (skip) only when the Slurm or munge programs are not installed (scripts/setup.sh installs them).
set -euo pipefail

rb=$(realpath "$1")
src=$(pwd)
here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
# shellcheck source=slurm_test_harness.sh
source "$here"/slurm_test_harness.sh

rb_test_begin rb_slurm_kill_test

node_state() { sinfo --noheader --nodes=node1 --format=%T 2>/dev/null | head -n 1; }
node_is() { [ "$(node_state)" = "$1" ]; }
node_down() { [[ $(node_state) == down* ]]; }
node_responding() { [[ -n $(node_state) && $(node_state) != *'*' ]]; }
# The controller's agent has no RPC waiting for a retry and no agent thread sending one.
agents_idle() {
  sdiag 2>/dev/null | awk '/^Agent queue size:/ { q = $4 } /^Agent count:/ { c = $3 } END { exit !(q == "0" && c == "0") }'
}
state_of() { grep -so '"state": "[a-z]*"' "$1"/status/"$2".json | cut -d'"' -f4; }
# Task I of batch DIR runs and has written at least one smoothed frame into its temporary folder.
writing() {
  [ "$(state_of "$1" "$2")" = running ] &&
    [ -n "$(find "$1"/tasks -path "$1/tasks/.tmp-$2-*/replay_long/smoothed/*.ply" -print -quit 2>/dev/null)" ]
}
# Batch A's short tasks 0 and 2 have succeeded, and both long tasks (A's 1, B's 0) are writing their frames:
# killed now, the node takes exactly those two with it and no task is being launched (Slurm requeues a task
# whose launch fails, --no-requeue or not).
ready_to_kill() {
  local t
  for t in "$a 1" "$b 0"; do
    case $(state_of $t) in succeeded | failed)
      fail "task ${t##* } of ${t%% *} ended before it could be killed (make it longer)" ;;
    esac
  done
  [ "$(state_of "$a" 0)" = succeeded ] && [ "$(state_of "$a" 2)" = succeeded ] && writing "$a" 1 && writing "$b" 0
}
all_dead() {
  local pid
  for pid in "$@"; do kill -0 "$pid" 2>/dev/null && return 1; done
  return 0
}
# check_killed DIR I: nothing of task I is published, its status still says running (the kill left it no time
# to record its end), and its partial outputs stay in its temporary folder.
check_killed() {
  local dir=$1 i=$2
  [ "$(state_of "$dir" "$i")" = running ] || fail "$dir task $i: status '$(state_of "$dir" "$i")', not running"
  [ ! -e "$dir"/tasks/"$i" ] || fail "$dir: the killed task $i published tasks/$i: $(ls -R "$dir"/tasks/"$i" | head)"
  local partial; partial=$(find "$dir"/tasks -path "$dir/tasks/.tmp-$i-*" -type f | wc -l)
  [ "$partial" -gt 0 ] || fail "$dir: no partial output of task $i left in its temporary folder"
  phase "nothing of $dir task $i published ($partial partial files in its temporary folder)"
}

# Two job slots whatever this process's CPU mask (the TSan suite pins each shard to one CPU, where nproc is 1
# and the long task would run alone, after the short ones).
rb_cluster_start "$work"/cluster 1 2
phase "cluster up"

m="$work"/manifest
mkdir -p "$m"
ln -s "$src"/recordings "$m"/recordings
ln -s "$src"/tests/data/meshes "$m"/meshes
# At a quarter of the recorded frame rate, so that the long tasks last at least 17 s on any machine: played as fast
# as possible they took 5.6 s on a fast one and ended before Slurm's 3 s scheduling passes had started B's task.
long='replay recordings/synth_planes_320x240 --repeat 16 --speed recorded --speed-factor 0.25 --downsample 4 --tolerance fast --no-previews --out replay_long'
cat >"$m"/tasks.txt <<MANIFEST
smooth meshes/trim-star_noisy_gauss_n3.obj trim-star.ply --tolerance fast --threads 1
# the long task: 128 frames (the recording's 8, played 16 times at 7.5 frames/s), killed while it writes them
$long
smooth meshes/fandisk_noisy_gauss0.3.obj fandisk.ply --noise 0.3 --tolerance fast --threads 1
MANIFEST
echo "$long" >"$m"/long.txt

# Batch A with --no-requeue: the dead node's job ends (NODE_FAIL), and `batch resubmit` brings its task back.
# Batch B as submitted by default (--requeue): Slurm requeues the dead node's task itself. B is submitted
# second, so its task starts once A's short tasks are done (the node has 2 job slots).
a="$work"/norequeue
b="$work"/requeue
job_a=$("$rb" batch submit "$m"/tasks.txt --out "$a" --slurm-arg=--no-requeue)
job_b=$("$rb" batch submit "$m"/long.txt --out "$b")
[[ $job_a =~ ^[0-9]+$ && $job_b =~ ^[0-9]+$ ]] || fail "batch submit printed '$job_a' and '$job_b', not job ids"
wait_for 120 "A's tasks 0 and 2 to succeed while A's task 1 and B's task 0 write their outputs" ready_to_kill
phase "A's tasks 0 and 2 done; A's task 1 and B's task 0 writing"

# The node dies: slurmd, the slurmstepd of every running task and every task process tree, SIGKILL all at once.
# The processes come from one snapshot of the process table, each task's found by its run-task command line.
slurmd_pid=$(cat "$work"/cluster/slurmd-node1.pid)
snapshot=$(ps -eo pid=,ppid=,pgid=,args=)
runtasks=$(awk -v key="batch run-task $work/" 'index($0, key) { print $1 }' <<<"$snapshot")
[ "$(wc -w <<<"$runtasks")" -eq 2 ] || fail "expected 2 run-task processes, found: $(grep -F "batch run-task" <<<"$snapshot")"
victims=("$slurmd_pid")
groups=()
for pid in $runtasks; do
  read -r parent group < <(awk -v p="$pid" '$1 == p { print $2, $3 }' <<<"$snapshot")
  parent_args=$(awk -v p="$parent" '$1 == p { $1 = $2 = $3 = ""; print }' <<<"$snapshot")
  [[ $parent_args == *slurmstepd* ]] || fail "run-task $pid has parent $parent '$parent_args', not slurmstepd"
  victims+=("$parent" "$pid")
  groups+=("$group")
  # The task's command and anything else it started.
  victims+=($(awk -v p="$pid" '$2 == p { print $1 }' <<<"$snapshot"))
done
kill -9 "${victims[@]}" 2>/dev/null || true
for g in "${groups[@]}"; do kill -9 -- "-$g" 2>/dev/null || true; done
wait_for 10 "the killed processes to be gone" all_dead "${victims[@]}"
# The dead slurmd's pid must not be signalled again by rb_cluster_stop (it may be reused).
alive=()
for pid in "${rb_cluster_pids[@]}"; do [ "$pid" = "$slurmd_pid" ] || alive+=("$pid"); done
rb_cluster_pids=("${alive[@]}")
phase "killed slurmd, ${#groups[@]} slurmstepd and their task trees: ${victims[*]}"

# The status files still say running; `batch status` finds the run-task processes (on this host) gone.
status=$("$rb" batch status "$a") && rc=0 || rc=$?
echo "$status"
[ "$rc" -eq 3 ] || fail "batch status exited $rc with an interrupted task, not 3"
expect_in "$status" "3 tasks: 2 succeeded, 0 failed, 0 running, 1 interrupted, 0 missing" "A after the kill"
expect_in "$status" "interrupted: task 1 (manifest line 3" "A's interrupted task"
expect_in "$("$rb" batch status "$b")" "1 tasks: 0 succeeded, 0 failed, 0 running, 1 interrupted, 0 missing" \
  "B after the kill"
check_killed "$a" 1
check_killed "$b" 0
for i in 0 2; do [ -d "$a"/tasks/$i ] || fail "A's finished task $i lost its result"; done

# The controller finds the node unresponsive (SlurmdTimeout=30) and marks it down: A's job ends, B's task is
# requeued (and held, BeginTime, about two minutes).
wait_for 150 "the controller to mark node1 down (state $(node_state))" node_down
phase "node1 $(node_state)"
wait_for 60 "B's job $job_b to be requeued (pending)" job_pending "$job_b"

slurmd -f "$SLURM_CONF" -N node1 || fail "slurmd did not restart"
wait_for 10 "slurmd to write its pid file" \
  bash -c '[ -s "$1" ] && [ "$(cat "$1")" != "$2" ]' _ "$work"/cluster/slurmd-node1.pid "$slurmd_pid"
rb_cluster_pids+=("$(cat "$work"/cluster/slurmd-node1.pid)")
wait_for 30 "node1 to register again (state $(node_state))" node_responding
# ReturnToService=2 returns a node that registers again; resume it where it stays down.
if node_down; then
  scontrol update nodename=node1 state=resume
  phase "node1 resumed"
fi
wait_for 60 "node1 to become idle (state $(node_state))" node_is idle
phase "node1 back, idle"
wait_for 60 "A's job $job_a to leave the queue" job_gone "$job_a"
phase "A's job $job_a ended"

# A: resubmit takes exactly the task the node took with it, whose status still says running.
job_a2=$("$rb" batch resubmit "$a")
[[ $job_a2 =~ ^[0-9]+$ && $job_a2 != "$job_a" ]] || fail "batch resubmit printed '$job_a2'"
array=$(grep -o '"--array=[^"]*"' "$a"/batch.json | tail -n 1)
[ "$array" = '"--array=1"' ] || fail "resubmit submitted $array, expected exactly task 1"
phase "A resubmitted as job $job_a2 ($array)"

# B: its job is still queued, so resubmit refuses; Slurm's requeue runs the task (released from its hold now).
if err=$("$rb" batch resubmit "$b" 2>&1); then fail "resubmit of B succeeded while its job $job_b is queued"; fi
expect_in "$err" "Slurm job $job_b of this batch is still queued or running" "resubmit of B while requeued"
# When the controller marked the node down it sent the node a terminate for the dead instance of B's job, which
# failed and waits in its retry list; delivered once slurmd is back, it cancels whatever runs under that job id
# then ("CANCELLED ... DUE TO NODE FAILURE"), and B's requeued instance would die at its start. So B is released
# only after the controller has no outgoing message left (sdiag: retry list and agent threads empty).
wait_for 120 "the controller's retried messages to node1 to be delivered (sdiag: agent queue and threads)" agents_idle
phase "the controller's messages delivered; B released"
scontrol update JobId="${job_b}_0" StartTime=now

wait_for 240 "A's job $job_a2 to leave the queue" job_gone "$job_a2"
wait_for 240 "B's job $job_b to leave the queue" job_gone "$job_b"
phase "resubmitted and requeued tasks done"
status=$("$rb" batch status "$a")
echo "$status"
expect_in "$status" "3 tasks: 3 succeeded, 0 failed, 0 running, 0 missing" "A after resubmit"
status=$("$rb" batch status "$b" --json)
expect_in "$status" '"succeeded": 1' "B after Slurm's requeue"
expect_in "$status" '"attempt": 1' "B's attempt from SLURM_RESTART_COUNT"
for dir in "$a" "$b"; do
  ls -A "$dir"/tasks | grep -q '^\.' && fail "a temporary task folder was left behind: $(ls -A "$dir"/tasks)"
done
[ "$(grep -c '^==> task 1 ' "$a"/logs/1.log)" -eq 2 ] || fail "A's task 1 log does not show two runs"
[ "$(grep -c '^==> task 0 ' "$b"/logs/0.log)" -eq 2 ] || fail "B's task 0 log does not show two runs"

# The same manifest on two local workers gives the same files.
local_out="$work"/local
"$rb" batch submit "$m"/tasks.txt --out "$local_out" --local 2 >"$work"/local.txt ||
  { cat "$work"/local.txt; fail "batch submit --local 2"; }
phase "local run done"
expect_in "$(cat "$work"/local.txt)" "3 tasks: 3 succeeded" "local run"
frames=$(find "$a"/tasks/1/replay_long -type f -name '*.ply' | wc -l)
[ "$frames" -ge 128 ] || fail "A's task 1 wrote $frames meshes, expected at least 128"
# replay's summary.json holds wall-clock timings; every other file must be identical, byte for byte.
compare() {  # compare SLURM_FOLDER LOCAL_FOLDER
  diff -r -x summary.json "$1" "$2" || fail "$1 and $2 differ"
  local f
  for f in $(cd "$1" && find . -type f ! -name summary.json); do cmp "$1/$f" "$2/$f" || fail "$1/$f differs"; done
}
compare "$a"/tasks "$local_out"/tasks
compare "$b"/tasks/0 "$local_out"/tasks/1
echo "PASS: $(find "$a"/tasks "$b"/tasks -type f ! -name summary.json | wc -l) output files of the killed batches" \
  "(resubmitted, and requeued by Slurm) identical to --local 2"
