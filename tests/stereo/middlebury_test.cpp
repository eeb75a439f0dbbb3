// Middlebury readers: calib.txt import (doffs kept), scene layouts, disparity maps with scale, masks, errors.
#include "calibration/middlebury.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "core/error.h"
#include "stereo/disparity_io.h"
#include "stereo/evaluate.h"
#include "stereo/pfm.h"
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
  // cam1 of another focal length or principal row is not a rectified pair's (its values were dropped silently).
  for (const char* cam1 : {"cam1=[1038 0 20; 0 1038 30; 0 0 1]", "cam1=[1000 0 20; 0 1000 31; 0 0 1]"}) {
    {
      std::ofstream out(path, std::ios::trunc);
      out << "cam0=[1000 0 10; 0 1000 30; 0 0 1]\n" << cam1 << "\nbaseline=10\nwidth=5\nheight=5\n";
    }
    try {
      ReadMiddleburyCalib(path);
      ADD_FAILURE() << cam1;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("not the calibration of a rectified pair"), std::string::npos) << e.what();
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

// No estimated pixel: the statistics over estimated pixels are unknown, not a perfect 0 (the report said "RMS 0.000
// px" and bad-x with holes excluded 0.00% for an all-NaN map).
TEST(Evaluate, AnEmptyEstimateHasNoRms) {
  const cv::Mat gt(2, 3, CV_32F, cv::Scalar(10.0f)), est(2, 3, CV_32F, cv::Scalar(NAN));
  const DisparityEvaluation ev = EvaluateDisparity(est, gt, {});
  EXPECT_EQ(ev.evaluated_pixels, 6);
  EXPECT_EQ(ev.estimated_pixels, 0);
  EXPECT_DOUBLE_EQ(ev.bad_with_holes[0], 1.0);
  EXPECT_TRUE(std::isnan(ev.rms_px) && std::isnan(ev.mean_abs_px) && std::isnan(ev.bad_valid_only[0]));
  const std::string report = ev.BriefReport();
  EXPECT_NE(report.find("no estimated pixel (RMS n/a)"), std::string::npos) << report;
  EXPECT_EQ(report.find("nan"), std::string::npos) << report;
}

// A colour picture (the disparity.png that `stereo` writes) is not read as a disparity map from its first channel,
// a grey map stored with three equal channels is; a PFM refuses a scale (it divided by one, undocumented).
TEST(Evaluate, ColourPicturesAndScaledPfmsAreRefused) {
  const TempDir dir("disparity_io");
  cv::Mat grey(4, 5, CV_8U, cv::Scalar(32)), colour;
  cv::Mat channels[] = {grey, grey, grey};
  cv::merge(channels, 3, colour);
  ASSERT_TRUE(cv::imwrite(dir.path() + "/grey3.png", colour));
  const cv::Mat d = ReadDisparityMap(dir.path() + "/grey3.png", 16.0);
  EXPECT_FLOAT_EQ(d.at<float>(0, 0), 2.0f);
  colour.at<cv::Vec3b>(1, 1)[2] = 200;
  ASSERT_TRUE(cv::imwrite(dir.path() + "/colour.png", colour));
  try {
    ReadDisparityMap(dir.path() + "/colour.png", 1.0);
    ADD_FAILURE() << "a colour image was read";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("a colour image, not a disparity map"), std::string::npos) << e.what();
  }
  WritePfm(cv::Mat(2, 2, CV_32F, cv::Scalar(3.0f)), dir.path() + "/d.pfm");
  EXPECT_FLOAT_EQ(ReadDisparityMap(dir.path() + "/d.pfm").at<float>(0, 0), 3.0f);
  EXPECT_THROW(ReadDisparityMap(dir.path() + "/d.pfm", 256.0), Error);
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
