"""Rigs, noise models, recordings, stereo, triangulation, replay, decimation and learning from Python."""

import os
import signal
import subprocess

import numpy as np
import pytest

import rangebayes as rb


def test_rig_and_noise_model_yaml(tmp_path, recording_dir):
    rig = rb.read_rig(str(recording_dir / "rig.yaml"))
    assert (rig.width, rig.height) == (320, 240)
    assert rig.K_left.shape == (3, 3) and rig.K_left[0, 0] == 320.0
    assert rig.baseline_m() == pytest.approx(0.1)
    path = str(tmp_path / "rig.yaml")
    rb.write_rig(path, rig)
    back = rb.read_rig(path)
    np.testing.assert_array_equal(back.K_left, rig.K_left)
    np.testing.assert_array_equal(back.t_right_from_left_m, rig.t_right_from_left_m)

    model = rb.DisparityNoiseModel()
    model.form = "floor-plus-scale"
    model.floor_px, model.scale, model.matcher = 0.05, 1.5, "spacetime"
    path = str(tmp_path / "noise.yaml")
    rb.write_noise_model(path, model)
    back = rb.read_noise_model(path)
    assert back.form == "floor-plus-scale" and back.matcher == "spacetime"
    assert back.apply(0.1) == pytest.approx(model.apply(0.1))
    model.sigma_px = float("nan")  # the constant form's field, set out of range: an error, not a NaN σ_d
    model.form = "constant"
    with pytest.raises(rb.Error, match="sigma_px"):
        model.apply(0.1)
    with pytest.raises(rb.Error):
        rb.read_rig(str(tmp_path / "missing.yaml"))
    # A rig built in code is held to what a file is: one clear error, not depths from a zero baseline or a
    # mirrored R.
    left = (np.random.default_rng(1).random((240, 320)) * 255).astype(np.uint8)
    for field, value in [("t_right_from_left_m", np.zeros(3)), ("R_right_from_left", np.diag([1.0, 1.0, -1.0]))]:
        bad = rb.read_rig(str(recording_dir / "rig.yaml"))
        setattr(bad, field, value)
        with pytest.raises(rb.Error, match="baseline|rotation"):
            rb.stereo(bad, left, left)
        with pytest.raises(rb.Error, match="not written"):
            rb.write_rig(str(tmp_path / "bad.yaml"), bad)
        assert not (tmp_path / "bad.yaml").exists()


def test_recording_frames_are_numpy(recording_dir):
    rec = rb.open_recording(str(recording_dir))
    assert len(rec) == 8 and rec.rig is not None and rec.meta["scene"] == "planes"
    frames = list(rec)
    assert [f.index for f in frames] == list(range(8))
    left = frames[0].left
    assert isinstance(left, np.ndarray) and left.shape[:2] == (240, 320) and left.dtype == np.uint8
    assert rec[-1].index == 7
    with pytest.raises(IndexError):
        rec[8]


def test_recording_notices_are_warnings(tmp_path, recording_dir):
    """What `replay` prints about a damaged recording (a frame missing on disk) reaches Python as a UserWarning."""
    import re
    import shutil

    damaged = tmp_path / "rec"
    shutil.copytree(recording_dir, damaged)
    (damaged / "left" / "000003.png").unlink()
    notice = "^" + re.escape(f"{damaged}: frame 3: left/000003.png is missing") + "$"  # the CLI's line
    with pytest.warns(UserWarning, match=notice):
        rec = rb.open_recording(damaged)
    assert len(rec) == 8
    with pytest.warns(UserWarning, match=notice):
        rb.replay(damaged, playback={"count": 1}, smooth=False, decimate=False)


