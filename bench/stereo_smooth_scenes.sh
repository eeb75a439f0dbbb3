#!/usr/bin/env bash
# Smoothing on the 12 Middlebury 2014 trainingQ scenes (BENCHMARKS.md "Smoothing on real stereo"): for each scene,
# `rangebayes stereo` (defaults, every DOWNSAMPLE-th pixel), the default `rangebayes smooth`, a reference solve
# (the same path at a 100x tighter distance tolerance, --gap-tolerance 1e-7), and the SGBM + 9x9 bilateral peer,
# each scored against the ground truth; one JSON line each. Wall times of stereo and smooth, one after the other.
# STEREO_ARGS="--noise-model noise.yaml": extra flags of `rangebayes stereo`; NO_REFERENCE=1: skip the reference solve.
#   bench/stereo_smooth_scenes.sh BUILD_DIR OUT_DIR [DOWNSAMPLE] [SCENE...]
set -euo pipefail
build=$1; out=$2; ds=${3:-4}; shift $(( $# >= 3 ? 3 : 2 ))
data=../shared/data/stereo/middlebury_2014_trainingQ
scenes=("$@"); [ ${#scenes[@]} -gt 0 ] || scenes=($(ls "$data"))
rb=${RB:-$build/apps/rangebayes}; ev=${EV:-$build/bench/bench_stereo_smooth}
mkdir -p "$out"
for s in "${scenes[@]}"; do
  d=$out/$s; mkdir -p "$d"
  $rb calibrate import-middlebury "$data/$s/calib.txt" --out "$d/rig.yaml" > /dev/null
  t0=$(date +%s.%N); $rb stereo "$data/$s/im0.png" "$data/$s/im1.png" --rig "$d/rig.yaml" --out "$d" --downsample "$ds" ${STEREO_ARGS:-} -q > "$d/stereo.log"
  t1=$(date +%s.%N); $rb smooth "$d/mesh.ply" "$d/smoothed.ply" -q > "$d/smooth.log"
  t2=$(date +%s.%N)
  if [ -n "${NO_REFERENCE:-}" ]; then cp "$d/smoothed.ply" "$d/reference.ply"; : > "$d/reference.log"
  else $rb smooth "$d/mesh.ply" "$d/reference.ply" -q --gap-tolerance 1e-7 --max-iterations 20000 > "$d/reference.log"; fi
  echo "{\"scene\": \"$s\", \"stereo_s\": $(printf %.3f "$(echo "$t1 - $t0" | bc)"), \"smooth_s\": $(printf %.3f "$(echo "$t2 - $t1" | bc)"), \"smooth\": \"$(grep -h '^summary\|^energy\|^distance' "$d/smooth.log" | tr '\n' ' ')\", \"reference\": \"$(grep -h '^summary\|^energy' "$d/reference.log" | tr '\n' ' ')\"}"
  for m in mesh smoothed reference; do $ev eval "$data/$s" "$d/$m.ply"; done
  $ev bilateral "$data/$s" "$d" "$d/bilateral.ply" "$ds"
done
