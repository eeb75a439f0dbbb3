"""render() and write_png(): the pictures the CLI's --png options draw."""

import subprocess

import numpy as np
import pytest

import rangebayes as rb


def read_png(path):
    import matplotlib.image

    return np.round(matplotlib.image.imread(str(path))[:, :, :3] * 255).astype(np.uint8)


def test_the_cli_before_after_picture(tmp_path, cli, trim_star):
    """`smooth --png` draws noisy | smoothed side by side (8 px apart) in the noisy mesh's framing."""
    subprocess.run([str(cli), "smooth", str(trim_star), str(tmp_path / "out.ply"), "--noise", "0.3", "--png",
                    str(tmp_path / "cli.png"), "-q"], check=True, capture_output=True)
    noisy = rb.read_mesh(trim_star)
    smoothed, _ = rb.smooth(noisy, noise=0.3)
    options = dict(width_px=640, height_px=640, view_direction=(0, 0, -1))
    before = rb.render(noisy, **options)
    after = rb.render(smoothed, frame_like=noisy, **options)
    assert before.shape == (640, 640, 3) and before.dtype == np.uint8
    cli_picture = read_png(tmp_path / "cli.png")
    np.testing.assert_array_equal(cli_picture[:, :640], before)
    np.testing.assert_array_equal(cli_picture[:, 648:], after)
    rb.write_png(tmp_path / "py.png", np.concatenate([before, after], axis=1))
    np.testing.assert_array_equal(read_png(tmp_path / "py.png"), np.concatenate([before, after], axis=1))
    # A decimated mesh shaded with its patch normal fields.
    decimated, _ = rb.decimate(smoothed, target_faces=300)
    flat = rb.render(decimated, frame_like=noisy)
    smooth = rb.render(decimated, frame_like=noisy, shading="smooth")
    assert (flat != smooth).any()


def test_bad_input(tmp_path, trim_star):
    mesh = rb.read_mesh(trim_star)
    with pytest.raises(rb.Error, match="view_direction must be nonzero"):
        rb.render(mesh, view_direction=(0, 0, 0))
    with pytest.raises(ValueError, match="up: expected three numbers, got 2"):
        rb.render(mesh, up=(1, 2))
    with pytest.raises(ValueError, match="background: not finite"):
        rb.render(mesh, background=(1, float("nan"), 1))
    with pytest.raises(ValueError, match="'phong' is not one of 'flat', 'smooth'"):
        rb.render(mesh, shading="phong")
    with pytest.raises(rb.Error, match="width_px 0"):
        rb.render(mesh, width_px=0)
    with pytest.raises(TypeError, match="render: expected a Mesh or NoisyMesh"):
        rb.render("mesh.ply")
    with pytest.raises(TypeError, match=r"write_png: expected an \(h, w, 3\) uint8 RGB array"):
        rb.write_png(tmp_path / "x.png", np.zeros((4, 4, 3)))
    with pytest.raises(rb.Error, match="no/x.png: cannot create: No such file or directory"):
        rb.write_png(tmp_path / "no" / "x.png", np.zeros((4, 4, 3), np.uint8))
