"""numpy -> Mesh / NoisyMesh: every layout copies exactly, bad values are a clear ValueError (never a crash)."""

import os
import subprocess
import sys

import numpy as np
import pytest

import rangebayes as rb

V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int32)


def grid(n):
    """An n x n vertex grid (2 (n-1)^2 faces) with random covariances."""
    rng = np.random.default_rng(7)
    u, v = np.meshgrid(np.arange(n, dtype=np.float64), np.arange(n, dtype=np.float64))
    verts = np.column_stack([u.ravel(), v.ravel(), rng.normal(size=n * n)])
    i = np.arange(n - 1)
    a = (i[:, None] * n + i[None, :]).ravel()
    faces = np.concatenate([np.column_stack([a, a + 1, a + n]), np.column_stack([a + 1, a + n + 1, a + n])])
    cov = rng.normal(size=(n * n, 3, 3))
    return verts, faces.astype(np.int32), cov


def test_every_layout_copies_exactly():
    verts, faces, cov = grid(400)  # 160k vertices: 3.8 MB of positions, 11.5 MB of covariances
    layouts_v = [verts, np.asfortranarray(verts), verts[::-1][::-1], np.ascontiguousarray(verts[::-1])[::-1],
                 verts.astype(">f8")]
    for vv in layouts_v:
        np.testing.assert_array_equal(rb.Mesh(vv, faces).V, verts)
    single = verts.astype(np.float32)  # other dtypes are converted (float32 -> float64 is exact)
    np.testing.assert_array_equal(rb.Mesh(single, faces).V, single.astype(np.float64))
    for ff in [faces, faces.astype(np.int64), faces.astype(">i4"), np.asfortranarray(faces), faces.astype(np.uint32)]:
        np.testing.assert_array_equal(rb.Mesh(verts, ff).F, faces)
    for cc in [cov, np.asfortranarray(cov), cov.transpose(0, 2, 1).copy().transpose(0, 2, 1), cov.astype(">f8"),
               cov[::-1][::-1]]:
        np.testing.assert_array_equal(rb.NoisyMesh(verts, faces, cc).covariances, cov)


def test_non_finite_values_are_rejected_with_the_row():
    verts, faces, cov = grid(400)
    for row in (0, 3, verts.shape[0] - 1):  # first, early and last row
        bad = verts.copy()
        bad[row, 1] = np.nan
        with pytest.raises(ValueError, match=rf"V: row {row} is not finite"):
            rb.Mesh(bad, faces)
    bad = verts.copy()
    bad[5, 2] = -np.inf
    with pytest.raises(ValueError, match="V: row 5 is not finite"):
        rb.Mesh(bad[::-1][::-1], faces)  # the strided path too
    c = cov.copy()
    c[100_000, 2, 0] = np.nan
    with pytest.raises(ValueError, match="covariances: matrix 100000 is not finite"):
        rb.NoisyMesh(verts, faces, c)
    with pytest.raises(ValueError, match="N: row 2 is not finite"):
        rb.Mesh(V, F, np.where(np.arange(4)[:, None] == 2, np.nan, V))
    noisy = rb.NoisyMesh(V, F)
    with pytest.raises(ValueError, match="pixel: row 1 is not finite"):
        noisy.pixel = np.array([[0, 0], [np.nan, 1], [2, 2], [3, 3]], dtype=np.float32)


def test_face_indices_and_counts_are_checked():
    with pytest.raises(ValueError, match=r"F: row 1 \[0 1 4\] has an index outside \[0, 4\)"):
        rb.Mesh(V, [[0, 2, 1], [0, 1, 4]])
    with pytest.raises(ValueError, match="outside"):
        rb.Mesh(V, F - 1)
    with pytest.raises(ValueError, match="covariances: 3 matrices for 4 vertices"):
        rb.NoisyMesh(V, F, np.broadcast_to(np.eye(3), (3, 3, 3)))
    with pytest.raises(ValueError, match="N: 2 normals for 4 vertices"):
        rb.Mesh(V, F, V[:2])
    m = rb.Mesh(V, F)
    with pytest.raises(ValueError, match="outside"):
        m.F = [[0, 1, 9]] * 4
    with pytest.raises(TypeError, match="expected an integer array"):
        rb.Mesh(V, F.astype(bool))
    with pytest.raises(TypeError, match="V: expected a real-valued array, got dtype <U8"):
        rb.Mesh("vertices", F)
    with pytest.raises(TypeError, match="V: expected a real-valued array, got dtype object"):
        rb.Mesh(object(), F)


