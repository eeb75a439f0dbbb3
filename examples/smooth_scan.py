#!/usr/bin/env python3
"""Smooth a noisy scan and save a before/after picture (headless: matplotlib's Agg backend, no display).

    python3 examples/smooth_scan.py [MESH] [--out DIR] [--noise K]

MESH defaults to the bundled trim-star scan; writes DIR/smoothed.ply and DIR/before_after.png.
"""

import argparse
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import rangebayes as rb  # noqa: E402

ROOT = pathlib.Path(__file__).resolve().parents[1]


def shade(ax, mesh, title):
    V, F = mesh.V, mesh.F
    tri = V[F]
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    n /= np.linalg.norm(n, axis=1, keepdims=True) + 1e-300
    light = np.array([0.3, 0.4, 1.0]) / np.linalg.norm([0.3, 0.4, 1.0])
    order = np.argsort(tri[:, :, 2].mean(axis=1))  # painter's order along z
    grey = np.clip(np.abs(n @ light), 0.05, 1.0)[order]
    from matplotlib.collections import PolyCollection

    ax.add_collection(PolyCollection(tri[order][:, :, :2], facecolors=plt.cm.gray(grey), edgecolors="none"))
    ax.autoscale()
    ax.set_aspect("equal")
    ax.set_axis_off()
    ax.set_title(title)


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

    fig, axes = plt.subplots(1, 2, figsize=(10, 5))
    shade(axes[0], noisy, "noisy")
    shade(axes[1], smoothed, "smoothed")
    fig.savefig(out / "before_after.png", dpi=80, bbox_inches="tight")
    print(f"wrote {out / 'smoothed.ply'} and {out / 'before_after.png'}")


if __name__ == "__main__":
    main()
