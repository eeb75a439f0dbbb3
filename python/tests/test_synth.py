"""synth(): synthetic recordings with exact ground truth, the files of `rangebayes synth`."""

import subprocess

import numpy as np
import pytest

import rangebayes as rb


def test_same_recording_as_the_cli(tmp_path, cli):
    subprocess.run([str(cli), "synth", "--scene", "box", "--frames", "3", "--width", "96", "--height", "64",
                    "--seed", "5", "--out", str(tmp_path / "cli"), "-q"], check=True, capture_output=True)
    rec = rb.synth(out=tmp_path / "py", scene="box", frames=3, width=96, height=64, seed=5)
    cli_files = sorted(p.relative_to(tmp_path / "cli") for p in (tmp_path / "cli").rglob("*") if p.is_file())
    py_files = sorted(p.relative_to(tmp_path / "py") for p in (tmp_path / "py").rglob("*") if p.is_file())
    assert py_files == cli_files and len(cli_files) >= 9
    for f in cli_files:
        assert (tmp_path / "py" / f).read_bytes() == (tmp_path / "cli" / f).read_bytes(), f
    assert len(rec.left) == len(rec.right) == 3
    assert rec.left[0].shape == (64, 96) and rec.left[0].dtype == np.uint8
    assert rec.depth_m.dtype == np.float32 and rec.disparity_px.shape == (64, 96)
    # Ground truth consistent with the rig: d = f·B / Z.
    f, b = rec.intrinsics.fx_px, rec.rig.baseline_m()
    ok = np.isfinite(rec.depth_m)
    np.testing.assert_allclose(rec.disparity_px[ok], f * b / rec.depth_m[ok], rtol=1e-5)
    # The folder is a recording the pipeline replays.
    assert len(rb.open_recording(tmp_path / "py")) == 3


def test_bad_input(tmp_path):
    with pytest.raises(ValueError, match="'cube' is not one of"):
        rb.synth(scene="cube")
    with pytest.raises(rb.Error, match="frames"):
        rb.synth(frames=0)
    with pytest.raises(TypeError, match="synth.*colour"):
        rb.synth(colour=True)
    with pytest.raises(TypeError, match="out must be a folder path"):
        rb.synth(out=5)
    rb.synth(out=tmp_path / "rec", frames=1, width=32, height=32)
    with pytest.raises(rb.Error, match="already|overwrite"):
        rb.synth(out=tmp_path / "rec", frames=1, width=32, height=32)
    rb.synth(out=tmp_path / "rec", overwrite=True, frames=1, width=32, height=32)
