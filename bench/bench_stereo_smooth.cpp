// Smoothing on real stereo meshes scored against Middlebury 2014 ground truth (BENCHMARKS.md "Smoothing on real
// stereo").
//
//   bench_stereo_smooth eval SCENE MESH          one JSON line: normal error (deg) and depth MAE (mm) of MESH
//   bench_stereo_smooth bilateral SCENE DIR OUT [N] the peer: DIR/disparity.pfm (from `rangebayes stereo`) filtered
//                                                 by a 9×9 bilateral filter (NaN holes kept), triangulated with the
//                                                 defaults (every N-th pixel) into OUT (PLY), then scored like eval
//   bench_stereo_smooth rig SCENE OUT_RIG         the scene's rig (2014: calib.txt; older layouts: the nominal rig
//                                                 f = 2.7 px per pixel of width, B = 160 mm, doffs 0), written to
//                                                 OUT_RIG; prints the search range (the scene's, rounded up to 16)
//   bench_stereo_smooth pair SCENE RIG MESH OUT   real-noise pair (BENCHMARKS.md "Real sensor noise, part 2"): MESH
//                                                 (from `rangebayes stereo`) restricted to the faces whose three
//                                                 vertices have a ground-truth disparity at their pixel, written as
//                                                 OUT/noisy_cov.ply (covariances kept), OUT/noisy.ply (plain) and
//                                                 OUT/gt.ply (each vertex moved along its pixel ray to the ground-truth
//                                                 depth; a ground truth stored in whole steps has them fitted out
//                                                 first, RemoveQuantisationSteps); one JSON line with the raw scores
//                                                 and the step found (gt_step_px, 0: continuous)
//   bench_stereo_smooth compare RESULT GT         one JSON line: face-normal error (deg, same connectivity) and depth
//                                                 MAE (mm, per vertex) of RESULT against GT
//
// Scores, per face of the mesh with a ground-truth pixel: the angle between the face normal and the ground-truth
// normal at the pixel the face centroid projects to (central differences of the ground-truth points; faces
// whose pixel has no ground truth in its 3×3 neighbourhood are skipped), and |Z_centroid − Z_gt| there.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <string>

#include "bench/bench_main.h"
#include "calibration/middlebury.h"
#include "calibration/stereo_rig.h"
#include "core/error.h"
#include "core/mesh_io.h"
#include "core/normal_error.h"
#include "core/topology.h"
#include "reconstruction/triangulate.h"
#include "stereo/depth_frame.h"
#include "stereo/disparity_io.h"
#include "stereo/evaluate.h"
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

// A rig for every layout: only the 2014 scenes come with a calibration.
rb::StereoRig SceneRig(const rb::MiddleburyScene& scene) {
  if (scene.layout == "2014") return rb::StereoRigFromMiddlebury(rb::ReadMiddleburyCalib(scene.folder + "/calib.txt"));
  rb::MiddleburyCalib calib;
  calib.width = scene.left.cols;
  calib.height = scene.left.rows;
  // The 2005/2006 third-size focal length over its image width (3740 px / 3 over 463 px); no set states doffs.
  const double f = 2.7 * calib.width;
  calib.cam0 << f, 0, 0.5 * (calib.width - 1), 0, f, 0.5 * (calib.height - 1), 0, 0, 1;
  calib.cam1 = calib.cam0;
  calib.baseline_mm = 160.0;
  calib.ndisp = scene.num_disparities;
  return rb::StereoRigFromMiddlebury(calib);
}

// Depth errors per vertex and the face-normal error of `result` against `gt` (same vertices and faces).
Score CompareSameConnectivity(const rb::Mesh& result, const rb::Mesh& gt) {
  Score s;
  s.normal_deg = rb::MeanAngularErrorDeg(result, gt);
  double sum = 0;
  for (int v = 0; v < gt.num_vertices(); ++v) sum += std::abs(result.V(v, 2) - gt.V(v, 2));
  s.depth_mae_mm = gt.num_vertices() > 0 ? 1000.0 * sum / gt.num_vertices() : 0;
  s.faces = gt.num_faces();
  return s;
}

