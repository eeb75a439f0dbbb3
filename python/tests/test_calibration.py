"""calibrate_rig(), calibrate_noise(), check_noise_model(): the files `rangebayes calibrate` writes, from Python."""

import subprocess

import numpy as np
import pytest

import rangebayes as rb


def run(cli, *args):
    return subprocess.run([str(cli), *map(str, args)], check=True, capture_output=True, text=True).stdout


def test_rig_is_the_cli_rig(tmp_path, cli, root):
    boards = root / "tests" / "data" / "calibration" / "opencv_stereo"
    run(cli, "calibrate", "rig", "--left", boards / "left*.jpg", "--right", boards / "right*.jpg",
        "--out", tmp_path / "cli.yaml", "-q")
    lefts = sorted(boards.glob("left*.jpg"))  # a list of paths works as the patterns do
    rig, summary = rb.calibrate_rig(lefts, str(boards / "right*.jpg"), board={"cols": 9, "rows": 6})
    rb.write_rig(tmp_path / "py.yaml", rig)
    assert (tmp_path / "py.yaml").read_bytes() == (tmp_path / "cli.yaml").read_bytes()
    assert summary.pairs_used == len([v for v in summary.views if v["used"]]) >= 10
    assert 0 < summary.rms_stereo_px < 0.5
    assert rig.baseline_m() == pytest.approx(0.083, abs=0.002)  # 25 mm squares
    assert "left01.jpg" in summary.brief_report()  # the table of views
    # An image without a partner is left out with a warning (the CLI's notice).
    with pytest.warns(UserWarning, match=r"no partner image for .*left01\.jpg"):
        rb.calibrate_rig(lefts, [p for p in sorted(boards.glob("right*.jpg")) if p.name != "right01.jpg"])


def test_rig_bad_input(root):
    boards = root / "tests" / "data" / "calibration" / "opencv_stereo"
    left, right = str(boards / "left*.jpg"), str(boards / "right*.jpg")
    with pytest.raises(rb.Error, match="matches nothing|no file"):
        rb.calibrate_rig(str(boards / "nothing*.jpg"), right)
    with pytest.raises(ValueError, match="'square' is not one of 'chessboard', 'charuco'"):
        rb.calibrate_rig(left, right, board={"type": "square"})
    with pytest.raises(TypeError, match=r"calibrate_rig\(board=...\).*colls"):
        rb.calibrate_rig(left, right, board={"colls": 9})
    with pytest.raises(TypeError, match="calibrate_rig.*min_pair"):
        rb.calibrate_rig(left, right, min_pair=3)
    with pytest.raises(rb.Error, match="square size -1 m must be positive"):
        rb.calibrate_rig(left, right, board={"square_m": -1.0})  # "board: square size -1 m must be positive"
    with pytest.raises(TypeError, match="expected a path"):
        rb.calibrate_rig(3, right)


def test_an_unusable_rig_is_an_error(tmp_path, root):
    """One right image replaced by another view's: stereo RMS ~19 px, refused as `calibrate rig` refuses it."""
    import shutil
    for image in (root / "tests" / "data" / "calibration" / "opencv_stereo").glob("*.jpg"):
        shutil.copy(image, tmp_path / image.name)
    shutil.copy(tmp_path / "right09.jpg", tmp_path / "right05.jpg")
    left, right = str(tmp_path / "left*.jpg"), str(tmp_path / "right*.jpg")
    with pytest.raises(rb.Error, match="not usable: stereo RMS .* --drop-outliers"):
        rb.calibrate_rig(left, right)
    rig, summary = rb.calibrate_rig(left, right, max_rms_px=float("inf"))
    assert summary.rms_stereo_px > 2.0
    assert rb.RIG_CALIBRATION_OPTIONS["max_rms_px"] == 2.0


