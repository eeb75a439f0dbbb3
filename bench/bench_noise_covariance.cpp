// The effect that matters for the noise model: smoothing a synthetic scan with the covariances of the fitted
// disparity-noise model against the same covariances off by 3x (and 9x) either way. Prints the depth RMS of
// the vertices against the ground truth before and after smoothing.
// Usage: bench_noise_covariance [image_noise_gray] [scene]
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

#include "bayes/smooth.h"
#include "bench/bench_main.h"
#include "calibration/disparity_noise_model.h"
#include "calibration/plane_target.h"
#include "reconstruction/triangulate.h"
#include "stereo/depth_frame.h"
#include "stereo/spacetime_matcher.h"
#include "stereo/synth.h"

using namespace rangebayes;

namespace {

SpaceTimeMatcherOptions RawMatcher(double noise) {
  SpaceTimeMatcherOptions m;
  m.num_disparities = 64;
  m.sigma_floor_px = 0.0;  // raw curvature prediction; the fitted model supplies floor and scale
  m.sigma_scale = 1.0;
  m.image_noise_gray = std::max(noise, 0.5);
  return m;
}

SynthOptions Scene(SynthScene scene, double noise, std::uint64_t seed) {
  SynthOptions s;
  s.scene = scene;
  s.frames = 1;
  s.image_noise_gray = noise;
  s.seed = seed;
  s.width = 200;
  s.height = 150;
  s.supersample = 2;
  return s;
}

// RMS of the depth error over vertices whose input error is under `gate_m` (gross mismatches excluded, the same
// vertices for every run), metres.
double DepthRms(const Mesh& mesh, const NoisyMesh& noisy, const cv::Mat& depth_gt, double gate_m = 1e9) {
  double sum = 0;
  int n = 0;
  for (Eigen::Index i = 0; i < mesh.V.rows(); ++i) {
    const int u = static_cast<int>(std::lround(noisy.pixel(i, 0))), v = static_cast<int>(std::lround(noisy.pixel(i, 1)));
    if (u < 0 || v < 0 || u >= depth_gt.cols || v >= depth_gt.rows) continue;
    const float z = depth_gt.at<float>(v, u);
    if (!std::isfinite(z) || std::abs(noisy.mesh.V(i, 2) - z) > gate_m) continue;
    const double e = mesh.V(i, 2) - z;
    sum += e * e;
    ++n;
  }
  return std::sqrt(sum / std::max(n, 1));
}

}  // namespace

int RunBench(int argc, char** argv) {
  const double noise = argc > 1 ? std::atof(argv[1]) : 4.0;
  const SynthScene scene = ParseSynthScene(argc > 2 ? argv[2] : "box");

  // 1. Tune the noise model on a plane recording (no ground truth used).
  const SynthRecording plane = RenderSynthetic(Scene(SynthScene::kPlane, noise, 11));
  SpaceTimeMatcher matcher(RawMatcher(noise));
  const DisparityResult pd = matcher.Match(plane.left, plane.right);
  DisparityGeometry g;
  g.camera = plane.intrinsics;
  g.baseline_m = plane.rig.baseline_m();
  NoiseFitOptions fo;
  fo.form = NoiseForm::kFloorPlusScale;
  const DisparityNoiseModel model =
      FitDisparityNoiseModel(PlaneDisparityResiduals(ObservationsFromDisparity(pd.disparity_px, pd.sigma_disparity_px), g, {}), fo);
  std::printf("image noise %.1f grey, scene %s: fitted sigma_d = sqrt(%.4f^2 + (%.3f sigma_pred)^2)\n", noise,
              ToString(scene).c_str(), model.floor_px, model.scale);

  // 2. Scan another scene, σ_d from the model, triangulate with ray-aligned covariances.
  const SynthRecording rec = RenderSynthetic(Scene(scene, noise, 12));
  const DisparityResult d = matcher.Match(rec.left, rec.right);
  cv::Mat sigma = d.sigma_disparity_px.clone();
  sigma.forEach<float>([&](float& s, const int*) { s = static_cast<float>(model.Apply(s)); });
  const DepthFrame frame = DepthFromDisparity(d.disparity_px, sigma, rec.intrinsics, rec.rig.baseline_m(), 0.0);
  const NoisyMesh noisy = TriangulateDepth(frame, {});
  const double gate_m = 0.02;
  std::printf("mesh: %d vertices; depth RMS before smoothing %.3f mm (all), %.3f mm (input error < %.0f mm)\n",
              static_cast<int>(noisy.mesh.V.rows()), 1e3 * DepthRms(noisy.mesh, noisy, rec.depth_m),
              1e3 * DepthRms(noisy.mesh, noisy, rec.depth_m, gate_m), 1e3 * gate_m);

  // 3. Smooth with the tuned covariance and with it scaled.
  for (double factor : {1.0 / 9.0, 1.0 / 3.0, 1.0, 3.0, 9.0}) {
    NoisyMesh scaled = noisy;
    for (auto& c : scaled.covariance) c *= factor;
    SmoothOptions so;
    so.adaptive_epsilon = false;  // the plain solve (global ε²)
    SmoothSummary ss;
    const Mesh out = Smooth(scaled, so, &ss);
    std::printf("covariance x %.3f: depth RMS after smoothing %.3f mm (all), %.3f mm (gated) (%d iterations, %.1f s)\n",
                factor, 1e3 * DepthRms(out, noisy, rec.depth_m), 1e3 * DepthRms(out, noisy, rec.depth_m, gate_m),
                ss.iterations, ss.time_s);
  }
  return 0;
}

// Bad input (a missing file, a wrong option or value) ends with one error line and exit code 1, not an abort.
int main(int argc, char** argv) { return rangebayes::bench::Main("bench_noise_covariance", RunBench, argc, argv); }