def test_stereo_sgbm_and_spacetime_then_triangulate(recording_dir):
    rec = rb.open_recording(str(recording_dir))
    f = rec[0]
    depth = rb.stereo(rec.rig, f.left, f.right, matcher="sgbm", num_disparities=64)
    assert depth.depth_m.shape == (240, 320) and depth.depth_m.dtype == np.float32
    assert np.isfinite(depth.depth_m).mean() > 0.5
    frames = [rec[i] for i in range(4)]
    st = rb.stereo(rec.rig, [x.left for x in frames], [x.right for x in frames], matcher="spacetime",
                   num_disparities=64, depth={"max_depth_m": 100.0})
    assert np.isfinite(st.sigma_disparity_px).any()
    mesh = rb.triangulate(st)
    assert isinstance(mesh, rb.NoisyMesh) and mesh.has_covariance and mesh.num_faces > 1000
    assert mesh.pixel.shape == (mesh.num_vertices, 2)
    # On every 4th pixel the smoother's β is the given one over the pixel stride (prior_weight_per_stride).
    coarse = rb.triangulate(st, downsample=4)
    _, s = rb.smooth(coarse, tolerance="fast", max_iterations=2)
    assert s.pixel_stride == 4 and s.prior_weight == rb.SMOOTH_OPTIONS["prior_weight"] / 4
    _, s = rb.smooth(coarse, tolerance="fast", max_iterations=2, prior_weight_per_stride=False)
    assert s.pixel_stride == 0 and s.prior_weight == rb.SMOOTH_OPTIONS["prior_weight"]
    cov = mesh.covariances
    np.testing.assert_allclose(cov, cov.transpose(0, 2, 1), rtol=1e-9, atol=1e-18)
    d = rb.match(f.left, f.right)  # the synthetic rig is already rectified
    assert d["disparity_px"].shape == (240, 320) and d["sigma_disparity_px"] is None
    assert 0.0 <= d["range_end_fraction"] < 0.03  # the synthetic scene lies inside the default search range
    assert d["num_disparities_searched"] == 0  # 64, as asked
    assert rb.match(f.left, f.right, num_disparities=40)["num_disparities_searched"] == 48
    back = rb.depth_from_disparity(st.disparity_px, st.sigma_disparity_px, st.intrinsics, st.baseline_m,
                                   max_depth_m=100.0)
    np.testing.assert_array_equal(back.depth_m, st.depth_m)
    with pytest.raises(TypeError, match="unexpected keyword argument 'blocksize'.*block_size_px"):
        rb.match(f.left, f.right, blocksize=3)
    with pytest.raises(rb.Error):
        rb.match(f.left, f.right[:100])


def test_replay_collects_results(recording_dir):
    results, summary = rb.replay(str(recording_dir), playback={"count": 2}, triangulate={"downsample": 2},
                                 smoothing={"tolerance": "fast"})
    assert summary.results == 2 and summary.failed == 0
    assert [r.index for r in results] == [0, 1]
    r = results[0]
    assert r.error == "" and r.raw_mesh.has_covariance
    assert isinstance(r.smoothed, rb.Mesh) and r.smoothed.num_vertices == r.raw_mesh.num_vertices
    assert r.decimated is not None and r.decimated.mesh.num_faces < r.raw_mesh.num_faces
    assert r.depth.depth_m.shape == (240, 320)
    with pytest.raises(TypeError, match="valid:"):
        rb.replay(str(recording_dir), smoothing={"bogus": 1})


def test_decimate_static_and_animated(trim_star):
    m = rb.read_mesh(str(trim_star))
    smoothed, _ = rb.smooth(m, noise=0.3, tolerance="fast")
    out, summary = rb.decimate(smoothed, target_faces=500)
    assert 0 < out.mesh.num_faces <= 500 and summary.num_patches == out.num_patches
    assert len(out.face_patch) == out.mesh.num_faces
    # The CLI's summary: sizes and the λ search.
    assert f"output: {out.mesh.num_faces} faces" in summary.brief_report()
    poses = [smoothed, rb.Mesh(smoothed.V * 1.5, smoothed.F)]
    outs, summary = rb.decimate_animated(poses, **{"lambda": 0.5})
    assert len(outs) == 2 and outs[0].face_patch == outs[1].face_patch
    with pytest.raises(TypeError, match="lambda"):
        rb.decimate(smoothed, lam=1.0)


