#!/usr/bin/env bash
# Fits the disparity noise model on the Gray-code plane sequence (../shared/data/stereo/graycode_stereo_d435_zengzhik,
# no licence: read here, never copied into the repository) for single-frame block matching, SGBM and space-time
# matching. Usage: bench/calibration_noise_graycode.sh [RANGEBAYES_BINARY] [DATA_FOLDER] [WORK_FOLDER]
set -euo pipefail
bin=${1:-build/apps/rangebayes}
data=${2:-../shared/data/stereo/graycode_stereo_d435_zengzhik}
work=${3:-$(mktemp -d)}
rec=$work/graycode_recording
mkdir -p "$rec/left" "$rec/right"
# The images are already rectified; rig numbers from the source repository's main.py (see SOURCES.md there).
cat > "$rec/rig.yaml" <<YAML
%YAML:1.0
---
image_width: 1280
image_height: 720
K_left: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 640.07, 0., 642.22, 0., 640.07, 355.13, 0., 0., 1. ]
K_right: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 640.07, 0., 642.22, 0., 640.07, 355.13, 0., 0., 1. ]
R: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 1., 0., 0., 0., 1., 0., 0., 0., 1. ]
T: !!opencv-matrix
   rows: 3
   cols: 1
   dt: d
   data: [ -0.04997, 0., 0. ]
is_rectified: 1
P1: !!opencv-matrix
   rows: 3
   cols: 4
   dt: d
   data: [ 640.07, 0., 642.22, 0., 0., 640.07, 355.13, 0., 0., 0., 1., 0. ]
P2: !!opencv-matrix
   rows: 3
   cols: 4
   dt: d
   data: [ 640.07, 0., 642.22, -31.9843, 0., 640.07, 355.13, 0., 0., 0., 1., 0. ]
doffs_px: 0.
YAML
echo "index,timestamp_left_ns,timestamp_right_ns,left,right,pattern_id" > "$rec/frames.csv"
for i in $(seq 0 50); do
  n=$(printf %02d "$i"); m=$(printf %06d "$i")
  ln -sf "$(realpath "$data/frames/$n-left.png")" "$rec/left/$m.png"
  ln -sf "$(realpath "$data/frames/$n-right.png")" "$rec/right/$m.png"
  echo "$i,$i,$i,left/$m.png,right/$m.png,$i" >> "$rec/frames.csv"
done
# The lit projection surface in the left image (the rest is dark background and room).
common=(--min-disparity 60 --num-disparities 40 --roi 440 170 560 330 --quiet)
echo "== block matching, frame 0 (projected wallpaper), 11x11 window"
"$bin" calibrate noise "$rec" --matcher block --frame 0 --window 11 --out "$work/noise_block.yaml" --png "$work/noise_block.png" "${common[@]}"
echo "== SGBM, frame 0, 5x5 block"
"$bin" calibrate noise "$rec" --matcher sgbm --frame 0 --window 5 --out "$work/noise_sgbm.yaml" --png "$work/noise_sgbm.png" "${common[@]}"
echo "== space-time, frames 3-26 (vertical Gray code and inverses, T = 24), 5x5 window"
"$bin" calibrate noise "$rec" --matcher spacetime --frame 3 --frames 24 --window 5 --out "$work/noise_spacetime.yaml" --png "$work/noise_spacetime.png" "${common[@]}"
echo "outputs in $work"
