"""The examples run headless and write what they say."""

import os
import subprocess
import sys

import rangebayes as rb


def run(root, script, *args, cwd):
    env = dict(os.environ, MPLBACKEND="Agg")
    package_dir = os.path.dirname(os.path.dirname(os.path.abspath(rb.__file__)))  # the module under test
    env["PYTHONPATH"] = os.pathsep.join([package_dir, env.get("PYTHONPATH", "")])
    env.pop("DISPLAY", None)
    subprocess.run([sys.executable, str(root / "examples" / script), *args], check=True, cwd=cwd, env=env,
                   stdout=subprocess.DEVNULL)


def test_smooth_scan(root, tmp_path):
    run(root, "smooth_scan.py", "--out", str(tmp_path), "--noise", "0.3", cwd=tmp_path)
    assert (tmp_path / "before_after.png").stat().st_size > 1000
    assert rb.read_mesh(str(tmp_path / "smoothed.ply")).num_faces > 0


def test_replay_recording(root, tmp_path):
    run(root, "replay_recording.py", "--out", str(tmp_path), "--count", "2", cwd=tmp_path)
    assert len(list(tmp_path.glob("frame_*.ply"))) == 2


def test_calibrate_noise(root, tmp_path):
    run(root, "calibrate_noise.py", "--out", str(tmp_path), cwd=tmp_path)
    assert (tmp_path / "residuals.png").stat().st_size > 1000
    model = rb.read_noise_model(str(tmp_path / "noise.yaml"))
    assert model.form == "floor-plus-scale" and model.samples > 1000
