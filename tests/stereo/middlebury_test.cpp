// Middlebury readers: calib.txt import (doffs kept), scene layouts, disparity maps with scale, masks, errors.
#include "calibration/middlebury.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "core/error.h"
#include "stereo/disparity_io.h"
#include "stereo/evaluate.h"
#include "tests/temp_dir.h"

namespace rangebayes {
namespace {

TEST(Middlebury, CalibTxtBecomesARectifiedRigWithDoffs) {
  const MiddleburyCalib c = ReadMiddleburyCalib("tests/data/stereo/motorcycle_calib/calib.txt");
  EXPECT_DOUBLE_EQ(c.cam0(0, 0), 999.421);
  EXPECT_DOUBLE_EQ(c.cam1(0, 2), 326.96);
  EXPECT_DOUBLE_EQ(c.doffs_px, 32.778);
  EXPECT_EQ(c.width, 741);
  EXPECT_EQ(c.ndisp, 70);
  const StereoRig rig = StereoRigFromMiddlebury(c);
  EXPECT_TRUE(rig.is_rectified);
  EXPECT_NEAR(rig.baseline_m(), 0.193001, 1e-12);
  EXPECT_DOUBLE_EQ(rig.doffs_px, 32.778);
  // Z = f·B/(d + doffs), and Q must say the same: W = d/B + doffs/B, Z = f/W.
  const double d = 40.0;
  const double z = c.cam0(0, 0) * 0.193001 / (d + 32.778);
  EXPECT_NEAR(rig.Q(2, 3) / (rig.Q(3, 2) * d + rig.Q(3, 3)), z, 1e-9);
  const std::string out = TempPath("motorcycle_rig.yaml");
  WriteStereoRig(rig, out);
  const StereoRig back = ReadStereoRig(out);
  EXPECT_DOUBLE_EQ(back.doffs_px, 32.778);
  EXPECT_TRUE(back.is_rectified);
  EXPECT_NEAR(back.RectifiedLeft().fx_px, 999.421, 1e-9);
}

TEST(Middlebury, CalibErrorsNameTheKey) {
  const std::string path = TempPath("bad_calib.txt");
  {
    std::ofstream out(path);
    out << "cam0=[1 0 0; 0 1 0; 0 0 1]\nbaseline=10\nwidth=5\nheight=5\n";
  }
  try {
    ReadMiddleburyCalib(path);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cam1"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ReadMiddleburyCalib("tests/data/stereo/none/calib.txt"), Error);
  // An image given for the calib file: one readable line, no raw bytes.
  {
    std::ofstream out(path, std::ios::binary);
    out << "\x89PNG\r\n\x1a\n" << std::string("\0\0\0\rIHDR", 8);
  }
  try {
    ReadMiddleburyCalib(path);
    FAIL();
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(": line 1 is not text: not a Middlebury calib.txt"), std::string::npos)
        << e.what();
  }
  // Sizes and counts beyond int (a cast of 1e30 is undefined) or not whole.
  for (const char* bad : {"width=1e12", "ndisp=1e30", "height=2.5", "width=-3"}) {
    {
      std::ofstream out(path, std::ios::trunc);
      out << "cam0=[1 0 0; 0 1 0; 0 0 1]\ncam1=[1 0 0; 0 1 0; 0 0 1]\nbaseline=10\nwidth=5\nheight=5\n" << bad << "\n";
    }
    try {
      ReadMiddleburyCalib(path);
      ADD_FAILURE() << bad;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("is not a whole number in"), std::string::npos) << e.what();
    }
  }
}

TEST(Middlebury, V2SceneReadsWithScaleAndMask) {
  const MiddleburyScene s = ReadMiddleburyScene("tests/data/stereo/tsukuba");
  EXPECT_EQ(s.layout, "v2");
  EXPECT_EQ(s.left.cols, 384);
  EXPECT_EQ(s.left.rows, 288);
  EXPECT_EQ(s.num_disparities, 15);
  ASSERT_FALSE(s.gt_disparity_px.empty());
  double lo = 0, hi = 0;
  cv::minMaxLoc(s.gt_disparity_px, &lo, &hi, nullptr, nullptr, s.gt_disparity_px == s.gt_disparity_px);
  EXPECT_GE(lo, 1.0);   // tsukuba's ground truth spans 5–14 px (value/16)
  EXPECT_LE(hi, 15.0);
  ASSERT_FALSE(s.mask_nonocc.empty());
  EXPECT_GT(cv::countNonZero(s.mask_nonocc), 80000);  // 85,438 of 110,592 pixels are marked
  EXPECT_THROW(ReadMiddleburyScene("tests/data/stereo"), Error);
  EXPECT_THROW(ReadDisparityMap("tests/data/stereo/tsukuba/groundtruth.png", 0.0), Error);
}

TEST(Evaluate, CountsHolesBothWays) {
  cv::Mat gt(1, 4, CV_32F, cv::Scalar(10.0f)), est(1, 4, CV_32F);
  est.at<float>(0, 0) = 10.2f;  // good
  est.at<float>(0, 1) = 11.5f;  // bad at 1
  est.at<float>(0, 2) = NAN;    // hole
  est.at<float>(0, 3) = 10.0f;  // good
  const DisparityEvaluation ev = EvaluateDisparity(est, gt, {});
  EXPECT_EQ(ev.evaluated_pixels, 4);
  EXPECT_DOUBLE_EQ(ev.coverage, 0.75);
  EXPECT_DOUBLE_EQ(ev.bad_with_holes[1], 0.5);        // bad-1: one wrong plus one hole of four
  EXPECT_DOUBLE_EQ(ev.bad_valid_only[1], 1.0 / 3.0);  // one wrong of three estimated
  EXPECT_DOUBLE_EQ(ev.bad_with_holes[3], 0.25);       // bad-4: only the hole
  EXPECT_THROW(EvaluateDisparity(est, cv::Mat(2, 4, CV_32F), {}), Error);
  // A mask that selects no pixel scored nothing and reported every bad-x as 0%, a perfect score.
  EXPECT_THROW(EvaluateDisparity(est, gt, cv::Mat::zeros(est.size(), CV_8U)), Error);
}

// A slanted plane stored in steps of 1/3 px (as Middlebury's third-size maps are) beside another plane 6 px nearer:
// the step is found, the fit brings the values nearer the planes (RMS under half the stored one) without taking a
// neighbour from across the jump, and moves none by more than a step; a continuous map has no step.
TEST(Evaluate, RemovesQuantisationStepsOfAStoredGroundTruth) {
  const int rows = 40, cols = 60;
  const double step = 1.0 / 3.0;
  cv::Mat truth(rows, cols, CV_32F), stored(rows, cols, CV_32F);
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const double d = c < 30 ? 20.0 + 0.037 * c + 0.021 * r : 26.0 + 0.05 * c - 0.013 * r;
      truth.at<float>(r, c) = static_cast<float>(d);
      stored.at<float>(r, c) = static_cast<float>(std::round(d / step) * step);
    }
  }
  truth.at<float>(5, 5) = stored.at<float>(5, 5) = NAN;
  EXPECT_DOUBLE_EQ(QuantisationStep(stored), step);
  EXPECT_EQ(QuantisationStep(truth), 0.0);
  const cv::Mat fitted = RemoveQuantisationSteps(stored, step);
  EXPECT_TRUE(std::isnan(fitted.at<float>(5, 5)));
  double stored_squares = 0, fitted_squares = 0, beside_jump = 0;
  for (int r = 0; r < rows; ++r) {
    for (int c = 0; c < cols; ++c) {
      const float t = truth.at<float>(r, c), s = stored.at<float>(r, c), f = fitted.at<float>(r, c);
      if (!std::isfinite(t)) continue;
      stored_squares += (s - t) * (s - t);
      fitted_squares += (f - t) * (f - t);
      EXPECT_LE(std::abs(f - s), step + 1e-5);
      if (c == 29 || c == 30) beside_jump = std::max(beside_jump, static_cast<double>(std::abs(f - t)));
    }
  }
  EXPECT_LT(fitted_squares, 0.25 * stored_squares);
  EXPECT_LT(beside_jump, 0.5 * step);
  EXPECT_THROW(RemoveQuantisationSteps(stored, 0.0), Error);
  EXPECT_THROW(RemoveQuantisationSteps(stored, step, 0), Error);
  EXPECT_THROW(QuantisationStep(cv::Mat(2, 2, CV_64F)), Error);
}

}  // namespace
}  // namespace rangebayes