def test_learn_prior_runs(trim_star):
    truth = rb.read_mesh(str(trim_star))
    rng = np.random.default_rng(3)
    noisy_mesh = rb.Mesh(truth.V + rng.normal(scale=1e-3, size=truth.V.shape), truth.F)
    noisy, _ = rb.make_generic_noisy_mesh(noisy_mesh, noise=0.3)
    prior, summary = rb.learn_prior([(noisy, truth)], method="interleaved", bump_search_sweeps=0, max_iterations=1,
                                   tolerance="fast")
    assert prior.theta.shape == (prior.num_knots,)
    assert summary["iterations"] >= 1
    for bad in (5, None, "ab", (noisy,), (noisy, truth, truth)):  # 5 and None raised "'int' object is not iterable"
        with pytest.raises(ValueError, match=r"each pair is \(noisy NoisyMesh, truth Mesh\)"):
            rb.learn_prior([bad])
    # The record is the CLI's: the method with its search, and the training error (it said the bare method, nan).
    assert prior.method.startswith("interleaved") and np.isfinite(prior.training_mse_le2)
    # A noisy mesh with fewer faces than its truth (the first ones the same) was accepted as the same connectivity.
    fewer = rb.NoisyMesh(noisy.V, noisy.F[:10], noisy.covariances)
    with pytest.raises(rb.Error, match="differ in connectivity"):
        rb.learn_prior([(fewer, truth)], bump_search_sweeps=0, tolerance="fast")


def test_array_fields_are_copies():
    # An array read from a field stays valid after the field is given an array of another size (it was a view of
    # the C++ buffer, which the assignment freed: it then showed other data).
    p = rb.LearnedPrior()
    p.theta = np.arange(16.0)
    theta = p.theta
    p.theta = np.zeros(4000)
    junk = [np.full(16, 7.0) for _ in range(100)]
    np.testing.assert_array_equal(theta, np.arange(16.0))
    r = rb.StereoRig()
    r.distortion_left = np.arange(5.0)
    d = r.distortion_left
    r.distortion_left = np.zeros(100000)
    junk += [np.full(5, 42.0) for _ in range(100)]
    np.testing.assert_array_equal(d, np.arange(5.0))
    k = r.K_left
    r.K_left = np.eye(3) * 5
    assert k[0, 0] == 1.0 and r.K_left[0, 0] == 5.0  # copies on read, as documented
    with pytest.raises(TypeError):
        r.K_left = np.eye(4)


def write_test_prior(path, prior_weight):
    p = rb.LearnedPrior()
    p.num_knots = 5
    theta = np.sqrt(np.linspace(0.0, 2.0, 5) ** 2 + p.epsilon_squared)
    theta[1:-1] *= 1.1  # the ends are the square root's (SplinePotential's contract)
    p.theta = theta
    p.prior_weight = prior_weight
    rb.write_learned_prior(str(path), p)
    return p


@pytest.mark.parametrize("prior_weight_flag", [None, 2.4])  # the learned prior's β, then an explicit one
def test_replay_same_bytes_as_the_cli_with_a_learned_prior(tmp_path, cli, recording_dir, prior_weight_flag):
    prior = tmp_path / "prior.yaml"
    write_test_prior(prior, prior_weight=1.5)
    flags = ["--count", "1", "--downsample", "2", "--tolerance", "fast", "--prior", str(prior), "--no-previews", "-q"]
    smoothing = {"tolerance": "fast", "prior": str(prior)}
    if prior_weight_flag is not None:
        flags += ["--prior-weight", str(prior_weight_flag)]
        smoothing["prior_weight"] = prior_weight_flag
    out = tmp_path / "cli"
    subprocess.run([str(cli), "replay", str(recording_dir), "--out", str(out), *flags], check=True,
                   stdout=subprocess.DEVNULL)
    results, summary = rb.replay(str(recording_dir), playback={"count": 1}, triangulate={"downsample": 2},
                                 smoothing=smoothing)
    assert summary.results == 1 and results[0].error == ""
    r = results[0]
    for folder, mesh, ext in [("raw", r.raw_mesh, "ply"), ("smoothed", r.smoothed, "ply"),
                              ("decimated", r.decimated, "obj")]:
        py_file = tmp_path / f"py_{folder}.{ext}"
        rb.write_mesh(str(py_file), mesh)
        assert py_file.read_bytes() == (out / folder / f"000000.{ext}").read_bytes(), folder
    # The learned prior changed the result (its β 1.5 unless 2.4 was given).
    plain, _ = rb.replay(str(recording_dir), playback={"count": 1}, triangulate={"downsample": 2},
                         smoothing={"tolerance": "fast"})
    assert not np.array_equal(plain[0].smoothed.V, r.smoothed.V)
    smoothing["prior"] = rb.read_learned_prior(str(prior))  # a LearnedPrior object gives the same
    again, _ = rb.replay(str(recording_dir), playback={"count": 1}, triangulate={"downsample": 2},
                         smoothing=smoothing)
    np.testing.assert_array_equal(again[0].smoothed.V, r.smoothed.V)


