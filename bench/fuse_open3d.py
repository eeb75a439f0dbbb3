#!/usr/bin/python3
"""Open3D peer of bench_fuse: multiway registration (pairwise point-to-plane ICP coarse to fine, pose graph with
uncertain loop-closure edges, Levenberg-Marquardt) and ScalableTSDFVolume, on the scans bench_fuse wrote.

  /usr/bin/python3 bench/fuse_open3d.py OUT SEED [VOXEL_M]

Reads OUT/bunXXX.ply (each scan's vertices, normals and triangles in its own frame, as bench_fuse bunny writes
them) and OUT/start_seedSEED.conf (the same perturbed start as ours); writes OUT/open3d_seedSEED.conf and
OUT/open3d_fused_seedSEED.ply. Score them with `bench_fuse score`. Open3D's TSDF integrates depth images: each
scan is projected into a virtual pinhole camera 0.5 m in front of it (on its sensor side, +z of the scan frame,
looking along -z), one pixel per point, focal length chosen so a pixel is 0.7 mm at the object.
"""
import os
import sys
import time

import numpy as np
import open3d as o3d

NAMES = ["bun000", "bun045", "bun090", "bun180", "bun270", "bun315", "chin", "ear_back", "top2", "top3"]


def quat_to_R(x, y, z, w):
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def read_conf(path):
    poses = {}
    for line in open(path):
        w = line.split()
        if w and w[0] == "bmesh":
            t = np.array([float(v) for v in w[2:5]])
            q = [float(v) for v in w[5:9]]
            T = np.eye(4)
            T[:3, :3] = quat_to_R(*q).T  # p_world = R(q)^T p + t
            T[:3, 3] = t
            poses[w[1].replace(".ply", "")] = T
    return poses


