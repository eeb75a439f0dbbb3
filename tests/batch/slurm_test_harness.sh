# Source this file from a test that runs on its own Slurm cluster (slurm_cluster_test.sh,
# slurm_node_kill_test.sh): the skip-or-root check, the test's temporary folder and the EXIT trap that stops the
# cluster, kills what the test left running and removes the folder, and the helpers every such test uses.
#
#   rb_test_begin PREFIX   # exits 77/1 as rb_cluster_require; sets $work (mode 755, /tmp/PREFIX.XXXXXX)
#                          # and installs the trap
#   wait_for SECONDS WHAT COMMAND...   # polls COMMAND every 0.1 s; fails naming WHAT after SECONDS × the factor
#
# RANGEBAYES_TEST_TIMEOUT_FACTOR (from CMake; the sanitizer presets set 10) scales every wait_for.

# shellcheck source=slurm_local_cluster.sh
source "$(dirname "${BASH_SOURCE[0]}")"/slurm_local_cluster.sh

fail() { echo "FAIL: $*" >&2; exit 1; }
phase() { echo "[$SECONDS s] $*"; }
expect_in() {  # expect_in TEXT PATTERN WHAT
  grep -qF -- "$2" <<<"$1" || { echo "$1" >&2; fail "$3: expected '$2'"; }
}

rb_test_factor=${RANGEBAYES_TEST_TIMEOUT_FACTOR:-1}
[[ $rb_test_factor =~ ^[1-9][0-9]*$ ]] ||
  { echo "FAIL: RANGEBAYES_TEST_TIMEOUT_FACTOR '$rb_test_factor' is not a whole number" >&2; exit 1; }

rb_test_begin() {
  rb_cluster_require
  work=$(mktemp -d /tmp/"$1".XXXXXX)
  chmod 755 "$work"
  trap rb_test_cleanup EXIT
}

# Every process whose command line names the test's folder (task processes, slurmstepd's children); the
# folder's name is unique, so no process of another cluster on this machine matches.
rb_test_processes() {
  ps -eo pid=,args= | awk -v dir="$work" 'index($0, dir) && !/awk/ { print $1 }' | grep -vx "$$" || true
}

rb_test_cleanup() {
  local rc=$?
  rb_cluster_stop
  local pid
  for pid in $(rb_test_processes); do kill -9 "$pid" 2>/dev/null || true; done
  if [ $rc -ne 0 ] && [ -d "$work" ]; then
    echo "--- slurmctld log (tail)"; tail -n 30 "$work"/cluster/log/slurmctld.log 2>/dev/null || true
    echo "--- slurmd log (tail)"; tail -n 30 "$work"/cluster/log/slurmd-node1.log 2>/dev/null || true
  fi
  rm -rf "$work"
  exit $rc
}

wait_for() {
  local limit=$(($1 * rb_test_factor)) what=$2 i
  shift 2
  for i in $(seq $((limit * 10))); do
    "$@" && return 0
    sleep 0.1
  done
  "$@" && return 0
  sinfo -N >&2 || true
  squeue >&2 || true
  fail "$what: not after $limit s"
}

job_gone() { [ -z "$(squeue --noheader --jobs "$1" 2>/dev/null)" ]; }
job_pending() { squeue --noheader --jobs "$1" --format=%T 2>/dev/null | grep -q PENDING; }