def test_replay_progress_exception_stops_the_run(recording_dir):
    seen = []

    def boom(fraction, stage):
        seen.append(stage)
        raise KeyError("stop the replay")

    options = dict(playback={"count": 3}, triangulate={"downsample": 4}, smoothing={"tolerance": "fast"},
                   decimate=False)
    with pytest.raises(KeyError, match="stop the replay"):
        rb.replay(str(recording_dir), progress=boom, **options)
    assert len(seen) == 1  # the first result's progress raised; the run was stopped there
    results, summary = rb.replay(str(recording_dir), progress=lambda f, s: None, **options)  # still usable
    assert summary.results == 3


def test_replay_releases_the_gil(recording_dir, ticks_during):
    (_, summary), during = ticks_during(
        lambda: rb.replay(str(recording_dir), playback={"count": 2}, triangulate={"downsample": 2},
                          smoothing={"tolerance": "fast"}))
    assert summary.results == 2
    assert len(during) >= 5


def test_replay_bad_input_is_a_clear_error(tmp_path, recording_dir):
    with pytest.raises(rb.Error, match="missing"):
        rb.replay(str(tmp_path / "missing"))
    with pytest.raises(rb.Error, match="missing"):
        rb.replay(tmp_path / "missing")  # a pathlib.Path is a folder too
    with pytest.raises(TypeError, match="recording must be a folder"):
        rb.replay(42)
    with pytest.raises(TypeError, match="rig must be a StereoRig or None, not str"):
        rb.replay(str(recording_dir), "rig.yaml")
    with pytest.raises(TypeError, match="smoothing must be a dict"):
        rb.replay(str(recording_dir), smoothing="fast")
    with pytest.raises(TypeError, match=r"replay\(smoothing=...\)\(\) got an unexpected keyword argument 'tol'"):
        rb.replay(str(recording_dir), smoothing={"tol": "fast"})
    with pytest.raises(rb.Error, match="prior"):
        rb.replay(str(recording_dir), smoothing={"prior": "nonsense"})
    with pytest.raises(rb.Error):
        rb.replay(str(recording_dir), smoothing={"prior": str(tmp_path / "missing.yaml")})


def test_replay_live_path_preset(recording_dir):
    # replay --live-path: drop-oldest queues, stereo every 2nd pixel, fast smoothing within a budget, no
    # decimation; a keyword given wins over the preset.
    results, summary = rb.replay(str(recording_dir), live_path=True, playback={"count": 3})
    assert results and summary.results == len(results)
    assert summary.results + summary.dropped + summary.failed == summary.frames_captured
    assert all(r.stereo_downsample == 2 and r.smoothed is not None and r.decimated is None for r in results)
    results, _ = rb.replay(str(recording_dir), live_path=True, stereo_downsample=1, playback={"count": 1})
    assert results and results[0].stereo_downsample == 1
    with pytest.raises(TypeError):
        rb.replay(str(recording_dir), live_path="yes please")


def test_replay_stops_on_ctrl_c(recording_dir, ctrl_c):
    sent = []

    def interrupt_once(fraction, stage):  # on the pipeline's sink thread: SIGINT as from Ctrl-C
        if not sent:
            sent.append(stage)
            os.kill(os.getpid(), signal.SIGINT)

    with pytest.raises(KeyboardInterrupt):
        rb.replay(str(recording_dir), progress=interrupt_once, playback={"count": 8, "repeats": 4},
                  triangulate={"downsample": 4}, smoothing={"tolerance": "fast"}, decimate=False)
    assert sent
