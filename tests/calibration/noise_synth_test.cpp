// Validation of the plane-target noise fit on synthetic recordings with exact ground truth: the σ_d fitted
// from residuals about the fitted plane (no ground truth used) matches the σ_d of the disparity error against
// the ground truth.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "calibration/disparity_noise_model.h"
#include "calibration/plane_target.h"
#include "stereo/spacetime_matcher.h"
#include "stereo/synth.h"

namespace rangebayes {
namespace {

struct NoiseCase {
  double true_sigma_px = 0;    // ML σ of (d − d_gt), same estimator as the fit
  double fitted_sigma_px = 0;  // ML σ of the residuals about the fitted plane
};

NoiseCase RunCase(double image_noise_gray, int frames) {
  SynthOptions s;
  s.scene = SynthScene::kPlane;
  s.pattern = SynthPattern::kRandom;
  s.frames = frames;
  s.image_noise_gray = image_noise_gray;
  s.seed = 3;
  s.width = 240;
  s.height = 180;
  s.supersample = 2;
  const SynthRecording rec = RenderSynthetic(s);
  SpaceTimeMatcherOptions m;
  m.num_disparities = 48;
  m.sigma_floor_px = 0.0;
  m.sigma_scale = 1.0;
  m.image_noise_gray = std::max(image_noise_gray, 0.5);
  SpaceTimeMatcher matcher(m);
  const DisparityResult d = matcher.Match(rec.left, rec.right);

  const std::vector<DisparityObservation> obs = ObservationsFromDisparity(d.disparity_px, d.sigma_disparity_px);
  DisparityGeometry g;
  g.camera = rec.intrinsics;
  g.baseline_m = rec.rig.baseline_m();
  const std::vector<NoiseSample> samples = PlaneDisparityResiduals(obs, g, {});
  std::vector<NoiseSample> truth;
  for (const DisparityObservation& o : obs) {
    NoiseSample t;
    t.residual_px = o.disparity_px - rec.disparity_px.at<float>(static_cast<int>(o.v_px), static_cast<int>(o.u_px));
    t.depth_m = 1.0;
    truth.push_back(t);
  }
  NoiseCase c;
  c.true_sigma_px = FitDisparityNoiseModel(truth, {}).sigma_px;
  c.fitted_sigma_px = FitDisparityNoiseModel(samples, {}).sigma_px;
  return c;
}

TEST(NoiseFitOnSynthetic, WithinTenPercentOfTruthAtThreeNoiseLevels) {
  for (double noise : {1.0, 4.0, 10.0}) {
    const NoiseCase c = RunCase(noise, 1);
    std::printf("image noise %.1f grey: true sigma_d %.4f px, fitted %.4f px (%+.1f%%)\n", noise, c.true_sigma_px,
                c.fitted_sigma_px, 100.0 * (c.fitted_sigma_px / c.true_sigma_px - 1.0));
    EXPECT_NEAR(c.fitted_sigma_px, c.true_sigma_px, 0.10 * c.true_sigma_px) << "image noise " << noise;
  }
}

}  // namespace
}  // namespace rangebayes
