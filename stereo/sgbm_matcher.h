// OpenCV's semi-global block matcher behind our matcher interface.
#pragma once

#include "stereo/matcher.h"

namespace rangebayes {

// The largest block OpenCV's SGBM takes (px).
inline constexpr int kSgbmMaxBlockSizePx = 11;
// SGBM's disparities are fixed point with four fractional bits: steps of 1/16 px.
inline constexpr double kSgbmDisparityStepPx = 1.0 / 16.0;

struct SgbmMatcherOptions {
  int min_disparity_px = 0;        // any integer: smallest disparity searched
  int num_disparities = 64;        // ≥ 1, rounded up to a multiple of 16 (OpenCV's requirement)
  int block_size_px = 5;           // odd, 1–kSgbmMaxBlockSizePx
  int p1 = 0;                      // ≥ 0; 0: 8·channels·block² (OpenCV's sample)
  int p2 = 0;                      // > p1 or 0; 0: 32·channels·block²
  int uniqueness_ratio_pct = 10;   // 0–100: margin by which the best cost must win
  int speckle_window_px = 100;     // ≥ 0: speckle filter region size (0: off)
  int speckle_range_px = 2;        // ≥ 0: disparity variation allowed within a speckle region
  int left_right_max_diff_px = 1;  // < 0: off; else OpenCV's left-right consistency check (disp12MaxDiff)
  int pre_filter_cap = 63;         // 1–63: clamp of OpenCV's x-derivative pre-filter
  bool three_way = true;           // MODE_SGBM_3WAY (default) or MODE_SGBM (5 directions)
  void Check() const;
};

// cv::StereoSGBM wrapped: its 1/16-px fixed-point output is converted here, once, to float pixels with NaN for
// every invalid pixel. sigma_disparity_px stays empty.
class SgbmMatcher : public StereoMatcher {
 public:
  explicit SgbmMatcher(const SgbmMatcherOptions& options = {});
  DisparityResult Match(const std::vector<cv::Mat>& left, const std::vector<cv::Mat>& right) override;
  std::string name() const override { return "sgbm"; }

 private:
  SgbmMatcherOptions options_;
};

// Converts OpenCV's CV_16S disparity (value·16; below min_disparity·16 means invalid) to CV_32F pixels, NaN
// where invalid and at min_disparity exactly (a winner at the range's lower end is a tie or beyond the range).
cv::Mat FixedPointDisparityToFloat(const cv::Mat& disparity16, int min_disparity_px);

}  // namespace rangebayes
