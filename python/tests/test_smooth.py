"""smooth(): the CLI's result byte for byte, keyword validation, errors, progress, the GIL."""

import json
import math
import os
import subprocess

import numpy as np
import pytest

import rangebayes as rb


def cli_smooth(cli, src, out, *flags):
    subprocess.run([str(cli), "smooth", str(src), str(out), "--quiet", *flags], check=True,
                   stdout=subprocess.DEVNULL)


@pytest.mark.parametrize(
    "flags, kwargs",
    [
        ([], {}),  # noise estimated, adaptive ε: the CLI's defaults
        (["--noise", "0.3", "--tolerance", "fast", "--no-adaptive-eps", "--prior-weight", "1.7", "--eps2", "0.001"],
         dict(noise=0.3, tolerance="fast", adaptive_epsilon=False, prior_weight=1.7, sqrt_epsilon_squared=1e-3)),
        (["--sigma", "0.004", "--prior", "cauchy", "--threads", "1"],
         dict(sigma=0.004, prior="cauchy", num_threads=1)),
    ],
)
def test_same_bytes_as_the_cli(tmp_path, cli, trim_star, flags, kwargs):
    cli_out = tmp_path / "cli.ply"
    cli_smooth(cli, trim_star, cli_out, *flags)
    mesh, summary = rb.smooth(rb.read_mesh(str(trim_star)), **kwargs)
    py_out = tmp_path / "py.ply"
    rb.write_mesh(str(py_out), mesh)
    assert py_out.read_bytes() == cli_out.read_bytes()
    assert summary.iterations > 0
    assert "iterations" in summary.brief_report()
    # The distance estimate the CLI prints ("distance: E - E* estimated ...").
    assert summary.remaining_decrease >= 0 and math.isfinite(summary.remaining_decrease)
    assert f"estimated {summary.remaining_decrease:.3g} " in summary.brief_report()


def test_file_covariances_are_used_like_the_cli(tmp_path, cli, trim_star):
    noisy, _ = rb.make_generic_noisy_mesh(rb.read_mesh(str(trim_star)), noise=0.3, across_ratio=3.0)
    src = tmp_path / "cov.ply"
    rb.write_mesh(str(src), noisy)
    cli_out = tmp_path / "cli.ply"
    cli_smooth(cli, src, cli_out, "--tolerance", "fast")
    mesh, summary = rb.smooth(rb.read_mesh(str(src)), tolerance="fast")
    assert summary.noise_model.from_file
    py_out = tmp_path / "py.ply"
    rb.write_mesh(str(py_out), mesh)
    assert py_out.read_bytes() == cli_out.read_bytes()


def test_result_arrays_and_defaults(trim_star):
    m = rb.read_mesh(str(trim_star))
    out, summary = rb.smooth(m, noise=0.3, tolerance="fast")
    assert out.V.shape == m.V.shape and out.V.dtype == np.float64
    np.testing.assert_array_equal(out.F, m.F)
    assert not summary.noise_model.from_file and summary.noise_model.generic.noise_edge_multiple == 0.3
    assert rb.SMOOTH_OPTIONS["adaptive_epsilon"] is True
    assert rb.SMOOTH_OPTIONS["tolerance"] == "default"


def test_estimated_noise_level_says_what_it_read(trim_star):
    # Gaussian noise (trim-star n3): a light tail (about 3.8), growth below 1.15, so k is the one-ring residual.
    _, summary = rb.make_generic_noisy_mesh(rb.read_mesh(str(trim_star)))
    assert summary.estimated
    e = summary.estimate
    assert 3.5 < e.tail < 4.5 and not e.raised_to_floor
    assert 1.0 < e.growth < 1.15
    assert summary.noise_edge_multiple == e.one_ring
    assert f"tail {e.tail:.3g}" in rb.smooth(rb.read_mesh(str(trim_star)), tolerance="fast")[1].noise_model.brief_report()