def test_values_written_through_views_are_checked_before_library_calls(tmp_path):
    m = rb.Mesh(V, F)
    m.F[0, 0] = 1000  # views write straight into the C++ storage
    for call in (lambda: rb.smooth(m, noise=0.1), lambda: rb.decimate(m), lambda: rb.estimate_noise_level(m),
                 lambda: rb.write_mesh(str(tmp_path / "m.ply"), m)):
        with pytest.raises(ValueError, match="face 0 refers to vertex 1000 of 4"):
            call()
    n = rb.NoisyMesh(V, F, np.broadcast_to(np.eye(3), (4, 3, 3)))
    n.V[2, 0] = np.nan
    with pytest.raises(ValueError, match="smooth: vertex 2 is not finite"):
        rb.smooth(n)
    n.V[2, 0] = 0.0
    n.covariances[1, 1, 1] = np.inf
    with pytest.raises(ValueError, match="covariance of vertex 1 is not finite"):
        rb.smooth(n)


def test_empty_arrays():
    m = rb.Mesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int32))
    assert m.V.shape == (0, 3) and m.F.shape == (0, 3)
    n = rb.NoisyMesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64), np.zeros((0, 3, 3)))
    assert n.covariances.shape == (0, 3, 3)


def test_assignment_of_the_same_shape_is_in_place_and_keeps_views():
    verts, faces, cov = grid(50)
    n = rb.NoisyMesh(verts, faces, cov)
    V_view, F_view, C_view = n.V, n.F, n.covariances
    n.V = verts * 2.0
    n.F = faces[:, ::-1]
    n.covariances = cov * 3.0
    np.testing.assert_array_equal(V_view, verts * 2.0)  # the old views see the new values: same storage
    np.testing.assert_array_equal(F_view, faces[:, ::-1])
    np.testing.assert_array_equal(C_view, cov * 3.0)
    bad = verts.copy()
    bad[-1, 0] = np.nan
    with pytest.raises(ValueError, match=f"V: row {len(verts) - 1} is not finite"):
        n.V = bad
    np.testing.assert_array_equal(n.V, verts * 2.0)  # checked before writing: unchanged
    n.V = n.V[::-1]  # a view of the storage itself: copied through fresh storage, not overwritten in place
    np.testing.assert_array_equal(n.V, (verts * 2.0)[::-1])
    np.testing.assert_array_equal(V_view, (verts * 2.0)[::-1])
    # Storage with values keeps its size, so that no view can point into freed memory.
    with pytest.raises(ValueError, match=r"V: the storage has 2500 rows, the array 10.*build a new mesh"):
        n.V = verts[:10]
    with pytest.raises(ValueError, match="covariances: 3 matrices for 2500 vertices"):
        n.covariances = cov[:3]
    with pytest.raises(ValueError, match="covariances: the storage has 2500 rows"):
        n.covariances = None
    with pytest.raises(ValueError, match="mesh.V: the storage has 2500 rows"):
        n.mesh = rb.Mesh(V, F)
    m = rb.Mesh(V, F)
    m.N = V * 0.5  # empty (0, 3) normals take the vertex count
    np.testing.assert_array_equal(m.N, V * 0.5)
    plain = rb.NoisyMesh(V, F)
    plain.covariances = np.broadcast_to(np.eye(3), (4, 3, 3))  # no covariances yet: any count
    assert plain.has_covariance


@pytest.mark.parametrize("tunables, expected", [(None, "applied"),
                                                ("glibc.malloc.trim_threshold=1000000", "user tunables")])
def test_import_sets_malloc_as_the_cli_unless_the_user_did(tunables, expected):
    env = {k: v for k, v in os.environ.items() if k != "GLIBC_TUNABLES"}
    if tunables is not None:
        env["GLIBC_TUNABLES"] = tunables
    out = subprocess.run([sys.executable, "-c", "import rangebayes; print(rangebayes._rangebayes._malloc)"],
                         env=env, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == expected
