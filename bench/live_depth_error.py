#!/usr/bin/python3
"""Depth error of a replay's results against a `rangebayes synth` recording's ground truth (BENCHMARKS.md,
issue 14 target 3: the live path's warm start).

    bench/live_depth_error.py RECORDING OUT [OUT...]

RECORDING: the synth recording (its ground_truth/depth_left_m.pfm); OUT: folders written by `rangebayes replay`
(raw/ with pixel coordinates, smoothed/). Per OUT, one line: the mean over results of the median |z - z_true| (mm)
of the raw and the smoothed meshes at their pixels, for all results and for the first and last quarter.
Needs the Python module on PYTHONPATH (build/release/python).
"""
import os
import sys

import numpy as np
import rangebayes as rb


def read_pfm(path):
    with open(path, 'rb') as f:
        f.readline()
        width, height = map(int, f.readline().split())
        scale = float(f.readline())
        data = np.frombuffer(f.read(), dtype='<f4' if scale < 0 else '>f4').reshape(height, width)
    return np.flipud(data)


def main():
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    truth_path = os.path.join(sys.argv[1], 'ground_truth', 'depth_left_m.pfm')
    try:
        truth = read_pfm(truth_path)
    except (OSError, ValueError) as e:
        sys.exit(f'live_depth_error: error: {truth_path}: {e}')
    for out in sys.argv[2:]:
        if not os.path.isdir(os.path.join(out, 'smoothed')):
            sys.exit(f'live_depth_error: error: {out}/smoothed is not a folder (an output of rangebayes replay?)')
        rows = []
        for name in sorted(os.listdir(os.path.join(out, 'smoothed'))):
            raw = rb.read_noisy_mesh(os.path.join(out, 'raw', name))
            smoothed = rb.read_mesh(os.path.join(out, 'smoothed', name))
            pixel = np.rint(np.asarray(raw.pixel)).astype(int)
            z_true = truth[pixel[:, 1], pixel[:, 0]]
            ok = np.isfinite(z_true)
            raw_error = np.abs(np.asarray(raw.V)[ok, 2] - z_true[ok]) * 1000
            smoothed_error = np.abs(np.asarray(smoothed.V)[ok, 2] - z_true[ok]) * 1000
            rows.append((np.median(raw_error), np.median(smoothed_error)))
        if not rows:
            sys.exit(f'live_depth_error: error: {out}/smoothed holds no result')
        r = np.array(rows)
        q = max(1, len(r) // 4)
        print(f'{out}: {len(r)} results, median |dz| mm: raw {r[:, 0].mean():.2f}, smoothed {r[:, 1].mean():.2f} '
              f'(first quarter {r[:q, 1].mean():.2f}, last quarter {r[-q:, 1].mean():.2f})')


if __name__ == '__main__':
    main()
