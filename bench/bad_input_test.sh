#!/usr/bin/env bash
# The benchmark programs on bad input (a missing file, a malformed argument): one error line on stderr and a
# non-zero exit, never an abort. Run by ctest as bench/bad_input from the repository root:
#   bench/bad_input_test.sh BENCH_DIR
set -uo pipefail
dir=$1
failures=0
check() {  # check NAME ARGS...
  local name=$1; shift
  local err rc
  err=$("$dir/$name" "$@" 2>&1 >/dev/null); rc=$?
  if [ "$rc" -eq 0 ] || [ "$rc" -ge 128 ] || [ "$(printf '%s\n' "$err" | wc -l)" -ne 1 ] ||
     ! printf '%s' "$err" | grep -q "^$name: error: "; then
    echo "FAIL: $name $* -> exit $rc, stderr: $err"
    failures=$((failures + 1))
  fi
}
check bench_decimate_compare /nonexistent/mesh.ply
check bench_decimate_compare not-a-mesh
check bench_calibration 'a:b:c:9x'
check bench_calibration 'a:/nonexistent/left*.jpg:/nonexistent/right*.jpg:9x6'
check bench_noise_covariance 4 no-such-scene
check bench_console_soak 0
check bench_fuse score /nonexistent /nonexistent/poses.conf
check bench_stereo_smooth eval /nonexistent /nonexistent/mesh.ply
check bench_smooth speed /nonexistent/mesh.ply
check bench_decimate target 0.02 /nonexistent/mesh.ply
check bench_stereo --quality=2014 --data=/nonexistent
check make_middlebury_recording /nonexistent /nonexistent/out
echo "$((12 - failures)) passed, $failures failed"
[ "$failures" -eq 0 ]
