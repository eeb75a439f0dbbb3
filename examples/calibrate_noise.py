#!/usr/bin/env python3
"""Fit the disparity noise model of a rig from a recording of a plane, and plot the residuals against it.

    python3 examples/calibrate_noise.py [RECORDING] [--out DIR] [--matcher block|spacetime|sgbm]

RECORDING: a recording folder of one plane facing the rig (frames.csv, rig.yaml; what `rangebayes record` writes).
Without one, a synthetic plane under a random pattern is rendered first (rangebayes.synth). Writes DIR/noise.yaml
(what `rangebayes calibrate noise RECORDING --target plane` writes) and DIR/residuals.png (headless: matplotlib's
Agg backend).
"""

import argparse
import pathlib

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import rangebayes as rb  # noqa: E402


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("recording", nargs="?", default=None)
    p.add_argument("--out", default="calibrate_noise_out")
    p.add_argument("--matcher", default="block", choices=["block", "spacetime", "sgbm"])
    args = p.parse_args()
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    recording = args.recording
    if recording is None:
        recording = out / "plane"
        rb.synth(out=recording, overwrite=True, scene="plane", frames=4, width=320, height=240, seed=1)
        print(f"rendered a synthetic plane recording into {recording}")

    model, report = rb.calibrate_noise(recording, matcher=args.matcher)
    print(report.brief_report(), end="")
    rb.write_noise_model(out / "noise.yaml", model)

    # The residuals against the fitted σ_d: z = r / σ_d should look like the model's mixture (mostly N(0, 1)).
    r, pred = report.samples[:, 0], report.samples[:, 1]
    sigma = np.array([model.apply(s) if np.isfinite(s) else model.sigma_px for s in pred])
    z = r / sigma
    z = z[np.isfinite(z)]
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.hist(np.clip(z, -6, 6), bins=121, range=(-6, 6), density=True, color="0.6", label="z = residual / sigma_d")
    x = np.linspace(-6, 6, 400)
    ax.plot(x, (1 - model.outlier_fraction) * np.exp(-x * x / 2) / np.sqrt(2 * np.pi), "k",
            label=f"model ({model.form}, outliers {model.outlier_fraction:.1%})")
    ax.set_xlabel("normalised residual z")
    ax.legend()
    fig.savefig(out / "residuals.png", dpi=80, bbox_inches="tight")
    print(f"wrote {out / 'noise.yaml'} and {out / 'residuals.png'} ({len(z)} residuals)")


if __name__ == "__main__":
    main()
