"""Meshes from and to numpy and files: dtypes, shapes, strides, views, copies, errors, Open3D."""

import re
import warnings

import numpy as np
import pytest

import rangebayes as rb

V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int32)


def test_mesh_round_trip_dtype_shape_strides():
    m = rb.Mesh(V, F)
    assert m.V.dtype == np.float64 and m.V.shape == (4, 3) and m.V.strides == (24, 8)
    assert m.F.dtype == np.int32 and m.F.shape == (4, 3) and m.F.strides == (12, 4)
    assert m.N.shape == (0, 3)
    np.testing.assert_array_equal(m.V, V)
    np.testing.assert_array_equal(m.F, F)
    assert m.num_vertices == 4 and m.num_faces == 4


def test_mesh_views_share_storage_and_constructor_copies():
    src = V.copy()
    m = rb.Mesh(src, F)
    src[0, 0] = 42.0
    assert m.V[0, 0] == 0.0  # the constructor copied
    view = m.V
    view[1, 1] = 7.0
    assert m.V[1, 1] == 7.0  # reading gives a view of the C++ storage
    assert not view.flags.owndata


def test_non_contiguous_and_other_dtypes():
    big = np.zeros((4, 6))
    big[:, ::2] = V
    strided = big[:, ::2]
    assert not strided.flags.c_contiguous
    fortran = np.asfortranarray(V)
    faces64 = F.astype(np.int64)
    for vv in (strided, fortran, V.astype(np.float32), V.astype(np.int64)):
        m = rb.Mesh(vv, faces64[::1])
        np.testing.assert_array_equal(m.V, V)
        np.testing.assert_array_equal(m.F, F)
    m = rb.Mesh(V.tolist(), F.T.copy().T)  # lists and transposed views convert too
    np.testing.assert_array_equal(m.F, F)


def test_bad_arrays_raise():
    with pytest.raises(ValueError, match=r"shape \(n, 3\)"):
        rb.Mesh(V[:, :2], F)
    with pytest.raises(TypeError, match="integer"):
        rb.Mesh(V, F.astype(np.float64))
    with pytest.raises(ValueError, match=r"outside \[0, 4\)"):
        rb.Mesh(V, F.astype(np.int64) + 2**40)  # int64 indices beyond int32 are not wrapped around
    with pytest.raises(TypeError, match="real"):
        rb.Mesh(V.astype(np.complex128), F)


def test_noisy_mesh_covariances_round_trip():
    rng = np.random.default_rng(1)
    A = rng.normal(size=(4, 3, 3))
    cov = A @ A.transpose(0, 2, 1) + np.eye(3)
    cov[0, 0, 1] = 0.25  # not symmetric: the layout must be exact, not just symmetric
    n = rb.NoisyMesh(V, F, cov)
    assert n.has_covariance
    out = n.covariances
    assert out.shape == (4, 3, 3) and out.dtype == np.float64
    np.testing.assert_array_equal(out, cov)
    out[2, 1, 0] = -3.0
    assert n.covariances[2, 1, 0] == -3.0  # a view
    n2 = rb.NoisyMesh(rb.Mesh(V, F), cov[:, ::1, ::1].transpose(0, 2, 1))
    np.testing.assert_array_equal(n2.covariances, cov.transpose(0, 2, 1))
    assert not rb.NoisyMesh(V, F).has_covariance


def test_files_round_trip(tmp_path, trim_star):
    m = rb.read_mesh(str(trim_star))
    assert isinstance(m, rb.Mesh)
    for ext in ("ply", "obj", "off"):
        path = str(tmp_path / f"m.{ext}")
        rb.write_mesh(path, m)
        back = rb.read_mesh(path)
        np.testing.assert_array_equal(back.F, m.F)
        np.testing.assert_allclose(back.V, m.V, rtol=0, atol=1e-12 if ext == "ply" else 1e-6)
    noisy, _ = rb.make_generic_noisy_mesh(m, noise=0.3, across_ratio=2.0)
    path = str(tmp_path / "noisy.ply")
    rb.write_mesh(path, noisy)
    back = rb.read_mesh(path)
    assert isinstance(back, rb.NoisyMesh)
    r, c = np.triu_indices(3)  # PLY stores the upper triangle
    np.testing.assert_array_equal(back.covariances[:, r, c], noisy.covariances[:, r, c])