// The noisy mesh on the faces with ground truth at all three vertices, and its ground-truth twin.
int WritePair(const rb::MiddleburyScene& scene, const rb::StereoRig& rig, const rb::NoisyMesh& input,
              const std::string& out) {
  RB_CHECK(!scene.gt_disparity_px.empty(), scene.folder, ": has no ground-truth disparity");
  RB_CHECK(input.mesh.num_faces() > 0, scene.folder, ": the stereo mesh has no face");
  const rb::CameraIntrinsics k = rig.RectifiedLeft();
  const double fb = k.fx_px * rig.baseline_m();
  // Ground truth stored in whole steps is a staircase on slanted surfaces (stereo/evaluate.h); the pair's
  // ground-truth mesh takes it with the steps fitted out.
  double step = 0;
  const cv::Mat d = rb::GroundTruthWithoutSteps(scene.gt_disparity_px, &step);
  const int nv = input.mesh.num_vertices();
  std::vector<double> gt_depth(static_cast<size_t>(nv), std::nan(""));
  for (int v = 0; v < nv; ++v) {
    const Eigen::Vector3d p = input.mesh.V.row(v);
    if (!(p.z() > 0)) continue;
    // Vertices lie on the rays of pixel centres, so the projection rounds to their own pixel.
    const int u = static_cast<int>(std::lround(k.fx_px * p.x() / p.z() + k.cx_px));
    const int r = static_cast<int>(std::lround(k.fy_px * p.y() / p.z() + k.cy_px));
    if (u < 0 || r < 0 || u >= d.cols || r >= d.rows) continue;
    const float disparity = d.at<float>(r, u);
    if (std::isfinite(disparity) && disparity + rig.doffs_px > 0) gt_depth[v] = fb / (disparity + rig.doffs_px);
  }
  std::vector<int> index(static_cast<size_t>(nv), -1);
  std::vector<int> faces;
  for (int f = 0; f < input.mesh.num_faces(); ++f) {
    bool valid = true;
    for (int c = 0; c < 3; ++c) valid = valid && std::isfinite(gt_depth[input.mesh.F(f, c)]);
    if (valid) faces.push_back(f);
  }
  RB_CHECK(!faces.empty(), scene.folder, ": no face of the stereo mesh has ground truth at its three vertices");
  int count = 0;
  for (int f : faces) {
    for (int c = 0; c < 3; ++c) {
      int& i = index[input.mesh.F(f, c)];
      if (i < 0) i = count++;
    }
  }
  rb::NoisyMesh noisy;
  rb::Mesh gt;
  noisy.mesh.V.resize(count, 3);
  gt.V.resize(count, 3);
  noisy.covariance.resize(static_cast<size_t>(count));
  const bool has_pixel = input.pixel.rows() == nv;
  if (has_pixel) noisy.pixel.resize(count, 2);
  for (int v = 0; v < nv; ++v) {
    const int i = index[v];
    if (i < 0) continue;
    noisy.mesh.V.row(i) = input.mesh.V.row(v);
    gt.V.row(i) = input.mesh.V.row(v) * (gt_depth[v] / input.mesh.V(v, 2));
    if (input.has_covariance()) noisy.covariance[i] = input.covariance[v];
    if (has_pixel) noisy.pixel.row(i) = input.pixel.row(v);
  }
  if (!input.has_covariance()) noisy.covariance.clear();
  noisy.mesh.F.resize(static_cast<int>(faces.size()), 3);
  for (size_t j = 0; j < faces.size(); ++j) {
    for (int c = 0; c < 3; ++c) noisy.mesh.F(static_cast<int>(j), c) = index[input.mesh.F(faces[j], c)];
  }
  gt.F = noisy.mesh.F;
  rb::WriteNoisyMesh(noisy, out + "/noisy_cov.ply");
  rb::WriteMesh(noisy.mesh, out + "/noisy.ply");
  rb::WriteMesh(gt, out + "/gt.ply");
  const Score s = CompareSameConnectivity(noisy.mesh, gt);
  double displacement2 = 0;
  for (int v = 0; v < count; ++v) displacement2 += (noisy.mesh.V.row(v) - gt.V.row(v)).squaredNorm();
  const double rms_k = std::sqrt(displacement2 / std::max(count, 1)) / rb::MeanEdgeLength(noisy.mesh);
  std::printf(
      "{\"scene\": \"%s\", \"vertices\": %d, \"faces\": %d, \"faces_dropped\": %d, \"raw_normal_deg\": %.3f, "
      "\"raw_depth_mae_mm\": %.3f, \"rms_displacement_edge_multiple\": %.4f, \"gt_step_px\": %.4f}\n",
      scene.folder.c_str(), count, static_cast<int>(faces.size()),
      input.mesh.num_faces() - static_cast<int>(faces.size()), s.normal_deg, s.depth_mae_mm, rms_k, step);
  return 0;
}

int RunBench(int argc, char** argv) {
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
  if (mode == "rig" && argc == 4) {
    const rb::MiddleburyScene scene = rb::ReadMiddleburyScene(argv[2]);
    rb::WriteStereoRig(SceneRig(scene), argv[3]);
    std::printf("%d\n", (scene.num_disparities + 15) / 16 * 16);
    return 0;
  }
  if (mode == "pair" && argc == 6) {
    return WritePair(rb::ReadMiddleburyScene(argv[2]), rb::ReadStereoRig(argv[3]), rb::ReadNoisyMesh(argv[4]), argv[5]);
  }
  if (mode == "compare" && argc == 4) {
    const Score s = CompareSameConnectivity(rb::ReadMesh(argv[2]), rb::ReadMesh(argv[3]));
    std::printf("{\"mesh\": \"%s\", \"normal_deg\": %.3f, \"depth_mae_mm\": %.3f, \"faces\": %d}\n", argv[2],
                s.normal_deg, s.depth_mae_mm, s.faces);
    return 0;
  }
  std::fprintf(stderr,
               "usage: bench_stereo_smooth eval SCENE MESH | bilateral SCENE STEREO_DIR OUT.ply [DOWNSAMPLE] | rig "
               "SCENE OUT_RIG | pair SCENE RIG MESH OUT_DIR | compare RESULT GT\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) { return rangebayes::bench::Main("bench_stereo_smooth", RunBench, argc, argv); }
