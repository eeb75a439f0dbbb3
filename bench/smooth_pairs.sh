#!/usr/bin/env bash
# The stereo path (`smooth noisy_cov.ply`, covariances kept) with extra smooth flags on pairs that
# bench/real_noise_pairs.sh built (PAIRS_ONLY=1 is enough); one JSON line per pair, scored like that script.
#   bench/smooth_pairs.sh BUILD_DIR "SMOOTH FLAGS" PAIR_DIR...     e.g. "--robust-data 4" OUT/middlebury_2014_trainingQ/*
set -euo pipefail
build=$1; flags=$2; shift 2
rb=${RB:-$build/apps/rangebayes}; ev=${EV:-$build/bench/bench_stereo_smooth}
for d in "$@"; do
  $rb smooth "$d/noisy_cov.ply" "$d/flags.ply" $flags -q > /dev/null 2>&1
  echo "{\"pair\": \"$d\", \"flags\": \"$flags\", \"score\": $($ev compare "$d/flags.ply" "$d/gt.ply")}"
  rm -f "$d/flags.ply"
done