def test_keyword_validation(trim_star):
    m = rb.read_mesh(str(trim_star))
    with pytest.raises(TypeError, match=r"unexpected keyword argument 'max_iter'.*max_iterations"):
        rb.smooth(m, max_iter=3)
    with pytest.raises(TypeError, match="max_iterations: expected an int"):
        rb.smooth(m, max_iterations=2.5)
    with pytest.raises(TypeError, match="adaptive_epsilon: expected a bool"):
        rb.smooth(m, adaptive_epsilon=1)
    with pytest.raises(ValueError, match="tolerance: 'slow' is not one of 'fast', 'default', 'tight'"):
        rb.smooth(m, tolerance="slow")
    with pytest.raises(rb.Error, match="prior_weight"):
        rb.smooth(m, prior_weight=-1.0)  # range checks are the library's own (SmoothOptions::Check)
    with pytest.raises(ValueError, match="not both"):
        rb.smooth(m, noise=0.3, sigma=0.1)
    for name in ("noise", "sigma"):  # None estimates the noise; a NaN is not taken for None
        with pytest.raises(ValueError, match=name + ": nan is not a value"):
            rb.smooth(m, **{name: float("nan")})
        with pytest.raises(ValueError, match=name + ": nan is not a value"):
            rb.make_generic_noisy_mesh(m, **{name: np.nan})
    with pytest.raises(rb.Error):
        rb.smooth(m, prior="nonsense")
    tetra = rb.Mesh([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    for name in rb.SMOOTH_OPTIONS:  # every exposed field is accepted with its own default
        rb.smooth(tetra, noise=0.1, **{name: rb.SMOOTH_OPTIONS[name]})


def test_progress_callback_and_its_exception(trim_star):
    m = rb.read_mesh(str(trim_star))
    calls = []
    rb.smooth(m, noise=0.3, tolerance="fast", progress=lambda f, stage: calls.append((f, stage)))
    assert calls and all(0.0 <= f <= 1.0 for f, _ in calls)

    def boom(f, stage):
        raise KeyError("stop here")

    with pytest.raises(KeyError, match="stop here"):
        rb.smooth(m, noise=0.3, tolerance="fast", progress=boom)


CTRL_C_CHILD = """
import sys
import numpy as np
import rangebayes as rb
n = 300
u, v = np.meshgrid(np.arange(n, dtype=np.float64), np.arange(n, dtype=np.float64))
V = np.stack([u.ravel(), v.ravel(), np.random.default_rng(1).normal(0.0, 0.3, n * n)], axis=1)
idx = np.arange(n * n, dtype=np.int32).reshape(n, n)
a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel()
mesh = rb.Mesh(V, np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)]))
print("smoothing", flush=True)
try:
    # Uninterrupted this runs until its 600 s limit (the gap tolerance is out of reach).
    rb.smooth(mesh, noise=0.5, tolerance="tight", gap_tolerance=1e-14, max_iterations=10000000,
              time_limit_s=600, adaptive_epsilon=False)
except KeyboardInterrupt:
    sys.exit(3)
sys.exit(0)
"""


def cpu_seconds(pid):
    """User + system CPU time of process `pid` (all its threads), from /proc."""
    fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def test_ctrl_c_stops_smooth_without_a_progress_function(ctrl_c):
    # SIGINT (Ctrl-C) to a process inside smooth() with no progress function: KeyboardInterrupt from inside the
    # call. Before the fix the signal waited for the solve to end (600 s here), so the 120 s guard would fail.
    # The signal goes once the child has spent 0.3 s of CPU after printing "smoothing": the one thing it does after
    # that line is the call, so it is inside smooth() then (a signal before the call would also exit 3, from the
    # Python code, without testing anything).
    import signal
    import sys
    import time

    child = subprocess.Popen([sys.executable, "-c", CTRL_C_CHILD], stdout=subprocess.PIPE, text=True,
                             env=dict(os.environ), preexec_fn=ctrl_c)
    try:
        assert child.stdout.readline().strip() == "smoothing"
        start, deadline = cpu_seconds(child.pid), time.monotonic() + 60
        while cpu_seconds(child.pid) - start < 0.3:
            assert time.monotonic() < deadline and child.poll() is None
            time.sleep(0.01)
        child.send_signal(signal.SIGINT)
        assert child.wait(timeout=120) == 3
    finally:
        child.kill()
        child.wait()


def test_gil_is_released_during_smooth(trim_star, ticks_during):
    m = rb.read_mesh(str(trim_star))
    (_, summary), during = ticks_during(lambda: rb.smooth(m, noise=0.3, adaptive_epsilon=False, num_threads=1))
    # With the GIL held the thread could not tick at all during the call.
    assert summary.iterations > 10
    assert len(during) >= 5, len(during)


def test_learned_prior_file_and_object(tmp_path, trim_star):
    p = rb.LearnedPrior()
    p.num_knots = 5
    t = np.linspace(0.0, 2.0, 5)
    p.theta = np.sqrt(t**2 + p.epsilon_squared)
    p.prior_weight = 1.5
    path = str(tmp_path / "prior.yaml")
    rb.write_learned_prior(path, p)
    back = rb.read_learned_prior(path)
    np.testing.assert_allclose(back.theta, p.theta, rtol=1e-12)
    m = rb.read_mesh(str(trim_star))
    a, _ = rb.smooth(m, noise=0.3, prior=path, tolerance="fast")
    b, _ = rb.smooth(m, noise=0.3, prior=back, tolerance="fast")
    np.testing.assert_array_equal(a.V, b.V)
    c, _ = rb.smooth(m, noise=0.3, prior=tmp_path / "prior.yaml", tolerance="fast")  # a pathlib.Path too
    np.testing.assert_array_equal(a.V, c.V)


def test_evaluate_is_what_eval_prints(cli, root, tmp_path):
    """evaluate(): the keys and values of `rangebayes eval`'s JSON line, with and without the normal error."""
    meshes = root / "tests" / "data" / "meshes"
    truth, noisy = meshes / "block_gt.obj", meshes / "block_noisy_gauss0.4.obj"
    for flags, kwargs in (([], {}), (["--surface-only"], dict(surface_only=True))):
        line = subprocess.run([str(cli), "eval", str(truth), str(noisy), *flags], check=True,
                              capture_output=True, text=True).stdout
        expected = json.loads(line)
        got = rb.evaluate(rb.read_mesh(truth), rb.read_mesh(noisy), **kwargs)  # GT, RESULT as the CLI takes them
        assert sorted(got) == sorted(expected)
        for key, value in expected.items():
            assert got[key] == pytest.approx(value, rel=1e-15, abs=0), key
        assert ("mae_deg" in got) == (not flags)
    assert isinstance(got["faces"], int) and got["faces"] == 17550
    other = rb.read_mesh(meshes / "fandisk_gt.obj")
    with pytest.raises(ValueError, match="surface_only=True"):
        rb.evaluate(other, rb.read_mesh(noisy))
    assert rb.evaluate(other, rb.read_mesh(noisy), surface_only=True)["hausdorff"] > 0
    with pytest.raises(TypeError, match="evaluate: expected a Mesh or NoisyMesh"):
        rb.evaluate(other, "a.ply")
    points = rb.Mesh(np.zeros((3, 3)), np.zeros((0, 3), dtype=np.int32))
    with pytest.raises(rb.Error, match=r"evaluate: result: no faces \(eval compares surfaces\)"):
        rb.evaluate(other, points, surface_only=True)
    (tmp_path / "nan.obj").write_text("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    with pytest.raises(ValueError, match="evaluate: vertex 0 is not finite"):
        rb.evaluate(other, rb.read_mesh(tmp_path / "nan.obj"), surface_only=True)


def test_summary_reports_the_work_before_the_final_solve(cli, tmp_path, trim_star):
    m = rb.read_mesh(str(trim_star))
    _, plain = rb.smooth(m, noise=0.3, tolerance="fast")
    assert plain.continuation_stages == 0 and plain.levels == 1 and plain.coarse_work == 0
    # Continuation asked for on a generic mesh runs (with the global ε) and is in the report as the CLI prints it.
    mesh, staged = rb.smooth(m, noise=0.3, tolerance="fast", epsilon_continuation_stages=2)
    assert staged.continuation_stages == 2 and not staged.adaptive_epsilon_used
    assert staged.coarse_work > 0
    assert "earlier:    2 eps continuation stage(s): " in staged.brief_report()
    cli_out = tmp_path / "cli.ply"
    cli_smooth(cli, trim_star, cli_out, "--noise", "0.3", "--tolerance", "fast", "--continuation", "2")
    py_out = tmp_path / "py.ply"
    rb.write_mesh(str(py_out), mesh)
    assert py_out.read_bytes() == cli_out.read_bytes()
