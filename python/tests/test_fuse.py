"""fuse(): many scans to one model, the same result as `rangebayes fuse`."""

import subprocess

import numpy as np
import pytest

import rangebayes as rb


@pytest.fixture(scope="module")
def pieces(root):
    d = root / "tests" / "data" / "scans"
    return [d / "bun000_piece.ply", d / "bun045_piece.ply"], d / "pieces.conf"


def read_pose_file(path):
    """bun.conf lines 'bmesh FILE tx ty tz qx qy qz qw' as {FILE: 4x4 world_from_scan}."""
    out = {}
    for line in path.read_text().splitlines():
        parts = line.split()
        if len(parts) != 9 or parts[0] != "bmesh":
            continue
        t = np.array([float(x) for x in parts[2:5]])
        x, y, z, w = (float(v) for v in parts[5:9])
        r = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                      [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                      [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
        m = np.eye(4)
        m[:3, :3], m[:3, 3] = r.T, t  # the file's quaternion is the conjugate of world_from_scan's rotation
        out[parts[1]] = m
    return out


@pytest.mark.parametrize("flags, kwargs", [
    ([], {}),
    (["--no-align", "--smooth", "--decimate"], dict(align=False, smooth=True, decimate=True)),
])
def test_same_model_and_poses_as_the_cli(tmp_path, cli, pieces, flags, kwargs):
    scans, conf = pieces
    out = tmp_path / "cli"
    subprocess.run([str(cli), "fuse", *map(str, scans), "--poses", str(conf), "--out", str(out), "-q", *flags],
                   check=True, capture_output=True)
    model, poses, summary = rb.fuse(scans, conf, **kwargs)
    rb.write_mesh(tmp_path / "py.ply", model)
    assert (tmp_path / "py.ply").read_bytes() == (out / "fused.ply").read_bytes()
    assert summary.pair_report == (out / "report.txt").read_text()
    cli_poses = read_pose_file(out / "poses.conf")
    assert poses.shape == (2, 4, 4)
    for k, scan in enumerate(scans):
        np.testing.assert_allclose(poses[k], cli_poses[scan.name], rtol=0, atol=1e-12)  # 17 digits in the file
    assert len(summary.smoothing) == (2 if kwargs.get("smooth") else 0)
    assert (summary.decimation is not None) == bool(kwargs.get("decimate"))
    assert summary.fusion.faces == (model.num_faces if not kwargs.get("decimate") else summary.fusion.faces)
    assert [p["a"] for p in summary.registration.pairs] == [0, 1]


def test_poses_as_matrices_and_meshes_as_scans(tmp_path, cli, pieces):
    """Scans given as NoisyMesh objects with 4x4 poses: the model `fuse` makes of the same meshes as files."""
    scans, conf = pieces
    matrices = read_pose_file(conf)
    meshes = [rb.read_mesh(s) for s in scans]  # range grids triangulated, with their covariances
    files = []
    for k, mesh in enumerate(meshes):
        files.append(tmp_path / f"mesh{k}.ply")
        rb.write_mesh(files[-1], mesh)
    (tmp_path / "meshes.conf").write_text(
        conf.read_text().replace("bun000_piece.ply", "mesh0.ply").replace("bun045_piece.ply", "mesh1.ply"))
    subprocess.run([str(cli), "fuse", *map(str, files), "--poses", str(tmp_path / "meshes.conf"), "--no-align",
                    "--out", str(tmp_path / "cli"), "-q"], check=True, capture_output=True)
    poses = np.stack([matrices[s.name] for s in scans])
    model, placed, summary = rb.fuse(meshes, poses, align=False)
    np.testing.assert_array_equal(placed, poses)  # align=False keeps the given poses
    cli_model = rb.read_mesh(tmp_path / "cli" / "fused.ply")
    assert model.num_faces > 5000
    # The same surface: the CLI renormalises the pose file's 6-digit quaternions and these matrices are not, which
    # moves marching cubes' output a little.
    assert rb.evaluate(cli_model, model, surface_only=True)["hausdorff"] < 1e-5
    assert summary.pair_report.splitlines()[1].startswith("scan 0 scan 1 ")
    stages = []
    rb.fuse(meshes, poses, align=False, smooth=True, smoothing={"tolerance": "fast"},
            progress=lambda fraction, stage: stages.append(stage))
    assert {"smoothing scan 0", "smoothing scan 1"} <= set(stages)


def test_bad_input_is_named(pieces, tmp_path):
    scans, conf = pieces
    with pytest.raises(rb.Error, match="the given poses do not align them"):
        rb.fuse(scans, align=False)  # identity poses, 45 degrees apart
    with pytest.raises(rb.Error, match="alignment needs at least two scans"):
        rb.fuse(scans[:1])
    with pytest.raises(TypeError, match="unexpected keyword argument 'voxel'"):
        rb.fuse(scans, conf, voxel=0.001)
    with pytest.raises(TypeError, match=r"fuse\(fusion=...\).*voxl"):
        rb.fuse(scans, conf, fusion={"voxl": 0.001})
    with pytest.raises(ValueError, match=r"poses\[1\]: not a rigid motion"):
        rb.fuse(scans, [np.eye(4), 2 * np.eye(4)])
    with pytest.raises(ValueError, match="1 poses for 2 scans"):
        rb.fuse(scans, [np.eye(4)])
    with pytest.raises(ValueError, match=r"poses\[0\]: expected a 4x4 matrix"):
        rb.fuse(scans, [np.eye(3), np.eye(4)])
    with pytest.raises(ValueError, match="every scan given as a path"):
        rb.fuse([rb.read_mesh(scans[0]), scans[1]], conf)
    with pytest.raises(TypeError, match="scans must be a list of paths or meshes"):
        rb.fuse(str(scans[0]))
    with pytest.raises(TypeError, match="poses must be None, a pose file or a list of 4x4 matrices"):
        rb.fuse(scans, 5)
    from_generator, _, _ = rb.fuse((s for s in scans), conf, align=False)  # any iterable of scans
    assert from_generator.num_faces > 5000
    with pytest.raises(rb.Error, match="not found|No such file"):
        rb.fuse([scans[0], tmp_path / "missing.ply"], align=False)
    with pytest.raises(rb.Error, match="voxel_size"):
        rb.fuse(scans, conf, fusion={"voxel_size": -1.0})


def test_progress_that_raises_stops_fuse(pieces):
    scans, conf = pieces

    def stop(fraction, stage):
        raise KeyError("stop here")

    with pytest.raises(KeyError, match="stop here"):
        rb.fuse(scans, conf, align=False, smooth=True, progress=stop)
    with pytest.raises(KeyError, match="stop here"):  # alignment reports too
        rb.fuse(scans, conf, progress=stop)
