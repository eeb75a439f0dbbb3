// Smoothing on real stereo meshes scored against Middlebury 2014 ground truth (BENCHMARKS.md "Smoothing on real
// stereo").
//
//   bench_stereo_smooth eval SCENE MESH          one JSON line: normal error (deg) and depth MAE (mm) of MESH
//   bench_stereo_smooth bilateral SCENE DIR OUT [N] the peer: DIR/disparity.pfm (from `rangebayes stereo`) filtered
//                                                 by a 9×9 bilateral filter (NaN holes kept), triangulated with the
//                                                 defaults (every N-th pixel) into OUT (PLY), then scored like eval
//
// Scores, per face of the mesh with a ground-truth pixel: the angle between the face normal and the ground-truth
// normal at the pixel the face centroid projects to (central differences of the ground-truth points; faces
// whose pixel has no ground truth in its 3×3 neighbourhood are skipped), and |Z_centroid − Z_gt| there.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <string>

#include "core/error.h"
#include "core/mesh_io.h"
#include "reconstruction/triangulate.h"
#include "stereo/depth_frame.h"
#include "stereo/disparity_io.h"
#include "stereo/pfm.h"

namespace rb = rangebayes;

namespace {

struct Score {
  double normal_deg = 0;
  double depth_mae_mm = 0;
  int faces = 0;
};

Score Evaluate(const rb::MiddleburyScene& scene, const rb::Mesh& mesh) {
  RB_CHECK(scene.rig.has_value() && !scene.gt_disparity_px.empty(), scene.folder, ": needs calib.txt and disp0GT.pfm");
  const rb::StereoRig& rig = *scene.rig;
  const rb::CameraIntrinsics k = rig.RectifiedLeft();
  const double fx = k.fx_px, fy = k.fy_px, cx = k.cx_px, cy = k.cy_px;
  const double fb = fx * rig.baseline_m();
  const cv::Mat& d = scene.gt_disparity_px;
  auto point = [&](int u, int v, Eigen::Vector3d* p) {
    if (u < 0 || v < 0 || u >= d.cols || v >= d.rows) return false;
    const float disparity = d.at<float>(v, u);
    if (!std::isfinite(disparity) || disparity + rig.doffs_px <= 0) return false;
    const double z = fb / (disparity + rig.doffs_px);
    *p = Eigen::Vector3d((u - cx) * z / fx, (v - cy) * z / fy, z);
    return true;
  };
  Score score;
  double angle_sum = 0, depth_sum = 0;
  for (int f = 0; f < mesh.num_faces(); ++f) {
    const Eigen::Vector3d a = mesh.V.row(mesh.F(f, 0)), b = mesh.V.row(mesh.F(f, 1)), c = mesh.V.row(mesh.F(f, 2));
    const Eigen::Vector3d centroid = (a + b + c) / 3.0;
    if (!(centroid.z() > 0)) continue;
    const int u = static_cast<int>(std::lround(fx * centroid.x() / centroid.z() + cx));
    const int v = static_cast<int>(std::lround(fy * centroid.y() / centroid.z() + cy));
    Eigen::Vector3d p, left, right, up, down;
    if (!point(u, v, &p) || !point(u - 1, v, &left) || !point(u + 1, v, &right) || !point(u, v - 1, &up) ||
        !point(u, v + 1, &down)) {
      continue;
    }
    Eigen::Vector3d n_gt = (right - left).cross(down - up);
    Eigen::Vector3d n = (b - a).cross(c - a);
    if (!(n_gt.norm() > 0) || !(n.norm() > 0)) continue;
    n_gt.normalize();
    n.normalize();
    if (n_gt.dot(p) > 0) n_gt = -n_gt;  // towards the camera, as the faces are
    angle_sum += std::acos(std::clamp(n.dot(n_gt), -1.0, 1.0)) * 180.0 / M_PI;
    depth_sum += std::abs(centroid.z() - p.z()) * 1000.0;
    ++score.faces;
  }
  if (score.faces > 0) {
    score.normal_deg = angle_sum / score.faces;
    score.depth_mae_mm = depth_sum / score.faces;
  }
  return score;
}

void Print(const std::string& scene, const std::string& what, const Score& s) {
  std::printf("{\"scene\": \"%s\", \"mesh\": \"%s\", \"normal_deg\": %.3f, \"depth_mae_mm\": %.3f, \"faces\": %d}\n",
              scene.c_str(), what.c_str(), s.normal_deg, s.depth_mae_mm, s.faces);
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const std::string mode = argc > 1 ? argv[1] : "";
    if (mode == "eval" && argc == 4) {
      const rb::MiddleburyScene scene = rb::ReadMiddleburyScene(argv[2]);
      Print(argv[2], argv[3], Evaluate(scene, rb::ReadMesh(argv[3])));
      return 0;
    }
    if (mode == "bilateral" && (argc == 5 || argc == 6)) {
      const rb::MiddleburyScene scene = rb::ReadMiddleburyScene(argv[2]);
      const std::string dir = argv[3];
      const cv::Mat disparity = rb::ReadPfm(dir + "/disparity.pfm");
      cv::Mat valid = disparity == disparity;  // not NaN
      cv::Mat filled = disparity.clone();
      filled.setTo(0, ~valid);
      cv::Mat filtered;
      cv::bilateralFilter(filled, filtered, 9, 2.0, 4.5);
      filtered.setTo(std::nanf(""), ~valid);
      const rb::StereoRig& rig = *scene.rig;
      const rb::DepthFrame frame =
          rb::DepthFromDisparity(filtered, cv::Mat(), rig.RectifiedLeft(), rig.baseline_m(), rig.doffs_px);
      rb::TriangulateOptions triangulate;
      triangulate.downsample = argc == 6 ? std::stoi(argv[5]) : 1;
      const rb::NoisyMesh mesh = rb::TriangulateDepth(frame, triangulate);
      rb::WriteMesh(mesh.mesh, argv[4]);
      Print(argv[2], argv[4], Evaluate(scene, mesh.mesh));
      return 0;
    }
    std::fprintf(stderr, "usage: bench_stereo_smooth eval SCENE MESH | bilateral SCENE STEREO_DIR OUT.ply [DOWNSAMPLE]\n");
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "bench_stereo_smooth: error: %s\n", e.what());
    return 1;
  }
}
