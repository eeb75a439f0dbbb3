"""What a script passes as numpy gives it usually does: float64 maps, boolean masks, the CLI's matcher names,
both constructors of NoisyMesh; and what the module would take silently or let crash another library is refused
(session 34's review of the module as a researcher uses it)."""

import importlib.util

import numpy as np
import pytest

import rangebayes as rb


def test_float64_disparity_and_bool_mask(recording_dir):
    rec = rb.open_recording(str(recording_dir))
    st = rb.stereo(rec.rig, rec[0].left, rec[0].right, matcher="block", num_disparities=64)
    as32 = rb.depth_from_disparity(st.disparity_px, st.sigma_disparity_px, st.intrinsics, st.baseline_m)
    as64 = rb.depth_from_disparity(st.disparity_px.astype(np.float64), st.sigma_disparity_px.astype(np.float64),
                                   st.intrinsics, st.baseline_m)
    np.testing.assert_array_equal(as64.depth_m, as32.depth_m)
    d = st.disparity_px
    gt = np.where(np.isfinite(d), d + 0.3, np.nan).astype(np.float32)
    left_half = np.zeros(d.shape, bool)
    left_half[:, : d.shape[1] // 2] = True
    by_bool = rb.evaluate_disparity(d, gt, left_half)
    by_uint8 = rb.evaluate_disparity(d, gt, left_half.astype(np.uint8))
    assert by_bool.evaluated_pixels == by_uint8.evaluated_pixels < np.isfinite(gt).sum()
    assert by_bool.brief_report() == by_uint8.brief_report()


def test_block_is_spacetime_on_one_pair(recording_dir):
    rec = rb.open_recording(str(recording_dir))
    f = rec[0]
    block = rb.match(f.left, f.right, "block", num_disparities=64)
    spacetime = rb.match(f.left, f.right, "spacetime", num_disparities=64)
    np.testing.assert_array_equal(block["disparity_px"], spacetime["disparity_px"])
    with pytest.raises(ValueError, match="matcher must be 'sgbm', 'spacetime' or 'block'"):
        rb.match(f.left, f.right, "bm")


def test_noisy_mesh_from_a_mesh_by_keyword(trim_star):
    mesh = rb.read_mesh(trim_star)
    noisy = rb.NoisyMesh(mesh=mesh)
    np.testing.assert_array_equal(noisy.V, mesh.V)


def test_decimate_refuses_lambda_with_target_faces(trim_star):
    mesh = rb.read_mesh(trim_star)
    with pytest.raises(ValueError, match="give lambda or target_faces, not both"):
        rb.decimate(mesh, **{"lambda": 2.0, "target_faces": 500})


@pytest.mark.skipif(importlib.util.find_spec("open3d") is None, reason="python3-open3d not installed")
def test_to_open3d_refuses_a_face_index_out_of_range(trim_star):
    mesh = rb.read_mesh(trim_star)
    mesh.F[7, 1] = mesh.num_vertices  # through the writable view
    # Open3D does not check its triangles: its next computation would crash the interpreter.
    with pytest.raises(ValueError, match=f"to_open3d: face 7 uses vertex .* but there are {mesh.num_vertices}"):
        rb.to_open3d(mesh)
    with pytest.raises(TypeError, match="from_open3d: expected an open3d.geometry.TriangleMesh"):
        rb.from_open3d(None)


def test_integer_keywords_out_of_range_name_themselves(trim_star):
    mesh = rb.read_mesh(trim_star)
    # pybind11 alone says "Unable to cast Python instance to C++ type", without the keyword.
    with pytest.raises(ValueError, match=r"max_iterations: 2147483648 is out of range \[.*, 2147483647\]"):
        rb.smooth(mesh, max_iterations=2**31)
    with pytest.raises(ValueError, match="target_faces: 4294967296 is out of range"):
        rb.decimate(mesh, target_faces=2**32)