def write_conf(path, poses):
    with open(path, "w") as f:
        for name in NAMES:
            T = poses[name]
            Rq = T[:3, :3].T
            q = o3d.geometry.get_rotation_matrix_from_quaternion  # noqa: F841 (kept for clarity)
            # quaternion of Rq (x, y, z, w)
            m = Rq
            tr = np.trace(m)
            if tr > 0:
                s = 0.5 / np.sqrt(tr + 1.0)
                w, x, y, z = 0.25 / s, (m[2, 1] - m[1, 2]) * s, (m[0, 2] - m[2, 0]) * s, (m[1, 0] - m[0, 1]) * s
            else:
                i = np.argmax(np.diag(m))
                if i == 0:
                    s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
                    w, x, y, z = (m[2, 1] - m[1, 2]) / s, 0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s
                elif i == 1:
                    s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
                    w, x, y, z = (m[0, 2] - m[2, 0]) / s, (m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s
                else:
                    s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
                    w, x, y, z = (m[1, 0] - m[0, 1]) / s, (m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s
            t = T[:3, 3]
            f.write("bmesh %s.ply %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n" % (name, t[0], t[1], t[2], x, y, z, w))


def pairwise(source, target, init, voxel):
    result = None
    T = init
    for scale, iters in ((4.0, 60), (2.0, 40), (1.0, 30)):
        reg = o3d.pipelines.registration.registration_icp(
            source, target, scale * voxel * 1.5, T,
            o3d.pipelines.registration.TransformationEstimationPointToPlane(),
            o3d.pipelines.registration.ICPConvergenceCriteria(max_iteration=iters))
        T = reg.transformation
        result = reg
    info = o3d.pipelines.registration.get_information_matrix_from_point_clouds(source, target, voxel * 1.5, T)
    return T, info, result.fitness


def main():
    out, seed = sys.argv[1], int(sys.argv[2])
    voxel = float(sys.argv[3]) if len(sys.argv) > 3 else 0.001
    start = read_conf(os.path.join(out, "start_seed%d.conf" % seed))
    t0, c0 = time.time(), time.process_time()
    clouds, meshes = [], []
    for name in NAMES:
        m = o3d.io.read_triangle_mesh(os.path.join(out, name + ".ply"))
        meshes.append(m)
        pc = o3d.geometry.PointCloud(m.vertices)
        pc = pc.voxel_down_sample(voxel)
        pc.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=voxel * 3, max_nn=30))
        pc.orient_normals_towards_camera_location(np.array([0.0, 0.0, 1.0]))
        clouds.append(pc)
    # Multiway registration (Open3D's documented recipe), with the perturbed poses as the initial guess.
    graph = o3d.pipelines.registration.PoseGraph()
    inv0 = np.linalg.inv(start[NAMES[0]])
    world = [inv0 @ start[n] for n in NAMES]  # bun000 at the identity
    for k in range(len(NAMES)):
        graph.nodes.append(o3d.pipelines.registration.PoseGraphNode(world[k]))
    for i in range(len(NAMES)):
        for j in range(i + 1, len(NAMES)):
            init = np.linalg.inv(world[j]) @ world[i]  # j_from_i
            T, info, fitness = pairwise(clouds[i], clouds[j], init, voxel)
            if fitness < 0.05:
                continue
            graph.edges.append(o3d.pipelines.registration.PoseGraphEdge(i, j, T, info, uncertain=(j != i + 1)))
    option = o3d.pipelines.registration.GlobalOptimizationOption(
        max_correspondence_distance=voxel * 1.5, edge_prune_threshold=0.25, reference_node=0)
    o3d.pipelines.registration.global_optimization(
        graph, o3d.pipelines.registration.GlobalOptimizationLevenbergMarquardt(),
        o3d.pipelines.registration.GlobalOptimizationConvergenceCriteria(), option)
    poses = {n: start[NAMES[0]] @ graph.nodes[k].pose for k, n in enumerate(NAMES)}
    t_align, c_align = time.time() - t0, time.process_time() - c0
    write_conf(os.path.join(out, "open3d_seed%d.conf" % seed), poses)
    # ScalableTSDFVolume on virtual depth images of the scans.
    t1, c1 = time.time(), time.process_time()
    volume = o3d.pipelines.integration.ScalableTSDFVolume(
        voxel_length=voxel * 0.5, sdf_trunc=voxel * 1.5, color_type=o3d.pipelines.integration.TSDFVolumeColorType.NoColor)
    W = H = 400
    f = 0.5 / 0.0007
    intr = o3d.camera.PinholeCameraIntrinsic(W, H, f, f, W / 2, H / 2)
    for k, name in enumerate(NAMES):
        P = np.asarray(meshes[k].vertices)
        c = P.mean(axis=0)
        # camera_from_scan: camera 0.5 m along +z from the scan's centroid, looking along -z (x right, y down).
        R = np.diag([1.0, -1.0, -1.0])
        cam_centre = c + np.array([0.0, 0.0, 0.5])
        q = (P - cam_centre) @ R.T
        u = np.round(f * q[:, 0] / q[:, 2] + W / 2).astype(int)
        v = np.round(f * q[:, 1] / q[:, 2] + H / 2).astype(int)
        ok = (u >= 0) & (u < W) & (v >= 0) & (v < H) & (q[:, 2] > 0)
        depth = np.full((H, W), np.inf, dtype=np.float32)
        np.minimum.at(depth, (v[ok], u[ok]), q[ok, 2].astype(np.float32))
        depth[~np.isfinite(depth)] = 0
        depth_img = o3d.geometry.Image(depth)
        color = o3d.geometry.Image(np.zeros((H, W, 3), dtype=np.uint8))
        rgbd = o3d.geometry.RGBDImage.create_from_color_and_depth(color, depth_img, depth_scale=1.0, depth_trunc=2.0,
                                                                  convert_rgb_to_intensity=False)
        camera_from_scan = np.eye(4)
        camera_from_scan[:3, :3] = R
        camera_from_scan[:3, 3] = -R @ cam_centre
        extrinsic = camera_from_scan @ np.linalg.inv(poses[name])  # camera_from_world
        volume.integrate(rgbd, intr, extrinsic)
    mesh = volume.extract_triangle_mesh()
    t_fuse, c_fuse = time.time() - t1, time.process_time() - c1
    o3d.io.write_triangle_mesh(os.path.join(out, "open3d_fused_seed%d.ply" % seed), mesh)
    print("open3d seed %d: alignment %.2f s wall %.2f s CPU, TSDF %.2f s wall %.2f s CPU, %d triangles"
          % (seed, t_align, c_align, t_fuse, c_fuse, len(mesh.triangles)))


if __name__ == "__main__":
    main()
