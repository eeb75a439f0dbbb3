#!/usr/bin/env bash
# Real-noise benchmark (issue #16, BENCHMARKS.md "Real sensor noise, part 2"): per Middlebury scene with ground
# truth, the raw mesh of `rangebayes stereo` (defaults, the scene's search range, every DOWNSAMPLE-th pixel) and
# the same connectivity with each vertex moved along its pixel ray to the ground-truth depth (faces touching a
# vertex without ground truth are dropped from both). Writes OUT/<set>/<scene>/{noisy_cov,noisy,gt}.ply, one JSON
# line per scene and the pairs lists of `rangebayes learn-prior` (and bench/smooth_pairs.sh) per split:
# OUT/<split>_pairs.txt (noisy_cov.ply, the stereo path), OUT/<split>_pairs_generic.txt (noisy.ply, the generic
# path); then scores the raw mesh, the default stereo path (`smooth noisy_cov.ply`, covariances kept) and the
# default generic path (`smooth noisy.ply`, no covariances, no noise level). OUT lies outside the repository.
# KS="0.5 1 2": also the generic path at each given k (`smooth noisy.ply --noise k`), for the hindsight curve.
# PAIRS_ONLY=1: build the pairs only. STEREO_ARGS="--noise-model noise.yaml": extra flags of `rangebayes stereo`
# (e.g. the learned disparity-noise model). STEREO_ONLY=1: score the raw mesh and the stereo default path only.
# The D435 Gray-code plane (test split; DATA/graycode_stereo_d435_zengzhik, no licence: read from ../shared only) is
# turned into a 2014-layout scene under OUT/<scene>/scene: frame 00 (projected wallpaper), the pseudo ground truth
# disparity_graycode.npy as disp0GT.pfm (0: unknown), the rig of bench/calibration_noise_graycode.sh as calib.txt.
#   bench/real_noise_pairs.sh BUILD_DIR OUT_DIR [DOWNSAMPLE] [SPLIT...]     SPLIT: train validation test (default all)
set -euo pipefail
build=$1; out=$2; ds=${3:-4}; shift $(( $# >= 3 ? 3 : 2 ))
data=${DATA:-../shared/data/stereo}
rb=${RB:-$build/apps/rangebayes}; ev=${EV:-$build/bench/bench_stereo_smooth}
# The fixed split, by scene (scenes of one subject stay together: Motorcycle/MotorcycleE, Piano/PianoL, 2014 Teddy
# with v2 teddy, 2014 ArtL with 2005 Art). Settings are chosen on train and validation only.
declare -A split
split[train]="middlebury_2014_trainingQ/Adirondack middlebury_2014_trainingQ/ArtL middlebury_2014_trainingQ/Jadeplant
  middlebury_2014_trainingQ/Motorcycle middlebury_2014_trainingQ/MotorcycleE
  middlebury_2005_2006_thirdsize/Aloe middlebury_2005_2006_thirdsize/Art middlebury_2005_2006_thirdsize/Baby1
  middlebury_2005_2006_thirdsize/Baby2 middlebury_2005_2006_thirdsize/Baby3 middlebury_2005_2006_thirdsize/Books
  middlebury_2005_2006_thirdsize/Cloth1 middlebury_2005_2006_thirdsize/Cloth2 middlebury_2005_2006_thirdsize/Cloth3
  middlebury_2005_2006_thirdsize/Cloth4"
split[validation]="middlebury_2014_trainingQ/Piano middlebury_2014_trainingQ/PianoL middlebury_2014_trainingQ/Pipes
  middlebury_2005_2006_thirdsize/Bowling1 middlebury_2005_2006_thirdsize/Bowling2 middlebury_2005_2006_thirdsize/Dolls
  middlebury_2005_2006_thirdsize/Flowerpots middlebury_2005_2006_thirdsize/Lampshade1
  middlebury_2005_2006_thirdsize/Lampshade2 middlebury_2001_extra/barn1 middlebury_2001_extra/barn2"
split[test]="middlebury_2014_trainingQ/Playroom middlebury_2014_trainingQ/Shelves middlebury_2014_trainingQ/Teddy
  middlebury_2014_trainingQ/Vintage middlebury_2005_2006_thirdsize/Laundry middlebury_2005_2006_thirdsize/Midd1
  middlebury_2005_2006_thirdsize/Midd2 middlebury_2005_2006_thirdsize/Moebius middlebury_2005_2006_thirdsize/Monopoly
  middlebury_2005_2006_thirdsize/Reindeer middlebury_2005_2006_thirdsize/Rocks1 middlebury_2005_2006_thirdsize/Rocks2
  middlebury_2005_2006_thirdsize/Wood1 middlebury_2005_2006_thirdsize/Wood2 middlebury_2001_extra/poster
  middlebury_2001_extra/sawtooth middlebury_v2_2001_2003/cones middlebury_v2_2001_2003/teddy
  middlebury_v2_2001_2003/tsukuba middlebury_v2_2001_2003/venus graycode_stereo_d435_zengzhik"
# The Gray-code plane as a Middlebury 2014 folder DST (numbers from the source repository's main.py, SOURCES.md).
graycode_scene() {
  mkdir -p "$2"
  ln -sf "$(realpath "$1/frames/00-left.png")" "$2/im0.png"
  ln -sf "$(realpath "$1/frames/00-right.png")" "$2/im1.png"
  printf '%s\n' "cam0=[640.07 0 642.22; 0 640.07 355.13; 0 0 1]" "cam1=[640.07 0 642.22; 0 640.07 355.13; 0 0 1]" \
    doffs=0 baseline=49.97 width=1280 height=720 ndisp=96 > "$2/calib.txt"
  /usr/bin/python3 - "$1/disparity_graycode.npy" "$2/disp0GT.pfm" <<'PY'
import sys
import numpy as np
d = np.load(sys.argv[1])
assert d.ndim == 2 and d.dtype == np.float32, (d.shape, d.dtype)
d = np.where(d > 0, d, np.inf).astype('<f4')
with open(sys.argv[2], 'wb') as out:
    out.write(f'Pf\n{d.shape[1]} {d.shape[0]}\n-1.0\n'.encode())
    out.write(np.ascontiguousarray(d[::-1]).tobytes())
PY
}
splits=("$@"); [ ${#splits[@]} -gt 0 ] || splits=(train validation test)
mkdir -p "$out"
for sp in "${splits[@]}"; do
  : > "$out/${sp}_pairs.txt"; : > "$out/${sp}_pairs_generic.txt"
  for s in ${split[$sp]}; do
    d=$out/$s; mkdir -p "$d"; src=$data/$s
    if [ -f "$src/disparity_graycode.npy" ]; then graycode_scene "$src" "$d/scene"; src=$d/scene; fi
    ndisp=$($ev rig "$src" "$d/rig.yaml")
    for f in im0.png imL.png view1.png im2.ppm im2.png; do [ -f "$src/$f" ] && left=$src/$f && break; done
    for f in im1.png imR.png view5.png im6.ppm im6.png; do [ -f "$src/$f" ] && right=$src/$f && break; done
    $rb stereo "$left" "$right" --rig "$d/rig.yaml" --num-disparities "$ndisp" --out "$d" --downsample "$ds" ${STEREO_ARGS:-} -q > "$d/stereo.log"
    echo "{\"split\": \"$sp\", \"scene\": \"$s\", \"pair\": $($ev pair "$src" "$d/rig.yaml" "$d/mesh.ply" "$d")}"
    echo "$s/noisy_cov.ply $s/gt.ply" >> "$out/${sp}_pairs.txt"
    echo "$s/noisy.ply $s/gt.ply" >> "$out/${sp}_pairs_generic.txt"
    [ -n "${PAIRS_ONLY:-}" ] && continue
    $rb smooth "$d/noisy_cov.ply" "$d/stereo_default.ply" -q > "$d/smooth_cov.log"
    if [ -n "${STEREO_ONLY:-}" ]; then
      echo "{\"split\": \"$sp\", \"scene\": \"$s\", \"k\": \"\", \"score\": $($ev compare "$d/stereo_default.ply" "$d/gt.ply")}"
      continue
    fi
    $rb smooth "$d/noisy.ply" "$d/generic_default.ply" -q > "$d/smooth_generic.log"
    k=$(sed -n 's/^noise: *k = \([^ ]*\) .*/\1/p' "$d/smooth_generic.log")
    for m in stereo_default generic_default; do echo "{\"split\": \"$sp\", \"scene\": \"$s\", \"k\": \"$([ $m = generic_default ] && echo "$k")\", \"score\": $($ev compare "$d/$m.ply" "$d/gt.ply")}"; done
    for k in ${KS:-}; do
      $rb smooth "$d/noisy.ply" "$d/k$k.ply" --noise "$k" -q > /dev/null
      echo "{\"split\": \"$sp\", \"scene\": \"$s\", \"k\": \"$k\", \"score\": $($ev compare "$d/k$k.ply" "$d/gt.ply")}"
      rm -f "$d/k$k.ply"
    done
  done
done
