// OpenCV SGBM behind our interface on Middlebury Tsukuba, and the fixed-point conversion.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "core/error.h"
#include "stereo/disparity_io.h"
#include "stereo/evaluate.h"
#include "stereo/sgbm_matcher.h"
#include "stereo/spacetime_matcher.h"

namespace rangebayes {
namespace {

TEST(Sgbm, FixedPointBecomesFloatWithNaN) {
  cv::Mat d16(1, 4, CV_16S);
  d16.at<short>(0, 0) = 16 * 5 + 8;  // 5.5 px
  d16.at<short>(0, 1) = -16;          // invalid (min disparity 0 → invalid is (0 − 1)·16)
  d16.at<short>(0, 2) = 0;            // the range's lower end: a tie or beyond the range
  d16.at<short>(0, 3) = 1;            // 1/16 px
  const cv::Mat f = FixedPointDisparityToFloat(d16, 0);
  EXPECT_FLOAT_EQ(f.at<float>(0, 0), 5.5f);
  EXPECT_TRUE(std::isnan(f.at<float>(0, 1)));
  EXPECT_TRUE(std::isnan(f.at<float>(0, 2)));
  EXPECT_FLOAT_EQ(f.at<float>(0, 3), 1.0f / 16.0f);
  // With min disparity 5: 5.5 px stays, 5 px exactly is the lower end.
  EXPECT_FLOAT_EQ(FixedPointDisparityToFloat(d16, 5).at<float>(0, 0), 5.5f);
  EXPECT_TRUE(std::isnan(FixedPointDisparityToFloat(cv::Mat(1, 1, CV_16S, cv::Scalar(80)), 5).at<float>(0, 0)));
}

// A pair with no texture has no disparity: every disparity costs the same, SGBM's winner is the range's lower end,
// and that was kept as a measurement (a uniform grey pair came out 91% valid, one plane at the range's far end).
TEST(Sgbm, AUniformPairHasNoValidDisparity) {
  const cv::Mat grey(120, 160, CV_8U, cv::Scalar(128));
  SgbmMatcherOptions o;
  o.num_disparities = 32;
  const DisparityResult r = SgbmMatcher(o).Match({grey}, {grey});
  EXPECT_EQ(r.valid_fraction, 0.0);
}

// Middlebury v2 reports OpenCV's SGBM at about 5% bad-1.0 (non-occluded, holes as errors) on Tsukuba; our
// wrapper runs the same algorithm, so it must land there too (measured 5–8% here, see BENCHMARKS.md).
TEST(Sgbm, TsukubaNonOccludedBad1) {
  const MiddleburyScene s = ReadMiddleburyScene("tests/data/stereo/tsukuba");
  SgbmMatcherOptions o;
  o.num_disparities = 16;
  SgbmMatcher m(o);
  const DisparityResult r = m.Match({s.left}, {s.right});
  const DisparityEvaluation ev = EvaluateDisparity(r.disparity_px, s.gt_disparity_px, s.mask_nonocc);
  std::printf("tsukuba sgbm: bad-1 %.2f%% (holes as errors), coverage %.1f%%\n", 100 * ev.bad_with_holes[1],
              100 * ev.coverage);
  EXPECT_LT(ev.bad_with_holes[1], 0.10);
  EXPECT_GT(ev.coverage, 0.9);
}

// Our block matcher on one Tsukuba pair, with its σ_d. Measured: bad-2 4.6% (holes excluded), coverage 90.3%
// (the non-occluded pixels; SGBM reaches 98%), σ_d 0.07–0.17 px (10th–90th percentile). Tsukuba's ground truth
// is whole pixels: its own error, uniform over ±0.5 px (variance 1/12 px²), is in every e = d − d_true, so the
// normalised residual is e / sqrt(σ_d² + 1/12) (measured RMS 0.91 over the Gaussian core |z| < 5, 99.6% of the
// pixels). The band allows SpaceTime.SigmaMatchesTheErrors' factor 2 on σ_d either way: σ_d doubled gives 0.67,
// halved 1.17 (the ground truth's share of the variance does not scale). And σ_d follows the errors: the quarter
// of the pixels with the largest σ_d has the larger errors (measured 8.8× the RMS error of the quarter with the
// smallest; 1 for a σ_d that says nothing).
TEST(BlockMatcher, TsukubaSingleFrameWithSigma) {
  const MiddleburyScene s = ReadMiddleburyScene("tests/data/stereo/tsukuba");
  SpaceTimeMatcherOptions o;
  o.num_disparities = 16;
  o.window_px = 9;
  SpaceTimeMatcher m(o);
  const DisparityResult r = m.Match({s.left}, {s.right});
  const DisparityEvaluation ev = EvaluateDisparity(r.disparity_px, s.gt_disparity_px, s.mask_nonocc);
  std::printf("tsukuba block: bad-1 %.2f%% (holes as errors), %.2f%% (excluded), coverage %.1f%%\n",
              100 * ev.bad_with_holes[1], 100 * ev.bad_valid_only[1], 100 * ev.coverage);
  EXPECT_LT(ev.bad_valid_only[2], 0.15);
  EXPECT_GT(ev.coverage, 0.85);

  ASSERT_EQ(r.sigma_disparity_px.size(), r.disparity_px.size());
  std::vector<std::pair<double, double>> sigma_error;  // (σ_d, e) on the non-occluded pixels with ground truth
  double z2 = 0;
  int core = 0, not_finite_together = 0, not_positive = 0;
  for (int y = 0; y < r.disparity_px.rows; ++y) {
    for (int x = 0; x < r.disparity_px.cols; ++x) {
      const float d = r.disparity_px.at<float>(y, x), sigma = r.sigma_disparity_px.at<float>(y, x);
      not_finite_together += std::isfinite(d) != std::isfinite(sigma);
      if (!std::isfinite(d)) continue;
      not_positive += !(sigma > 0);
      const float truth = s.gt_disparity_px.at<float>(y, x);
      if (!s.mask_nonocc.at<uchar>(y, x) || !std::isfinite(truth)) continue;
      const double e = d - truth, z = e / std::sqrt(sigma * sigma + 1.0 / 12.0);
      sigma_error.emplace_back(sigma, e);
      if (std::abs(z) < 5) {
        z2 += z * z;
        ++core;
      }
    }
  }
  EXPECT_EQ(not_finite_together, 0);
  EXPECT_EQ(not_positive, 0);
  ASSERT_GT(core, 0.95 * static_cast<double>(sigma_error.size()));
  const double rms_z = std::sqrt(z2 / core);
  EXPECT_GT(rms_z, 0.67);
  EXPECT_LT(rms_z, 1.17);
  std::sort(sigma_error.begin(), sigma_error.end());
  const size_t quarter = sigma_error.size() / 4;
  double low = 0, high = 0;
  for (size_t i = 0; i < quarter; ++i) {
    low += std::pow(sigma_error[i].second, 2);
    high += std::pow(sigma_error[sigma_error.size() - 1 - i].second, 2);
  }
  std::printf("rms e/sqrt(sigma^2 + 1/12) %.3f; RMS error, largest / smallest quarter of sigma: %.2f\n", rms_z,
              std::sqrt(high / low));
  EXPECT_GT(std::sqrt(high / low), 3.0);
}

// Tsukuba's disparities run from 5 to 14 px. Searched over 0–15 the ends hold few winners; a range that misses
// part of the scene (from 8 px up for SGBM, whose range comes in steps of 16; up to 7 px for the block matcher)
// puts them there, which `stereo` and `spacetime` then warn about.
TEST(Matchers, RangeEndShareSaysTheSearchRangeIsShort) {
  const MiddleburyScene s = ReadMiddleburyScene("tests/data/stereo/tsukuba");
  for (int min_disparity : {0, 8}) {
    SgbmMatcherOptions o;
    o.min_disparity_px = min_disparity;
    o.num_disparities = 16;
    const DisparityResult r = SgbmMatcher(o).Match({s.left}, {s.right});
    std::printf("sgbm from %d px: range end %.4f\n", min_disparity, r.range_end_fraction);
    if (min_disparity == 0) {
      EXPECT_LT(r.range_end_fraction, kRangeEndWarning);
    } else {
      EXPECT_GT(r.range_end_fraction, kRangeEndWarning);
    }
  }
  for (int num : {16, 8}) {
    SpaceTimeMatcherOptions o;
    o.num_disparities = num;
    o.window_px = 9;
    SpaceTimeMatcher m(o);
    const DisparityResult r = m.Match({s.left}, {s.right});
    std::printf("block matcher over %d px: range end %.4f\n", num, r.range_end_fraction);
    EXPECT_EQ(r.range_end_fraction, m.last_summary().rejected_range_end / static_cast<double>(s.left.total()));
    if (num == 16) {
      EXPECT_LT(r.range_end_fraction, kRangeEndWarning);
    } else {
      EXPECT_GT(r.range_end_fraction, kRangeEndWarning);
    }
  }
}

TEST(Sgbm, BadInputThrows) {
  SgbmMatcher m;
  EXPECT_THROW(m.Match({cv::Mat(10, 10, CV_8U)}, {cv::Mat(10, 11, CV_8U)}), Error);
  SgbmMatcherOptions o;
  o.block_size_px = 4;
  EXPECT_THROW(SgbmMatcher{o}, Error);
}

// An image no wider than the search range has no column to match: a clear error, where OpenCV aborts the process.
TEST(Sgbm, ImageNarrowerThanTheSearchRangeThrows) {
  cv::Mat narrow(50, 64, CV_8U), wide(50, 65, CV_8U);
  cv::randu(narrow, 0, 255);
  cv::randu(wide, 0, 255);
  SgbmMatcherOptions o;
  o.num_disparities = 64;
  EXPECT_THROW(SgbmMatcher(o).Match({narrow}, {narrow}), Error);
  EXPECT_NO_THROW(SgbmMatcher(o).Match({wide}, {wide}));
  o.num_disparities = 16;
  o.min_disparity_px = 60;  // searches 60..75
  EXPECT_THROW(SgbmMatcher(o).Match({wide}, {wide}), Error);
  o.min_disparity_px = -16;  // searches -16..-1: the columns lose 16 on the right instead
  EXPECT_NO_THROW(SgbmMatcher(o).Match({narrow}, {narrow}));
  const cv::Mat tiny(2, 2, CV_8U, cv::Scalar(7));
  try {
    SgbmMatcher{}.Match({tiny}, {tiny});
    ADD_FAILURE() << "a 2 px wide image was matched";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("2 px wide"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace rangebayes
