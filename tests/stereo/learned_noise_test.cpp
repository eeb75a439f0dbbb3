// The learned disparity-noise model: features of a matcher's disparity, the fit from ground truth (tsukuba), the
// calibration check, and the errors for a model of another matcher or resolution and for ground truth without a
// valid pixel.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "calibration/disparity_noise_model.h"
#include "core/error.h"
#include "stereo/disparity_features.h"
#include "stereo/disparity_io.h"
#include "stereo/noise_calibration.h"

namespace rangebayes {
namespace {

// A random texture and its view from a camera `shift` px to the right: right(x − shift) = left(x).
void TexturedPair(int shift, cv::Mat* left, cv::Mat* right) {
  cv::Mat big(40, 80 + shift, CV_8U);
  cv::RNG rng(7);
  rng.fill(big, cv::RNG::UNIFORM, 0, 255);
  *left = big(cv::Rect(0, 0, 80, 40)).clone();
  *right = big(cv::Rect(shift, 0, 80, 40)).clone();
}

TEST(DisparityFeatures, TexturedPlaneHasSmallSigmaNoJumpFlatHasTheCap) {
  cv::Mat l, r;
  TexturedPair(3, &l, &r);
  cv::Mat d(l.size(), CV_32F, cv::Scalar(3.0));
  d.at<float>(5, 5) = std::numeric_limits<float>::quiet_NaN();
  DisparityFeatureOptions o;
  const DisparityFeatures f = ComputeDisparityFeatures({l}, {r}, d, o);
  EXPECT_TRUE(std::isnan(f.sigma_pred_px.at<float>(5, 5)));
  EXPECT_EQ(f.jump_px.at<float>(20, 40), 0.0f);
  // A random texture of 25 pixels with gradients of ~100 grey levels: C″ ≈ 2·25·10⁴, σ_pred ≈ 0.004 px.
  EXPECT_LT(f.sigma_pred_px.at<float>(20, 40), 0.05f);
  EXPECT_GT(f.sigma_pred_px.at<float>(20, 40), 0.0f);
  d.at<float>(20, 41) = 5.0f;
  EXPECT_FLOAT_EQ(ComputeDisparityFeatures({l}, {r}, d, o).jump_px.at<float>(20, 40), 2.0f);
  const cv::Mat flat(l.size(), CV_8U, cv::Scalar(100));
  const DisparityFeatures g = ComputeDisparityFeatures({flat}, {flat}, d, o);
  EXPECT_FLOAT_EQ(g.sigma_pred_px.at<float>(20, 40), static_cast<float>(o.max_sigma_pred_px));
}

TEST(LearnedNoise, FitFromTsukubaGroundTruthAndItsErrors) {
  GroundTruthNoiseOptions o;
  o.stride_px = 2;
  std::vector<std::pair<std::string, double>> progress;
  o.progress = [&](double fraction, std::string_view stage) { progress.emplace_back(stage, fraction); };
  GroundTruthNoiseSummary s;
  const DisparityNoiseModel m = CalibrateDisparityNoiseFromGroundTruth({"tests/data/stereo/tsukuba"}, o, &s);
  // The scene, then the fit's start and each of its three starts.
  const std::vector<std::pair<std::string, double>> expected = {
      {"scene tsukuba (1 of 1)", 0.0}, {"fit", 0.0}, {"fit", 1.0 / 3.0}, {"fit", 2.0 / 3.0}, {"fit", 1.0}};
  EXPECT_EQ(progress, expected);
  EXPECT_EQ(m.form, NoiseForm::kLearned);
  EXPECT_EQ(m.matcher, "sgbm");
  EXPECT_EQ(m.width_min_px, 384);
  EXPECT_EQ(m.width_max_px, 384);
  EXPECT_EQ(s.scenes, 1);
  EXPECT_GT(s.samples, 12000);  // most of the 192x144 non-occluded pixels of stride 2
  // Physical ranges (SGBM on tsukuba, whose ground truth is whole pixels, fitted out before the residuals are
  // taken: measured floor 0.041 px, a few % mismatches): a broken fit falls outside. The floor's band is the
  // measured value halved and tripled: above the fit's clamp for SGBM (1/16 px steps, 1/(16√12) = 0.018 px), and
  // below what whole-pixel rounding left in the residuals gives (uniform over ±0.5 px, σ = 1/√12 = 0.29 px; such
  // an error added to the residuals gave a floor of 0.32 px). The outlier share: none or half of them is outside.
  EXPECT_GT(m.floor_px, 0.02);
  EXPECT_LT(m.floor_px, 0.15);
  EXPECT_GT(m.outlier_fraction, 0.001);
  EXPECT_LT(m.outlier_fraction, 0.3);
  // On its own training scene: shares of |z| ≤ 1, 2, 3 within 0.07 of the model's. Measured 0.047 at |z| ≤ 1 (the
  // real residuals are more peaked than the model's Gaussian core; BENCHMARKS.md, learned disparity noise).
  const NoiseModelCheck c = CheckDisparityNoiseOnGroundTruth(m, {"tests/data/stereo/tsukuba"}, 2);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(c.observed_within[k], c.predicted_within[k], 0.07) << k;
  // The model refuses another matcher and another resolution.
  EXPECT_THROW(m.CheckApplicable("block", 384, "m.yaml"), Error);
  EXPECT_THROW(m.CheckApplicable("sgbm", 1482, "m.yaml"), Error);
  EXPECT_THROW(m.CheckApplicable("sgbm", 192, "m.yaml"), Error);
  EXPECT_NO_THROW(m.CheckApplicable("sgbm", 400, "m.yaml"));
  // σ_d for these frames: finite where the disparity is, NaN elsewhere.
  const MiddleburyScene scene = ReadMiddleburyScene("tests/data/stereo/tsukuba");
  cv::Mat d(scene.left.size(), CV_32F, cv::Scalar(8.0));
  d.at<float>(0, 0) = std::numeric_limits<float>::quiet_NaN();
  const cv::Mat sigma = LearnedDisparitySigma(m, "sgbm", {scene.left}, {scene.right}, d, "m.yaml");
  EXPECT_TRUE(std::isnan(sigma.at<float>(0, 0)));
  EXPECT_GE(sigma.at<float>(100, 100), m.floor_px * 0.999);
  EXPECT_THROW(LearnedDisparitySigma(m, "spacetime", {scene.left}, {scene.right}, d, "m.yaml"), Error);
}

TEST(LearnedNoise, GroundTruthWithoutValidPixelIsAnError) {
  MiddleburyScene scene = ReadMiddleburyScene("tests/data/stereo/tsukuba");
  scene.gt_disparity_px.setTo(std::numeric_limits<float>::infinity());
  GroundTruthNoiseOptions o;
  try {
    GroundTruthNoiseSamples(scene, o);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("no pixel with a finite"), std::string::npos) << e.what();
  }
  scene.gt_disparity_px = cv::Mat();
  EXPECT_THROW(GroundTruthNoiseSamples(scene, o), Error);
  EXPECT_THROW(CalibrateDisparityNoiseFromGroundTruth({}, o), Error);
}

}  // namespace
}  // namespace rangebayes