def test_noise_from_a_plane_is_the_cli_model(tmp_path, cli):
    rec = tmp_path / "plane"
    run(cli, "synth", "--scene", "plane", "--frames", "4", "--width", "160", "--height", "120", "--out", rec, "-q")
    out = run(cli, "calibrate", "noise", rec, "--out", tmp_path / "cli.yaml")
    model, report = rb.calibrate_noise(rec)
    rb.write_noise_model(tmp_path / "py.yaml", model)
    assert (tmp_path / "py.yaml").read_bytes() == (tmp_path / "cli.yaml").read_bytes()
    assert report.brief_report() in out
    assert model.form == "floor-plus-scale" and model.matcher == "block"
    assert report.samples.shape == (model.samples, 4)
    assert np.all(np.isfinite(report.samples[:, :2]))
    # The same with the options the CLI gives as flags.
    run(cli, "calibrate", "noise", rec, "--rig", rec / "rig.yaml", "--form", "constant", "--roi", 10, 10, 120, 90,
        "--stride", 2, "--out", tmp_path / "cli2.yaml")
    model, _ = rb.calibrate_noise(rec, rig=rb.read_rig(rec / "rig.yaml"), form="constant", roi=(10, 10, 120, 90),
                                  stride_px=2)
    rb.write_noise_model(tmp_path / "py2.yaml", model)
    assert (tmp_path / "py2.yaml").read_bytes() == (tmp_path / "cli2.yaml").read_bytes()
    with pytest.raises(rb.Error, match="floor-plus-scale|sigma_d"):
        rb.calibrate_noise(rec, matcher="sgbm", form="floor-plus-scale")
    with pytest.raises(rb.Error, match="frames 0..8 requested but the recording has 4"):
        rb.calibrate_noise(rec, matcher="spacetime", frames=9)
    with pytest.raises(ValueError, match="roi takes four numbers"):
        rb.calibrate_noise(rec, roi=(1, 2, 3))
    with pytest.raises(ValueError, match="target 'cube'"):
        rb.calibrate_noise(rec, target="cube")
    with pytest.raises(TypeError, match="one recording folder"):
        rb.calibrate_noise([rec, rec])
    # The warning of the CLI about a search range beside the plane is a UserWarning here (it was the CLI's alone).
    with pytest.warns(UserWarning, match="disparities lie on the fitted plane"):
        rb.calibrate_noise(rec, min_disparity_px=20, num_disparities=8)
    with pytest.raises(TypeError, match="rig must be a StereoRig or a rig file"):
        rb.calibrate_noise(rec, rig=5)
    with pytest.raises(TypeError, match="target: cannot convert"):
        rb.calibrate_noise(rec, target=3)


def test_noise_from_ground_truth_and_its_check(tmp_path, cli, root):
    scene = root / "tests" / "data" / "stereo" / "tsukuba"
    out = run(cli, "calibrate", "noise", scene, "--target", "ground-truth", "--out", tmp_path / "cli.yaml")
    model, report = rb.calibrate_noise([scene], target="ground-truth")
    rb.write_noise_model(tmp_path / "py.yaml", model)
    assert (tmp_path / "py.yaml").read_bytes() == (tmp_path / "cli.yaml").read_bytes()
    assert model.form == "learned" and model.matcher == "sgbm" and report.scenes == 1
    assert report.brief_report() in out
    check = rb.check_noise_model(model, [scene])
    cli_check = run(cli, "calibrate", "check-noise", scene, "--noise-model", tmp_path / "cli.yaml")
    assert check.brief_report() == cli_check
    assert check.samples > 1000 and len(check.observed_within) == 3
    assert check.passes() == ("NOT calibrated" not in cli_check)
    # The samples the check scores (its default stride 2): z = residual / σ_d of the model gives its shares.
    samples = rb.ground_truth_noise_samples(scene, stride_px=2)
    assert samples.shape == (check.samples, 4) and np.isnan(samples[:, 2]).all()
    z = np.abs(samples[:, 0]) / np.array([model.apply(s, j) for s, j in samples[:, [1, 3]]])
    assert [np.mean(z <= k) for k in (1, 2, 3)] == pytest.approx(check.observed_within, abs=1e-9)
    with pytest.raises(TypeError, match="ground_truth_noise_samples.*frames"):
        rb.ground_truth_noise_samples(scene, frames=3)
    with pytest.raises(TypeError, match=r"calibrate_noise\(target='ground-truth'\).*frames"):
        rb.calibrate_noise([scene], target="ground-truth", frames=3)
    with pytest.raises(rb.Error, match="tsukuba_missing"):
        rb.calibrate_noise([root / "tsukuba_missing"], target="ground-truth")
