"""read_middlebury_scene(), read_disparity(), evaluate_disparity(): what `rangebayes eval-depth` scores."""

import subprocess

import numpy as np
import pytest

import rangebayes as rb


@pytest.fixture(scope="module")
def tsukuba(root):
    return root / "tests" / "data" / "stereo" / "tsukuba"


def test_scores_as_eval_depth(tmp_path, cli, tsukuba):
    subprocess.run([str(cli), "stereo", str(tsukuba / "imL.png"), str(tsukuba / "imR.png"), "--num-disparities",
                    "16", "--out", str(tmp_path), "-q"], check=True, capture_output=True)
    printed = subprocess.run([str(cli), "eval-depth", str(tmp_path / "disparity.pfm"), str(tsukuba)], check=True,
                             capture_output=True, text=True).stdout
    scene = rb.read_middlebury_scene(tsukuba)
    assert scene.layout == "v2" and scene.left.shape == (288, 384, 3) and scene.left.dtype == np.uint8
    assert scene.gt_disparity_px.dtype == np.float32 and scene.mask_nonocc.dtype == np.uint8
    assert scene.rig is None  # only the 2014 layout has a calib.txt
    disparity = rb.read_disparity(tmp_path / "disparity.pfm")
    assert disparity.dtype == np.float32 and disparity.shape == (288, 384)
    score = rb.evaluate_disparity(disparity, scene)
    assert score.brief_report() == printed
    assert score.thresholds_px == [0.5, 1.0, 2.0, 4.0]
    assert 0 < score.bad_valid_only[1] <= score.bad_with_holes[1] < 0.1
    # Without the scene's mask every pixel with ground truth counts; float64 is scored as float32.
    everywhere = rb.evaluate_disparity(disparity.astype(np.float64), scene.gt_disparity_px)
    assert everywhere.evaluated_pixels > score.evaluated_pixels
    exact = rb.evaluate_disparity(scene.gt_disparity_px, scene, bad_thresholds_px=[0.25])
    assert exact.bad_with_holes == [0.0] and exact.rms_px == 0.0


def test_bad_input(tsukuba, tmp_path):
    scene = rb.read_middlebury_scene(tsukuba)
    d = scene.gt_disparity_px
    with pytest.raises(ValueError, match="differ in size"):
        rb.evaluate_disparity(d[:10], scene)
    with pytest.raises(ValueError, match="differ in size"):
        rb.evaluate_disparity(d, scene, mask=np.zeros((3, 3), np.uint8))
    with pytest.raises(TypeError, match="float32 or float64"):
        rb.evaluate_disparity(np.zeros(d.shape, np.uint8), scene)
    with pytest.raises(TypeError, match="mask must be uint8"):
        rb.evaluate_disparity(d, scene, mask=np.zeros(d.shape, np.float32))
    with pytest.raises(rb.Error, match="bad-N threshold -1 must be positive"):
        rb.evaluate_disparity(d, scene, bad_thresholds_px=[-1.0])
    with pytest.raises(TypeError, match="evaluate_disparity.*thresholds"):
        rb.evaluate_disparity(d, scene, thresholds=[1.0])
    with pytest.raises(rb.Error, match="not a Middlebury scene folder"):
        rb.read_middlebury_scene(tmp_path)
    with pytest.raises(rb.Error, match="disparity map not found"):
        rb.read_disparity(tmp_path / "none.pfm")