def test_reader_notices_are_warnings(tmp_path):
    """What the reader left out or changed, which the CLI prints as a notice, is a UserWarning."""
    (tmp_path / "quad.obj").write_text("v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n")
    notice = "^" + re.escape(f"{tmp_path / 'quad.obj'}: 1 polygons with more than 3 vertices were fan-triangulated")
    with pytest.warns(UserWarning, match=notice):
        assert rb.read_mesh(tmp_path / "quad.obj").num_faces == 2
    with pytest.warns(UserWarning, match=notice):
        rb.read_noisy_mesh(tmp_path / "quad.obj")


def test_range_grid_scans_read_as_the_cli_reads_them(root, cli, tmp_path):
    piece = root / "tests" / "data" / "scans" / "bun000_piece.ply"
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a range grid's triangulation is no repair: no warning
        scan = rb.read_mesh(str(piece))
    assert isinstance(scan, rb.NoisyMesh) and scan.has_covariance and scan.num_faces > 10000
    np.testing.assert_array_equal(rb.read_noisy_mesh(str(piece)).mesh.F, scan.mesh.F)
    import subprocess
    subprocess.run([str(cli), "convert", str(piece), str(tmp_path / "cli.ply"), "-q"], check=True)
    from_cli = rb.read_mesh(str(tmp_path / "cli.ply"))
    np.testing.assert_array_equal(from_cli.mesh.F, scan.mesh.F)
    np.testing.assert_array_equal(from_cli.mesh.V, scan.mesh.V)


def test_errors_are_rangebayes_error_with_the_message(tmp_path):
    assert issubclass(rb.Error, RuntimeError)
    bad = tmp_path / "bad.off"
    bad.write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n")
    with pytest.raises(rb.Error, match="bad.off"):
        rb.read_mesh(str(bad))
    with pytest.raises(rb.Error, match="missing.obj"):
        rb.read_mesh(str(tmp_path / "missing.obj"))


def test_open3d_interop():
    o3d = pytest.importorskip("open3d")
    m = rb.Mesh(V, F)
    om = rb.to_open3d(m)
    assert isinstance(om, o3d.geometry.TriangleMesh)
    np.testing.assert_array_equal(np.asarray(om.triangles), F)
    back = rb.from_open3d(om)
    np.testing.assert_array_equal(back.V, V)
    np.testing.assert_array_equal(back.F, F)


def test_paths_may_be_pathlib(tmp_path, recording_dir):
    # Every file or folder argument takes a str or any os.PathLike.
    m = rb.Mesh(V, F)
    rb.write_mesh(tmp_path / "m.ply", m)
    np.testing.assert_array_equal(rb.read_mesh(tmp_path / "m.ply").F, F)
    np.testing.assert_array_equal(rb.read_noisy_mesh(tmp_path / "m.ply").mesh.F, F)
    rig = rb.read_rig(recording_dir / "rig.yaml")
    rb.write_rig(tmp_path / "rig.yaml", rig)
    assert rb.read_rig(tmp_path / "rig.yaml").width == rig.width
    model = rb.DisparityNoiseModel()
    rb.write_noise_model(tmp_path / "noise.yaml", model)
    assert rb.read_noise_model(tmp_path / "noise.yaml").sigma_px == model.sigma_px
    assert len(rb.open_recording(recording_dir)) == 8
    with pytest.raises(TypeError):
        rb.read_mesh(42)
    with pytest.raises(TypeError, match="to_open3d: expected a Mesh"):
        rb.to_open3d(42)  # said so before open3d is imported
