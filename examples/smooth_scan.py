#!/usr/bin/env python3
"""Smooth a noisy scan and save a before/after picture (rangebayes.render: headless, no display).

    python3 examples/smooth_scan.py [MESH] [--out DIR] [--noise K]

MESH defaults to the bundled trim-star scan; writes DIR/smoothed.ply and DIR/before_after.png.
"""

import argparse
import pathlib

import numpy as np

import rangebayes as rb

ROOT = pathlib.Path(__file__).resolve().parents[1]


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("mesh", nargs="?", default=str(ROOT / "tests/data/meshes/trim-star_noisy_gauss_n3.obj"))
    p.add_argument("--out", default="smooth_scan_out")
    p.add_argument("--noise", type=float, default=None, help="k (sigma / mean edge); default: estimated")
    args = p.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)

    noisy = rb.read_mesh(args.mesh)
    smoothed, summary = rb.smooth(noisy, noise=args.noise)
    print(summary.brief_report(), end="")
    rb.write_mesh(str(out / "smoothed.ply"), smoothed)

    # One framing for both pictures (the noisy mesh's), side by side.
    before = rb.render(noisy)
    after = rb.render(smoothed, frame_like=noisy)
    gap = np.full((before.shape[0], 8, 3), 255, np.uint8)
    rb.write_png(out / "before_after.png", np.concatenate([before, gap, after], axis=1))
    print(f"wrote {out / 'smoothed.ply'} and {out / 'before_after.png'}")


if __name__ == "__main__":
    main()
