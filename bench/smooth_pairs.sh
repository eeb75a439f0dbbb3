#!/usr/bin/env bash
# The stereo path (`smooth noisy_cov.ply`, covariances kept) with extra smooth flags on pairs that
# bench/real_noise_pairs.sh built (PAIRS_ONLY=1 is enough); one JSON line per pair, scored like that script.
# INPUT=noisy: the generic path instead (`smooth noisy.ply`, no covariances, k estimated unless the flags give it).
# Two runs compare per scene with `bench/real_noise_table.py --compare BASE.jsonl OTHER.jsonl`.
# A PAIRS argument (a file: OUT/<split>_pairs.txt of that script) stands for the pair folders it lists.
#   bench/smooth_pairs.sh BUILD_DIR "SMOOTH FLAGS" PAIR_DIR|PAIRS...   e.g. "--robust-data 4" OUT/test_pairs.txt
#   bench/smooth_pairs.sh BUILD_DIR "--prior prior.yaml" OUT/test_pairs.txt   a learned prior (`rangebayes learn-prior`)
set -euo pipefail
build=$1; flags=$2; shift 2
rb=${RB:-$build/apps/rangebayes}; ev=${EV:-$build/bench/bench_stereo_smooth}
input=${INPUT:-noisy_cov}
dirs=()
for a in "$@"; do
  if [ -f "$a" ]; then
    while read -r noisy _; do dirs+=("$(dirname "$a")/$(dirname "$noisy")"); done < <(grep -v '^#' "$a")
  else
    dirs+=("$a")
  fi
done
for d in "${dirs[@]}"; do
  $rb smooth "$d/$input.ply" "$d/flags.ply" $flags -q > /dev/null 2>&1
  echo "{\"pair\": \"$d\", \"input\": \"$input\", \"flags\": \"$flags\", \"score\": $($ev compare "$d/flags.ply" "$d/gt.ply")}"
  rm -f "$d/flags.ply"
done
