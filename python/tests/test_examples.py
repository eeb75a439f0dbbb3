"""The examples run headless and write what they say."""

import os
import subprocess
import struct
import sys

import numpy as np

import rangebayes as rb


def run(root, script, *args, cwd):
    env = dict(os.environ, MPLBACKEND="Agg")
    package_dir = os.path.dirname(os.path.dirname(os.path.abspath(rb.__file__)))  # the module under test
    env["PYTHONPATH"] = os.pathsep.join([package_dir, env.get("PYTHONPATH", "")])
    env.pop("DISPLAY", None)
    subprocess.run([sys.executable, str(root / "examples" / script), *args], check=True, cwd=cwd, env=env,
                   stdout=subprocess.DEVNULL)


def png_size(path):
    """(width, height) from a PNG's IHDR chunk."""
    header = path.read_bytes()[:24]
    assert header[:8] == b"\x89PNG\r\n\x1a\n" and header[12:16] == b"IHDR"
    return struct.unpack(">II", header[16:24])


def test_smooth_scan(root, tmp_path):
    run(root, "smooth_scan.py", "--out", str(tmp_path), "--noise", "0.3", cwd=tmp_path)
    noisy = rb.read_mesh(str(root / "tests/data/meshes/trim-star_noisy_gauss_n3.obj"))
    smoothed = rb.read_mesh(str(tmp_path / "smoothed.ply"))
    # What the script says it writes: the library's smoothing of its default mesh (deterministic), which is closer
    # to the ground truth than the noisy scan.
    expected, _ = rb.smooth(noisy, noise=0.3)
    np.testing.assert_allclose(smoothed.V, expected.V, rtol=0, atol=1e-6 * np.ptp(noisy.V))
    np.testing.assert_array_equal(smoothed.F, noisy.F)
    truth = rb.read_mesh(str(root / "tests/data/meshes/trim-star_gt.obj"))
    assert rb.evaluate(truth, smoothed)["mae_deg"] < rb.evaluate(truth, noisy)["mae_deg"]
    # Before and after side by side with an 8-pixel gap, each the size of the library's render of the scan.
    height, width = rb.render(noisy).shape[:2]
    assert png_size(tmp_path / "before_after.png") == (2 * width + 8, height)


def test_replay_recording(root, tmp_path):
    run(root, "replay_recording.py", "--out", str(tmp_path), "--count", "2", cwd=tmp_path)
    assert len(list(tmp_path.glob("frame_*.ply"))) == 2


def test_calibrate_noise(root, tmp_path):
    run(root, "calibrate_noise.py", "--out", str(tmp_path), cwd=tmp_path)
    assert (tmp_path / "residuals.png").stat().st_size > 1000
    model = rb.read_noise_model(str(tmp_path / "noise.yaml"))
    assert model.form == "floor-plus-scale" and model.samples > 1000
